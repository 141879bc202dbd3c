//! A holodeck as a static web site: the index a page reads to replay a file
//! with no server (`holodeck export web`). The rays lie in chunk files of
//! whole beams (`beams-0000.bin`, …: 10-byte records, beams in key order);
//! the index says where each beam's records are, so a page fetches exactly
//! the beams its view sees, by byte range.
//!
//! The index (`holodeck.idx`) is the magic `HDKSITE1`, a little-endian u32
//! length and that many bytes of a postcard-encoded [`SiteHeader`] (the
//! sections and the chunk files' sizes), then one 20-byte row per beam that
//! holds rays: section u32, beam u32, chunk u32, offset u32 (bytes into the
//! chunk), rays u32. Rows are in key order, each beam once, each inside its
//! chunk. [`SiteIndex::decode`] takes untrusted bytes and checks all of it.

use serde::{Deserialize, Serialize};

use crate::beam::BeamKey;
use crate::record::RAY_RECORD_BYTES;
use crate::section::Section;

/// The index's first bytes.
pub const SITE_MAGIC: &[u8; 8] = b"HDKSITE1";

/// Bytes of one beam's row.
pub const SITE_ROW_BYTES: usize = 20;

/// Largest header accepted (sections and chunk sizes): 1 MiB.
pub const MAX_SITE_HEADER: usize = 1 << 20;

/// Largest chunk file: offsets are u32.
pub const MAX_SITE_CHUNK: u64 = u32::MAX as u64;

/// The index's header.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SiteHeader {
    /// The holodeck's sections, in index order.
    pub sections: Vec<Section>,
    /// Each chunk file's size in bytes (chunk `i` is `beams-{i:04}.bin`).
    pub chunks: Vec<u64>,
}

/// Where one beam's records are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SiteBeam {
    /// The beam.
    pub key: BeamKey,
    /// Its chunk file.
    pub chunk: u32,
    /// Bytes into the chunk file.
    pub offset: u32,
    /// Its records.
    pub rays: u32,
}

impl SiteBeam {
    /// Bytes past its last record in the chunk.
    pub fn end(&self) -> u64 {
        u64::from(self.offset) + u64::from(self.rays) * RAY_RECORD_BYTES as u64
    }
}

/// Why bytes are not a site index.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SiteError {
    /// Not an index (or another version's).
    #[error("not a holodeck site index (no HDKSITE1 magic)")]
    Magic,
    /// The bytes end early.
    #[error("the index is cut short: {0}")]
    Truncated(&'static str),
    /// The header does not decode.
    #[error("the index's header: {0}")]
    Header(String),
    /// A row that is impossible.
    #[error("beam row {row}: {why}")]
    Row {
        /// Which row (0-based).
        row: usize,
        /// What is wrong with it.
        why: String,
    },
}

/// The whole index: the header and every beam's row, in key order.
#[derive(Clone, Debug, PartialEq)]
pub struct SiteIndex {
    /// Sections and chunk sizes.
    pub header: SiteHeader,
    /// One row per beam that holds rays, in key order.
    pub beams: Vec<SiteBeam>,
}

/// Chunk file `i`'s name.
pub fn chunk_name(i: u32) -> String {
    format!("beams-{i:04}.bin")
}

