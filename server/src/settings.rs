//! The holodeck's settings, stored as `KEY=value` text in the file header, like
//! Radiance's holodeck variables, and read from TOML control files.
//!
//! Settings are pure data: this module parses and prints them and never opens
//! files itself.

use std::fmt::Write as _;
use std::time::Duration;

use holodeck_protocol::{grid_for_beam_count, grid_for_length, Section, SectionField, SectionKind};
use serde::Deserialize;

mod error;

pub use error::{DurationError, SectionTextError, SettingsError, SizeError, ValueError};

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

/// Parses a byte size such as `64M`, `1.5G`, `4096` or `0`.
pub fn parse_size(s: &str) -> Result<u64, SizeError> {
    let s = s.trim();
    let (num, mult) = match s.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let mult = match c.to_ascii_uppercase() {
                'K' => 1u64 << 10,
                'M' => 1 << 20,
                'G' => 1 << 30,
                'T' => 1 << 40,
                _ => return Err(SizeError::UnknownUnit(s.to_string())),
            };
            (&s[..i], mult)
        }
        _ => (s, 1),
    };
    let v: f64 = num.trim().parse().map_err(|_| SizeError::NotANumber(s.to_string()))?;
    if !(v.is_finite() && v >= 0.0) {
        return Err(SizeError::Negative(s.to_string()));
    }
    let bytes = (v * mult as f64).round();
    // 2^64 itself is the first value a u64 cannot hold.
    if bytes >= 18_446_744_073_709_551_616.0 {
        return Err(SizeError::TooLarge(s.to_string()));
    }
    Ok(bytes as u64)
}

/// Formats a byte size compactly, exactly (`64M`, `1536K`, `1000`).
pub fn format_size(bytes: u64) -> String {
    for (unit, shift) in [("T", 40), ("G", 30), ("M", 20), ("K", 10)] {
        if bytes != 0 && bytes.is_multiple_of(1u64 << shift) {
            return format!("{}{unit}", bytes >> shift);
        }
    }
    bytes.to_string()
}

/// Parses a duration such as `90s`, `15m`, `2h`; a bare number takes `default_unit` seconds.
pub fn parse_duration(s: &str, default_unit: f64) -> Result<Duration, DurationError> {
    let s = s.trim();
    let (num, unit) = match s.chars().last() {
        Some('s') => (&s[..s.len() - 1], 1.0),
        Some('m') => (&s[..s.len() - 1], 60.0),
        Some('h') => (&s[..s.len() - 1], 3600.0),
        _ => (s, default_unit),
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| DurationError::NotANumber(s.to_string()))?;
    if !(v.is_finite() && v >= 0.0) {
        return Err(DurationError::Negative(s.to_string()));
    }
    Duration::try_from_secs_f64(v * unit).map_err(|_| DurationError::TooLong(s.to_string()))
}

fn format_duration(d: Duration) -> String {
    format!("{}s", d.as_secs_f64())
}

