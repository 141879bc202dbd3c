//! The holodeck's settings, stored as `KEY=value` text in the file header, like
//! Radiance's holodeck variables, and read from TOML control files.
//!
//! Settings are pure data: these modules parse and print them and never open
//! files themselves. [`Settings`] is the model; [`text`] its header text,
//! [`control`] its TOML control file, [`units`] the sizes and durations both
//! write. Sections are described by the protocol's [`SectionSpec`].

use std::time::Duration;

use holodeck_protocol::Section;
#[cfg(doc)]
use holodeck_protocol::SectionSpec;

pub mod control;
mod error;
pub mod text;
pub mod units;

pub use control::ControlFile;
pub use error::{DurationError, SettingsError, SizeError, ValueError};
pub use holodeck_protocol::SectionTextError;
pub use units::{format_duration, format_size, parse_duration, parse_size};

/// Default beam cache budget: 64 MiB.
pub const DEFAULT_CACHE_BYTES: u64 = 64 << 20;

/// Everything a holodeck file records about how it was set up.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// The sections, in index order.
    pub sections: Vec<Section>,
    /// Cell length used to size grids (Radiance's GRID), if one was given.
    pub grid: Option<f64>,
    /// Whether sections may contain geometry (trace rays from the entry wall).
    pub obstructions: bool,
    /// Whether to record virtual distances through flat mirrors and glass.
    pub vdistance: bool,
    /// Beam cache budget in bytes.
    pub cache_bytes: u64,
    /// Largest file size in bytes; 0 means unlimited.
    pub diskspace_bytes: u64,
    /// Longest batch run; zero means unlimited.
    pub time: Duration,
    /// Interval between progress reports; zero means none.
    pub report: Duration,
    /// Content hash of the scene the rays were traced in, if known.
    pub scene: Option<String>,
    /// Some rays were traced in an older version of the scene: an admin
    /// adopted an edited scene and kept them (STALE).
    pub stale: bool,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            sections: Vec::new(),
            grid: None,
            obstructions: false,
            vdistance: false,
            cache_bytes: DEFAULT_CACHE_BYTES,
            diskspace_bytes: 0,
            time: Duration::ZERO,
            report: Duration::ZERO,
            scene: None,
            stale: false,
        }
    }
}

impl Settings {
    /// The default settings of a file of these sections.
    pub fn with_sections(sections: Vec<holodeck_protocol::Section>) -> Settings {
        Settings {
            sections,
            ..Settings::default()
        }
    }

    /// Checks what parsing cannot: that there is a section and the scene identity
    /// and text will survive a round trip through the file header.
    pub fn validate(&self) -> Result<(), SettingsError> {
        if self.sections.is_empty() {
            return Err(SettingsError::NoSections);
        }
        if let Some(scene) = &self.scene {
            text::check_scene(scene).map_err(|error| SettingsError::Key { key: "scene", error })?;
        }
        if let Some(g) = self.grid.filter(|g| !(g.is_finite() && *g > 0.0)) {
            return Err(SettingsError::Key {
                key: "grid",
                error: ValueError::GridLength(g.to_string()),
            });
        }
        Ok(())
    }
}
