//! The Delaunay triangulation on the view sphere that gives the mesh driver
//! its topology (the holodeck paper, section 2.4.5).
//!
//! Samples are directions from a canonical eye point; the mesh connects them
//! by the Delaunay triangulation of their points on the unit sphere, kept up
//! to date one insertion at a time. This module is only that triangulation:
//! it never sees a sample, a colour or a GPU buffer, and it never deletes a
//! vertex (a better sample for the same direction replaces the driver's data
//! for a [`Insert::Duplicate`] vertex, not the topology).
//!
//! Invariants (checked by [`SphereMesh::validate`]):
//! * The Delaunay triangulation of points on a sphere is their convex hull,
//!   so every test is an exact 3-D orientation (Shewchuk's predicates):
//!   "left of the arc a→b" is the side of the plane through the origin, a
//!   and b; "inside the circumcircle of abc" is "beyond the plane of abc".
//!   Cocircular ties never flip.
//! * The mesh starts as the octahedron of the six axis directions, the
//!   ghosts (ids 0..6): the origin is strictly inside the hull from the
//!   start and every triangle is smaller than a hemisphere. A direction
//!   within `min_angle` of an axis claims that ghost, which becomes a real
//!   vertex with the exact axis direction.
//! * Every vertex is in convex position: a direction that the exact
//!   predicate puts on or inside the hull is a duplicate of a vertex, never
//!   inserted, and no two real vertices are within `min_angle` (never less
//!   than [`MIN_ANGLE_FLOOR`]) of each other. That floor keeps vertices far
//!   enough apart that normalized directions, which are only nearly on the
//!   sphere, stay in convex position.
//! * Triangles are counter-clockwise seen from outside, and each knows the
//!   triangle and the vertex across each of its edges.
//!
//! Point location walks from the last vertex, or from a vertex remembered in
//! a coarse cube-map grid (the paper's octahedral quadtree plays the same
//! part), so both pixel-order and random insertions find their triangle in
//! two or three steps. Memory is about 100 bytes per vertex: a direction, a
//! triangle of it, and two triangles of 36 bytes. A large mesh fed random
//! directions is bound by memory latency, not arithmetic: every step lands
//! somewhere new in arrays larger than the caches; [`SphereMesh::insert_many`]
//! sorts a batch along a Hilbert curve first, so that it is not.

mod bench;
mod check;
mod grid;
mod insert;
mod locate;
pub(crate) mod order;
mod predicates;
#[cfg(test)]
mod tests;

use std::fmt;

use glam::DVec3;

pub use bench::{bench_insertions, bench_sorted_insertions};
pub use check::MeshDefect;

use grid::Grid;
use predicates::unit;

/// A vertex of a [`SphereMesh`]: an index into its directions. Ids are dense
/// and stable; 0..6 are the octahedron's corners (the ghosts).
pub type VertexId = u32;

/// The smallest `min_angle`, in radians: directions closer than this are
/// always one vertex. Normalized `f64` directions lie within about 1e-16 of
/// the unit sphere; points closer than about 1e-7 radians could then leave
/// convex position and fold the mesh. 1e-6 radians keeps a wide margin and is
/// still a quarter pixel of a 4K picture one degree wide.
pub const MIN_ANGLE_FLOOR: f64 = 1e-6;

/// The largest `min_angle`, in radians: beyond it "the same direction" means
/// nothing for a picture.
pub const MAX_MIN_ANGLE: f64 = 1.0;

/// Asks the CPU to start loading `x` into cache: the insertion rate of a
/// large mesh is bounded by waiting for memory, and some addresses are known
/// well before their contents are needed.
#[inline(always)]
fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint: it changes no state the program can see
    // and cannot fault, whatever the address (here a live reference).
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>((x as *const T).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}

/// The number of octahedron corners that start every mesh.
pub const GHOSTS: usize = 6;

/// The ghost directions in id order: +x, -x, +y, -y, +z, -z.
const AXES: [DVec3; GHOSTS] = [DVec3::X, DVec3::NEG_X, DVec3::Y, DVec3::NEG_Y, DVec3::Z, DVec3::NEG_Z];

/// "No triangle" / "no vertex" in the compact arrays.
const NONE: u32 = u32::MAX;

