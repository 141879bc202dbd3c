//! The landscape: the furnished room, its window looking east onto rolling
//! terrain (an fBm heightfield, flat under the room and rising into hills away
//! from it) covered by a forest of low-poly trees (a six-sided trunk under two
//! cone tiers). About 40% of the triangle budget goes to the terrain and the
//! rest to trees; the terrain grows with the forest so tree density stays
//! near one per 25 m². Everything is written in parallel into vectors sized
//! exactly in advance, from stateless hashes of (seed, index): the same seed
//! gives the same scene on any number of threads, and 100M+ triangles fit in
//! about 2.5 GB.

use glam::Vec3;
use rayon::prelude::*;

use super::noise::{fbm, hash, unit};
use super::shapes::{cone_triangles, cone_vertices, prism_triangles, prism_vertices, write_cone, write_prism};
use super::{add_room, material, GenParams, Setting};
use crate::error::SceneError;
use crate::scene::builder::SceneBuilder;
use crate::scene::material::Material;
use crate::scene::Triangle;

/// Triangles asked for when no count is given.
pub const DEFAULT_TRIANGLES: u64 = 1_000_000;
/// Sides of a trunk and of a crown tier.
const TRUNK_SIDES: usize = 6;
const CROWN_SIDES: usize = 8;
/// Vertices and triangles of one tree.
const TREE_VERTICES: usize = prism_vertices(TRUNK_SIDES) + 2 * cone_vertices(CROWN_SIDES);
const TREE_TRIANGLES: usize = prism_triangles(TRUNK_SIDES) + 2 * cone_triangles(CROWN_SIDES);
/// Triangles kept back for the room.
const ROOM_BUDGET: u64 = 1_700;
/// Room center (x, y); no trees within `CLEARING` meters of it.
const ROOM_CENTER: [f32; 2] = [3.0, 2.0];
const CLEARING: f32 = 14.0;

/// How the budget is spent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Plan {
    /// Terrain quads per side.
    pub cells: u32,
    /// Trees.
    pub trees: u64,
    /// Terrain side length, meters.
    pub size_m: u32,
}

/// The plan for about `triangles` triangles in all.
pub fn plan(triangles: u64) -> Plan {
    let budget = triangles
        .saturating_sub(ROOM_BUDGET)
        .max(2 * 2 * 2 + TREE_TRIANGLES as u64);
    let cells = (((budget as f64 * 0.4) / 2.0).sqrt().floor() as u64).clamp(2, 60_000) as u32;
    let trees = (budget - 2 * u64::from(cells) * u64::from(cells)) / TREE_TRIANGLES as u64;
    let size_m = (5.0 * (trees as f64).sqrt()).max(100.0).ceil() as u32;
    Plan { cells, trees, size_m }
}

/// Terrain height at (x, y): -5 cm within 8 m of the room (under its floor),
/// rising to fBm hills of about ±12 m from 60 m out.
pub fn height(seed: u64, x: f32, y: f32) -> f32 {
    let d = ((x - ROOM_CENTER[0]).powi(2) + (y - ROOM_CENTER[1]).powi(2)).sqrt();
    let t = ((d - 8.0) / 52.0).clamp(0.0, 1.0);
    let ramp = t * t * (3.0 - 2.0 * t);
    let hills = 12.0 * fbm(seed, x / 150.0, y / 150.0, 6) + 2.0;
    -0.05 + ramp * hills
}

/// The landscape's own materials.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MaterialIds {
    /// The terrain.
    pub grass: u32,
    /// Tree trunks.
    pub bark: u32,
    /// Tree crowns.
    pub foliage: u32,
}

/// Adds (or finds) the landscape's materials.
pub fn add_materials(b: &mut SceneBuilder) -> Result<MaterialIds, SceneError> {
    Ok(MaterialIds {
        grass: material(b, "grass", Material::lambertian([0.16, 0.28, 0.08]))?,
        bark: material(b, "bark", Material::lambertian([0.3, 0.2, 0.12]))?,
        foliage: material(b, "foliage", Material::lambertian([0.07, 0.2, 0.06]))?,
    })
}

/// Where the terrain lies and how it is cut.
struct Layout {
    n: usize,
    origin: [f32; 2],
    half: f32,
    step: f32,
}

