//! The denoising stage after reconstruction: a driver's frame cleaned of
//! the noise its few rays per pixel leave, guided by what the sample store
//! knows of each pixel (depth, normal, the spread of its rays).
//!
//! Two denoisers: the edge-avoiding à-trous filter steered by variance
//! ([`atrous`] on the CPU, [`gpu`] on a GPU or lavapipe), and Intel Open Image Denoise with
//! the normals as its auxiliary feature ([`oidn`], with the `oidn` cargo
//! feature). Every denoiser here must keep the light of every region of the
//! picture: a denoised frame is measured by the light it keeps in the dark,
//! middle and bright parts of the reference as much as by its error.

pub mod atrous;
pub mod driver;
pub mod gpu;
pub mod guide;
#[cfg(feature = "oidn")]
pub mod oidn;

use holodeck_protocol::Picture;

pub use atrous::{atrous, AtrousOptions};
pub use driver::Denoised;
pub use guide::Guide;

/// Which denoiser a display runs after reconstruction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Denoiser {
    /// None: the frame as reconstructed.
    Off,
    /// The variance-guided à-trous filter, on the CPU.
    Atrous(AtrousOptions),
    /// The same filter on the GPU (the CPU's where no device can run it).
    AtrousGpu(AtrousOptions),
    /// The same filter where it runs fastest: on the GPU where the machine
    /// has a hardware one, on the CPU where it has only a software
    /// rasterizer or none (the frames agree within float rounding).
    Auto(AtrousOptions),
    /// Intel Open Image Denoise (with the `oidn` feature).
    Oidn,
}

/// The names [`Denoiser::parse`] knows.
pub const DENOISERS: [&str; 5] = ["off", "auto", "atrous", "atrous-gpu", "oidn"];

/// Why a frame could not be denoised.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DenoiseError {
    /// No denoiser has this name.
    #[error("unknown denoiser {0:?} (known: {known})", known = DENOISERS.join(", "))]
    Unknown(String),
    /// OIDN was asked for in a build without it.
    #[error("this build has no Open Image Denoise: rebuild with `--features oidn` (see the README)")]
    NoOidn,
    /// OIDN failed.
    #[error("Open Image Denoise: {0}")]
    Oidn(String),
}

impl Denoiser {
    /// The denoiser called `name` (one of [`DENOISERS`]), with default options.
    pub fn parse(name: &str) -> Result<Denoiser, DenoiseError> {
        match name {
            "off" => Ok(Denoiser::Off),
            "atrous" => Ok(Denoiser::Atrous(AtrousOptions::default())),
            "atrous-gpu" => Ok(Denoiser::AtrousGpu(AtrousOptions::default())),
            "auto" => Ok(Denoiser::Auto(AtrousOptions::default())),
            "oidn" if cfg!(feature = "oidn") => Ok(Denoiser::Oidn),
            "oidn" => Err(DenoiseError::NoOidn),
            other => Err(DenoiseError::Unknown(other.to_string())),
        }
    }

    /// Its name.
    pub fn name(&self) -> &'static str {
        match self {
            Denoiser::Off => "off",
            Denoiser::Atrous(_) => "atrous",
            Denoiser::AtrousGpu(_) => "atrous-gpu",
            Denoiser::Auto(_) => "auto",
            Denoiser::Oidn => "oidn",
        }
    }

    /// What [`Denoiser::Auto`] runs on this machine: the GPU filter where
    /// a hardware GPU is found, the CPU filter otherwise; any other
    /// denoiser is itself.
    pub fn resolved(&self) -> Denoiser {
        match *self {
            Denoiser::Auto(o) if crate::gpu::GpuContext::hardware_present() => Denoiser::AtrousGpu(o),
            Denoiser::Auto(o) => Denoiser::Atrous(o),
            other => other,
        }
    }

    /// `picture` denoised, guided by `guide` (the same frame's).
    pub fn apply(&self, picture: &Picture, guide: &Guide) -> Result<Picture, DenoiseError> {
        match self {
            Denoiser::Auto(_) => self.resolved().apply(picture, guide),
            Denoiser::Off => Ok(picture.clone()),
            Denoiser::Atrous(o) => Ok(atrous(picture, guide, o)),
            Denoiser::AtrousGpu(o) => match gpu::GpuAtrous::shared().and_then(|g| g.filter(picture, guide, o)) {
                Ok(p) => Ok(p),
                Err(e) => {
                    tracing::debug!("the GPU filter cannot run ({e}); the CPU filters this frame");
                    Ok(atrous(picture, guide, o))
                }
            },
            #[cfg(feature = "oidn")]
            Denoiser::Oidn => oidn::denoise_guided(picture, guide),
            #[cfg(not(feature = "oidn"))]
            Denoiser::Oidn => Err(DenoiseError::NoOidn),
        }
    }
}
