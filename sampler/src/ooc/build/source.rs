//! Where a build's triangles come from: a stream that can be replayed. A
//! scene already in memory streams its triangles; the built-in landscape and
//! Mandelbulb generate them tile by tile and slab by slab, so a scene of
//! hundreds of millions of triangles never exists in memory as a whole.

use glam::Vec3;
use holodeck_protocol::Section;

use super::super::OocError;
use std::sync::Mutex;

use crate::scene::gen::{landscape, mandelbulb, GenParams};
use crate::scene::{content_hash, Material, Scene, SceneBuilder, Sky};

/// One triangle on its way into the build.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RawTri {
    /// Vertices.
    pub v: [Vec3; 3],
    /// Material index.
    pub material: u32,
    /// Scene-wide id (its index in the stream).
    pub id: u32,
}

/// Bytes of a triangle in the build's spill files.
pub const RAW_BYTES: usize = 44;

impl RawTri {
    /// Appends the spill-file form.
    pub fn write(&self, out: &mut Vec<u8>) {
        for p in self.v {
            for c in p.to_array() {
                out.extend(c.to_bits().to_le_bytes());
            }
        }
        out.extend(self.material.to_le_bytes());
        out.extend(self.id.to_le_bytes());
    }
    /// Reads the spill-file form (`RAW_BYTES` bytes).
    pub fn read(b: &[u8]) -> RawTri {
        let w = |i: usize| u32::from_le_bytes([b[4 * i], b[4 * i + 1], b[4 * i + 2], b[4 * i + 3]]);
        let p = |k: usize| {
            Vec3::new(
                f32::from_bits(w(3 * k)),
                f32::from_bits(w(3 * k + 1)),
                f32::from_bits(w(3 * k + 2)),
            )
        };
        RawTri {
            v: [p(0), p(1), p(2)],
            material: w(9),
            id: w(10),
        }
    }
    /// Axis-aligned bounds.
    pub fn bounds(&self) -> crate::geom::Aabb {
        let mut b = crate::geom::Aabb::EMPTY;
        for p in self.v {
            b.grow(p);
        }
        b
    }
}

/// Everything about a scene except its triangles.
#[derive(Clone, Debug, Default)]
pub struct SceneMeta {
    /// Materials by index.
    pub materials: Vec<Material>,
    /// Their names.
    pub material_names: Vec<String>,
    /// The sky.
    pub sky: Sky,
    /// Sections.
    pub sections: Vec<Section>,
}

/// A replayable stream of triangles.
pub trait TriangleSource {
    /// Materials, sky and sections.
    fn meta(&self) -> &SceneMeta;
    /// Sends every triangle, in batches, in the same order each time.
    fn stream(&self, emit: &mut dyn FnMut(&[RawTri]) -> Result<(), OocError>) -> Result<(), OocError>;
    /// The content hash of the scene the stream makes (streams with no other
    /// identity hash their triangles as they go: see [`StreamHash`]).
    fn content_hash(&self) -> Option<String>;
    /// Triangles skipped before streaming (degenerate, not finite).
    fn skipped(&self) -> u64 {
        0
    }
    /// The sections, asked for after the first stream: a generated scene's
    /// sections may depend on where its geometry turned out to lie.
    fn sections(&self) -> Result<Vec<Section>, OocError> {
        Ok(self.meta().sections.clone())
    }
    /// The scene whose textures, maps and texture coordinates the file
    /// keeps (its triangle indices the stream's ids); `None` for untextured streams.
    fn textured(&self) -> Option<&Scene> {
        None
    }
}

/// Numbers streamed triangles and sends them on in batches, leaving out
/// degenerate ones as the in-core scene builder does.
struct Batcher {
    batch: Vec<RawTri>,
    next: u32,
}

impl Batcher {
    fn new() -> Batcher {
        Batcher {
            batch: Vec::with_capacity(1 << 15),
            next: 0,
        }
    }

    fn push(
        &mut self,
        v: [Vec3; 3],
        material: u32,
        emit: &mut dyn FnMut(&[RawTri]) -> Result<(), OocError>,
    ) -> Result<(), OocError> {
        if (v[1] - v[0]).cross(v[2] - v[0]).length_squared() > 0.0 {
            self.batch.push(RawTri {
                v,
                material,
                id: self.next,
            });
            self.next = self
                .next
                .checked_add(1)
                .ok_or_else(|| OocError::Build("more than 2^32 triangles".into()))?;
        }
        if self.batch.len() == self.batch.capacity() {
            emit(&self.batch)?;
            self.batch.clear();
        }
        Ok(())
    }

