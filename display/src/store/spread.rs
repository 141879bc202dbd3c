//! Spreading the light cut off fireflies over their neighborhood, so that
//! the picture keeps it: an estimate's excess (what its brightest ray had
//! beyond the firefly limit) is shared out over the pixels within a square
//! of a given radius that hold estimates, each an equal share, and added to
//! their values.
//!
//! Light is conserved exactly at pixel level: a pixel's excess is divided by
//! the number of filled pixels its square reaches before the squares are
//! summed, so empty pixels take nothing and every share lands somewhere.
//! Box sums by running totals, and counts of filled pixels from a
//! summed-area table, cost the same whatever the radius.

use rayon::prelude::*;

/// Rows at least this many are summed on every core.
const PARALLEL_ROWS: usize = 64;

/// Per-pixel scratch: excess (RGB) and filled (1 or 0), and their sums.
#[derive(Clone, Debug, Default)]
pub(super) struct Spread {
    grid: Vec<[f32; 4]>,
    across: Vec<[f32; 4]>,
    /// The summed-area table of filled pixels.
    table: Vec<u32>,
}

impl Spread {
    /// Heap bytes held.
    pub fn heap_bytes(&self) -> usize {
        (self.grid.capacity() + self.across.capacity()) * std::mem::size_of::<[f32; 4]>()
            + self.table.capacity() * std::mem::size_of::<u32>()
    }

    /// Shares out the excess of pixels over the filled pixels within
    /// `radius` of each, on a `w` x `h` frame: `excess` yields (pixel, the
    /// pixel's excess, RGB) for every filled pixel (zero excess too: it is
    /// what marks it filled). Returns, per pixel, the light it receives
    /// (RGB in channels 0 to 2; channel 3 is scratch), valid for filled
    /// pixels (row-major).
    pub fn run(
        &mut self,
        w: usize,
        h: usize,
        radius: usize,
        excess: impl Iterator<Item = (usize, [f32; 3])>,
    ) -> &[[f32; 4]] {
        self.grid.clear();
        self.grid.resize(w * h, [0.0; 4]);
        for (p, e) in excess {
            let g = &mut self.grid[p];
            g[0] += e[0];
            g[1] += e[1];
            g[2] += e[2];
            g[3] = 1.0;
        }
        // How many filled pixels each pixel's square reaches, from a
        // summed-area table of them: whole numbers, exactly what running
        // sums of ones and zeros give.
        self.count_filled(w, h, radius);
        // Divided among them: the light each filled pixel gives out per receiver.
        // (The counts ride in channel 3; the excess in 0..3 was not summed.)
        self.grid.par_iter_mut().for_each(|g| {
            if g[3] > 0.0 {
                let n = g[3];
                g[0] /= n;
                g[1] /= n;
                g[2] /= n;
            }
        });
        box_sum(&mut self.grid, &mut self.across, w, h, radius);
        &self.grid
    }
}

impl Spread {
    /// Replaces channel 3 of the grid (1 where a pixel is filled, else 0)
    /// by the number of filled pixels within `radius` of each pixel.
    fn count_filled(&mut self, w: usize, h: usize, radius: usize) {
        // table[(r + 1) * (w + 1) + c + 1]: filled pixels in rows 0..=r, columns 0..=c.
        let stride = w + 1;
        self.table.clear();
        self.table.resize(stride * (h + 1), 0);
        for r in 0..h {
            let (done, rest) = self.table.split_at_mut((r + 1) * stride);
            let above = &done[r * stride..];
            let mut run = 0u32;
            for c in 0..w {
                run += u32::from(self.grid[r * w + c][3] > 0.0);
                rest[c + 1] = above[c + 1] + run;
            }
        }
        let table = &self.table;
        let count = |(r, row): (usize, &mut [[f32; 4]])| {
            let (r0, r1) = (r.saturating_sub(radius), (r + radius + 1).min(h));
            for (c, g) in row.iter_mut().enumerate() {
                let (c0, c1) = (c.saturating_sub(radius), (c + radius + 1).min(w));
                let n = table[r1 * stride + c1] + table[r0 * stride + c0]
                    - table[r0 * stride + c1]
                    - table[r1 * stride + c0];
                g[3] = n as f32;
            }
        };
        if h >= PARALLEL_ROWS {
            self.grid.par_chunks_mut(w).enumerate().for_each(count);
        } else {
            self.grid.chunks_mut(w).enumerate().for_each(count);
        }
    }
}

