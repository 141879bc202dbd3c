//! The text header of a Radiance holodeck: `#?RADIANCE`, then `rholo`'s
//! variables one per line (`GRID= 0.25`, `section= ...`), `BigEndian=`,
//! `FORMAT=Holodeck`, and an empty line. Variables map to this program's
//! settings with Radiance's units: CACHE and DISKSPACE in megabytes, TIME in
//! hours, REPORT in minutes.

use std::fmt::Write as _;
use std::time::Duration;

use holodeck_protocol::{Section, SectionKind};

use super::error::{RadianceError, Result};
use crate::settings::Settings;

/// The first line of every Radiance file.
pub const RADIANCE_MAGIC: &str = "#?RADIANCE";
/// The format name of a holodeck.
pub const HOLODECK_FORMAT: &str = "Holodeck";
/// Longest header read: Radiance's own lines are at most 2 KiB and a header
/// holds a few dozen of them.
pub const MAX_HEADER: usize = 1 << 20;

/// This program's own header lines, which Radiance ignores: the sections'
/// kinds, and the scene's identity.
const KINDS: &str = "HOLODECK_KINDS";
const SCENE: &str = "HOLODECK_SCENE";
const STALE: &str = "HOLODECK_STALE";

/// The parsed header.
#[derive(Clone, Debug, PartialEq)]
pub struct Header {
    /// Lines between the first line and `FORMAT=`/the end, as written.
    pub lines: Vec<String>,
    /// The `FORMAT=` value, if any.
    pub format: Option<String>,
    /// The `BigEndian=` value, if any.
    pub big_endian: Option<u8>,
    /// Bytes of the header, the empty line included: where the magic number starts.
    pub len: u64,
}

/// rholo's variables, with the shortest prefix each may be abbreviated to.
const VARIABLES: [(&str, usize); 14] = [
    ("CACHE", 2),
    ("DISKSPACE", 3),
    ("EYESEP", 3),
    ("geometry", 3),
    ("GRID", 2),
    ("OBSTRUCTIONS", 3),
    ("OCTREE", 3),
    ("portals", 3),
    ("render", 3),
    ("REPORT", 3),
    ("RIF", 3),
    ("section", 3),
    ("TIME", 2),
    ("VDISTANCE", 2),
];

/// The variable a name abbreviates, as rholo matches it (case-sensitive prefix).
fn variable(name: &str) -> Option<&'static str> {
    VARIABLES
        .iter()
        .find(|(v, nick)| name.len() >= *nick && v.starts_with(name))
        .map(|(v, _)| *v)
}

/// Parses the header at the start of `bytes` (the file's first [`MAX_HEADER`] bytes or fewer).
pub fn parse(bytes: &[u8]) -> Result<Header> {
    let first = RADIANCE_MAGIC.as_bytes();
    if !bytes.starts_with(first) {
        let shown = String::from_utf8_lossy(&bytes[..bytes.len().min(16)]).into_owned();
        return Err(RadianceError::NotHolodeck(format!(
            "it starts with {shown:?}, not \"{RADIANCE_MAGIC}\""
        )));
    }
    let mut header = Header {
        lines: Vec::new(),
        format: None,
        big_endian: None,
        len: 0,
    };
    let mut at = 0usize;
    loop {
        let Some(end) = bytes[at..].iter().position(|&b| b == b'\n') else {
            return Err(RadianceError::NotHolodeck(format!(
                "its header has no empty line ending it within the first {} bytes",
                bytes.len()
            )));
        };
        let line = &bytes[at..at + end];
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        at += end + 1;
        if line.is_empty() {
            break;
        }
        if line == first {
            continue;
        }
        let text = String::from_utf8_lossy(line).into_owned();
        if let Some(f) = text.strip_prefix("FORMAT=") {
            header.format = Some(f.trim().to_string());
        } else if let Some(b) = text.strip_prefix("BigEndian=") {
            header.big_endian = match b.trim() {
                "0" => Some(0),
                "1" => Some(1),
                other => {
                    return Err(RadianceError::Invalid {
                        what: "header line BigEndian=".into(),
                        at: (at - end - 1) as u64,
                        detail: format!("{other:?} is neither 0 nor 1"),
                    })
                }
            };
        } else {
            header.lines.push(text);
        }
    }
    header.len = at as u64;
    match header.format.as_deref() {
        None | Some(HOLODECK_FORMAT) => Ok(header),
        Some(other) => Err(RadianceError::NotHolodeck(format!(
            "its header says FORMAT={other}, not {HOLODECK_FORMAT} (a Radiance picture or octree?)"
        ))),
    }
}

