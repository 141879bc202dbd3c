//! Radiance's beam numbering, and its correspondence with this program's.
//!
//! Both number the ordered pairs of cells on different walls, with the same
//! walls (`2 * axis + side`) and the same cell axes per wall, and both keep a
//! ray's entry cell first; only the order differs. Radiance counts from 1,
//! first every pair whose entry wall is the lower-numbered one, ordered by
//! (entry wall, exit wall, entry cell, exit cell) with a cell numbered
//! `u + grid_u * v`, then the same pairs reversed.

use holodeck_protocol::{BeamIndex, CellPair, Section, Wall, WallCell};

/// Radiance's numbering for one grid.
#[derive(Clone, Debug)]
pub struct RadianceBeams {
    grid: [u16; 3],
    cells: [u64; 6],
    /// Radiance's `wi`: the first number of each lower wall's beams.
    first: [u64; 6],
    /// Beams whose entry wall is the lower one.
    half: u64,
}

impl RadianceBeams {
    /// The numbering of a grid.
    pub fn new(grid: [u16; 3]) -> RadianceBeams {
        let cells = Wall::ALL.map(|w| {
            let [u, v] = w.cell_axes();
            u64::from(grid[u]) * u64::from(grid[v])
        });
        let mut first = [1u64; 6];
        for w in 1..6 {
            first[w] = first[w - 1] + cells[w - 1] * cells[w..].iter().sum::<u64>();
        }
        RadianceBeams {
            grid,
            cells,
            first,
            half: first[5] - 1,
        }
    }

    /// Number of beams, numbered `1..=count`.
    pub fn count(&self) -> u64 {
        2 * self.half
    }

    fn cell(&self, c: WallCell) -> u64 {
        let [u, _] = c.wall.cell_axes();
        u64::from(c.cell[0]) + u64::from(self.grid[u]) * u64::from(c.cell[1])
    }

    /// Radiance's number of a beam (cells must lie on the grid, on different walls).
    pub fn index(&self, pair: CellPair) -> u64 {
        let (lo, hi, reversed) = if pair.entry.wall < pair.exit.wall {
            (pair.entry, pair.exit, false)
        } else {
            (pair.exit, pair.entry, true)
        };
        let (a, b) = (usize::from(lo.wall.0), usize::from(hi.wall.0));
        let between: u64 = self.cells[a + 1..b].iter().sum();
        let forward = self.first[a] + self.cells[a] * between + self.cell(lo) * self.cells[b] + self.cell(hi);
        if reversed {
            forward + self.half
        } else {
            forward
        }
    }

    /// For each of Radiance's numbers `1..=count` (at `number - 1`), this
    /// program's index of the same beam of `section`.
    pub fn ours(section: &Section) -> Vec<BeamIndex> {
        let numbering = RadianceBeams::new(section.grid());
        let mut table = vec![0; section.beam_count() as usize];
        for beam in 0..section.beam_count() {
            // Every index below the count has cells: the section made them.
            if let Ok(pair) = section.beam_cells(beam) {
                table[(numbering.index(pair) - 1) as usize] = beam;
            }
        }
        table
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use holodeck_protocol::SectionKind;
    use proptest::prelude::*;

    fn section(grid: [u16; 3]) -> Section {
        Section::new(
            [0.0; 3],
            [[5.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 3.0]],
            grid,
            SectionKind::Interior,
        )
        .unwrap()
    }

    fn cell(wall: u8, cell: [u16; 2]) -> WallCell {
        WallCell { wall: Wall(wall), cell }
    }

    #[test]
    fn numbers_match_radiances_own() {
        // Values from rholo's hdbindex on a 5 x 4 x 3 grid: 7,298 beams.
        let n = RadianceBeams::new([5, 4, 3]);
        assert_eq!(n.count(), 7298);
        let pair = |a, b| CellPair { entry: a, exit: b };
        assert_eq!(n.index(pair(cell(0, [0, 0]), cell(1, [0, 0]))), 1);
        assert_eq!(n.index(pair(cell(0, [0, 0]), cell(1, [0, 1]))), 5);
        assert_eq!(n.index(pair(cell(0, [3, 0]), cell(2, [0, 1]))), 193);
        // The reverse of beam 1 is the first of the second half.
        assert_eq!(n.index(pair(cell(1, [0, 0]), cell(0, [0, 0]))), 3650);
        assert_eq!(RadianceBeams::new([2, 3, 1]).count(), 386);
        assert_eq!(RadianceBeams::new([4, 4, 4]).count(), 7680);
    }

    proptest! {
        #[test]
        fn the_two_numberings_are_one_bijection(grid in proptest::array::uniform3(1u16..7)) {
            let s = section(grid);
            let n = RadianceBeams::new(grid);
            prop_assert_eq!(n.count(), u64::from(s.beam_count()));
            let table = RadianceBeams::ours(&s);
            let mut seen = vec![false; table.len()];
            for (k, &ours) in table.iter().enumerate() {
                prop_assert!(!std::mem::replace(&mut seen[ours as usize], true));
                prop_assert_eq!(n.index(s.beam_cells(ours).unwrap()), k as u64 + 1);
            }
        }
    }
}
