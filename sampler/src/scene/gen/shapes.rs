//! Mesh building blocks for the generators: quads, boxes, icospheres, and the
//! fixed-size trunk and cone writers the forest fills in parallel. Every shape
//! is closed or faces where it is told to; none allocates per call except
//! [`MeshBuf`] growing.

use std::collections::HashMap;

use glam::Vec3;

use crate::error::SceneError;
use crate::scene::builder::SceneBuilder;
use crate::scene::Triangle;

/// A growing world-space mesh whose triangles carry scene material ids.
#[derive(Default)]
pub struct MeshBuf {
    /// Vertex positions, world meters.
    pub positions: Vec<Vec3>,
    /// Triangles indexing `positions`, counter-clockwise seen from the front.
    pub triangles: Vec<Triangle>,
}

impl MeshBuf {
    /// An empty mesh.
    pub fn new() -> MeshBuf {
        MeshBuf::default()
    }

    /// Adds a vertex and returns its index.
    pub fn vertex(&mut self, p: Vec3) -> u32 {
        self.positions.push(p);
        (self.positions.len() - 1) as u32
    }

    /// Adds a triangle of existing vertices.
    pub fn triangle(&mut self, v: [u32; 3], material: u32) {
        self.triangles.push(Triangle { v, material });
    }

    /// A planar quad whose front faces `normal`, from corners in cyclic order
    /// (either winding; it is fixed to face `normal`).
    pub fn quad(&mut self, corners: [Vec3; 4], normal: Vec3, material: u32) {
        let [a, b, c, d] = corners;
        let ordered = if (b - a).cross(c - a).dot(normal) >= 0.0 {
            [a, b, c, d]
        } else {
            [a, d, c, b]
        };
        let v = ordered.map(|p| self.vertex(p));
        self.triangle([v[0], v[1], v[2]], material);
        self.triangle([v[0], v[2], v[3]], material);
    }

    /// An axis-aligned box from `lo` to `hi`, faces outward, 8 shared vertices, 12 triangles.
    pub fn cuboid(&mut self, lo: Vec3, hi: Vec3, material: u32) {
        let base = self.positions.len() as u32;
        for k in 0..8 {
            let pick = |bit: u32, l: f32, h: f32| if k & bit != 0 { h } else { l };
            self.positions
                .push(Vec3::new(pick(1, lo.x, hi.x), pick(2, lo.y, hi.y), pick(4, lo.z, hi.z)));
        }
        // Corner k has bit 1 = +x, bit 2 = +y, bit 4 = +z; each face counter-clockwise from outside.
        const FACES: [[u32; 4]; 6] = [
            [0, 4, 6, 2],
            [1, 3, 7, 5],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 2, 3, 1],
            [4, 5, 7, 6],
        ];
        for f in FACES {
            self.triangle([base + f[0], base + f[1], base + f[2]], material);
            self.triangle([base + f[0], base + f[2], base + f[3]], material);
        }
    }

    /// A geodesic sphere: an icosahedron subdivided `levels` times (20·4^levels
    /// triangles), vertices shared, faces outward.
    pub fn icosphere(&mut self, center: Vec3, radius: f32, levels: u32, material: u32) {
        let t = (1.0 + 5f32.sqrt()) / 2.0;
        let mut verts: Vec<Vec3> = [
            [-1.0, t, 0.0],
            [1.0, t, 0.0],
            [-1.0, -t, 0.0],
            [1.0, -t, 0.0],
            [0.0, -1.0, t],
            [0.0, 1.0, t],
            [0.0, -1.0, -t],
            [0.0, 1.0, -t],
            [t, 0.0, -1.0],
            [t, 0.0, 1.0],
            [-t, 0.0, -1.0],
            [-t, 0.0, 1.0],
        ]
        .iter()
        .map(|p| Vec3::from(*p).normalize())
        .collect();
        let mut faces: Vec<[u32; 3]> = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        for _ in 0..levels {
            let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
            let mut midpoint = |a: u32, b: u32, verts: &mut Vec<Vec3>| {
                *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    verts.push(((verts[a as usize] + verts[b as usize]) * 0.5).normalize());
                    (verts.len() - 1) as u32
                })
            };
            let mut next = Vec::with_capacity(faces.len() * 4);
            for [a, b, c] in faces {
                let (ab, bc, ca) = (
                    midpoint(a, b, &mut verts),
                    midpoint(b, c, &mut verts),
                    midpoint(c, a, &mut verts),
                );
                next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
            }
            faces = next;
        }
        let base = self.positions.len() as u32;
        self.positions.extend(verts.iter().map(|v| center + *v * radius));
        self.triangles.extend(faces.iter().map(|f| Triangle {
            v: f.map(|i| i + base),
            material,
        }));
    }

    /// Adds this mesh to `b` under the name `source`.
    pub fn flush(self, b: &mut SceneBuilder, source: &str) -> Result<(), SceneError> {
        b.add_world_mesh(source, self.positions, self.triangles)
    }
}

/// Vertices written by [`write_prism`] with `segments` sides.
pub const fn prism_vertices(segments: usize) -> usize {
    2 * segments
}

/// Triangles written by [`write_prism`] with `segments` sides.
pub const fn prism_triangles(segments: usize) -> usize {
    2 * segments
}

