//! Reading and writing pictures: Radiance RGBE `.hdr` (all of the range) and
//! 8-bit sRGB `.png` (after an exposure and a clamp, or tone mapped).

use std::path::{Path, PathBuf};

use image::codecs::hdr::HdrEncoder;
use image::Rgb;

use holodeck_protocol::Picture;

/// A picture that could not be written.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct ImageError {
    /// The file.
    pub path: PathBuf,
    /// Why.
    pub message: String,
}

fn err(path: &Path, e: impl std::fmt::Display) -> ImageError {
    ImageError {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Reads a picture as linear radiance: a Radiance `.hdr` as it is, an 8-bit
/// image decoded from sRGB.
pub fn read_picture(path: &Path) -> Result<Picture, ImageError> {
    let img = image::open(path).map_err(|e| err(path, e))?;
    let hdr = matches!(
        img,
        image::DynamicImage::ImageRgb32F(_) | image::DynamicImage::ImageRgba32F(_)
    );
    let rgb = img.into_rgb32f();
    let (width, height) = (rgb.width() as usize, rgb.height() as usize);
    let pixels = rgb
        .pixels()
        .map(|p| {
            let c = if hdr {
                p.0
            } else {
                // The image crate hands 8-bit values over as v/255: undo the sRGB curve.
                p.0.map(|v| crate::tonemap::decode_srgb((v * 255.0).round() as u8))
            };
            glam::Vec3::from_array(c)
        })
        .collect();
    Ok(Picture { width, height, pixels })
}

/// Writes a Radiance RGBE picture.
pub fn write_hdr(p: &Picture, path: &Path) -> Result<(), ImageError> {
    write_hdr_view(p, path, None)
}

/// Writes a Radiance RGBE picture with its view in a `VIEW=` header line,
/// as Radiance's renderers do (rpict, rhpict and rvu read it back). The
/// picture is encoded in memory and written whole, so a full disk is an
/// error rather than a truncated file.
pub fn write_hdr_view(p: &Picture, path: &Path, view: Option<&holodeck_protocol::View>) -> Result<(), ImageError> {
    // The encoder's exponent goes wrong for values below the shared exponent's
    // range (a subnormal comes out near 1e38): like Radiance, a pixel whose
    // largest channel is below 1e-32 is written as black.
    let pixels: Vec<Rgb<f32>> = p
        .pixels
        .iter()
        .map(|c| {
            let c = c.max(glam::Vec3::ZERO);
            Rgb(if c.max_element() < 1e-32 {
                [0.0; 3]
            } else {
                c.to_array()
            })
        })
        .collect();
    let mut bytes = Vec::new();
    HdrEncoder::new(&mut bytes)
        .encode(&pixels, p.width, p.height)
        .map_err(|e| err(path, e))?;
    if let Some(view) = view {
        // After the magic line `#?RADIANCE`, among the header's lines.
        let at = bytes.iter().position(|&b| b == b'\n').map_or(0, |i| i + 1);
        let line = format!("VIEW= {}\n", view.to_spec());
        bytes.splice(at..at, line.into_bytes());
    }
    write_whole(path, &bytes)
}

/// Writes `bytes` to `path` whole or not at all: to a temporary name, then
/// renamed over it (a device such as /dev/stdout is written directly), so a
/// full disk fails the write and leaves no truncated picture.
fn write_whole(path: &Path, bytes: &[u8]) -> Result<(), ImageError> {
    use std::io::Write;
    if std::fs::metadata(path).is_ok_and(|m| !m.is_file()) {
        return std::fs::write(path, bytes).map_err(|e| err(path, e));
    }
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".{}.tmp", std::process::id()));
    let tmp = path.with_file_name(name);
    let written = (|| -> std::io::Result<()> {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(err(path, e));
    }
    Ok(())
}

fn srgb(v: f32) -> u8 {
    let v = v.clamp(0.0, 1.0);
    let s = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// Writes an 8-bit sRGB picture after multiplying by `exposure`.
pub fn write_png(p: &Picture, path: &Path, exposure: f32) -> Result<(), ImageError> {
    let bytes: Vec<u8> = p
        .pixels
        .iter()
        .flat_map(|c| (*c * exposure).to_array().map(srgb))
        .collect();
    write_rgb8(path, p.width, p.height, &bytes)
}

/// Writes 8-bit RGB bytes (rows from the top, as `ToneMap::apply` makes
/// them) as a PNG whatever the file's extension. A buffer that is not
/// exactly `3 * width * height` bytes is an error, not a panic in the encoder.
pub fn write_rgb8(path: &Path, width: usize, height: usize, rgb: &[u8]) -> Result<(), ImageError> {
    let (w, h) = match (u32::try_from(width), u32::try_from(height)) {
        (Ok(w), Ok(h)) => (w, h),
        _ => return Err(err(path, format!("{width}x{height} is too large for a PNG"))),
    };
    if width.checked_mul(height).and_then(|n| n.checked_mul(3)) != Some(rgb.len()) {
        let message = format!("{} bytes for a {width}x{height} RGB picture", rgb.len());
        return Err(err(path, message));
    }
    // Encoded in memory and written whole: a full disk is an error, never
    // a truncated file reported as written.
    let mut png = std::io::Cursor::new(Vec::new());
    image::write_buffer_with_format(&mut png, rgb, w, h, image::ColorType::Rgb8, image::ImageFormat::Png)
        .map_err(|e| err(path, e))?;
    write_whole(path, &png.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn hdr_round_trips_and_values_below_its_range_come_back_black() {
        let dir = tempfile_dir();
        let path = dir.join("tiny.hdr");
        let p = Picture {
            width: 4,
            height: 1,
            pixels: vec![
                Vec3::new(1e-39, 9e-40, 7e-40),
                Vec3::splat(1e-35),
                Vec3::new(0.25, 3.0, 1500.0),
                Vec3::new(-1.0, 0.5, 0.0),
            ],
        };
        write_hdr(&p, &path).unwrap();
        let q = read_picture(&path).unwrap();
        assert_eq!((q.width, q.height), (4, 1));
        assert_eq!(q.pixels[0], Vec3::ZERO);
        assert_eq!(q.pixels[1], Vec3::ZERO);
        for (a, b) in q.pixels[2].to_array().into_iter().zip(p.pixels[2].to_array()) {
            assert!((a - b).abs() <= 0.01 * 1500.0, "{a} {b}");
        }
        assert!((q.pixels[2].z / 1500.0 - 1.0).abs() < 0.01);
        assert_eq!(q.pixels[3].x, 0.0);
        assert!((q.pixels[3].y - 0.5).abs() < 0.005);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn hdr_pictures_carry_their_view_and_a_full_disk_is_an_error() {
        let dir = tempfile_dir();
        let path = dir.join("view.hdr");
        let p = Picture {
            width: 2,
            height: 2,
            pixels: vec![Vec3::splat(0.5); 4],
        };
        let view = holodeck_protocol::View::parse("-vtv -vp 1 2 3 -vd 0 1 0 -vu 0 0 1 -vh 50 -vv 40 -vo 0.5").unwrap();
        write_hdr_view(&p, &path, Some(&view)).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        let header = String::from_utf8_lossy(&bytes[..64.min(bytes.len())]).into_owned();
        let text = String::from_utf8_lossy(&bytes);
        let line = text.lines().find(|l| l.starts_with("VIEW= ")).expect("a VIEW= line");
        assert_eq!(holodeck_protocol::View::parse(line).unwrap(), view, "{header}");
        assert!(text.starts_with("#?RADIANCE\nVIEW= "), "{header}");
        assert_eq!(read_picture(&path).unwrap().pixels.len(), 4, "readers skip the line");
        // /dev/full fails every write with ENOSPC, as a full disk does.
        let full = Path::new("/dev/full");
        if full.exists() {
            assert!(write_hdr(&p, full).is_err());
            assert!(write_png(&p, full, 1.0).is_err());
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    fn tempfile_dir() -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("holodeck-image-io-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }
}
