//! The binary layout of a Radiance holodeck after its text header, for each
//! of the C data models Radiance has been built with. All integers and
//! doubles are in the writer's byte order.
//!
//! ```text
//! magic         4 B   324 + size of a directory entry (340 on 64-bit systems)
//! section record, repeated along a chain:
//!   next        4|8 B absolute position of the next record, 0 after the last
//!   grid      104 B   origin (3 doubles), 3 axis vectors (9 doubles),
//!                     cells per axis (3 x int16), 2 bytes of padding
//!   directory n x 8|12|16 B   per beam 1..=n: ray count (uint32), then
//!                     the file position of its rays (off_t, aligned)
//! beams: runs of 10-byte rays anywhere after the directories; a ray's
//!   depth code (its last two bytes) is in the writer's byte order too
//! ```

use holodeck_protocol::{RayRecord, RAY_RECORD_BYTES};

/// Bytes of a section's grid record (Radiance's `HDGRID`).
pub const GRID_BYTES: u64 = 104;

/// The magic number is 324 plus the size of a directory entry.
const MAGIC_BASE: u32 = 324;

/// A byte order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ByteOrder {
    /// Least significant byte first (x86, ARM as usually run).
    Little,
    /// Most significant byte first (SPARC, PowerPC).
    Big,
}

impl ByteOrder {
    /// The name used in messages.
    pub fn name(self) -> &'static str {
        match self {
            ByteOrder::Little => "little",
            ByteOrder::Big => "big",
        }
    }
}

/// Byte order and offset sizes of one Radiance build.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Layout {
    /// Byte order of every number.
    pub order: ByteOrder,
    /// Bytes of a file position (`off_t`): 4 or 8.
    pub offset_bytes: u8,
    /// Bytes of a directory entry: 8 (32-bit offsets), 12 (64-bit offsets on
    /// 4-byte alignment) or 16 (64-bit offsets, 8-byte aligned).
    pub entry_bytes: u8,
}

impl Layout {
    /// What Radiance writes on today's 64-bit systems: little-endian, 8-byte
    /// offsets, 16-byte directory entries (magic 340).
    pub const LP64: Layout = Layout {
        order: ByteOrder::Little,
        offset_bytes: 8,
        entry_bytes: 16,
    };

    /// Every layout this program reads.
    pub const ALL: [Layout; 6] = [
        Layout::LP64,
        Layout {
            order: ByteOrder::Big,
            ..Layout::LP64
        },
        Layout {
            order: ByteOrder::Little,
            offset_bytes: 8,
            entry_bytes: 12,
        },
        Layout {
            order: ByteOrder::Big,
            offset_bytes: 8,
            entry_bytes: 12,
        },
        Layout {
            order: ByteOrder::Little,
            offset_bytes: 4,
            entry_bytes: 8,
        },
        Layout {
            order: ByteOrder::Big,
            offset_bytes: 4,
            entry_bytes: 8,
        },
    ];

    /// The magic number of this layout.
    pub fn magic(self) -> u32 {
        MAGIC_BASE + u32::from(self.entry_bytes)
    }

    /// The layout whose magic number the 4 bytes are, if any.
    pub fn from_magic(bytes: [u8; 4]) -> Option<Layout> {
        Layout::ALL.into_iter().find(|l| l.u32(&bytes) == l.magic())
    }

    /// The magic number's bytes.
    pub fn magic_bytes(self) -> [u8; 4] {
        self.put_u32(self.magic())
    }

    /// Bytes of the pointer to the next section.
    pub fn pointer_bytes(self) -> u64 {
        u64::from(self.offset_bytes)
    }

    /// Bytes of a section record holding `beams` directory entries.
    pub fn record_bytes(self, beams: u64) -> u64 {
        self.pointer_bytes() + GRID_BYTES + beams * u64::from(self.entry_bytes)
    }

    /// Reads a `u32` from the first 4 bytes.
    pub fn u32(self, b: &[u8]) -> u32 {
        let a = [b[0], b[1], b[2], b[3]];
        match self.order {
            ByteOrder::Little => u32::from_le_bytes(a),
            ByteOrder::Big => u32::from_be_bytes(a),
        }
    }

    /// The bytes of a `u32`.
    pub fn put_u32(self, v: u32) -> [u8; 4] {
        match self.order {
            ByteOrder::Little => v.to_le_bytes(),
            ByteOrder::Big => v.to_be_bytes(),
        }
    }

    fn u64(self, b: &[u8]) -> u64 {
        let mut a = [0u8; 8];
        a.copy_from_slice(&b[..8]);
        match self.order {
            ByteOrder::Little => u64::from_le_bytes(a),
            ByteOrder::Big => u64::from_be_bytes(a),
        }
    }

    fn put_u64(self, v: u64) -> [u8; 8] {
        match self.order {
            ByteOrder::Little => v.to_le_bytes(),
            ByteOrder::Big => v.to_be_bytes(),
        }
    }

    /// Reads a signed file position of this layout's size.
    pub fn offset(self, b: &[u8]) -> i64 {
        match self.offset_bytes {
            4 => self.u32(b) as i32 as i64,
            _ => self.u64(b) as i64,
        }
    }

    /// The bytes of a file position (`b.len()` must be the offset size).
    pub fn put_offset(self, v: u64, out: &mut [u8]) {
        match self.offset_bytes {
            4 => out.copy_from_slice(&self.put_u32(v as u32)),
            _ => out.copy_from_slice(&self.put_u64(v)),
        }
    }