    fn finish(self, emit: &mut dyn FnMut(&[RawTri]) -> Result<(), OocError>) -> Result<(), OocError> {
        emit(&self.batch)
    }
}

/// The meta of a scene being built from generated parts.
fn meta_of(scene: &Scene) -> SceneMeta {
    SceneMeta {
        materials: scene.materials.clone(),
        material_names: scene.material_names.clone(),
        sky: scene.sky.clone(),
        sections: scene.sections.clone(),
    }
}

/// A scene in memory as a source; its content hash is the scene's own, so a
/// scene file and the `.hds` built from it serve the same holodecks.
pub struct SceneSource {
    scene: Scene,
    meta: SceneMeta,
}

impl SceneSource {
    /// Wraps a scene; a textured scene's file keeps its textures.
    pub fn new(scene: Scene) -> SceneSource {
        let meta = SceneMeta {
            materials: scene.materials.clone(),
            material_names: scene.material_names.clone(),
            sky: scene.sky.clone(),
            sections: scene.sections.clone(),
        };
        SceneSource { scene, meta }
    }
}

impl TriangleSource for SceneSource {
    fn meta(&self) -> &SceneMeta {
        &self.meta
    }
    fn textured(&self) -> Option<&Scene> {
        self.scene.maps.iter().any(|m| !m.is_empty()).then_some(&self.scene)
    }
    fn stream(&self, emit: &mut dyn FnMut(&[RawTri]) -> Result<(), OocError>) -> Result<(), OocError> {
        let mut batch = Vec::with_capacity(1 << 14);
        for (i, t) in self.scene.triangles.iter().enumerate() {
            batch.push(RawTri {
                v: self.scene.vertices(i),
                material: t.material,
                id: i as u32,
            });
            if batch.len() == batch.capacity() {
                emit(&batch)?;
                batch.clear();
            }
        }
        emit(&batch)
    }
    fn content_hash(&self) -> Option<String> {
        Some(content_hash(&self.scene))
    }
    fn skipped(&self) -> u64 {
        self.scene.stats.degenerate + self.scene.stats.non_finite
    }
}

/// The content hash of a streamed scene: BLAKE3 over every triangle's
/// vertices and material in stream order, then materials and sky.
pub struct StreamHash(blake3::Hasher);

impl Default for StreamHash {
    fn default() -> Self {
        let mut h = blake3::Hasher::new();
        h.update(b"holodeck scene stream v1");
        StreamHash(h)
    }
}

impl StreamHash {
    /// Hashes a batch.
    pub fn update(&mut self, batch: &[RawTri]) {
        let mut buf = Vec::with_capacity(batch.len() * 40);
        for t in batch {
            for p in t.v {
                for c in p.to_array() {
                    buf.extend(c.to_bits().to_le_bytes());
                }
            }
            buf.extend(t.material.to_le_bytes());
        }
        self.0.update(&buf);
    }
    /// The hash, `blake3:` and 64 hex digits.
    pub fn finish(mut self, meta: &SceneMeta) -> String {
        self.0.update(format!("{:?}", meta.materials).as_bytes());
        self.0.update(format!("{:?}", meta.sky).as_bytes());
        format!("blake3:{}", self.0.finalize().to_hex())
    }
}

/// The built-in landscape, generated tile by tile: the room, then terrain
/// rows, then trees, each from stateless hashes of (seed, index).
pub struct LandscapeSource {
    params: GenParams,
    meta: SceneMeta,
    room: Scene,
    ids: landscape::MaterialIds,
}

impl LandscapeSource {
    /// The landscape of about `params.triangles` triangles.
    pub fn new(params: GenParams) -> Result<LandscapeSource, OocError> {
        let err = |e: crate::SceneError| OocError::Build(format!("builtin:landscape: {e}"));
        let mut b = SceneBuilder::new();
        let ids = landscape::add_materials(&mut b).map_err(err)?;
        let room = crate::scene::gen::room::add_room(&mut b, &GenParams::default()).map_err(err)?;
        let setting = landscape::with_outdoors(room).map_err(err)?;
        b.sky(setting.sky).map_err(err)?;
        for s in setting.sections {
            b.section(s);
        }
        let room = b.finish();
        let meta = meta_of(&room);
        Ok(LandscapeSource {
            params,
            meta,
            room,
            ids,
        })
    }
}

