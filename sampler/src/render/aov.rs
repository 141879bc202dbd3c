//! A view's auxiliary pictures (AOVs) for denoisers: the albedo and the
//! normal of the first surface each pixel sees, averaged over the same
//! stratified sample positions the renderer uses, as Cycles and Arnold
//! write them for Open Image Denoise.

use glam::Vec3;
use holodeck_protocol::{check_picture_size, Picture, View};
use rayon::prelude::*;

use super::{RenderError, RenderOptions};
use crate::geom::Ray;
use crate::shade::{Rng, Tracer};

/// Positions per pixel the auxiliary pictures average (at most): enough to
/// anti-alias edges, which is all a denoiser asks of them.
pub const AOV_SAMPLES: u32 = 16;

/// The albedo (0..=1) and world-space normal (unit, facing the eye; zero
/// where the ray escapes) pictures of `view`, each pixel the mean over up
/// to [`AOV_SAMPLES`] positions stratified over it. A pixel whose rays
/// escape has albedo and normal zero.
pub fn render_aovs(tracer: &Tracer, view: &View, o: &RenderOptions) -> Result<(Picture, Picture), RenderError> {
    check_picture_size(u64::from(o.width), u64::from(o.height)).map_err(RenderError::Size)?;
    let (w, h) = (o.width as usize, o.height as usize);
    let n = o.spp.clamp(1, AOV_SAMPLES);
    let strata = (f64::from(n).sqrt() as u32).max(1);
    let rays = view.rays();
    let pixels: Vec<(Vec3, Vec3)> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (col, row) = (i % w, i / w);
            let mut rng = Rng::new(o.seed ^ 0xa0f5, i as u64);
            let (mut albedo, mut normal) = (Vec3::ZERO, Vec3::ZERO);
            for s in 0..strata * strata {
                let (jx, jy) = rng.f32x2();
                let sx = ((s % strata) as f32 + jx) / strata as f32;
                let sy = ((s / strata) as f32 + jy) / strata as f32;
                let x = (col as f64 + f64::from(sx)) / w as f64;
                let y = 1.0 - (row as f64 + f64::from(sy)) / h as f64;
                let Some((origin, dir)) = rays.ray(x, y) else { continue };
                if let Some(f) = tracer.first_surface(&Ray::new(origin.as_vec3(), dir.as_vec3())) {
                    albedo += f.albedo;
                    normal += f.normal;
                }
            }
            let k = (strata * strata) as f32;
            (albedo / k, normal / k)
        })
        .collect();
    let (albedo, normal): (Vec<Vec3>, Vec<Vec3>) = pixels.into_iter().unzip();
    Ok((
        Picture {
            width: w,
            height: h,
            pixels: albedo,
        },
        Picture {
            width: w,
            height: h,
            pixels: normal,
        },
    ))
}
