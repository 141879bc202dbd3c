//! LOD voxels (Áfra 2012, 4.2): a voxel fills its kd-tree node and holds one
//! shading sample per face (normal, color and coverage of what is seen through
//! that face, occlusion taken into account). A sample packs into 8 bytes: the
//! normal octahedron-encoded in two bytes each way, the color square-root
//! encoded in 8 bits per channel, and the coverage in 8 bits.

use glam::{Vec2, Vec3};

/// Faces in the order -x, +x, -y, +y, -z, +z.
pub const FACES: usize = 6;

/// What is seen through one face.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaceSample {
    /// Unit normal, facing out of that face.
    pub normal: Vec3,
    /// Diffuse color (linear RGB).
    pub color: Vec3,
    /// Share of the face's rays that hit something, 0..1.
    pub coverage: f32,
}

/// A voxel: six encoded face samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Voxel(pub [u64; FACES]);

/// Outward unit normal of face `f`.
pub fn face_normal(f: usize) -> Vec3 {
    let mut n = [0.0f32; 3];
    n[f / 2] = if f % 2 == 1 { 1.0 } else { -1.0 };
    Vec3::from(n)
}

/// The face a ray enters through when it crosses the plane of `axis` going `dir`.
#[inline]
pub fn entry_face(axis: usize, dir: Vec3) -> usize {
    2 * axis + usize::from(dir[axis] < 0.0)
}

/// The octahedral coordinates of `n` rounded to 16 bits each (the four
/// corners, all straight down, as one).
fn oct_quantize(n: Vec3) -> [u16; 2] {
    let n = n / (n.x.abs() + n.y.abs() + n.z.abs()).max(1e-20);
    let p = if n.z >= 0.0 {
        Vec2::new(n.x, n.y)
    } else {
        let s = |v: f32| if v >= 0.0 { 1.0 } else { -1.0 };
        Vec2::new((1.0 - n.y.abs()) * s(n.x), (1.0 - n.x.abs()) * s(n.y))
    };
    let q = |v: f32| ((v.clamp(-1.0, 1.0) * 0.5 + 0.5) * 65535.0).round() as u16;
    let e = [q(p.x), q(p.y)];
    // The four corners of the square are all straight down (-z): one of
    // them stands for it, so that a decoded normal encodes to the same bits.
    if e.iter().all(|&v| v == 0 || v == u16::MAX) {
        return [u16::MAX; 2];
    }
    e
}

/// A unit normal in two 16-bit octahedral coordinates, chosen so that
/// decoding and encoding again gives the same bits: near the fold (the
/// equator) a normal can round to either side of it, and the code is
/// moved to the one its own decoding rounds to.
fn oct_encode(n: Vec3) -> [u16; 2] {
    let mut e = oct_quantize(n);
    for _ in 0..4 {
        let again = oct_quantize(oct_decode(e));
        if again == e {
            break;
        }
        e = again;
    }
    e
}

fn oct_decode(e: [u16; 2]) -> Vec3 {
    let f = |v: u16| f32::from(v) / 65535.0 * 2.0 - 1.0;
    let (x, y) = (f(e[0]), f(e[1]));
    let z = 1.0 - x.abs() - y.abs();
    let t = (-z).max(0.0);
    let s = |v: f32| if v >= 0.0 { -t } else { t };
    Vec3::new(x + s(x), y + s(y), z).normalize_or(Vec3::Z)
}

impl FaceSample {
    /// Packs the sample.
    pub fn encode(&self) -> u64 {
        let [nx, ny] = oct_encode(self.normal);
        let c = |v: f32| (v.clamp(0.0, 1.0).sqrt() * 255.0).round() as u64;
        let cov = (self.coverage.clamp(0.0, 1.0) * 255.0).round() as u64;
        u64::from(nx)
            | u64::from(ny) << 16
            | c(self.color.x) << 32
            | c(self.color.y) << 40
            | c(self.color.z) << 48
            | cov << 56
    }
    /// Unpacks a sample (any 64 bits decode to a valid sample).
    pub fn decode(w: u64) -> FaceSample {
        let c = |s: u32| {
            let v = ((w >> s) & 255) as f32 / 255.0;
            v * v
        };
        FaceSample {
            normal: oct_decode([(w & 0xFFFF) as u16, ((w >> 16) & 0xFFFF) as u16]),
            color: Vec3::new(c(32), c(40), c(48)),
            coverage: ((w >> 56) & 255) as f32 / 255.0,
        }
    }
}

impl Voxel {
    /// A voxel from six samples.
    pub fn new(faces: [FaceSample; FACES]) -> Voxel {
        Voxel(faces.map(|f| f.encode()))
    }
    /// The sample of face `f`.
    pub fn face(&self, f: usize) -> FaceSample {
        FaceSample::decode(self.0[f % FACES])
    }
}

