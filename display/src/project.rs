//! World points to frame pixels and back, with a view's constants made once:
//! every driver projects millions of samples per frame, and reprojection
//! turns each pixel's estimate back into a world point.

use glam::DVec3;
use holodeck_protocol::{ViewProjector, ViewRays, ViewType};

use crate::viewport::Viewport;

/// [`Viewport::pixel`] with the view's projector made once (the basis and
/// the tangents are not recomputed per point); the same arithmetic, so the
/// pixels agree exactly.
#[derive(Clone, Debug)]
pub struct Projector {
    view: ViewProjector,
    /// The angle one pixel spans at the frame's center, radians (for a
    /// parallel view: its width in world units).
    pixel_angle: f64,
    /// Eye and direction, for the direction an eye looks at a point along.
    eye: DVec3,
    direction: DVec3,
    parallel: bool,
    rays: ViewRays,
    width: u32,
    height: u32,
}

impl Projector {
    /// Precomputes the constants of `viewport`.
    pub fn new(viewport: &Viewport) -> Projector {
        let v = &viewport.view;
        let across = match v.kind {
            ViewType::Perspective => 2.0 * (v.horizontal.to_radians() / 2.0).tan(),
            ViewType::Angular => v.horizontal.to_radians(),
            ViewType::Hemispherical => 2.0 * (v.horizontal.to_radians() / 2.0).sin(),
            ViewType::Parallel => v.horizontal,
        };
        Projector {
            pixel_angle: across / f64::from(viewport.width.max(1)),
            view: viewport.view.projector(),
            eye: viewport.view.position,
            direction: viewport.view.direction.normalize(),
            parallel: viewport.view.kind == ViewType::Parallel,
            // Rays from the eye: depths are measured from it, fore clipping or not.
            rays: holodeck_protocol::View {
                fore: 0.0,
                ..viewport.view.clone()
            }
            .rays(),
            width: viewport.width,
            height: viewport.height,
        }
    }

    /// The pixel (column, row from the top) and depth of a world point, as
    /// [`Viewport::pixel`].
    #[inline]
    pub fn pixel(&self, p: DVec3) -> Option<(u32, u32, f64)> {
        self.locate(p).map(|(col, row, _, depth)| (col, row, depth))
    }

    /// [`Projector::pixel`] with where in the pixel the point falls (0..1
    /// across, 0..1 down).
    #[inline]
    pub fn locate(&self, p: DVec3) -> Option<(u32, u32, [f32; 2], f64)> {
        let (x, y, depth) = self.view.project(p)?;
        let (col, row, at) = self.place(x, y)?;
        Some((col, row, at, depth))
    }

    /// The view's projection constants.
    pub fn view(&self) -> &ViewProjector {
        &self.view
    }

    /// The pixel (column, row from the top) at view coordinates (`x`, `y`)
    /// (0..1 across, 0..1 up, as [`ViewProjector::project`] gives them) and
    /// where in it they fall (0..1 across, 0..1 down); `None` off the frame.
    #[inline]
    pub fn place(&self, x: f64, y: f64) -> Option<(u32, u32, [f32; 2])> {
        // A hand-built zero-sized viewport has no pixels to land on.
        if self.width == 0 || self.height == 0 || !(0.0..1.0).contains(&x) || !(0.0..1.0).contains(&y) {
            return None;
        }
        let (fx, fy) = (x * f64::from(self.width), (1.0 - y) * f64::from(self.height));
        let col = (fx as u32).min(self.width - 1);
        let row = (fy as u32).min(self.height - 1);
        let at = [
            (fx - f64::from(col)).clamp(0.0, 1.0) as f32,
            (fy - f64::from(row)).clamp(0.0, 1.0) as f32,
        ];
        Some((col, row, at))
    }

    /// The unit direction this view looks at world point `p` along, given
    /// its `depth` from [`Projector::pixel`]: from the eye, or the view
    /// direction in a parallel view.
    #[inline]
    pub fn look(&self, p: DVec3, depth: f64) -> DVec3 {
        if self.parallel {
            self.direction
        } else {
            (p - self.eye) / depth
        }
    }

    /// True for a parallel view (no eye point: every ray looks the same way).
    #[inline]
    pub fn is_parallel(&self) -> bool {
        self.parallel
    }

    /// The angle a pixel spans seen from a point at `depth`: what a ray must
    /// pass the eye within for its hit point to be trusted to the pixel
    /// (a hidden point shows at most that far from the edge hiding it).
    #[inline]
    pub fn pixel_angle(&self, depth: f64) -> f64 {
        if self.parallel {
            self.pixel_angle / depth.max(1e-300)
        } else {
            self.pixel_angle
        }
    }

    /// The ray through point `at` (0..1 across, down) of pixel (`col`,
    /// `row`): origin and unit direction, or `None` outside a fisheye's
    /// circle. A point at depth `d` (as [`Projector::pixel`] measures it)
    /// lies at `origin + direction * d`.
    #[inline]
    pub fn ray(&self, col: u32, row: u32, at: [f32; 2]) -> Option<(DVec3, DVec3)> {
        let x = (f64::from(col) + f64::from(at[0])) / f64::from(self.width.max(1));
        let y = 1.0 - (f64::from(row) + f64::from(at[1])) / f64::from(self.height.max(1));
        self.rays.ray(x, y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use holodeck_protocol::View;
    use proptest::prelude::*;

    fn viewport(spec: &str, width: u32, height: u32) -> Viewport {
        Viewport::new(View::parse(spec).unwrap(), width, height).unwrap()
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(128))]

        #[test]
        fn projector_matches_viewport_pixel(
            kind in 0usize..4,
            (h, v) in (1.0f64..179.0, 1.0f64..179.0),
            (dx, dz, sh, li) in (-1.0f64..1.0, -1.0f64..1.0, -0.5f64..0.5, -0.5f64..0.5),
            p in prop::array::uniform3(-10.0f64..10.0),
            (w, hh) in (1u32..300, 1u32..300),
        ) {
            let t = ["-vtv", "-vta", "-vth", "-vtl"][kind];
            let spec = format!("{t} -vp 0.5 -1 0.25 -vd {dx} 1 {dz} -vu 0 0 1 -vh {h} -vv {v} -vs {sh} -vl {li}");
            let vp = viewport(&spec, w, hh);
            let p = DVec3::from_array(p);
            prop_assert_eq!(Projector::new(&vp).pixel(p), vp.pixel(p));
        }

        #[test]
        fn a_point_in_a_pixel_at_its_depth_projects_back_to_it(
            kind in 0usize..4,
            (h, v) in (10.0f64..170.0, 10.0f64..170.0),
            (col, row) in (0u32..64, 0u32..48),
            at in prop::array::uniform2(0.01f32..0.99),
            depth in 0.5f64..100.0,
        ) {
            let t = ["-vtv", "-vta", "-vth", "-vtl"][kind];
            let vp = viewport(&format!("{t} -vp 1 2 0.5 -vd 1 0.2 0.1 -vu 0 0 1 -vh {h} -vv {v}"), 64, 48);
            let p = Projector::new(&vp);
            if let Some((o, d)) = p.ray(col, row, at) {
                let (c, r, back, z) = p.locate(o + d * depth).unwrap();
                prop_assert_eq!((c, r), (col, row));
                prop_assert!((back[0] - at[0]).abs() < 1e-4 && (back[1] - at[1]).abs() < 1e-4, "{:?} {:?}", back, at);
                prop_assert!((z - depth).abs() < 1e-6 * depth.max(1.0));
            }
        }
    }
}
