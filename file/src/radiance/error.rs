//! Why a Radiance holodeck cannot be read or written: each error names the
//! part of the file and the byte position at fault.

use std::io;
use std::path::PathBuf;

use holodeck_protocol::SectionError;

use crate::storage::StorageError;

/// Anything that can go wrong importing or exporting a Radiance holodeck.
#[derive(Debug, thiserror::Error)]
pub enum RadianceError {
    /// The operating system refused an operation.
    #[error("{path}: {op}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What was being done.
        op: &'static str,
        /// The OS error.
        source: io::Error,
    },
    /// The file is not a Radiance holodeck, or not one this program reads.
    #[error("not a Radiance holodeck: {0}")]
    NotHolodeck(String),
    /// The magic number after the header is not one of Radiance's layouts.
    #[error(
        "the magic number after the header at byte {at} is {little} read little-endian ({big} big-endian): \
         not a Radiance holodeck layout this program reads (340: 64-bit offsets, 336: 64-bit offsets \
         packed on 4 bytes, 332: 32-bit offsets, in either byte order)"
    )]
    Magic {
        /// Its position.
        at: u64,
        /// Read little-endian.
        little: u32,
        /// Read big-endian.
        big: u32,
    },
    /// The header's `BigEndian=` line disagrees with the magic number.
    #[error("the header says BigEndian={said} but the magic number is {found}-endian")]
    ByteOrderMismatch {
        /// The header's value.
        said: u8,
        /// What the magic number shows.
        found: &'static str,
    },
    /// A part of the file ends before its declared size.
    #[error("{what} at bytes {start}..{end} is cut off: the file ends at byte {len}")]
    Truncated {
        /// Which part.
        what: String,
        /// Its first byte.
        start: u64,
        /// One past its last byte.
        end: u64,
        /// The file's length.
        len: u64,
    },
    /// A value that no Radiance writer produces.
    #[error("{what} at byte {at}: {detail}")]
    Invalid {
        /// Which part.
        what: String,
        /// Its position.
        at: u64,
        /// What is wrong.
        detail: String,
    },
    /// A section's grid does not make a section this program can hold.
    #[error("section {index} (at byte {at}): {source}")]
    Section {
        /// The section, counting from 0.
        index: usize,
        /// Its position.
        at: u64,
        /// Why.
        source: SectionError,
    },
    /// The holodeck file being read or written failed.
    #[error(transparent)]
    Storage(#[from] StorageError),
}

/// Result of this module.
pub type Result<T> = std::result::Result<T, RadianceError>;
