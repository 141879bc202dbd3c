//! Byte layout of a holodeck file, and the codecs for each of its parts.
//!
//! ```text
//! 0     prefix (64 B): magic "HOLODECK", format version, settings-text length, CRC
//! 64    commit slot A (64 B)  } the slot with the highest generation whose CRC,
//! 128   commit slot B (64 B)  } root and directories all verify is the current state
//! 192   settings text (key=value lines) + CRC32C
//! ...   allocatable space: beam runs (10-byte records), directory blocks, roots
//! ```
//!
//! A *root* lists, per section, where its directory block lies. A *directory
//! block* holds, per beam, the ray count, the run's offset (delta-coded against
//! the end of the previous run, so a collated file spends one byte on it) and
//! the run's CRC32C. All integers are little-endian. Every decoder here takes
//! untrusted bytes: it returns a [`FormatError`] naming what failed and where,
//! and never panics.

use holodeck_protocol::RAY_RECORD_BYTES;

/// First eight bytes of every holodeck file.
pub const MAGIC: [u8; 8] = *b"HOLODECK";
/// The format version this code writes and reads.
pub const FORMAT_VERSION: u32 = 1;
/// Size of the fixed prefix.
pub const PREFIX_LEN: u64 = 64;
/// Size of one commit slot.
pub const SLOT_LEN: u64 = 64;
/// File offsets of the two commit slots.
pub const SLOT_OFFSETS: [u64; 2] = [64, 128];
/// Where the settings text begins.
pub const TEXT_OFFSET: u64 = 192;
/// Longest settings text accepted (sections are a line each; this is generous).
pub const MAX_TEXT_LEN: u32 = 1 << 24;

const SLOT_MAGIC: [u8; 4] = *b"HDKC";
const ROOT_MAGIC: [u8; 4] = *b"HDKR";
const DIR_MAGIC: [u8; 4] = *b"HDKD";
const RECORD: u64 = RAY_RECORD_BYTES as u64;

/// What is wrong with some bytes of a holodeck file, and where.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FormatError {
    /// The file does not start with the holodeck magic.
    #[error("not a holodeck file: it starts with {found:?}, not \"HOLODECK\"{hint}")]
    NotHolodeck {
        /// The first bytes found, lossily as text.
        found: String,
        /// Extra advice (e.g. for Radiance holodeck files).
        hint: &'static str,
    },
    /// The file is written in a newer format than this program reads.
    #[error(
        "file format version {found} is newer than this program reads (version {supported}); use a newer holodeck"
    )]
    FutureVersion {
        /// Version in the file.
        found: u32,
        /// Version supported here.
        supported: u32,
    },
    /// A part ends before its declared size.
    #[error("{what} at bytes {start}..{end} is truncated: only {have} bytes are there")]
    Truncated {
        /// Which part.
        what: String,
        /// Its first byte.
        start: u64,
        /// One past its last byte.
        end: u64,
        /// Bytes present.
        have: u64,
    },
    /// A checksum does not match.
    #[error("{what} at bytes {start}..{end} fails its checksum (stored {stored:08x}, computed {computed:08x})")]
    Checksum {
        /// Which part.
        what: String,
        /// Its first byte.
        start: u64,
        /// One past its last byte.
        end: u64,
        /// Stored CRC.
        stored: u32,
        /// CRC of the bytes present.
        computed: u32,
    },
    /// A value is impossible.
    #[error("{what} at byte {at}: {detail}")]
    Invalid {
        /// Which part.
        what: String,
        /// File offset of the bad value.
        at: u64,
        /// What is wrong.
        detail: String,
    },
}

fn invalid(what: impl Into<String>, at: u64, detail: impl Into<String>) -> FormatError {
    FormatError::Invalid {
        what: what.into(),
        at,
        detail: detail.into(),
    }
}

/// Reads little-endian values from a byte slice that lies at `base` in the file.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
    base: u64,
    what: &'a str,
}

