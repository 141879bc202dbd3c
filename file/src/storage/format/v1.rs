//! Format version 1, read only: files written by earlier builds. One prefix
//! at 0, commit slots A and B at 64 and 128, the settings text at 192 and the
//! data area right after it; one root and one directory block per section,
//! each stored once. `holodeck optimize` converts such a file to the current
//! format.

use super::directory::decode_entries;
use super::{check_trailing_crc, invalid, BeamEntry, Extent, FormatError, Reader, MAX_GENERATION};

/// Offsets of the two commit slots.
pub const SLOT_OFFSETS: [u64; 2] = [64, 128];
/// Where the settings text begins.
pub const TEXT_OFFSET: u64 = 192;

/// Offset of the first allocatable byte for a settings text of `text_len` bytes.
pub fn data_start(text_len: u32) -> u64 {
    TEXT_OFFSET + u64::from(text_len) + 4
}

/// A format-1 commit slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Slot {
    /// Increases by one with every commit.
    pub generation: u64,
    /// Where the root lies.
    pub root: Extent,
    /// CRC32C of the root bytes.
    pub root_crc: u32,
}

/// Decodes a format-1 slot at `base`; `Ok(None)` for a never-written one.
pub fn decode_slot(bytes: &[u8], base: u64) -> Result<Option<Slot>, FormatError> {
    let what = format!("commit slot at byte {base}");
    if bytes.len() < 64 {
        return Err(FormatError::Truncated {
            what,
            start: base,
            end: base + 64,
            have: bytes.len() as u64,
        });
    }
    let bytes = &bytes[..64];
    if bytes.iter().all(|&b| b == 0) {
        return Ok(None);
    }
    check_trailing_crc(bytes, base, &what)?;
    let mut r = Reader::new(bytes, base, &what);
    r.magic(*b"HDKC")?;
    let generation = r.u64()?;
    let offset = r.u64()?;
    let len = r.u64()?;
    let root_crc = r.u32()?;
    if generation == 0 || generation > MAX_GENERATION || offset.checked_add(len).is_none() || len > 1 << 32 {
        return Err(invalid(&what, base + 4, "impossible generation or root extent"));
    }
    Ok(Some(Slot {
        generation,
        root: Extent { offset, len },
        root_crc,
    }))
}

/// One section's directory block in a format-1 root.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DirRef {
    /// The block.
    pub block: Extent,
    /// Rays in the section.
    pub rays: u64,
}

/// Decodes a format-1 root listing `sections` sections.
pub fn decode_root(bytes: &[u8], base: u64, generation: u64, sections: usize) -> Result<Vec<DirRef>, FormatError> {
    let what = format!("root of commit {generation}");
    check_trailing_crc(bytes, base, &what)?;
    let mut r = Reader::new(&bytes[..bytes.len() - 4], base, &what);
    r.magic(*b"HDKR")?;
    if r.u64()? != generation {
        return Err(invalid(&what, base + 4, "root is of another commit"));
    }
    let n = r.u32()? as usize;
    if n != sections {
        return Err(invalid(
            &what,
            base + 12,
            format!("root lists {n} sections, the settings define {sections}"),
        ));
    }
    let mut out = Vec::with_capacity(n.min(1 << 16));
    for _ in 0..n {
        let at = r.at();
        let (offset, len, _beams, rays) = (r.u64()?, r.u64()?, r.u32()?, r.u64()?);
        if offset.checked_add(len).is_none() {
            return Err(invalid(&what, at, "directory extent overflows"));
        }
        out.push(DirRef {
            block: Extent { offset, len },
            rays,
        });
    }
    Ok(out)
}

/// Decodes a format-1 directory block of section `section` with `beams` beams.
pub fn decode_directory(
    bytes: &[u8],
    base: u64,
    section: u32,
    beams: u32,
    data_start: u64,
) -> Result<Vec<BeamEntry>, FormatError> {
    let what = format!("directory of section {section}");
    check_trailing_crc(bytes, base, &what)?;
    let mut r = Reader::new(&bytes[..bytes.len() - 4], base, &what);
    r.magic(*b"HDKD")?;
    let found = (r.u32()?, r.u32()?);
    if found != (section, beams) {
        return Err(invalid(
            &what,
            base + 4,
            format!("block describes section {} with {} beams", found.0, found.1),
        ));
    }
    decode_entries(&mut r, &what, 0, beams, data_start)
}
