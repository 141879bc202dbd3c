//! One pixel's running estimate of the radiance an eye sees there, built from
//! every ray that lands on the pixel's nearest surface, in constant memory.
//!
//! Three rules make it converge where the paper's one-sample-per-pixel rule
//! cannot (our rays are single path-traced estimates, not smooth irradiance
//! cached values):
//!
//! * **Depth clustering.** An estimate covers one surface: the depth range of
//!   the rays in it, grown by each ray within [`EstimatorOptions::depth_tolerance`]
//!   of it (so a surface seen at a grazing angle, whose depth varies across
//!   the pixel, stays one cluster). A ray wholly in front starts the estimate
//!   afresh (the earlier rays hit something this one passes in front of: a
//!   surface hidden from the eye); a ray wholly behind is left out (it passed
//!   behind a silhouette or through a window the eye does not look through).
//! * **Weights by direction.** A ray that reached the surface from a direction
//!   near the eye's weighs more: `1 / (1 + (θ/θ₀)²)` for the angle θ between
//!   the two seen from the hit point. Diffuse surfaces do not care; glossy ones
//!   do, and θ₀ = [`EstimatorOptions::angle_scale`] trades their bias against
//!   the variance that unequal weights cost.
//! * **History kept apart.** A view change turns the estimate's rays into
//!   history; when the new view's rays disagree with it beyond their noise
//!   (a mirror, glass or a glossy finish seen from elsewhere), they alone
//!   make the estimate.
//! * **Fireflies spread, not dropped.** The brightest ray (by luminance) is
//!   kept apart from the running sums. When the estimate is read, it counts
//!   at most [`EstimatorOptions::firefly_ratio`] times the mean of the others,
//!   or of a reference the caller gives (the neighborhood's mean, so that an
//!   estimate of few rays is judged too), and what is cut off is handed back
//!   as the estimate's *excess*, which the store spreads over the estimates
//!   around it ([`EstimatorOptions::firefly_spread`]): an isolated firefly
//!   becomes a faint glow over its neighborhood, and no light is lost. (Dropping
//!   the excess, as a plain winsorized mean does, is a bias that falls on the
//!   darkest regions, lit by rare bright rays: half their light in a room lit
//!   through a blind; it is measured in `docs/DISPLAY.md`.) The brightest ray
//!   stays apart across view changes, as history, so a firefly never joins the
//!   sums whole.

/// Rays per estimate kept apart from the running sums as firefly candidates.
pub const TOPS: usize = 1;

/// Rec. 709 luminance of linear RGB.
#[inline]
pub fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// How rays combine into a pixel's estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EstimatorOptions {
    /// Rays whose depths differ by more than this fraction are on different
    /// surfaces (the paper's 2%).
    pub depth_tolerance: f32,
    /// θ₀ of the direction weight, radians; infinity weighs every ray alike.
    pub angle_scale: f32,
    /// The brightest rays count at most this many times the mean of the rest
    /// (infinity: as they are); what is cut off is spread around.
    pub firefly_ratio: f32,
    /// Radius in pixels of the square over which the light cut off the
    /// brightest rays is spread, among the estimates there (0 drops it: a
    /// winsorized mean, which loses light where it is scarce).
    pub firefly_spread: f32,
    /// Estimates per pixel along each axis (1, 2 or 4; 0 picks by frame
    /// size: 4 up to 256 x 256 pixels, 2 up to 512 x 512, 1 above, so that
    /// a frame holds at most about a million estimates): rays that passed
    /// within a sub-pixel's angle of the eye are clustered by depth on this
    /// finer grid, so that at a silhouette the surfaces in front and behind
    /// each keep their part of the pixel (pixels are then the mean of their
    /// sub-pixels). Rays from farther may hit points the eye does not see
    /// beside an edge, so they must also not be behind their pixel's
    /// nearest surface.
    pub subpixels: u32,
}

impl Default for EstimatorOptions {
    fn default() -> Self {
        EstimatorOptions {
            depth_tolerance: 0.02,
            angle_scale: 1f32.to_radians(),
            firefly_ratio: 4.0,
            firefly_spread: 3.0,
            subpixels: 0,
        }
    }
}

