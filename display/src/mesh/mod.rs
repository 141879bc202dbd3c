//! The paper's triangle-mesh driver (section 2.4.5): a 3-D mesh whose
//! vertices are the pixel estimates' world points and whose topology is a
//! Delaunay triangulation on the view sphere around a canonical eye
//! ([`crate::sphere`]), drawn Gouraud-shaded by the GPU.
//!
//! The mesh is kept across frames and across small moves: an estimate
//! that a view change carries to a new slot keeps its vertex (the store
//! says where each came from, [`Store::moved_from`]); a new estimate is
//! located on the sphere and inserted with edge flips; one in the same
//! direction as a vertex takes that vertex over (the better sample for
//! the direction); one far behind all its neighbours' depths is rejected
//! as a likely multidepth sample. The mesh is rebuilt around a new
//! canonical eye when the eye moves far from it, and after the store drops
//! its estimates on a large turn.

mod pipeline;
#[cfg(test)]
mod tests;

use std::sync::Arc;

use glam::{DVec3, Vec3};
use holodeck_protocol::{Picture, ViewType};
use rayon::prelude::*;

use crate::driver::{Driver, Viewport};
use crate::gpu::target::{black, downsample, fill_holes};
use crate::gpu::{GpuContext, GpuError, ViewUniform};
use crate::project::Projector;
use crate::sphere::{Insert, SphereMesh, VertexId};
use crate::splat::Grid;
use crate::store::{EstimatorOptions, PixelIndex, Store, NO_SLOT};
use pipeline::MeshPipeline;

/// Where escaped rays' vertices are put: this far from the canonical eye
/// along their direction (reversed depth keeps it drawable).
const SKY_DISTANCE: f64 = 1e6;
/// The mesh is rebuilt when the eye is farther than this share of the
/// median estimate depth from the canonical eye.
const REBUILD_SHARE: f64 = 0.05;
/// Directions closer than this share of a target pixel's angle are one
/// vertex.
const SAME_DIRECTION: f64 = 0.25;
/// A new estimate this many times deeper than every vertex of the small
/// triangle it falls in is taken for a multidepth sample.
const MULTIDEPTH_RATIO: f32 = 1.5;
/// ... where "small" is at most this many pixels across.
const MULTIDEPTH_PIXELS: f64 = 4.0;
/// A slot whose estimate took over a vertex another slot holds, or was
/// rejected: not drawn, not tried again until the next view change.
const PASSED: u32 = u32::MAX - 1;

/// One mesh vertex as the GPU reads it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct MeshVertex {
    /// World position relative to the canonical eye; w: distance from it
    /// (0 for a vertex without a sample: an octahedron corner).
    pub position: [f32; 4],
    /// Linear radiance.
    pub color: [f32; 4],
}

/// What the mesh driver has done, beyond the store's counters.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MeshDriverStats {
    /// Real vertices in the mesh.
    pub vertices: usize,
    /// Triangles drawn in the last frame (after frustum culling).
    pub drawn: usize,
    /// Triangles in the mesh.
    pub triangles: usize,
    /// Vertices inserted since the mesh was made or rebuilt.
    pub inserted: u64,
    /// Edge flips per insertion, on average.
    pub flips_per_insertion: f64,
    /// Estimates rejected as likely multidepth samples.
    pub multidepth: u64,
    /// Times the mesh was rebuilt around a new canonical eye.
    pub rebuilds: u64,
}

/// The GPU spherical Delaunay mesh driver.
#[derive(Debug)]
pub struct MeshDriver {
    /// In a web page, the last frame read back: shown while the next one
    /// is on its way from the GPU.
    shown: Option<Picture>,
    store: Store<Grid>,
    pipeline: MeshPipeline,
    sphere: SphereMesh,
    /// The eye the sphere is centered on; `None` until the first frame.
    canonical: Option<DVec3>,
    /// Vertex data by [`VertexId`].
    vertices: Vec<MeshVertex>,
    /// The vertex of each store slot ([`NO_SLOT`]: not in the mesh yet).
    slot_vertex: Vec<u32>,
    /// The store's drops seen, to rebuild after one.
    drops_seen: u64,
    indices: Vec<u32>,
    stats: MeshDriverStats,
}

