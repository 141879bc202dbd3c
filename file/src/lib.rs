//! The holodeck file: what every program that reads or writes one links
//! (the server, and the file's own commands: pictures, copies, imports and
//! exports, replay), with no networking. As Radiance's `holofile.c` serves
//! rholo, rhpict, rhcopy, rhinfo and rhoptimize alike.
//!
//! * `storage` — the storage engine that owns one file: its format
//!   (`storage::format`), directories and fragments, the LRU beam cache,
//!   crash-safe commits, space accounting, copy, optimize, survey and repair.
//! * `settings` — the settings a file records, and the control file.
//! * `radiance` — Radiance holodeck (`.hdk`) files read and written.
//! * `testing` — helpers the storage tests and the other crates' tests share.

pub mod radiance;
pub mod settings;
pub mod storage;
pub mod testing;

pub use settings::{ControlFile, Settings, SettingsError};
pub use storage::{HoloFile, OpenOptions, StorageError};