/// The most vertices a mesh holds: corners pack a triangle into 30 bits.
pub const MAX_VERTICES: usize = 1 << 28;

/// What [`SphereMesh::insert`] did with a direction.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Insert {
    /// A new vertex, or a ghost claimed by a direction within `min_angle` of
    /// its axis (the ghost keeps its exact axis direction; a direction the
    /// exact predicates cannot tell from a ghost claims it too).
    Added(VertexId),
    /// Within `min_angle` of this real vertex, or not in convex position
    /// next to it; the mesh did not change.
    Duplicate(VertexId),
    /// The `accept` test of [`SphereMesh::insert_with`] said no; the mesh did
    /// not change.
    Rejected,
}

/// Why a direction could not be inserted or located.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SphereError {
    /// A component is NaN or infinite.
    #[error("the direction has a component that is NaN or infinite")]
    NotFinite,
    /// All components are zero.
    #[error("the direction has zero length")]
    Zero,
    /// The mesh already holds [`MAX_VERTICES`] vertices.
    #[error("the sphere mesh is full ({MAX_VERTICES} vertices)")]
    Full,
}

/// Counters since the mesh was made or cleared.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MeshStats {
    /// Directions that became vertices, claimed ghosts included.
    pub insertions: u64,
    /// Directions answered with [`Insert::Duplicate`].
    pub duplicates: u64,
    /// Directions answered with [`Insert::Rejected`].
    pub rejected: u64,
    /// Edge flips that restored the Delaunay condition after insertions
    /// (flips of insertions later undone are not counted).
    pub flips: u64,
    /// Point locations (walks), one per insertion attempt that got past the
    /// ghost test, plus the ones for claimed ghosts.
    pub locations: u64,
    /// Triangles stepped across by those walks.
    pub location_steps: u64,
    /// Insertions taken back because the flips met a vertex within
    /// `min_angle` that the containing triangle did not show; they are
    /// counted as duplicates too.
    pub undone: u64,
    /// Edges left not locally Delaunay because flipping them would have
    /// folded the mesh. Only vertices closer than the floor can cause this,
    /// so it stays 0; [`SphereMesh::validate`] fails if it does not.
    pub unflippable: u64,
}

impl MeshStats {
    /// Flips per inserted vertex (0 when none was inserted).
    pub fn flips_per_insertion(&self) -> f64 {
        self.flips as f64 / (self.insertions.max(1)) as f64
    }

    /// Triangles stepped across per point location (0 when none was made).
    pub fn steps_per_location(&self) -> f64 {
        self.location_steps as f64 / (self.locations.max(1)) as f64
    }
}

/// One triangle: vertices counter-clockwise seen from outside the sphere;
/// `n[i]`, the [`corner`] of the triangle across the edge opposite `v[i]`
/// that faces this one; and `o[i]`, that triangle's vertex at that corner.
/// Corners, not bare triangles, so that a neighbour's back-link can be
/// rewritten without reading it first; far vertices, so that a flip test or
/// a walk step can fetch the direction it needs without first waiting for
/// the triangle across. Both matter because reading memory, not
/// arithmetic, bounds the insertion rate of a large mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Tri {
    pub v: [VertexId; 3],
    pub n: [u32; 3],
    pub o: [VertexId; 3],
}

/// Corner `i` of triangle `t`: the edge opposite `v[i]` seen from `t`.
#[inline]
pub(crate) fn corner(t: u32, i: usize) -> u32 {
    (t << 2) | i as u32
}

/// The triangle of a corner.
#[inline]
pub(crate) fn tri_of(c: u32) -> u32 {
    c >> 2
}

/// The index within its triangle of a corner.
#[inline]
pub(crate) fn index_of(c: u32) -> usize {
    (c & 3) as usize
}

/// One change to an existing triangle, as it was before.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Change {
    /// Triangle `t` was overwritten.
    Tri(u32, Tri),
    /// The neighbour link and far vertex of corner `corner` were rewritten.
    Link { corner: u32, old: (u32, VertexId) },
}

