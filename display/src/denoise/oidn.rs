//! Intel Open Image Denoise (OIDN), the denoiser Blender Cycles, Arnold and
//! most studios clean path-traced frames with: its `RT` filter in HDR mode,
//! with albedo and normal buffers where a renderer has them, as it is used
//! in practice. Behind the `oidn` cargo feature: it needs Intel's library
//! (see the README for where to get it).

use glam::Vec3;
use holodeck_protocol::Picture;

use super::{DenoiseError, Guide};

fn flat(p: &Picture) -> Vec<f32> {
    p.pixels
        .iter()
        .flat_map(|c| {
            if c.is_finite() {
                c.max(Vec3::ZERO).to_array()
            } else {
                [0.0; 3]
            }
        })
        .collect()
}

fn oidn_error(e: oidn::Error) -> DenoiseError {
    DenoiseError::Oidn(e.to_string())
}

/// `color` (linear HDR radiance) denoised by OIDN's `RT` filter, with the
/// auxiliary `albedo` (0..=1) and `normal` pictures of the same view where
/// given (OIDN takes a normal only beside an albedo).
pub fn denoise(color: &Picture, albedo: Option<&Picture>, normal: Option<&Picture>) -> Result<Picture, DenoiseError> {
    let (w, h) = (color.width, color.height);
    for aux in [albedo, normal].into_iter().flatten() {
        if (aux.width, aux.height) != (w, h) || aux.pixels.len() != w * h {
            return Err(DenoiseError::Oidn(format!(
                "an auxiliary picture is {}x{}, the colour {w}x{h}",
                aux.width, aux.height
            )));
        }
    }
    if w == 0 || h == 0 {
        return Ok(color.clone());
    }
    let device = oidn::Device::new().map_err(oidn_error)?;
    let mut filter = oidn::RayTracing::try_new(&device).map_err(oidn_error)?;
    filter.hdr(true).srgb(false).image_dimensions(w, h);
    match (albedo, normal) {
        (Some(a), Some(n)) => {
            let a = device.create_buffer(&flat(a)).map_err(oidn_error)?;
            let n = device.create_buffer(&flat_normal(n)).map_err(oidn_error)?;
            filter.albedo_normal_buffer(a, n).map_err(oidn_error)?;
        }
        (Some(a), None) => {
            let a = device.create_buffer(&flat(a)).map_err(oidn_error)?;
            filter.albedo_buffer(a).map_err(oidn_error)?;
        }
        (None, _) => {}
    }
    let input = flat(color);
    let mut output = vec![0.0f32; input.len()];
    filter.filter(&input, &mut output).map_err(oidn_error)?;
    device.get_error().map_err(oidn_error)?;
    Ok(Picture {
        width: w,
        height: h,
        pixels: output.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])).collect(),
    })
}

/// Normals as OIDN takes them: any length, values in -1..=1; non-finite
/// ones as zero.
fn flat_normal(p: &Picture) -> Vec<f32> {
    p.pixels
        .iter()
        .flat_map(|c| {
            if c.is_finite() {
                c.clamp(Vec3::splat(-1.0), Vec3::ONE).to_array()
            } else {
                [0.0; 3]
            }
        })
        .collect()
}

/// A display frame denoised by OIDN with the guide's normals and its
/// albedo where it has one (the store's rays carry none: then a constant
/// one, which OIDN needs beside a normal).
pub fn denoise_guided(color: &Picture, guide: &Guide) -> Result<Picture, DenoiseError> {
    let (w, h) = (color.width, color.height);
    if guide.width != w || guide.height != h {
        return Ok(color.clone());
    }
    let albedo = Picture {
        width: w,
        height: h,
        pixels: if guide.albedo.len() == w * h {
            guide.albedo.iter().map(|&a| Vec3::from_array(a)).collect()
        } else {
            vec![Vec3::splat(0.5); w * h]
        },
    };
    let normal = Picture {
        width: w,
        height: h,
        pixels: guide.normal.iter().map(|&n| Vec3::from_array(n)).collect(),
    };
    denoise(color, Some(&albedo), Some(&normal))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A picture of two flat halves (a lit wall and a shaded one) with
    /// uniform noise of half the value, deterministic.
    fn noisy_halves(w: usize, h: usize) -> (Picture, Picture) {
        let truth = |i: usize| if i % w < w / 2 { 2.0f32 } else { 0.2 };
        let mut z = 0x1234_5678u64;
        let mut noise = || {
            z ^= z << 13;
            z ^= z >> 7;
            z ^= z << 17;
            (z >> 11) as f32 / (1u64 << 53) as f32 - 0.5
        };
        let clean = Picture {
            width: w,
            height: h,
            pixels: (0..w * h).map(|i| Vec3::splat(truth(i))).collect(),
        };
        let noisy = Picture {
            width: w,
            height: h,
            pixels: (0..w * h).map(|i| Vec3::splat(truth(i) * (1.0 + noise()))).collect(),
        };
        (clean, noisy)
    }

    fn rmse(a: &Picture, b: &Picture) -> f32 {
        let s: f32 = a
            .pixels
            .iter()
            .zip(&b.pixels)
            .map(|(x, y)| (*x - *y).length_squared())
            .sum();
        (s / (3 * a.pixels.len()) as f32).sqrt()
    }

    #[test]
    fn noise_falls_and_each_half_keeps_its_light() {
        let (w, h) = (64, 48);
        let (clean, noisy) = noisy_halves(w, h);
        let albedo = Picture {
            width: w,
            height: h,
            pixels: vec![Vec3::splat(0.7); w * h],
        };
        let normal = Picture {
            width: w,
            height: h,
            pixels: vec![Vec3::Z; w * h],
        };
        let out = denoise(&noisy, Some(&albedo), Some(&normal)).unwrap();
        assert!(
            rmse(&out, &clean) < 0.5 * rmse(&noisy, &clean),
            "{} {}",
            rmse(&out, &clean),
            rmse(&noisy, &clean)
        );
        for side in [0..w / 2, w / 2..w] {
            let sum = |p: &Picture| -> f32 {
                (0..w * h)
                    .filter(|i| side.contains(&(i % w)))
                    .map(|i| p.pixels[i].x)
                    .sum()
            };
            let kept = sum(&out) / sum(&clean);
            assert!((kept - 1.0).abs() < 0.05, "{side:?}: {kept}");
        }
        // Colour alone works too; a mismatched auxiliary picture is an error.
        assert!(denoise(&noisy, None, None).is_ok());
        let small = Picture {
            width: 2,
            height: 2,
            pixels: vec![Vec3::ONE; 4],
        };
        assert!(matches!(
            denoise(&noisy, Some(&small), None),
            Err(DenoiseError::Oidn(_))
        ));
    }
}
