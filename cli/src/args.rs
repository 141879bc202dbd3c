//! Argument groups several subcommands share, and the bounds of the numbers
//! they take: a number that sizes an allocation is refused by its flag before
//! anything is allocated.

use std::ops::RangeInclusive;
use std::path::PathBuf;

use anyhow::{bail, Context, Result};
pub use holodeck::DriverChoice;
use holodeck_display::denoise::Denoiser;
use holodeck_display::geometry::{Geometry, DEFAULT_BUDGET};
use holodeck_display::EstimatorOptions;
use holodeck_protocol::wire::client;
use holodeck_protocol::wire::tls::Pin;
use holodeck_protocol::{check_picture_size, MAX_PICTURE_SIDE};

/// Pixels along one side of a picture (the whole picture is checked by
/// [`frame_size`]).
pub const SIDE: RangeInclusive<i64> = 1..=MAX_PICTURE_SIDE as i64;

/// Most triangles a generated scene may be asked for (an in-core scene's limit).
pub const MAX_TRIANGLES: u64 = holodeck_sampler::scene::builder::MAX_TRIANGLES as u64;

/// Most worker threads or sampler processes one command starts.
pub const MAX_WORKERS: i64 = 1024;

/// Checks a frame of `width` x `height` pixels from `-x/--width` and
/// `-y/--height` against the largest picture, naming the flags.
pub fn frame_size(width: u32, height: u32) -> Result<()> {
    check_picture_size(u64::from(width), u64::from(height)).context("-x/--width and -y/--height")
}

/// A value that is not a finite number in the range a flag takes.
#[derive(Debug, thiserror::Error)]
#[error("{text:?} is not a number {range}")]
pub struct NumberError {
    text: String,
    range: &'static str,
}

/// How samplers order the paths of a batch: the `--reorder` option of the
/// commands that trace.
#[derive(clap::Args, Clone, Copy, Debug)]
pub struct ReorderArgs {
    /// How the rays of a batch of paths are ordered: `auto` sorts them by
    /// estimated hit point (Moon et al. 2010) where the scene is larger
    /// than the CPU's cache and a batch is large; `off` traces each path to
    /// its end; `hit-point` and `origin` always sort. The rays come out the
    /// same; only the speed differs.
    #[arg(long, default_value = "auto", value_parser = |s: &str| s.parse::<holodeck_sampler::Reorder>())]
    pub reorder: holodeck_sampler::Reorder,
}

/// A clap value parser of finite numbers of at least 0 (radii, fractions).
pub fn non_negative(s: &str) -> Result<f64, NumberError> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        _ => Err(NumberError {
            text: s.to_string(),
            range: "of at least 0",
        }),
    }
}

/// A clap value parser of finite numbers above 0 (seconds, targets).
pub fn positive(s: &str) -> Result<f64, NumberError> {
    match s.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(NumberError {
            text: s.to_string(),
            range: "above 0",
        }),
    }
}

impl FrameArgs {
    /// Checks the frame size as a whole (each side is checked as it is parsed).
    pub fn check(&self) -> Result<()> {
        frame_size(self.width, self.height)
    }
}

/// How a client proves it may talk to the server.
#[derive(clap::Args)]
pub struct TokenArgs {
    /// Access token.
    #[arg(long, conflicts_with = "token_file")]
    token: Option<String>,
    /// File holding the access token (as `holodeck serve` writes it, with the
    /// fingerprint of the server's certificate, which is then pinned: TLS).
    #[arg(long)]
    token_file: Option<PathBuf>,
    /// The SHA-256 fingerprint of the server's certificate, to pin it (TLS)
    /// where the token is given with --token; `holodeck serve` prints it.
    #[arg(long, value_name = "HEX")]
    tls_fingerprint: Option<String>,
    /// Talk to a server on another host over plain TCP: the token and every
    /// ray cross the network in clear text, readable and forgeable by anyone
    /// on the path. Without it a server elsewhere needs a pinned certificate.
    #[arg(long, conflicts_with_all = ["tls_fingerprint", "tls_ca"])]
    plain_text: bool,
    /// Check the server's certificate against this CA (PEM) and the host name
    /// of --connect, instead of pinning it (for a certificate `serve` was
    /// given with --tls-cert).
    #[arg(long, value_name = "FILE", conflicts_with = "tls_fingerprint")]
    tls_ca: Option<PathBuf>,
}

