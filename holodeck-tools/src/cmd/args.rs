//! Argument groups several subcommands share.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use holodeck_display::EstimatorOptions;

/// How a client proves it may talk to the server.
#[derive(clap::Args)]
pub struct TokenArgs {
    /// Access token.
    #[arg(long, conflicts_with = "token_file")]
    token: Option<String>,
    /// File holding the access token (as `holodeck serve` writes it).
    #[arg(long)]
    token_file: Option<PathBuf>,
}

impl TokenArgs {
    /// The token, from the flag or the file.
    pub fn token(&self) -> Result<String> {
        Ok(match (&self.token, &self.token_file) {
            (Some(t), _) => t.clone(),
            (None, Some(p)) => std::fs::read_to_string(p)
                .with_context(|| format!("reading {}", p.display()))?
                .trim()
                .to_string(),
            (None, None) => bail!("give --token or --token-file (the server writes FILE.token)"),
        })
    }
}

/// How a display draws its frames.
#[derive(clap::Args)]
pub struct FrameArgs {
    /// Frame width.
    #[arg(short = 'x', long, default_value_t = 512)]
    pub width: u32,
    /// Frame height.
    #[arg(short = 'y', long, default_value_t = 384)]
    pub height: u32,
    /// Display driver: quadtree, or splat (plain points, the baseline).
    #[arg(long, default_value = "quadtree")]
    pub driver: String,
    /// Tone mapping for PNG: camera, human, exposure:X or exposure:auto.
    #[arg(long, default_value = "camera")]
    pub tone: String,
    #[command(flatten)]
    pub estimator: EstimatorArgs,
}

/// How a display combines the rays of a pixel (see docs/DISPLAY.md).
#[derive(clap::Args)]
pub struct EstimatorArgs {
    /// Rays whose depths differ by more than this fraction hit different surfaces.
    #[arg(long, default_value_t = EstimatorOptions::default().depth_tolerance)]
    pub depth_tolerance: f32,
    /// Degrees at which a ray that reached its surface off the eye's direction weighs half
    /// (glossy surfaces); 0 weighs every ray alike.
    #[arg(long, default_value_t = EstimatorOptions::default().angle_scale.to_degrees())]
    pub angle_scale: f32,
    /// A pixel's brightest ray counts at most this many times the mean of the others
    /// (fireflies); 0 turns the cut off.
    #[arg(long, default_value_t = EstimatorOptions::default().firefly_ratio)]
    pub firefly_ratio: f32,
    /// Estimates per pixel along each axis (1, 2 or 4; 0: 4 up to 256 x 256 pixels, 2 up to
    /// 512 x 512, else 1): finer keeps silhouettes sharper.
    #[arg(long, default_value_t = EstimatorOptions::default().subpixels)]
    pub subpixels: u32,
}

impl EstimatorArgs {
    /// The options, checked.
    pub fn options(&self) -> Result<EstimatorOptions> {
        let finite = |v: f32, what: &str| {
            if v.is_finite() && v >= 0.0 {
                Ok(v)
            } else {
                bail!("--{what} must be a number of at least 0, not {v}")
            }
        };
        let tolerance = finite(self.depth_tolerance, "depth-tolerance")?;
        let angle = finite(self.angle_scale, "angle-scale")?;
        let ratio = finite(self.firefly_ratio, "firefly-ratio")?;
        if ![0, 1, 2, 4].contains(&self.subpixels) {
            bail!(
                "--subpixels must be 0 (by frame size), 1, 2 or 4, not {}",
                self.subpixels
            );
        }
        Ok(EstimatorOptions {
            depth_tolerance: tolerance,
            angle_scale: if angle == 0.0 {
                f32::INFINITY
            } else {
                angle.to_radians()
            },
            firefly_ratio: if ratio == 0.0 { f32::INFINITY } else { ratio },
            subpixels: self.subpixels,
        })
    }
}
