//! A coarse cube map over the sphere that remembers one recent vertex per
//! cell: the starting point of point-location walks.
//!
//! It remembers vertices, not triangles: vertices never move, while a
//! triangle slot is reused by flips, which can carry it far away where long
//! thin triangles span the unfilled part of the sphere. It only speeds
//! location up: a far entry costs steps, never correctness. The resolution
//! grows with the vertex count so that a cell holds a few vertices and a
//! walk from its vertex is short, whatever order directions arrive in.

use glam::DVec3;

use super::NONE;

/// Cells along a face edge at first (6 × 8 × 8 cells).
const FIRST_SIDE: usize = 8;

/// Cells along a face edge at most: 6 × 512 × 512 cells, 6 MiB, fine enough
/// for several million vertices.
const MAX_SIDE: usize = 512;

/// Vertices per cell that make the grid double its resolution.
const GROW_AT: usize = 2;

#[derive(Clone, Debug)]
pub(crate) struct Grid {
    side: usize,
    cells: Vec<u32>,
}

impl Grid {
    pub fn new() -> Grid {
        let mut grid = Grid {
            side: FIRST_SIDE,
            cells: Vec::new(),
        };
        grid.clear();
        grid
    }

    /// At the first resolution, every cell remembering the ghost at the
    /// centre of its cube face (face k is ghost k), keeping the allocation.
    pub fn clear(&mut self) {
        self.side = FIRST_SIDE;
        let face_cells = FIRST_SIDE * FIRST_SIDE;
        self.cells.clear();
        self.cells.extend((0..6 * face_cells).map(|c| (c / face_cells) as u32));
    }

    /// The vertex remembered for the cell of unit direction `p`.
    #[inline]
    pub fn get(&self, p: DVec3) -> u32 {
        self.cells[self.cell(p)]
    }

    /// Remembers vertex `v` for the cell of unit direction `p`.
    #[inline]
    pub fn set(&mut self, p: DVec3, v: u32) {
        let c = self.cell(p);
        self.cells[c] = v;
    }

    /// The squared chord of the widest cell: a vertex nearer than this to a
    /// direction is as good a start as the grid's.
    #[inline]
    pub fn cell_chord2(&self) -> f64 {
        let width = 2.0 / self.side as f64;
        width * width
    }

    /// Whether `vertices` vertices call for a finer grid.
    #[inline]
    pub fn wants_growth(&self, vertices: usize) -> bool {
        self.side < MAX_SIDE && vertices > GROW_AT * self.cells.len()
    }

    /// Doubles the resolution and refills it from every vertex; a cell with
    /// no vertex of its own takes the one of the nearest cell on its face
    /// that has one (a two-pass city-block distance transform), or its
    /// parent's when the face has none. No cell is ever empty, and none
    /// sends walks from far away.
    pub fn grow(&mut self, dirs: &[DVec3]) {
        let old = self.side;
        let n = (old * 2).min(MAX_SIDE);
        let parents = std::mem::replace(&mut self.cells, vec![NONE; 6 * n * n]);
        self.side = n;
        for (v, &p) in dirs.iter().enumerate() {
            self.set(p, v as u32);
        }
        let mut dist: Vec<u32> = self
            .cells
            .iter()
            .map(|&v| if v == NONE { u32::MAX } else { 0 })
            .collect();
        for face in 0..6 {
            let at = |i: usize, j: usize| (face * n + j) * n + i;
            let relax = |c: usize, from: usize, cells: &mut [u32], dist: &mut [u32]| {
                if dist[from] != u32::MAX && dist[from] + 1 < dist[c] {
                    dist[c] = dist[from] + 1;
                    cells[c] = cells[from];
                }
            };
            for j in 0..n {
                for i in 0..n {
                    if i > 0 {
                        relax(at(i, j), at(i - 1, j), &mut self.cells, &mut dist);
                    }
                    if j > 0 {
                        relax(at(i, j), at(i, j - 1), &mut self.cells, &mut dist);
                    }
                }
            }
            for j in (0..n).rev() {
                for i in (0..n).rev() {
                    if i + 1 < n {
                        relax(at(i, j), at(i + 1, j), &mut self.cells, &mut dist);
                    }
                    if j + 1 < n {
                        relax(at(i, j), at(i, j + 1), &mut self.cells, &mut dist);
                    }
                }
            }
            for j in 0..n {
                for i in 0..n {
                    if self.cells[at(i, j)] == NONE {
                        self.cells[at(i, j)] = parents[(face * old + j * old / n) * old + i * old / n];
                    }
                }
            }
        }
    }

    pub fn heap_bytes(&self) -> usize {
        self.cells.capacity() * std::mem::size_of::<u32>()
    }

    /// The cell of a unit direction: the cube face of its largest component,
    /// then the gnomonic coordinates on that face.
    #[inline]
    fn cell(&self, p: DVec3) -> usize {
        let (face, u, v, major) = cube_face(p);
        let n = self.side;
        let half = 0.5 * n as f64;
        let scale = half / major;
        // `as usize` saturates: a negative coordinate lands in cell 0.
        let i = ((u * scale + half) as usize).min(n - 1);
        let j = ((v * scale + half) as usize).min(n - 1);
        (face * n + j) * n + i
    }
}

/// The cube face a direction points through (0..6: +x, -x, +y, -y, +z,
/// -z, by its largest component), its two other components in the
/// face's order, and the largest component's magnitude.
#[inline(always)]
pub(super) fn cube_face(p: DVec3) -> (usize, f64, f64, f64) {
    let a = p.abs();
    if a.x >= a.y && a.x >= a.z {
        (usize::from(p.x < 0.0), p.y, p.z, a.x)
    } else if a.y >= a.z {
        (2 + usize::from(p.y < 0.0), p.z, p.x, a.y)
    } else {
        (4 + usize::from(p.z < 0.0), p.x, p.y, a.z)
    }
}
