//! Packet traversal for coherent rays (Wald et al. 2001; Manta, Stephens et
//! al. 2006, section 3.2): up to eight rays with the same direction signs walk
//! the kd-tree together, each with its own `[t_min, t_max]` interval, and a
//! child is visited when any active ray needs it. The rays of one beam packet
//! pass through the same pair of grid cells, so they stay together deep into
//! the tree. At the leaves, rays sharing the watertight test's axis
//! permutation are tested against each triangle in structure-of-arrays form;
//! rays that land exactly on an edge are settled by the exact scalar test.

use glam::Vec3;

use super::{Hit, KdTree};
use crate::geom::{axis_permutation, intersect_triangle, Ray, RayPrep};
use crate::scene::Scene;

/// Rays per packet.
pub const PACKET: usize = 8;

const STACK: usize = 64;
const SLACK_UP: f32 = 1.0 + 1e-5;
const SLACK_DOWN: f32 = 1.0 - 1e-5;

#[derive(Clone, Copy)]
struct Lane {
    origin: [[f32; PACKET]; 3],
    inv: [[f32; PACKET]; 3],
}

impl KdTree {
    /// Nearest hits of up to [`PACKET`] rays; rays may point anywhere (they are
    /// grouped by direction octant), but coherent rays gain the most.
    pub fn intersect_packet(&self, scene: &Scene, rays: &[Ray]) -> [Option<Hit>; PACKET] {
        let mut out = [None; PACKET];
        let n = rays.len().min(PACKET);
        // By sign bit, so that a -0.0 component walks like the single ray, whose inverse is -inf.
        let octant = |r: &Ray| {
            r.dir.x.is_sign_negative() as u8
                | (r.dir.y.is_sign_negative() as u8) << 1
                | (r.dir.z.is_sign_negative() as u8) << 2
        };
        let mut done = 0u32;
        for i in 0..n {
            if done & (1 << i) != 0 {
                continue;
            }
            let o = octant(&rays[i]);
            let mask = (i..n)
                .filter(|&j| done & (1 << j) == 0 && octant(&rays[j]) == o)
                .fold(0u32, |m, j| m | 1 << j);
            done |= mask;
            self.packet_octant(scene, rays, mask, &mut out);
        }
        out
    }

