//! TOML control files: the settings in lowercase keys, with `[[section]]`
//! tables in the protocol's [`SectionSpec`] form.

use holodeck_protocol::SectionSpec;
use serde::Deserialize;

use super::units::{parse_duration, parse_size};
use super::{Settings, SettingsError, ValueError};

/// A TOML control file: lowercase versions of the settings plus `[[section]]`
/// tables. A section's grid comes from its `grid`, else its `beams`, else the
/// global cell length `grid`, else a default beam count.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControlFile {
    /// The sections.
    #[serde(default, rename = "section")]
    pub sections: Vec<SectionSpec>,
    /// Cell length for grids.
    pub grid: Option<f64>,
    /// OBSTRUCTIONS.
    #[serde(default)]
    pub obstructions: bool,
    /// VDISTANCE.
    #[serde(default)]
    pub vdistance: bool,
    /// CACHE, e.g. "64M".
    pub cache: Option<String>,
    /// DISKSPACE, e.g. "2G".
    pub diskspace: Option<String>,
    /// TIME, e.g. "2h".
    pub time: Option<String>,
    /// REPORT, e.g. "1m".
    pub report: Option<String>,
    /// Scene identity.
    pub scene: Option<String>,
}

impl ControlFile {
    /// Validates and converts to [`Settings`].
    pub fn resolve(&self) -> Result<Settings, SettingsError> {
        let key = |key: &'static str| move |error: ValueError| SettingsError::Key { key, error };
        let mut s = Settings {
            grid: self.grid,
            obstructions: self.obstructions,
            vdistance: self.vdistance,
            scene: self.scene.clone(),
            ..Settings::default()
        };
        if let Some(c) = &self.cache {
            s.cache_bytes = parse_size(c).map_err(|e| key("cache")(e.into()))?;
        }
        if let Some(d) = &self.diskspace {
            s.diskspace_bytes = parse_size(d).map_err(|e| key("diskspace")(e.into()))?;
        }
        if let Some(t) = &self.time {
            s.time = parse_duration(t, 3600.0).map_err(|e| key("time")(e.into()))?;
        }
        if let Some(r) = &self.report {
            s.report = parse_duration(r, 60.0).map_err(|e| key("report")(e.into()))?;
        }
        for (index, e) in self.sections.iter().enumerate() {
            let section = e
                .resolve(self.grid, None)
                .map_err(|error| SettingsError::Section { index, error })?;
            s.sections.push(section);
        }
        s.validate()?;
        Ok(s)
    }
}

impl Settings {
    /// Parses a TOML control file (see [`ControlFile`]).
    pub fn from_toml(text: &str) -> Result<Settings, SettingsError> {
        let c: ControlFile = toml::from_str(text).map_err(|e| SettingsError::Toml(e.to_string()))?;
        c.resolve()
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;
    use crate::settings::DurationError;
    use holodeck_protocol::SectionKind;

    #[test]
    fn control_file_sizes_grids() {
        let toml = r#"
            grid = 0.5
            cache = "32M"
            time = "2h"
            [[section]]
            origin = [0, 0, 0]
            axes = [[4, 0, 0], [0, 3, 0], [0, 0, 2.2]]
            [[section]]
            kind = "exterior"
            origin = [10, 0, 0]
            axes = [[2, 0, 0], [0, 2, 0], [0, 0, 2]]
            grid = [3, 3, 3]
        "#;
        let s = Settings::from_toml(toml).unwrap();
        assert_eq!(s.sections[0].grid(), [8, 6, 5]);
        assert_eq!(s.sections[1].grid(), [3, 3, 3]);
        assert_eq!(s.sections[1].kind(), SectionKind::Exterior);
        assert_eq!(s.cache_bytes, 32 << 20);
        assert_eq!(s.time, Duration::from_secs(7200));
        let bad = Settings::from_toml("[[section]]\norigin=[0,0,0]\naxes=[[1,0,0],[0,1,0],[0,0,1]]\ngird=[1,1,1]\n");
        assert!(bad.unwrap_err().to_string().contains("gird"));
        let e =
            Settings::from_toml("time = \"forever\"\n[[section]]\norigin=[0,0,0]\naxes=[[1,0,0],[0,1,0],[0,0,1]]\n");
        assert_eq!(
            e,
            Err(SettingsError::Key {
                key: "time",
                error: ValueError::Duration(DurationError::NotANumber("forever".into()))
            })
        );
        let both =
            Settings::from_toml("[[section]]\norigin=[0,0,0]\naxes=[[1,0,0],[0,1,0],[0,0,1]]\ngrid=[1,1,1]\nbeams=9\n");
        assert_eq!(
            both.unwrap_err().to_string(),
            "section 0 grid: give a grid or a target beam count, not both"
        );
    }
}
