//! The paper's X11 display driver (section 2.4.3): an image-plane quadtree
//! whose leaves hold at most one pixel estimate, drawn as constant-color
//! squares, with empty leaves taking the average of their siblings.
//!
//! The estimates themselves (every ray of a pixel's surface combined, kept
//! across view changes) live in the shared [`Store`]; this driver only
//! decides how to fill the pixels that have none yet.

#[cfg(test)]
mod tests;
mod tree;

pub use tree::Tree;

use glam::Vec3;
use holodeck_protocol::Picture;

use crate::driver::{Driver, Viewport};
use crate::store::{EstimatorOptions, Store};
use tree::Node;

/// The CPU quadtree display driver of the paper's section 2.4.3.
///
/// Each leaf of an image-plane quadtree holds at most one estimate; a leaf is
/// split when a ray lands in it on another pixel, down to single pixels,
/// where rays combine into the pixel's estimate. Rendering fills each leaf's
/// square with its estimate, and each empty leaf with the average of its
/// non-empty siblings (a sibling with children standing in with the average
/// of its own children, recursively).
#[derive(Clone, Debug)]
pub struct QuadtreeDriver {
    store: Store<Tree>,
    /// The render's traversal stack, kept to avoid reallocating.
    stack: Vec<Frame>,
}

/// A branch being drawn: its square (corner and log2 of the side), the next
/// child to visit and the sum of its non-empty children's colors so far.
#[derive(Clone, Copy, Debug)]
struct Frame {
    node: u32,
    x0: u32,
    y0: u32,
    lg: u32,
    next: u32,
    sum: Vec3,
    count: u32,
}

impl Frame {
    fn new(node: u32, x0: u32, y0: u32, lg: u32) -> Frame {
        Frame {
            node,
            x0,
            y0,
            lg,
            next: 0,
            sum: Vec3::ZERO,
            count: 0,
        }
    }
}

impl QuadtreeDriver {
    /// An empty driver for `viewport`.
    pub fn new(viewport: Viewport) -> QuadtreeDriver {
        QuadtreeDriver::with_options(viewport, EstimatorOptions::default())
    }

    /// An empty driver whose pixels combine rays as `options` say.
    pub fn with_options(viewport: Viewport, options: EstimatorOptions) -> QuadtreeDriver {
        QuadtreeDriver {
            store: Store::new(viewport, Tree::default(), true, options),
            stack: Vec::new(),
        }
    }

    /// Nodes in the quadtree (for memory and benchmark reports).
    pub fn node_count(&self) -> usize {
        self.store.index().nodes.len()
    }

    /// The shared store of pixel estimates.
    pub fn store(&self) -> &Store<Tree> {
        &self.store
    }

    /// Estimates held for reprojection, on and off the frame.
    pub fn cached(&self) -> usize {
        self.store.cached()
    }
}

impl Driver for QuadtreeDriver {
    fn name(&self) -> &'static str {
        "quadtree"
    }

    fn store(&self) -> &dyn crate::store::SampleStore {
        &self.store
    }

    fn store_mut(&mut self) -> &mut dyn crate::store::SampleStore {
        &mut self.store
    }

    fn render(&mut self) -> Picture {
        self.store.update_colors();
        let colors = self.store.colors();
        let (w, h) = (self.store.viewport().width, self.store.viewport().height);
        // The tree is over sub-pixels; the picture is drawn at pixel size.
        let sub = self.store.subpixels();
        let (sw, sh) = (w * sub, h * sub);
        let width = w as usize;
        let mut pixels = vec![Vec3::ZERO; width * h as usize];
        let levels = self.store.index().levels;
        let nodes = &self.store.index().nodes;
        let color = |slot: u32| colors[slot as usize];
        // Draws a square of sub-pixels: whole pixels take its color, a part
        // of a pixel adds its share (the sub-pixels of a pixel are siblings,
        // so all of them are drawn).
        let fill = |pixels: &mut [Vec3], x0: u32, y0: u32, side: u32, color: Vec3| {
            if side < sub {
                if x0 < sw && y0 < sh {
                    let share = (side * side) as f32 / (sub * sub) as f32;
                    pixels[(y0 / sub) as usize * width + (x0 / sub) as usize] += color * share;
                }
                return;
            }
            let (x0, y0, side) = (x0 / sub, y0 / sub, side / sub);
            // Clipped to the frame: the root square may stick out of it.
            let (x1, y1) = ((x0 + side).min(w) as usize, (y0 + side).min(h) as usize);
            for row in y0 as usize..y1 {
                pixels[row * width + x0 as usize..row * width + x1].fill(color);
            }
        };
        let root = nodes.first().copied().unwrap_or(Node::EMPTY);
        if !root.is_branch() {
            if root != Node::EMPTY {
                fill(&mut pixels, 0, 0, 1 << levels, color(root.0));
            }
            return Picture {
                width,
                height: h as usize,
                pixels,
            };
        }
        // One depth-first walk: full leaves are drawn on the way down and
        // summed into their parent; a branch, once all its children are
        // summed, draws its empty children with the mean and passes the mean
        // up as its own color. Every branch holds an estimate somewhere (it was
        // made by splitting a full leaf, and estimates are only ever replaced),
        // so the mean is over at least one child.
        let stack = &mut self.stack;
        stack.clear();
        stack.push(Frame::new(0, 0, 0, levels));
        while let Some(top) = stack.last_mut() {
            let first = nodes[top.node as usize].children();
            let half = 1u32 << (top.lg - 1);
            if top.next < 4 {
                let q = top.next;
                top.next += 1;
                let (x, y) = (top.x0 + (q & 1) * half, top.y0 + (q >> 1) * half);
                let c = nodes[first + q as usize];
                if c.is_branch() {
                    let (child, lg) = ((first + q as usize) as u32, top.lg - 1);
                    stack.push(Frame::new(child, x, y, lg));
                } else if c != Node::EMPTY {
                    let k = color(c.0);
                    top.sum += k;
                    top.count += 1;
                    fill(&mut pixels, x, y, half, k);
                }
                continue;
            }
            let done = *top;
            stack.pop();
            let mean = done.sum / done.count.max(1) as f32;
            for q in 0..4u32 {
                let (x, y) = (done.x0 + (q & 1) * half, done.y0 + (q >> 1) * half);
                if nodes[first + q as usize] == Node::EMPTY && x < sw && y < sh {
                    fill(&mut pixels, x, y, half, mean);
                }
            }
            if let Some(parent) = stack.last_mut() {
                parent.sum += mean;
                parent.count += 1;
            }
        }
        Picture {
            width,
            height: h as usize,
            pixels,
        }
    }

    fn heap_bytes(&self) -> usize {
        self.store.heap_bytes() + self.stack.capacity() * std::mem::size_of::<Frame>()
    }
}
