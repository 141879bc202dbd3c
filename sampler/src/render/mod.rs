//! The direct reference renderer: traces a view pixel by pixel, in parallel,
//! with a deterministic sequence of samples per pixel. Its pictures are the
//! ground truth every holodeck reconstruction is measured against.

mod aov;

pub use aov::{render_aovs, AOV_SAMPLES};
pub use holodeck_protocol::{Picture, PictureSizeError};

use std::sync::atomic::{AtomicUsize, Ordering};

use glam::Vec3;
use holodeck_protocol::{check_picture_size, View};
use rayon::prelude::*;

use crate::accel::PACKET;
use crate::geom::Ray;
use crate::shade::{Rng, Tracer};

/// What to render.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel (stratified over the pixel).
    pub spp: u32,
    /// Seed of the random sequence.
    pub seed: u64,
}

/// Why a render cannot start.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum RenderError {
    /// No picture can have the size asked for.
    #[error("{0}")]
    Size(PictureSizeError),
    /// Zero samples per pixel would leave every pixel undefined.
    #[error("0 samples per pixel render nothing: give at least 1")]
    NoSamples,
}

/// Renders `view`; `progress` is called with rows done and the total.
pub fn render(
    tracer: &Tracer,
    view: &View,
    o: &RenderOptions,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<Picture, RenderError> {
    check_picture_size(u64::from(o.width), u64::from(o.height)).map_err(RenderError::Size)?;
    if o.spp == 0 {
        return Err(RenderError::NoSamples);
    }
    let (w, h) = (o.width as usize, o.height as usize);
    let spp = o.spp;
    // Stratify over a sqrt(spp) x sqrt(spp) grid where spp is a square, else jitter freely.
    let strata = (f64::from(spp).sqrt() as u32).max(1);
    let stratified = strata * strata == spp;
    let done = AtomicUsize::new(0);
    let rays = view.rays();
    let rows: Vec<Vec<Vec3>> = (0..h)
        .into_par_iter()
        .map(|row| {
            let mut out = Vec::with_capacity(w);
            for col in 0..w {
                let pixel = (row * w + col) as u64;
                let mut rng = Rng::new(o.seed, pixel);
                let mut sum = Vec3::ZERO;
                // A pixel's samples eight at a time: their positions, then
                // their paths, all from the pixel's one random sequence.
                let mut s = 0;
                while s < spp {
                    let mut batch = [(Vec3::ZERO, Vec3::ZERO); PACKET];
                    // Where each ray meets the aft clipping plane: what
                    // lies beyond is black, as Radiance renders it.
                    let mut aft = [f32::INFINITY; PACKET];
                    let mut n = 0;
                    for s in s..(s + PACKET as u32).min(spp) {
                        let (jx, jy) = rng.f32x2();
                        let (sx, sy) = if stratified {
                            (
                                ((s % strata) as f32 + jx) / strata as f32,
                                ((s / strata) as f32 + jy) / strata as f32,
                            )
                        } else {
                            (jx, jy)
                        };
                        let x = (col as f64 + f64::from(sx)) / w as f64;
                        let y = 1.0 - (row as f64 + f64::from(sy)) / h as f64;
                        if let Some((origin, dir)) = rays.ray(x, y) {
                            batch[n] = (origin.as_vec3(), dir.as_vec3());
                            aft[n] = view.aft_limit(origin, dir) as f32;
                            n += 1;
                        }
                    }
                    tracer.trace_together(&batch[..n], &mut rng, |k, sample| {
                        if sample.distance <= aft[k] {
                            sum += sample.radiance;
                        }
                    });
                    s += PACKET as u32;
                }
                out.push(sum / spp as f32);
            }
            let n = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress(n, h);
            out
        })
        .collect();
    Ok(Picture {
        width: w,
        height: h,
        pixels: rows.into_iter().flatten().collect(),
    })
}

/// Pixels of a `width` x `height` frame of `view` that straddle a silhouette:
/// the first hits of a 4 x 4 grid of rays through the pixel differ in depth
/// by more than `ratio` (nearest to farthest), or some hit and some escape.
/// The band where reconstructions from reprojected rays are hardest, so image
/// errors are reported there separately.
pub fn silhouettes(
    tracer: &Tracer,
    view: &View,
    width: u32,
    height: u32,
    ratio: f32,
) -> Result<Vec<bool>, PictureSizeError> {
    const N: u32 = 4;
    check_picture_size(u64::from(width), u64::from(height))?;
    let (w, h) = (width as usize, height as usize);
    let rays = view.rays();
    Ok((0..w * h)
        .into_par_iter()
        .map(|i| {
            let (col, row) = ((i % w) as f64, (i / w) as f64);
            let (mut near, mut far, mut escaped, mut hit) = (f32::INFINITY, 0.0f32, false, false);
            for k in 0..N * N {
                let (sx, sy) = (
                    (f64::from(k % N) + 0.5) / f64::from(N),
                    (f64::from(k / N) + 0.5) / f64::from(N),
                );
                let Some((origin, dir)) = rays.ray((col + sx) / w as f64, 1.0 - (row + sy) / h as f64) else {
                    continue;
                };
                match tracer.first_hit(&Ray::new(origin.as_vec3(), dir.as_vec3())) {
                    Some(t) => {
                        hit = true;
                        near = near.min(t);
                        far = far.max(t);
                    }
                    None => escaped = true,
                }
            }
            hit && (escaped || far > near * ratio)
        })
        .collect())
}