impl Layout {
    fn new(plan: &Plan) -> Layout {
        let half = plan.size_m as f32 / 2.0;
        Layout {
            n: plan.cells as usize,
            origin: [ROOM_CENTER[0] - half, ROOM_CENTER[1] - half],
            half,
            step: plan.size_m as f32 / plan.cells as f32,
        }
    }
    fn vertex(&self, seed: u64, i: usize, j: usize) -> Vec3 {
        let (x, y) = (
            self.origin[0] + i as f32 * self.step,
            self.origin[1] + j as f32 * self.step,
        );
        Vec3::new(x, y, height(seed, x, y))
    }
}

/// Writes tree `k` into `pos` and `tris` (vertex indices from `first`).
#[allow(clippy::too_many_arguments)]
fn write_tree(seed: u64, k: usize, l: &Layout, first: u32, pos: &mut [Vec3], tris: &mut [Triangle], ids: MaterialIds) {
    let tree_seed = hash(seed, 0x7EE5);
    let r = |salt: u64| unit(tree_seed, (k as u64) << 4 | salt);
    let (mut x, mut y) = (l.origin[0] + r(0) * 2.0 * l.half, l.origin[1] + r(1) * 2.0 * l.half);
    let (dx, dy) = (x - ROOM_CENTER[0], y - ROOM_CENTER[1]);
    let d = (dx * dx + dy * dy).sqrt();
    if d < CLEARING {
        // Push trees out of the clearing around the room, keeping their direction.
        let (ux, uy) = if d > 1e-3 { (dx / d, dy / d) } else { (1.0, 0.0) };
        let out = CLEARING + r(2) * 10.0;
        (x, y) = (ROOM_CENTER[0] + ux * out, ROOM_CENTER[1] + uy * out);
    }
    let ground = height(seed, x, y);
    let scale = 0.7 + 0.8 * r(3);
    let trunk_h = 2.5 * scale;
    let base = Vec3::new(x, y, ground - 0.3);
    let (tp, cp) = pos.split_at_mut(prism_vertices(TRUNK_SIDES));
    let (tt, ct) = tris.split_at_mut(prism_triangles(TRUNK_SIDES));
    write_prism(tp, tt, first, base, 0.18 * scale, trunk_h, ids.bark);
    let (c1p, c2p) = cp.split_at_mut(cone_vertices(CROWN_SIDES));
    let (c1t, c2t) = ct.split_at_mut(cone_triangles(CROWN_SIDES));
    let crown_r = (1.4 + 0.8 * r(4)) * scale;
    let lower = base + Vec3::Z * (trunk_h * 0.6 + 0.3);
    let first2 = first + prism_vertices(TRUNK_SIDES) as u32;
    write_cone(c1p, c1t, first2, lower, crown_r, 3.5 * scale, ids.foliage);
    let upper = lower + Vec3::Z * (1.8 * scale);
    write_cone(
        c2p,
        c2t,
        first2 + cone_vertices(CROWN_SIDES) as u32,
        upper,
        crown_r * 0.7,
        3.0 * scale,
        ids.foliage,
    );
}

/// Adds the room, the terrain and the forest; returns the room's daylight sky,
/// its section and one outdoors ([`with_outdoors`]).
pub fn add_landscape(b: &mut SceneBuilder, params: &GenParams) -> Result<Setting, SceneError> {
    if params.resolution.is_some() {
        tracing::warn!("landscape: --resolution does not apply; ignored");
    }
    let plan = plan(params.triangles.unwrap_or(DEFAULT_TRIANGLES));
    let ids = add_materials(b)?;
    tracing::info!(
        "landscape: {} x {} terrain cells over {} m, {} trees",
        plan.cells,
        plan.cells,
        plan.size_m,
        plan.trees
    );

    let l = Layout::new(&plan);
    let n = l.n;
    let terrain_vertices = (n + 1) * (n + 1);
    let tree_count = usize::try_from(plan.trees).map_err(|_| too_big())?;
    let vertex_count = terrain_vertices + tree_count * TREE_VERTICES;
    let triangle_count = 2 * n * n + tree_count * TREE_TRIANGLES;
    // Checked before allocating: the scene could not hold more anyway.
    if u32::try_from(vertex_count).is_err() || triangle_count > crate::scene::builder::MAX_TRIANGLES {
        return Err(too_big());
    }
    let mut positions = vec![Vec3::ZERO; vertex_count];
    let mut triangles = vec![
        Triangle {
            v: [0; 3],
            material: ids.grass
        };
        triangle_count
    ];
    let (terrain_pos, tree_pos) = positions.split_at_mut(terrain_vertices);
    let (terrain_tris, tree_tris) = triangles.split_at_mut(2 * n * n);
    let seed = params.seed;

    terrain_pos.par_chunks_mut(n + 1).enumerate().for_each(|(j, row)| {
        for (i, p) in row.iter_mut().enumerate() {
            *p = l.vertex(seed, i, j);
        }
    });
    terrain_tris.par_chunks_mut(2 * n).enumerate().for_each(|(j, row)| {
        let w = (n + 1) as u32;
        for i in 0..n {
            let v00 = j as u32 * w + i as u32;
            let (v10, v01, v11) = (v00 + 1, v00 + w, v00 + w + 1);
            row[2 * i] = Triangle {
                v: [v00, v10, v11],
                material: ids.grass,
            };
            row[2 * i + 1] = Triangle {
                v: [v00, v11, v01],
                material: ids.grass,
            };
        }
    });
    tree_pos
        .par_chunks_mut(TREE_VERTICES)
        .zip(tree_tris.par_chunks_mut(TREE_TRIANGLES))
        .enumerate()
        .for_each(|(k, (pos, tris))| {
            let first = (terrain_vertices + k * TREE_VERTICES) as u32;
            write_tree(seed, k, &l, first, pos, tris, ids);
        });
    b.add_world_mesh("landscape terrain and trees", positions, triangles)?;
    with_outdoors(add_room(b, &GenParams::default())?)
}

