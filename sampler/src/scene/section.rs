//! A `[[section]]` table of a scene file: a holodeck section as written by
//! people (kind, origin, axes, and a grid or a target beam count), and its
//! conversion to a validated [`Section`].

use holodeck_protocol::{grid_for_beam_count, Section, SectionError, SectionKind};
use serde::{Deserialize, Serialize};

/// Beam count aimed at when a section gives neither `grid` nor `beams`.
pub const DEFAULT_BEAMS: u64 = 150_000;

/// Why a `[[section]]` table is not a valid section.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SectionTableError {
    /// Both `grid` and `beams` were given.
    #[error("give grid or beams, not both")]
    GridAndBeams,
    /// The numbers do not make a valid section; the message names the key
    /// the problem is in, where it is in one.
    #[error("{key}{0}", key = .0.field().map(|f| format!("{}: ", f.toml_key())).unwrap_or_default())]
    Section(SectionError),
}

impl From<SectionError> for SectionTableError {
    fn from(e: SectionError) -> Self {
        SectionTableError::Section(e)
    }
}

/// A section as written in a scene file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SectionTable {
    /// `interior` (looked out of; the default) or `exterior` (looked into).
    #[serde(default = "interior")]
    pub kind: SectionKind,
    /// World corner, meters.
    pub origin: [f64; 3],
    /// The three edge vectors from the origin, meters.
    pub axes: [[f64; 3]; 3],
    /// Cells along each axis (1..=255); excludes `beams`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub grid: Option<[u16; 3]>,
    /// Target beam count for an automatic grid (default 150,000); excludes `grid`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beams: Option<u64>,
}

fn interior() -> SectionKind {
    SectionKind::Interior
}

impl SectionTable {
    /// The table of an existing section, with its explicit grid.
    pub fn from_section(s: &Section) -> SectionTable {
        let spec = s.spec();
        SectionTable {
            kind: spec.kind,
            origin: spec.origin,
            axes: spec.axes,
            grid: Some(spec.grid),
            beams: None,
        }
    }

    /// The validated section; the error says what is wrong, and in which key.
    pub fn to_section(&self) -> Result<Section, SectionTableError> {
        let grid = match (self.grid, self.beams) {
            (Some(_), Some(_)) => return Err(SectionTableError::GridAndBeams),
            (Some(g), None) => g,
            (None, beams) => grid_for_beam_count(self.axes, beams.unwrap_or(DEFAULT_BEAMS))?,
        };
        Ok(Section::new(self.origin, self.axes, grid, self.kind)?)
    }
}

/// An axis-aligned section with its low corner at `origin` and edge lengths
/// `size` (world meters), with about [`DEFAULT_BEAMS`] beams.
pub fn box_section(kind: SectionKind, origin: [f64; 3], size: [f64; 3]) -> Result<Section, SectionTableError> {
    let [dx, dy, dz] = size;
    SectionTable {
        kind,
        origin,
        axes: [[dx, 0.0, 0.0], [0.0, dy, 0.0], [0.0, 0.0, dz]],
        grid: None,
        beams: None,
    }
    .to_section()
}

#[cfg(test)]
mod tests {
    use super::*;
    use holodeck_protocol::SectionField;

    #[test]
    fn default_grid_aims_at_150k_beams_and_grid_round_trips() {
        let t: SectionTable = toml::from_str("origin = [0, 0, 0]\naxes = [[6, 0, 0], [0, 4, 0], [0, 0, 2.5]]").unwrap();
        let s = t.to_section().unwrap();
        assert_eq!(s.kind(), SectionKind::Interior);
        let n = f64::from(s.beam_count());
        assert!((100_000.0..225_000.0).contains(&n), "{n}");
        let back = SectionTable::from_section(&s).to_section().unwrap();
        assert_eq!(back, s);
        let both = SectionTable {
            beams: Some(1000),
            ..SectionTable::from_section(&s)
        };
        assert_eq!(both.to_section(), Err(SectionTableError::GridAndBeams));
        let flat = SectionTable {
            axes: [[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 1.0]],
            ..t.clone()
        };
        assert!(
            matches!(
                flat.to_section(),
                Err(SectionTableError::Section(SectionError::Degenerate(_)))
            ),
            "{:?}",
            flat.to_section()
        );
        let nan = SectionTable {
            axes: [[1.0, 0.0, 0.0], [0.0, f64::NAN, 0.0], [0.0, 0.0, 1.0]],
            grid: Some([2, 2, 2]),
            ..t
        };
        let e = nan.to_section().unwrap_err();
        assert!(
            matches!(&e, SectionTableError::Section(s) if s.field() == Some(SectionField::Axis(1))),
            "{e:?}"
        );
        assert!(e.to_string().starts_with("axes[1]: "), "{e}");
        assert!(toml::from_str::<SectionTable>(
            "origin = [0, 0, 0]\naxes = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\nsize = 3"
        )
        .unwrap_err()
        .to_string()
        .contains("size"));
    }
}
