//! The two header copies: prefix, commit slots and settings text, and where
//! each lies. The copies are a whole number of [`HEADER_ALIGN`] pages apart,
//! so a damaged disk sector never takes both; from format 3 on, at least
//! [`COPY_GAP`](super::COPY_GAP) apart, as every other piece of metadata is.

use super::{
    check_trailing_crc, invalid, push_crc, Extent, FormatError, Reader, COPY_GAP, FORMAT_VERSION, MAX_GENERATION,
    MAX_TEXT_LEN, OLDEST_READ,
};

/// First eight bytes of every holodeck file (and of its second header copy).
pub const MAGIC: [u8; 8] = *b"HOLODECK";
/// Size of the fixed prefix.
pub const PREFIX_LEN: u64 = 64;
/// Size of one commit slot.
pub const SLOT_LEN: u64 = 64;
/// Where the settings text begins within a header copy.
pub const TEXT_IN_HEADER: u64 = 192;
/// Header copies start at multiples of this.
pub const HEADER_ALIGN: u64 = 4096;

const SLOT_MAGIC: [u8; 4] = *b"HDKC";

/// Bytes one header copy spans for a settings text of `text_len` bytes: the
/// prefix, both slots, the text and its CRC, rounded up to [`HEADER_ALIGN`].
pub fn header_span(text_len: u32) -> u64 {
    (TEXT_IN_HEADER + u64::from(text_len) + 4).next_multiple_of(HEADER_ALIGN)
}

/// Where header copy 2 begins (copy 1 is at 0): right after copy 1 in
/// format 2; in format 3 and later at least [`COPY_GAP`] from the start, so
/// that a damaged stretch of the disk shorter than that never takes both.
pub fn header_stride(p: Prefix) -> u64 {
    let span = header_span(p.text_len);
    if p.version >= 3 {
        span.max(COPY_GAP).next_multiple_of(HEADER_ALIGN)
    } else {
        span
    }
}

/// Offset of the first allocatable byte: past both header copies.
pub fn data_start(p: Prefix) -> u64 {
    header_stride(p) + header_span(p.text_len)
}

/// Where header copy `copy` (0 or 1) keeps the settings text.
pub fn text_offset(p: Prefix, copy: usize) -> u64 {
    copy as u64 * header_stride(p) + TEXT_IN_HEADER
}

/// Where header copy `copy` (0 or 1) keeps commit slot `side` (0: A, 1: B).
pub fn slot_offset(p: Prefix, copy: usize, side: usize) -> u64 {
    copy as u64 * header_stride(p) + PREFIX_LEN + side as u64 * SLOT_LEN
}

/// What the prefix says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Prefix {
    /// Format version of the file.
    pub version: u32,
    /// Length of the settings text.
    pub text_len: u32,
}

impl Prefix {
    /// The prefix of a new file: this code's format version.
    pub fn new(text_len: u32) -> Prefix {
        Prefix {
            version: FORMAT_VERSION,
            text_len,
        }
    }
}

/// The fixed prefix: the format version and the length of the settings
/// text that follows the slots.
pub fn encode_prefix(p: Prefix) -> [u8; PREFIX_LEN as usize] {
    let mut b = [0u8; PREFIX_LEN as usize];
    b[..8].copy_from_slice(&MAGIC);
    b[8..12].copy_from_slice(&p.version.to_le_bytes());
    b[12..16].copy_from_slice(&p.text_len.to_le_bytes());
    let crc = crc32c::crc32c(&b[..60]);
    b[60..].copy_from_slice(&crc.to_le_bytes());
    b
}

