//! The 10-byte ray record stored in holodeck beams and sent over the wire:
//! entry sub-cell (2 bytes), exit sub-cell (2 bytes), RGBE color (4 bytes) and
//! depth code (2 bytes, little-endian). Any 10 bytes form a valid record, so a
//! slice of records can be viewed as raw bytes and back without copying.

use bytemuck::{Pod, Zeroable};
use glam::DVec3;

use crate::beam::{BeamIndex, BeamRay};
use crate::depth::{DepthCode, DepthCoding};
use crate::rgbe::Rgbe;
use crate::section::{Section, SectionError};

/// Size of one record in bytes.
pub const RAY_RECORD_BYTES: usize = 10;

/// One traced ray of a beam, in the paper's 10-byte encoding.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Pod, Zeroable)]
pub struct RayRecord {
    /// Sub-cell position within the entry cell (u, v).
    pub entry: [u8; 2],
    /// Sub-cell position within the exit cell (u, v).
    pub exit: [u8; 2],
    /// Radiance along the ray toward its origin.
    pub color: Rgbe,
    /// Depth code, little-endian: distance from the entry wall to the first hit.
    pub depth: [u8; 2],
}

const _: () = assert!(std::mem::size_of::<RayRecord>() == RAY_RECORD_BYTES);

impl RayRecord {
    /// Assembles a record.
    pub fn new(entry: [u8; 2], exit: [u8; 2], color: Rgbe, depth: DepthCode) -> RayRecord {
        RayRecord {
            entry,
            exit,
            color,
            depth: depth.0.to_le_bytes(),
        }
    }
    /// The depth code.
    pub fn depth_code(&self) -> DepthCode {
        DepthCode(u16::from_le_bytes(self.depth))
    }
    /// Views a slice of records as bytes (no copy).
    pub fn slice_as_bytes(records: &[RayRecord]) -> &[u8] {
        bytemuck::cast_slice(records)
    }
    /// Views bytes as records (no copy); `None` unless the length is a multiple of 10.
    pub fn slice_from_bytes(bytes: &[u8]) -> Option<&[RayRecord]> {
        bytemuck::try_cast_slice(bytes).ok()
    }
    /// Copies records out of bytes; `None` unless the length is a multiple of 10.
    pub fn vec_from_bytes(bytes: &[u8]) -> Option<Vec<RayRecord>> {
        if !bytes.len().is_multiple_of(RAY_RECORD_BYTES) {
            return None;
        }
        Some(
            bytes
                .chunks_exact(RAY_RECORD_BYTES)
                .map(bytemuck::pod_read_unaligned)
                .collect(),
        )
    }
}

/// Where a decoded ray ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Hit {
    /// It hit a surface at this world point.
    Point(DVec3),
    /// It escaped; only its direction is known.
    Infinite,
}

/// A record decoded against its section: everything needed to reproject it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DecodedRay {
    /// Ray through the beam's cells, from the entry wall.
    pub ray: BeamRay,
    /// Linear RGB radiance.
    pub color: [f32; 3],
    /// The first surface hit, in world coordinates.
    pub hit: Hit,
}

/// A wall cell in world space: a corner and a step per sub-cell unit.
#[derive(Clone, Copy, Debug)]
struct WallFrame {
    base: DVec3,
    du: DVec3,
    dv: DVec3,
}

impl WallFrame {
    #[inline]
    fn point(&self, sub: [u8; 2]) -> DVec3 {
        self.base + self.du * (f64::from(sub[0]) + 0.5) + self.dv * (f64::from(sub[1]) + 0.5)
    }
}

/// Decodes the records of one beam (see [`Section::beam_decoder`]); equal to
/// [`Section::decode_record`] up to rounding.
#[derive(Clone, Copy, Debug)]
pub struct BeamDecoder {
    entry: WallFrame,
    exit: WallFrame,
    depth: DepthCoding,
    depth_scale: f64,
}

impl BeamDecoder {
    /// The entry and exit walls of the beam, each as a corner and the step
    /// per sub-cell unit along its two axes: record sub-cell `[u, v]` is at
    /// `corner + du * (u + 0.5) + dv * (v + 0.5)`, as [`BeamDecoder::decode`]
    /// computes it (for decoders that work on several records at once).
    pub fn walls(&self) -> [[DVec3; 3]; 2] {
        [self.entry, self.exit].map(|w| [w.base, w.du, w.dv])
    }

    /// The distance from the entry wall to the record's hit, as
    /// [`BeamDecoder::decode`] finds it; `None` for a ray that escaped.
    #[inline]
    pub fn depth(&self, rec: &RayRecord) -> Option<f64> {
        self.depth.decode(rec.depth_code(), self.depth_scale)
    }

    /// Decodes one record.
    #[inline]
    pub fn decode(&self, rec: &RayRecord) -> DecodedRay {
        let a = self.entry.point(rec.entry);
        let b = self.exit.point(rec.exit);
        let along = b - a;
        let length = along.length();
        let direction = along / length;
        let hit = match self.depth(rec) {
            Some(d) => Hit::Point(a + direction * d),
            None => Hit::Infinite,
        };
        DecodedRay {
            ray: BeamRay {
                origin: a,
                direction,
                length,
            },
            color: rec.color.to_rgb(),
            hit,
        }
    }
}

impl Section {
    /// Decodes a record of `beam` into its world ray, color and hit point.
    pub fn decode_record(&self, beam: BeamIndex, rec: &RayRecord) -> Result<DecodedRay, SectionError> {
        let ray = self.beam_ray(beam, rec.entry, rec.exit)?;
        let hit = match self.decode_depth(rec.depth_code()) {
            Some(d) => Hit::Point(ray.origin + ray.direction * d),
            None => Hit::Infinite,
        };
        Ok(DecodedRay {
            ray,
            color: rec.color.to_rgb(),
            hit,
        })
    }