impl EstimatorOptions {
    /// The weight of a ray that reached its hit point at `cos` (cosine of
    /// the angle) from the direction the eye looks at it along.
    #[inline]
    pub fn weight(&self, cos: f64) -> f32 {
        // 2 (1 - cos θ) is θ² to fourth order, and needs no arccosine.
        let theta2 = (2.0 * (1.0 - cos.clamp(-1.0, 1.0))) as f32;
        let s = self.angle_scale;
        let w = 1.0 / (1.0 + theta2 / (s * s));
        // An infinite scale weighs alike (0/inf); never let a weight vanish.
        if w.is_nan() {
            1.0
        } else {
            w.max(1e-6)
        }
    }
}

/// Where a ray (or a group of them) stands against an estimate's surface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fit {
    /// On the same surface: it joins.
    Joins,
    /// Wholly in front: it replaces the estimate.
    Nearer,
    /// Wholly behind: it is left out.
    Behind,
}

/// A firefly candidate: one ray kept out of the sums.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Top {
    color: [f32; 3],
    weight: f32,
    /// Its luminance; negative for an empty slot, so any ray ranks above it.
    luma: f32,
    /// It came from an earlier view (it belongs with the history).
    history: bool,
}

impl Top {
    const EMPTY: Top = Top {
        color: [0.0; 3],
        weight: 0.0,
        luma: -1.0,
        history: false,
    };

    fn used(&self) -> bool {
        self.luma >= 0.0
    }
}

/// Weighted running sums of some rays: color, weight, squared luminance
/// (for their variance) and count.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Sums {
    sum: [f32; 3],
    weight: f32,
    lsq: f32,
    count: u32,
}

impl Sums {
    #[inline]
    fn add(&mut self, color: [f32; 3], weight: f32, luma: f32) {
        for (s, c) in self.sum.iter_mut().zip(color) {
            *s += c * weight;
        }
        self.weight += weight;
        self.lsq += weight * luma * luma;
        self.count += 1;
    }

    fn merge(&mut self, o: &Sums) {
        for (s, c) in self.sum.iter_mut().zip(o.sum) {
            *s += c;
        }
        self.weight += o.weight;
        self.lsq += o.lsq;
        self.count += o.count;
    }

    /// Mean luminance and the variance of the rays' luminance.
    fn moments(&self) -> Option<(f32, f32)> {
        (self.weight > 0.0).then(|| {
            let mean = luminance(self.sum) / self.weight;
            (mean, (self.lsq / self.weight - mean * mean).max(0.0))
        })
    }
}

/// Fresh rays needed before a view's rays can overrule the estimate brought
/// from earlier views.
const MIN_FRESH: u32 = 4;

/// How many standard errors apart the fresh rays and the history must be to
/// overrule it.
const HISTORY_Z: f32 = 3.0;

/// Differences below this fraction of the mean never overrule the history:
/// noise-free surfaces differ by the rays' quantization, and a glossy
/// finish that changes by a few percent for a step of the eye is not worth
/// tracing again (at 5% the walkthrough benchmark saw some views never
/// reach their target, see docs/DISPLAY.md).
const HISTORY_SLACK: f32 = 0.1;

/// A pixel's estimate: weighted running sums of the rays since the last view
/// change and of those brought from earlier views (the history), the
/// brightest fresh rays apart, and the depth range of the surface they hit.
///
/// The history is kept apart because a surface may look different from the
/// new eye (a mirror, glass, a glossy finish): when the fresh rays disagree
/// with it beyond their noise, the estimate uses the fresh rays alone, as
/// temporal reprojection in real-time renderers rejects stale history.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    /// Rays since the last view change, but the `tops`.
    fresh: Sums,
    /// Rays from before the last view change, reprojected.
    history: Sums,
    /// The brightest fresh rays, brightest first.
    tops: [Top; TOPS],
    /// Sum of the rays' depths (for the mean: where the surface is).
    depth_sum: f32,
    /// Sum of the rays' positions within the pixel (0..1 across and down):
    /// with the mean depth, the centroid that reprojection moves.
    at_sum: [f32; 2],
    /// Nearest and farthest depth of the rays.
    near: f32,
    far: f32,
}

impl Estimate {
    /// The estimate of one ray of `color`, `weight` and `depth`, at `at`
    /// within its pixel.
    #[inline]
    pub fn of_ray(color: [f32; 3], weight: f32, depth: f32, at: [f32; 2]) -> Estimate {
        let mut tops = [Top::EMPTY; TOPS];
        tops[0] = Top {
            color,
            weight,
            luma: luminance(color),
            history: false,
        };
        Estimate {
            fresh: Sums::default(),
            history: Sums::default(),
            tops,
            depth_sum: depth,
            at_sum: at,
            near: depth,
            far: depth,
        }
    }

