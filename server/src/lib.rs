//! The holodeck server: the storage engine that owns a holodeck file and the
//! settings it records. Network service and scheduler build on these.

pub mod net;
pub mod radiance;
pub mod schedule;
pub mod settings;
pub mod storage;
pub mod testing;

pub use settings::{ControlFile, Settings, SettingsError};
pub use storage::{HoloFile, OpenOptions, StorageError};