    /// A decoder for the records of one beam with the beam's geometry worked
    /// out once: for displays that decode millions of records per second.
    pub fn beam_decoder(&self, beam: BeamIndex) -> Result<BeamDecoder, SectionError> {
        let cells = self.beam_cells(beam)?;
        let frame = |c: crate::beam::WallCell| {
            let [u, v] = c.wall.cell_axes();
            let axes = self.axes();
            let g = self.grid();
            let (gu, gv) = (f64::from(g[u]), f64::from(g[v]));
            WallFrame {
                base: self.origin()
                    + axes[c.wall.axis()] * f64::from(c.wall.side())
                    + axes[u] * (f64::from(c.cell[0]) / gu)
                    + axes[v] * (f64::from(c.cell[1]) / gv),
                du: axes[u] / (256.0 * gu),
                dv: axes[v] / (256.0 * gv),
            }
        };
        Ok(BeamDecoder {
            entry: frame(cells.entry),
            exit: frame(cells.exit),
            depth: self.depth_coding(),
            depth_scale: self.depth_scale(),
        })
    }

    /// Encodes a traced ray: the line through `origin` along `dir`, its radiance,
    /// and its first hit (`None` if it escaped). Returns `None` if the line misses
    /// the section. The depth is measured from the entry wall along the ray.
    pub fn encode_ray(
        &self,
        origin: DVec3,
        dir: DVec3,
        rgb: [f32; 3],
        hit: Option<DVec3>,
    ) -> Option<(BeamIndex, RayRecord)> {
        let at = self.locate(origin, dir)?;
        let unit = dir.normalize();
        let entry_point = origin + dir * at.t_entry;
        let depth = match hit {
            Some(h) => self.encode_depth((h - entry_point).dot(unit)),
            None => DepthCode::INFINITE,
        };
        Some((
            at.beam,
            RayRecord::new(at.entry_sub, at.exit_sub, Rgbe::from_rgb(rgb), depth),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::section::SectionKind;
    use proptest::prelude::*;

    #[test]
    fn layout_is_ten_bytes_in_paper_order() {
        let r = RayRecord::new([1, 2], [3, 4], Rgbe([5, 6, 7, 8]), DepthCode(0x0a09));
        assert_eq!(RayRecord::slice_as_bytes(&[r]), &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10]);
        let bytes = [9u8; 25];
        assert!(RayRecord::vec_from_bytes(&bytes).is_none());
        assert_eq!(RayRecord::vec_from_bytes(&bytes[..20]).unwrap().len(), 2);
    }

    proptest! {
        #[test]
        fn hit_points_survive_encoding(
            a in prop::array::uniform3(0.05f64..0.95),
            dir in prop::array::uniform3(-1.0f64..1.0),
            dist in 0.1f64..50.0,
        ) {
            let s = Section::new([0.0; 3], [[4.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 2.0]],
                [8, 6, 4], SectionKind::Interior).unwrap();
            let dir = DVec3::from(dir);
            prop_assume!(dir.length() > 0.1);
            let origin = s.unit_to_world(DVec3::from(a));
            let hit = origin + dir.normalize() * dist;
            let (beam, rec) = s.encode_ray(origin, dir, [1.0, 2.0, 3.0], Some(hit)).unwrap();
            let d = s.decode_record(beam, &rec).unwrap();
            let Hit::Point(p) = d.hit else { panic!("finite hit decoded as infinite") };
            // Error: depth quantization (0.05% of max(depth, diagonal)) plus the
            // direction error of one sub-cell at each wall, lever-armed by the depth.
            let cell = 4.0 / 8.0 / 256.0;
            let depth = (hit - d.ray.origin).length();
            let tolerance = 5e-4 * depth.max(s.diagonal()) + cell * (2.0 + 2.0 * depth / d.ray.length);
            prop_assert!((p - hit).length() <= tolerance, "{p} vs {hit} (tol {tolerance})");
            prop_assert!((d.color[2] - 3.0).abs() < 3.0 / 128.0);
        }
    }

    #[test]
    fn the_beam_decoder_agrees_with_decode_record() {
        let s = Section::new(
            [1.0, -2.0, 0.5],
            [[4.0, 0.5, 0.0], [0.0, 3.0, 0.2], [0.1, 0.0, 2.0]],
            [5, 4, 3],
            crate::section::SectionKind::Interior,
        )
        .unwrap();
        for beam in (0..s.beam_count()).step_by(37) {
            let fast = s.beam_decoder(beam).unwrap();
            for (i, depth) in [0u16, 7, 2047, 2048, 40_000, u16::MAX].into_iter().enumerate() {
                let rec = RayRecord::new(
                    [(i * 40) as u8, 255 - (i * 31) as u8],
                    [(i * 13) as u8, (i * 50) as u8],
                    Rgbe::from_rgb([0.5, 1.0, 2.0]),
                    DepthCode(depth),
                );
                let slow = s.decode_record(beam, &rec).unwrap();
                let quick = fast.decode(&rec);
                assert!((slow.ray.origin - quick.ray.origin).length() < 1e-12);
                assert!((slow.ray.direction - quick.ray.direction).length() < 1e-12);
                assert_eq!(slow.color, quick.color);
                match (slow.hit, quick.hit) {
                    (Hit::Point(a), Hit::Point(b)) => assert!((a - b).length() <= 1e-12 * a.length().max(1.0)),
                    (a, b) => assert_eq!(a, b),
                }
            }
        }
    }
}