impl<'a> Reader<'a> {
    fn new(bytes: &'a [u8], base: u64, what: &'a str) -> Self {
        Reader {
            bytes,
            pos: 0,
            base,
            what,
        }
    }
    fn at(&self) -> u64 {
        self.base + self.pos as u64
    }
    fn take(&mut self, n: usize) -> Result<&'a [u8], FormatError> {
        if self.bytes.len() - self.pos < n {
            return Err(FormatError::Truncated {
                what: self.what.to_string(),
                start: self.base,
                end: self.at() + n as u64,
                have: self.bytes.len() as u64,
            });
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32, FormatError> {
        let mut b = [0u8; 4];
        b.copy_from_slice(self.take(4)?);
        Ok(u32::from_le_bytes(b))
    }
    fn u64(&mut self) -> Result<u64, FormatError> {
        let mut b = [0u8; 8];
        b.copy_from_slice(self.take(8)?);
        Ok(u64::from_le_bytes(b))
    }
    fn varint(&mut self) -> Result<u64, FormatError> {
        let at = self.at();
        let mut value = 0u64;
        for shift in (0..64).step_by(7) {
            let byte = self.take(1)?[0];
            value |= u64::from(byte & 0x7f) << shift;
            if byte & 0x80 == 0 {
                if shift == 63 && byte > 1 {
                    break;
                }
                return Ok(value);
            }
        }
        Err(invalid(self.what, at, "variable-length integer is longer than 64 bits"))
    }
    fn magic(&mut self, expected: [u8; 4]) -> Result<(), FormatError> {
        let at = self.at();
        let found = self.take(4)?;
        if found != expected {
            return Err(invalid(
                self.what,
                at,
                format!(
                    "expected marker {:?}, found {:?}",
                    String::from_utf8_lossy(&expected),
                    String::from_utf8_lossy(found)
                ),
            ));
        }
        Ok(())
    }
}

fn put_varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// Checks the trailing CRC32C of `bytes` (last four bytes cover the rest).
fn check_trailing_crc(bytes: &[u8], base: u64, what: &str) -> Result<(), FormatError> {
    if bytes.len() < 4 {
        return Err(FormatError::Truncated {
            what: what.into(),
            start: base,
            end: base + 4,
            have: bytes.len() as u64,
        });
    }
    let (body, tail) = bytes.split_at(bytes.len() - 4);
    let stored = u32::from_le_bytes([tail[0], tail[1], tail[2], tail[3]]);
    let computed = crc32c::crc32c(body);
    if stored != computed {
        return Err(FormatError::Checksum {
            what: what.into(),
            start: base,
            end: base + bytes.len() as u64,
            stored,
            computed,
        });
    }
    Ok(())
}

fn push_crc(mut out: Vec<u8>) -> Vec<u8> {
    let crc = crc32c::crc32c(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// The fixed prefix: encodes the length of the settings text that follows the slots.
pub fn encode_prefix(text_len: u32) -> [u8; PREFIX_LEN as usize] {
    let mut b = [0u8; PREFIX_LEN as usize];
    b[..8].copy_from_slice(&MAGIC);
    b[8..12].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
    b[12..16].copy_from_slice(&text_len.to_le_bytes());
    let crc = crc32c::crc32c(&b[..60]);
    b[60..].copy_from_slice(&crc.to_le_bytes());
    b
}

/// Decodes the prefix; returns the settings-text length.
pub fn decode_prefix(bytes: &[u8]) -> Result<u32, FormatError> {
    if bytes.len() < 8 || bytes[..8] != MAGIC {
        let found = String::from_utf8_lossy(&bytes[..bytes.len().min(10)]).into_owned();
        let hint = if bytes.starts_with(b"#?RADIANCE") {
            " (this looks like a Radiance file; holodeck files use their own portable format)"
        } else {
            ""
        };
        return Err(FormatError::NotHolodeck { found, hint });
    }
    if (bytes.len() as u64) < PREFIX_LEN {
        return Err(FormatError::Truncated {
            what: "file prefix".into(),
            start: 0,
            end: PREFIX_LEN,
            have: bytes.len() as u64,
        });
    }
    let version = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]);
    if version > FORMAT_VERSION {
        return Err(FormatError::FutureVersion {
            found: version,
            supported: FORMAT_VERSION,
        });
    }
    if version == 0 {
        return Err(invalid("file prefix", 8, "format version 0 does not exist"));
    }
    check_trailing_crc(&bytes[..PREFIX_LEN as usize], 0, "file prefix")?;
    let len = u32::from_le_bytes([bytes[12], bytes[13], bytes[14], bytes[15]]);
    if len > MAX_TEXT_LEN {
        return Err(invalid(
            "file prefix",
            12,
            format!("settings text of {len} bytes is longer than the {MAX_TEXT_LEN} allowed"),
        ));
    }
    Ok(len)
}

/// Settings text followed by its CRC.
pub fn encode_text(text: &str) -> Vec<u8> {
    push_crc(text.as_bytes().to_vec())
}

/// Decodes the settings text (bytes from [`TEXT_OFFSET`], text plus CRC).
pub fn decode_text(bytes: &[u8]) -> Result<String, FormatError> {
    check_trailing_crc(bytes, TEXT_OFFSET, "settings text")?;
    String::from_utf8(bytes[..bytes.len() - 4].to_vec()).map_err(|e| {
        invalid(
            "settings text",
            TEXT_OFFSET + e.utf8_error().valid_up_to() as u64,
            "not UTF-8",
        )
    })
}

/// Offset of the first allocatable byte for a settings text of `text_len` bytes.
pub fn data_start(text_len: u32) -> u64 {
    TEXT_OFFSET + u64::from(text_len) + 4
}

/// A commit slot: which root is current.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Slot {
    /// Increases by one with every commit.
    pub generation: u64,
    /// Where the root lies.
    pub root: Extent,
    /// CRC32C of the root bytes.
    pub root_crc: u32,
}

