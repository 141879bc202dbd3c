//! Beams: every ray through a section enters one wall cell and leaves another,
//! and the ordered pair of cells is its beam.
//!
//! Beam indices are laid out by (entry wall, exit wall) pair in wall order, then
//! by entry cell, then by exit cell, so the mapping is a dense bijection onto
//! `0..section.beam_count()`. Positions inside a cell are one byte per axis
//! (256 sub-cells); decoding places a ray at sub-cell centers.

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::section::{Section, SectionError, Wall};

/// Index of a beam within its section.
pub type BeamIndex = u32;

/// A beam of a particular section of a holodeck.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct BeamKey {
    /// Index of the section within the holodeck.
    pub section: u32,
    /// Index of the beam within the section.
    pub beam: BeamIndex,
}

impl BeamKey {
    /// Makes a key.
    pub fn new(section: u32, beam: BeamIndex) -> BeamKey {
        BeamKey { section, beam }
    }
}

/// One cell of one wall; `cell` holds the (u, v) coordinates along [`Wall::cell_axes`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct WallCell {
    /// The wall.
    pub wall: Wall,
    /// Cell coordinates along the wall's two cell axes.
    pub cell: [u16; 2],
}

/// The two cells that define a beam.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct CellPair {
    /// The cell a ray enters the section through.
    pub entry: WallCell,
    /// The cell it leaves through.
    pub exit: WallCell,
}

/// Where a ray's line crosses a section.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocatedRay {
    /// Its beam.
    pub beam: BeamIndex,
    /// Sub-cell position (u, v) within the entry cell.
    pub entry_sub: [u8; 2],
    /// Sub-cell position (u, v) within the exit cell.
    pub exit_sub: [u8; 2],
    /// Ray parameter where the line enters the section (may be negative).
    pub t_entry: f64,
    /// Ray parameter where the line leaves it.
    pub t_exit: f64,
}

/// The ray a beam sample stands for: from the entry wall toward the exit wall.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BeamRay {
    /// World point on the entry wall.
    pub origin: DVec3,
    /// Unit world direction toward the exit point.
    pub direction: DVec3,
    /// World distance from the entry point to the exit point.
    pub length: f64,
}

impl Section {
    fn cell_index(&self, c: WallCell) -> Result<u32, SectionError> {
        let [u, v] = c.wall.cell_axes();
        let (gu, gv) = (self.grid()[u], self.grid()[v]);
        if c.wall.0 > 5 || c.cell[0] >= gu || c.cell[1] >= gv {
            return Err(SectionError::CellOutOfRange {
                wall: c.wall.0,
                cell: c.cell,
            });
        }
        Ok(u32::from(c.cell[0]) * u32::from(gv) + u32::from(c.cell[1]))
    }

    fn cell_at(&self, wall: Wall, index: u32) -> WallCell {
        let gv = u32::from(self.grid()[wall.cell_axes()[1]]);
        WallCell {
            wall,
            cell: [(index / gv) as u16, (index % gv) as u16],
        }
    }

    /// The beam index of an ordered cell pair.
    pub fn beam_index(&self, pair: CellPair) -> Result<BeamIndex, SectionError> {
        if pair.entry.wall == pair.exit.wall {
            return Err(SectionError::SameWall(pair.entry.wall.0));
        }
        let entry = self.cell_index(pair.entry)?;
        let exit = self.cell_index(pair.exit)?;
        let base = self
            .wall_pairs()
            .iter()
            .find(|(a, b, _)| *a == pair.entry.wall && *b == pair.exit.wall)
            .map(|p| p.2)
            .unwrap_or(0);
        Ok(base + entry * self.wall_cells(pair.exit.wall) + exit)
    }

    /// The cell pair of a beam index.
    pub fn beam_cells(&self, beam: BeamIndex) -> Result<CellPair, SectionError> {
        if beam >= self.beam_count() {
            return Err(SectionError::BeamOutOfRange {
                beam,
                count: self.beam_count(),
            });
        }
        let pairs = self.wall_pairs();
        let k = pairs.partition_point(|p| p.2 <= beam) - 1;
        let (entry_wall, exit_wall, base) = pairs[k];
        let offset = beam - base;
        let exit_cells = self.wall_cells(exit_wall);
        Ok(CellPair {
            entry: self.cell_at(entry_wall, offset / exit_cells),
            exit: self.cell_at(exit_wall, offset % exit_cells),
        })
    }

