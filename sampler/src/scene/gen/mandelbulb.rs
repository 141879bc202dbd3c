//! The power-8 Mandelbulb: the isosurface DE(p) = ε of its distance estimator
//! (ε = half a grid cell), sampled on a resolution³ grid over [-1.3, 1.3]³ and
//! extracted by marching tetrahedra (six tetrahedra per cube around its main
//! diagonal, so neighbouring cubes agree on every face). Vertices are keyed by
//! the grid edge they lie on, so the mesh is welded: a closed, consistently
//! oriented 2-manifold, every edge shared by exactly two triangles. Slabs of
//! the grid are sampled and triangulated in parallel. The bulb (a gold metal)
//! rests on a ground plane at z = 0 under the daylight sky, inside one exterior
//! section.

use glam::{DVec3, Vec3};
use holodeck_protocol::SectionKind;
use rayon::prelude::*;

use super::room::daylight;
use super::shapes::MeshBuf;
use super::{material, section_error, GenParams, Setting};
use crate::error::SceneError;
use crate::scene::builder::SceneBuilder;
use crate::scene::material::Material;
use crate::scene::section::box_section;
use crate::scene::Triangle;

/// Grid cells per axis when none is given.
pub const DEFAULT_RESOLUTION: u32 = 128;
/// Largest resolution accepted (the grid holds resolution³ samples).
pub const MAX_RESOLUTION: u32 = 1024;
/// Half the side of the sampled cube.
const EXTENT: f64 = 1.3;

/// Distance estimate from `p` to the power-8 Mandelbulb (negative or tiny inside).
pub fn distance(p: DVec3) -> f64 {
    let mut z = p;
    let (mut dr, mut r) = (1.0f64, 0.0f64);
    for _ in 0..12 {
        r = z.length();
        if r > 2.0 {
            break;
        }
        if r < 1e-12 {
            z = p;
            continue;
        }
        let theta = (z.z / r).clamp(-1.0, 1.0).acos() * 8.0;
        let phi = z.y.atan2(z.x) * 8.0;
        dr = r.powi(7) * 8.0 * dr + 1.0;
        let zr = r.powi(8);
        z = zr * DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()) + p;
    }
    if r < 1e-12 {
        return -1.0;
    }
    0.5 * r.ln() * r / dr
}

/// The closed surface mesh at `resolution` cells per axis, in bulb coordinates
/// (about [-1.2, 1.2]³): positions and triangles (vertex triples).
pub fn surface(resolution: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let n = resolution as usize;
    let p = n + 1;
    let cell = 2.0 * EXTENT / n as f64;
    let iso = 0.5 * cell;
    let at = |i: usize| -EXTENT + i as f64 * cell;
    // Field samples, z-major slabs; inside where negative. The outer layer is forced outside so the surface closes.
    let mut field = vec![0.0f32; p * p * p];
    field.par_chunks_mut(p * p).enumerate().for_each(|(k, slab)| {
        for j in 0..p {
            for i in 0..p {
                let border = i == 0 || j == 0 || k == 0 || i == n || j == n || k == n;
                let d = (distance(DVec3::new(at(i), at(j), at(k))) - iso) as f32;
                slab[j * p + i] = if border {
                    d.max(1e-6)
                } else if d == 0.0 {
                    1e-9
                } else {
                    d
                };
            }
        }
    });
    let index = |i: usize, j: usize, k: usize| (k * p + j) * p + i;
    // Edge key: 8 * (grid point at the low end) + direction mask (bit 0 x, bit 1 y, bit 2 z).
    let keyed: Vec<[u64; 3]> = (0..n)
        .into_par_iter()
        .flat_map_iter(|k| {
            let mut out = Vec::new();
            for j in 0..n {
                for i in 0..n {
                    let corner = |m: usize| index(i + (m & 1), j + (m >> 1 & 1), k + (m >> 2 & 1));
                    let values: [f32; 8] = std::array::from_fn(|m| field[corner(m)]);
                    let inside = values.iter().filter(|v| **v < 0.0).count();
                    if inside == 0 || inside == 8 {
                        continue;
                    }
                    for tet in TETS {
                        march(&tet, &values, |a, b| (corner(a) as u64) << 3 | (b ^ a) as u64, &mut out);
                    }
                }
            }
            out
        })
        .collect();
    let mut keys: Vec<u64> = keyed.par_iter().flat_map_iter(|t| t.iter().copied()).collect();
    keys.par_sort_unstable();
    keys.dedup();
    let positions: Vec<Vec3> = keys
        .par_iter()
        .map(|&key| {
            let a = (key >> 3) as usize;
            let (i, j, k) = (a % p, a / p % p, a / (p * p));
            let d = (key & 7) as usize;
            let b = index(i + (d & 1), j + (d >> 1 & 1), k + (d >> 2 & 1));
            let (fa, fb) = (f64::from(field[a]), f64::from(field[b]));
            let t = (fa / (fa - fb)).clamp(0.01, 0.99);
            let pa = DVec3::new(at(i), at(j), at(k));
            let pb = pa + cell * DVec3::new((d & 1) as f64, (d >> 1 & 1) as f64, (d >> 2 & 1) as f64);
            (pa + (pb - pa) * t).as_vec3()
        })
        .collect();
    let triangles: Vec<[u32; 3]> = keyed
        .par_iter()
        .map(|t| t.map(|key| keys.binary_search(&key).map_or(0, |v| v as u32)))
        .collect();
    (positions, triangles)
}

