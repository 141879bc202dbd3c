//! The ways the demo draws a view, and what each drawing cost and scored:
//! the holodeck's display drivers on their own and with the display's
//! denoiser, and a direct render of the view given the same time, on its
//! own and cleaned by Open Image Denoise with its albedo and normals (what
//! a user would otherwise do).

use std::time::Instant;

use holodeck_display::compare::Metrics;
use holodeck_display::denoise::{AtrousOptions, Denoiser};
use holodeck_display::{EstimatorOptions, Viewport};
use holodeck_file::HoloFile;
use holodeck_protocol::{Picture, View};
use holodeck_sampler::render::{render, render_aovs, RenderOptions};
use holodeck_sampler::Tracer;

use crate::truth::Truth;
use crate::{DriverChoice, Error};

/// What the functions here return.
type Result<T> = std::result::Result<T, Error>;

/// The display drivers drawn, in the order of the sheets.
pub const DRIVERS: [&str; 3] = ["quadtree", "voronoi", "mesh"];

/// How a view is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    /// From the holodeck with a driver, and a denoiser after it.
    Holodeck {
        /// The driver.
        driver: &'static str,
        /// The denoiser.
        denoise: Denoiser,
        /// The denoiser is guided by the albedo of the scene's surfaces (a
        /// display given the scene), not by the store alone.
        scene: bool,
    },
    /// Traced directly in the view's share of the holodeck's time, and
    /// cleaned by Open Image Denoise if `oidn`.
    Direct {
        /// Cleaned by OIDN with albedo and normals.
        oidn: bool,
    },
}

impl Kind {
    /// The method's name in tables, legends and file names.
    pub fn name(&self) -> String {
        match self {
            Kind::Holodeck {
                driver,
                denoise: Denoiser::Off,
                ..
            } => driver.to_string(),
            Kind::Holodeck {
                driver,
                denoise,
                scene: true,
            } => format!("{driver} + {} with the scene's albedo", denoise.name()),
            Kind::Holodeck { driver, denoise, .. } => format!("{driver} + {}", denoise.name()),
            Kind::Direct { oidn: false } => "direct, same time".into(),
            Kind::Direct { oidn: true } => "direct + oidn, same time".into(),
        }
    }

    /// A short name for frame files.
    pub fn file_name(&self) -> String {
        match self {
            Kind::Holodeck {
                driver,
                denoise: Denoiser::Off,
                ..
            } => driver.to_string(),
            Kind::Holodeck {
                driver,
                denoise,
                scene: true,
            } => format!("{driver}-{}-albedo", denoise.name()),
            Kind::Holodeck { driver, denoise, .. } => format!("{driver}-{}", denoise.name()),
            Kind::Direct { oidn: false } => "direct".into(),
            Kind::Direct { oidn: true } => "direct-oidn".into(),
        }
    }
}

/// Every method the demo measures: each driver raw and denoised (by OIDN
/// too where the build has it), then the direct renders.
pub fn methods() -> Vec<Kind> {
    let mut out = Vec::new();
    for driver in DRIVERS {
        out.push(Kind::Holodeck {
            driver,
            denoise: Denoiser::Off,
            scene: false,
        });
        out.push(Kind::Holodeck {
            driver,
            denoise: Denoiser::Atrous(AtrousOptions::default()),
            scene: false,
        });
    }
    if cfg!(feature = "oidn") {
        for scene in [false, true] {
            out.push(Kind::Holodeck {
                driver: "quadtree",
                denoise: Denoiser::Oidn,
                scene,
            });
        }
    }
    out.push(Kind::Direct { oidn: false });
    out.push(Kind::Direct { oidn: true });
    out
}

/// The method the holodeck's time is counted by: what a user gets by
/// default (the quadtree, denoised).
pub fn default_method() -> Kind {
    Kind::Holodeck {
        driver: "quadtree",
        denoise: Denoiser::Atrous(AtrousOptions::default()),
        scene: false,
    }
}

/// One view drawn by one method.
pub struct Shot {
    /// The picture.
    pub picture: Picture,
    /// Every measure against the view's reference.
    pub metrics: Metrics,
    /// Seconds it took: for the holodeck recalling, drawing and denoising
    /// (the fill is counted once, apart); for a direct render all of it.
    pub secs: f64,
    /// Samples recalled from the file, or paths traced.
    pub samples: u64,
}

/// A method's shots along the walk.
pub struct Column {
    /// The method.
    pub kind: Kind,
    /// Per view; `None` where it could not draw.
    pub shots: Vec<Option<Shot>>,
    /// Why it could not draw here, if it could not.
    pub failed: Option<String>,
}

impl Column {
    /// An empty column for `kind`.
    pub fn new(kind: Kind) -> Column {
        Column {
            kind,
            shots: Vec::new(),
            failed: None,
        }
    }

