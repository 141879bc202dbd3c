//! Tests of the sphere mesh, and the checks they share: answers against
//! their promises, a global empty-circumcircle test, vertex separation.

use std::collections::BTreeSet;
use std::f64::consts::PI;

use glam::DVec3;
use proptest::prelude::*;

use super::bench::{coherent_directions, random_directions, SplitMix};
use super::predicates::{chord2, in_circle, side, unit};
use super::*;

/// Every vertex against every triangle: none strictly inside a
/// circumcircle. Quadratic: small meshes only.
fn global_delaunay(mesh: &SphereMesh) -> Result<(), String> {
    let dirs: Vec<DVec3> = (0..mesh.vertex_count() as u32).map(|v| mesh.direction(v)).collect();
    for tri in mesh.triangles() {
        let [a, b, c] = tri.map(|v| dirs[v as usize]);
        for (d, &dd) in dirs.iter().enumerate() {
            if !tri.contains(&(d as u32)) && in_circle(a, b, c, dd) > 0.0 {
                return Err(format!("vertex {d} is inside the circumcircle of {tri:?}"));
            }
        }
    }
    Ok(())
}

/// What a run of insertions returned, each answer checked against its promise.
#[derive(Debug, Default)]
struct Tally {
    added: usize,
    duplicates: usize,
}

fn insert_all(mesh: &mut SphereMesh, dirs: &[DVec3]) -> Result<Tally, String> {
    let threshold = chord_threshold(mesh);
    let mut tally = Tally::default();
    for (k, &d) in dirs.iter().enumerate() {
        let p = unit(d).map_err(|e| format!("direction {k} {d}: {e}"))?;
        let before = mesh.vertex_count();
        match mesh.insert(d).map_err(|e| format!("direction {k} {d}: {e}"))? {
            Insert::Added(v) if (v as usize) < GHOSTS => {
                if chord2(p, mesh.direction(v)) > threshold {
                    return Err(format!("direction {k} {p} claimed ghost {v} from too far"));
                }
                if mesh.vertex_count() != before || mesh.is_ghost(v) {
                    return Err(format!(
                        "claiming ghost {v} changed the vertex count or left it a ghost"
                    ));
                }
                tally.added += 1;
            }
            Insert::Added(v) => {
                if v as usize != before || mesh.direction(v) != p {
                    return Err(format!("direction {k} {p} became vertex {v} at {}", mesh.direction(v)));
                }
                tally.added += 1;
            }
            Insert::Duplicate(v) => {
                if mesh.is_ghost(v) || chord2(p, mesh.direction(v)) > threshold {
                    return Err(format!(
                        "direction {k} {p} called a duplicate of vertex {v} at {}, {} radians away",
                        mesh.direction(v),
                        mesh.direction(v).angle_between(p)
                    ));
                }
                if mesh.vertex_count() != before {
                    return Err(format!("duplicate direction {k} changed the vertex count"));
                }
                tally.duplicates += 1;
            }
            Insert::Rejected => return Err(format!("direction {k} rejected without a test")),
        }
    }
    Ok(tally)
}

fn chord_threshold(mesh: &SphereMesh) -> f64 {
    let chord = 2.0 * (0.5 * mesh.min_angle()).sin();
    chord * chord
}

/// No two vertices (unclaimed ghosts included) closer than `min_angle`.
fn separated(mesh: &SphereMesh) -> Result<(), String> {
    let threshold = chord_threshold(mesh);
    let n = mesh.vertex_count() as u32;
    for a in 0..n {
        for b in a + 1..n {
            if chord2(mesh.direction(a), mesh.direction(b)) <= threshold {
                return Err(format!("vertices {a} and {b} are within min_angle"));
            }
        }
    }
    Ok(())
}

/// The full set of checks for a mesh built from `dirs`.
fn check_run(min_angle: f64, dirs: &[DVec3]) -> Result<SphereMesh, String> {
    let mut mesh = SphereMesh::new(min_angle);
    let tally = insert_all(&mut mesh, dirs)?;
    mesh.validate().map_err(|e| e.to_string())?;
    let stats = mesh.stats();
    if tally.added + tally.duplicates != dirs.len()
        || mesh.real_count() != tally.added
        || stats.insertions as usize != tally.added
        || stats.duplicates as usize != tally.duplicates
        || stats.rejected != 0
    {
        return Err(format!(
            "{} directions, {tally:?}, real {}, {stats:?}",
            dirs.len(),
            mesh.real_count()
        ));
    }
    if mesh.vertex_count() <= 400 {
        global_delaunay(&mesh)?;
        separated(&mesh)?;
    }
    Ok(mesh)
}

fn sorted_neighbours(mesh: &SphereMesh, v: VertexId) -> Vec<VertexId> {
    let mut n: Vec<_> = mesh.neighbours(v).collect();
    n.sort_unstable();
    n
}

/// Unit vectors perpendicular to `c` and to each other.
fn frame(c: DVec3) -> (DVec3, DVec3) {
    let e1 = c.any_orthonormal_vector();
    (e1, c.cross(e1))
}

/// `k` points at equal angles on the circle `radius` radians around `center`.
fn circle(center: DVec3, radius: f64, k: usize) -> Vec<DVec3> {
    let c = center.normalize();
    let (e1, e2) = frame(c);
    (0..k)
        .map(|i| {
            let t = 2.0 * PI * i as f64 / k as f64;
            radius.cos() * c + radius.sin() * (t.cos() * e1 + t.sin() * e2)
        })
        .collect()
}

mod cases;
mod properties;
mod scale;
