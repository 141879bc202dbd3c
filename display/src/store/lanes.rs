//! Stored rays decoded and projected four at a time, in SIMD lanes.
//!
//! Decoding a record and projecting its hit into a perspective view takes
//! a dozen divisions and two square roots, and the divider is what bounds
//! replay on one core. Lanes divide several rays at once. Every lane does
//! exactly the arithmetic of [`BeamDecoder::decode`], [`Projector::locate`]
//! and [`Projector::look`], operation for operation (IEEE division, square
//! root, products and sums are exact per lane, and nothing is fused), so a
//! ray lands on the same pixel with the same weight, bit for bit, as one
//! decoded into a [`crate::Sample`] and projected alone. What is not
//! arithmetic on lanes (the depth code, the color, the pixel, the weight)
//! is done per ray, with the same functions.

use glam::DVec3;
use holodeck_protocol::{BeamDecoder, RayRecord};
use wide::f64x4;

use super::lens::{Lens, NOT_FINITE, OFF};
use super::Pending;
use crate::sample::SampleDecoder;

/// Rays per group.
const LANES: usize = 4;

/// A vector per lane: x, y and z of four rays.
#[derive(Clone, Copy)]
struct V4 {
    x: f64x4,
    y: f64x4,
    z: f64x4,
}

impl V4 {
    fn splat(v: DVec3) -> V4 {
        V4 {
            x: f64x4::splat(v.x),
            y: f64x4::splat(v.y),
            z: f64x4::splat(v.z),
        }
    }

    /// As `DVec3::dot`: `(x x' + y y') + z z'`.
    #[inline(always)]
    fn dot(self, o: V4) -> f64x4 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    #[inline(always)]
    fn sub(self, o: V4) -> V4 {
        V4 {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }

    #[inline(always)]
    fn div(self, d: f64x4) -> V4 {
        V4 {
            x: self.x / d,
            y: self.y / d,
            z: self.z / d,
        }
    }

    #[inline(always)]
    fn lane(&self, i: usize) -> DVec3 {
        DVec3::new(self.x.to_array()[i], self.y.to_array()[i], self.z.to_array()[i])
    }
}

/// A wall of the beam on lanes: corner and steps per sub-cell unit.
struct Wall {
    base: V4,
    du: V4,
    dv: V4,
}

impl Wall {
    fn new(w: [DVec3; 3]) -> Wall {
        Wall {
            base: V4::splat(w[0]),
            du: V4::splat(w[1]),
            dv: V4::splat(w[2]),
        }
    }

