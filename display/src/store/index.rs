//! How a driver finds a pixel's estimate: a spatial index over the frame's
//! pixels that maps each pixel to at most one slot of the store. The
//! quadtree is one; the splat baseline's plain grid is another.

use super::Entry;

/// Where an estimate goes in a pixel index.
pub enum Spot {
    /// Nothing on its pixel yet: the index position to record its slot at.
    Free(usize),
    /// The slot of the estimate already on its pixel.
    Taken(u32),
}

/// A spatial index over the frame's pixels, one slot per pixel at most.
pub trait PixelIndex {
    /// Empties the index for a frame of this size.
    fn reset(&mut self, width: u32, height: u32);
    /// A number for pixel (`col`, `row`), unique to it, whose order is the
    /// index's memory order (batches are inserted sorted by it).
    fn key(&self, col: u32, row: u32) -> u64;
    /// The pixel (`col`, `row`) of a key: the inverse of [`PixelIndex::key`].
    fn pixel(&self, key: u64) -> (u32, u32);
    /// Keys are below `1 << key_bits()`.
    fn key_bits(&self) -> u32;
    /// Finds the spot of the pixel with `key`, restructuring as needed
    /// (`entries` gives the keys of the slots already in the index).
    fn find(&mut self, entries: &[Entry], key: u64) -> Spot;
    /// Records `slot` at a spot [`PixelIndex::find`] returned as free.
    fn fill(&mut self, at: usize, slot: u32);
    /// Heap bytes the index holds.
    fn heap_bytes(&self) -> usize;
    /// A number for the block of `2^shift` x `2^shift` cells (a pixel of
    /// sub-pixels) that holds the cell of `key`: below [`PixelIndex::blocks`],
    /// and in the same order as the keys, so that a sorted batch visits its
    /// blocks in order.
    fn block(&self, key: u64, shift: u32) -> usize;
    /// How many block numbers there are for `shift`.
    fn blocks(&self, shift: u32) -> usize;
}