    /// Unit-frame point at sub-cell center `sub` of a wall cell.
    fn wall_point(&self, c: WallCell, sub: [u8; 2]) -> DVec3 {
        let [u, v] = c.wall.cell_axes();
        let mut p = DVec3::ZERO;
        p[c.wall.axis()] = f64::from(c.wall.side());
        for (k, axis) in [u, v].into_iter().enumerate() {
            let within = (f64::from(sub[k]) + 0.5) / 256.0;
            p[axis] = (f64::from(c.cell[k]) + within) / f64::from(self.grid()[axis]);
        }
        p
    }

    /// Cell and sub-cell of a unit-frame point lying on `wall`.
    fn wall_position(&self, wall: Wall, p: DVec3) -> (WallCell, [u8; 2]) {
        let mut cell = [0u16; 2];
        let mut sub = [0u8; 2];
        for (k, axis) in wall.cell_axes().into_iter().enumerate() {
            let g = self.grid()[axis];
            let x = (p[axis] * f64::from(g)).clamp(0.0, f64::from(g));
            let c = (x.floor() as u16).min(g - 1);
            cell[k] = c;
            sub[k] = (((x - f64::from(c)) * 256.0) as u16).min(255) as u8;
        }
        (WallCell { wall, cell }, sub)
    }

    /// Finds where the *line* through `origin` along `dir` (world frame) crosses the
    /// section, or `None` if it misses or only grazes an edge. The entry is where
    /// the line enters moving along `dir`.
    pub fn locate(&self, origin: DVec3, dir: DVec3) -> Option<LocatedRay> {
        let p = self.world_to_unit(origin);
        let d = self.world_dir_to_unit(dir);
        let (mut t_near, mut t_far) = (f64::NEG_INFINITY, f64::INFINITY);
        let (mut entry_wall, mut exit_wall) = (None, None);
        for a in 0..3 {
            if d[a] == 0.0 {
                if !(0.0..=1.0).contains(&p[a]) {
                    return None;
                }
                continue;
            }
            let (t0, t1) = ((0.0 - p[a]) / d[a], (1.0 - p[a]) / d[a]);
            let (near, far, near_side) = if d[a] > 0.0 { (t0, t1, 0) } else { (t1, t0, 1) };
            if near > t_near {
                t_near = near;
                entry_wall = Some(Wall((2 * a + near_side) as u8));
            }
            if far < t_far {
                t_far = far;
                exit_wall = Some(Wall((2 * a + 1 - near_side) as u8));
            }
        }
        let (entry_wall, exit_wall) = (entry_wall?, exit_wall?);
        // Finite first: then the comparison cannot meet a NaN.
        if !t_near.is_finite() || !t_far.is_finite() || t_near >= t_far || entry_wall == exit_wall {
            return None;
        }
        let (entry, entry_sub) = self.wall_position(entry_wall, p + d * t_near);
        let (exit, exit_sub) = self.wall_position(exit_wall, p + d * t_far);
        let beam = self.beam_index(CellPair { entry, exit }).ok()?;
        Some(LocatedRay {
            beam,
            entry_sub,
            exit_sub,
            t_entry: t_near,
            t_exit: t_far,
        })
    }

    /// The ray a beam sample stands for, from sub-cell centers of its entry and exit cells.
    pub fn beam_ray(&self, beam: BeamIndex, entry_sub: [u8; 2], exit_sub: [u8; 2]) -> Result<BeamRay, SectionError> {
        let cells = self.beam_cells(beam)?;
        let a = self.unit_to_world(self.wall_point(cells.entry, entry_sub));
        let b = self.unit_to_world(self.wall_point(cells.exit, exit_sub));
        let along = b - a;
        let length = along.length();
        Ok(BeamRay {
            origin: a,
            direction: along / length,
            length,
        })
    }

