//! Settings as `KEY=value` text, the form stored in a holodeck file's header
//! (like Radiance's holodeck variables): `SECTION=` lines in the protocol's
//! section grammar, sizes and durations with units, `#` comments.

use std::fmt::Write as _;

use holodeck_protocol::{SectionSpec, SectionTextError};

use super::units::{format_duration, format_size, parse_duration, parse_size};
use super::{Settings, SettingsError, ValueError};

const KEYS: &[&str] = &[
    "SECTION",
    "GRID",
    "OBSTRUCTIONS",
    "VDISTANCE",
    "CACHE",
    "DISKSPACE",
    "TIME",
    "REPORT",
    "SCENE",
    "STALE",
];

/// A scene identity is one word of letters, digits and `:._-+/=` (a hash such as
/// `blake3:...`), so it survives the settings text unchanged.
pub(super) fn check_scene(s: &str) -> Result<&str, ValueError> {
    let ok = !s.is_empty() && s.len() <= 256 && s.chars().all(|c| c.is_ascii_alphanumeric() || ":._-+/=".contains(c));
    if ok {
        Ok(s)
    } else {
        Err(ValueError::Scene(s.to_string()))
    }
}

fn parse_bool(s: &str) -> Result<bool, ValueError> {
    match s.trim().to_ascii_lowercase().as_str() {
        "1" | "true" | "yes" | "on" | "t" | "y" => Ok(true),
        "0" | "false" | "no" | "off" | "f" | "n" => Ok(false),
        other => Err(ValueError::Bool(other.to_string())),
    }
}

impl Settings {
    /// Prints the settings as `KEY=value` lines.
    pub fn to_text(&self) -> String {
        let mut t = String::from("# holodeck settings\n");
        for s in &self.sections {
            let _ = writeln!(t, "SECTION={}", s.spec());
        }
        if let Some(g) = self.grid {
            let _ = writeln!(t, "GRID={g}");
        }
        let _ = writeln!(t, "OBSTRUCTIONS={}", self.obstructions);
        let _ = writeln!(t, "VDISTANCE={}", self.vdistance);
        let _ = writeln!(t, "CACHE={}", format_size(self.cache_bytes));
        let _ = writeln!(t, "DISKSPACE={}", format_size(self.diskspace_bytes));
        let _ = writeln!(t, "TIME={}", format_duration(self.time));
        let _ = writeln!(t, "REPORT={}", format_duration(self.report));
        if let Some(h) = &self.scene {
            let _ = writeln!(t, "SCENE={h}");
        }
        // Written only when set: the text of every other file stays as it was.
        if self.stale {
            let _ = writeln!(t, "STALE=true");
        }
        t
    }