/// Replaces every channel of `grid` (`w` x `h`) by its sum over the square
/// of `radius` around each pixel, clipped to the frame. All four channels
/// go together, as one vector of four: a caller that needs fewer ignores
/// the rest, and each channel's sums are the ones it would get alone.
fn box_sum(grid: &mut [[f32; 4]], across: &mut Vec<[f32; 4]>, w: usize, h: usize, radius: usize) {
    across.clear();
    across.resize(w * h, [0.0; 4]);
    // Along rows.
    let rows = |(src, dst): (&[[f32; 4]], &mut [[f32; 4]])| row_sums(src, dst, radius);
    if h >= PARALLEL_ROWS {
        grid.par_chunks(w).zip(across.par_chunks_mut(w)).for_each(rows);
    } else {
        grid.chunks(w).zip(across.chunks_mut(w)).for_each(rows);
    }
    // Along columns: one running row of sums, moved down a row at a time.
    let mut acc = vec![[0.0f64; 4]; w];
    let add = |acc: &mut [[f64; 4]], row: &[[f32; 4]]| {
        for (a, v) in acc.iter_mut().zip(row) {
            for k in 0..4 {
                a[k] += f64::from(v[k]);
            }
        }
    };
    let take = |acc: &mut [[f64; 4]], row: &[[f32; 4]]| {
        for (a, v) in acc.iter_mut().zip(row) {
            for k in 0..4 {
                a[k] -= f64::from(v[k]);
            }
        }
    };
    for r in 0..(radius + 1).min(h) {
        add(&mut acc, &across[r * w..(r + 1) * w]);
    }
    for r in 0..h {
        for (g, a) in grid[r * w..(r + 1) * w].iter_mut().zip(&acc) {
            for k in 0..4 {
                g[k] = a[k] as f32;
            }
        }
        if r + radius + 1 < h {
            add(&mut acc, &across[(r + radius + 1) * w..(r + radius + 2) * w]);
        }
        if r >= radius {
            take(&mut acc, &across[(r - radius) * w..(r - radius + 1) * w]);
        }
    }
}

/// Running sums over `radius` on each side along one row, every channel.
fn row_sums(src: &[[f32; 4]], dst: &mut [[f32; 4]], radius: usize) {
    let n = src.len();
    let mut acc = [0.0f64; 4];
    for v in &src[..(radius + 1).min(n)] {
        for k in 0..4 {
            acc[k] += f64::from(v[k]);
        }
    }
    for i in 0..n {
        for k in 0..4 {
            dst[i][k] = acc[k] as f32;
        }
        if i + radius + 1 < n {
            for k in 0..4 {
                acc[k] += f64::from(src[i + radius + 1][k]);
            }
        }
        if i >= radius {
            for k in 0..4 {
                acc[k] -= f64::from(src[i - radius][k]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_sums_match_brute_force_at_borders_too() {
        let (w, h) = (7, 5);
        let src: Vec<[f32; 4]> = (0..w * h).map(|i| [i as f32, 1.0, (i % 3) as f32, 0.5]).collect();
        for radius in [0, 1, 2, 6, 20] {
            let mut grid = src.clone();
            box_sum(&mut grid, &mut Vec::new(), w, h, radius);
            for r in 0..h {
                for c in 0..w {
                    let mut want = [0.0f32; 4];
                    for rr in r.saturating_sub(radius)..=(r + radius).min(h - 1) {
                        for cc in c.saturating_sub(radius)..=(c + radius).min(w - 1) {
                            for k in 0..4 {
                                want[k] += src[rr * w + cc][k];
                            }
                        }
                    }
                    for k in 0..4 {
                        assert!((grid[r * w + c][k] - want[k]).abs() < 1e-3, "r{radius} ({c},{r})[{k}]");
                    }
                }
            }
        }
    }

    #[test]
    fn counts_from_the_summed_area_table_are_the_box_sums_of_the_filled() {
        // Tall enough to count on every core; radii past the frame too.
        let (w, h) = (37, PARALLEL_ROWS + 5);
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let grid: Vec<[f32; 4]> = (0..w * h)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                [1.5, 0.0, 2.0, if x.is_multiple_of(3) { 1.0 } else { 0.0 }]
            })
            .collect();
        for radius in [0, 1, 3, 40, 200] {
            let mut want = grid.clone();
            box_sum(&mut want, &mut Vec::new(), w, h, radius);
            let mut s = Spread {
                grid: grid.clone(),
                ..Spread::default()
            };
            s.count_filled(w, h, radius);
            // The counts (channel 3) are the box sums of the filled marks,
            // bit for bit; the other channels are left as they were.
            let counts = |g: &[[f32; 4]]| g.iter().map(|p| p[3].to_bits()).collect::<Vec<u32>>();
            assert!(counts(&s.grid) == counts(&want), "radius {radius}");
            assert!(s.grid.iter().zip(&grid).all(|(a, b)| a[..3] == b[..3]));
        }
    }

    #[test]
    fn spreading_conserves_light_and_reaches_only_filled_pixels() {
        let (w, h) = (30, 20);
        // Filled: every pixel but a band; excess on a few, near a border too.
        let filled = |p: usize| !(10..13).contains(&(p % w));
        let excess = |p: usize| match p {
            45 => [3.0, 1.0, 0.0],
            301 => [0.0, 0.0, 7.0],
            599 => [1.0, 1.0, 1.0],
            _ => [0.0; 3],
        };
        let mut s = Spread::default();
        let out = s
            .run(w, h, 3, (0..w * h).filter(|&p| filled(p)).map(|p| (p, excess(p))))
            .to_vec();
        let mut total = [0.0f64; 3];
        for (p, g) in out.iter().enumerate() {
            if filled(p) {
                for k in 0..3 {
                    total[k] += f64::from(g[k]);
                }
            }
        }
        for (k, want) in [4.0, 2.0, 8.0].into_iter().enumerate() {
            assert!((total[k] - want).abs() < 1e-4, "channel {k}: {total:?}");
        }
        // Pixel 45 (col 15, row 1) reaches no farther than 3 pixels.
        assert!(out[45][0] > 0.0 && out[45 + 3][0] > 0.0 && out[45 + 4][0] == 0.0);
    }
}
