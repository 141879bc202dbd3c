//! From estimates to cones: where each apex lies, how far its cone may
//! reach and how many triangles draw it, from the local density of
//! estimates on a coarse screen grid (paper, 2.4.4).

use glam::Vec3;

use crate::splat::Grid;
use crate::store::{Entry, PixelIndex};

/// Side of a density cell, in target pixels.
pub const CELL: u32 = 8;
/// Fan sizes, fewest triangles first: the paper's cones use 4 to 32.
pub const FANS: [u32; 4] = [4, 8, 16, 32];
/// A cone reaches this many times the mean spacing of estimates around it,
/// so that neighbouring cones overlap and the nearest apex decides.
const REACH: f32 = 2.5;
/// The largest cone covers this share of the frame (the paper's 10%).
const LARGEST_SHARE: f32 = 0.1;
/// The smallest cone's radius in target pixels: it still covers its own
/// pixel whatever the apex's place in it.
const SMALLEST: f32 = 1.5;

/// One cone as the vertex shader reads it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Cone {
    /// Apex (target pixels, y down), depth (negative for escaped rays),
    /// radius in target pixels.
    pub apex: [f32; 4],
    /// Linear radiance, and the fan's triangle count.
    pub color: [f32; 4],
}

/// The largest cone radius for a `width` x `height` target.
pub fn largest_radius(width: u32, height: u32) -> f32 {
    (LARGEST_SHARE * width as f32 * height as f32 / std::f32::consts::PI)
        .sqrt()
        .max(SMALLEST)
}

/// Triangles in the fan of a cone of radius `r`: enough that the polygon
/// strays from the circle by at most about a pixel, at least 4, at most 32.
pub fn fan_for(r: f32) -> u32 {
    if r < 4.0 {
        4
    } else if r < 16.0 {
        8
    } else if r < 64.0 {
        16
    } else {
        32
    }
}

/// Fills `out` with the cones of `entries` (values `colors`, pixels of a
/// `width` x `height` target through `index`), ordered by fan size, and
/// returns how many cones each fan size in [`FANS`] has.
pub fn build(
    entries: &[Entry],
    colors: &[Vec3],
    index: &Grid,
    width: u32,
    height: u32,
    out: &mut Vec<Cone>,
) -> [u32; 4] {
    let (cw, ch) = (
        width.div_ceil(CELL).max(1) as usize,
        height.div_ceil(CELL).max(1) as usize,
    );
    let mut counts = vec![0u32; cw * ch];
    let cell_of = |col: u32, row: u32| (row / CELL) as usize * cw + (col / CELL) as usize;
    for e in entries {
        let (col, row) = index.pixel(e.key);
        counts[cell_of(col, row)] += 1;
    }
    // Estimates in each cell's 3 x 3 neighbourhood: the local density,
    // smooth across cell borders.
    let mut around = vec![0u32; cw * ch];
    for cy in 0..ch {
        for cx in 0..cw {
            let mut n = 0;
            for y in cy.saturating_sub(1)..=(cy + 1).min(ch - 1) {
                for x in cx.saturating_sub(1)..=(cx + 1).min(cw - 1) {
                    n += counts[y * cw + x];
                }
            }
            around[cy * cw + cx] = n;
        }
    }
    let largest = largest_radius(width, height);
    let area = (3 * CELL * 3 * CELL) as f32;
    let radius = |col: u32, row: u32| -> f32 {
        let n = around[cell_of(col, row)].max(1) as f32;
        (REACH * (area / n).sqrt()).clamp(SMALLEST, largest)
    };
    let mut by_fan = [0u32; 4];
    let fan_index = |r: f32| FANS.iter().position(|&f| f == fan_for(r)).unwrap_or(3);
    for e in entries {
        let (col, row) = index.pixel(e.key);
        by_fan[fan_index(radius(col, row))] += 1;
    }
    let mut start = [0usize; 4];
    for i in 1..4 {
        start[i] = start[i - 1] + by_fan[i - 1] as usize;
    }
    out.clear();
    out.resize(entries.len(), Cone::default());
    for (e, c) in entries.iter().zip(colors) {
        let (col, row) = index.pixel(e.key);
        let r = radius(col, row);
        let fan = fan_index(r);
        let at = e.estimate.centroid();
        let depth = e.estimate.depth();
        out[start[fan]] = Cone {
            apex: [
                col as f32 + at[0],
                row as f32 + at[1],
                if depth.is_finite() { depth } else { -1.0 },
                r,
            ],
            color: [c.x, c.y, c.z, FANS[fan] as f32],
        };
        start[fan] += 1;
    }
    by_fan
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fans_grow_with_the_cone_and_stay_within_the_papers_range() {
        assert_eq!(fan_for(1.5), 4);
        assert_eq!(fan_for(10.0), 8);
        assert_eq!(fan_for(40.0), 16);
        assert_eq!(fan_for(500.0), 32);
        // The largest cone covers a tenth of the frame.
        let r = largest_radius(1000, 500);
        assert!((std::f32::consts::PI * r * r / 500_000.0 - 0.1).abs() < 1e-4);
    }
}
