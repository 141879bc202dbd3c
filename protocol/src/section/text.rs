//! The one-line text form of a [`SectionSpec`], as written in a holodeck's
//! settings header, in settings files and on the command line:
//! `interior origin=0,0,0 x=6,0,0 y=0,4,0 z=0,0,2.5 grid=24,16,10`, where
//! `grid=` may give way to `beams=N` or be left out. Numbers print as the
//! shortest text that reads back to the same value.

use std::fmt;
use std::str::FromStr;

use super::{SectionError, SectionField, SectionKind, SectionSpec};
use crate::depth::DepthCoding;

/// A section line that does not describe a valid section.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SectionTextError {
    /// The first word is not `interior` or `exterior`.
    #[error("section must start with interior or exterior, not {0:?}")]
    Kind(Option<String>),
    /// A word without `=`.
    #[error("{0:?} is not key=value")]
    NotKeyValue(String),
    /// A key other than origin, x, y, z, grid and beams.
    #[error("unknown section field {0:?} (expected origin, x, y, z, grid, beams, depth)")]
    UnknownField(String),
    /// A value that is not three comma-separated numbers.
    #[error("{}{text} is not three comma-separated numbers", key.text_key())]
    NotThreeNumbers {
        /// The key.
        key: SectionField,
        /// Its value as written.
        text: String,
    },
    /// A grid size that is not a whole number of cells.
    #[error("grid size {0} is not a whole number of cells")]
    GridNotWhole(f64),
    /// A depth coding other than holodeck and radiance.
    #[error("depth={0} is not a depth coding (holodeck or radiance)")]
    Depth(String),
    /// A beam count that is not a positive whole number.
    #[error("beams={0} is not a positive whole number")]
    Beams(String),
    /// A key given twice.
    #[error("section gives {}{} twice", .0.text_key(), if matches!(.0, SectionField::Axis(_)) { " (an axis)" } else { "" })]
    Repeated(SectionField),
    /// A required key is missing.
    #[error("section has no {}", missing(*.0))]
    Missing(SectionField),
    /// The numbers do not make a valid section; the message names the key
    /// the problem is in, where it is in one.
    #[error("{key}{0}", key = .0.field().map(|f| format!("{}: ", f.text_key())).unwrap_or_default())]
    Section(SectionError),
}

impl From<SectionError> for SectionTextError {
    fn from(e: SectionError) -> Self {
        SectionTextError::Section(e)
    }
}