/// An incremental Delaunay triangulation of directions on the unit sphere.
#[derive(Clone)]
pub struct SphereMesh {
    /// `min_angle` as given to [`SphereMesh::new`], after clamping.
    min_angle: f64,
    /// The squared chord length of `min_angle`: closeness is tested on
    /// chords, which stay accurate for tiny angles where cosines do not.
    min_chord2: f64,
    /// Unit direction of every vertex.
    dirs: Vec<DVec3>,
    /// One triangle incident to every vertex.
    vert_tri: Vec<u32>,
    tris: Vec<Tri>,
    /// Which ghosts a direction has claimed.
    claimed: [bool; GHOSTS],
    grid: Grid,
    stats: MeshStats,
    /// Triangles whose edge opposite the new vertex may need a flip.
    stack: Vec<u32>,
    /// What this insertion changed in triangles that existed before it, so
    /// that an insertion that turns out to be a duplicate can be taken back.
    log: Vec<Change>,
    /// The triangle count before this insertion: slots at or above it are
    /// new and need no log.
    log_base: u32,
    /// The vertex the last insertion added or found: where a walk starts
    /// when it is nearer than the grid's vertex, as it is for directions
    /// that arrive in pixel order.
    recent: VertexId,
}

impl SphereMesh {
    /// An octahedron of six ghosts. Directions within `min_angle` radians of a
    /// vertex are duplicates of it; `min_angle` is clamped to
    /// [`MIN_ANGLE_FLOOR`]..=[`MAX_MIN_ANGLE`] (NaN means the floor).
    pub fn new(min_angle: f64) -> SphereMesh {
        let min_angle = if min_angle.is_nan() {
            MIN_ANGLE_FLOOR
        } else {
            min_angle.clamp(MIN_ANGLE_FLOOR, MAX_MIN_ANGLE)
        };
        let chord = 2.0 * (0.5 * min_angle).sin();
        let mut mesh = SphereMesh {
            min_angle,
            min_chord2: chord * chord,
            dirs: Vec::new(),
            vert_tri: Vec::new(),
            tris: Vec::new(),
            claimed: [false; GHOSTS],
            grid: Grid::new(),
            stats: MeshStats::default(),
            stack: Vec::new(),
            log: Vec::new(),
            log_base: 0,
            recent: 0,
        };
        mesh.clear();
        mesh
    }

    /// Back to the octahedron of ghosts, keeping every allocation.
    pub fn clear(&mut self) {
        self.dirs.clear();
        self.dirs.extend_from_slice(&AXES);
        self.tris.clear();
        // Octant (sx, sy, sz) holds the triangle of the +-x, +-y, +-z ghosts,
        // turned to be counter-clockwise from outside.
        for octant in 0..8u32 {
            let x = octant & 1;
            let y = 2 + ((octant >> 1) & 1);
            let z = 4 + ((octant >> 2) & 1);
            let v = if octant.count_ones() % 2 == 0 {
                [x, y, z]
            } else {
                [y, x, z]
            };
            self.tris.push(Tri {
                v,
                n: [NONE; 3],
                o: [NONE; 3],
            });
        }
        link_by_edges(&mut self.tris);
        self.vert_tri.clear();
        self.vert_tri.resize(GHOSTS, NONE);
        for (t, tri) in self.tris.iter().enumerate() {
            for &v in &tri.v {
                self.vert_tri[v as usize] = t as u32;
            }
        }
        self.claimed = [false; GHOSTS];
        self.grid.clear();
        self.recent = 0;
        self.stats = MeshStats::default();
        self.stack.clear();
        self.log.clear();
    }

    /// Inserts a direction (any finite length above zero). See [`Insert`].
    pub fn insert(&mut self, dir: DVec3) -> Result<Insert, SphereError> {
        self.insert_with(dir, |_| true)
    }

    /// The triangle containing a direction (one of them when it lies on an
    /// edge or a vertex), counter-clockwise from outside.
    pub fn locate(&self, dir: DVec3) -> Result<[VertexId; 3], SphereError> {
        let p = unit(dir)?;
        let found = self.walk(p, self.walk_start(p));
        Ok(self.tris[found.tri as usize].v)
    }

    /// The unit direction of a vertex.
    ///
    /// # Panics
    /// If `v` is not a vertex of this mesh (ids come from this mesh only).
    pub fn direction(&self, v: VertexId) -> DVec3 {
        self.dirs[v as usize]
    }

