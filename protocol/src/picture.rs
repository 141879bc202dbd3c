//! A linear-radiance picture and the comparisons tests and charts need.

use glam::Vec3;

/// The most pixels any picture may have: 8192 x 8192, 768 MiB of linear
/// radiance (a 16384 x 16384 picture would need 3 GiB before any driver or
/// encoder adds its own).
pub const MAX_PICTURE_PIXELS: u64 = 8192 * 8192;

/// The longest side a picture may have: wide panoramas up to
/// [`MAX_PICTURE_PIXELS`] in all.
pub const MAX_PICTURE_SIDE: u32 = 65536;

/// Why no picture can have a size.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum PictureSizeError {
    /// A zero width or height.
    #[error("a {width} x {height} picture has no pixels: width and height must be at least 1")]
    Empty {
        /// Width asked for.
        width: u64,
        /// Height asked for.
        height: u64,
    },
    /// More pixels, or a longer side, than any picture may have.
    #[error("a {width} x {height} picture is too large: at most {MAX_PICTURE_SIDE} pixels a side and {MAX_PICTURE_PIXELS} in all (8192 x 8192)")]
    TooLarge {
        /// Width asked for.
        width: u64,
        /// Height asked for.
        height: u64,
    },
}

/// Checks that a `width` x `height` picture may be made: every caller that
/// allocates a frame from numbers a user gave asks here first, so the largest
/// picture is defined once.
pub fn check_size(width: u64, height: u64) -> Result<(), PictureSizeError> {
    if width == 0 || height == 0 {
        return Err(PictureSizeError::Empty { width, height });
    }
    let side = u64::from(MAX_PICTURE_SIDE);
    if width > side || height > side || width.saturating_mul(height) > MAX_PICTURE_PIXELS {
        return Err(PictureSizeError::TooLarge { width, height });
    }
    Ok(())
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_are_checked_against_one_limit() {
        assert_eq!(check_size(1, 1), Ok(()));
        assert_eq!(check_size(8192, 8192), Ok(()));
        assert_eq!(check_size(65536, 1024), Ok(()));
        assert_eq!(check_size(0, 5), Err(PictureSizeError::Empty { width: 0, height: 5 }));
        assert_eq!(
            check_size(8193, 8192),
            Err(PictureSizeError::TooLarge {
                width: 8193,
                height: 8192
            })
        );
        assert!(matches!(
            check_size(4_000_000_000, 1),
            Err(PictureSizeError::TooLarge { .. })
        ));
        assert!(matches!(
            check_size(u64::MAX, u64::MAX),
            Err(PictureSizeError::TooLarge { .. })
        ));
    }
}