fn missing(key: SectionField) -> String {
    match key {
        SectionField::Axis(_) => format!("{} axis", key.text_key()),
        _ => key.text_key().to_string(),
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

fn parse_grid(s: &str) -> Result<[u16; 3], SectionTextError> {
    let g = parse_vec3(SectionField::Grid, s)?;
    let mut out = [0u16; 3];
    for (k, x) in g.iter().enumerate() {
        if x.fract() != 0.0 || !(0.0..=65535.0).contains(x) {
            return Err(SectionTextError::GridNotWhole(*x));
        }
        out[k] = *x as u16;
    }
    Ok(out)
}

fn set<T>(slot: &mut Option<T>, key: SectionField, value: T) -> Result<(), SectionTextError> {
    if slot.replace(value).is_some() {
        return Err(SectionTextError::Repeated(key));
    }
    Ok(())
}

impl FromStr for SectionSpec {
    type Err = SectionTextError;

    /// Parses a section line; the numbers are checked when it is resolved.
    fn from_str(text: &str) -> Result<SectionSpec, SectionTextError> {
        let mut words = text.split_whitespace();
        let kind = match words.next() {
            Some("interior") => SectionKind::Interior,
            Some("exterior") => SectionKind::Exterior,
            other => return Err(SectionTextError::Kind(other.map(str::to_string))),
        };
        let (mut origin, mut axes, mut grid, mut beams, mut depth) = (None, [None; 3], None, None, None);
        for w in words {
            let (k, v) = w
                .split_once('=')
                .ok_or_else(|| SectionTextError::NotKeyValue(w.to_string()))?;
            match k {
                "origin" => set(&mut origin, SectionField::Origin, parse_vec3(SectionField::Origin, v)?)?,
                "x" | "y" | "z" => {
                    let a = usize::from(k.as_bytes()[0] - b'x');
                    let key = SectionField::Axis(a);
                    set(&mut axes[a], key, parse_vec3(key, v)?)?;
                }
                "grid" => set(&mut grid, SectionField::Grid, parse_grid(v)?)?,
                "beams" => {
                    let n = v
                        .parse::<u64>()
                        .ok()
                        .filter(|n| *n > 0)
                        .ok_or_else(|| SectionTextError::Beams(v.to_string()))?;
                    set(&mut beams, SectionField::Beams, n)?;
                }
                "depth" => {
                    let coding = DepthCoding::from_name(v).ok_or_else(|| SectionTextError::Depth(v.to_string()))?;
                    set(&mut depth, SectionField::Depth, coding)?;
                }
                other => return Err(SectionTextError::UnknownField(other.to_string())),
            }
        }
        let origin = origin.ok_or(SectionTextError::Missing(SectionField::Origin))?;
        let axis = |k: usize| axes[k].ok_or(SectionTextError::Missing(SectionField::Axis(k)));
        Ok(SectionSpec {
            kind,
            origin,
            axes: [axis(0)?, axis(1)?, axis(2)?],
            grid,
            beams,
            depth,
        })
    }
}

struct Vec3Text([f64; 3]);

impl fmt::Display for Vec3Text {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // `{}` prints the shortest text that reads back to the same f64.
        write!(f, "{},{},{}", self.0[0], self.0[1], self.0[2])
    }
}

impl fmt::Display for SectionSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} origin={} x={} y={} z={}",
            self.kind.name(),
            Vec3Text(self.origin),
            Vec3Text(self.axes[0]),
            Vec3Text(self.axes[1]),
            Vec3Text(self.axes[2])
        )?;
        if let Some([w, d, h]) = self.grid {
            write!(f, " grid={w},{d},{h}")?;
        }
        if let Some(b) = self.beams {
            write!(f, " beams={b}")?;
        }
        if let Some(d) = self.depth {
            write!(f, " depth={}", d.name())?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Section;
    use proptest::prelude::*;

    #[test]
    fn lines_name_what_is_wrong() {
        let err = |t: &str| t.parse::<SectionSpec>().unwrap_err().to_string();
        assert!(err("inside origin=0,0,0").contains("interior or exterior"));
        assert!(err("interior origin=0,0").contains("origin=0,0 is not three"));
        assert!(err("interior origin=0,0,0 x=1,0,0 y=0,1,0").contains("no z= axis"));
        assert!(err("interior origin=0,0,0 x=1,0,0 x=2,0,0 y=0,1,0 z=0,0,1").contains("x= (an axis) twice"));
        assert!(err("interior origin=0,0,0 x=1,0,0 y=0,1,0 z=0,0,1 grid=1.5,2,2").contains("1.5"));
        assert!(err("interior origin=0,0,0 x=1,0,0 y=0,1,0 z=0,0,1 beams=0").contains("beams=0"));
        assert!(err("interior origin=0,0,0 x=1,0,0 y=0,1,0 z=0,0,1 cells=3").contains("cells"));
        assert!(
            err("interior origin=0,0,0 x=1,0,0 y=0,1,0 z=0,0,1 depth=radiance depth=holodeck").contains("depth= twice")
        );
        assert!(err("interior origin=0,0,0 x=1,0,0 y=0,1,0 z=0,0,1 depth=metric").contains("depth=metric"));
        let spec: SectionSpec = "interior origin=0,0,0 x=1,0,0 y=0,1,0 z=0,0,1 grid=4,4,4 beams=9"
            .parse()
            .unwrap();
        let e = SectionTextError::from(spec.resolve(None, None).unwrap_err()).to_string();
        assert!(e.starts_with("grid=: "), "{e}");
    }

    proptest! {
        #[test]
        fn every_section_prints_a_line_that_reads_back_to_it(
            origin in proptest::array::uniform3(-1e3f64..1e3),
            size in proptest::array::uniform3(0.01f64..100.0),
            shear in -0.5f64..0.5,
            grid in proptest::array::uniform3(1u16..20),
            exterior: bool,
            radiance: bool,
        ) {
            let kind = if exterior { SectionKind::Exterior } else { SectionKind::Interior };
            let axes = [[size[0], 0.0, 0.0], [size[1] * shear, size[1], 0.0], [0.0, size[2] * shear, size[2]]];
            let Ok(s) = Section::new(origin, axes, grid, kind) else { return Ok(()) };
            let s = if radiance { s.with_depth_coding(DepthCoding::Radiance) } else { s };
            let line = s.spec().to_string();
            let back: SectionSpec = line.parse().unwrap();
            prop_assert_eq!(back.resolve(None, None).unwrap(), s);
        }
    }
}
