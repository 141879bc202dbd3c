//! The power-8 Mandelbulb: the isosurface DE(p) = ε of its distance estimator
//! (ε = half a grid cell), sampled on a resolution³ grid over [-1.3, 1.3]³ and
//! extracted by marching tetrahedra (six tetrahedra per cube around its main
//! diagonal, so neighbouring cubes agree on every face). Vertices are keyed by
//! the grid edge they lie on, so the mesh is welded: a closed, consistently
//! oriented 2-manifold, every edge shared by exactly two triangles. The grid
//! is sampled two planes at a time and each slab between them triangulated in
//! parallel, so the surface can be streamed at any resolution without holding
//! the grid or the mesh. The bulb (a gold metal) rests on a ground plane at
//! z = 0 under the daylight sky, inside one exterior section.

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

/// Most cells per axis when the bulb is streamed into a scene-file build: the
/// grid is sampled two planes at a time (2 x 256 MiB here), and the surface
/// has about 2 billion triangles, half of what triangle ids can number.
pub const MAX_STREAM_RESOLUTION: u32 = 8_192;

/// One surface triangle as it leaves a slab: per corner, the key of the grid
/// edge it lies on (`8 * low grid point + direction mask`) and its position.
pub type SlabTriangle = [(u64, Vec3); 3];

/// The sampling grid over [-EXTENT, EXTENT]³.
struct Grid {
    /// Cells per axis.
    n: usize,
    /// Grid points per axis.
    p: usize,
    cell: f64,
    iso: f64,
}

impl Grid {
    fn new(resolution: u32) -> Grid {
        let n = resolution as usize;
        let cell = 2.0 * EXTENT / n as f64;
        Grid {
            n,
            p: n + 1,
            cell,
            iso: 0.5 * cell,
        }
    }

    fn at(&self, i: usize) -> f64 {
        -EXTENT + i as f64 * self.cell
    }

    /// Field samples of grid plane `k`, row by row; inside where negative. The
    /// outer layer is forced outside so the surface closes.
    fn plane(&self, k: usize) -> Vec<f32> {
        let (n, p) = (self.n, self.p);
        let mut plane = vec![0.0f32; p * p];
        plane.par_chunks_mut(p).enumerate().for_each(|(j, row)| {
            for (i, out) in row.iter_mut().enumerate() {
                let border = i == 0 || j == 0 || k == 0 || i == n || j == n || k == n;
                let d = (distance(DVec3::new(self.at(i), self.at(j), self.at(k))) - self.iso) as f32;
                *out = if border {
                    d.max(1e-6)
                } else if d == 0.0 {
                    1e-9
                } else {
                    d
                };
            }
        });
        plane
    }

    /// The surface triangles of slab `k` (between planes `k` and `k + 1`,
    /// given as `planes`), in row, cell, tetrahedron order.
    fn slab(&self, k: usize, planes: [&[f32]; 2]) -> Vec<SlabTriangle> {
        let (n, p) = (self.n, self.p);
        let value = |i: usize, j: usize, dz: usize| planes[dz][j * p + i];
        let position = |key: u64| {
            let a = (key >> 3) as usize;
            let (i, j, kk) = (a % p, a / p % p, a / (p * p));
            let d = (key & 7) as usize;
            let (dx, dy, dz) = (d & 1, d >> 1 & 1, d >> 2 & 1);
            let (fa, fb) = (
                f64::from(value(i, j, kk - k)),
                f64::from(value(i + dx, j + dy, kk - k + dz)),
            );
            let t = (fa / (fa - fb)).clamp(0.01, 0.99);
            let pa = DVec3::new(self.at(i), self.at(j), self.at(kk));
            let pb = pa + self.cell * DVec3::new(dx as f64, dy as f64, dz as f64);
            (pa + (pb - pa) * t).as_vec3()
        };
        (0..n)
            .into_par_iter()
            .flat_map_iter(|j| {
                let mut keys = Vec::new();
                for i in 0..n {
                    let values: [f32; 8] = std::array::from_fn(|m| value(i + (m & 1), j + (m >> 1 & 1), m >> 2 & 1));
                    let inside = values.iter().filter(|v| **v < 0.0).count();
                    if inside == 0 || inside == 8 {
                        continue;
                    }
                    let corner = |m: usize| ((k + (m >> 2 & 1)) * p + j + (m >> 1 & 1)) * p + i + (m & 1);
                    for tet in TETS {
                        march(
                            &tet,
                            &values,
                            |a, b| (corner(a) as u64) << 3 | (b ^ a) as u64,
                            &mut keys,
                        );
                    }
                }
                keys.into_iter().map(move |t| t.map(|key| (key, position(key))))
            })
            .collect()
    }
}

