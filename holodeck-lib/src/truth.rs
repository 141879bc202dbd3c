//! A view's converged reference picture, made of two independent halves
//! that state its own noise, and the band around its silhouettes: what every
//! holodeck picture and every direct render is measured against (see
//! `holodeck_display::compare` for the measures).

use holodeck_display::compare::{Metrics, Yardstick};
use holodeck_display::tonemap::{ToneMap, ToneMode};
use holodeck_protocol::{Picture, View};
use holodeck_sampler::render::{render, silhouettes, RenderOptions};
use holodeck_sampler::Tracer;

use crate::Error;

/// What the functions here return.
type Result<T> = std::result::Result<T, Error>;

/// Depth ratio (farthest to nearest first hit within a pixel) that makes a
/// pixel a silhouette.
pub const SILHOUETTE_RATIO: f32 = 1.1;

/// A view's converged reference and its silhouette band.
pub struct Truth {
    /// The reference picture: the mean of its two halves.
    pub picture: Picture,
    /// The reference's tone map (camera mode), for SSIM and for pictures.
    pub tone: ToneMap,
    /// Every measure against the reference, its noise stated.
    pub yardstick: Yardstick,
}

impl Truth {
    /// The truth of `view` from two independent renders `halves` of it (see
    /// [`reference_halves`]): the reference is their mean, they state its
    /// noise, and the silhouettes are found by tracing the scene.
    pub fn new(tracer: &Tracer, view: &View, halves: (Picture, Picture)) -> Result<Truth> {
        let (a, b) = halves;
        let (w, h) = (a.width, a.height);
        let edges = silhouettes(tracer, view, w as u32, h as u32, SILHOUETTE_RATIO)?;
        let band = dilate(&edges, w, h);
        let mean = Picture {
            width: w,
            height: h,
            pixels: a.pixels.iter().zip(&b.pixels).map(|(&x, &y)| 0.5 * (x + y)).collect(),
        };
        let tone = ToneMap::from_picture(&mean, ToneMode::Camera);
        let yardstick = Yardstick::from_halves(&a, &b, tone.clone())?.with_band(band)?;
        Ok(Truth {
            picture: mean,
            tone,
            yardstick,
        })
    }

    /// The relative RMSE of `p` over the frame, for loops that need no more.
    pub fn rmse(&self, p: &Picture) -> Result<f64> {
        Ok(holodeck_display::compare::relative_rmse(p, &self.picture)?)
    }

    /// Every measure of `p` against the reference.
    pub fn measure(&self, p: &Picture) -> Result<Metrics> {
        Ok(self.yardstick.measure(p)?)
    }
}

/// A converged reference of `view` in two independent halves: each of
/// `spp / 2` samples per pixel (at least one) at `size`, with the random
/// sequences `seed` and `seed + 1`. [`Truth::new`] makes them one.
pub fn reference_halves(
    tracer: &Tracer,
    view: &View,
    size: (u32, u32),
    spp: u32,
    seed: u64,
) -> Result<(Picture, Picture)> {
    let half = |seed| -> Result<Picture> {
        let o = RenderOptions {
            width: size.0,
            height: size.1,
            spp: (spp / 2).max(1),
            seed,
        };
        Ok(render(tracer, view, &o, &|_, _| {})?)
    };
    Ok((half(seed)?, half(seed.wrapping_add(1))?))
}

/// The samples per pixel a reference of `view` at `size` takes to render
/// in about `secs` on this machine: a pass of two samples per pixel is
/// timed and the rest scaled from it (even, so the two halves are equal;
/// at least 2, at most 65,536).
pub fn spp_for_time(tracer: &Tracer, view: &View, size: (u32, u32), secs: f64) -> Result<u32> {
    let start = std::time::Instant::now();
    reference(tracer, view, size, 2, 0x7173)?;
    let per_pass = start.elapsed().as_secs_f64().max(1e-6) / 2.0;
    let spp = (secs / per_pass).clamp(2.0, 65_536.0) as u32;
    Ok(spp & !1)
}

/// A converged reference of `view`: `spp` samples per pixel at `size`,
/// with the random sequence `seed`.
pub fn reference(tracer: &Tracer, view: &View, size: (u32, u32), spp: u32, seed: u64) -> Result<Picture> {
    let o = RenderOptions {
        width: size.0,
        height: size.1,
        spp,
        seed,
    };
    Ok(render(tracer, view, &o, &|_, _| {})?)
}

/// A direct render of `view` at `width` x `height` with about `paths`
/// paths (rounded to whole samples per pixel): the picture, the seconds it
/// took and the paths traced. What a holodeck picture is worth is measured
/// against this, given the same paths.
pub fn direct_render(
    tracer: &Tracer,
    view: &View,
    (width, height): (u32, u32),
    paths: u64,
    seed: u64,
) -> Result<(Picture, f64, u64)> {
    let pixels = u64::from(width) * u64::from(height);
    let spp = (paths as f64 / pixels as f64).round().max(1.0) as u32;
    let start = std::time::Instant::now();
    let p = reference(tracer, view, (width, height), spp, seed)?;
    Ok((p, start.elapsed().as_secs_f64(), u64::from(spp) * pixels))
}

