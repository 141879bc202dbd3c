//! Writing frames: Radiance `.hdr` keeps all of the radiance (no tone
//! mapping, nothing lost); `.png` is tone mapped with the display's histogram.

use std::path::Path;

use holodeck_protocol::Picture;

use crate::image_io::{self, ImageError};
use crate::tonemap::{DisplayRange, Histogram, ToneMap, ToneMode};

/// A tone-mapping mode that does not parse.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ToneError {
    /// Not one of the modes.
    #[error("tone mapping {0:?}: use camera, human, exposure:X or exposure:auto")]
    UnknownMode(String),
    /// `exposure:X` with an X that is not a positive finite number.
    #[error("exposure {0:?} is not a positive number")]
    BadExposure(String),
}

/// Parses a tone-mapping mode: `camera`, `human`, or `exposure:X` (a linear
/// multiplier; `exposure:auto` puts the log-average at middle grey).
pub fn parse_tone(s: &str, picture_hint: Option<&Picture>) -> Result<ToneMode, ToneError> {
    match s {
        "camera" => Ok(ToneMode::Camera),
        "human" => Ok(ToneMode::Human),
        _ => {
            let Some(x) = s.strip_prefix("exposure:") else {
                return Err(ToneError::UnknownMode(s.to_string()));
            };
            if x == "auto" {
                return Ok(ToneMode::Exposure(picture_hint.map_or(1.0, Picture::auto_exposure)));
            }
            match x.parse::<f32>() {
                Ok(v) if v.is_finite() && v > 0.0 => Ok(ToneMode::Exposure(v)),
                _ => Err(ToneError::BadExposure(x.to_string())),
            }
        }
    }
}

/// True when `path` names a Radiance picture (written linear).
pub fn is_hdr(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("hdr") || e.eq_ignore_ascii_case("pic"))
}

/// Writes `picture` to `path`: linear RGBE for `.hdr`/`.pic` (with `view`
/// in its `VIEW=` line), else a PNG tone mapped by `mode` over `histogram`
/// (the samples the display has seen).
pub fn save(
    picture: &Picture,
    histogram: &Histogram,
    mode: ToneMode,
    path: &Path,
    view: Option<&holodeck_protocol::View>,
) -> Result<(), ImageError> {
    if is_hdr(path) {
        return image_io::write_hdr_view(picture, path, view);
    }
    let map = ToneMap::new(histogram, mode, DisplayRange::default());
    image_io::write_rgb8(path, picture.width, picture.height, &map.apply(picture))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tone_modes_parse_and_bad_ones_say_why() {
        assert_eq!(parse_tone("camera", None), Ok(ToneMode::Camera));
        assert_eq!(parse_tone("human", None), Ok(ToneMode::Human));
        assert_eq!(parse_tone("exposure:2", None), Ok(ToneMode::Exposure(2.0)));
        let p = Picture {
            width: 1,
            height: 1,
            pixels: vec![glam::Vec3::splat(0.36)],
        };
        let Ok(ToneMode::Exposure(auto)) = parse_tone("exposure:auto", Some(&p)) else {
            panic!("auto exposure")
        };
        assert!((auto - 0.5).abs() < 1e-6, "0.18 / 0.36 = {auto}");
        assert_eq!(
            parse_tone("exposure:-1", None),
            Err(ToneError::BadExposure("-1".into()))
        );
        let film = parse_tone("film", None).unwrap_err();
        assert_eq!(film, ToneError::UnknownMode("film".into()));
        assert!(film.to_string().contains("camera, human"), "{film}");
    }

    #[test]
    fn hdr_frames_keep_the_radiance_and_png_frames_are_tone_mapped() {
        let dir = std::env::temp_dir().join(format!("holodeck-output-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = Picture {
            width: 2,
            height: 1,
            pixels: vec![glam::Vec3::new(0.01, 0.02, 0.03), glam::Vec3::splat(500.0)],
        };
        let hist = Histogram::from_picture(&p);
        save(&p, &hist, ToneMode::Camera, &dir.join("a.hdr"), None).unwrap();
        save(&p, &hist, ToneMode::Camera, &dir.join("a.png"), None).unwrap();
        let hdr = image::open(dir.join("a.hdr")).unwrap().into_rgb32f();
        let big = hdr.get_pixel(1, 0).0;
        assert!((big[0] - 500.0).abs() / 500.0 < 0.01, "{big:?}");
        let png = image::open(dir.join("a.png")).unwrap().into_rgb8();
        let (dark, bright) = (png.get_pixel(0, 0).0, png.get_pixel(1, 0).0);
        assert!(bright[0] > dark[0] && dark[2] > 0, "{dark:?} {bright:?}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