impl MeshDriver {
    /// A driver on `gpu` for `viewport`.
    pub fn new(gpu: Arc<GpuContext>, viewport: Viewport, options: EstimatorOptions) -> MeshDriver {
        let store = Store::new(viewport, Grid::default(), true, options);
        let min_angle = SAME_DIRECTION * pixel_angle(&store);
        MeshDriver {
            shown: None,
            store,
            pipeline: MeshPipeline::new(gpu),
            sphere: SphereMesh::new(min_angle),
            canonical: None,
            vertices: Vec::new(),
            slot_vertex: Vec::new(),
            drops_seen: 0,
            indices: Vec::new(),
            stats: MeshDriverStats::default(),
        }
    }

    /// The mesh's counters.
    pub fn mesh_stats(&self) -> MeshDriverStats {
        let s = self.sphere.stats();
        MeshDriverStats {
            vertices: self.sphere.real_count(),
            triangles: self.sphere.triangle_count(),
            flips_per_insertion: if s.insertions > 0 { s.flips_per_insertion() } else { 0.0 },
            inserted: s.insertions,
            ..self.stats
        }
    }

    /// Forgets the mesh and centers the next one on `eye`.
    fn rebuild(&mut self, eye: DVec3) {
        if self.canonical.is_some() {
            self.stats.rebuilds += 1;
        }
        self.canonical = Some(eye);
        self.sphere = SphereMesh::new(SAME_DIRECTION * pixel_angle(&self.store));
        self.vertices.clear();
        self.slot_vertex.clear();
    }

    /// Brings the mesh up to date with the store's estimates.
    fn sync(&mut self) {
        let vp = self.store.viewport().clone();
        let eye = vp.view.position;
        let drops = self.store.stats().cache_drops;
        let moved = match self.canonical {
            None => true,
            Some(c) => (eye - c).length() > REBUILD_SHARE * median_depth(&self.store),
        };
        if moved || drops != self.drops_seen {
            self.drops_seen = drops;
            self.rebuild(eye);
        }
        let canonical = self.canonical.unwrap_or(eye);
        let sub = self.store.subpixels();
        let grid = Viewport {
            view: vp.view.clone(),
            width: vp.width * sub,
            height: vp.height * sub,
        };
        let projector = Projector::new(&grid);
        let index = self.store.index();
        let entries = self.store.entries();
        let colors = self.store.colors();
        // World points of every estimate (in parallel: the bulk of the work
        // for estimates that already have their vertex).
        let points: Vec<Option<DVec3>> = entries
            .par_iter()
            .map(|e| {
                let (col, row) = index.pixel(e.key);
                let (origin, dir) = projector.ray(col, row, e.estimate.centroid())?;
                let depth = e.estimate.depth();
                Some(if depth.is_finite() {
                    origin + dir * f64::from(depth)
                } else {
                    canonical + dir * SKY_DISTANCE
                })
            })
            .collect();
        self.slot_vertex.resize(entries.len(), NO_SLOT);
        let small = MULTIDEPTH_PIXELS * f64::from(sub) * pixel_angle(&self.store);
        for (slot, (point, color)) in points.iter().zip(colors).enumerate() {
            let Some(p) = *point else { continue };
            let rel = p - canonical;
            let data = MeshVertex {
                position: [rel.x as f32, rel.y as f32, rel.z as f32, rel.length() as f32],
                color: [color.x, color.y, color.z, 1.0],
            };
            match self.slot_vertex[slot] {
                PASSED => {}
                NO_SLOT => {
                    let vertices = &self.vertices;
                    let depth = data.position[3];
                    let accept = |tri: [VertexId; 3]| {
                        let around: Vec<&MeshVertex> = tri
                            .iter()
                            .filter_map(|&v| vertices.get(v as usize))
                            .filter(|v| v.position[3] > 0.0)
                            .collect();
                        let [Some(a), Some(b), Some(c)] = [around.first(), around.get(1), around.get(2)] else {
                            return true;
                        };
                        let deepest = a.position[3].max(b.position[3]).max(c.position[3]);
                        !(depth > MULTIDEPTH_RATIO * deepest && corner_angle([a, b, c]) <= small)
                    };
                    match self.sphere.insert_with(rel, accept) {
                        Ok(Insert::Added(v)) => {
                            let v = v as usize;
                            if self.vertices.len() <= v {
                                self.vertices.resize(v + 1, MeshVertex::default());
                            }
                            self.vertices[v] = data;
                            self.slot_vertex[slot] = v as u32;
                        }
                        Ok(Insert::Duplicate(v)) => {
                            // The better sample for the direction: the estimate
                            // on the current frame takes the vertex over.
                            if let Some(d) = self.vertices.get_mut(v as usize) {
                                *d = data;
                            }
                            self.slot_vertex[slot] = PASSED;
                        }
                        Ok(Insert::Rejected) => {
                            self.stats.multidepth += 1;
                            self.slot_vertex[slot] = PASSED;
                        }
                        Err(_) => self.slot_vertex[slot] = PASSED,
                    }
                }
                v => {
                    if let Some(d) = self.vertices.get_mut(v as usize) {
                        *d = data;
                    }
                }
            }
        }
    }