/// Pixels within one pixel of a marked one.
pub fn dilate(mask: &[bool], w: usize, h: usize) -> Vec<bool> {
    let mut out = vec![false; mask.len()];
    for row in 0..h {
        for col in 0..w {
            if !mask[row * w + col] {
                continue;
            }
            for r in row.saturating_sub(1)..=(row + 1).min(h - 1) {
                for c in col.saturating_sub(1)..=(col + 1).min(w - 1) {
                    out[r * w + c] = true;
                }
            }
        }
    }
    out
}

/// A walk of `n` views from `v`: each a `step` metres further along the
/// view's horizontal direction and turned `turn` degrees left about the
/// vertical, as someone walking and looking around.
pub fn walk(v: &View, n: usize, step: f64, turn: f64) -> Vec<View> {
    let flat = glam::DVec3::new(v.direction.x, v.direction.y, 0.0).normalize_or_zero();
    (0..n)
        .map(|i| {
            let (s, c) = (turn * i as f64).to_radians().sin_cos();
            let d = glam::DVec3::new(
                v.direction.x * c - v.direction.y * s,
                v.direction.x * s + v.direction.y * c,
                v.direction.z,
            );
            View {
                position: v.position + flat * (step * i as f64),
                direction: d.normalize(),
                ..v.clone()
            }
        })
        .collect()
}

/// The LOD ratio C of Áfra 2012, eq. (3), for `pixels` pixels of error: a
/// voxel of radius R at distance t stands in for its subtree when R <= t C,
/// i.e. when its projected radius is below that of a disc of `pixels` area.
pub fn lod_ratio(pixels: f64, view: &View, width: u32) -> f32 {
    if pixels <= 0.0 {
        return 0.0;
    }
    let r_max = (pixels / std::f64::consts::PI).sqrt();
    // lambda = (w / 2) / tan(fov / 2): pixels per unit of tangent.
    let half = (view.horizontal.to_radians() / 2.0).tan().max(1e-6);
    let lambda = f64::from(width) / 2.0 / half;
    (r_max / lambda) as f32
}

/// The albedo of the surfaces `view` sees at `size`, each pixel the mean
/// over 4 positions in it: what a display with the scene guides OIDN by.
pub fn scene_albedo(tracer: &Tracer, view: &View, size: (u32, u32), seed: u64) -> Result<Picture> {
    let o = RenderOptions {
        width: size.0,
        height: size.1,
        spp: 4,
        seed,
    };
    Ok(holodeck_sampler::render::render_aovs(tracer, view, &o)?.0)
}

/// `picture` cleaned by Open Image Denoise with its albedo and normals.
#[cfg(feature = "oidn")]
pub fn denoise_oidn(
    picture: &holodeck_protocol::Picture,
    albedo: &holodeck_protocol::Picture,
    normal: &holodeck_protocol::Picture,
) -> std::result::Result<holodeck_protocol::Picture, holodeck_display::denoise::DenoiseError> {
    holodeck_display::denoise::oidn::denoise(picture, Some(albedo), Some(normal))
}

/// Without the `oidn` feature there is nothing to clean with: always
/// [`DenoiseError::NoOidn`](holodeck_display::denoise::DenoiseError::NoOidn).
#[cfg(not(feature = "oidn"))]
pub fn denoise_oidn(
    _: &holodeck_protocol::Picture,
    _: &holodeck_protocol::Picture,
    _: &holodeck_protocol::Picture,
) -> std::result::Result<holodeck_protocol::Picture, holodeck_display::denoise::DenoiseError> {
    Err(holodeck_display::denoise::DenoiseError::NoOidn)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dilation_marks_the_eight_neighbours_and_stays_in_the_frame() {
        let mut mask = vec![false; 5 * 4];
        mask[0] = true;
        mask[2 * 5 + 3] = true;
        let d = dilate(&mask, 5, 4);
        let marked: Vec<usize> = (0..d.len()).filter(|&i| d[i]).collect();
        assert_eq!(marked, vec![0, 1, 5, 6, 7, 8, 9, 12, 13, 14, 17, 18, 19]);
    }

    /// A reference sized by time: the samples per pixel are even and at
    /// least 2, and a time far longer than a pass buys many.
    #[test]
    fn a_reference_time_buys_even_samples_per_pixel() {
        let scene = crate::load("builtin:room", None).unwrap();
        let tracer = Tracer::new(scene, Default::default());
        let view = View::parse("-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56").unwrap();
        assert_eq!(spp_for_time(&tracer, &view, (16, 12), 0.0).unwrap(), 2);
        // A pass of 384 paths takes far less than a second anywhere.
        let many = spp_for_time(&tracer, &view, (16, 12), 10.0).unwrap();
        assert!(many.is_multiple_of(2) && many > 20, "{many}");
    }
}