/// Decodes a prefix found at file offset `base`.
pub fn decode_prefix(bytes: &[u8], base: u64) -> Result<Prefix, FormatError> {
    let what = format!("file prefix at byte {base}");
    if bytes.len() < 8 || bytes[..8] != MAGIC {
        let found = String::from_utf8_lossy(&bytes[..bytes.len().min(10)]).into_owned();
        let hint = if bytes.starts_with(b"#?RADIANCE") {
            " (this is a Radiance file; holodeck files use their own portable format: a Radiance \
             holodeck converts with `holodeck import radiance FILE -o NEW.hdk`)"
        } else {
            ""
        };
        return Err(FormatError::NotHolodeck { found, hint });
    }
    if (bytes.len() as u64) < PREFIX_LEN {
        return Err(FormatError::Truncated {
            what,
            start: base,
            end: base + PREFIX_LEN,
            have: bytes.len() as u64,
        });
    }
    let bytes = &bytes[..PREFIX_LEN as usize];
    let version = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]);
    // A later format may lay its prefix out differently: its version decides
    // first. A flipped version bit is caught when the other copy verifies.
    if version <= FORMAT_VERSION {
        check_trailing_crc(bytes, base, &what)?;
    }
    if version > FORMAT_VERSION {
        return Err(FormatError::FutureVersion {
            found: version,
            supported: FORMAT_VERSION,
        });
    }
    if version < OLDEST_READ {
        return Err(invalid(
            what,
            base + 8,
            format!("format version {version} does not exist"),
        ));
    }
    let text_len = u32::from_le_bytes([bytes[12], bytes[13], bytes[14], bytes[15]]);
    if text_len > MAX_TEXT_LEN {
        return Err(invalid(
            what,
            base + 12,
            format!("settings text of {text_len} bytes is longer than the {MAX_TEXT_LEN} allowed"),
        ));
    }
    Ok(Prefix { version, text_len })
}

/// Settings text followed by its CRC.
pub fn encode_text(text: &str) -> Vec<u8> {
    push_crc(text.as_bytes().to_vec())
}

/// Decodes the settings text (text plus CRC) read from file offset `base`.
pub fn decode_text(bytes: &[u8], base: u64) -> Result<String, FormatError> {
    check_trailing_crc(bytes, base, "settings text")?;
    String::from_utf8(bytes[..bytes.len() - 4].to_vec())
        .map_err(|e| invalid("settings text", base + e.utf8_error().valid_up_to() as u64, "not UTF-8"))
}

/// A commit slot: which root is current. The root is stored twice.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Slot {
    /// Increases by one with every commit.
    pub generation: u64,
    /// Where the two copies of the root lie.
    pub roots: [u64; 2],
    /// Length of the root.
    pub root_len: u64,
    /// CRC32C of the root bytes.
    pub root_crc: u32,
}

impl Slot {
    /// The extents of the two root copies.
    pub fn root_copies(&self) -> [Extent; 2] {
        self.roots.map(|offset| Extent {
            offset,
            len: self.root_len,
        })
    }
}

/// Encodes a slot.
pub fn encode_slot(s: &Slot) -> [u8; SLOT_LEN as usize] {
    let mut b = [0u8; SLOT_LEN as usize];
    b[..4].copy_from_slice(&SLOT_MAGIC);
    b[4..12].copy_from_slice(&s.generation.to_le_bytes());
    b[12..20].copy_from_slice(&s.roots[0].to_le_bytes());
    b[20..28].copy_from_slice(&s.roots[1].to_le_bytes());
    b[28..36].copy_from_slice(&s.root_len.to_le_bytes());
    b[36..40].copy_from_slice(&s.root_crc.to_le_bytes());
    let crc = crc32c::crc32c(&b[..60]);
    b[60..].copy_from_slice(&crc.to_le_bytes());
    b
}