/// Accumulates hits seen through one face into a sample.
#[derive(Clone, Copy, Debug, Default)]
pub struct FaceAccumulator {
    normal: Vec3,
    color: Vec3,
    weight: f32,
    rays: u32,
    hits: u32,
}

impl FaceAccumulator {
    /// Counts a ray that hit a surface of this normal (any orientation) and color
    /// with weight `w`; `toward` is the direction back to the viewer.
    pub fn hit(&mut self, normal: Vec3, color: Vec3, toward: Vec3, w: f32) {
        let n = if normal.dot(toward) < 0.0 { -normal } else { normal };
        self.normal += n * w;
        self.color += color * w;
        self.weight += w;
        self.rays += 1;
        self.hits += 1;
    }
    /// Counts a ray that saw nothing.
    pub fn miss(&mut self) {
        self.rays += 1;
    }
    /// Adds a sample seen through part of the face, weighted by the share `w`
    /// of the face it covers (for voxels made from their children's voxels).
    pub fn add_sample(&mut self, s: &FaceSample, w: f32) {
        let w = w * s.coverage;
        self.normal += s.normal * w;
        self.color += s.color * w;
        self.weight += w;
    }
    /// The sample, or `None` if nothing was seen; `coverage` overrides the
    /// hit ratio (composited samples know their own).
    pub fn finish(&self, coverage: Option<f32>) -> Option<FaceSample> {
        if self.weight <= 0.0 {
            return None;
        }
        Some(FaceSample {
            normal: self.normal.normalize_or(Vec3::Z),
            color: self.color / self.weight,
            coverage: coverage.unwrap_or(self.hits as f32 / self.rays.max(1) as f32),
        })
    }
}

/// Fills faces that saw nothing with the mean of the others (a voxel is drawn
/// as a box, so every face needs a sample); `None` if no face saw anything.
pub fn complete(faces: [Option<FaceSample>; FACES]) -> Option<Voxel> {
    let seen: Vec<FaceSample> = faces.iter().flatten().copied().collect();
    if seen.is_empty() {
        return None;
    }
    let n = seen.len() as f32;
    let color = seen.iter().map(|s| s.color).sum::<Vec3>() / n;
    let mut out = [FaceSample {
        normal: Vec3::Z,
        color,
        coverage: 0.0,
    }; FACES];
    for (f, s) in faces.iter().enumerate() {
        out[f] = s.unwrap_or(FaceSample {
            normal: face_normal(f),
            color,
            coverage: 0.0,
        });
    }
    Some(Voxel::new(out))
}

/// A neutral voxel for a node with nothing in it that could be seen.
pub fn grey() -> Voxel {
    Voxel::new(std::array::from_fn(|f| FaceSample {
        normal: face_normal(f),
        color: Vec3::splat(0.5),
        coverage: 0.0,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn samples_round_trip_within_quantization(
            x in -1.0f32..1.0, y in -1.0f32..1.0, z in -1.0f32..1.0,
            r in 0.0f32..1.0, g in 0.0f32..1.0, b in 0.0f32..1.0, c in 0.0f32..1.0,
        ) {
            let n = Vec3::new(x, y, z);
            prop_assume!(n.length() > 0.1);
            let n = n.normalize();
            let s = FaceSample { normal: n, color: Vec3::new(r, g, b), coverage: c };
            let d = FaceSample::decode(s.encode());
            prop_assert!(d.normal.dot(n) > 0.9999, "{:?} {:?}", n, d.normal);
            prop_assert!((d.color - s.color).abs().max_element() < 0.01);
            prop_assert!((d.coverage - c).abs() <= 0.5 / 255.0 + 1e-6);
            prop_assert_eq!(d.encode(), s.encode());
        }

        #[test]
        fn any_bits_decode_to_a_unit_normal(w in any::<u64>()) {
            let s = FaceSample::decode(w);
            prop_assert!((s.normal.length() - 1.0).abs() < 1e-4);
            prop_assert!(s.color.min_element() >= 0.0 && s.color.max_element() <= 1.0);
        }
    }

    #[test]
    fn entry_faces_face_the_ray() {
        // A ray going +x enters through the -x face, whose normal points back at it.
        assert_eq!(entry_face(0, Vec3::X), 0);
        assert!(face_normal(entry_face(0, Vec3::X)).dot(Vec3::X) < 0.0);
        assert_eq!(entry_face(2, -Vec3::Z), 5);
        assert!(face_normal(5).dot(-Vec3::Z) < 0.0);
    }
}