/// The room's setting with a second section outdoors, over the clearing east
/// of its window (x 7 to 15 m, y 0.5 to 3.5 m, eye heights 1.2 to 2.2 m):
/// a walk can leave the room and go on across the terrain.
pub fn with_outdoors(mut room: Setting) -> Result<Setting, SceneError> {
    let outdoors = crate::scene::section::box_section(
        holodeck_protocol::SectionKind::Interior,
        [7.0, 0.5, 1.2],
        [8.0, 3.0, 1.0],
    )
    .map_err(|e| super::section_error("landscape outdoor", e))?;
    room.sections.push(outdoors);
    Ok(room)
}

/// Streams the terrain and the forest of the landscape (not the room),
/// triangle by triangle, a row or a few hundred trees generated at a time in
/// parallel: nothing is held beyond one batch. The same triangles as
/// [`add_landscape`], in the same order.
pub fn stream<E>(
    params: &GenParams,
    ids: MaterialIds,
    emit: &mut dyn FnMut([Vec3; 3], u32) -> Result<(), E>,
) -> Result<(), E> {
    let plan = plan(params.triangles.unwrap_or(DEFAULT_TRIANGLES));
    let l = Layout::new(&plan);
    let (n, seed) = (l.n, params.seed);
    let mut lower: Vec<Vec3> = (0..=n).into_par_iter().map(|i| l.vertex(seed, i, 0)).collect();
    for j in 0..n {
        let upper: Vec<Vec3> = (0..=n).into_par_iter().map(|i| l.vertex(seed, i, j + 1)).collect();
        for i in 0..n {
            let (v00, v10, v01, v11) = (lower[i], lower[i + 1], upper[i], upper[i + 1]);
            emit([v00, v10, v11], ids.grass)?;
            emit([v00, v11, v01], ids.grass)?;
        }
        lower = upper;
    }
    const BATCH: usize = 4096;
    let trees = plan.trees as usize;
    for start in (0..trees).step_by(BATCH) {
        let end = (start + BATCH).min(trees);
        let made: Vec<(Vec<Vec3>, Vec<Triangle>)> = (start..end)
            .into_par_iter()
            .map(|k| {
                let mut pos = vec![Vec3::ZERO; TREE_VERTICES];
                let mut tris = vec![
                    Triangle {
                        v: [0; 3],
                        material: ids.bark
                    };
                    TREE_TRIANGLES
                ];
                write_tree(seed, k, &l, 0, &mut pos, &mut tris, ids);
                (pos, tris)
            })
            .collect();
        for (pos, tris) in made {
            for t in tris {
                emit(t.v.map(|v| pos[v as usize]), t.material)?;
            }
        }
    }
    Ok(())
}

fn too_big() -> SceneError {
    SceneError::Invalid {
        what: "landscape".to_string(),
        message: format!(
            "too many triangles for one in-core scene ({} at most)",
            crate::scene::builder::MAX_TRIANGLES
        ),
    }
}