/// A run of bytes in the file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Extent {
    /// First byte.
    pub offset: u64,
    /// Length in bytes.
    pub len: u64,
}

impl Extent {
    /// One past the last byte.
    pub fn end(&self) -> u64 {
        self.offset + self.len
    }
}

/// Encodes a slot.
pub fn encode_slot(s: &Slot) -> [u8; SLOT_LEN as usize] {
    let mut b = [0u8; SLOT_LEN as usize];
    b[..4].copy_from_slice(&SLOT_MAGIC);
    b[4..12].copy_from_slice(&s.generation.to_le_bytes());
    b[12..20].copy_from_slice(&s.root.offset.to_le_bytes());
    b[20..28].copy_from_slice(&s.root.len.to_le_bytes());
    b[28..32].copy_from_slice(&s.root_crc.to_le_bytes());
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
    let offset = r.u64()?;
    let len = r.u64()?;
    let root_crc = r.u32()?;
    if generation == 0 || generation > MAX_GENERATION {
        return Err(invalid(
            &what,
            base + 4,
            format!("generation {generation} is impossible"),
        ));
    }
    if offset.checked_add(len).is_none() || len > u64::from(u32::MAX) {
        return Err(invalid(
            &what,
            base + 12,
            format!("root extent {offset}+{len} is impossible"),
        ));
    }
    Ok(Some(Slot {
        generation,
        root: Extent { offset, len },
        root_crc,
    }))
}

/// Where one section's directory block lies, with summary counts for quick reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DirRef {
    /// The directory block.
    pub block: Extent,
    /// Number of beams in the section.
    pub beams: u32,
    /// Rays stored in the section.
    pub rays: u64,
}

/// Byte length of a root listing `sections` sections.
pub fn root_len(sections: usize) -> u64 {
    20 + 28 * sections as u64
}