    /// Parses `KEY=value` lines (`#` starts a comment). Bare TIME values are
    /// hours and bare REPORT values minutes, as in Radiance.
    pub fn from_text(text: &str) -> Result<Settings, SettingsError> {
        let mut s = Settings::default();
        let mut specs = Vec::new();
        for (i, raw) in text.lines().enumerate() {
            let line = i + 1;
            let err = |message: String| SettingsError::Line { line, message };
            let bad = |error: ValueError| SettingsError::Value { line, error };
            let content = raw.split('#').next().unwrap_or("").trim();
            if content.is_empty() {
                continue;
            }
            let (key, value) = content
                .split_once('=')
                .ok_or_else(|| err(format!("{content:?} is not KEY=value")))?;
            let (key, value) = (key.trim().to_ascii_uppercase(), value.trim());
            match key.as_str() {
                "SECTION" => specs.push((line, value.parse::<SectionSpec>().map_err(|e| bad(e.into()))?)),
                "GRID" => {
                    let g: f64 = value
                        .parse()
                        .map_err(|_| bad(ValueError::GridLength(value.to_string())))?;
                    s.grid = Some(g);
                }
                "OBSTRUCTIONS" => s.obstructions = parse_bool(value).map_err(bad)?,
                "VDISTANCE" => s.vdistance = parse_bool(value).map_err(bad)?,
                "CACHE" => s.cache_bytes = parse_size(value).map_err(|e| bad(e.into()))?,
                "DISKSPACE" => s.diskspace_bytes = parse_size(value).map_err(|e| bad(e.into()))?,
                "TIME" => s.time = parse_duration(value, 3600.0).map_err(|e| bad(e.into()))?,
                "REPORT" => s.report = parse_duration(value, 60.0).map_err(|e| bad(e.into()))?,
                "SCENE" => s.scene = Some(check_scene(value).map_err(bad)?.to_string()),
                "STALE" => s.stale = parse_bool(value).map_err(bad)?,
                other => {
                    return Err(err(format!(
                        "unknown setting {other:?}; known settings are {}",
                        KEYS.join(", ")
                    )))
                }
            }
        }
        // After every line: a section without grid= takes its grid from GRID, wherever that is.
        for (line, spec) in specs {
            let section = spec.resolve(s.grid, None).map_err(|e| SettingsError::Value {
                line,
                error: SectionTextError::from(e).into(),
            })?;
            s.sections.push(section);
        }
        s.validate()?;
        Ok(s)
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;
    use crate::settings::SizeError;
    use holodeck_protocol::{Section, SectionError, SectionField, SectionKind};

    pub(crate) fn sample() -> Settings {
        let a = Section::new(
            [0.1, -2.0, 0.3],
            [[10.0, 0.0, 0.0], [0.0, 6.5, 0.0], [0.0, 0.0, 1.0 / 3.0]],
            [20, 13, 3],
            SectionKind::Interior,
        )
        .unwrap();
        let b = Section::new(
            [5.0, 5.0, 5.0],
            [[1.0, 1.0, 0.0], [-1.0, 1.0, 0.0], [0.0, 0.0, 2.0]],
            [4, 4, 5],
            SectionKind::Exterior,
        )
        .unwrap();
        Settings {
            sections: vec![a, b],
            grid: Some(0.5),
            obstructions: true,
            cache_bytes: 96 << 20,
            diskspace_bytes: 3 << 30,
            time: Duration::from_secs(5400),
            report: Duration::from_secs(60),
            scene: Some("blake3:0123abcd".into()),
            stale: true,
            ..Settings::default()
        }
    }

    #[test]
    fn text_round_trips_exactly() {
        let s = sample();
        let text = s.to_text();
        assert!(text.contains("CACHE=96M"), "{text}");
        assert_eq!(Settings::from_text(&text).unwrap(), s);
    }

    #[test]
    fn radiance_units_and_errors_name_the_line() {
        let base = "SECTION=interior origin=0,0,0 x=1,0,0 y=0,1,0 z=0,0,1 grid=2,2,2\n";
        let s = Settings::from_text(&format!("{base}TIME=1.5\nREPORT=2\ncache=1.5M\n")).unwrap();
        assert_eq!(s.time, Duration::from_secs(5400));
        assert_eq!(s.report, Duration::from_secs(120));
        assert_eq!(s.cache_bytes, 1_572_864);
        let e = Settings::from_text(&format!("{base}\nFOO=1\n")).unwrap_err();
        assert!(e.to_string().starts_with("line 3: unknown setting \"FOO\""), "{e}");
        let e = Settings::from_text("SECTION=interior origin=0,0,0 x=1,0,0 y=0,1,0 grid=2,2,2").unwrap_err();
        assert!(
            matches!(
                e,
                SettingsError::Value {
                    line: 1,
                    error: ValueError::Section(ref s),
                } if **s == SectionTextError::Missing(SectionField::Axis(2))
            ),
            "{e:?}"
        );
        assert!(e.to_string().contains("no z= axis"), "{e}");
        assert_eq!(Settings::from_text("# nothing\n"), Err(SettingsError::NoSections));
        let e = Settings::from_text(&format!("{base}CACHE=12Q")).unwrap_err();
        assert_eq!(
            e,
            SettingsError::Value {
                line: 2,
                error: ValueError::Size(SizeError::UnknownUnit("12Q".into()))
            }
        );
        assert!(e.to_string().contains("unknown unit"), "{e}");
    }

    #[test]
    fn a_section_line_without_a_grid_takes_the_cell_length_given_on_any_line() {
        let s = Settings::from_text("SECTION=interior origin=0,0,0 x=4,0,0 y=0,3,0 z=0,0,2\nGRID=0.5\n").unwrap();
        assert_eq!(s.sections[0].grid(), [8, 6, 4]);
        let e = Settings::from_text("SECTION=interior origin=0,0,0 x=1,0,0 y=2,0,0 z=0,0,1 grid=2,2,2\n").unwrap_err();
        assert!(
            matches!(
                &e,
                SettingsError::Value { line: 1, error: ValueError::Section(s) }
                    if matches!(**s, SectionTextError::Section(SectionError::Degenerate(_)))
            ),
            "{e:?}"
        );
    }
}
