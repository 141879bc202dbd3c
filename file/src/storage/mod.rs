//! The holodeck storage engine: a portable, checksummed, crash-safe file of
//! beams, with an LRU beam cache. It never touches sockets.
//!
//! Layout and codecs are in [`format`]; the fragment list in [`extents`]; the
//! cache in [`cache`]; crash-safe commits on disk in [`disk`]; the user-facing API in
//! [`HoloFile`]; whole-file tools in [`maintain`].

pub mod bulk;
pub mod cache;
pub mod copy;
pub mod disk;
pub mod error;
pub mod extents;
#[cfg(feature = "fault-injection")]
pub mod faults;
pub mod format;
mod found;
pub mod holofile;
mod io;
mod legacy;
pub mod maintain;
mod space;
pub mod survey;

pub use bulk::SequentialWriter;
pub use copy::{copy, copy_with, CopyOptions, CopyReport};
pub use disk::{IoStats, OpenInfo};
pub use error::CommitDamage;
pub use error::{Result, StorageError};
pub use holofile::{FileSummary, HoloFile, OpenOptions, ReadReport, DEFAULT_FLUSH_INTERVAL};
pub use maintain::{check, optimize, repair, CheckReport, OptimizeReport, RepairReport};