    /// The triangles to draw: those of real vertices, less those wholly
    /// outside the frame (frustum culling).
    fn visible_triangles(&mut self) {
        let vp = self.store.viewport();
        let canonical = self.canonical.unwrap_or(vp.view.position);
        let projector = vp.view.projector();
        let perspective = vp.view.kind == ViewType::Perspective;
        // Outcodes: left, right, below, above, behind (or unprojectable).
        let codes: Vec<u8> = self
            .vertices
            .par_iter()
            .map(|v| {
                if v.position[3] <= 0.0 {
                    return 0xff;
                }
                let p = canonical + Vec3::new(v.position[0], v.position[1], v.position[2]).as_dvec3();
                match projector.project(p) {
                    None => 16,
                    Some((x, y, _)) => {
                        u8::from(x < 0.0) | u8::from(x > 1.0) << 1 | u8::from(y < 0.0) << 2 | u8::from(y > 1.0) << 3
                    }
                }
            })
            .collect();
        self.indices.clear();
        for t in self.sphere.triangles() {
            let c = t.map(|v| codes.get(v as usize).copied().unwrap_or(0xff));
            if c.contains(&0xff) {
                continue;
            }
            if c[0] & c[1] & c[2] != 0 {
                continue;
            }
            // Non-perspective projections are not linear: a triangle with
            // a corner behind the eye would wrap across the frame.
            if !perspective && (c[0] | c[1] | c[2]) & 16 != 0 {
                continue;
            }
            self.indices.extend_from_slice(&t);
        }
        self.stats.drawn = self.indices.len() / 3;
    }
}

/// The angle a pixel of the store's sub-pixel grid spans at the frame's
/// center, radians (a parallel view's is taken at unit distance).
fn pixel_angle(store: &Store<Grid>) -> f64 {
    let vp = store.viewport();
    let across = match vp.view.kind {
        ViewType::Perspective => 2.0 * (vp.view.horizontal.to_radians() / 2.0).tan(),
        ViewType::Angular => vp.view.horizontal.to_radians(),
        ViewType::Hemispherical => 2.0 * (vp.view.horizontal.to_radians() / 2.0).sin(),
        ViewType::Parallel => vp.view.horizontal,
    };
    (across / f64::from((vp.width * store.subpixels()).max(1))).max(1e-9)
}