    /// The beams whose entry cell is the beam's or next to it on the same
    /// wall (diagonals included), and whose exit cell is too: the beam
    /// itself left out. Their rays run nearly as the beam's do, so that
    /// where a sparse file left a view's pixels without a ray, rays of these
    /// can fill them.
    pub fn neighbour_beams(&self, beam: BeamIndex) -> Result<Vec<BeamIndex>, SectionError> {
        let pair = self.beam_cells(beam)?;
        let around = |c: WallCell| -> Vec<WallCell> {
            let [u, v] = c.wall.cell_axes();
            let (gu, gv) = (i32::from(self.grid()[u]), i32::from(self.grid()[v]));
            let (cu, cv) = (i32::from(c.cell[0]), i32::from(c.cell[1]));
            (cu - 1..=cu + 1)
                .flat_map(|a| (cv - 1..=cv + 1).map(move |b| (a, b)))
                .filter(|&(a, b)| a >= 0 && b >= 0 && a < gu && b < gv)
                .map(|(a, b)| WallCell {
                    wall: c.wall,
                    cell: [a as u16, b as u16],
                })
                .collect()
        };
        let exits = around(pair.exit);
        let mut out = Vec::with_capacity(9 * exits.len());
        for entry in around(pair.entry) {
            for &exit in &exits {
                let b = self.beam_index(CellPair { entry, exit })?;
                if b != beam {
                    out.push(b);
                }
            }
        }
        Ok(out)
    }

    /// World volume swept between a beam's two cells, used to weight batch filling:
    /// half the sum of each cell's area projected onto the line joining the cell
    /// centers, times that line's length. Exact for a prism between facing cells.
    pub fn beam_volume(&self, beam: BeamIndex) -> Result<f64, SectionError> {
        let cells = self.beam_cells(beam)?;
        let centre = |c: WallCell| self.unit_to_world(self.wall_point(c, [127, 127]) + self.half_sub(c));
        let area = |c: WallCell| {
            let [u, v] = c.wall.cell_axes();
            let eu = self.axes()[u] / f64::from(self.grid()[u]);
            let ev = self.axes()[v] / f64::from(self.grid()[v]);
            eu.cross(ev)
        };
        let between = centre(cells.exit) - centre(cells.entry);
        Ok(0.5 * (area(cells.entry).dot(between).abs() + area(cells.exit).dot(between).abs()))
    }