/// Longest possible directory block for `beams` beams: a 5-byte count, a
/// 10-byte offset delta and a 4-byte CRC per beam, 16 bytes of framing.
pub fn max_directory_len(beams: u32) -> u64 {
    16 + 19 * u64::from(beams)
}

/// Bytes LEB128 takes for `v`.
pub fn varint_len(v: u64) -> u64 {
    u64::from((64 - v.leading_zeros()).max(1)).div_ceil(7)
}

/// Longest directory block [`encode_directory`] can produce for `beams` beams
/// of which `filled` hold rays, when every run ends at or before byte `max_end`.
/// Each beam's count is at most `max_end / 10` and each offset delta lies in
/// `-max_end..=max_end`, so its zigzag code is at most `2 * max_end`.
pub fn directory_len_bound(beams: u32, filled: u64, max_end: u64) -> u64 {
    let count = varint_len((max_end / RECORD).min(u64::from(u32::MAX)));
    let delta = varint_len(max_end.saturating_mul(2));
    // An empty beam is one byte (count 0); a filled one adds the rest of its
    // count, its offset delta and its CRC.
    16 + u64::from(beams) + filled.min(u64::from(beams)) * (count - 1 + delta + 4)
}

/// Largest generation accepted: far beyond any real count of commits, and far
/// from overflow.
pub const MAX_GENERATION: u64 = 1 << 62;

/// Encodes a root.
pub fn encode_root(generation: u64, dirs: &[DirRef]) -> Vec<u8> {
    let mut out = Vec::with_capacity(20 + dirs.len() * 28);
    out.extend_from_slice(&ROOT_MAGIC);
    out.extend_from_slice(&generation.to_le_bytes());
    out.extend_from_slice(&(dirs.len() as u32).to_le_bytes());
    for d in dirs {
        out.extend_from_slice(&d.block.offset.to_le_bytes());
        out.extend_from_slice(&d.block.len.to_le_bytes());
        out.extend_from_slice(&d.beams.to_le_bytes());
        out.extend_from_slice(&d.rays.to_le_bytes());
    }
    push_crc(out)
}

/// Decodes a root read from `base`, checking its generation and section count.
pub fn decode_root(bytes: &[u8], base: u64, generation: u64, sections: usize) -> Result<Vec<DirRef>, FormatError> {
    let what = format!("root of commit {generation}");
    check_trailing_crc(bytes, base, &what)?;
    let mut r = Reader::new(&bytes[..bytes.len() - 4], base, &what);
    r.magic(ROOT_MAGIC)?;
    let found = r.u64()?;
    if found != generation {
        return Err(invalid(&what, base + 4, format!("root is of commit {found}")));
    }
    let n = r.u32()? as usize;
    if n != sections {
        return Err(invalid(
            &what,
            base + 12,
            format!("root lists {n} sections, the settings define {sections}"),
        ));
    }
    let mut dirs = Vec::with_capacity(n.min(1 << 16));
    for _ in 0..n {
        let at = r.at();
        let offset = r.u64()?;
        let len = r.u64()?;
        let beams = r.u32()?;
        let rays = r.u64()?;
        if offset.checked_add(len).is_none() {
            return Err(invalid(&what, at, "directory extent overflows"));
        }
        dirs.push(DirRef {
            block: Extent { offset, len },
            beams,
            rays,
        });
    }
    Ok(dirs)
}

/// One beam's entry in a directory: where its run of records lies.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BeamEntry {
    /// File offset of the first record (meaningless when `count` is 0).
    pub offset: u64,
    /// Number of records.
    pub count: u32,
    /// CRC32C of the run's bytes.
    pub crc: u32,
}

impl BeamEntry {
    /// The bytes the run occupies.
    pub fn extent(&self) -> Extent {
        Extent {
            offset: self.offset,
            len: u64::from(self.count) * RECORD,
        }
    }
}

fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

