//! Where a build's triangles come from: a stream that can be replayed. A
//! scene already in memory streams its triangles; the built-in landscape
//! generates them tile by tile, so a scene of hundreds of millions of
//! triangles never exists in memory as a whole.

use glam::Vec3;
use holodeck_protocol::Section;

use super::super::OocError;
use crate::scene::gen::{landscape, GenParams};
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
}

/// A scene in memory as a source; its content hash is the scene's own, so a
/// scene file and the `.hds` built from it serve the same holodecks.
pub struct SceneSource {
    scene: Scene,
    meta: SceneMeta,
}

impl SceneSource {
    /// Wraps a scene.
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
        let setting = crate::scene::gen::room::add_room(&mut b, &GenParams::default()).map_err(err)?;
        b.sky(setting.sky).map_err(err)?;
        for s in setting.sections {
            b.section(s);
        }
        let room = b.finish();
        let meta = SceneMeta {
            materials: room.materials.clone(),
            material_names: room.material_names.clone(),
            sky: room.sky.clone(),
            sections: room.sections.clone(),
        };
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
        let mut next = 0u32;
        let mut batch: Vec<RawTri> = Vec::with_capacity(1 << 15);
        let mut push = |batch: &mut Vec<RawTri>, v: [Vec3; 3], material: u32| -> Result<(), OocError> {
            // The same checks as the in-core builder: no degenerate triangles.
            if (v[1] - v[0]).cross(v[2] - v[0]).length_squared() > 0.0 {
                batch.push(RawTri { v, material, id: next });
                next = next
                    .checked_add(1)
                    .ok_or_else(|| OocError::Build("more than 2^32 triangles".into()))?;
            }
            if batch.len() == batch.capacity() {
                emit(batch)?;
                batch.clear();
            }
            Ok(())
        };
        for i in 0..self.room.triangles.len() {
            push(&mut batch, self.room.vertices(i), self.room.triangles[i].material)?;
        }
        landscape::stream(&self.params, self.ids, &mut |v, m| push(&mut batch, v, m))?;
        emit(&batch)
    }
    fn content_hash(&self) -> Option<String> {
        None
    }
}