    /// Offset from sub-cell 127's center to the exact cell center, unit frame.
    fn half_sub(&self, c: WallCell) -> DVec3 {
        let mut off = DVec3::ZERO;
        for axis in c.wall.cell_axes() {
            off[axis] = 0.5 / 256.0 / f64::from(self.grid()[axis]);
        }
        off
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::section::SectionKind;
    use proptest::prelude::*;

    fn room(grid: [u16; 3]) -> Section {
        Section::new(
            [1.0, 2.0, -0.5],
            [[4.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 2.5]],
            grid,
            SectionKind::Interior,
        )
        .unwrap()
    }

    fn sheared(grid: [u16; 3]) -> Section {
        Section::new(
            [-3.0, 0.5, 7.0],
            [[3.0, 0.4, -0.2], [-0.5, 2.0, 0.3], [0.1, 0.2, 1.7]],
            grid,
            SectionKind::Exterior,
        )
        .unwrap()
    }

    #[test]
    fn every_beam_index_round_trips_on_small_grids() {
        for grid in [[1, 1, 1], [2, 3, 4], [5, 1, 7], [6, 6, 6]] {
            let s = room(grid);
            for beam in 0..s.beam_count() {
                let cells = s.beam_cells(beam).unwrap();
                assert_ne!(cells.entry.wall, cells.exit.wall);
                assert_eq!(s.beam_index(cells).unwrap(), beam, "grid {grid:?}");
            }
            assert!(s.beam_cells(s.beam_count()).is_err());
        }
    }

    #[test]
    fn a_beams_neighbours_are_the_beams_of_the_cells_around_its_two() {
        let s = room([4, 5, 6]);
        let step = |a: WallCell, b: WallCell| {
            a.wall == b.wall && (0..2).all(|k| (i32::from(a.cell[k]) - i32::from(b.cell[k])).abs() <= 1)
        };
        let mut counts = std::collections::BTreeMap::new();
        for beam in (0..s.beam_count()).step_by(7) {
            let cells = s.beam_cells(beam).unwrap();
            let n = s.neighbour_beams(beam).unwrap();
            let mut unique = n.clone();
            unique.sort_unstable();
            unique.dedup();
            assert_eq!(unique.len(), n.len(), "beam {beam}: a neighbour twice");
            assert!(!n.contains(&beam));
            for &b in &n {
                let c = s.beam_cells(b).unwrap();
                assert!(step(c.entry, cells.entry) && step(c.exit, cells.exit), "{beam} -> {b}");
            }
            // Every beam that qualifies is there: 3 x 3 cells at each end,
            // fewer at the edges of a wall, less the beam itself.
            let qualifying = (0..s.beam_count())
                .filter(|&b| b != beam)
                .filter(|&b| {
                    let c = s.beam_cells(b).unwrap();
                    step(c.entry, cells.entry) && step(c.exit, cells.exit)
                })
                .count();
            assert_eq!(n.len(), qualifying, "beam {beam}");
            *counts.entry(n.len()).or_insert(0) += 1;
        }
        // Cells inside a wall have 8 neighbours: 81 - 1 beams.
        assert!(counts.contains_key(&80), "{counts:?}");
        assert!(s.neighbour_beams(s.beam_count()).is_err());
    }

    #[test]
    fn bad_cell_pairs_are_refused() {
        let s = room([2, 2, 2]);
        let c = WallCell {
            wall: Wall(0),
            cell: [0, 0],
        };
        assert_eq!(
            s.beam_index(CellPair { entry: c, exit: c }),
            Err(SectionError::SameWall(0))
        );
        let far = WallCell {
            wall: Wall(1),
            cell: [2, 0],
        };
        assert!(matches!(
            s.beam_index(CellPair { entry: c, exit: far }),
            Err(SectionError::CellOutOfRange { .. })
        ));
    }

    #[test]
    fn rays_parallel_to_walls_and_grazing_edges() {
        let s = room([4, 3, 2]);
        let o = s.origin();
        // Straight along axis 0 through the middle: enters wall 0, leaves wall 1.
        let hit = s.locate(o + DVec3::new(-1.0, 1.5, 1.25), DVec3::X).unwrap();
        let cells = s.beam_cells(hit.beam).unwrap();
        assert_eq!((cells.entry.wall, cells.exit.wall), (Wall(0), Wall(1)));
        assert_eq!(cells.entry.cell, [1, 1]);
        assert!((hit.t_entry - 1.0).abs() < 1e-12 && (hit.t_exit - 5.0).abs() < 1e-12);
        // Reversed direction swaps entry and exit walls.
        let back = s.locate(o + DVec3::new(-1.0, 1.5, 1.25), -DVec3::X).unwrap();
        assert_eq!(s.beam_cells(back.beam).unwrap().entry.wall, Wall(1));
        // Parallel to a wall but outside: miss. Zero direction: miss.
        assert!(s.locate(o + DVec3::new(0.0, 5.0, 1.0), DVec3::X).is_none());
        assert!(s.locate(o + DVec3::new(1.0, 1.0, 1.0), DVec3::ZERO).is_none());
        // Lying in a wall's plane is inside the closed slab: still a beam.
        assert!(s.locate(o + DVec3::new(-1.0, 0.0, 1.0), DVec3::X).is_some());
    }

    #[test]
    fn facing_cells_have_prism_volume() {
        let s = room([4, 3, 2]);
        let entry = WallCell {
            wall: Wall(0),
            cell: [1, 1],
        };
        let exit = WallCell {
            wall: Wall(1),
            cell: [1, 1],
        };
        let beam = s.beam_index(CellPair { entry, exit }).unwrap();
        let cell_area = (3.0 / 3.0) * (2.5 / 2.0);
        assert!((s.beam_volume(beam).unwrap() - cell_area * 4.0).abs() < 1e-9);
        for b in (0..s.beam_count()).step_by(97) {
            let v = s.beam_volume(b).unwrap();
            assert!(v.is_finite() && v > 0.0);
        }
    }

    fn any_section() -> impl Strategy<Value = Section> {
        (1u16..10, 1u16..10, 1u16..10, any::<bool>()).prop_map(
            |(w, d, h, shear)| {
                if shear {
                    sheared([w, d, h])
                } else {
                    room([w, d, h])
                }
            },
        )
    }

    proptest! {
        #[test]
        fn random_beam_indices_round_trip_on_large_grids(
            w in 1u16..=255, d in 1u16..=40, h in 1u16..=40, pick in any::<u32>()
        ) {
            prop_assume!(crate::section::beam_count_for_grid([w, d, h]) <= crate::MAX_BEAMS_PER_SECTION);
            let s = room([w, d, h]);
            let beam = pick % s.beam_count();
            prop_assert_eq!(s.beam_index(s.beam_cells(beam).unwrap()).unwrap(), beam);
        }

        #[test]
        fn decoded_beam_rays_locate_back_to_the_same_sample(
            s in any_section(), pick in any::<u32>(), sub in any::<[u8; 4]>()
        ) {
            let beam = pick % s.beam_count();
            let r = s.beam_ray(beam, [sub[0], sub[1]], [sub[2], sub[3]]).unwrap();
            let found = s.locate(r.origin, r.direction).unwrap();
            prop_assert_eq!(found.beam, beam);
            prop_assert_eq!(found.entry_sub, [sub[0], sub[1]]);
            prop_assert_eq!(found.exit_sub, [sub[2], sub[3]]);
            prop_assert!(found.t_entry.abs() < 1e-9 * s.diagonal());
            prop_assert!((found.t_exit - r.length).abs() < 1e-9 * s.diagonal());
        }

        #[test]
        fn random_rays_map_to_the_cells_they_cross(
            s in any_section(),
            a in prop::array::uniform3(0.0f64..1.0),
            b in prop::array::uniform3(0.0f64..1.0),
            back in -3.0f64..3.0, scale in 0.01f64..100.0,
        ) {
            let (pa, pb) = (s.unit_to_world(DVec3::from(a)), s.unit_to_world(DVec3::from(b)));
            prop_assume!((pb - pa).length() > 1e-6 * s.diagonal());
            let dir = (pb - pa) * scale;
            let origin = pa - dir * back;
            let hit = s.locate(origin, dir).unwrap();
            let cells = s.beam_cells(hit.beam).unwrap();
            let r = s.beam_ray(hit.beam, hit.entry_sub, hit.exit_sub).unwrap();
            for (cell, t, decoded) in [
                (cells.entry, hit.t_entry, r.origin),
                (cells.exit, hit.t_exit, r.origin + r.direction * r.length),
            ] {
                // The true crossing, from a plane intersection independent of `locate`.
                let axis = cell.wall.axis();
                let normal = s.axes()[(axis + 1) % 3].cross(s.axes()[(axis + 2) % 3]);
                let plane = s.origin() + s.axes()[axis] * f64::from(cell.wall.side());
                let tp = (plane - origin).dot(normal) / dir.dot(normal);
                prop_assert!((tp - t).abs() <= 1e-9 * (1.0 + t.abs()));
                let truth = s.world_to_unit(origin + dir * tp);
                let got = s.world_to_unit(decoded);
                for (k, ax) in cell.wall.cell_axes().into_iter().enumerate() {
                    let g = f64::from(s.grid()[ax]);
                    let x = truth[ax] * g;
                    // The ray really crosses the beam's cell...
                    prop_assert!(x >= f64::from(cell.cell[k]) - 1e-9 && x <= f64::from(cell.cell[k]) + 1.0 + 1e-9);
                    // ...and decodes to within one sub-cell of where it crossed.
                    prop_assert!((got[ax] * g - x).abs() * 256.0 <= 1.0 + 1e-6);
                }
            }
        }
    }
}
