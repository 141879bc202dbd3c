//! A coarse occupancy grid of a tree's scene, for reordering's hit-point
//! estimates: a bit per cell, set where the tree's top levels hold
//! something, and a ray marched cell by cell from its origin to the first
//! occupied one. A ray that leaves a surface starts in an occupied cell and
//! is answered at once; walking the tree's top levels instead took a
//! mispredicted branch a level.

use super::node::Node;
use crate::geom::{Aabb, Ray};

/// Cells in all, about: 2^18 bits are 32 KiB, which stay in a core's L1
/// or L2 cache.
const CELLS: f32 = (1 << 18) as f32;

/// Tree levels whose boxes mark the grid: below this depth a node's box is
/// taken whole.
const DEPTH: usize = 16;

/// The grid.
pub(super) struct CoarseGrid {
    lo: [f32; 3],
    /// Cells per unit length, per axis.
    scale: [f32; 3],
    /// Cell size, per axis.
    size: [f32; 3],
    res: [usize; 3],
    bits: Vec<u64>,
}

impl CoarseGrid {
    /// The grid over `bounds` of the tree `nodes` (root at 0), marked with
    /// the boxes of its non-empty leaves and of its nodes at [`DEPTH`].
    pub(super) fn new(nodes: &[Node], bounds: &Aabb) -> CoarseGrid {
        let extent = (bounds.hi - bounds.lo).max(glam::Vec3::splat(f32::MIN_POSITIVE));
        // Cells about cubic, as many as `CELLS`, at least one an axis.
        let side = (extent.x * extent.y * extent.z / CELLS)
            .cbrt()
            .max(extent.max_element() / 1024.0);
        let res = extent.to_array().map(|e| ((e / side).round() as usize).clamp(1, 1024));
        let size = [0, 1, 2].map(|a| extent[a] / res[a] as f32);
        let mut grid = CoarseGrid {
            lo: bounds.lo.to_array(),
            scale: [0, 1, 2].map(|a| res[a] as f32 / extent[a]),
            size,
            res,
            bits: vec![0; (res[0] * res[1] * res[2]).div_ceil(64)],
        };
        if nodes.is_empty() || bounds.is_empty() {
            return grid;
        }
        let mut todo = vec![(0usize, *bounds, 0usize)];
        while let Some((i, b, depth)) = todo.pop() {
            let Some(n) = nodes.get(i) else { continue };
            if n.is_leaf() {
                if n.count() > 0 {
                    grid.mark(&b);
                }
            } else if depth >= DEPTH {
                grid.mark(&b);
            } else {
                let (mut l, mut r) = (b, b);
                l.hi[n.axis()] = n.split();
                r.lo[n.axis()] = n.split();
                todo.push((n.left(), l, depth + 1));
                todo.push((n.left() + 1, r, depth + 1));
            }
        }
        grid
    }

    /// The cell holding coordinate `x` on `axis`, clamped into the grid.
    fn cell(&self, x: f32, axis: usize) -> usize {
        let c = (x - self.lo[axis]) * self.scale[axis];
        // NaN and negatives cast to 0.
        (c as usize).min(self.res[axis] - 1)
    }

    fn index(&self, c: [usize; 3]) -> usize {
        (c[2] * self.res[1] + c[1]) * self.res[0] + c[0]
    }