/// Decodes a slot found at file offset `base`; `Ok(None)` for a never-written (all zero) slot.
pub fn decode_slot(bytes: &[u8], base: u64) -> Result<Option<Slot>, FormatError> {
    let what = format!("commit slot at byte {base}");
    if bytes.len() < SLOT_LEN as usize {
        return Err(FormatError::Truncated {
            what,
            start: base,
            end: base + SLOT_LEN,
            have: bytes.len() as u64,
        });
    }
    let bytes = &bytes[..SLOT_LEN as usize];
    if bytes.iter().all(|&b| b == 0) {
        return Ok(None);
    }
    check_trailing_crc(bytes, base, &what)?;
    let mut r = Reader::new(bytes, base, &what);
    r.magic(SLOT_MAGIC)?;
    let generation = r.u64()?;
    let roots = [r.u64()?, r.u64()?];
    let root_len = r.u64()?;
    let root_crc = r.u32()?;
    if generation == 0 || generation > MAX_GENERATION {
        return Err(invalid(
            &what,
            base + 4,
            format!("generation {generation} is impossible"),
        ));
    }
    if roots.iter().any(|o| o.checked_add(root_len).is_none()) || root_len > u64::from(u32::MAX) {
        return Err(invalid(
            &what,
            base + 12,
            format!("root extents {roots:?}+{root_len} are impossible"),
        ));
    }
    Ok(Some(Slot {
        generation,
        roots,
        root_len,
        root_crc,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prefix_round_trip_and_refusals() {
        let p = encode_prefix(Prefix::new(1234));
        assert_eq!(
            decode_prefix(&p, 0).unwrap(),
            Prefix {
                version: FORMAT_VERSION,
                text_len: 1234
            }
        );
        assert!(
            matches!(decode_prefix(b"#?RADIANCE\nformat", 0), Err(FormatError::NotHolodeck { hint, .. }) if !hint.is_empty())
        );
        assert!(matches!(decode_prefix(&p[..30], 0), Err(FormatError::Truncated { .. })));
        let mut flipped = p;
        flipped[13] ^= 1;
        assert!(matches!(
            decode_prefix(&flipped, 4096),
            Err(FormatError::Checksum { start: 4096, .. })
        ));
        let mut future = p;
        future[8] = 9;
        assert!(matches!(
            decode_prefix(&future, 0),
            Err(FormatError::FutureVersion { found: 9, .. })
        ));
    }

    #[test]
    fn header_copies_are_whole_pages_apart() {
        assert_eq!(header_span(0), HEADER_ALIGN);
        assert_eq!(header_span(3900), HEADER_ALIGN);
        assert_eq!(header_span(3901), 2 * HEADER_ALIGN);
        // Format 2: the second copy right after the first.
        let v2 = Prefix {
            version: 2,
            text_len: 100,
        };
        assert_eq!(slot_offset(v2, 1, 1), HEADER_ALIGN + 128);
        assert_eq!(text_offset(v2, 1), HEADER_ALIGN + 192);
        assert_eq!(data_start(v2), 2 * HEADER_ALIGN);
        // Format 3: at least COPY_GAP apart, then as many pages as the text needs.
        let v3 = Prefix::new(100);
        assert_eq!(header_stride(v3), COPY_GAP);
        assert_eq!(slot_offset(v3, 1, 1), COPY_GAP + 128);
        assert_eq!(text_offset(v3, 1), COPY_GAP + 192);
        assert_eq!(data_start(v3), COPY_GAP + HEADER_ALIGN);
        let long = Prefix::new(100_000);
        assert_eq!(header_stride(long), header_span(100_000));
        assert!(header_stride(long) > COPY_GAP);
    }

    #[test]
    fn slots_round_trip_and_detect_tears() {
        let s = Slot {
            generation: 7,
            roots: [4096, 9000],
            root_len: 48,
            root_crc: 0xdead_beef,
        };
        let b = encode_slot(&s);
        assert_eq!(decode_slot(&b, 64).unwrap(), Some(s));
        assert_eq!(decode_slot(&[0; 64], 64).unwrap(), None);
        let mut torn = b;
        torn[40..].fill(0);
        let err = decode_slot(&torn, 128).unwrap_err();
        assert!(err.to_string().contains("commit slot at byte 128"), "{err}");
    }
}