impl SiteIndex {
    /// The index's bytes.
    pub fn encode(&self) -> Result<Vec<u8>, SiteError> {
        let header = postcard::to_allocvec(&self.header).map_err(|e| SiteError::Header(e.to_string()))?;
        let mut out = Vec::with_capacity(12 + header.len() + self.beams.len() * SITE_ROW_BYTES);
        out.extend_from_slice(SITE_MAGIC);
        out.extend_from_slice(&(header.len() as u32).to_le_bytes());
        out.extend_from_slice(&header);
        for b in &self.beams {
            for v in [b.key.section, b.key.beam, b.chunk, b.offset, b.rays] {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        Ok(out)
    }

    /// Reads an index from untrusted bytes, checking every row against the
    /// sections and chunk sizes.
    pub fn decode(bytes: &[u8]) -> Result<SiteIndex, SiteError> {
        let rest = bytes.strip_prefix(SITE_MAGIC.as_slice()).ok_or(SiteError::Magic)?;
        let (len, rest) = rest
            .split_first_chunk::<4>()
            .ok_or(SiteError::Truncated("the header's length"))?;
        let len = u32::from_le_bytes(*len) as usize;
        if len > MAX_SITE_HEADER {
            return Err(SiteError::Header(format!(
                "{len} bytes, more than the {MAX_SITE_HEADER} allowed"
            )));
        }
        if rest.len() < len {
            return Err(SiteError::Truncated("the header"));
        }
        let (head, rows) = rest.split_at(len);
        let header: SiteHeader = postcard::from_bytes(head).map_err(|e| SiteError::Header(e.to_string()))?;
        if rows.len() % SITE_ROW_BYTES != 0 {
            return Err(SiteError::Truncated("a beam row"));
        }
        let mut beams = Vec::with_capacity(rows.len() / SITE_ROW_BYTES);
        for (row, r) in rows.chunks_exact(SITE_ROW_BYTES).enumerate() {
            let v = |i: usize| u32::from_le_bytes([r[4 * i], r[4 * i + 1], r[4 * i + 2], r[4 * i + 3]]);
            let b = SiteBeam {
                key: BeamKey::new(v(0), v(1)),
                chunk: v(2),
                offset: v(3),
                rays: v(4),
            };
            let bad = |why: String| SiteError::Row { row, why };
            let Some(section) = header.sections.get(b.key.section as usize) else {
                return Err(bad(format!("section {} of {}", b.key.section, header.sections.len())));
            };
            if b.key.beam >= section.beam_count() {
                return Err(bad(format!("beam {} of {}", b.key.beam, section.beam_count())));
            }
            let Some(&size) = header.chunks.get(b.chunk as usize) else {
                return Err(bad(format!("chunk {} of {}", b.chunk, header.chunks.len())));
            };
            if b.rays == 0 || b.end() > size {
                return Err(bad(format!(
                    "{} rays at byte {} of a {size}-byte chunk",
                    b.rays, b.offset
                )));
            }
            if beams.last().is_some_and(|p: &SiteBeam| p.key >= b.key) {
                return Err(bad("out of key order".into()));
            }
            beams.push(b);
        }
        Ok(SiteIndex { header, beams })
    }

    /// The row of `key`, if it holds rays.
    pub fn beam(&self, key: BeamKey) -> Option<&SiteBeam> {
        self.beams
            .binary_search_by_key(&key, |b| b.key)
            .ok()
            .map(|i| &self.beams[i])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::section::SectionKind;
    use proptest::prelude::*;

    fn index(rows: &[(u32, u32)]) -> SiteIndex {
        let section = Section::new(
            [0.0; 3],
            [[4.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 2.0]],
            [4, 4, 2],
            SectionKind::Interior,
        )
        .unwrap();
        let mut offset = 0;
        let beams = rows
            .iter()
            .map(|&(beam, rays)| {
                let b = SiteBeam {
                    key: BeamKey::new(0, beam),
                    chunk: 0,
                    offset,
                    rays,
                };
                offset += rays * RAY_RECORD_BYTES as u32;
                b
            })
            .collect();
        SiteIndex {
            header: SiteHeader {
                sections: vec![section],
                chunks: vec![u64::from(offset)],
            },
            beams,
        }
    }

    #[test]
    fn an_index_round_trips_and_finds_its_beams() {
        let i = index(&[(3, 2), (7, 5), (100, 1)]);
        let bytes = i.encode().unwrap();
        let back = SiteIndex::decode(&bytes).unwrap();
        assert_eq!(back, i);
        assert_eq!(
            back.beam(BeamKey::new(0, 7)).map(|b| (b.offset, b.end())),
            Some((20, 70))
        );
        assert_eq!(back.beam(BeamKey::new(0, 8)), None);
        assert_eq!(chunk_name(3), "beams-0003.bin");
    }

    #[test]
    fn bad_indexes_say_what_is_wrong() {
        let good = index(&[(3, 2), (7, 5)]).encode().unwrap();
        assert_eq!(SiteIndex::decode(b"HDKSITE0"), Err(SiteError::Magic));
        assert!(matches!(
            SiteIndex::decode(&good[..good.len() - 1]),
            Err(SiteError::Truncated(_))
        ));
        // A beam past its chunk's end.
        let mut long = index(&[(3, 2), (7, 5)]);
        long.beams[1].rays = 6;
        let e = SiteIndex::decode(&long.encode().unwrap()).unwrap_err();
        assert!(e.to_string().contains("beam row 1: 6 rays at byte 20"), "{e}");
        // Out of order.
        let mut swapped = index(&[(3, 2), (7, 5)]);
        swapped.beams.swap(0, 1);
        let e = SiteIndex::decode(&swapped.encode().unwrap()).unwrap_err();
        assert!(matches!(e, SiteError::Row { row: 1, .. }), "{e}");
        // A beam the section does not have.
        let e = SiteIndex::decode(&index(&[(1 << 30, 1)]).encode().unwrap()).unwrap_err();
        assert!(e.to_string().contains("beam 1073741824 of"), "{e}");
    }

    proptest! {
        #[test]
        fn any_sorted_rows_round_trip(mut beams in proptest::collection::btree_map(0u32..600, 1u32..50, 0..40)) {
            let rows: Vec<(u32, u32)> = std::mem::take(&mut beams).into_iter().collect();
            let i = index(&rows);
            prop_assert_eq!(SiteIndex::decode(&i.encode().unwrap()).unwrap(), i);
        }

        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
            let mut b = SITE_MAGIC.to_vec();
            b.extend(bytes);
            let _ = SiteIndex::decode(&b);
        }
    }
}