/// Radiance's boolean values: the first letter decides.
fn boolean(value: &str) -> Option<bool> {
    match value.trim().chars().next()? {
        'y' | 'Y' | 't' | 'T' | '+' | '1' => Some(true),
        'n' | 'N' | 'f' | 'F' | '-' | '0' => Some(false),
        _ => None,
    }
}

fn number(value: &str) -> Option<f64> {
    value
        .split_whitespace()
        .next()?
        .parse()
        .ok()
        .filter(|v: &f64| v.is_finite() && *v >= 0.0)
}

/// What a header's variables give: the settings they map to, the sections'
/// kinds when the file says them, and the variables left behind.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Variables {
    /// Settings without sections.
    pub settings: Settings,
    /// The sections' kinds, when written by this program.
    pub kinds: Option<Vec<SectionKind>>,
    /// `section=` lines (the binary grids are what counts; these are checked against them).
    pub section_lines: usize,
    /// Lines not carried over (rendering options, octree, ...), as written.
    pub unused: Vec<String>,
}

impl Header {
    /// Maps the variables to settings. Values that do not parse are reported
    /// as unused rather than refused: the rays do not depend on them.
    pub fn variables(&self) -> Variables {
        let mut out = Variables::default();
        for line in &self.lines {
            let Some((name, value)) = line.split_once('=') else {
                out.unused.push(line.clone());
                continue;
            };
            let (name, value) = (name.trim(), value.trim());
            let s = &mut out.settings;
            let used = match (name, variable(name)) {
                (KINDS, _) => {
                    let kinds: Option<Vec<SectionKind>> = value
                        .split_whitespace()
                        .map(|k| match k {
                            "interior" => Some(SectionKind::Interior),
                            "exterior" => Some(SectionKind::Exterior),
                            _ => None,
                        })
                        .collect();
                    out.kinds = kinds;
                    out.kinds.is_some()
                }
                (SCENE, _) => {
                    s.scene = Some(value.to_string());
                    true
                }
                (STALE, _) => boolean(value).map(|b| s.stale = b).is_some(),
                (_, Some("CACHE")) => number(value)
                    .map(|mb| s.cache_bytes = (mb * 1048576.0) as u64)
                    .is_some(),
                (_, Some("DISKSPACE")) => number(value)
                    .map(|mb| s.diskspace_bytes = (mb * 1048576.0) as u64)
                    .is_some(),
                (_, Some("GRID")) => number(value).filter(|g| *g > 0.0).map(|g| s.grid = Some(g)).is_some(),
                (_, Some("OBSTRUCTIONS")) => boolean(value).map(|b| s.obstructions = b).is_some(),
                (_, Some("VDISTANCE")) => boolean(value).map(|b| s.vdistance = b).is_some(),
                (_, Some("TIME")) => number(value)
                    .and_then(|h| Duration::try_from_secs_f64(h * 3600.0).ok())
                    .map(|d| s.time = d)
                    .is_some(),
                (_, Some("REPORT")) => number(value)
                    .and_then(|m| Duration::try_from_secs_f64(m * 60.0).ok())
                    .map(|d| s.report = d)
                    .is_some(),
                (_, Some("section")) => {
                    out.section_lines += 1;
                    true
                }
                _ => false,
            };
            if !used {
                out.unused.push(line.clone());
            }
        }
        out
    }
}

fn mb(bytes: u64) -> String {
    format!("{}", bytes as f64 / 1048576.0)
}

fn truth(b: bool) -> &'static str {
    if b {
        "True"
    } else {
        "False"
    }
}

/// The header of a Radiance holodeck holding `settings`, in `order`
/// (`big_endian`), as rholo writes it, plus this program's own lines.
pub fn write(settings: &Settings, big_endian: bool) -> String {
    let s = settings;
    let mut t = format!("{RADIANCE_MAGIC}\nSOFTWARE= holodeck {}\n", env!("CARGO_PKG_VERSION"));
    let _ = writeln!(t, "CACHE={}", mb(s.cache_bytes));
    if s.diskspace_bytes > 0 {
        let _ = writeln!(t, "DISKSPACE={}", mb(s.diskspace_bytes));
    }
    if let Some(g) = s.grid {
        let _ = writeln!(t, "GRID={g}");
    }
    let _ = writeln!(t, "OBSTRUCTIONS={}", truth(s.obstructions));
    if !s.report.is_zero() {
        let _ = writeln!(t, "REPORT={}", s.report.as_secs_f64() / 60.0);
    }
    for section in &s.sections {
        let _ = writeln!(t, "section= {}", section_line(section));
    }
    if !s.time.is_zero() {
        let _ = writeln!(t, "TIME={}", s.time.as_secs_f64() / 3600.0);
    }
    let _ = writeln!(t, "VDISTANCE={}", truth(s.vdistance));
    let kinds: Vec<&str> = s.sections.iter().map(|x| x.kind().name()).collect();
    let _ = writeln!(t, "{KINDS}= {}", kinds.join(" "));
    if let Some(scene) = &s.scene {
        let _ = writeln!(t, "{SCENE}= {scene}");
    }
    if s.stale {
        let _ = writeln!(t, "{STALE}= True");
    }
    let _ = writeln!(t, "BigEndian={}", u8::from(big_endian));
    let _ = writeln!(t, "FORMAT={HOLODECK_FORMAT}\n");
    t
}