/// The line of a token file that pins the server's certificate.
pub const FINGERPRINT_LINE: &str = "tls-sha256 ";

/// What a token file holds: the token (its first line) and the server's
/// certificate fingerprint, where a `tls-sha256 HEX` line gives one.
pub fn read_token_file(path: &std::path::Path) -> Result<(String, Option<Pin>)> {
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let mut lines = text.lines();
    let token = lines.next().unwrap_or("").trim().to_string();
    let mut pin = None;
    for line in lines {
        if let Some(hex) = line.trim().strip_prefix(FINGERPRINT_LINE.trim_end()) {
            let p = Pin::parse(hex.trim())
                .with_context(|| format!("{}: {:?} is not a SHA-256 fingerprint", path.display(), hex.trim()))?;
            pin = Some(p);
        }
    }
    if token.is_empty() {
        bail!("{} holds no token", path.display());
    }
    Ok((token, pin))
}

impl TokenArgs {
    /// The token, from the flag or the file.
    pub fn token(&self) -> Result<String> {
        Ok(match (&self.token, &self.token_file) {
            (Some(t), _) => t.clone(),
            (None, Some(p)) => read_token_file(p)?.0,
            (None, None) => bail!("give --token or --token-file (the server writes FILE.token)"),
        })
    }

    /// The server's certificate fingerprint, from the flag or the file.
    pub fn pin(&self) -> Result<Option<Pin>> {
        if let Some(hex) = &self.tls_fingerprint {
            return Pin::parse(hex)
                .map(Some)
                .with_context(|| format!("--tls-fingerprint {hex:?}: not 64 hex digits"));
        }
        match &self.token_file {
            Some(p) => Ok(read_token_file(p)?.1),
            None => Ok(None),
        }
    }

    /// The address the client connects to for `--connect ADDR`: TLS with
    /// the pinned certificate where there is one, plain otherwise (which the
    /// client allows to this machine alone, unless --plain-text).
    pub fn address(&self, connect: &str) -> Result<String> {
        if connect.starts_with("unix:") {
            return Ok(connect.to_string());
        }
        if let Some(ca) = &self.tls_ca {
            let ca = ca.to_str().context("--tls-ca: the path must be valid UTF-8")?;
            return Ok(format!("{}{ca}@{connect}", holodeck_protocol::wire::tls::TLS_CA_PREFIX));
        }
        Ok(match (self.pin()?, self.plain_text) {
            (Some(pin), _) => client::address(connect, Some(pin)),
            (None, true) => format!("{}{connect}", client::PLAIN_PREFIX),
            (None, false) => connect.to_string(),
        })
    }
}

/// How a display draws its frames.
#[derive(clap::Args)]
pub struct FrameArgs {
    /// Frame width.
    #[arg(short = 'x', long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(SIDE))]
    pub width: u32,
    /// Frame height.
    #[arg(short = 'y', long, default_value_t = 384, value_parser = clap::value_parser!(u32).range(SIDE))]
    pub height: u32,
    /// Display driver: quadtree (CPU), splat (plain points, the baseline), voronoi (GPU
    /// cones) or mesh (GPU spherical Delaunay mesh). The GPU drivers run on Mesa's software
    /// Vulkan where there is no GPU.
    #[arg(long, default_value = "quadtree", value_parser = clap::builder::PossibleValuesParser::new(holodeck_display::DRIVERS))]
    pub driver: String,
    /// Scene whose geometry the voronoi driver culls samples by and stops cones at
    /// (a scene file or builtin:NAME; the scene the holodeck was filled from). With
    /// --denoise oidn, the albedo of the surfaces each view sees is traced from it and
    /// guides OIDN beside the normals.
    #[arg(long, value_name = "SCENE")]
    pub geometry: Option<String>,
    /// Most triangles of --geometry drawn: larger scenes are simplified to it.
    #[arg(long, default_value_t = DEFAULT_BUDGET as u64, value_parser = clap::value_parser!(u64).range(1..=100_000_000))]
    pub geometry_budget: u64,
    /// Tone mapping for PNG: camera, human, exposure:X or exposure:auto.
    #[arg(long, default_value = "camera")]
    pub tone: String,
    /// Denoiser run on every frame after reconstruction: auto (the atrous filter on the
    /// GPU where the machine has a hardware one, else on the CPU), atrous (edge-avoiding
    /// wavelets steered by each pixel's noise, on the CPU), atrous-gpu (the same filter on the GPU,
    /// or on Mesa's software Vulkan where there is none; the CPU's where no device runs it),
    /// oidn (Intel Open Image Denoise; a build with --features oidn) or off.
    #[arg(long, default_value = DEFAULT_DENOISER)]
    pub denoise: String,
    #[command(flatten)]
    pub estimator: EstimatorArgs,
}