    /// Marks every cell `b` touches.
    fn mark(&mut self, b: &Aabb) {
        let lo = [0, 1, 2].map(|a| self.cell(b.lo[a], a));
        let hi = [0, 1, 2].map(|a| self.cell(b.hi[a], a));
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    let i = self.index([x, y, z]);
                    self.bits[i / 64] |= 1 << (i % 64);
                }
            }
        }
    }

    fn occupied(&self, c: [usize; 3]) -> bool {
        let i = self.index(c);
        self.bits[i / 64] & (1 << (i % 64)) != 0
    }

    /// The middle of the ray's range in the first occupied cell it meets
    /// within `(0, ray.t_max]`, or `None` if it meets none.
    pub(super) fn first_hit(&self, ray: &Ray, bounds: &Aabb) -> Option<f32> {
        if !ray.origin.is_finite() || !ray.dir.is_finite() {
            return None;
        }
        let (t0, t1) = bounds.range(ray, ray.dir.recip())?;
        let (o, d) = (ray.origin.to_array(), ray.dir.to_array());
        let start = [0, 1, 2].map(|a| o[a] + d[a] * t0);
        let mut c = [0, 1, 2].map(|a| self.cell(start[a], a));
        // Per axis: the step, the distance between cell walls, and the
        // distance to the next wall (infinite where the ray runs parallel).
        let mut step = [0isize; 3];
        let mut delta = [f32::INFINITY; 3];
        let mut next = [f32::INFINITY; 3];
        for a in 0..3 {
            if d[a] > 0.0 {
                step[a] = 1;
                delta[a] = self.size[a] / d[a];
                next[a] = (self.lo[a] + (c[a] + 1) as f32 * self.size[a] - o[a]) / d[a];
            } else if d[a] < 0.0 {
                step[a] = -1;
                delta[a] = -self.size[a] / d[a];
                next[a] = (self.lo[a] + c[a] as f32 * self.size[a] - o[a]) / d[a];
            }
        }
        let mut enter = t0;
        // Each step leaves a cell for a neighbour: the walk ends within the
        // grid's three widths.
        for _ in 0..self.res.iter().sum::<usize>() + 3 {
            let a = if next[0] <= next[1] && next[0] <= next[2] {
                0
            } else if next[1] <= next[2] {
                1
            } else {
                2
            };
            let exit = next[a].min(t1);
            if self.occupied(c) {
                let t = 0.5 * (enter.max(t0) + exit.max(enter));
                return t.is_finite().then_some(t);
            }
            if next[a] >= t1 || next[a].is_nan() {
                return None;
            }
            let moved = c[a] as isize + step[a];
            if moved < 0 || moved >= self.res[a] as isize {
                return None;
            }
            c[a] = moved as usize;
            enter = next[a];
            next[a] += delta[a];
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::accel::testing::heightfield_and_rays;
    use crate::accel::{BuildOptions, KdTree};

    /// On a field of triangles: a ray leaving the surface is answered in
    /// the cell it starts in; a ray from above meets the first occupied cell
    /// near the surface it will hit; a ray pointing away from everything,
    /// or along the field above it, meets nothing.
    #[test]
    fn estimates_fall_in_the_first_occupied_cell() {
        let (scene, rays) = heightfield_and_rays(64, 500, 3);
        let tree = KdTree::build(&scene, &BuildOptions::default());
        let (grid, bounds) = (tree.grid(), &tree.bounds);
        assert!(grid.res.iter().product::<usize>() > 1000, "{:?}", grid.res);
        for ray in &rays {
            let hit = tree.intersect(ray).unwrap();
            let t = grid.first_hit(ray, bounds).unwrap();
            // The cell holding the hit is marked, so the first occupied cell
            // comes no later; the tree's boxes around the field's squares
            // (0.25 wide) may mark cells a little before it.
            let (est, at) = (t * ray.dir.length(), hit.t * ray.dir.length());
            let cell = Vec3::from(grid.size).length();
            assert!(est <= at + cell && est >= at - 0.5, "{ray:?}: {t} against {}", hit.t);
        }
        let leaving = Ray::new(Vec3::new(8.0, 8.0, 0.02), Vec3::new(0.3, 0.2, 1.0));
        let t = grid.first_hit(&leaving, bounds).unwrap();
        assert!(t >= 0.0 && t <= Vec3::from(grid.size).length(), "{t}");
        let away = Ray::new(Vec3::new(8.0, 8.0, 5.0), Vec3::new(0.1, 0.0, 1.0));
        assert_eq!(grid.first_hit(&away, bounds), None);
        let along = Ray::new(Vec3::new(-1.0, 8.0, 3.0), Vec3::X);
        assert_eq!(grid.first_hit(&along, bounds), None);
    }

    /// Rays that are not finite, or that start outside the grid and miss
    /// it, get no estimate and never panic.
    #[test]
    fn odd_rays_get_no_estimate_or_a_finite_one() {
        let (scene, _) = heightfield_and_rays(16, 1, 1);
        let tree = KdTree::build(&scene, &BuildOptions::default());
        for (o, d) in [
            (Vec3::splat(f32::NAN), Vec3::X),
            (Vec3::ZERO, Vec3::splat(f32::NAN)),
            (Vec3::new(1.0, 1.0, 1.0), Vec3::new(0.0, 0.0, -1.0)),
            (Vec3::new(-100.0, 1.0, 0.01), Vec3::X),
            (Vec3::new(1e30, 1.0, 0.0), -Vec3::X),
            (Vec3::new(2.0, 2.0, 0.01), Vec3::new(f32::INFINITY, 0.0, 0.0)),
        ] {
            if let Some(t) = tree.grid().first_hit(&Ray::new(o, d), &tree.bounds) {
                assert!(t.is_finite() && t >= 0.0, "{o} {d}: {t}");
            }
        }
    }
}