    /// Largest file position this layout can point at.
    pub fn max_offset(self) -> u64 {
        match self.offset_bytes {
            4 => i32::MAX as u64,
            _ => i64::MAX as u64,
        }
    }

    /// Decodes a section's grid record.
    pub fn grid(self, b: &[u8]) -> GridRecord {
        let f = |k: usize| f64::from_bits(self.u64(&b[8 * k..]));
        let i = |k: usize| {
            let x = [b[96 + 2 * k], b[97 + 2 * k]];
            match self.order {
                ByteOrder::Little => i16::from_le_bytes(x),
                ByteOrder::Big => i16::from_be_bytes(x),
            }
        };
        GridRecord {
            origin: [f(0), f(1), f(2)],
            axes: [[f(3), f(4), f(5)], [f(6), f(7), f(8)], [f(9), f(10), f(11)]],
            grid: [i(0), i(1), i(2)],
        }
    }

    /// Encodes a section's grid record, padding zeroed.
    pub fn put_grid(self, g: &GridRecord) -> [u8; GRID_BYTES as usize] {
        let mut out = [0u8; GRID_BYTES as usize];
        let doubles = g.origin.iter().chain(g.axes.iter().flatten());
        for (k, d) in doubles.enumerate() {
            out[8 * k..8 * k + 8].copy_from_slice(&self.put_u64(d.to_bits()));
        }
        for (k, n) in g.grid.iter().enumerate() {
            let x = match self.order {
                ByteOrder::Little => n.to_le_bytes(),
                ByteOrder::Big => n.to_be_bytes(),
            };
            out[96 + 2 * k..98 + 2 * k].copy_from_slice(&x);
        }
        out
    }

    /// Decodes one directory entry: (ray count, file position).
    pub fn entry(self, b: &[u8]) -> (u32, i64) {
        let fo_at = usize::from(self.entry_bytes - self.offset_bytes);
        (self.u32(b), self.offset(&b[fo_at..]))
    }

    /// Encodes one directory entry, padding zeroed.
    pub fn put_entry(self, count: u32, position: u64, out: &mut [u8]) {
        out.fill(0);
        out[..4].copy_from_slice(&self.put_u32(count));
        let fo_at = usize::from(self.entry_bytes - self.offset_bytes);
        self.put_offset(position, &mut out[fo_at..usize::from(self.entry_bytes)]);
    }

    /// Turns rays as stored in this layout into this program's records (only
    /// the depth code's byte order can differ), in place.
    pub fn rays_to_records(self, bytes: &mut [u8]) {
        if self.order == ByteOrder::Big {
            for r in bytes.chunks_exact_mut(RAY_RECORD_BYTES) {
                r.swap(8, 9);
            }
        }
    }

    /// Writes records as this layout stores rays.
    pub fn records_to_rays(self, records: &[RayRecord], out: &mut Vec<u8>) {
        let start = out.len();
        out.extend_from_slice(RayRecord::slice_as_bytes(records));
        self.rays_to_records(&mut out[start..]);
    }
}

/// A section's grid as Radiance stores it: the numbers as written, before
/// any check.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridRecord {
    /// The corner.
    pub origin: [f64; 3],
    /// The three edge vectors.
    pub axes: [[f64; 3]; 3],
    /// Cells per axis.
    pub grid: [i16; 3],
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn magic_numbers_give_the_layout_in_both_byte_orders() {
        assert_eq!(Layout::LP64.magic_bytes(), [0x54, 0x01, 0, 0]);
        for l in Layout::ALL {
            assert_eq!(Layout::from_magic(l.magic_bytes()), Some(l));
        }
        assert_eq!(Layout::from_magic([0x54, 0x01, 0, 1]), None);
        assert_eq!(Layout::ALL.map(|l| l.magic()), [340, 340, 336, 336, 332, 332]);
    }

    #[test]
    fn grids_and_entries_round_trip_in_every_layout() {
        let g = GridRecord {
            origin: [0.5, -1.0, 2.0],
            axes: [[6.0, 0.0, 0.0], [0.0, 4.0, 0.25], [0.0, 0.0, 2.5]],
            grid: [24, 16, 10],
        };
        for l in Layout::ALL {
            assert_eq!(l.grid(&l.put_grid(&g)), g);
            let mut e = vec![0xAA; usize::from(l.entry_bytes)];
            l.put_entry(77, 123_456, &mut e);
            assert_eq!(l.entry(&e), (77, 123_456));
            let r = [RayRecord::new(
                [1, 2],
                [3, 4],
                holodeck_protocol::Rgbe([5, 6, 7, 8]),
                holodeck_protocol::DepthCode(0x0a09),
            )];
            let mut bytes = Vec::new();
            l.records_to_rays(&r, &mut bytes);
            let depth = if l.order == ByteOrder::Big {
                [0x0a, 0x09]
            } else {
                [0x09, 0x0a]
            };
            assert_eq!(bytes[8..], depth);
            l.rays_to_records(&mut bytes);
            assert_eq!(RayRecord::vec_from_bytes(&bytes).unwrap(), r);
        }
        // A 64-bit Linux directory entry: count, 4 bytes of padding, position.
        let mut e = [0u8; 16];
        Layout::LP64.put_entry(3, 0x0102, &mut e);
        assert_eq!(e, [3, 0, 0, 0, 0, 0, 0, 0, 2, 1, 0, 0, 0, 0, 0, 0]);
    }
}