/// The largest angle between two of three vertices seen from the
/// canonical eye.
fn corner_angle(v: [&MeshVertex; 3]) -> f64 {
    let d = v.map(|v| {
        DVec3::new(
            f64::from(v.position[0]),
            f64::from(v.position[1]),
            f64::from(v.position[2]),
        )
    });
    let angle = |a: DVec3, b: DVec3| a.cross(b).length().atan2(a.dot(b));
    angle(d[0], d[1]).max(angle(d[1], d[2])).max(angle(d[0], d[2]))
}

/// The median depth of (a subset of) the store's estimates; 1 without any.
fn median_depth(store: &Store<Grid>) -> f64 {
    let entries = store.entries();
    let step = entries.len().div_ceil(4096).max(1);
    let mut d: Vec<f32> = entries
        .iter()
        .step_by(step)
        .map(|e| e.estimate.depth())
        .filter(|d| d.is_finite())
        .collect();
    if d.is_empty() {
        return 1.0;
    }
    let mid = d.len() / 2;
    f64::from(*d.select_nth_unstable_by(mid, f32::total_cmp).1)
}

impl Driver for MeshDriver {
    fn name(&self) -> &'static str {
        "mesh"
    }

    fn store(&self) -> &dyn crate::store::SampleStore {
        &self.store
    }

    fn store_mut(&mut self) -> &mut dyn crate::store::SampleStore {
        &mut self.store
    }

    fn set_view(&mut self, viewport: Viewport) {
        self.store.set_view(viewport);
        // Each estimate keeps the vertex it had under its old slot.
        let old = std::mem::take(&mut self.slot_vertex);
        self.slot_vertex = self
            .store
            .moved_from()
            .iter()
            .map(|&from| match old.get(from as usize) {
                Some(&v) if from != NO_SLOT && v != PASSED => v,
                _ => NO_SLOT,
            })
            .collect();
    }

    fn frame_pending(&self) -> bool {
        self.pipeline.pending()
    }

    fn render(&mut self) -> Picture {
        let start = web_time::Instant::now();
        self.store.update_colors();
        self.sync();
        self.visible_triangles();
        let vp = self.store.viewport().clone();
        let sub = self.store.subpixels();
        let (gw, gh) = (vp.width * sub, vp.height * sub);
        let canonical = self.canonical.unwrap_or(vp.view.position);
        let view = ViewUniform::new(&vp, canonical, gw, gh);
        let prepared = start.elapsed();
        match self.pipeline.draw(&view, gw, gh, &self.vertices, &self.indices) {
            Ok(mut rgba) => {
                let drawn = start.elapsed();
                fill_holes(&mut rgba, gw, gh);
                let picture = downsample(&rgba, vp.width, vp.height, sub);
                if cfg!(target_arch = "wasm32") {
                    self.shown = Some(picture.clone());
                }
                tracing::debug!(
                    "mesh frame: prepared and drawn in {:.1} ms ({:.1} ms on the GPU and reading back), finished in {:.1} ms",
                    drawn.as_secs_f64() * 1e3,
                    (drawn - prepared).as_secs_f64() * 1e3,
                    start.elapsed().as_secs_f64() * 1e3
                );
                picture
            }
            // A web page's frame still on the GPU: the last one meanwhile.
            Err(GpuError::NotReady) => self.shown.clone().unwrap_or_else(|| black(vp.width, vp.height)),
            Err(e) => {
                tracing::error!("mesh: {e}");
                black(vp.width, vp.height)
            }
        }
    }

    fn clear(&mut self) {
        self.store.clear();
        self.canonical = None;
        self.vertices.clear();
        self.slot_vertex.clear();
        self.sphere.clear();
    }

    fn heap_bytes(&self) -> usize {
        self.store.heap_bytes()
            + self.sphere.heap_bytes()
            + self.vertices.capacity() * std::mem::size_of::<MeshVertex>()
            + (self.slot_vertex.capacity() + self.indices.capacity()) * 4
    }
}
