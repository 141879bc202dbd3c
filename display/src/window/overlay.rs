//! What the window draws over the picture, on the CPU into the frame's
//! RGBA bytes: the holodeck section grids during motion (so the user stays
//! oriented where no samples are yet), the focus rectangle, and the status
//! line in an 8 x 8 bitmap font.

use glam::DVec3;
use holodeck_protocol::{Section, View};

/// The grid color (rholo draws its grids in cyan).
pub const GRID: [u8; 3] = [0, 255, 255];

/// The focus rectangle's color.
pub const FOCUS: [u8; 3] = [255, 220, 0];

/// Height of the status line in pixels.
pub const STATUS_HEIGHT: u32 = 12;

/// Pieces each grid line is cut into before projection, so that lines stay
/// right in fisheye views, where straight lines show curved.
const PIECES: usize = 8;

/// RGBA bytes of a frame, top row first, to draw on.
pub struct Canvas<'a> {
    /// The pixels.
    pub rgba: &'a mut [u8],
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl Canvas<'_> {
    /// Sets a pixel, ignoring those off the frame.
    pub fn put(&mut self, x: i64, y: i64, rgb: [u8; 3]) {
        if x < 0 || y < 0 || x >= i64::from(self.width) || y >= i64::from(self.height) {
            return;
        }
        let at = (y as usize * self.width as usize + x as usize) * 4;
        self.rgba[at..at + 4].copy_from_slice(&[rgb[0], rgb[1], rgb[2], 255]);
    }

    /// A line between two points in pixel coordinates (clipped to the frame).
    pub fn line(&mut self, a: [f64; 2], b: [f64; 2], rgb: [u8; 3]) {
        let Some((a, b)) = clip(a, b, f64::from(self.width), f64::from(self.height)) else {
            return;
        };
        let steps = (b[0] - a[0]).abs().max((b[1] - a[1]).abs()).ceil().max(1.0);
        let n = steps as i64;
        for i in 0..=n {
            let t = i as f64 / steps;
            let x = a[0] + (b[0] - a[0]) * t;
            let y = a[1] + (b[1] - a[1]) * t;
            self.put(x.floor() as i64, y.floor() as i64, rgb);
        }
    }

    /// A rectangle's outline, between two corners in pixels.
    pub fn rect(&mut self, a: [f64; 2], b: [f64; 2], rgb: [u8; 3]) {
        let (c, d) = ([a[0], b[1]], [b[0], a[1]]);
        self.line(a, c, rgb);
        self.line(c, b, rgb);
        self.line(b, d, rgb);
        self.line(d, a, rgb);
    }

    /// Text in the 8 x 8 font with its top left corner at (`x`, `y`);
    /// characters outside ASCII show as `?`.
    pub fn text(&mut self, x: i64, y: i64, text: &str, rgb: [u8; 3]) {
        for (i, ch) in text.chars().enumerate() {
            let code = if ch.is_ascii() { ch as usize } else { '?' as usize };
            let glyph = font8x8::legacy::BASIC_LEGACY[code];
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..8 {
                    if bits >> col & 1 == 1 {
                        self.put(x + i as i64 * 8 + col, y + row as i64, rgb);
                    }
                }
            }
        }
    }

    /// The status line: a dark band along the bottom with `text` in it,
    /// wrapped at spaces onto as many lines of [`STATUS_HEIGHT`] as a narrow
    /// window needs (nothing is cut off).
    pub fn status(&mut self, text: &str) {
        let lines = wrap(text, ((self.width.saturating_sub(8)) / 8).max(1) as usize);
        let band = STATUS_HEIGHT * lines.len().max(1) as u32;
        let top = self.height.saturating_sub(band);
        for y in top..self.height {
            let row = (y as usize * self.width as usize) * 4;
            for px in self.rgba[row..row + self.width as usize * 4].chunks_exact_mut(4) {
                px[0] /= 4;
                px[1] /= 4;
                px[2] /= 4;
            }
        }
        for (k, line) in lines.iter().enumerate() {
            let y = i64::from(top) + 2 + i64::from(STATUS_HEIGHT) * k as i64;
            self.text(4, y, line, [230, 230, 230]);
        }
    }

    /// The sections' box and wall grids as `view` sees them.
    pub fn grids(&mut self, view: &View, sections: &[Section]) {
        let projector = view.projector();
        let eye = view.position;
        let dir = view.direction.normalize();
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        for section in sections {
            for [p, q] in section.grid_lines() {
                for k in 0..PIECES {
                    let a = p + (q - p) * (k as f64 / PIECES as f64);
                    let b = p + (q - p) * ((k + 1) as f64 / PIECES as f64);
                    let Some((a, b)) = in_front(a, b, eye, dir) else {
                        continue;
                    };
                    let (Some(pa), Some(pb)) = (projector.project(a), projector.project(b)) else {
                        continue;
                    };
                    let px = |(x, y, _): (f64, f64, f64)| [x * w, (1.0 - y) * h];
                    self.line(px(pa), px(pb), GRID);
                }
            }
        }
    }
}

