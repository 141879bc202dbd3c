//! A linear-radiance picture and the comparisons tests and charts need.

use glam::Vec3;

/// Linear RGB radiance, row-major from the top row.
#[derive(Clone, Debug, PartialEq)]
pub struct Picture {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Pixels, `width * height`, top row first.
    pub pixels: Vec<Vec3>,
}

impl Picture {
    /// Mean squared difference per channel against another picture of the same size.
    pub fn mse(&self, other: &Picture) -> Option<f64> {
        if self.width != other.width || self.height != other.height {
            return None;
        }
        let sum: f64 = self
            .pixels
            .iter()
            .zip(&other.pixels)
            .map(|(a, b)| {
                let d = *a - *b;
                f64::from(d.x * d.x + d.y * d.y + d.z * d.z)
            })
            .sum();
        Some(sum / (3 * self.pixels.len()).max(1) as f64)
    }

    /// Mean luminance.
    pub fn mean_luminance(&self) -> f64 {
        let sum: f64 = self
            .pixels
            .iter()
            .map(|p| f64::from(0.2126 * p.x + 0.7152 * p.y + 0.0722 * p.z))
            .sum();
        sum / self.pixels.len().max(1) as f64
    }

    /// Exposure that maps the log-average luminance to middle grey (0.18).
    pub fn auto_exposure(&self) -> f32 {
        let (mut sum, mut n) = (0.0f64, 0usize);
        for p in &self.pixels {
            let y = f64::from(0.2126 * p.x + 0.7152 * p.y + 0.0722 * p.z);
            if y > 0.0 && y.is_finite() {
                sum += y.ln();
                n += 1;
            }
        }
        if n == 0 {
            return 1.0;
        }
        (0.18 / (sum / n as f64).exp()) as f32
    }
}