    /// Where rays spanning depths `near..=far` stand against this surface.
    #[inline]
    pub fn fit(&self, near: f32, far: f32, tolerance: f32) -> Fit {
        if far < self.near * (1.0 - tolerance) {
            Fit::Nearer
        } else if near > self.far * (1.0 + tolerance) {
            Fit::Behind
        } else {
            Fit::Joins
        }
    }

    /// Adds one ray on this surface, at `at` within the pixel.
    #[inline]
    pub fn add_ray(&mut self, color: [f32; 3], weight: f32, depth: f32, at: [f32; 2]) {
        self.depth_sum += depth;
        self.at_sum[0] += at[0];
        self.at_sum[1] += at[1];
        self.near = self.near.min(depth);
        self.far = self.far.max(depth);
        self.add_top(Top {
            color,
            weight,
            luma: luminance(color),
            history: false,
        });
    }

    /// Ranks a ray among the firefly candidates: the one that drops out (it,
    /// or the dimmest candidate) joins the sums it belongs with.
    #[inline]
    fn add_top(&mut self, t: Top) {
        let out = if t.luma > self.tops[TOPS - 1].luma {
            let out = self.tops[TOPS - 1];
            let mut at = TOPS - 1;
            while at > 0 && self.tops[at - 1].luma < t.luma {
                self.tops[at] = self.tops[at - 1];
                at -= 1;
            }
            self.tops[at] = t;
            out
        } else {
            t
        };
        if out.used() {
            let sums = if out.history {
                &mut self.history
            } else {
                &mut self.fresh
            };
            sums.add(out.color, out.weight, out.luma);
        }
    }

    /// Adds another estimate of the same surface.
    pub fn merge(&mut self, other: &Estimate) {
        self.depth_sum += other.depth_sum;
        self.at_sum[0] += other.at_sum[0];
        self.at_sum[1] += other.at_sum[1];
        self.near = self.near.min(other.near);
        self.far = self.far.max(other.far);
        self.fresh.merge(&other.fresh);
        self.history.merge(&other.history);
        for t in other.tops {
            if t.used() {
                self.add_top(t);
            }
        }
    }

    /// Turns every ray into history (the view changes). The firefly
    /// candidates stay apart, as history, so that a firefly is still judged
    /// (and spread) from the new view and never joins the sums whole.
    pub fn settle(&mut self) {
        for t in &mut self.tops {
            t.history = true;
        }
        let fresh = std::mem::take(&mut self.fresh);
        self.history.merge(&fresh);
    }

    fn top_count(&self) -> u32 {
        self.tops.iter().filter(|t| t.used()).count() as u32
    }

    /// The firefly candidates that count now: all of them, or only the
    /// fresh ones when the fresh rays overrule the history.
    fn live_tops(&self, history_rejected: bool) -> impl Iterator<Item = &Top> {
        self.tops
            .iter()
            .filter(move |t| t.used() && !(history_rejected && t.history))
    }

    /// Rays in the estimate.
    pub fn count(&self) -> u32 {
        self.fresh.count + self.history.count + self.top_count()
    }

    /// Their total weight.
    pub fn weight(&self) -> f32 {
        self.fresh.weight + self.history.weight + self.tops.iter().map(|t| t.weight).sum::<f32>()
    }

    /// Mean depth of its rays (infinite for rays that escaped).
    pub fn depth(&self) -> f32 {
        self.depth_sum / self.count().max(1) as f32
    }

    /// Where its rays are on average within the pixel (0..1 across, down).
    pub fn centroid(&self) -> [f32; 2] {
        let n = self.count().max(1) as f32;
        [self.at_sum[0] / n, self.at_sum[1] / n]
    }

    /// Moves the centroid to `at` within a (new) pixel.
    pub fn move_to(&mut self, at: [f32; 2]) {
        let n = self.count() as f32;
        self.at_sum = [at[0] * n, at[1] * n];
    }

    /// Nearest and farthest depth of its rays.
    pub fn depth_range(&self) -> (f32, f32) {
        (self.near, self.far)
    }

