//! One chunk built in core: its triangles as a small scene, the existing
//! binned-SAH kd-tree built inside the chunk's box, and voxels sampled by
//! casting rays into each node through its six faces against that tree, so
//! that what a voxel shows is what is visible from outside it.

use glam::Vec3;

use super::super::treelet::{SourceTree, SrcNode};
use super::super::voxel::{complete, face_normal, grey, FaceAccumulator, Voxel, FACES};
use super::source::RawTri;
use crate::accel::{BuildOptions, KdTree};
use crate::geom::{Aabb, Ray};
use crate::scene::{Material, Scene, Triangle};

/// Rays per face side when sampling a voxel (n x n per face).
const VOXEL_RAYS: usize = 4;

/// The color a voxel shows for a material: its diffuse or specular tint.
pub fn shade_color(m: &Material) -> Vec3 {
    let c = match m {
        Material::Lambertian { albedo, .. } | Material::Plastic { albedo, .. } => *albedo,
        Material::Metal { color, .. } | Material::Mirror { color } => *color,
        Material::Glass { color, .. } => color.map(|c| c * 0.1),
        Material::Emitter { radiance } => {
            let m = radiance.iter().copied().fold(0.0f32, f32::max).max(1e-6);
            radiance.map(|c| c / m)
        }
    };
    Vec3::from_array(c)
}

/// A chunk's triangles and tree.
pub struct Chunk {
    scene: Scene,
    ids: Vec<u32>,
    tree: KdTree,
    colors: Vec<Vec3>,
}

impl Chunk {
    /// Builds the tree of `tris` inside `bounds`.
    pub fn build(tris: &[RawTri], bounds: Aabb, materials: &[Material]) -> Chunk {
        let mut scene = Scene {
            positions: Vec::with_capacity(tris.len() * 3),
            triangles: Vec::with_capacity(tris.len()),
            materials: materials.to_vec(),
            ..Scene::default()
        };
        let mut ids = Vec::with_capacity(tris.len());
        for (i, t) in tris.iter().enumerate() {
            scene.positions.extend(t.v);
            let b = 3 * i as u32;
            scene.triangles.push(Triangle {
                v: [b, b + 1, b + 2],
                material: t.material,
            });
            ids.push(t.id);
        }
        let tree = KdTree::build_within(&scene, bounds, &BuildOptions::one_triangle_at_a_time());
        let colors = materials.iter().map(shade_color).collect();
        Chunk {
            scene,
            ids,
            tree,
            colors,
        }
    }
}

impl SourceTree for Chunk {
    fn node(&self, i: usize) -> SrcNode<'_> {
        let n = self.tree.nodes()[i];
        if n.is_leaf() {
            SrcNode::Leaf(&self.tree.leaf_tris()[n.first()..n.first() + n.count()])
        } else {
            SrcNode::Inner {
                axis: n.axis(),
                split: n.split(),
                children: [n.left(), n.left() + 1],
            }
        }
    }

    fn triangle(&self, t: u32) -> ([Vec3; 3], u16, u32) {
        let tri = self.scene.triangles[t as usize];
        (
            self.scene.vertices(t as usize),
            tri.material as u16,
            self.ids[t as usize],
        )
    }

    fn voxel(&self, _i: usize, b: &Aabb) -> Voxel {
        let size = b.hi - b.lo;
        let mut faces = [None; FACES];
        for (f, out) in faces.iter_mut().enumerate() {
            let axis = f / 2;
            let n = face_normal(f);
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut acc = FaceAccumulator::default();
            for k in 0..VOXEL_RAYS * VOXEL_RAYS {
                let (s, t) = (
                    ((k % VOXEL_RAYS) as f32 + 0.5) / VOXEL_RAYS as f32,
                    ((k / VOXEL_RAYS) as f32 + 0.5) / VOXEL_RAYS as f32,
                );
                let mut o = b.lo;
                o[u] += s * size[u];
                o[v] += t * size[v];
                o[axis] = if f % 2 == 1 { b.hi[axis] } else { b.lo[axis] };
                let ray = Ray {
                    origin: o,
                    dir: -n,
                    t_max: size[axis].max(1e-30),
                };
                match self.tree.intersect(&ray) {
                    Some(h) => {
                        let [a, bb, c] = self.scene.vertices(h.tri as usize);
                        let ng = (bb - a).cross(c - a).normalize_or(n);
                        let m = self.scene.triangles[h.tri as usize].material as usize;
                        acc.hit(ng, self.colors.get(m).copied().unwrap_or(Vec3::splat(0.5)), n, 1.0);
                    }
                    None => acc.miss(),
                }
            }
            *out = acc.finish(None);
        }
        complete(faces).unwrap_or_else(grey)
    }
}