    fn packet_octant(&self, scene: &Scene, rays: &[Ray], mask: u32, out: &mut [Option<Hit>; PACKET]) {
        let mut lane = Lane {
            origin: [[0.0; PACKET]; 3],
            inv: [[0.0; PACKET]; 3],
        };
        let mut t_min = [f32::INFINITY; PACKET];
        let mut t_max = [f32::NEG_INFINITY; PACKET];
        let mut closest = [f32::INFINITY; PACKET];
        let mut active = 0u32;
        let mut preps = [None; PACKET];
        for i in 0..PACKET {
            if mask & (1 << i) == 0 {
                continue;
            }
            let r = &rays[i];
            let inv = r.dir.recip();
            for a in 0..3 {
                lane.origin[a][i] = r.origin[a];
                lane.inv[a][i] = inv[a];
            }
            closest[i] = r.t_max;
            if let Some((a, b)) = self.bounds.range(r, inv) {
                t_min[i] = a;
                t_max[i] = b;
                active |= 1 << i;
                preps[i] = Some(RayPrep::new(r.origin, r.dir));
            }
        }
        if active == 0 {
            return;
        }
        let first_lane = active.trailing_zeros() as usize;
        let negative = [
            rays[first_lane].dir.x.is_sign_negative(),
            rays[first_lane].dir.y.is_sign_negative(),
            rays[first_lane].dir.z.is_sign_negative(),
        ];
        let shared = SharedPrep::new(rays, active);
        let mut stack = [(0u32, 0u32, [0f32; PACKET], [0f32; PACKET]); STACK];
        let mut sp = 0;
        let mut node = 0usize;
        loop {
            let nd = self.nodes[node];
            if !nd.is_leaf() {
                let axis = nd.axis();
                let split = nd.split();
                let (first, second) = if negative[axis] {
                    (nd.left() + 1, nd.left())
                } else {
                    (nd.left(), nd.left() + 1)
                };
                let (mut need_first, mut need_second) = (0u32, 0u32);
                let mut ts = [0f32; PACKET];
                for i in 0..PACKET {
                    if active & (1 << i) == 0 {
                        continue;
                    }
                    let t = (split - lane.origin[axis][i]) * lane.inv[axis][i];
                    ts[i] = t;
                    if t.is_nan() {
                        need_first |= 1 << i;
                        need_second |= 1 << i;
                        continue;
                    }
                    // The single-ray walk's rules exactly, boundaries included.
                    if t <= 0.0 {
                        // The plane is behind this ray (or it starts on it): only the
                        // child it starts in, decided as the single-ray walk decides.
                        let o = lane.origin[axis][i];
                        let starts_left = o < split || (o == split && lane.inv[axis][i] <= 0.0);
                        if starts_left != negative[axis] {
                            need_first |= 1 << i;
                        } else {
                            need_second |= 1 << i;
                        }
                        continue;
                    }
                    if t >= t_min[i] * SLACK_DOWN {
                        need_first |= 1 << i;
                    }
                    if t <= t_max[i] * SLACK_UP {
                        need_second |= 1 << i;
                    }
                }
                match (need_first != 0, need_second != 0) {
                    (true, true) => {
                        let mut t0 = t_min;
                        let mut t1 = t_max;
                        // Rays that need both children split their range at the plane,
                        // as the single-ray walk does (slack included).
                        for i in 0..PACKET {
                            let both = need_first & need_second & (1 << i) != 0;
                            if both && !ts[i].is_nan() && ts[i] > 0.0 {
                                t0[i] = ts[i];
                                t1[i] = ts[i];
                            }
                        }
                        if sp < STACK {
                            stack[sp] = (second as u32, need_second, t0, t_max);
                            sp += 1;
                        }
                        active = need_first;
                        t_max = t1;
                        node = first;
                    }
                    (true, false) => {
                        active = need_first;
                        node = first;
                    }
                    (false, true) => {
                        active = need_second;
                        node = second;
                    }
                    (false, false) => active = 0,
                }
                if active != 0 {
                    continue;
                }
            } else {
                let tris = &self.leaf_tris[nd.first()..nd.first() + nd.count()];
                for &t in tris {
                    let [a, b, c] = scene.vertices(t as usize);
                    shared.test(&preps, active, a, b, c, t, &mut closest, out);
                }
                // Rays whose nearest hit lies in this leaf drop out when the
                // next node is popped: its interval starts beyond their hit.
            }
            // Pop the next node that still has unfinished rays.
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                let (next, m, a, b) = stack[sp];
                let mut live = 0u32;
                for i in 0..PACKET {
                    if m & (1 << i) != 0 && a[i] <= closest[i] {
                        live |= 1 << i;
                    }
                }
                if live != 0 {
                    node = next as usize;
                    active = live;
                    t_min = a;
                    t_max = b;
                    break;
                }
            }
        }
    }
}

/// The exact scalar test of one ray, keeping a nearer hit.
#[inline]
fn scalar_test(prep: Option<&RayPrep>, [a, b, c]: [Vec3; 3], tri: u32, closest: &mut f32, out: &mut Option<Hit>) {
    if let Some(h) = prep.and_then(|p| intersect_triangle(p, a, b, c, *closest)) {
        *closest = h.t;
        *out = Some(Hit {
            t: h.t,
            tri,
            u: h.u,
            v: h.v,
        });
    }
}

/// The watertight test's per-ray constants in structure-of-arrays form, when
/// every ray of the packet shares one axis permutation.
struct SharedPrep {
    k: Option<[usize; 3]>,
    ox: [f32; PACKET],
    oy: [f32; PACKET],
    oz: [f32; PACKET],
    sx: [f32; PACKET],
    sy: [f32; PACKET],
    sz: [f32; PACKET],
}

impl SharedPrep {
    fn new(rays: &[Ray], active: u32) -> SharedPrep {
        let mut p = SharedPrep {
            k: None,
            ox: [0.0; PACKET],
            oy: [0.0; PACKET],
            oz: [0.0; PACKET],
            sx: [0.0; PACKET],
            sy: [0.0; PACKET],
            sz: [0.0; PACKET],
        };
        let mut k: Option<[usize; 3]> = None;
        for (i, r) in rays.iter().enumerate().take(PACKET) {
            if active & (1 << i) == 0 {
                continue;
            }
            let [kx, ky, kz] = axis_permutation(r.dir);
            match k {
                None => k = Some([kx, ky, kz]),
                Some(prev) if prev != [kx, ky, kz] => return p,
                _ => {}
            }
            p.ox[i] = r.origin[kx];
            p.oy[i] = r.origin[ky];
            p.oz[i] = r.origin[kz];
            p.sx[i] = r.dir[kx] / r.dir[kz];
            p.sy[i] = r.dir[ky] / r.dir[kz];
            p.sz[i] = 1.0 / r.dir[kz];
        }
        p.k = k;
        p
    }

