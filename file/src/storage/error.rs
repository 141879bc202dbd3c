//! Errors of the storage engine. Each names the file and, where it applies, the
//! section, beam and byte range involved, so a user knows what broke and where.

use std::io;
use std::path::PathBuf;

use holodeck_protocol::{BeamKey, SectionError};

use super::format::FormatError;
use crate::settings::SettingsError;

/// Anything that can go wrong reading or writing a holodeck file.
#[derive(Debug, thiserror::Error)]
pub enum StorageError {
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
    /// Bytes in the file are not a valid holodeck.
    #[error("{path}: {source}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What and where.
        source: FormatError,
    },
    /// The settings text in the header is invalid.
    #[error("{path}: settings in the file header: {source}")]
    Settings {
        /// The file.
        path: PathBuf,
        /// What.
        source: SettingsError,
    },
    /// Neither commit slot leads to a consistent state.
    #[error(
        "{path}: no consistent commit found; `holodeck check --repair` can salvage the beams that verify.\n{problems}"
    )]
    NoValidCommit {
        /// The file.
        path: PathBuf,
        /// Why each candidate failed, one per line.
        problems: String,
    },
    /// The newest commit is damaged: writing on top of it would make its loss
    /// permanent, so a writable open refuses unless told to accept the loss.
    #[error(
        "{path}: {}\n`holodeck check {}` tells more and `holodeck check --repair NEW_FILE` copies every beam that verifies; \
         --accept-loss writes on top of what can be read",
        damage.describe(), path.display()
    )]
    Damaged {
        /// The file.
        path: PathBuf,
        /// What is damaged and lost.
        damage: Box<CommitDamage>,
    },
    /// A beam's records fail their checksum.
    #[error("{path}: beam {} of section {} (bytes {start}..{end}) fails its checksum; `holodeck check --repair` salvages the other beams", key.beam, key.section)]
    BeamCorrupt {
        /// The file.
        path: PathBuf,
        /// Which beam.
        key: BeamKey,
        /// First byte of its run.
        start: u64,
        /// One past its last byte.
        end: u64,
    },
    /// A section index beyond the holodeck's sections.
    #[error("section {section} does not exist: the holodeck has {count}")]
    NoSuchSection {
        /// Index asked for.
        section: u32,
        /// Sections present.
        count: usize,
    },
    /// A beam index beyond its section's beams.
    #[error("section {section}: {source}")]
    Beam {
        /// The section.
        section: u32,
        /// Why.
        source: SectionError,
    },
    /// A beam would exceed the 2^32-1 rays its directory entry can count.
    #[error("beam {} of section {} would hold more than {} rays", key.beam, key.section, u32::MAX)]
    BeamFull {
        /// Which beam.
        key: BeamKey,
    },
    /// Another process holds the file.
    #[error("{path} is in use by another holodeck process")]
    Locked {
        /// The file.
        path: PathBuf,
    },
    /// Creating a file that exists.
    #[error("{path} already exists; remove it or choose another name")]
    Exists {
        /// The file.
        path: PathBuf,
    },
    /// An earlier write or sync failed; what is on disk since the last commit is uncertain.
    #[error("{path}: an earlier write or sync failed, so nothing more is written; reopen the file (it recovers its last commit)")]
    Poisoned {
        /// The file.
        path: PathBuf,
    },
    /// Storing more would let the file grow past its DISKSPACE limit. Nothing
    /// was written: refused rays were not stored, and rays already accepted
    /// stay in the cache. The file stays usable; smaller appends may still fit.
    #[error("{path}: DISKSPACE limit of {limit} bytes reached: the file could grow to {needed} bytes")]
    DiskSpace {
        /// The file.
        path: PathBuf,
        /// The limit in bytes.
        limit: u64,
        /// How long the file could become (an upper bound) if this were done.
        needed: u64,
    },
    /// Writing to a file opened for reading.
    #[error("{path} is open read-only")]
    ReadOnly {
        /// The file.
        path: PathBuf,
    },
    /// New settings would need a larger header than the file has room for.
    #[error("{path}: the new settings take {need} bytes, more than the {room} the header has room for")]
    SettingsTooLong {
        /// The file.
        path: PathBuf,
        /// Bytes of settings text the header holds at most.
        room: u64,
        /// Bytes the new settings take.
        need: u64,
    },
}

/// Result type of the storage engine.
pub type Result<T> = std::result::Result<T, StorageError>;

/// How a commit's newest state was damaged, and what reading it loses.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CommitDamage {
    /// The damaged commit: the newest one the file's slots hold.
    pub generation: u64,
    /// What is damaged, one line each.
    pub problems: Vec<String>,
    /// Rays that commit holds, when its root could still be read.
    pub claimed_rays: Option<u64>,
    /// Rays the planned directory holds (before their checksums are verified).
    pub readable_rays: u64,
    /// The older commit some chunks were taken from, if any.
    pub fallback: Option<u64>,
}

impl CommitDamage {
    /// Rays of the damaged commit that reading what verifies loses, if known.
    pub fn rays_lost(&self) -> Option<u64> {
        self.claimed_rays.map(|c| c.saturating_sub(self.readable_rays))
    }

    /// One paragraph for messages: which commit, what is damaged, what is lost.
    pub fn describe(&self) -> String {
        let mut s = format!("commit {} (the newest) is damaged:", self.generation);
        for p in &self.problems {
            s.push_str("\n  ");
            s.push_str(p);
        }
        let from = match self.fallback {
            Some(g) => format!(", taking lost directories from commit {g}"),
            None => String::new(),
        };
        match self.rays_lost() {
            Some(lost) => s.push_str(&format!(
                "\nreading what can be read{from} keeps {} of its {} rays and loses {lost}",
                self.readable_rays,
                self.claimed_rays.unwrap_or(0)
            )),
            None => s.push_str(&format!(
                "\nits ray count is unreadable; reading what can be read{from} keeps {} rays",
                self.readable_rays
            )),
        }
        s
    }
}