fn unzigzag(v: u64) -> i64 {
    ((v >> 1) as i64) ^ -((v & 1) as i64)
}

/// Encodes one section's directory block.
pub fn encode_directory(section: u32, entries: &[BeamEntry]) -> Vec<u8> {
    let mut out = Vec::with_capacity(16 + entries.len() * 2);
    out.extend_from_slice(&DIR_MAGIC);
    out.extend_from_slice(&section.to_le_bytes());
    out.extend_from_slice(&(entries.len() as u32).to_le_bytes());
    let mut expected = 0u64;
    for e in entries {
        put_varint(&mut out, u64::from(e.count));
        if e.count > 0 {
            put_varint(&mut out, zigzag(e.offset.wrapping_sub(expected) as i64));
            out.extend_from_slice(&e.crc.to_le_bytes());
            expected = e.extent().end();
        }
    }
    push_crc(out)
}

/// Decodes a directory block read from `base`. Checks the section number, beam
/// count, and that every run lies within `data_start..file_len`.
pub fn decode_directory(
    bytes: &[u8],
    base: u64,
    section: u32,
    beams: u32,
    data_start: u64,
    file_len: u64,
) -> Result<Vec<BeamEntry>, FormatError> {
    let what = format!("directory of section {section}");
    check_trailing_crc(bytes, base, &what)?;
    let mut r = Reader::new(&bytes[..bytes.len() - 4], base, &what);
    r.magic(DIR_MAGIC)?;
    let found = r.u32()?;
    if found != section {
        return Err(invalid(&what, base + 4, format!("block belongs to section {found}")));
    }
    let n = r.u32()?;
    if n != beams {
        return Err(invalid(
            &what,
            base + 8,
            format!("block lists {n} beams, the section has {beams}"),
        ));
    }
    // Every beam takes at least one byte: never reserve more than the bytes could hold.
    let mut out = Vec::with_capacity((n as usize).min(bytes.len()));
    let mut expected = 0u64;
    for beam in 0..n {
        let at = r.at();
        let count = r.varint()?;
        if count > u64::from(u32::MAX) {
            return Err(invalid(&what, at, format!("beam {beam} claims {count} rays")));
        }
        if count == 0 {
            out.push(BeamEntry::default());
            continue;
        }
        let offset = expected.wrapping_add(unzigzag(r.varint()?) as u64);
        let crc = r.u32()?;
        let entry = BeamEntry {
            offset,
            count: count as u32,
            crc,
        };
        let end = offset.checked_add(u64::from(entry.count) * RECORD);
        match end {
            Some(end) if offset >= data_start && end <= file_len => expected = end,
            _ => {
                return Err(invalid(
                    &what,
                    at,
                    format!(
                        "beam {beam} says its {count} rays lie at byte {offset}, outside the data area {data_start}..{file_len}"
                    ),
                ))
            }
        }
        out.push(entry);
    }
    if r.pos != r.bytes.len() {
        return Err(invalid(&what, r.at(), "unexpected bytes after the last beam"));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn prefix_round_trip_and_refusals() {
        let p = encode_prefix(1234);
        assert_eq!(decode_prefix(&p).unwrap(), 1234);
        assert!(
            matches!(decode_prefix(b"#?RADIANCE\nformat"), Err(FormatError::NotHolodeck { hint, .. }) if !hint.is_empty())
        );
        assert!(matches!(decode_prefix(&p[..30]), Err(FormatError::Truncated { .. })));
        let mut future = p;
        future[8] = 9;
        assert!(matches!(
            decode_prefix(&future),
            Err(FormatError::FutureVersion { found: 9, .. })
        ));
        let mut flipped = p;
        flipped[13] ^= 1;
        assert!(matches!(decode_prefix(&flipped), Err(FormatError::Checksum { .. })));
    }

    #[test]
    fn slots_round_trip_and_detect_tears() {
        let s = Slot {
            generation: 7,
            root: Extent { offset: 4096, len: 48 },
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

    #[test]
    fn root_checks_generation_and_sections() {
        let dirs = [DirRef {
            block: Extent { offset: 300, len: 20 },
            beams: 30,
            rays: 5,
        }];
        let b = encode_root(3, &dirs);
        assert_eq!(decode_root(&b, 900, 3, 1).unwrap(), dirs);
        assert!(decode_root(&b, 900, 4, 1).is_err());
        assert!(decode_root(&b, 900, 3, 2)
            .unwrap_err()
            .to_string()
            .contains("settings define 2"));
    }

    #[test]
    fn collated_directories_cost_about_six_bytes_per_full_beam() {
        let mut off = 1000u64;
        let entries: Vec<BeamEntry> = (0..1000u32)
            .map(|i| {
                let e = BeamEntry {
                    offset: off,
                    count: 40 + i % 7,
                    crc: i.wrapping_mul(2654435761),
                };
                off = e.extent().end();
                e
            })
            .collect();
        let b = encode_directory(0, &entries);
        // Header 16 bytes, 6 per beam, plus the first beam's absolute offset.
        assert!(b.len() <= 16 + 6 * entries.len() + 8, "{} bytes", b.len());
        assert_eq!(decode_directory(&b, 0, 0, 1000, 1000, off).unwrap(), entries);
        let err = decode_directory(&b, 0, 0, 1000, 1000, off - 1).unwrap_err();
        assert!(err.to_string().contains("beam 999"), "{err}");
    }

    #[test]
    fn varint_lengths_match_the_encoder() {
        for v in [0u64, 1, 127, 128, 16_383, 16_384, 1 << 35, u64::MAX] {
            let mut out = Vec::new();
            put_varint(&mut out, v);
            assert_eq!(varint_len(v), out.len() as u64, "{v}");
        }
    }

    proptest! {
        #[test]
        fn directory_bound_holds(
            max_end in 200u64..1 << 40,
            beams in prop::collection::vec((any::<u64>(), any::<u64>(), any::<bool>()), 0..200),
        ) {
            // Runs anywhere below max_end, in any order, with any count that fits.
            let entries: Vec<BeamEntry> = beams.into_iter().map(|(a, b, full)| {
                let count = if full { (a % (max_end / RECORD)).min(u64::from(u32::MAX)) as u32 } else { 0 };
                let len = u64::from(count) * RECORD;
                let offset = if count == 0 { 0 } else { b % (max_end - len + 1) };
                BeamEntry { offset, count, crc: a as u32 }
            }).collect();
            let filled = entries.iter().filter(|e| e.count > 0).count() as u64;
            let len = encode_directory(0, &entries).len() as u64;
            prop_assert!(len <= directory_len_bound(entries.len() as u32, filled, max_end));
            prop_assert!(directory_len_bound(entries.len() as u32, filled, max_end) <= max_directory_len(entries.len() as u32));
        }

        #[test]
        fn directories_round_trip(entries in prop::collection::vec((0u64..1 << 40, 0u32..100_000, any::<u32>()), 0..200)) {
            let entries: Vec<BeamEntry> = entries.into_iter().map(|(o, c, crc)| {
                if c == 0 { BeamEntry::default() } else { BeamEntry { offset: o + 100, count: c, crc } }
            }).collect();
            let b = encode_directory(5, &entries);
            let back = decode_directory(&b, 0, 5, entries.len() as u32, 100, u64::MAX).unwrap();
            prop_assert_eq!(back, entries);
        }

        #[test]
        fn decoders_never_panic_on_garbage(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
            let _ = decode_prefix(&bytes);
            let _ = decode_slot(&bytes, 64);
            let _ = decode_text(&bytes);
            let _ = decode_root(&bytes, 0, 1, 2);
            let _ = decode_directory(&bytes, 0, 0, 30, 0, 1 << 20);
        }
    }
}