/// The part of segment `a`-`b` in front of the eye (a little way out, so
/// that nothing projects from behind or from the eye itself).
fn in_front(a: DVec3, b: DVec3, eye: DVec3, dir: DVec3) -> Option<(DVec3, DVec3)> {
    const NEAR: f64 = 1e-3;
    let (da, db) = ((a - eye).dot(dir) - NEAR, (b - eye).dot(dir) - NEAR);
    match (da > 0.0, db > 0.0) {
        (true, true) => Some((a, b)),
        (false, false) => None,
        (true, false) => Some((a, a + (b - a) * (da / (da - db)))),
        (false, true) => Some((a + (b - a) * (da / (da - db)), b)),
    }
}

/// Liang-Barsky: the part of segment `a`-`b` inside 0..w x 0..h.
fn clip(a: [f64; 2], b: [f64; 2], w: f64, h: f64) -> Option<([f64; 2], [f64; 2])> {
    if !(a.iter().chain(&b).all(|v| v.is_finite())) {
        return None;
    }
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for (p, q) in [(-dx, a[0]), (dx, w - 1e-6 - a[0]), (-dy, a[1]), (dy, h - 1e-6 - a[1])] {
        if p == 0.0 {
            if q < 0.0 {
                return None;
            }
            continue;
        }
        let r = q / p;
        if p < 0.0 {
            t0 = t0.max(r);
        } else {
            t1 = t1.min(r);
        }
        if t0 > t1 {
            return None;
        }
    }
    Some(([a[0] + dx * t0, a[1] + dy * t0], [a[0] + dx * t1, a[1] + dy * t1]))
}

