//! The wavefront estimator: the paths of a batch advance together, one
//! segment at a time, and each segment's rays (nearest hits, then shadow
//! rays) are sorted before they are cast, so that rays which will touch the
//! same nodes and triangles follow one another (Moon et al. 2010,
//! "Cache-Oblivious Ray Reordering"). Bounce and shadow rays from many beams
//! run every way through the scene; traced in the order they were made,
//! each one fetches its part of a large tree from memory anew.
//!
//! Paths are stepped by the same code as the depth-first estimator
//! (`path.rs`), with the same random numbers, so a batch comes out the same
//! bits in any order; only the time differs. Where it pays is measured
//! (`holodeck bench tracer`): on scenes whose structure is far larger than
//! the CPU's last-level cache, and batches of many thousands of paths.
//!
//! Never: used out of core (scene files batch their rays by the blocks
//! they wait for), or where a path's random numbers could depend on the order.

use glam::Vec3;

use super::hit::SurfaceHit;
use super::options::{last_level_cache_bytes, Reorder, AUTO_MIN_PATHS};
use super::path::{Direct, Path};
use super::rng::Rng;
use super::tracer::Tracer;
use crate::accel::RayOrder;
use crate::geom::Ray;
use crate::ooc::Fetch;

impl Tracer {
    /// Whether a batch of `paths` paths may be traced a segment at a time
    /// in sorted order: always where an order is asked for, and where
    /// [`Reorder::Auto`] measures whether it pays (a scene larger than the
    /// caches, a batch of at least [`AUTO_MIN_PATHS`]). In core only.
    pub fn may_reorder(&self, paths: usize) -> bool {
        if self.caster.file().is_some() || paths == 0 {
            return false;
        }
        match self.options.reorder {
            Reorder::Off => false,
            Reorder::HitPoint | Reorder::Origin => true,
            Reorder::Auto => paths >= AUTO_MIN_PATHS && self.exceeds_cache(),
        }
    }

    /// The order in which a batch of `paths` paths is traced a segment at
    /// a time (`None`: each path to its end), and whether the batch is to
    /// be timed for [`Reorder::Auto`]'s choice.
    pub(super) fn path_order_for(&self, paths: usize) -> (Option<RayOrder>, bool) {
        if !self.may_reorder(paths) {
            return (None, false);
        }
        match self.options.reorder {
            Reorder::Origin => (Some(RayOrder::Origin), false),
            Reorder::Auto => {
                let sorted = self.path_order.choose() == 0;
                (sorted.then_some(RayOrder::Origin), true)
            }
            _ => (Some(RayOrder::HitPoint), false),
        }
    }

    /// Whether the scene is in core and what rays walk through there (the
    /// structure and the mesh) is larger than the last-level cache: where
    /// [`Reorder::Auto`] sorts large batches, and callers gather them.
    pub fn exceeds_cache(&self) -> bool {
        self.caster.file().is_none() && self.in_core_bytes() > last_level_cache_bytes()
    }

