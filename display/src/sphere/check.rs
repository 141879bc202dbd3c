//! The full consistency check of a mesh, for tests and debugging: linear in
//! the mesh size, never called by insertion.

use std::f64::consts::PI;

use super::predicates::{in_circle, side};
use super::{corner, index_of, tri_of, SphereMesh, NONE};

/// An invariant of a [`SphereMesh`] that does not hold, as
/// [`SphereMesh::validate`] finds it: the first violation, in words naming
/// the triangles and vertices involved.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct MeshDefect(pub String);

impl SphereMesh {
    /// Checks every invariant: neighbour links symmetric and on the same
    /// edge, every triangle counter-clockwise from outside, every edge
    /// locally Delaunay by the exact predicate, every vertex in one fan of
    /// triangles that it points into, the triangles covering the sphere once
    /// (their areas sum to 4π), `V - E + F == 2` and `F == 2V - 4`, and no
    /// refused flip. `Err` names the first violation.
    pub fn validate(&self) -> Result<(), MeshDefect> {
        self.first_defect().map_err(MeshDefect)
    }

    /// [`SphereMesh::validate`]'s checks, in order, the first failing one in words.
    fn first_defect(&self) -> Result<(), String> {
        let nv = self.dirs.len();
        let nt = self.tris.len();
        if self.vert_tri.len() != nv {
            return Err(format!(
                "{} vertices but {} vertex→triangle links",
                nv,
                self.vert_tri.len()
            ));
        }
        for (t, tri) in self.tris.iter().enumerate() {
            for i in 0..3 {
                let v = tri.v[i];
                if v as usize >= nv {
                    return Err(format!("triangle {t} names vertex {v} of {nv}"));
                }
                if v == tri.v[(i + 1) % 3] {
                    return Err(format!("triangle {t} repeats vertex {v}"));
                }
                let link = tri.n[i];
                let (u, j) = (tri_of(link), index_of(link));
                let Some(ut) = self.tris.get(u as usize).filter(|_| j < 3) else {
                    return Err(format!(
                        "triangle {t} links to corner {link}, not of one of {nt} triangles"
                    ));
                };
                if ut.n[j] != corner(t as u32, i) {
                    return Err(format!("triangle {t} links to {u}, which does not link back"));
                }
                if tri.o[i] != ut.v[j] {
                    return Err(format!(
                        "triangle {t} sees vertex {} across edge {i}, not {}",
                        tri.o[i], ut.v[j]
                    ));
                }
                let (a, b) = (tri.v[(i + 1) % 3], tri.v[(i + 2) % 3]);
                if ut.v[(j + 1) % 3] != b || ut.v[(j + 2) % 3] != a {
                    return Err(format!("triangles {t} and {u} link but do not share edge {a}-{b}"));
                }
            }
            let [a, b, c] = tri.v.map(|v| self.dirs[v as usize]);
            if side(a, b, c) <= 0.0 {
                return Err(format!(
                    "triangle {t} {:?} is not counter-clockwise from outside",
                    tri.v
                ));
            }
            for i in 0..3 {
                let d = tri.o[i];
                if in_circle(a, b, c, self.dirs[d as usize]) > 0.0 {
                    return Err(format!(
                        "edge {}-{} is not Delaunay: vertex {d} is inside the circumcircle of triangle {t} {:?}",
                        tri.v[(i + 1) % 3],
                        tri.v[(i + 2) % 3],
                        tri.v
                    ));
                }
            }
        }
        let mut degrees = 0usize;
        for v in 0..nv {
            let t = self.vert_tri[v];
            if t == NONE || t as usize >= nt || !self.tris[t as usize].v.contains(&(v as u32)) {
                return Err(format!("vertex {v} points at triangle {t}, which does not hold it"));
            }
            let degree = self.neighbours(v as u32).count();
            if degree < 3 {
                return Err(format!("vertex {v} has {degree} neighbours"));
            }
            degrees += degree;
        }
        // Each triangle has three corners, each in one vertex's fan: a vertex
        // whose triangles form two fans, or none, comes up short here.
        if degrees != 3 * nt {
            return Err(format!(
                "the vertex fans hold {degrees} corners but the {nt} triangles have {}",
                3 * nt
            ));
        }
        if !nt.is_multiple_of(2) || nt + 4 != 2 * nv {
            return Err(format!("{nv} vertices and {nt} triangles: a sphere has F = 2V - 4"));
        }
        let edges = 3 * nt / 2;
        if nv + nt != edges + 2 {
            return Err(format!("V - E + F = {nv} - {edges} + {nt}, not 2"));
        }
        for (v, d) in self.dirs.iter().enumerate() {
            if (d.length() - 1.0).abs() > 1e-12 {
                return Err(format!("vertex {v} has direction {d} of length {}", d.length()));
            }
        }
        let area = self.spherical_area();
        if (area - 4.0 * PI).abs() > 1e-6 {
            return Err(format!("the triangles cover {area} steradians, not 4π once"));
        }
        if self.stats.unflippable != 0 {
            return Err(format!(
                "{} edges were left unflipped to avoid a fold",
                self.stats.unflippable
            ));
        }
        Ok(())
    }

    /// The summed solid angle of every triangle (Van Oosterom and Strackee's
    /// formula): 4π when they cover the sphere once.
    fn spherical_area(&self) -> f64 {
        self.tris
            .iter()
            .map(|tri| {
                let [a, b, c] = tri.v.map(|v| self.dirs[v as usize]);
                let det = a.dot(b.cross(c));
                let div = 1.0 + a.dot(b) + b.dot(c) + c.dot(a);
                2.0 * det.atan2(div)
            })
            .sum()
    }
}
