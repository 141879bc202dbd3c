//! Directory blocks: for a range of one section's beams, where each beam's run
//! of ray records lies, how many records it holds, and their CRC32C.

use super::{check_trailing_crc, invalid, push_crc, put_varint, varint_len, Extent, FormatError, Reader, RECORD};

const DIR_MAGIC: [u8; 4] = *b"HDKD";
/// Bytes of a block that are not beam entries: magic, section, first beam, beam count, CRC.
const DIR_FRAMING: u64 = 20;

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

/// Longest possible directory block for `beams` beams: a 5-byte count, a
/// 10-byte offset delta and a 4-byte CRC per beam, and the framing.
pub fn max_directory_len(beams: u32) -> u64 {
    DIR_FRAMING + 19 * u64::from(beams)
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
    DIR_FRAMING + u64::from(beams) + filled.min(u64::from(beams)) * (count - 1 + delta + 4)
}

fn zigzag(v: i64) -> u64 {
    ((v << 1) ^ (v >> 63)) as u64
}

fn unzigzag(v: u64) -> i64 {
    ((v >> 1) as i64) ^ -((v & 1) as i64)
}

/// Encodes the directory block of beams `first..first + entries.len()` of `section`.
pub fn encode_directory(section: u32, first: u32, entries: &[BeamEntry]) -> Vec<u8> {
    let mut out = Vec::with_capacity(DIR_FRAMING as usize + entries.len() * 2);
    out.extend_from_slice(&DIR_MAGIC);
    out.extend_from_slice(&section.to_le_bytes());
    out.extend_from_slice(&first.to_le_bytes());
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

/// Decodes a directory block read from `base` that should describe beams
/// `first..first + beams` of `section`. Checks that every run starts at or
/// after `data_start` and that its end is a valid offset; whether it lies
/// within the file is the caller's to judge (a truncated file is reported
/// beam by beam).
pub fn decode_directory(
    bytes: &[u8],
    base: u64,
    section: u32,
    first: u32,
    beams: u32,
    data_start: u64,
) -> Result<Vec<BeamEntry>, FormatError> {
    let what = format!(
        "directory of section {section} beams {first}..{}",
        u64::from(first) + u64::from(beams)
    );
    check_trailing_crc(bytes, base, &what)?;
    let mut r = Reader::new(&bytes[..bytes.len() - 4], base, &what);
    r.magic(DIR_MAGIC)?;
    let found = (r.u32()?, r.u32()?, r.u32()?);
    if found != (section, first, beams) {
        return Err(invalid(
            &what,
            base + 4,
            format!("block describes section {} beams {}..+{}", found.0, found.1, found.2),
        ));
    }
    decode_entries(&mut r, &what, first, beams, data_start)
}

/// Decodes the `beams` entries of a block (whose first is beam `first`) that
/// follow its header in `r`, up to its CRC.
pub(super) fn decode_entries(
    r: &mut Reader<'_>,
    what: &str,
    first: u32,
    beams: u32,
    data_start: u64,
) -> Result<Vec<BeamEntry>, FormatError> {
    // Every beam takes at least one byte: never reserve more than the bytes could hold.
    let mut out = Vec::with_capacity((beams as usize).min(r.bytes.len()));
    let mut expected = 0u64;
    for i in 0..beams {
        let at = r.at();
        let beam = u64::from(first) + u64::from(i);
        let count = r.varint()?;
        if count > u64::from(u32::MAX) {
            return Err(invalid(what, at, format!("beam {beam} claims {count} rays")));
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
        match offset.checked_add(entry.extent().len) {
            Some(end) if offset >= data_start => expected = end,
            _ => {
                return Err(invalid(
                    what,
                    at,
                    format!("beam {beam} says its {count} rays lie at byte {offset}, outside the data area"),
                ))
            }
        }
        out.push(entry);
    }
    if r.pos != r.bytes.len() {
        return Err(invalid(what, r.at(), "unexpected bytes after the last beam"));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

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
        let b = encode_directory(0, 8192, &entries);
        // Framing, 6 bytes per beam, plus the first beam's absolute offset.
        assert!(b.len() <= 20 + 6 * entries.len() + 8, "{} bytes", b.len());
        assert_eq!(decode_directory(&b, 0, 0, 8192, 1000, 1000).unwrap(), entries);
        let err = decode_directory(&b, 0, 0, 8192, 1000, 1001).unwrap_err();
        assert!(err.to_string().contains("beam 8192 says"), "{err}");
        let err = decode_directory(&b, 0, 0, 0, 1000, 1000).unwrap_err();
        assert!(
            err.to_string().contains("block describes section 0 beams 8192"),
            "{err}"
        );
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
            let len = encode_directory(0, 0, &entries).len() as u64;
            prop_assert!(len <= directory_len_bound(entries.len() as u32, filled, max_end));
            prop_assert!(directory_len_bound(entries.len() as u32, filled, max_end) <= max_directory_len(entries.len() as u32));
        }

        #[test]
        fn directories_round_trip(first in 0u32..1 << 20, entries in prop::collection::vec((0u64..1 << 40, 0u32..100_000, any::<u32>()), 0..200)) {
            let entries: Vec<BeamEntry> = entries.into_iter().map(|(o, c, crc)| {
                if c == 0 { BeamEntry::default() } else { BeamEntry { offset: o + 100, count: c, crc } }
            }).collect();
            let b = encode_directory(5, first, &entries);
            let back = decode_directory(&b, 0, 5, first, entries.len() as u32, 100).unwrap();
            prop_assert_eq!(back, entries);
        }

        #[test]
        fn decoders_never_panic_on_garbage(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
            let _ = super::super::decode_prefix(&bytes, 0);
            let _ = super::super::decode_slot(&bytes, 64);
            let _ = super::super::decode_text(&bytes, 192);
            let _ = super::super::decode_root(&bytes, 0, 1, &[30, 2]);
            let _ = decode_directory(&bytes, 0, 0, 0, 30, 0);
        }
    }
}