/// `text` broken at spaces into lines of at most `width` characters (a
/// word longer than that is cut into pieces).
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    let mut line = String::new();
    for word in text.split(' ').filter(|w| !w.is_empty()) {
        let mut word: Vec<char> = word.chars().collect();
        while word.len() > width {
            if !line.is_empty() {
                lines.push(std::mem::take(&mut line));
            }
            lines.push(word.drain(..width).collect());
        }
        let word: String = word.into_iter().collect();
        if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > width {
            lines.push(std::mem::take(&mut line));
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(&word);
    }
    if !line.is_empty() || lines.is_empty() {
        lines.push(line);
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lit(rgba: &[u8], w: u32, x: u32, y: u32) -> bool {
        rgba[((y * w + x) * 4) as usize..][..3] != [0, 0, 0]
    }

    #[test]
    fn lines_are_clipped_to_the_frame_and_land_on_their_pixels() {
        let (w, h) = (20u32, 10u32);
        let mut rgba = vec![0u8; (w * h * 4) as usize];
        let mut c = Canvas {
            rgba: &mut rgba,
            width: w,
            height: h,
        };
        c.line([-100.0, 5.5], [100.0, 5.5], [255, 0, 0]);
        c.line([3.5, -50.0], [3.5, 1e9], [0, 255, 0]);
        c.line([f64::NAN, 0.0], [1.0, 1.0], [0, 0, 255]);
        for x in 0..w {
            assert!(lit(&rgba, w, x, 5), "row 5 at {x}");
        }
        for y in 0..h {
            assert!(lit(&rgba, w, 3, y), "column 3 at {y}");
        }
        let lit_count = (0..w * h).filter(|i| lit(&rgba, w, i % w, i / w)).count();
        assert_eq!(lit_count as u32, w + h - 1);
    }

    #[test]
    fn a_long_status_wraps_onto_more_lines_instead_of_being_cut() {
        assert_eq!(wrap("a bb ccc", 4), vec!["a bb", "ccc"]);
        assert_eq!(wrap("abcdefghij", 4), vec!["abcd", "efgh", "ij"]);
        assert_eq!(wrap("", 4), vec![""]);
        let status = "12.3 K samples/s  1.2 M received  1.1 M shown  server 4.5 M rays 120 K/s  2 samplers";
        let lines = wrap(status, (512 - 8) / 8);
        assert_eq!(lines.join(" "), status.split_whitespace().collect::<Vec<_>>().join(" "));
        assert!(lines.len() >= 2 && lines.iter().all(|l| l.len() <= 63), "{lines:?}");
        // Two lines (11 characters fit in 96 pixels) darken two bands' height.
        let (w, h) = (96u32, 40u32);
        let mut rgba = vec![200u8; (w * h * 4) as usize];
        let mut c = Canvas {
            rgba: &mut rgba,
            width: w,
            height: h,
        };
        c.status("abcd efgh ijkl");
        let darkened = |y: u32| rgba[((y * w) * 4) as usize] == 50;
        assert!(darkened(h - 1) && darkened(h - 2 * STATUS_HEIGHT));
        assert!(!darkened(h - 2 * STATUS_HEIGHT - 1));
    }

    #[test]
    fn text_draws_glyphs_and_the_status_band_darkens_the_bottom() {
        let (w, h) = (64u32, 24u32);
        let mut rgba = vec![200u8; (w * h * 4) as usize];
        let mut c = Canvas {
            rgba: &mut rgba,
            width: w,
            height: h,
        };
        c.status("|");
        // The bar of '|' is in the middle columns of the first glyph.
        let top = h - STATUS_HEIGHT + 2;
        assert_eq!(&rgba[(((top + 2) * w + 4 + 3) * 4) as usize..][..3], &[230, 230, 230]);
        assert_eq!(&rgba[(((top + 2) * w + 4 + 6) * 4) as usize..][..3], &[50, 50, 50]);
        assert_eq!(
            &rgba[(((top + 3) * w + 4 + 3) * 4) as usize..][..3],
            &[50, 50, 50],
            "the gap in the broken bar"
        );
        assert_eq!(&rgba[0..3], &[200, 200, 200], "above the band untouched");
    }

    #[test]
    fn a_section_box_seen_from_inside_draws_its_edges() {
        let section = Section::new(
            [0.0; 3],
            [[4.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 4.0]],
            [2, 2, 2],
            holodeck_protocol::SectionKind::Interior,
        )
        .unwrap();
        let view = View::parse("-vtv -vp 2 2 2 -vd 1 0 0 -vu 0 0 1 -vh 90 -vv 90").unwrap();
        let (w, h) = (64u32, 64u32);
        let mut rgba = vec![0u8; (w * h * 4) as usize];
        Canvas {
            rgba: &mut rgba,
            width: w,
            height: h,
        }
        .grids(&view, &[section]);
        // The far wall at x = 4 spans the whole 90-degree frame: its center
        // grid lines cross the middle, its edges run along the borders.
        assert!(lit(&rgba, w, 32, 10) || lit(&rgba, w, 31, 10), "vertical center line");
        assert!(lit(&rgba, w, 10, 32) || lit(&rgba, w, 10, 31), "horizontal center line");
        assert!(!lit(&rgba, w, 16, 16), "inside a cell nothing is drawn");
    }
}