    /// Seconds of all its shots.
    pub fn secs(&self) -> f64 {
        self.shots.iter().flatten().map(|s| s.secs).sum()
    }

    /// The mean of `f` over its shots (NaN for none; NaN values left out).
    pub fn mean(&self, f: impl Fn(&Metrics) -> f64) -> f64 {
        let v: Vec<f64> = self
            .shots
            .iter()
            .flatten()
            .map(|s| f(&s.metrics))
            .filter(|x| !x.is_nan())
            .collect();
        if v.is_empty() {
            f64::NAN
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    }
}

/// Draws `view` from `file` with every holodeck method of `kinds` that
/// uses `driver`: one recall, the raw frame, and each denoiser after it.
/// The methods marked `scene` are guided by the albedo of the surfaces the
/// view sees in `scene`, as a display given the scene has it
/// ([`crate::truth::scene_albedo`], its time counted in the method's). Returns (method index, shot) pairs.
pub fn draw_holodeck(
    file: &mut HoloFile,
    viewport: Viewport,
    driver: &'static str,
    kinds: &[Kind],
    truth: &Truth,
    seed: u64,
    scene: Option<&Tracer>,
) -> Result<Vec<(usize, Shot)>> {
    let view = viewport.view.clone();
    let size = (viewport.width, viewport.height);
    let choice = DriverChoice::plain(driver, EstimatorOptions::default());
    let (mut d, recalled) = crate::recall(file, viewport, &choice, 2, seed)?;
    let start = Instant::now();
    let raw = d.render();
    let base = recalled.secs.as_secs_f64() + start.elapsed().as_secs_f64();
    let guide = d.guide();
    let mut out = Vec::new();
    for (k, kind) in kinds.iter().enumerate() {
        let Kind::Holodeck {
            driver: dk,
            denoise,
            scene: with_scene,
        } = kind
        else {
            continue;
        };
        if *dk != driver {
            continue;
        }
        let start = Instant::now();
        let picture = match (denoise, scene.filter(|_| *with_scene)) {
            (Denoiser::Off, _) => raw.clone(),
            (dn, Some(tracer)) => {
                let albedo = crate::truth::scene_albedo(tracer, &view, size, seed)?;
                dn.apply(&raw, &guide.clone().with_albedo(&albedo))?
            }
            (dn, None) => dn.apply(&raw, &guide)?,
        };
        let secs = base + start.elapsed().as_secs_f64();
        out.push((
            k,
            Shot {
                metrics: truth.measure(&picture)?,
                picture,
                secs,
                samples: recalled.samples,
            },
        ));
    }
    Ok(out)
}

/// A direct render of `view` in passes of one sample per pixel until
/// `secs` have passed (at least one pass): the mean picture, the seconds
/// taken and the paths traced.
pub fn direct_for(tracer: &Tracer, view: &View, size: (u32, u32), secs: f64, seed: u64) -> Result<(Picture, f64, u64)> {
    let start = Instant::now();
    let pass = |passes: u64| {
        let o = RenderOptions {
            width: size.0,
            height: size.1,
            spp: 1,
            seed: seed << 20 | passes,
        };
        render(tracer, view, &o, &|_, _| {})
    };
    let mut picture = pass(0)?;
    let mut passes = 1u64;
    while start.elapsed().as_secs_f64() < secs {
        let p = pass(passes)?;
        picture.pixels.iter_mut().zip(&p.pixels).for_each(|(a, b)| *a += *b);
        passes += 1;
    }
    picture.pixels.iter_mut().for_each(|p| *p /= passes as f32);
    let paths = passes * u64::from(size.0) * u64::from(size.1);
    Ok((picture, start.elapsed().as_secs_f64(), paths))
}

/// A direct render of `view` cleaned by Open Image Denoise with its albedo
/// and normals, all of it within about `secs` (rendering stops early by
/// what the auxiliary pictures and the denoiser took last time, `overhead`,
/// which is updated). Fails in a build without OIDN.
pub fn direct_oidn_for(
    tracer: &Tracer,
    view: &View,
    size: (u32, u32),
    secs: f64,
    seed: u64,
    overhead: &mut f64,
) -> Result<(Picture, f64, u64)> {
    let start = Instant::now();
    let (noisy, _, paths) = direct_for(tracer, view, size, secs - *overhead, seed)?;
    let after = Instant::now();
    let o = RenderOptions {
        width: size.0,
        height: size.1,
        spp: 4,
        seed,
    };
    let (albedo, normal) = render_aovs(tracer, view, &o)?;
    let picture = crate::truth::denoise_oidn(&noisy, &albedo, &normal)?;
    *overhead = after.elapsed().as_secs_f64();
    Ok((picture, start.elapsed().as_secs_f64(), paths))
}