/// The denoiser displays run unless told otherwise.
pub const DEFAULT_DENOISER: &str = "auto";

impl FrameArgs {
    /// The driver these flags choose, with its geometry loaded.
    pub fn driver_choice(&self) -> Result<DriverChoice> {
        let denoise = Denoiser::parse(&self.denoise).context("--denoise")?;
        let budget = self.geometry_budget as usize;
        // OIDN takes the albedo of the surfaces seen beside the normals: a
        // display given the scene traces it for each view.
        let (geometry, scene) = match &self.geometry {
            Some(spec) if denoise == Denoiser::Oidn => {
                let scene = holodeck::load(spec, None)?;
                let geometry = geometry_of(&scene, spec, budget);
                let tracer = holodeck_sampler::Tracer::new(scene, holodeck_sampler::TraceOptions::default());
                (Some(std::sync::Arc::new(geometry)), Some(std::sync::Arc::new(tracer)))
            }
            Some(spec) => (Some(std::sync::Arc::new(load_geometry(spec, budget)?)), None),
            None => (None, None),
        };
        Ok(DriverChoice {
            name: self.driver.clone(),
            options: self.estimator.options()?,
            geometry,
            denoise,
            neighbours: false,
            scene,
        })
    }
}

/// Loads a scene's triangles for a display, simplified to `budget`; thin
/// glass and mirrors are left out (a display culls by what hides).
pub fn load_geometry(spec: &str, budget: usize) -> Result<Geometry> {
    Ok(geometry_of(&holodeck::load(spec, None)?, spec, budget))
}

/// The triangles of `scene` (loaded from `spec`) a display culls by,
/// simplified to `budget`.
fn geometry_of(scene: &holodeck_sampler::Scene, spec: &str, budget: usize) -> Geometry {
    // Windows and mirrors hide nothing a holodeck shows through them: with
    // virtual distances their samples lie beyond them, and culling by them
    // would black out every window.
    let see_through = |m: u32| {
        matches!(
            scene.materials[m as usize],
            holodeck_sampler::Material::Glass { thin: true, .. } | holodeck_sampler::Material::Mirror { .. }
        )
    };
    let triangles: Vec<[glam::Vec3; 3]> = (0..scene.triangles.len())
        .filter(|&t| !see_through(scene.triangles[t].material))
        .map(|t| scene.vertices(t))
        .collect();
    let g = Geometry::new(&triangles, budget, None);
    tracing::info!(
        "display geometry: {} of {} triangles of {spec}",
        g.triangles.len(),
        g.source_triangles
    );
    g
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
    /// (fireflies), the rest of its light spread around it (--firefly-spread); 0 turns
    /// the cut off.
    #[arg(long, default_value_t = EstimatorOptions::default().firefly_ratio)]
    pub firefly_ratio: f32,
    /// Radius in pixels over which the light cut off fireflies is spread among the
    /// estimates there; 0 drops it (a winsorized mean: loses light where it is scarce).
    #[arg(long, default_value_t = EstimatorOptions::default().firefly_spread)]
    pub firefly_spread: f32,
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
        let spread = finite(self.firefly_spread, "firefly-spread")?;
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
            firefly_spread: spread,
            subpixels: self.subpixels,
        })
    }
}
