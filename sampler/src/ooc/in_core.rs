//! A scene file assembled into the in-core mesh and kd-tree, for a machine
//! whose memory holds all of it: the walk is then the in-core walk, without
//! links, cache lookups or per-block indices. The tree keeps the file's split
//! planes and leaf lists, and triangles keep their scene-wide ids, so every
//! hit is the one the out-of-core walk finds.

use std::time::Instant;

use rayon::prelude::*;

use super::block::Block;
use super::node::NodeKind;
use super::{OocError, OocScene};
use crate::accel::{KdTree, Node};
use crate::scene::{Scene, Triangle};

/// What assembling cost.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct InCoreReport {
    /// Blocks read.
    pub blocks: u32,
    /// Decompressed bytes read.
    pub bytes: u64,
    /// Nodes of the assembled tree.
    pub nodes: usize,
    /// Seconds, reading included.
    pub seconds: f64,
}

/// Memory the system can give without swapping (Linux: `MemAvailable`).
pub fn available_memory() -> Option<u64> {
    let info = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = info.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

impl OocScene {
    /// True if the whole scene may be assembled in memory: the cache budget
    /// holds every block, and the blocks and the in-core copy, which exist
    /// together while it is made, take at most half the memory available.
    pub fn fits_in_core(&self) -> bool {
        let need = self.header().decompressed_bytes;
        let budget = self.cache().budget() as u64;
        budget >= need && available_memory().is_some_and(|free| need.saturating_mul(4) <= free)
    }

    /// Reads every block and assembles the in-core mesh (the header's
    /// materials, sky and sections) and kd-tree.
    pub fn in_core(&self) -> Result<(Scene, KdTree, InCoreReport), OocError> {
        let start = Instant::now();
        let h = self.header();
        // Texture blocks come after every treelet's.
        let tree_blocks = h
            .textures
            .iter()
            .map(|t| t.block)
            .chain(h.maps_block)
            .chain(h.uv_blocks.iter().copied())
            .min()
            .unwrap_or(h.blocks);
        let blocks: Vec<Block> = (0..tree_blocks)
            .into_par_iter()
            .map(|id| self.cache().read(id))
            .collect::<Result<_, _>>()?;
        let mut scene = self.shell();
        self.assemble_mesh(&blocks, &mut scene)?;
        self.separate_textured(&mut scene)?;
        let (nodes, leaf_tris) = self.assemble_tree(&blocks)?;
        let corrupt = OocError::Corrupt;
        let bytes = blocks.iter().map(|b| b.memory() as u64).sum();
        drop(blocks);
        let node_count = nodes.len();
        let tree = KdTree::from_parts(nodes, leaf_tris, self.bounds(), &scene).map_err(|e| corrupt(e.to_string()))?;
        let report = InCoreReport {
            blocks: h.blocks,
            bytes,
            nodes: node_count,
            seconds: start.elapsed().as_secs_f64(),
        };
        Ok((scene, tree, report))
    }

    /// The triangles of `blocks` into `scene`: a triangle's vertices come
    /// from the first block that lists it; each block's vertices are
    /// appended whole, so its indices only shift.
    fn assemble_mesh(&self, blocks: &[Block], scene: &mut Scene) -> Result<(), OocError> {
        let corrupt = OocError::Corrupt;
        let h = self.header();
        let count = usize::try_from(h.triangles).map_err(|_| corrupt("too many triangles".into()))?;
        let listed: usize = blocks.iter().map(|b| b.ids.len()).sum();
        if count > listed {
            return Err(corrupt(format!(
                "the header counts {count} triangles, the blocks list {listed}"
            )));
        }
        let mut triangles = vec![None; count];
        for b in blocks {
            let base = u32::try_from(scene.positions.len())
                .ok()
                .filter(|base| base.checked_add(b.verts.len() as u32).is_some())
                .ok_or_else(|| corrupt("more vertices than 32-bit indices reach".into()))?;
            scene.positions.extend_from_slice(&b.verts);
            for (t, &id) in b.ids.iter().enumerate() {
                let slot = triangles
                    .get_mut(id as usize)
                    .ok_or_else(|| corrupt(format!("triangle id {id} of {count}")))?;
                if slot.is_none() {
                    *slot = Some(Triangle {
                        v: b.tris[t].v.map(|v| base + u32::from(v)),
                        material: u32::from(b.tris[t].material),
                    });
                }
            }
        }
        scene.triangles = triangles
            .into_iter()
            .enumerate()
            .map(|(id, t)| t.ok_or_else(|| corrupt(format!("triangle {id} is in no block"))))
            .collect::<Result<_, _>>()?;
        Ok(())
    }

    /// Textured triangles get vertices of their own, with their texture
    /// coordinates (and tangents, where the file keeps them).
    fn separate_textured(&self, scene: &mut Scene) -> Result<(), OocError> {
        let corrupt = OocError::Corrupt;
        let count = scene.triangles.len();
        if !self.texturing.uvs.is_empty() {
            scene.uvs = vec![glam::Vec2::ZERO; scene.positions.len()];
            if !self.texturing.tangents.is_empty() {
                scene.tangents = vec![glam::Vec4::ZERO; scene.positions.len()];
            }
            for (k, (id, uv)) in self.texturing.uvs.iter().enumerate() {
                let t = scene
                    .triangles
                    .get_mut(*id as usize)
                    .ok_or_else(|| corrupt(format!("texture coordinates of triangle {id} of {count}")))?;
                let base = scene.positions.len() as u32;
                for (&v, &uv) in t.v.iter().zip(uv) {
                    let p = scene.positions[v as usize];
                    scene.positions.push(p);
                    scene.uvs.push(uv);
                }
                if let Some(tangents) = self.texturing.tangents.get(k) {
                    scene.tangents.extend_from_slice(tangents);
                }
                t.v = [base, base + 1, base + 2];
            }
        }
        Ok(())
    }

    /// The kd-tree's nodes and leaf lists, walked from the root through the
    /// blocks' treelets: links are followed, not kept; a walk through more
    /// links than there are levels means links that cycle.
    #[allow(clippy::type_complexity)]
    fn assemble_tree(&self, blocks: &[Block]) -> Result<(Vec<Node>, Vec<u32>), OocError> {
        let corrupt = OocError::Corrupt;
        let h = self.header();
        let root = self.root();
        let (mut nodes, mut leaf_tris) = (vec![Node::leaf(0, 0)], Vec::new());
        let mut todo = vec![(0usize, root.block, root.node, 0u32)];
        while let Some((out, mut block, mut node, mut hops)) = todo.pop() {
            loop {
                let b = blocks
                    .get(block as usize)
                    .ok_or_else(|| corrupt(format!("a link names block {block}")))?;
                let n = b
                    .nodes
                    .get(node as usize)
                    .ok_or_else(|| corrupt(format!("a link names node {node} past the end of block {block}")))?;
                match n.kind() {
                    NodeKind::Inner { axis, split, left } => {
                        let l = nodes.len();
                        if l + 2 >= 1 << 30 {
                            return Err(corrupt("too many nodes for the in-core tree".into()));
                        }
                        nodes[out] = Node::inner(axis, split, l);
                        nodes.extend([Node::leaf(0, 0); 2]);
                        todo.push((l + 1, block, left + 1, hops));
                        todo.push((l, block, left, hops));
                        break;
                    }
                    NodeKind::Leaf { first, count } => {
                        let f = leaf_tris.len();
                        let list = &b.list[first as usize..(first + count) as usize];
                        leaf_tris.extend(list.iter().map(|&t| b.ids[t as usize]));
                        nodes[out] = Node::leaf(f, count as usize);
                        break;
                    }
                    NodeKind::Link { link, .. } => {
                        let l = b.links[link as usize];
                        hops += 1;
                        if hops > h.levels {
                            return Err(corrupt("links between blocks form a cycle".into()));
                        }
                        (block, node) = (l.block, l.node);
                    }
                }
            }
        }
        Ok((nodes, leaf_tris))
    }
}
