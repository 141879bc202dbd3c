//! A comparison sheet: pictures of one view side by side, tone mapped
//! alike (by the reference's histogram, so brightness differences are the
//! pictures' own), each captioned with its name and its error.

use std::path::Path;

use anyhow::{anyhow, bail, Context, Result};
use holodeck_display::tonemap::ToneMap;
use holodeck_protocol::Picture;
use plotters::prelude::*;

/// One panel of a sheet: a picture (or none, when its method could not
/// run here) and the caption under it.
pub struct Panel<'a> {
    /// The picture.
    pub picture: Option<&'a Picture>,
    /// Its caption (at most two lines).
    pub caption: String,
}

/// Space between panels, in pixels.
const GAP: usize = 6;
/// Height of the caption row, in pixels.
const CAPTION: usize = 30;

/// Writes the panels side by side to the PNG `path`, all of one size,
/// tone mapped by `tone`.
pub fn write(path: &Path, panels: &[Panel<'_>], tone: &ToneMap) -> Result<()> {
    let Some((w, h)) = panels.iter().find_map(|p| p.picture.map(|q| (q.width, q.height))) else {
        bail!("a comparison sheet needs at least one picture");
    };
    if let Some(p) = panels
        .iter()
        .flat_map(|p| p.picture)
        .find(|q| (q.width, q.height) != (w, h))
    {
        bail!(
            "pictures of one sheet differ in size: {}x{} and {w}x{h}",
            p.width,
            p.height
        );
    }
    let n = panels.len();
    let (sheet_w, sheet_h) = (n * w + (n + 1) * GAP, h + CAPTION + 2 * GAP);
    let mut rgb = vec![255u8; sheet_w * sheet_h * 3];
    for (i, panel) in panels.iter().enumerate() {
        let x0 = GAP + i * (w + GAP);
        let pixels = match panel.picture {
            Some(p) => tone.apply(p),
            // A method that could not run: a grey panel.
            None => vec![200u8; w * h * 3],
        };
        for row in 0..h {
            let to = ((GAP + row) * sheet_w + x0) * 3;
            rgb[to..to + w * 3].copy_from_slice(&pixels[row * w * 3..(row + 1) * w * 3]);
        }
    }
    holodeck_cli::chart::register_font();
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (sheet_w as u32, sheet_h as u32)).into_drawing_area();
        let style = ("sans-serif", 12).into_font().color(&BLACK);
        for (i, panel) in panels.iter().enumerate() {
            let x = (GAP + i * (w + GAP)) as i32;
            // A caption may take two lines.
            for (k, line) in panel.caption.lines().take(2).enumerate() {
                let y = (GAP + h + 3 + 13 * k) as i32;
                root.draw_text(line, &style, (x, y)).map_err(|e| anyhow!("{e}"))?;
            }
        }
        root.present().map_err(|e| anyhow!("{e}"))?;
    }
    image::RgbImage::from_raw(sheet_w as u32, sheet_h as u32, rgb)
        .context("sheet buffer size")?
        .save(path)
        .with_context(|| format!("writing {}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use holodeck_display::tonemap::ToneMode;

    fn picture(w: usize, h: usize, v: f32) -> Picture {
        Picture {
            width: w,
            height: h,
            pixels: vec![Vec3::splat(v); w * h],
        }
    }

    #[test]
    fn panels_sit_side_by_side_with_captions_below() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (picture(40, 30, 1.0), picture(40, 30, 0.0));
        let tone = ToneMap::from_picture(&a, ToneMode::Camera);
        let path = dir.path().join("sheet.png");
        let panels = [
            Panel {
                picture: Some(&a),
                caption: "reference".into(),
            },
            Panel {
                picture: Some(&b),
                caption: "black\n1.000".into(),
            },
            Panel {
                picture: None,
                caption: "none".into(),
            },
        ];
        write(&path, &panels, &tone).unwrap();
        let img = image::open(&path).unwrap().to_rgb8();
        assert_eq!(
            img.dimensions(),
            (3 * 40 + 4 * GAP as u32, 30 + CAPTION as u32 + 2 * GAP as u32)
        );
        let at = |x: usize, y: usize| img.get_pixel(x as u32, y as u32).0;
        let mid = GAP + 15;
        assert!(
            at(GAP + 20, mid)[0] > 40,
            "the lit picture is lit: {:?}",
            at(GAP + 20, mid)
        );
        assert_eq!(at(2 * GAP + 40 + 20, mid), [0, 0, 0], "the black one is black");
        assert_eq!(at(3 * GAP + 80 + 20, mid), [200, 200, 200], "a missing one is grey");
        let ink = |rows: std::ops::Range<usize>| {
            rows.flat_map(|y| (0..40).map(move |x| (x, y)))
                .any(|(x, y)| at(GAP + x, y)[0] < 128)
        };
        assert!(ink(GAP + 30 + 3..GAP + 30 + 16), "captions are drawn under the panels");
        // The second panel's caption has a second line, below the first.
        let second = |rows: std::ops::Range<usize>| {
            rows.flat_map(|y| (0..40).map(move |x| (x, y)))
                .any(|(x, y)| at(2 * GAP + 40 + x, y)[0] < 128)
        };
        assert!(second(GAP + 30 + 16..GAP + 30 + 29), "a caption's second line");
        let tall = picture(40, 31, 1.0);
        let bad = [
            Panel {
                picture: Some(&a),
                caption: String::new(),
            },
            Panel {
                picture: Some(&tall),
                caption: String::new(),
            },
        ];
        assert!(write(&dir.path().join("bad.png"), &bad, &tone).is_err());
    }
}