    /// The rays that make the estimate now, but the firefly candidates:
    /// the fresh rays with the history, or without it when they disagree.
    fn body(&self) -> Sums {
        if self.history.count == 0 {
            return self.fresh;
        }
        if self.fresh.count >= MIN_FRESH {
            if let (Some((mf, vf)), Some((mh, vh))) = (self.fresh.moments(), self.history.moments()) {
                let se2 = vf / self.fresh.count as f32 + vh / self.history.count as f32;
                let slack = HISTORY_SLACK * mf.max(mh);
                let d = mf - mh;
                if d * d > HISTORY_Z * HISTORY_Z * se2 + slack * slack {
                    return self.fresh;
                }
            }
        }
        let mut b = self.fresh;
        b.merge(&self.history);
        b
    }

    /// True when the fresh rays overrule the history.
    pub fn history_rejected(&self) -> bool {
        self.history.count > 0 && self.body().count == self.fresh.count
    }

    /// The body and whether it left the history out.
    fn body_and_rejection(&self) -> (Sums, bool) {
        let b = self.body();
        (b, self.history.count > 0 && b.count == self.fresh.count)
    }

    /// Luminance of the mean of the rays in the body (not the brightest):
    /// what fireflies are judged against. `None` before there are any.
    pub fn body_luminance(&self) -> Option<f32> {
        self.body().moments().map(|m| m.0)
    }

    /// The weighted color sum and weight of the body: what a neighborhood's
    /// typical value is made of.
    pub fn body_sums(&self) -> ([f32; 3], f32) {
        let b = self.body();
        (b.sum, b.weight)
    }

    /// What the body says about the pixel's noise: its rays' weight, their
    /// weighted luminance sum and squared-luminance sum, and how many rays
    /// count in the estimate (the firefly candidates too).
    pub fn noise(&self) -> (f32, f32, f32, u32) {
        let b = self.body();
        (b.weight, luminance(b.sum), b.lsq, b.count + self.top_count())
    }

    /// Moves the surface to mean depth `depth` (reprojection into another
    /// view), keeping the depth range's proportions.
    pub fn move_to_depth(&mut self, depth: f32) {
        let mean = self.depth();
        if !(mean.is_finite() && mean > 0.0 && depth.is_finite()) {
            return;
        }
        let f = depth / mean;
        self.depth_sum *= f;
        self.near *= f;
        self.far *= f;
    }

    /// The estimate, with each firefly candidate counted at most `ratio`
    /// times the larger of the luminance of the other rays' mean and
    /// `reference` (what the neighborhood says is typical), and the excess:
    /// what was cut off, in the same units (the value plus the excess is
    /// the mean of the rays that count). With neither a mean nor a reference
    /// (a single ray and no reference) nothing can be judged and nothing is
    /// cut.
    pub fn value(&self, ratio: f32, reference: f32) -> ([f32; 3], [f32; 3]) {
        let (body, rejected) = self.body_and_rejection();
        let own = body.moments().map(|m| m.0);
        let limit = if own.is_none() && reference <= 0.0 {
            f32::INFINITY
        } else {
            ratio * own.unwrap_or(0.0).max(reference)
        };
        let (mut sum, mut weight, mut cut) = (body.sum, body.weight, [0.0f32; 3]);
        for t in self.live_tops(rejected) {
            let f = if t.luma > limit { limit / t.luma } else { 1.0 };
            for k in 0..3 {
                sum[k] += t.color[k] * f * t.weight;
                cut[k] += t.color[k] * (1.0 - f) * t.weight;
            }
            weight += t.weight;
        }
        if weight > 0.0 {
            (sum.map(|s| s / weight), cut.map(|c| c / weight))
        } else {
            ([0.0; 3], [0.0; 3])
        }
    }

    /// The plain weighted mean of every ray, nothing cut, history and all.
    pub fn mean(&self) -> [f32; 3] {
        let mut b = self.fresh;
        b.merge(&self.history);
        for t in self.tops.iter().filter(|t| t.used()) {
            b.add(t.color, t.weight, t.luma);
        }
        if b.weight > 0.0 {
            b.sum.map(|s| s / b.weight)
        } else {
            [0.0; 3]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const TOL: f32 = 0.02;
    /// The middle of a pixel.
    const C: [f32; 2] = [0.5, 0.5];

    fn close(a: [f32; 3], b: [f32; 3], eps: f32) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() <= eps * (1.0 + y.abs()))
    }