/// Samples the grid at `resolution` cells per axis two planes at a time and
/// hands each slab's surface triangles to `f`, bottom (lowest z) to top:
/// the whole surface in bulb coordinates (about [-1.2, 1.2]³), never held
/// at once. Triangles sharing a grid edge get bit-identical vertices.
pub fn for_each_slab<E>(resolution: u32, f: &mut dyn FnMut(&[SlabTriangle]) -> Result<(), E>) -> Result<(), E> {
    let grid = Grid::new(resolution);
    let mut lower = grid.plane(0);
    for k in 0..grid.n {
        let upper = grid.plane(k + 1);
        f(&grid.slab(k, [&lower, &upper]))?;
        lower = upper;
    }
    Ok(())
}

/// The closed surface mesh at `resolution` cells per axis, in bulb coordinates
/// (about [-1.2, 1.2]³): positions and triangles (vertex triples), welded by
/// grid edge.
pub fn surface(resolution: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut keyed: Vec<[u64; 3]> = Vec::new();
    let mut vertices: Vec<(u64, Vec3)> = Vec::new();
    let _ = for_each_slab::<std::convert::Infallible>(resolution, &mut |tris| {
        keyed.extend(tris.iter().map(|t| t.map(|(key, _)| key)));
        let start = vertices.len();
        vertices.extend(tris.iter().flatten());
        vertices[start..].sort_unstable_by_key(|v| v.0);
        let mut slab = vertices.split_off(start);
        slab.dedup_by_key(|v| v.0);
        vertices.extend(slab);
        Ok(())
    });
    // Slabs share the vertices of the plane between them.
    vertices.par_sort_unstable_by_key(|v| v.0);
    vertices.dedup_by_key(|v| v.0);
    let triangles: Vec<[u32; 3]> = keyed
        .par_iter()
        .map(|t| t.map(|key| vertices.binary_search_by_key(&key, |v| v.0).map_or(0, |v| v as u32)))
        .collect();
    (vertices.into_iter().map(|v| v.1).collect(), triangles)
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

/// Checks a resolution against `max`.
pub fn check_resolution(resolution: u32, max: u32) -> Result<(), SceneError> {
    if (4..=max).contains(&resolution) {
        Ok(())
    } else {
        Err(SceneError::Invalid {
            what: "mandelbulb".to_string(),
            message: format!("resolution {resolution} must be in 4..={max}"),
        })
    }
}

/// Adds (or finds) the bulb's and the ground's materials: (bulb, ground).
pub fn add_materials(b: &mut SceneBuilder) -> Result<(u32, u32), SceneError> {
    let bulb = material(
        b,
        "bulb",
        Material::Metal {
            color: [0.95, 0.72, 0.38],
            roughness: 0.25,
        },
    )?;
    let ground = material(b, "ground", Material::lambertian([0.45, 0.45, 0.43]))?;
    Ok((bulb, ground))
}

/// Adds the ground plane at z = 0.
pub fn add_ground(b: &mut SceneBuilder, ground: u32) -> Result<(), SceneError> {
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
    floor.flush(b, "mandelbulb ground")
}

/// The lift that rests a bulb whose lowest vertex is at `lowest_z` 1 cm above the ground.
pub fn lift(lowest_z: f32) -> Vec3 {
    Vec3::Z * (0.01 - lowest_z)
}

/// The daylight sky and an exterior section around the bulb, given the
/// bounds of its vertices before `lift`.
pub fn setting(lo: Vec3, hi: Vec3, lift: Vec3) -> Result<Setting, SceneError> {
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

/// The error for a grid that holds no surface.
pub fn no_surface() -> SceneError {
    SceneError::Invalid {
        what: "mandelbulb".to_string(),
        message: "no surface found".to_string(),
    }
}

/// Adds the bulb on its ground plane; returns the daylight sky and an exterior section around the bulb.
pub fn add_mandelbulb(b: &mut SceneBuilder, params: &GenParams) -> Result<Setting, SceneError> {
    if params.triangles.is_some() {
        tracing::warn!("mandelbulb: --triangles does not apply (use --resolution); ignored");
    }
    let resolution = params.resolution.unwrap_or(DEFAULT_RESOLUTION);
    check_resolution(resolution, MAX_RESOLUTION)?;
    let (bulb, ground) = add_materials(b)?;
    let (mut positions, tris) = surface(resolution);
    tracing::info!("mandelbulb: {} triangles at resolution {resolution}", tris.len());
    let (lo, hi) = positions
        .iter()
        .fold((Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)), |(l, h), p| {
            (l.min(*p), h.max(*p))
        });
    if tris.is_empty() {
        return Err(no_surface());
    }
    let lift = lift(lo.z);
    positions.par_iter_mut().for_each(|p| *p += lift);
    let triangles: Vec<Triangle> = tris.into_iter().map(|v| Triangle { v, material: bulb }).collect();
    b.add_world_mesh("mandelbulb", positions, triangles)?;
    add_ground(b, ground)?;
    setting(lo, hi, lift)
}