    /// Tests one triangle against every active ray, keeping nearer hits.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn test(
        &self,
        preps: &[Option<RayPrep>; PACKET],
        active: u32,
        a: Vec3,
        b: Vec3,
        c: Vec3,
        tri: u32,
        closest: &mut [f32; PACKET],
        out: &mut [Option<Hit>; PACKET],
    ) {
        let Some([kx, ky, kz]) = self.k else {
            for i in 0..PACKET {
                if active & (1 << i) == 0 {
                    continue;
                }
                scalar_test(preps[i].as_ref(), [a, b, c], tri, &mut closest[i], &mut out[i]);
            }
            return;
        };
        let (mut u, mut v, mut w, mut tz, mut det) = (
            [0f32; PACKET],
            [0f32; PACKET],
            [0f32; PACKET],
            [0f32; PACKET],
            [0f32; PACKET],
        );
        // Structure-of-arrays: the compiler turns this loop into vector code.
        for i in 0..PACKET {
            let (az, bz, cz) = (a[kz] - self.oz[i], b[kz] - self.oz[i], c[kz] - self.oz[i]);
            let ax = a[kx] - self.ox[i] - self.sx[i] * az;
            let ay = a[ky] - self.oy[i] - self.sy[i] * az;
            let bx = b[kx] - self.ox[i] - self.sx[i] * bz;
            let by = b[ky] - self.oy[i] - self.sy[i] * bz;
            let cx = c[kx] - self.ox[i] - self.sx[i] * cz;
            let cy = c[ky] - self.oy[i] - self.sy[i] * cz;
            u[i] = cx * by - cy * bx;
            v[i] = ax * cy - ay * cx;
            w[i] = bx * ay - by * ax;
            det[i] = u[i] + v[i] + w[i];
            // Same operation order as the scalar test, so both give identical bits.
            tz[i] = u[i] * (self.sz[i] * az) + v[i] * (self.sz[i] * bz) + w[i] * (self.sz[i] * cz);
        }
        for i in 0..PACKET {
            if active & (1 << i) == 0 {
                continue;
            }
            if u[i] == 0.0 || v[i] == 0.0 || w[i] == 0.0 {
                // On an edge: let the exact test decide.
                scalar_test(preps[i].as_ref(), [a, b, c], tri, &mut closest[i], &mut out[i]);
                continue;
            }
            let mixed = (u[i] < 0.0 || v[i] < 0.0 || w[i] < 0.0) && (u[i] > 0.0 || v[i] > 0.0 || w[i] > 0.0);
            if mixed || det[i] == 0.0 {
                continue;
            }
            let sign = det[i].signum();
            if !(tz[i] * sign > 0.0 && tz[i] * sign <= closest[i] * det[i] * sign) {
                continue;
            }
            let inv = 1.0 / det[i];
            closest[i] = tz[i] * inv;
            out[i] = Some(Hit {
                t: closest[i],
                tri,
                u: v[i] * inv,
                v: w[i] * inv,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::testing::soup;
    use crate::accel::BuildOptions;
    use rand::{Rng, SeedableRng};

    #[test]
    fn packets_find_exactly_what_single_rays_find() {
        for seed in 0..6 {
            let scene = soup(seed, 400);
            let tree = KdTree::build(&scene, &BuildOptions::default());
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed + 50);
            let mut hits = 0;
            for k in 0..600 {
                // Coherent packets (a small cone around one direction, as beam
                // rays are), mixed-octant packets, and partial packets.
                let origin = Vec3::new(
                    rng.gen_range(-7.0..7.0),
                    rng.gen_range(-7.0..7.0),
                    rng.gen_range(-7.0..7.0),
                );
                let centre = Vec3::new(
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                );
                let spread = if k % 3 == 0 { 1.0 } else { 0.05 };
                let n = if k % 5 == 0 { 1 + k % PACKET } else { PACKET };
                let rays: Vec<Ray> = (0..n)
                    .map(|_| {
                        let jitter = Vec3::new(
                            rng.gen_range(-1.0..1.0),
                            rng.gen_range(-1.0..1.0),
                            rng.gen_range(-1.0..1.0),
                        );
                        let o = if k % 7 == 0 { origin } else { origin + jitter * 0.2 };
                        Ray::new(o, centre + jitter * spread)
                    })
                    .filter(|r| r.dir.length() > 1e-3)
                    .collect();
                let packet = tree.intersect_packet(&scene, &rays);
                for (i, r) in rays.iter().enumerate() {
                    let single = tree.intersect(&scene, r);
                    match (packet[i], single) {
                        (None, None) => {}
                        (Some(p), Some(s)) => {
                            hits += 1;
                            assert!(
                                p.t == s.t || (p.t - s.t).abs() <= 1e-6 * s.t,
                                "seed {seed} packet {k} ray {i}: {p:?} vs {s:?}"
                            );
                        }
                        other => panic!("seed {seed} packet {k} ray {i} {r:?}: packet vs single {other:?}"),
                    }
                }
            }
            assert!(hits > 1000, "{hits}");
        }
    }

    /// Rays that start exactly on split planes, with zero (and negative zero)
    /// direction components, and bounce rays leaving a surface: where the
    /// packet walk once dropped rays that the single-ray walk kept.
    #[test]
    fn packets_agree_on_rays_starting_on_split_planes_and_leaving_surfaces() {
        let mut checked = 0;
        let mut near = 0;
        for seed in 0..4 {
            let scene = soup(seed, 400);
            let tree = KdTree::build(&scene, &BuildOptions::default());
            let planes: Vec<(usize, f32)> = tree
                .nodes()
                .iter()
                .filter(|n| !n.is_leaf())
                .map(|n| (n.axis(), n.split()))
                .collect();
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed + 90);
            for k in 0..800 {
                let rays: Vec<Ray> = if k % 2 == 0 {
                    let (axis, split) = planes[rng.gen_range(0..planes.len())];
                    let mut origin = Vec3::new(
                        rng.gen_range(-6.0..6.0),
                        rng.gen_range(-6.0..6.0),
                        rng.gen_range(-6.0..6.0),
                    );
                    origin[axis] = split;
                    let centre = Vec3::new(
                        rng.gen_range(-1.0..1.0),
                        rng.gen_range(-1.0..1.0),
                        rng.gen_range(-1.0..1.0),
                    );
                    (0..PACKET)
                        .map(|i| {
                            let mut d = centre
                                + 0.05
                                    * Vec3::new(
                                        rng.gen_range(-1.0..1.0),
                                        rng.gen_range(-1.0..1.0),
                                        rng.gen_range(-1.0..1.0),
                                    );
                            match (k / 2 + i) % 4 {
                                0 => d[axis] = 0.0,
                                1 => d[axis] = -0.0,
                                2 => d[(axis + 1) % 3] = -0.0,
                                _ => {}
                            }
                            Ray::new(origin, d)
                        })
                        .collect()
                } else {
                    // Bounce rays from one point just off a triangle, as a sampler makes them.
                    let t = rng.gen_range(0..scene.triangles.len());
                    let [a, b, c] = scene.vertices(t);
                    let n = (b - a).cross(c - a).normalize();
                    let (u, v) = (rng.gen_range(0.05..0.45), rng.gen_range(0.05..0.45));
                    let p = a + u * (b - a) + v * (c - a) + n * 1e-5;
                    (0..PACKET)
                        .map(|_| {
                            let d = Vec3::new(
                                rng.gen_range(-1.0..1.0),
                                rng.gen_range(-1.0..1.0),
                                rng.gen_range(-1.0..1.0),
                            );
                            Ray::new(p, if d.dot(n) < 0.0 { -d } else { d })
                        })
                        .collect()
                };
                let rays: Vec<Ray> = rays.into_iter().filter(|r| r.dir.length() > 1e-3).collect();
                let packet = tree.intersect_packet(&scene, &rays);
                for (i, r) in rays.iter().enumerate() {
                    let single = tree.intersect(&scene, r);
                    assert_eq!(
                        packet[i].map(|h| (h.t, h.tri)),
                        single.map(|h| (h.t, h.tri)),
                        "seed {seed} packet {k} ray {i} {r:?}"
                    );
                    checked += 1;
                    near += usize::from(single.is_some_and(|h| h.t < 1e-3));
                }
            }
        }
        assert!(checked > 20_000, "{checked}");
        assert!(near > 0, "some bounce rays hit a neighbour right away");
    }
}