    /// As the decoder's wall point: `base + du (u + 0.5) + dv (v + 0.5)`.
    #[inline(always)]
    fn point(&self, sub: [[u8; 2]; LANES]) -> V4 {
        let u = f64x4::from(sub.map(|s| f64::from(s[0]) + 0.5));
        let v = f64x4::from(sub.map(|s| f64::from(s[1]) + 0.5));
        V4 {
            x: self.base.x + self.du.x * u + self.dv.x * v,
            y: self.base.y + self.du.y * u + self.dv.y * v,
            z: self.base.z + self.du.z * u + self.dv.z * v,
        }
    }
}

/// Decodes `records` of the beam `d` decodes and projects them into `out`
/// (a perspective view) four at a time, as [`Lens::project`] would one by
/// one; returns how many it did (a multiple of four: the caller does the
/// rest). Rays that escaped are handed to [`Lens::project`] as they are.
pub(super) fn project_perspective(
    lens: &Lens<'_>,
    d: &BeamDecoder,
    records: &[RayRecord],
    out: &mut [Pending],
) -> usize {
    let [entry, exit] = d.walls().map(Wall::new);
    let view = lens.projector.view();
    let (eye, right, up, ahead) = (
        V4::splat(view.position),
        V4::splat(view.right),
        V4::splat(view.up),
        V4::splat(view.direction),
    );
    let (sx, sy) = (f64x4::splat(view.sx), f64x4::splat(view.sy));
    let (half, shift, lift) = (f64x4::splat(0.5), f64x4::splat(view.shift), f64x4::splat(view.lift));
    let groups = records.len() / LANES;
    for (recs, slots) in records.chunks_exact(LANES).zip(out.chunks_exact_mut(LANES)) {
        let recs: &[RayRecord; LANES] = recs.try_into().unwrap_or_else(|_| unreachable!());
        // The decoder's ray: entry point, direction, hit.
        let a = entry.point(recs.map(|r| r.entry));
        let along = exit.point(recs.map(|r| r.exit)).sub(a);
        let length = along.dot(along).sqrt();
        let dir = along.div(length);
        let depths = recs.map(|r| d.depth(&r));
        let t = f64x4::from(depths.map(|t| t.unwrap_or(0.0)));
        let hit = V4 {
            x: a.x + dir.x * t,
            y: a.y + dir.y * t,
            z: a.z + dir.z * t,
        };
        // The view's projection of the hit, and the direction the eye
        // looks at it along.
        let to = hit.sub(eye);
        let (fx, fy, fz) = (to.dot(right), to.dot(up), to.dot(ahead));
        let (px, py) = (fx / fz / sx, fy / fz / sy);
        // View coordinates, as the projector offsets them.
        let (x, y) = (px + half - shift, py + half - lift);
        let dist = to.dot(to).sqrt();
        let cos = dir.dot(to.div(dist));
        // Zero where the nine numbers of a lane's ray are finite (their sum
        // is; a sum that overflows is checked one number at a time).
        let sum = a.x + a.y + a.z + dir.x + dir.y + dir.z + hit.x + hit.y + hit.z;
        let check = (sum * f64x4::splat(0.0)).to_array();
        let (fz, x, y, dist, cos) = (
            fz.to_array(),
            x.to_array(),
            y.to_array(),
            dist.to_array(),
            cos.to_array(),
        );
        for (i, slot) in slots.iter_mut().enumerate() {
            let r = &recs[i];
            if depths[i].is_none() {
                *slot = lens.project(&SampleDecoder::sample(d, r));
                continue;
            }
            let color = r.color.to_rgb();
            let finite = (check[i] == 0.0
                || a.lane(i).is_finite() && dir.lane(i).is_finite() && hit.lane(i).is_finite())
                && color.iter().all(|c| c.is_finite());
            *slot = if !finite {
                Pending::nowhere(NOT_FINITE)
            } else if fz[i] <= 0.0 || fz[i] < view.fore || fz[i] > view.aft {
                Pending::nowhere(OFF)
            } else {
                match lens.projector.place(x[i], y[i]) {
                    Some((col, row, at)) => lens.surface(col, row, at, dist[i], cos[i], color),
                    None => Pending::nowhere(OFF),
                }
            };
        }
    }
    groups * LANES
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadtree::Tree;
    use crate::store::{EstimatorOptions, Store};
    use crate::Viewport;
    use holodeck_protocol::{DepthCode, Rgbe, View};
    use proptest::prelude::*;

    /// Every number of a projected ray, as bits.
    fn bits(p: &Pending) -> (u64, [u32; 3], u32, u32, [u16; 2]) {
        (
            p.key,
            p.color.map(f32::to_bits),
            p.weight.to_bits(),
            p.depth.to_bits(),
            p.at,
        )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]

        #[test]
        fn four_lanes_land_rays_as_one_at_a_time_does(
            (h, v) in (20.0f64..120.0, 20.0f64..100.0),
            (dx, dz, sh, li) in (-1.0f64..1.0, -0.5f64..0.5, -0.3f64..0.3, -0.3f64..0.3),
            fore in prop_oneof![Just(0.0f64), 0.0f64..2.0],
            eye in prop::array::uniform3(-0.5f64..0.5),
            beam in 0u32..2000,
            raw in prop::collection::vec((any::<[u8; 4]>(), any::<[u8; 4]>(), any::<u16>(), 0u8..4), 1..64),
        ) {
            let section = crate::store::tests::test_section();
            let d = section.beam_decoder(beam % section.beam_count()).unwrap();
            let spec = format!("-vtv -vp {} {} {} -vd {dx} 1 {dz} -vu 0 0 1 -vh {h} -vv {v} -vs {sh} -vl {li} -vo {fore}", eye[0], eye[1], eye[2]);
            let vp = Viewport::new(View::parse(&spec).unwrap(), 97, 61).unwrap();
            let store = Store::new(vp, Tree::default(), false, EstimatorOptions::default());
            let lens = store.lens();
            // Depth codes: escaped, near, linear and far logarithmic.
            let records: Vec<RayRecord> = raw
                .iter()
                .map(|&(sub, c, depth, kind)| {
                    let depth = match kind {
                        0 => DepthCode::INFINITE,
                        1 => DepthCode(depth % 2048),
                        2 => DepthCode(depth.min(u16::MAX - 1)),
                        _ => DepthCode(depth % 64),
                    };
                    RayRecord::new([sub[0], sub[1]], [sub[2], sub[3]], Rgbe(c), depth)
                })
                .collect();
            let mut out = vec![Pending::nowhere(OFF); records.len()];
            let done = project_perspective(&lens, &d, &records, &mut out);
            prop_assert_eq!(done, records.len() / 4 * 4);
            for (r, got) in records.iter().zip(&out).take(done) {
                let want = lens.project(&SampleDecoder::sample(&d, r));
                prop_assert_eq!(bits(got), bits(&want), "{:?}", r);
            }
        }
    }
}