/// The six tetrahedra of a cube, as corner masks along a path from corner 0 to 7.
const TETS: [[usize; 4]; 6] = [
    [0, 1, 3, 7],
    [0, 1, 5, 7],
    [0, 2, 3, 7],
    [0, 2, 6, 7],
    [0, 4, 5, 7],
    [0, 4, 6, 7],
];

/// Corner position of mask `m` in a unit cube.
fn corner_pos(m: usize) -> DVec3 {
    DVec3::new((m & 1) as f64, (m >> 1 & 1) as f64, (m >> 2 & 1) as f64)
}

/// Emits the 0, 1 or 2 surface triangles of one tetrahedron (corner masks
/// `tet`, field `values` by mask) as edge-key triples, facing from inside
/// (negative) to outside. `key(a, b)` names the edge from mask a to mask b (a ⊂ b).
fn march(tet: &[usize; 4], values: &[f32; 8], key: impl Fn(usize, usize) -> u64, out: &mut Vec<[u64; 3]>) {
    let (ins, outs): (Vec<usize>, Vec<usize>) = tet.iter().partition(|&&m| values[m] < 0.0);
    let edge = |a: usize, b: usize| if a < b { (a, b) } else { (b, a) };
    let mid = |(a, b): (usize, usize)| (corner_pos(a) + corner_pos(b)) * 0.5;
    let centroid = |s: &[usize]| s.iter().map(|&m| corner_pos(m)).sum::<DVec3>() / s.len() as f64;
    let outward = if ins.is_empty() || outs.is_empty() {
        return;
    } else {
        centroid(&outs) - centroid(&ins)
    };
    let mut emit = |e: [(usize, usize); 3]| {
        // Orientation from the edge midpoints, never degenerate, so it is exact however thin the real triangle.
        let [a, b, c] = e.map(mid);
        let e = if (b - a).cross(c - a).dot(outward) > 0.0 {
            e
        } else {
            [e[0], e[2], e[1]]
        };
        out.push(e.map(|(a, b)| key(a, b)));
    };
    match (ins.len(), outs.len()) {
        (1, 3) => emit([edge(ins[0], outs[0]), edge(ins[0], outs[1]), edge(ins[0], outs[2])]),
        (3, 1) => emit([edge(outs[0], ins[0]), edge(outs[0], ins[1]), edge(outs[0], ins[2])]),
        _ => {
            // Two in (a, b), two out (c, d): the quad a-c, a-d, b-d, b-c.
            let (a, b, c, d) = (ins[0], ins[1], outs[0], outs[1]);
            let quad = [edge(a, c), edge(a, d), edge(b, d), edge(b, c)];
            emit([quad[0], quad[1], quad[2]]);
            emit([quad[0], quad[2], quad[3]]);
        }
    }
}

/// Adds the bulb on its ground plane; returns the daylight sky and an exterior section around the bulb.
pub fn add_mandelbulb(b: &mut SceneBuilder, params: &GenParams) -> Result<Setting, SceneError> {
    if params.triangles.is_some() {
        tracing::warn!("mandelbulb: --triangles does not apply (use --resolution); ignored");
    }
    let resolution = params.resolution.unwrap_or(DEFAULT_RESOLUTION);
    if !(4..=MAX_RESOLUTION).contains(&resolution) {
        return Err(SceneError::Invalid {
            what: "mandelbulb".to_string(),
            message: format!("resolution {resolution} must be in 4..={MAX_RESOLUTION}"),
        });
    }
    let bulb = material(
        b,
        "bulb",
        Material::Metal {
            color: [0.95, 0.72, 0.38],
            roughness: 0.25,
        },
    )?;
    let ground = material(b, "ground", Material::lambertian([0.45, 0.45, 0.43]))?;
    let (mut positions, tris) = surface(resolution);
    tracing::info!("mandelbulb: {} triangles at resolution {resolution}", tris.len());
    let (lo, hi) = positions
        .iter()
        .fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(l, h), p| {
            (l.min(*p), h.max(*p))
        });
    if tris.is_empty() {
        return Err(SceneError::Invalid {
            what: "mandelbulb".to_string(),
            message: "no surface found".to_string(),
        });
    }
    // Rest the bulb 1 cm above the ground plane at z = 0.
    let lift = Vec3::Z * (0.01 - lo.z);
    positions.par_iter_mut().for_each(|p| *p += lift);
    let triangles: Vec<Triangle> = tris.into_iter().map(|v| Triangle { v, material: bulb }).collect();
    b.add_world_mesh("mandelbulb", positions, triangles)?;
    let mut floor = MeshBuf::new();
    let g = 15.0;
    floor.quad(
        [
            Vec3::new(-g, -g, 0.0),
            Vec3::new(g, -g, 0.0),
            Vec3::new(g, g, 0.0),
            Vec3::new(-g, g, 0.0),
        ],
        Vec3::Z,
        ground,
    );
    floor.flush(b, "mandelbulb ground")?;
    let (lo, hi) = ((lo + lift).as_dvec3(), (hi + lift).as_dvec3());
    let m = 0.05;
    let size = [hi.x - lo.x + 2.0 * m, hi.y - lo.y + 2.0 * m, hi.z + m - 0.005];
    let section = box_section(SectionKind::Exterior, [lo.x - m, lo.y - m, 0.005], size)
        .map_err(|e| section_error("mandelbulb", e))?;
    Ok(Setting {
        sky: daylight(),
        sections: vec![section],
    })
}
