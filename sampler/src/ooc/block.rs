//! One block of the scene file, decompressed: treelet nodes, the link table
//! (where each LOD node leads, the voxel it carries and its size), and the
//! triangles its leaves list (Áfra 2012, 4.3–4.6), with vertices shared inside
//! the block. The decoder checks every index before anything can follow it,
//! so a block that decodes cannot send the traversal out of bounds.

use glam::Vec3;

use super::node::{NodeKind, TNode};
use super::voxel::Voxel;

/// First word of every block.
pub const BLOCK_MAGIC: u32 = u32::from_le_bytes(*b"HDSB");
/// Most triangles or vertices in one block (they are addressed with 16 bits).
pub const MAX_BLOCK_ITEMS: usize = u16::MAX as usize;
/// Largest decompressed block accepted.
pub const MAX_BLOCK_BYTES: usize = 64 << 20;

/// Where an LOD node leads: the root of a treelet in some block, with the
/// voxel that stands for that treelet and the radius of its node's bounding sphere.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Link {
    /// Block holding the treelet.
    pub block: u32,
    /// Index of the treelet's root among that block's nodes.
    pub node: u32,
    /// Radius of the sphere around the node (f32 bits).
    pub radius_bits: u32,
    /// The voxel of the node.
    pub voxel: Voxel,
}

impl Link {
    /// Radius of the sphere around the linked node.
    #[inline]
    pub fn radius(&self) -> f32 {
        f32::from_bits(self.radius_bits)
    }
}

const LINK_WORDS: usize = 3 + 12;

/// A triangle of a block: three vertex indices and a material.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlockTri {
    /// Indices into the block's vertices.
    pub v: [u16; 3],
    /// Material index.
    pub material: u16,
}

/// A decoded, validated block.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Block {
    /// Treelet nodes; children come after their parent.
    pub nodes: Vec<TNode>,
    /// Link table of the LOD nodes.
    pub links: Vec<Link>,
    /// Vertex positions.
    pub verts: Vec<Vec3>,
    /// Scene-wide triangle ids, by block triangle.
    pub ids: Vec<u32>,
    /// Triangles.
    pub tris: Vec<BlockTri>,
    /// Triangle lists of the leaves (block triangle indices).
    pub list: Vec<u16>,
}

/// Why a block cannot be used.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BlockError {
    /// Shorter than its counts say, or not a block at all.
    #[error("block is truncated or not a block ({0})")]
    Malformed(&'static str),
    /// An index that points outside the block or the file.
    #[error("block is corrupt: {0}")]
    Corrupt(String),
}

impl Block {
    /// Bytes the block occupies in memory once decoded.
    pub fn memory(&self) -> usize {
        std::mem::size_of::<Block>()
            + self.nodes.len() * 8
            + self.links.len() * std::mem::size_of::<Link>()
            + self.verts.len() * 12
            + self.ids.len() * 4
            + self.tris.len() * 8
            + self.list.len() * 2
    }

    /// The three vertices of block triangle `t`.
    #[inline]
    pub fn triangle(&self, t: usize) -> [Vec3; 3] {
        let v = self.tris[t].v;
        [
            self.verts[v[0] as usize],
            self.verts[v[1] as usize],
            self.verts[v[2] as usize],
        ]
    }

    /// The stored bytes (before compression).
    pub fn encode(&self) -> Vec<u8> {
        let mut w: Vec<u32> = Vec::with_capacity(
            6 + self.nodes.len() * 2
                + self.links.len() * LINK_WORDS
                + self.verts.len() * 3
                + self.tris.len() * 3
                + self.list.len() / 2
                + 1,
        );
        w.extend([
            BLOCK_MAGIC,
            self.nodes.len() as u32,
            self.links.len() as u32,
            self.verts.len() as u32,
            self.tris.len() as u32,
            self.list.len() as u32,
        ]);
        for n in &self.nodes {
            w.extend(n.words());
        }
        for l in &self.links {
            w.extend([l.block, l.node, l.radius_bits]);
            for f in l.voxel.0 {
                w.extend([f as u32, (f >> 32) as u32]);
            }
        }
        for v in &self.verts {
            w.extend(v.to_array().map(f32::to_bits));
        }
        w.extend(&self.ids);
        for t in &self.tris {
            w.push(u32::from(t.v[0]) | u32::from(t.v[1]) << 16);
            w.push(u32::from(t.v[2]) | u32::from(t.material) << 16);
        }
        for pair in self.list.chunks(2) {
            w.push(u32::from(pair[0]) | u32::from(pair.get(1).copied().unwrap_or(0)) << 16);
        }
        w.iter().flat_map(|x| x.to_le_bytes()).collect()
    }