/// A scene identity is one word of letters, digits and `:._-+/=` (a hash such as
/// `blake3:...`), so it survives the settings text unchanged.
fn check_scene(s: &str) -> Result<&str, ValueError> {
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

fn parse_vec3(key: SectionField, s: &str) -> Result<[f64; 3], SectionTextError> {
    let bad = || SectionTextError::NotThreeNumbers {
        key,
        text: s.to_string(),
    };
    let parts: Vec<&str> = s.split(',').collect();
    if parts.len() != 3 {
        return Err(bad());
    }
    let mut v = [0.0; 3];
    for (k, p) in parts.iter().enumerate() {
        v[k] = p.trim().parse().map_err(|_| bad())?;
    }
    Ok(v)
}

fn vec3_text(v: [f64; 3]) -> String {
    // `{}` prints the shortest text that reads back to the same f64.
    format!("{},{},{}", v[0], v[1], v[2])
}

/// One section line: `interior origin=X,Y,Z x=.. y=.. z=.. grid=W,D,H`.
pub fn section_text(s: &Section) -> String {
    let spec = s.spec();
    format!(
        "{} origin={} x={} y={} z={} grid={},{},{}",
        spec.kind.name(),
        vec3_text(spec.origin),
        vec3_text(spec.axes[0]),
        vec3_text(spec.axes[1]),
        vec3_text(spec.axes[2]),
        spec.grid[0],
        spec.grid[1],
        spec.grid[2]
    )
}

/// Parses a section line (the inverse of [`section_text`]); `grid=` is required.
pub fn parse_section(text: &str) -> Result<Section, SectionTextError> {
    parse_section_with(text, None)
}

/// Parses a section line whose `grid=` may be left out: the grid then comes from
/// `grid_length` (Radiance's GRID), else from `target_beams`, else
/// [`DEFAULT_TARGET_BEAMS`] beams.
pub fn parse_section_line(
    text: &str,
    grid_length: Option<f64>,
    target_beams: Option<u64>,
) -> Result<Section, SectionTextError> {
    parse_section_with(text, Some((grid_length, target_beams)))
}

/// `auto` is `None` when the grid must be explicit.
fn parse_section_with(text: &str, auto: Option<(Option<f64>, Option<u64>)>) -> Result<Section, SectionTextError> {
    let mut words = text.split_whitespace();
    let kind = match words.next() {
        Some("interior") => SectionKind::Interior,
        Some("exterior") => SectionKind::Exterior,
        other => return Err(SectionTextError::Kind(other.map(str::to_string))),
    };
    let (mut origin, mut axes, mut grid) = (None, [None; 3], None);
    for w in words {
        let (k, v) = w
            .split_once('=')
            .ok_or_else(|| SectionTextError::NotKeyValue(w.to_string()))?;
        match k {
            "origin" => origin = Some(parse_vec3(SectionField::Origin, v)?),
            "x" => axes[0] = Some(parse_vec3(SectionField::Axis(0), v)?),
            "y" => axes[1] = Some(parse_vec3(SectionField::Axis(1), v)?),
            "z" => axes[2] = Some(parse_vec3(SectionField::Axis(2), v)?),
            "grid" => {
                let g = parse_vec3(SectionField::Grid, v)?;
                let mut out = [0u16; 3];
                for (k, x) in g.iter().enumerate() {
                    if x.fract() != 0.0 || !(0.0..=65535.0).contains(x) {
                        return Err(SectionTextError::GridNotWhole(*x));
                    }
                    out[k] = *x as u16;
                }
                grid = Some(out);
            }
            other => return Err(SectionTextError::UnknownField(other.to_string())),
        }
    }
    let origin = origin.ok_or(SectionTextError::Missing(SectionField::Origin))?;
    let axis = |k: usize| axes[k].ok_or(SectionTextError::Missing(SectionField::Axis(k)));
    let axes = [axis(0)?, axis(1)?, axis(2)?];
    let grid = match (grid, auto) {
        (Some(g), _) => g,
        (None, Some((Some(len), _))) => grid_for_length(axes, len)?,
        (None, Some((None, target))) => grid_for_beam_count(axes, target.unwrap_or(DEFAULT_TARGET_BEAMS))?,
        (None, None) => return Err(SectionTextError::Missing(SectionField::Grid)),
    };
    Ok(Section::new(origin, axes, grid, kind)?)
}

impl Settings {
    /// Checks what parsing cannot: that there is a section and the scene identity
    /// and text will survive a round trip through the file header.
    pub fn validate(&self) -> Result<(), SettingsError> {
        if self.sections.is_empty() {
            return Err(SettingsError::NoSections);
        }
        if let Some(scene) = &self.scene {
            check_scene(scene).map_err(|error| SettingsError::Key { key: "scene", error })?;
        }
        if let Some(g) = self.grid.filter(|g| !(g.is_finite() && *g > 0.0)) {
            return Err(SettingsError::Key {
                key: "grid",
                error: ValueError::GridLength(g.to_string()),
            });
        }
        Ok(())
    }

    /// Prints the settings as `KEY=value` lines.
    pub fn to_text(&self) -> String {
        let mut t = String::from("# holodeck settings\n");
        for s in &self.sections {
            let _ = writeln!(t, "SECTION={}", section_text(s));
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
                "SECTION" => s.sections.push(parse_section(value).map_err(|e| bad(e.into()))?),
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
        s.validate()?;
        Ok(s)
    }

    /// Parses a TOML control file (see [`ControlFile`]).
    pub fn from_toml(text: &str) -> Result<Settings, SettingsError> {
        let c: ControlFile = toml::from_str(text).map_err(|e| SettingsError::Toml(e.to_string()))?;
        c.resolve()
    }
}

/// A section in a control file: the grid comes from `grid`, else the global
/// cell length, else `beams` (a target beam count), else 150,000 beams.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SectionEntry {
    /// interior (default) or exterior.
    #[serde(default = "interior")]
    pub kind: SectionKind,
    /// World corner.
    pub origin: [f64; 3],
    /// The three edge vectors.
    pub axes: [[f64; 3]; 3],
    /// Explicit cells per axis.
    pub grid: Option<[u16; 3]>,
    /// Target beam count for an automatic grid.
    pub beams: Option<u64>,
}

fn interior() -> SectionKind {
    SectionKind::Interior
}

/// A TOML control file: lowercase versions of the settings plus `[[section]]` tables.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControlFile {
    /// The sections.
    #[serde(default, rename = "section")]
    pub sections: Vec<SectionEntry>,
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

/// Beam count aimed at when a section gives neither a grid nor a cell length.
pub const DEFAULT_TARGET_BEAMS: u64 = 150_000;

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
            let wrap = |error| SettingsError::Section { index, error };
            let grid = match (e.grid, self.grid, e.beams) {
                (Some(g), _, _) => g,
                (None, Some(len), None) => grid_for_length(e.axes, len).map_err(wrap)?,
                (None, _, target) => {
                    grid_for_beam_count(e.axes, target.unwrap_or(DEFAULT_TARGET_BEAMS)).map_err(wrap)?
                }
            };
            s.sections
                .push(Section::new(e.origin, e.axes, grid, e.kind).map_err(wrap)?);
        }
        s.validate()?;
        Ok(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use holodeck_protocol::SectionError;

    fn sample() -> Settings {
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
    fn values_that_do_not_parse_say_which_way() {
        assert_eq!(parse_size("1.5K"), Ok(1536));
        assert_eq!(parse_size("-1"), Err(SizeError::Negative("-1".into())));
        assert_eq!(parse_size("lots"), Err(SizeError::UnknownUnit("lots".into())));
        assert_eq!(parse_size("M"), Err(SizeError::NotANumber("M".into())));
        assert_eq!(parse_size("1e10T"), Err(SizeError::TooLarge("1e10T".into())));
        assert_eq!(parse_duration("2m", 1.0), Ok(Duration::from_secs(120)));
        assert_eq!(
            parse_duration("soon", 1.0),
            Err(DurationError::NotANumber("soon".into()))
        );
        assert_eq!(parse_duration("-3s", 1.0), Err(DurationError::Negative("-3s".into())));
        // Far past what a Duration holds: refused, not a panic.
        assert_eq!(
            parse_duration("1e30h", 1.0),
            Err(DurationError::TooLong("1e30h".into()))
        );
        let grid = parse_section("interior origin=0,0,0 x=1,0,0 y=0,1,0 z=0,0,1 grid=2,2.5,2");
        assert_eq!(grid, Err(SectionTextError::GridNotWhole(2.5)));
        let axis = parse_section("interior origin=0,0,0 x=1,0 y=0,1,0 z=0,0,1 grid=2,2,2").unwrap_err();
        assert!(
            matches!(
                axis,
                SectionTextError::NotThreeNumbers {
                    key: SectionField::Axis(0),
                    ..
                }
            ),
            "{axis:?}"
        );
        assert_eq!(axis.to_string(), "x=1,0 is not three comma-separated numbers");
        assert!(matches!(
            parse_section("inside origin=0,0,0"),
            Err(SectionTextError::Kind(Some(k))) if k == "inside"
        ));
        let flat = parse_section("interior origin=0,0,0 x=1,0,0 y=2,0,0 z=0,0,1 grid=2,2,2");
        assert!(
            matches!(flat, Err(SectionTextError::Section(SectionError::Degenerate(_)))),
            "{flat:?}"
        );
        let e =
            Settings::from_toml("time = \"forever\"\n[[section]]\norigin=[0,0,0]\naxes=[[1,0,0],[0,1,0],[0,0,1]]\n");
        assert_eq!(
            e,
            Err(SettingsError::Key {
                key: "time",
                error: ValueError::Duration(DurationError::NotANumber("forever".into()))
            })
        );
    }

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
    }
}