impl TriangleSource for LandscapeSource {
    fn meta(&self) -> &SceneMeta {
        &self.meta
    }
    fn stream(&self, emit: &mut dyn FnMut(&[RawTri]) -> Result<(), OocError>) -> Result<(), OocError> {
        let mut out = Batcher::new();
        for i in 0..self.room.triangles.len() {
            out.push(self.room.vertices(i), self.room.triangles[i].material, emit)?;
        }
        landscape::stream(&self.params, self.ids, &mut |v, m| out.push(v, m, emit))?;
        out.finish(emit)
    }
    fn content_hash(&self) -> Option<String> {
        None
    }
}

/// The built-in Mandelbulb, marched two grid planes at a time (see
/// [`mandelbulb::for_each_slab`]): the same triangles in the same order as
/// the in-core generator, at resolutions no in-core scene could hold.
pub struct MandelbulbSource {
    resolution: u32,
    meta: SceneMeta,
    /// The ground plane.
    ground: Scene,
    bulb: u32,
    /// Bounds of the bulb before its lift, and the lift, once streamed.
    placed: Mutex<Option<(Vec3, Vec3, Vec3)>>,
}

impl MandelbulbSource {
    /// The bulb at `resolution` grid cells per axis.
    pub fn new(resolution: u32) -> Result<MandelbulbSource, OocError> {
        let err = |e: crate::SceneError| OocError::Build(format!("builtin:mandelbulb: {e}"));
        mandelbulb::check_resolution(resolution, mandelbulb::MAX_STREAM_RESOLUTION).map_err(err)?;
        let mut b = SceneBuilder::new();
        let (bulb, ground) = mandelbulb::add_materials(&mut b).map_err(err)?;
        mandelbulb::add_ground(&mut b, ground).map_err(err)?;
        b.sky(crate::scene::gen::room::daylight()).map_err(err)?;
        let ground = b.finish();
        Ok(MandelbulbSource {
            resolution,
            meta: meta_of(&ground),
            ground,
            bulb,
            placed: Mutex::new(None),
        })
    }
}

impl TriangleSource for MandelbulbSource {
    fn meta(&self) -> &SceneMeta {
        &self.meta
    }
    fn stream(&self, emit: &mut dyn FnMut(&[RawTri]) -> Result<(), OocError>) -> Result<(), OocError> {
        let mut out = Batcher::new();
        let mut lift = None;
        let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
        mandelbulb::for_each_slab(self.resolution, &mut |tris| {
            // Slabs come bottom up, so the first with a surface holds the lowest vertex.
            let Some(first) = tris.first() else {
                return Ok(());
            };
            let l = *lift
                .get_or_insert_with(|| mandelbulb::lift(tris.iter().flatten().fold(first[0].1.z, |z, v| z.min(v.1.z))));
            for t in tris {
                let v = t.map(|(_, p)| p);
                for p in v {
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
                out.push(v.map(|p| p + l), self.bulb, emit)?;
            }
            Ok(())
        })?;
        for i in 0..self.ground.triangles.len() {
            out.push(self.ground.vertices(i), self.ground.triangles[i].material, emit)?;
        }
        out.finish(emit)?;
        let lift = lift.ok_or_else(|| OocError::Build(format!("builtin:mandelbulb: {}", mandelbulb::no_surface())))?;
        *self.placed.lock().unwrap_or_else(|e| e.into_inner()) = Some((lo, hi, lift));
        Ok(())
    }
    fn content_hash(&self) -> Option<String> {
        None
    }
    fn sections(&self) -> Result<Vec<Section>, OocError> {
        let placed = *self.placed.lock().unwrap_or_else(|e| e.into_inner());
        let (lo, hi, lift) =
            placed.ok_or_else(|| OocError::Build("builtin:mandelbulb: sections asked for before streaming".into()))?;
        mandelbulb::setting(lo, hi, lift)
            .map(|s| s.sections)
            .map_err(|e| OocError::Build(format!("builtin:mandelbulb: {e}")))
    }
}