    /// Decodes and validates a block of a file with `blocks` blocks and
    /// `materials` materials.
    pub fn decode(bytes: &[u8], blocks: u32, materials: u32) -> Result<Block, BlockError> {
        if !bytes.len().is_multiple_of(4) {
            return Err(BlockError::Malformed("length is not a whole number of words"));
        }
        let mut r = Reader { b: bytes };
        if r.take(1)?.get(0) != BLOCK_MAGIC {
            return Err(BlockError::Malformed("wrong magic"));
        }
        let c = r.take(5)?;
        let [n_nodes, n_links, n_verts, n_tris, n_list] = [0, 1, 2, 3, 4].map(|i| c.get(i) as usize);
        if n_verts > MAX_BLOCK_ITEMS || n_tris > MAX_BLOCK_ITEMS {
            return Err(BlockError::Corrupt(format!("{n_verts} vertices, {n_tris} triangles")));
        }
        let nodes: Vec<TNode> = r
            .take(n_nodes.checked_mul(2).ok_or(BlockError::Malformed("node count"))?)?
            .groups::<2>()
            .map(|p| TNode::from_words(p[0], p[1]))
            .collect();
        let links: Vec<Link> = r
            .take(
                n_links
                    .checked_mul(LINK_WORDS)
                    .ok_or(BlockError::Malformed("link count"))?,
            )?
            .groups::<LINK_WORDS>()
            .map(|p| Link {
                block: p[0],
                node: p[1],
                radius_bits: p[2],
                voxel: Voxel(std::array::from_fn(|f| {
                    u64::from(p[3 + 2 * f]) | u64::from(p[4 + 2 * f]) << 32
                })),
            })
            .collect();
        let verts: Vec<Vec3> = r
            .take(n_verts * 3)?
            .groups::<3>()
            .map(|p| Vec3::new(f32::from_bits(p[0]), f32::from_bits(p[1]), f32::from_bits(p[2])))
            .collect();
        let ids: Vec<u32> = r.take(n_tris)?.groups::<1>().map(|p| p[0]).collect();
        let tris: Vec<BlockTri> = r
            .take(n_tris * 2)?
            .groups::<2>()
            .map(|p| BlockTri {
                v: [p[0] as u16, (p[0] >> 16) as u16, p[1] as u16],
                material: (p[1] >> 16) as u16,
            })
            .collect();
        let list: Vec<u16> = r
            .take(n_list.div_ceil(2))?
            .groups::<1>()
            .flat_map(|[x]| [x as u16, (x >> 16) as u16])
            .take(n_list)
            .collect();
        if !r.b.is_empty() {
            return Err(BlockError::Malformed("bytes after the last list entry"));
        }
        let block = Block {
            nodes,
            links,
            verts,
            ids,
            tris,
            list,
        };
        block.validate(blocks, materials)?;
        Ok(block)
    }

    /// Lets the walk follow links into this block (`id`) itself without the
    /// link table: each such link node keeps its target node. Only targets
    /// after the link node are taken, so a walk inside a block never cycles.
    pub fn resolve_local_links(&mut self, id: u32) {
        for i in 0..self.nodes.len() {
            if let NodeKind::Link { link, local: 0 } = self.nodes[i].kind() {
                if let Some(l) = self.links.get(link as usize) {
                    if l.block == id
                        && l.node as usize > i
                        && (l.node as usize) < self.nodes.len()
                        && l.node < (1 << 28)
                    {
                        self.nodes[i] = TNode::local_link(link, l.node);
                    }
                }
            }
        }
    }

    fn validate(&self, blocks: u32, materials: u32) -> Result<(), BlockError> {
        let bad = |m: String| Err(BlockError::Corrupt(m));
        for (i, n) in self.nodes.iter().enumerate() {
            match n.kind() {
                NodeKind::Inner { split, left, .. } => {
                    // Children strictly after the parent: no cycles.
                    if left as usize <= i || left as usize + 1 >= self.nodes.len() || !split.is_finite() {
                        return bad(format!("node {i}: children at {left} of {}", self.nodes.len()));
                    }
                }
                NodeKind::Leaf { first, count } => {
                    if first as usize + count as usize > self.list.len() {
                        return bad(format!("node {i}: list {first}+{count} of {}", self.list.len()));
                    }
                }
                NodeKind::Link { link, local } => {
                    if link as usize >= self.links.len() || local != 0 {
                        return bad(format!("node {i}: link {link} of {}", self.links.len()));
                    }
                }
            }
        }
        for (i, l) in self.links.iter().enumerate() {
            if l.block >= blocks || !l.radius().is_finite() || l.radius() < 0.0 {
                return bad(format!("link {i}: block {} of {blocks}", l.block));
            }
        }
        if let Some((i, _)) = self.verts.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return bad(format!("vertex {i} is not finite"));
        }
        for (i, t) in self.tris.iter().enumerate() {
            if t.v.iter().any(|&v| v as usize >= self.verts.len()) || u32::from(t.material) >= materials {
                return bad(format!("triangle {i}: {t:?}"));
            }
        }
        if let Some(i) = self.list.iter().position(|&t| t as usize >= self.tris.len()) {
            return bad(format!("list entry {i} names triangle {}", self.list[i]));
        }
        Ok(())
    }
}