    /// Whether `v` is an octahedron corner no direction has claimed: the
    /// driver has no sample for it.
    pub fn is_ghost(&self, v: VertexId) -> bool {
        (v as usize) < GHOSTS && !self.claimed[v as usize]
    }

    /// All vertices, ghosts included.
    pub fn vertex_count(&self) -> usize {
        self.dirs.len()
    }

    /// Vertices that came from directions: all but the unclaimed ghosts.
    pub fn real_count(&self) -> usize {
        self.dirs.len() - self.claimed.iter().filter(|&&c| !c).count()
    }

    /// Triangles: always `2 * vertex_count() - 4`.
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// Every triangle, counter-clockwise seen from outside the sphere.
    pub fn triangles(&self) -> impl Iterator<Item = [VertexId; 3]> + '_ {
        self.tris.iter().map(|t| t.v)
    }

    /// The vertices sharing an edge with `v`, counter-clockwise around it
    /// seen from outside. Empty when `v` is not a vertex.
    pub fn neighbours(&self, v: VertexId) -> Neighbours<'_> {
        let start = self.vert_tri.get(v as usize).copied().unwrap_or(NONE);
        Neighbours {
            mesh: self,
            v,
            start,
            at: start,
            left: self.tris.len(),
        }
    }

    /// `min_angle` after clamping, in radians.
    pub fn min_angle(&self) -> f64 {
        self.min_angle
    }

    /// Counters since the mesh was made or cleared.
    pub fn stats(&self) -> MeshStats {
        self.stats
    }

    /// Bytes this mesh holds on the heap (capacities, not lengths).
    pub fn heap_bytes(&self) -> usize {
        use std::mem::size_of;
        self.dirs.capacity() * size_of::<DVec3>()
            + self.vert_tri.capacity() * size_of::<u32>()
            + self.tris.capacity() * size_of::<Tri>()
            + self.stack.capacity() * size_of::<u32>()
            + self.log.capacity() * size_of::<Change>()
            + self.grid.heap_bytes()
    }
}

impl fmt::Debug for SphereMesh {
    /// A summary: a mesh of a million vertices is not for printing.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SphereMesh")
            .field("min_angle", &self.min_angle)
            .field("vertices", &self.dirs.len())
            .field("real", &self.real_count())
            .field("triangles", &self.tris.len())
            .field("stats", &self.stats)
            .finish()
    }
}

/// The neighbours of one vertex, from [`SphereMesh::neighbours`].
pub struct Neighbours<'a> {
    mesh: &'a SphereMesh,
    v: VertexId,
    start: u32,
    at: u32,
    /// Steps allowed before giving up, so that a damaged mesh (which
    /// [`SphereMesh::validate`] reports) cannot loop forever.
    left: usize,
}

impl Iterator for Neighbours<'_> {
    type Item = VertexId;

    fn next(&mut self) -> Option<VertexId> {
        if self.at == NONE || self.left == 0 {
            return None;
        }
        self.left -= 1;
        let tri = self.mesh.tris.get(self.at as usize)?;
        let Some(k) = tri.v.iter().position(|&x| x == self.v) else {
            self.at = NONE;
            return None;
        };
        // Counter-clockwise around v: emit the next corner, then cross the
        // edge from v to the corner after it.
        let out = tri.v[(k + 1) % 3];
        self.at = tri_of(tri.n[(k + 1) % 3]);
        if self.at == self.start {
            self.at = NONE;
        }
        Some(out)
    }
}

/// Fills every `n` of `tris` from shared edges (the octahedron only: it is
/// quadratic).
fn link_by_edges(tris: &mut [Tri]) {
    for t in 0..tris.len() {
        for i in 0..3 {
            let (a, b) = (tris[t].v[(i + 1) % 3], tris[t].v[(i + 2) % 3]);
            let across = tris.iter().enumerate().find_map(|(u, tri)| {
                let j = (0..3).find(|&j| tri.v[(j + 1) % 3] == b && tri.v[(j + 2) % 3] == a)?;
                Some((corner(u as u32, j), tri.v[j]))
            });
            (tris[t].n[i], tris[t].o[i]) = across.unwrap_or((NONE, NONE));
        }
    }
}