    #[test]
    fn equal_weights_give_the_plain_mean() {
        let mut e = Estimate::of_ray([1.0, 2.0, 3.0], 1.0, 5.0, C);
        e.add_ray([3.0, 2.0, 1.0], 1.0, 5.05, C);
        e.add_ray([2.0, 2.0, 2.0], 1.0, 4.95, C);
        assert_eq!(e.count(), 3);
        assert!(close(e.mean(), [2.0, 2.0, 2.0], 1e-6), "{:?}", e.mean());
        assert!((e.depth() - 5.0).abs() < 1e-5);
        assert_eq!(e.depth_range(), (4.95, 5.05));
        // Nothing is a firefly here.
        assert_eq!(e.value(10.0, 0.0), (e.mean(), [0.0; 3]));
    }

    #[test]
    fn the_centroid_is_the_mean_position_and_moves_whole() {
        let mut e = Estimate::of_ray([1.0; 3], 1.0, 2.0, [0.1, 0.2]);
        e.add_ray([1.0; 3], 5.0, 2.0, [0.3, 0.8]);
        let [x, y] = e.centroid();
        assert!((x - 0.2).abs() < 1e-6 && (y - 0.5).abs() < 1e-6, "unweighted: {x} {y}");
        e.move_to([0.9, 0.1]);
        assert_eq!(e.centroid(), [0.9, 0.1]);
        let mut f = Estimate::of_ray([1.0; 3], 1.0, 2.0, [0.5, 0.5]);
        f.merge(&e);
        let [x, y] = f.centroid();
        assert!((x - (0.5 + 1.8) / 3.0).abs() < 1e-6 && (y - (0.5 + 0.2) / 3.0).abs() < 1e-6);
    }

    #[test]
    fn history_stays_while_fresh_rays_agree_and_goes_when_they_do_not() {
        let mut rng = 12345u64;
        let mut noise = || {
            rng = rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            0.8 + 0.4 * ((rng >> 33) as f32 / (1u64 << 31) as f32)
        };
        let mut e = Estimate::of_ray([1.0; 3], 1.0, 2.0, C);
        for _ in 0..60 {
            e.add_ray([noise(); 3], 1.0, 2.0, C);
        }
        e.settle();
        assert_eq!((e.count(), e.history_rejected()), (61, false));
        // The same surface from the new eye: everything counts.
        let mut same = e;
        for _ in 0..8 {
            same.add_ray([noise(); 3], 1.0, 2.0, C);
        }
        assert!(!same.history_rejected());
        assert!(close(same.value(10.0, 0.0).0, same.mean(), 1e-5));
        // A mirror: from the new eye it shows something three times brighter.
        let mut mirror = e;
        for _ in 0..3 {
            mirror.add_ray([3.0 * noise(); 3], 1.0, 2.0, C);
        }
        assert!(!mirror.history_rejected(), "too few fresh rays to judge");
        for _ in 0..5 {
            mirror.add_ray([3.0 * noise(); 3], 1.0, 2.0, C);
        }
        assert!(mirror.history_rejected());
        let v = mirror.value(10.0, 0.0).0;
        assert!((v[0] - 3.0).abs() < 0.3, "{v:?}");
        assert!(mirror.mean()[0] < 1.5, "the plain mean is still the old view's");
    }

    #[test]
    fn a_firefly_stays_apart_across_a_view_change_and_goes_with_its_history() {
        let mut e = Estimate::of_ray([0.5; 3], 1.0, 1.0, C);
        for _ in 0..9 {
            e.add_ray([0.5; 3], 1.0, 1.0, C);
        }
        e.add_ray([1e4; 3], 1.0, 1.0, C);
        let before = e.value(10.0, 0.0);
        e.settle();
        assert_eq!(e.count(), 11);
        // Still cut the same, and the cut is still handed back whole.
        let after = e.value(10.0, 0.0);
        assert!(close(after.0, before.0, 1e-5) && close(after.1, before.1, 1e-5));
        assert!(close(e.mean(), [after.0[0] + after.1[0]; 3], 1e-5));
        // New rays from the new eye that disagree overrule the history, the
        // firefly with it.
        for _ in 0..8 {
            e.add_ray([3.0; 3], 1.0, 1.0, C);
        }
        assert!(e.history_rejected());
        let (v, excess) = e.value(10.0, 0.0);
        assert!(close(v, [3.0; 3], 1e-5) && excess == [0.0; 3], "{v:?} {excess:?}");
    }