    /// Traces `paths` (each with its random sequence and its first hit)
    /// together, a segment at a time, each segment's rays cast in `order`;
    /// their radiance and distance, in the paths' order. In core only.
    pub(super) fn trace_wavefront(
        &self,
        mut paths: Vec<Path>,
        mut rngs: Vec<Rng>,
        mut hits: Vec<Option<SurfaceHit>>,
        order: RayOrder,
    ) -> Vec<(Vec3, f32)> {
        let mut live: Vec<u32> = (0..paths.len() as u32).collect();
        let mut fetch = Fetch::load();
        // Shadow rays start on the surfaces the paths just hit: their
        // origins are their estimated hit points' neighbours already.
        let shadow_order = match order {
            RayOrder::AsGiven => RayOrder::AsGiven,
            _ => RayOrder::Origin,
        };
        loop {
            let mut next = Vec::with_capacity(live.len());
            let mut waiting: Vec<(u32, Direct)> = Vec::new();
            let mut direct = Direct::default();
            for (&i, hit) in live.iter().zip(hits) {
                let step = self.shade(&mut paths[i as usize], hit, &mut rngs[i as usize], &mut direct);
                self.look_straight_on(&mut paths[i as usize], &mut fetch);
                if step.direct {
                    waiting.push((i, direct));
                }
                if step.goes_on {
                    next.push(i);
                }
            }
            let shadows: Vec<Ray> = waiting
                .iter()
                .flat_map(|(_, d)| d.shadows.iter().flatten().map(|s| s.0))
                .collect();
            let mut seen = self
                .caster
                .in_order(&shadows, shadow_order, |r| self.visibility(*r, &mut fetch))
                .into_iter();
            for (i, d) in &waiting {
                paths[*i as usize].add_direct(d, |_| seen.next().unwrap_or(Vec3::ZERO));
            }
            if next.is_empty() {
                break;
            }
            live = next;
            let rays: Vec<Ray> = live.iter().map(|&i| paths[i as usize].ray).collect();
            hits = self.caster.in_order(&rays, order, |r| self.nearest(r, 0.0, &mut fetch));
        }
        paths.iter().map(Path::result).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{generate, GenParams};
    use crate::{FirstHits, TraceOptions};

    /// Rays from all over the room every way, as bounces from many beams
    /// would be: points on random triangles, directions at random.
    fn scattered(tracer: &Tracer, n: usize) -> Vec<(Vec3, Vec3)> {
        let scene = tracer.scene();
        let mut rng = Rng::new(3, 4);
        (0..n)
            .map(|_| {
                let t = (rng.next_u32() as usize) % scene.triangles.len();
                let [a, b, c] = scene.vertices(t);
                let (u, v) = rng.f32x2();
                let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
                let p = a + (b - a) * u + (c - a) * v;
                let d = Vec3::new(rng.f32() - 0.5, rng.f32() - 0.5, rng.f32() - 0.5);
                (p + d * 0.01, d)
            })
            .collect()
    }

    /// Every order gives every sample bit for bit, with several estimates
    /// per ray, deep paths, thin panes and mirrors, VDISTANCE on and off,
    /// and rays that cannot be traced among the rest.
    #[test]
    fn the_order_of_the_paths_changes_no_sample() {
        let room = generate("room", &GenParams::default()).unwrap();
        let mut tracer = Tracer::new(
            room,
            TraceOptions {
                samples: 2,
                max_bounces: 12,
                roulette_after: 6,
                ..TraceOptions::default()
            },
        );
        let mut rays = scattered(&tracer, 3000);
        rays[17] = (Vec3::NAN, Vec3::X);
        rays[400] = (Vec3::ONE, Vec3::ZERO);
        for vdistance in [false, true] {
            let mut want = None;
            for reorder in [Reorder::Off, Reorder::HitPoint, Reorder::Origin, Reorder::Auto] {
                tracer.options.reorder = reorder;
                for first in [FirstHits::Single, FirstHits::Packets] {
                    let got = tracer.trace_rays(&rays, vdistance, first, &mut Rng::new(9, 9));
                    assert_eq!(got.len(), rays.len());
                    assert!(got.iter().all(Option::is_some));
                    match &want {
                        None => want = Some(got),
                        Some(w) => assert!(*w == got, "{reorder:?} {first:?} vdistance {vdistance}"),
                    }
                }
            }
            let want = want.unwrap();
            let lit = want.iter().flatten().filter(|s| s.radiance.max_element() > 0.0).count();
            let hit = want.iter().flatten().filter(|s| s.distance.is_finite()).count();
            assert!(lit > 1500 && hit > 2500, "{lit} lit, {hit} hit");
            assert_eq!(want[17].unwrap().radiance, Vec3::ZERO);
            assert_eq!(want[400].unwrap().distance, f32::INFINITY);
        }
    }

    /// Through the room's window pane (nothing outside it) every sample
    /// reports the view straight on, the sky's infinite distance, also the
    /// paths the pane reflected back into the room; without virtual
    /// distances they report the pane. The reflected light still counts.
    #[test]
    fn a_window_reports_what_lies_straight_on_through_it() {
        let room = generate("room", &GenParams::default()).unwrap();
        let mut tracer = Tracer::new(room, TraceOptions::default());
        let rays: Vec<(Vec3, Vec3)> = (0..2000)
            .map(|i| {
                let (y, z) = (1.2 + (i % 40) as f32 * 0.04, 1.0 + (i / 40) as f32 * 0.02);
                (Vec3::new(4.5, y, z), Vec3::new(1.0, 0.05, -0.02).normalize())
            })
            .collect();
        for reorder in [Reorder::Off, Reorder::HitPoint] {
            tracer.options.reorder = reorder;
            let through = tracer.trace_rays(&rays, true, FirstHits::Single, &mut Rng::new(4, 4));
            assert!(
                through.iter().flatten().all(|s| s.distance == f32::INFINITY),
                "{reorder:?}"
            );
            let at_pane = tracer.trace_rays(&rays, false, FirstHits::Single, &mut Rng::new(4, 4));
            assert!(at_pane.iter().flatten().all(|s| (s.distance - 1.5).abs() < 0.01));
            // The same paths either way: the light is the same.
            let light = |v: &[Option<crate::Sample>]| v.iter().flatten().map(|s| s.radiance.x).sum::<f32>();
            assert!((light(&through) - light(&at_pane)).abs() <= 1e-3 * light(&at_pane));
        }
    }

    /// Samples do not depend on which other rays share their batch.
    #[test]
    fn a_ray_gets_its_sample_in_any_batch() {
        let room = generate("room", &GenParams::default()).unwrap();
        let mut tracer = Tracer::new(room, TraceOptions::default());
        let rays = scattered(&tracer, 500);
        tracer.options.reorder = Reorder::HitPoint;
        let all = tracer.trace_rays(&rays, false, FirstHits::Single, &mut Rng::new(1, 1));
        tracer.options.reorder = Reorder::Off;
        let first_half = tracer.trace_rays(&rays[..250], false, FirstHits::Single, &mut Rng::new(1, 1));
        assert_eq!(all[..250], first_half[..]);
    }

    /// Automatic reordering stays off where the scene fits in cache or the
    /// batch is small; forced orders apply to any batch.
    #[test]
    fn automatic_reordering_needs_a_large_scene_and_a_large_batch() {
        let room = generate("room", &GenParams::default()).unwrap();
        let mut tracer = Tracer::new(room, TraceOptions::default());
        assert!(tracer.in_core_bytes() > 100_000 && tracer.in_core_bytes() < last_level_cache_bytes());
        assert!(!tracer.exceeds_cache());
        assert_eq!(tracer.path_order_for(AUTO_MIN_PATHS * 4), (None, false));
        tracer.options.reorder = Reorder::HitPoint;
        assert_eq!(tracer.path_order_for(1), (Some(RayOrder::HitPoint), false));
        assert_eq!(tracer.path_order_for(0), (None, false));
        tracer.options.reorder = Reorder::Origin;
        assert_eq!(tracer.path_order_for(5), (Some(RayOrder::Origin), false));
        tracer.options.reorder = Reorder::Off;
        assert!(!tracer.may_reorder(AUTO_MIN_PATHS * 4));
        assert!(last_level_cache_bytes() >= 1 << 16);
    }

    #[test]
    fn orders_parse_by_name() {
        assert_eq!("auto".parse(), Ok(Reorder::Auto));
        assert_eq!("off".parse(), Ok(Reorder::Off));
        assert_eq!("hit-point".parse(), Ok(Reorder::HitPoint));
        assert_eq!("origin".parse(), Ok(Reorder::Origin));
        for r in [Reorder::Auto, Reorder::Off, Reorder::HitPoint, Reorder::Origin] {
            assert_eq!(r.to_string().parse(), Ok(r));
        }
        assert!("sideways".parse::<Reorder>().unwrap_err().contains("hit-point"));
    }
}