/// Little-endian words read off the front of a block's bytes.
struct Reader<'a> {
    b: &'a [u8],
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<Words<'a>, BlockError> {
        let len = n
            .checked_mul(4)
            .filter(|&l| l <= self.b.len())
            .ok_or(BlockError::Malformed("shorter than its counts"))?;
        let (w, rest) = self.b.split_at(len);
        self.b = rest;
        Ok(Words(w))
    }
}

/// A run of little-endian words, read in place.
#[derive(Clone, Copy)]
struct Words<'a>(&'a [u8]);

impl<'a> Words<'a> {
    /// Word `i` (0 past the end).
    fn get(self, i: usize) -> u32 {
        self.0
            .get(4 * i..4 * i + 4)
            .map_or(0, |c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
    }
    /// The words `K` at a time.
    fn groups<const K: usize>(self) -> impl Iterator<Item = [u32; K]> + 'a {
        self.0
            .chunks_exact(4 * K)
            .map(|c| std::array::from_fn(|i| u32::from_le_bytes([c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]])))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn sample() -> Block {
        Block {
            nodes: vec![TNode::inner(1, 0.5, 1), TNode::leaf(0, 3), TNode::link(0)],
            links: vec![Link {
                block: 3,
                node: 7,
                radius_bits: 2.5f32.to_bits(),
                voxel: Voxel([1, 2, 3, 4, 5, u64::MAX]),
            }],
            verts: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z],
            ids: vec![10, 11],
            tris: vec![
                BlockTri {
                    v: [0, 1, 2],
                    material: 1,
                },
                BlockTri {
                    v: [1, 2, 3],
                    material: 0,
                },
            ],
            list: vec![0, 1, 1],
        }
    }

    #[test]
    fn blocks_round_trip() {
        let b = sample();
        let bytes = b.encode();
        assert_eq!(Block::decode(&bytes, 4, 2).unwrap(), b);
        assert!(b.memory() > bytes.len() / 2);
    }

    #[test]
    fn only_forward_links_into_the_block_itself_are_resolved() {
        let mut b = sample();
        // Nodes 3..6: links into block 3 forward (to 5), backward (to 0),
        // past the end (to 99), and into another block.
        b.nodes
            .extend([TNode::link(1), TNode::link(2), TNode::link(3), TNode::link(4)]);
        b.nodes.push(TNode::leaf(0, 1));
        for (block, node) in [(3, 5), (3, 0), (3, 99), (2, 5)] {
            b.links.push(Link {
                block,
                node,
                ..b.links[0]
            });
        }
        let bytes = b.encode();
        let mut r = Block::decode(&bytes, 4, 2).unwrap();
        r.resolve_local_links(3);
        let locals: Vec<u32> = r
            .nodes
            .iter()
            .filter_map(|n| match n.kind() {
                NodeKind::Link { local, .. } => Some(local),
                _ => None,
            })
            .collect();
        // Node 2's link (to block 3, node 7, the last) and node 3's resolve.
        assert_eq!(locals, vec![8, 6, 0, 0, 0]);
        // Stored as plain links: resolving changes nothing on disk.
        assert_eq!(r.encode(), bytes);
    }

    #[test]
    fn bad_indices_and_short_blocks_are_refused() {
        let b = sample();
        let bytes = b.encode();
        // The link names block 3: a file of 3 blocks has no such block.
        assert!(matches!(Block::decode(&bytes, 3, 2), Err(BlockError::Corrupt(_))));
        // Material 1 in a file of one material.
        assert!(matches!(Block::decode(&bytes, 4, 1), Err(BlockError::Corrupt(_))));
        for cut in [0, 3, 4, 20, bytes.len() - 4] {
            assert!(Block::decode(&bytes[..cut], 4, 2).is_err(), "cut at {cut}");
        }
        let mut cyclic = b.clone();
        cyclic.nodes[0] = TNode::inner(0, 1.0, 0);
        assert!(Block::decode(&cyclic.encode(), 4, 2).is_err());
        let mut far = b;
        far.list[2] = 9;
        assert!(Block::decode(&far.encode(), 4, 2).is_err());
    }
}
