//! The root of a commit: where the two copies of every directory block lie,
//! with each chunk's beam range and ray count for quick reports.

use super::{check_trailing_crc, invalid, push_crc, Extent, FormatError, Reader};

const ROOT_MAGIC: [u8; 4] = *b"HDKR";
/// Bytes of the root before its chunk list.
const ROOT_HEAD: u64 = 20;
/// Bytes per chunk in the root.
const CHUNK_REF: u64 = 44;

/// One directory chunk of a commit: a range of one section's beams, and the
/// two copies of the block that describes them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ChunkRef {
    /// The section.
    pub section: u32,
    /// First beam described.
    pub first: u32,
    /// Number of beams described.
    pub beams: u32,
    /// Rays in those beams.
    pub rays: u64,
    /// Offsets of the two copies of the directory block.
    pub copies: [u64; 2],
    /// Length of the block.
    pub len: u64,
}

impl ChunkRef {
    /// The extents of the two copies.
    pub fn extents(&self) -> [Extent; 2] {
        self.copies.map(|offset| Extent { offset, len: self.len })
    }
}

/// Byte length of a root listing `chunks` chunks.
pub fn root_len(chunks: usize) -> u64 {
    ROOT_HEAD + CHUNK_REF * chunks as u64 + 4
}

/// Encodes a root.
pub fn encode_root(generation: u64, chunks: &[ChunkRef]) -> Vec<u8> {
    let mut out = Vec::with_capacity(root_len(chunks.len()) as usize);
    out.extend_from_slice(&ROOT_MAGIC);
    out.extend_from_slice(&generation.to_le_bytes());
    out.extend_from_slice(&(chunks.len() as u32).to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    for c in chunks {
        out.extend_from_slice(&c.section.to_le_bytes());
        out.extend_from_slice(&c.first.to_le_bytes());
        out.extend_from_slice(&c.beams.to_le_bytes());
        out.extend_from_slice(&c.rays.to_le_bytes());
        out.extend_from_slice(&c.copies[0].to_le_bytes());
        out.extend_from_slice(&c.copies[1].to_le_bytes());
        out.extend_from_slice(&c.len.to_le_bytes());
    }
    push_crc(out)
}

/// Decodes a root read from `base`, checking its generation and that its
/// chunks cover every beam of the sections (`beams[s]` beams in section `s`)
/// exactly once, in order.
pub fn decode_root(bytes: &[u8], base: u64, generation: u64, beams: &[u32]) -> Result<Vec<ChunkRef>, FormatError> {
    let what = format!("root of commit {generation}");
    check_trailing_crc(bytes, base, &what)?;
    let mut r = Reader::new(&bytes[..bytes.len() - 4], base, &what);
    r.magic(ROOT_MAGIC)?;
    let found = r.u64()?;
    if found != generation {
        return Err(invalid(&what, base + 4, format!("root is of commit {found}")));
    }
    let n = r.u32()? as usize;
    let _reserved = r.u32()?;
    if root_len(n) != bytes.len() as u64 {
        return Err(invalid(
            &what,
            base + 12,
            format!("root lists {n} chunks but is {} bytes long", bytes.len()),
        ));
    }
    let mut chunks = Vec::with_capacity(n);
    let (mut section, mut next) = (0usize, 0u32);
    for _ in 0..n {
        let at = r.at();
        let c = ChunkRef {
            section: r.u32()?,
            first: r.u32()?,
            beams: r.u32()?,
            rays: r.u64()?,
            copies: [r.u64()?, r.u64()?],
            len: r.u64()?,
        };
        // Chunks tile the sections in order: move on once a section is covered.
        while section < beams.len() && next == beams[section] {
            section += 1;
            next = 0;
        }
        let fits = section < beams.len()
            && c.section as usize == section
            && c.first == next
            && c.beams > 0
            && c.beams <= beams[section] - next;
        if !fits {
            return Err(invalid(
                &what,
                at,
                format!(
                    "chunk of section {} beams {}..+{} does not follow on from section {section} beam {next}",
                    c.section, c.first, c.beams
                ),
            ));
        }
        if c.copies.iter().any(|o| o.checked_add(c.len).is_none()) {
            return Err(invalid(&what, at, "directory extent overflows"));
        }
        next += c.beams;
        chunks.push(c);
    }
    while section < beams.len() && next == beams[section] {
        section += 1;
        next = 0;
    }
    if section != beams.len() {
        return Err(invalid(
            &what,
            r.at(),
            format!("chunks end at section {section} beam {next}: not every beam is described"),
        ));
    }
    Ok(chunks)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chunk(section: u32, first: u32, beams: u32) -> ChunkRef {
        ChunkRef {
            section,
            first,
            beams,
            rays: 5,
            copies: [300, 900],
            len: 20,
        }
    }

    #[test]
    fn root_checks_generation_and_tiling() {
        let chunks = [chunk(0, 0, 20), chunk(0, 20, 10), chunk(1, 0, 7)];
        let b = encode_root(3, &chunks);
        assert_eq!(b.len() as u64, root_len(3));
        assert_eq!(decode_root(&b, 900, 3, &[30, 7]).unwrap(), chunks);
        assert!(decode_root(&b, 900, 4, &[30, 7]).is_err());
        for wrong in [&[30u32, 8][..], &[29, 7], &[30, 7, 1], &[30]] {
            let e = decode_root(&b, 900, 3, wrong).unwrap_err();
            assert!(e.to_string().contains("root of commit 3"), "{e}");
        }
        let mut gap = chunks;
        gap[1].first = 21;
        assert!(decode_root(&encode_root(3, &gap), 0, 3, &[31, 7]).is_err());
    }
}
