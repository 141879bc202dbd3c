//! What a survey of a file finds (for the current format and the older ones
//! alike), and reading one part of a file with the check that it is there.

use std::fs::File;
use std::path::Path;

use super::error::{CommitDamage, Result};
use super::format::{BeamEntry, ChunkRef, Extent, FormatError, Slot, COPIES};
use super::io;
use crate::settings::Settings;

/// What a survey found.
pub(crate) struct Survey {
    pub settings: Settings,
    pub text_len: u32,
    /// The file's format version (its header layout follows it).
    pub version: u32,
    pub data_start: u64,
    pub file_len: u64,
    /// Damaged copies whose twin verified: nothing is lost.
    pub repaired: Vec<String>,
    /// Commits a crash interrupted between their two slot copies (nothing is lost).
    pub torn: Vec<String>,
    /// Header copies that failed (rewritable from the other).
    pub bad_header: [bool; COPIES],
    /// The newest commit, when it can be read in full; else why not.
    pub damage: Option<CommitDamage>,
    /// Generation of the newest commit the slots hold.
    pub generation: u64,
    /// The side (0: A, 1: B) its slot is on.
    pub side: usize,
    /// The directory to use, per section.
    pub dirs: Vec<Vec<BeamEntry>>,
    /// The newest commit's root and chunks, when it was read in full.
    pub clean: Option<(Slot, Vec<ChunkRef>)>,
    /// Metadata extents that must not be overwritten until the next commit
    /// (every root and block copy the plan was read from).
    pub metadata: Vec<Extent>,
    /// Chunks (section, first beam) of the newest commit with a damaged copy.
    pub weak_chunks: Vec<(u32, u32)>,
    /// Slot sides whose two copies differ: the next commit to each rewrites them.
    pub uneven_slots: [bool; 2],
    /// The file is in an older format: it can be read, not written.
    pub legacy: Option<u32>,
}

/// Reads `len` bytes at `offset`, or says how the file ends before them.
pub(super) fn read_part(
    file: &File,
    path: &Path,
    offset: u64,
    len: u64,
    file_len: u64,
    what: &str,
) -> Result<std::result::Result<Vec<u8>, FormatError>> {
    if offset.checked_add(len).is_none_or(|end| end > file_len) {
        return Ok(Err(FormatError::Truncated {
            what: what.into(),
            start: offset,
            end: offset.saturating_add(len),
            have: file_len.saturating_sub(offset),
        }));
    }
    let mut buf = Vec::new();
    io::read_at(file, path, offset, len as usize, &mut buf)?;
    Ok(Ok(buf))
}
