//! The interactive walkthrough window (winit and wgpu): the holodeck
//! paper's input model (section 2.4.1) over any driver and any source of
//! samples, a live server or a holodeck file.
//!
//! [`navigate`] is the view arithmetic of each motion step, [`walk`] the
//! walkthrough's state (what is asked for when), [`command`] winit's keys
//! as the walkthrough's commands ([`crate::command`]), [`overlay`] the grids and the status line,
//! [`present`] the surface, [`source`] where samples come from, and
//! [`app`] ties them to window events.

pub mod app;
pub mod command;
pub use crate::navigate;
pub mod overlay;
pub mod present;
pub mod source;
pub mod walk;

pub use app::{run, WindowOptions};
pub use source::{Delivery, ServerSource, Source, SourceError};
pub use walk::{WalkError, WalkOptions, Walkthrough};

/// Why the window failed.
#[derive(Debug, thiserror::Error)]
pub enum WindowError {
    /// No window could be opened (no display, say).
    #[error("opening a window: {0} (is DISPLAY or WAYLAND_DISPLAY set? Without a screen, run under xvfb-run)")]
    Open(String),
    /// No GPU adapter or surface for it.
    #[error("{0}")]
    Gpu(String),
    /// The walkthrough failed.
    #[error(transparent)]
    Walk(#[from] WalkError),
    /// Writing a saved frame failed.
    #[error(transparent)]
    Image(#[from] crate::image_io::ImageError),
}

impl WindowError {
    /// True when the window closed because its server ended the session
    /// (it quit, was stopped, or its TIME was up): the end of a session,
    /// not a fault of the window.
    pub fn server_ended(&self) -> bool {
        matches!(
            self,
            WindowError::Walk(WalkError::Source(SourceError::Client(
                crate::client::ClientError::Closed
            )))
        )
    }
}
