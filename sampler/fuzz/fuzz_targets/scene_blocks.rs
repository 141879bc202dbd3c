//! Decompressed bytes of a scene-file block, and the same bytes as a
//! compressed block: decoding fails or yields a block whose every index is in
//! range (walked here node by node), never a panic; a decoded block encodes
//! back to the same bytes, also once its links into itself are resolved, and
//! those lead only forward.
#![no_main]

use holodeck_sampler::ooc::block::Block;
use holodeck_sampler::ooc::codec::Codec;
use holodeck_sampler::ooc::node::NodeKind;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&sel, bytes)) = data.split_first() else { return };
    let (blocks, materials) = (u32::from(sel >> 4) + 1, u32::from(sel & 15) + 1);
    if let Ok(mut b) = Block::decode(bytes, blocks, materials) {
        b.resolve_local_links(u32::from(sel) % blocks);
        for (i, n) in b.nodes.iter().enumerate() {
            match n.kind() {
                NodeKind::Inner { left, .. } => assert!((left as usize) + 1 < b.nodes.len()),
                NodeKind::Leaf { first, count } => {
                    for &t in &b.list[first as usize..(first + count) as usize] {
                        let _ = b.triangle(t as usize);
                        assert!(b.ids.len() > t as usize);
                    }
                }
                NodeKind::Link { link, local } => {
                    assert!(b.links[link as usize].block < blocks);
                    assert!(local == 0 || (local as usize > i + 1 && (local as usize) <= b.nodes.len()));
                }
            }
        }
        assert_eq!(b.encode(), bytes);
    }
    for codec in [Codec::Lz4, Codec::Zstd] {
        if let Ok(raw) = codec.decompress(bytes, usize::from(sel) * 97) {
            let _ = Block::decode(&raw, blocks, materials);
        }
    }
});