    #[test]
    fn weights_weigh() {
        let mut e = Estimate::of_ray([1.0; 3], 3.0, 1.0, C);
        e.add_ray([5.0; 3], 1.0, 1.0, C);
        assert!(close(e.mean(), [2.0; 3], 1e-6));
        assert!((e.weight() - 4.0).abs() < 1e-6);
    }

    #[test]
    fn depth_fit_follows_the_nearest_surface_and_grows_along_it() {
        let e = Estimate::of_ray([1.0; 3], 1.0, 2.0, C);
        assert_eq!(e.fit(2.03, 2.03, TOL), Fit::Joins);
        assert_eq!(e.fit(1.97, 1.97, TOL), Fit::Joins);
        assert_eq!(e.fit(2.1, 2.1, TOL), Fit::Behind);
        assert_eq!(e.fit(1.9, 1.9, TOL), Fit::Nearer);
        // A slanted surface chains: each ray within 2% of the range so far.
        let mut e = e;
        for d in [2.03, 2.06, 2.09, 2.12] {
            assert_eq!(e.fit(d, d, TOL), Fit::Joins, "{d}");
            e.add_ray([1.0; 3], 1.0, d, C);
        }
        assert_eq!(e.depth_range(), (2.0, 2.12));
        // Escaped rays (infinite depth) are behind every surface and join each other.
        assert_eq!(e.fit(f32::INFINITY, f32::INFINITY, TOL), Fit::Behind);
        let sky = Estimate::of_ray([1.0; 3], 1.0, f32::INFINITY, C);
        assert_eq!(sky.fit(f32::INFINITY, f32::INFINITY, TOL), Fit::Joins);
        assert_eq!(sky.fit(100.0, 100.0, TOL), Fit::Nearer);
        assert_eq!(sky.depth(), f32::INFINITY);
    }

    #[test]
    fn one_firefly_among_many_rays_is_cut_to_the_ratio() {
        let mut e = Estimate::of_ray([0.5; 3], 1.0, 1.0, C);
        for _ in 0..98 {
            e.add_ray([0.5; 3], 1.0, 1.0, C);
        }
        e.add_ray([1e5; 3], 1.0, 1.0, C);
        let (v, excess) = e.value(10.0, 0.0);
        // 99 rays of 0.5 and one counted as 10 x 0.5; the rest is the excess.
        assert!(close(v, [(99.0 * 0.5 + 5.0) / 100.0; 3], 1e-5), "{v:?}");
        assert!(close(excess, [(1e5 - 5.0) / 100.0; 3], 1e-5), "{excess:?}");
        // The plain mean would be a white pixel.
        assert!(e.mean()[0] > 900.0);
    }

    #[test]
    fn a_dark_surface_keeps_its_rare_bright_ray_above_the_floor() {
        // Nine black rays and one lit: without a floor the lit ray looks like
        // a firefly against a black mean.
        let mut e = Estimate::of_ray([0.0; 3], 1.0, 1.0, C);
        for _ in 0..8 {
            e.add_ray([0.0; 3], 1.0, 1.0, C);
        }
        e.add_ray([0.4; 3], 1.0, 1.0, C);
        assert_eq!(e.value(10.0, 0.0).0, [0.0; 3]);
        let (v, excess) = e.value(10.0, 0.05);
        assert_eq!(excess, [0.0; 3]);
        assert!(close(v, [0.04; 3], 1e-5));
    }

    #[test]
    fn a_single_ray_is_judged_by_its_neighborhood_alone() {
        let e = Estimate::of_ray([1e4; 3], 1.0, 1.0, C);
        assert_eq!(
            e.value(10.0, 0.0),
            ([1e4; 3], [0.0; 3]),
            "no reference: nothing to judge"
        );
        let (v, excess) = e.value(10.0, 0.5);
        assert!(close(v, [5.0; 3], 1e-5) && close(excess, [1e4 - 5.0; 3], 1e-5), "{v:?}");
    }