/// Writes the open side wall of a vertical prism (a tree trunk): `segments`
/// sides of radius `r` from `base` up `height`, faces outward. `first` is the
/// index of `pos[0]` in the whole mesh.
pub fn write_prism(
    pos: &mut [Vec3],
    tris: &mut [Triangle],
    first: u32,
    base: Vec3,
    r: f32,
    height: f32,
    material: u32,
) {
    let n = pos.len() / 2;
    for k in 0..n {
        let a = std::f32::consts::TAU * k as f32 / n as f32;
        let d = Vec3::new(a.cos() * r, a.sin() * r, 0.0);
        pos[2 * k] = base + d;
        pos[2 * k + 1] = base + d + Vec3::Z * height;
    }
    for k in 0..n {
        let (b0, t0) = (first + 2 * k as u32, first + 2 * k as u32 + 1);
        let next = ((k + 1) % n) as u32;
        let (b1, t1) = (first + 2 * next, first + 2 * next + 1);
        tris[2 * k] = Triangle {
            v: [b0, b1, t1],
            material,
        };
        tris[2 * k + 1] = Triangle {
            v: [b0, t1, t0],
            material,
        };
    }
}

/// Vertices written by [`write_cone`] with `segments` sides.
pub const fn cone_vertices(segments: usize) -> usize {
    segments + 2
}

/// Triangles written by [`write_cone`] with `segments` sides.
pub const fn cone_triangles(segments: usize) -> usize {
    2 * segments
}

/// Writes a closed cone (a crown tier): base disk of radius `r` at `base`,
/// apex `height` above, faces outward. `first` is the index of `pos[0]`.
pub fn write_cone(pos: &mut [Vec3], tris: &mut [Triangle], first: u32, base: Vec3, r: f32, height: f32, material: u32) {
    let n = pos.len() - 2;
    for (k, p) in pos[..n].iter_mut().enumerate() {
        let a = std::f32::consts::TAU * k as f32 / n as f32;
        *p = base + Vec3::new(a.cos() * r, a.sin() * r, 0.0);
    }
    let (apex, center) = (first + n as u32, first + n as u32 + 1);
    pos[n] = base + Vec3::Z * height;
    pos[n + 1] = base;
    for k in 0..n {
        let (v0, v1) = (first + k as u32, first + ((k + 1) % n) as u32);
        tris[2 * k] = Triangle {
            v: [v0, v1, apex],
            material,
        };
        tris[2 * k + 1] = Triangle {
            v: [v1, v0, center],
            material,
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every directed edge once and its reverse once: closed and consistently oriented.
    fn closed_oriented(t: &[Triangle]) -> bool {
        let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
        for tri in t {
            for k in 0..3 {
                *edges.entry((tri.v[k], tri.v[(k + 1) % 3])).or_default() += 1;
            }
        }
        edges
            .iter()
            .all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1))
    }

    /// Signed volume (positive when faces point outward).
    fn volume(m: &MeshBuf) -> f32 {
        m.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.v.map(|i| m.positions[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn shapes_are_closed_outward_and_sized() {
        let mut m = MeshBuf::new();
        m.cuboid(Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0), 0);
        assert!(closed_oriented(&m.triangles));
        assert!((volume(&m) - 6.0).abs() < 1e-5, "{}", volume(&m));

        let mut s = MeshBuf::new();
        s.icosphere(Vec3::new(1.0, 1.0, 1.0), 2.0, 2, 0);
        assert_eq!(s.triangles.len(), 320);
        assert_eq!(s.positions.len(), 162);
        assert!(closed_oriented(&s.triangles));
        let v = volume(&s);
        assert!(v > 0.9 * 4.0 / 3.0 * std::f32::consts::PI * 8.0 && v < 33.6, "{v}");

        let (nv, nt) = (cone_vertices(8), cone_triangles(8));
        let mut c = MeshBuf {
            positions: vec![Vec3::ZERO; nv],
            triangles: vec![Triangle { v: [0; 3], material: 0 }; nt],
        };
        write_cone(&mut c.positions, &mut c.triangles, 0, Vec3::ZERO, 1.0, 3.0, 0);
        assert!(closed_oriented(&c.triangles));
        assert!(volume(&c) > 0.0);

        let mut p = MeshBuf {
            positions: vec![Vec3::ZERO; prism_vertices(6)],
            triangles: vec![Triangle { v: [0; 3], material: 0 }; prism_triangles(6)],
        };
        write_prism(&mut p.positions, &mut p.triangles, 0, Vec3::ZERO, 1.0, 2.0, 0);
        // Open at both ends, but each side quad faces outward.
        for t in &p.triangles {
            let [a, b, c] = t.v.map(|i| p.positions[i as usize]);
            let n = (b - a).cross(c - a);
            let out = ((a + b + c) / 3.0) * Vec3::new(1.0, 1.0, 0.0);
            assert!(n.dot(out) > 0.0);
        }

        let mut q = MeshBuf::new();
        q.quad([Vec3::ZERO, Vec3::X, Vec3::X + Vec3::Y, Vec3::Y], -Vec3::Z, 0);
        let [a, b, c] = q.triangles[0].v.map(|i| q.positions[i as usize]);
        assert!((b - a).cross(c - a).z < 0.0);
    }
}