/// rholo's `section=` value: origin, the three axis vectors, the grid.
fn section_line(s: &Section) -> String {
    let mut words: Vec<String> = s.origin().to_array().iter().map(|v| v.to_string()).collect();
    for a in s.axes() {
        words.extend(a.to_array().iter().map(|v| v.to_string()));
    }
    words.extend(s.grid().iter().map(|g| g.to_string()));
    words.join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    const RHOLO: &str = "#?RADIANCE\nSOFTWARE= RADIANCE 5.4a test\nCA= 20\nGRID= 0.25\nOBSTRUCTIONS= False\n\
        OCTREE= t.oct\nrender= -ab 1 -ad 256\nREPORT= 5 log.txt\nsection= 0 0 0 2 0 0 0 3 0 0 0 1 5 4 3\n\
        section= 10 0 0 1 0 0 0 1 0 0 0 1\nTIME= 1.5\nVDISTANCE= F\nBigEndian=0\nFORMAT=Holodeck\n\n";

    #[test]
    fn rholos_header_gives_settings_in_radiance_units() {
        let mut bytes = RHOLO.as_bytes().to_vec();
        bytes.extend_from_slice(&[0x54, 1, 0, 0]);
        let h = parse(&bytes).unwrap();
        assert_eq!(h.len as usize, RHOLO.len());
        assert_eq!((h.format.as_deref(), h.big_endian), (Some("Holodeck"), Some(0)));
        let v = h.variables();
        assert_eq!(v.settings.cache_bytes, 20 << 20);
        assert_eq!(v.settings.grid, Some(0.25));
        assert!(!v.settings.obstructions && !v.settings.vdistance);
        assert_eq!(v.settings.time, Duration::from_secs(5400));
        assert_eq!(v.settings.report, Duration::from_secs(300));
        assert_eq!(v.section_lines, 2);
        assert_eq!(
            v.unused,
            ["SOFTWARE= RADIANCE 5.4a test", "OCTREE= t.oct", "render= -ab 1 -ad 256"]
        );
        assert_eq!(v.kinds, None);
    }

    #[test]
    fn what_is_not_a_holodeck_header_is_named() {
        let e = |b: &[u8]| parse(b).unwrap_err().to_string();
        assert!(e(b"HOLODECK").contains("not \"#?RADIANCE\""));
        assert!(e(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n").contains("FORMAT=32-bit_rle_rgbe"));
        assert!(e(b"#?RADIANCE\nGRID= 1\n").contains("no empty line"));
        assert!(e(b"#?RADIANCE\nBigEndian=2\n\n").contains("BigEndian="));
    }

    #[test]
    fn written_headers_read_back_to_the_same_settings() {
        let section = Section::new(
            [0.5, 0.0, -1.0],
            [[6.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 2.5]],
            [12, 8, 5],
            SectionKind::Exterior,
        )
        .unwrap();
        let s = Settings {
            sections: vec![section],
            grid: Some(0.5),
            obstructions: true,
            vdistance: true,
            cache_bytes: 96 << 20,
            diskspace_bytes: 3 << 30,
            time: Duration::from_secs(5400),
            report: Duration::from_secs(120),
            scene: Some("blake3:0123".into()),
            stale: true,
        };
        let text = write(&s, true);
        assert!(
            text.contains("\nsection= 0.5 0 -1 6 0 0 0 4 0 0 0 2.5 12 8 5\n"),
            "{text}"
        );
        let h = parse(text.as_bytes()).unwrap();
        assert_eq!((h.big_endian, h.len as usize), (Some(1), text.len()));
        let v = h.variables();
        assert_eq!(v.settings, Settings { sections: vec![], ..s });
        assert_eq!(v.kinds, Some(vec![SectionKind::Exterior]));
        assert_eq!(v.unused.len(), 1, "{:?}", v.unused);
    }
}