    #[test]
    fn escaped_rays_move_nowhere_and_finite_ones_keep_proportions() {
        let mut sky = Estimate::of_ray([1.0; 3], 1.0, f32::INFINITY, C);
        sky.move_to_depth(3.0);
        assert_eq!(sky.depth(), f32::INFINITY);
        let mut e = Estimate::of_ray([1.0; 3], 1.0, 2.0, C);
        e.add_ray([1.0; 3], 1.0, 2.2, C);
        e.move_to_depth(4.2);
        assert!((e.depth() - 4.2).abs() < 1e-5);
        let (n, f) = e.depth_range();
        assert!((n - 4.0).abs() < 1e-5 && (f - 4.4).abs() < 1e-5);
    }

    #[test]
    fn weights_fall_with_the_angle() {
        let o = EstimatorOptions::default();
        assert_eq!(o.weight(1.0), 1.0);
        let at = |deg: f64| o.weight(deg.to_radians().cos());
        assert!((at(o.angle_scale.to_degrees() as f64) - 0.5).abs() < 1e-3);
        assert!(at(1.0) > at(5.0) && at(5.0) > at(30.0));
        let flat = EstimatorOptions {
            angle_scale: f32::INFINITY,
            ..o
        };
        assert_eq!(flat.weight(0.5), 1.0);
        assert!(o.weight(-1.0) > 0.0);
    }

    proptest! {
        /// Merging estimates is adding their rays: whatever the grouping,
        /// the same mean, count, depths and firefly candidates.
        #[test]
        fn merging_groups_equals_adding_rays(
            // Floats drawn on fixed grids: proptest's own sampler of narrow
            // float ranges (1.0..1.01) can trip its internal checks.
            rays in prop::collection::vec(
                (
                    (0u32..100_000).prop_map(|x| x as f32 * 1e-4),
                    (1_000u32..20_000).prop_map(|x| x as f32 * 1e-4),
                    (0u32..10_000).prop_map(|x| 1.0 + x as f32 * 1e-6),
                    prop::bool::ANY,
                ),
                1..60,
            ),
            cut in 0usize..60,
        ) {
            let mk = |r: &[(f32, f32, f32, bool)]| {
                let c = |x: f32, hot: bool| if hot { [x * 100.0, x, x] } else { [x; 3] };
                let mut e = Estimate::of_ray(c(r[0].0, r[0].3), r[0].1, r[0].2, C);
                for &(x, w, d, hot) in &r[1..] {
                    e.add_ray(c(x, hot), w, d, C);
                }
                e
            };
            let all = mk(&rays);
            let cut = cut.min(rays.len() - 1).max(1);
            if cut < rays.len() {
                let mut a = mk(&rays[..cut]);
                a.merge(&mk(&rays[cut..]));
                prop_assert_eq!(a.count(), all.count());
                prop_assert!(close(a.mean(), all.mean(), 1e-4));
                prop_assert!(close(a.value(4.0, 0.0).0, all.value(4.0, 0.0).0, 1e-4));
                prop_assert_eq!(a.depth_range(), all.depth_range());
                prop_assert!((a.weight() - all.weight()).abs() <= 1e-4 * all.weight());
                // The noise the denoiser and the requests read: the body's
                // squared luminance (the variance term) merges too.
                let (na, nall) = (a.noise(), all.noise());
                prop_assert!((na.0 - nall.0).abs() <= 1e-4 * nall.0.max(1e-3), "{:?} {:?}", na, nall);
                prop_assert!((na.2 - nall.2).abs() <= 1e-3 * nall.2.max(1e-3), "{:?} {:?}", na, nall);
                prop_assert_eq!(na.3, nall.3);
            }
        }

        /// The robust value never exceeds the plain mean, and with the
        /// excess it is the plain mean: nothing is lost.
        #[test]
        fn cutting_only_lowers(rays in prop::collection::vec((0.0f32..1e4, 0.1f32..2.0), 1..40), ratio in 1.0f32..50.0) {
            let mut e = Estimate::of_ray([rays[0].0; 3], rays[0].1, 1.0, C);
            for &(x, w) in &rays[1..] {
                e.add_ray([x; 3], w, 1.0, C);
            }
            let (v, excess) = e.value(ratio, 0.0);
            let m = e.mean();
            prop_assert!(v[0] <= m[0] * (1.0 + 1e-5) + 1e-6);
            prop_assert!(excess[0] >= 0.0);
            prop_assert!(close([v[0] + excess[0]; 3], m, 1e-4));
        }
    }
}
