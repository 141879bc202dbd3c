//! A view and the pixel size of the frame it is drawn into, checked, and
//! why a driver cannot be made or cannot take one.

use holodeck_protocol::{check_picture_size, PictureSizeError, View};

/// The largest frame a driver accepts: the largest picture,
/// [`holodeck_protocol::MAX_PICTURE_PIXELS`].
pub const MAX_VIEWPORT_PIXELS: u64 = holodeck_protocol::MAX_PICTURE_PIXELS;

/// A view and the pixel size of the frame it is drawn into.
#[derive(Clone, Debug, PartialEq)]
pub struct Viewport {
    /// The view.
    pub view: View,
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
}

/// Why a driver cannot be made or cannot take a viewport.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DriverError {
    /// No driver has this name.
    #[error("unknown driver {0:?} (known: {known})", known = crate::DRIVERS.join(", "))]
    Unknown(String),
    /// A GPU driver where no GPU (nor a software one) can be opened.
    #[error("{0}")]
    Gpu(String),
    /// A zero-sized or oversized frame.
    #[error("frame: {0}")]
    FrameSize(PictureSizeError),
    /// A view whose numbers are not finite or whose directions are degenerate.
    #[error("the view is degenerate: {0}")]
    View(String),
}

impl Viewport {
    /// Checks the size and the view.
    pub fn new(view: View, width: u32, height: u32) -> Result<Viewport, DriverError> {
        check_picture_size(u64::from(width), u64::from(height)).map_err(DriverError::FrameSize)?;
        let finite = view.position.is_finite()
            && view.direction.is_finite()
            && view.up.is_finite()
            && view.horizontal.is_finite()
            && view.vertical.is_finite();
        if !finite || view.direction.length_squared() == 0.0 || view.direction.cross(view.up).length_squared() == 0.0 {
            return Err(DriverError::View(view.to_spec()));
        }
        Ok(Viewport { view, width, height })
    }

    /// The pixel (column, row from the top) a world point projects to, with its
    /// depth, or `None` outside the frame or behind the eye.
    pub fn pixel(&self, world: glam::DVec3) -> Option<(u32, u32, f64)> {
        let (x, y, depth) = self.view.project(world)?;
        if !(0.0..1.0).contains(&x) || !(0.0..1.0).contains(&y) {
            return None;
        }
        let col = (x * f64::from(self.width)) as u32;
        let row = ((1.0 - y) * f64::from(self.height)) as u32;
        Some((col.min(self.width - 1), row.min(self.height - 1), depth))
    }
}
