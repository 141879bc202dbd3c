//! Sections of built-in scenes. A scene file's `[[section]]` tables are the
//! protocol's [`SectionSpec`], the one description every reader shares.

use holodeck_protocol::{Section, SectionError, SectionKind, SectionSpec};

/// An axis-aligned section with its low corner at `origin` and edge lengths
/// `size` (world meters), with about [`holodeck_protocol::DEFAULT_BEAMS`] beams.
pub fn box_section(kind: SectionKind, origin: [f64; 3], size: [f64; 3]) -> Result<Section, SectionError> {
    let [dx, dy, dz] = size;
    SectionSpec {
        kind,
        origin,
        axes: [[dx, 0.0, 0.0], [0.0, dy, 0.0], [0.0, 0.0, dz]],
        grid: None,
        beams: None,
        depth: None,
    }
    .resolve(None, None)
}

/// The key a section error is about, as a scene file's table writes it
/// (`axes[1]: `), or nothing.
pub(crate) fn toml_key_prefix(e: &SectionError) -> String {
    e.field().map(|f| format!("{}: ", f.toml_key())).unwrap_or_default()
}

#[cfg(test)]
mod tests {
    use super::*;
    use holodeck_protocol::{SectionField, DEFAULT_BEAMS};

    #[test]
    fn a_scene_files_table_gets_the_default_grid_and_its_errors_name_the_key() {
        let t: SectionSpec = toml::from_str("origin = [0, 0, 0]\naxes = [[6, 0, 0], [0, 4, 0], [0, 0, 2.5]]").unwrap();
        let s = t.resolve(None, None).unwrap();
        assert_eq!(s.kind(), SectionKind::Interior);
        let n = f64::from(s.beam_count()) / DEFAULT_BEAMS as f64;
        assert!((0.66..1.5).contains(&n), "{n}");
        let nan = SectionSpec {
            axes: [[1.0, 0.0, 0.0], [0.0, f64::NAN, 0.0], [0.0, 0.0, 1.0]],
            grid: Some([2, 2, 2]),
            ..t
        };
        let e = nan.resolve(None, None).unwrap_err();
        assert_eq!(e.field(), Some(SectionField::Axis(1)));
        assert!(toml_key_prefix(&e).starts_with("axes[1]: "), "{e}");
        let room = box_section(SectionKind::Interior, [0.5, 0.5, 1.2], [5.0, 3.0, 1.0]).unwrap();
        assert_eq!(room.origin().to_array(), [0.5, 0.5, 1.2]);
    }
}
