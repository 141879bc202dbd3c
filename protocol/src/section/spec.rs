//! [`SectionSpec`]: the one description of a section, as people write it (a
//! scene file's `[[section]]` table, a control file, a settings line, an
//! imported Radiance holodeck) and as it travels on the wire. It may leave the
//! grid to be derived; [`SectionSpec::resolve`] makes the validated
//! [`Section`].

use serde::{Deserialize, Serialize};

use super::{grid_for_beam_count, grid_for_length, Section, SectionError, SectionKind};
use crate::depth::DepthCoding;

/// Beam count aimed at when a description gives neither a grid nor a cell
/// length: inside the paper's advice of 50k–500k.
pub const DEFAULT_BEAMS: u64 = 150_000;

/// A section as described: kind, corner, edge vectors, and a grid, or a target
/// beam count, or neither (the grid then follows a default).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SectionSpec {
    /// `interior` (looked out of; the default) or `exterior` (looked into).
    #[serde(default = "interior")]
    pub kind: SectionKind,
    /// World position of the corner at unit coordinates (0,0,0).
    pub origin: [f64; 3],
    /// The three edge vectors from the origin, in world units.
    pub axes: [[f64; 3]; 3],
    /// Cells along each axis (1..=255); excludes `beams`.
    #[serde(default)]
    pub grid: Option<[u16; 3]>,
    /// Target beam count for a derived grid; excludes `grid`.
    #[serde(default)]
    pub beams: Option<u64>,
    /// How the rays' depth codes map to distances; this program's own when
    /// absent, Radiance's for sections imported from Radiance.
    #[serde(default)]
    pub depth: Option<DepthCoding>,
}

fn interior() -> SectionKind {
    SectionKind::Interior
}

impl SectionSpec {
    /// A description with an explicit grid.
    pub fn new(kind: SectionKind, origin: [f64; 3], axes: [[f64; 3]; 3], grid: [u16; 3]) -> SectionSpec {
        SectionSpec {
            kind,
            origin,
            axes,
            grid: Some(grid),
            beams: None,
            depth: None,
        }
    }

    /// The validated section. Its grid is the one given, else one aiming at
    /// the `beams` given, else one of cells about `grid_length` long (Radiance's
    /// GRID), else one aiming at `default_beams`, else at [`DEFAULT_BEAMS`].
    /// The error names the field at fault where there is one.
    pub fn resolve(&self, grid_length: Option<f64>, default_beams: Option<u64>) -> Result<Section, SectionError> {
        let grid = match (self.grid, self.beams, grid_length) {
            (Some(_), Some(_), _) => return Err(SectionError::GridAndBeams),
            (Some(g), None, _) => g,
            (None, Some(b), _) => grid_for_beam_count(self.axes, b)?,
            (None, None, Some(len)) => grid_for_length(self.axes, len)?,
            (None, None, None) => grid_for_beam_count(self.axes, default_beams.unwrap_or(DEFAULT_BEAMS))?,
        };
        let section = Section::new(self.origin, self.axes, grid, self.kind)?;
        Ok(section.with_depth_coding(self.depth.unwrap_or_default()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::SectionField;

    const BOX: [[f64; 3]; 3] = [[6.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 2.5]];

    fn spec() -> SectionSpec {
        SectionSpec {
            kind: SectionKind::Interior,
            origin: [0.0; 3],
            axes: BOX,
            grid: None,
            beams: None,
            depth: None,
        }
    }

    #[test]
    fn the_grid_comes_from_the_first_rule_that_applies() {
        let explicit = SectionSpec {
            grid: Some([3, 2, 1]),
            ..spec()
        };
        assert_eq!(explicit.resolve(Some(0.1), Some(9)).unwrap().grid(), [3, 2, 1]);
        let beams = SectionSpec {
            beams: Some(20_000),
            ..spec()
        };
        let by_beams = beams.resolve(Some(0.1), None).unwrap();
        let ratio = by_beams.beam_count() as f64 / 20_000.0;
        assert!((0.7..1.4).contains(&ratio), "{}", by_beams.beam_count());
        assert_eq!(spec().resolve(Some(0.5), Some(9)).unwrap().grid(), [12, 8, 5]);
        let default = spec().resolve(None, None).unwrap().beam_count() as f64 / DEFAULT_BEAMS as f64;
        assert!((0.7..1.4).contains(&default), "{default}");
        let asked = spec().resolve(None, Some(1000)).unwrap();
        assert!(asked.beam_count() < 2000, "{}", asked.beam_count());
    }

    #[test]
    fn grid_and_beams_together_are_refused_naming_the_grid() {
        let both = SectionSpec {
            grid: Some([3, 2, 1]),
            beams: Some(100),
            ..spec()
        };
        let e = both.resolve(None, None).unwrap_err();
        assert_eq!(e, SectionError::GridAndBeams);
        assert_eq!(e.field(), Some(SectionField::Grid));
    }

    #[test]
    fn a_section_round_trips_through_its_description_in_toml_and_postcard() {
        let s = Section::new([1.0, -2.0, 0.5], BOX, [7, 5, 3], SectionKind::Exterior).unwrap();
        let text = toml::to_string(&s.spec()).unwrap();
        assert!(!text.contains("beams"), "{text}");
        let back: SectionSpec = toml::from_str(&text).unwrap();
        assert_eq!(back.resolve(None, None).unwrap(), s);
        let bytes = postcard::to_allocvec(&s).unwrap();
        assert_eq!(postcard::from_bytes::<Section>(&bytes).unwrap(), s);
        // A section of Radiance depth codes says so, and keeps saying so.
        let rad = s.clone().with_depth_coding(DepthCoding::Radiance);
        let text = toml::to_string(&rad.spec()).unwrap();
        assert!(text.contains("depth = \"radiance\""), "{text}");
        let back: SectionSpec = toml::from_str(&text).unwrap();
        assert_eq!(back.resolve(None, None).unwrap(), rad);
        let bytes = postcard::to_allocvec(&rad).unwrap();
        assert_eq!(postcard::from_bytes::<Section>(&bytes).unwrap(), rad);
        assert_ne!(rad, s);
        // Written by hand: the kind defaults to interior, unknown keys are refused.
        let hand: SectionSpec =
            toml::from_str("origin = [0, 0, 0]\naxes = [[6, 0, 0], [0, 4, 0], [0, 0, 2.5]]").unwrap();
        assert_eq!(hand, spec());
        assert!(toml::from_str::<SectionSpec>(
            "origin = [0, 0, 0]\naxes = [[6, 0, 0], [0, 4, 0], [0, 0, 2.5]]\ncells = 3"
        )
        .is_err());
    }
}
