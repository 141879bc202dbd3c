//! The holodeck paper's input model (section 2.4.1) as view arithmetic, one
//! step per frame while a button is held:
//!
//! - moving forward brings the eye 10% closer to the point under the cursor,
//!   along the line to it, so the view direction is unchanged and the point
//!   stays under the cursor; backing away is the same step outward;
//! - orbiting swings the eye around the point under the cursor, turning the
//!   view with it, so the point again stays where it is on screen;
//! - rotating turns the view toward the cursor and keeps the eye in place
//!   (it needs no geometry under the cursor);
//! - a focus rectangle frames a part of the view as the next view.
//!
//! With the head height fixed, forward, backward and orbit steps keep the
//! eye's height along the view's up vector.

use glam::{DQuat, DVec3};
use holodeck_protocol::{Section, View, ViewType};

/// Where a display starts when it is given no view: at the center of
/// `section`, looking along its first axis, with a 75 by 56 degree
/// perspective frame and the world's z up.
pub fn default_view(section: &Section) -> View {
    let [x, y, z] = section.axes();
    let c = section.origin() + (x + y + z) * 0.5;
    let d = x.normalize_or_zero();
    View {
        kind: ViewType::Perspective,
        position: c,
        direction: d,
        up: DVec3::Z,
        horizontal: 75.0,
        vertical: 56.0,
        ..View::default()
    }
}

/// The fraction of the distance to the point under the cursor one forward
/// (or backward) step covers.
pub const MOVE_FRACTION: f64 = 0.1;

/// Most motion steps per second while a button is held (so that a fast
/// machine does not fly).
pub const STEP_RATE: f64 = 30.0;

/// Degrees one orbit step swings the eye around the point under the cursor.
pub const ORBIT_DEGREES: f64 = 5.0;

/// A point of the image: 0..1 across from the left, 0..1 up from the bottom
/// (Radiance's image coordinates).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ImagePoint {
    /// Across, from the left edge.
    pub x: f64,
    /// Up, from the bottom edge.
    pub y: f64,
}

impl ImagePoint {
    /// The image point of the center of window pixel (`col`, `row` from the
    /// top) in a `width` x `height` frame.
    pub fn of_pixel(col: f64, row: f64, width: u32, height: u32) -> ImagePoint {
        ImagePoint {
            x: (col + 0.5) / f64::from(width.max(1)),
            y: 1.0 - (row + 0.5) / f64::from(height.max(1)),
        }
    }
}

/// One frame's worth of motion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// Toward the point (left button).
    Forward,
    /// Away from the point (right button).
    Backward,
    /// Around the point, about the view's up vector, this many steps
    /// (positive: the eye swings to the right, seen from the eye).
    OrbitAcross(f64),
    /// Around the point, over or under it, this many steps (positive: up).
    OrbitOver(f64),
}

/// Applies `step` about `target` (the world point under the cursor);
/// `head` keeps the eye's height when set. `None` when the step makes no
/// valid view (the eye on the point, or looking straight along the up
/// vector).
pub fn step(view: &View, target: DVec3, step: Step, head_fixed: bool) -> Option<View> {
    let mut v = view.clone();
    let to_target = target - v.position;
    if to_target.length_squared() == 0.0 || !to_target.is_finite() {
        return None;
    }
    let up = v.up.try_normalize()?;
    match step {
        Step::Forward => v.position += to_target * MOVE_FRACTION,
        Step::Backward => v.position -= to_target * MOVE_FRACTION,
        Step::OrbitAcross(n) => {
            let spin = DQuat::from_axis_angle(up, -(ORBIT_DEGREES * n).to_radians());
            v.position = target - spin * to_target;
            v.direction = (spin * v.direction).normalize();
        }
        Step::OrbitOver(n) => {
            let axis = to_target.cross(up).try_normalize()?;
            // Positive steps swing the eye up over the point.
            let spin = DQuat::from_axis_angle(axis, -(ORBIT_DEGREES * n).to_radians());
            v.position = target - spin * to_target;
            v.direction = (spin * v.direction).normalize();
        }
    }
    if head_fixed {
        v.position += up * (view.position - v.position).dot(up);
    }
    valid(v)
}

/// Turns the view toward image point `at` (the eye stays): the direction
/// becomes the ray through it, as Radiance's rholo does while the middle
/// button is held.
pub fn turn_toward(view: &View, at: ImagePoint) -> Option<View> {
    let (_, dir) = view.ray(at.x, at.y)?;
    let mut v = view.clone();
    v.direction = dir.normalize();
    valid(v)
}

/// Turns the view `fraction` of the way toward image point `at` (the eye
/// stays): held on the middle button at [`super::app::STEP_RATE`] steps a
/// second with a fraction of one step's time, the view turns toward the
/// cursor as fast as the cursor is far from the center (24 degrees off:
/// 24 degrees a second), and stops turning when the cursor is centered.
pub fn turn_partly(view: &View, at: ImagePoint, fraction: f64) -> Option<View> {
    let (_, dir) = view.ray(at.x, at.y)?;
    let f = fraction.clamp(0.0, 1.0);
    let mut v = view.clone();
    v.direction = (view.direction * (1.0 - f) + dir.normalize() * f).normalize();
    valid(v)
}

/// The view that frames the rectangle between image points `a` and `b`:
/// its center becomes the view's center and the rectangle's larger side
/// (for the frame's `aspect`, width over height) fills the frame. Only
/// perspective views zoom; other kinds turn to the center.
pub fn frame(view: &View, a: ImagePoint, b: ImagePoint, aspect: f64) -> Option<View> {
    let center = ImagePoint {
        x: 0.5 * (a.x + b.x),
        y: 0.5 * (a.y + b.y),
    };
    let mut v = turn_toward(view, center)?;
    if view.kind == ViewType::Perspective {
        let (w, h) = ((a.x - b.x).abs(), (a.y - b.y).abs());
        if w == 0.0 || h == 0.0 {
            return Some(v);
        }
        let half = |fov: f64, part: f64| ((fov.to_radians() / 2.0).tan() * part).atan();
        let hh = half(view.horizontal, w);
        let hv = half(view.vertical, h);
        // The rectangle's aspect may differ from the frame's: keep all of it.
        let hh = hh.tan().max(hv.tan() * aspect).atan();
        v.horizontal = 2.0 * hh.to_degrees();
        v.vertical = 2.0 * (hh.tan() / aspect).atan().to_degrees();
    }
    valid(v)
}

/// `view` with its vertical field made to match a `width` x `height`
/// frame (the horizontal field is kept), as a window resize needs.
pub fn fit_aspect(view: &View, width: u32, height: u32) -> View {
    let mut v = view.clone();
    let aspect = f64::from(width.max(1)) / f64::from(height.max(1));
    v.vertical = match v.kind {
        ViewType::Perspective => 2.0 * ((v.horizontal.to_radians() / 2.0).tan() / aspect).atan().to_degrees(),
        _ => v.horizontal / aspect,
    };
    v
}

fn valid(v: View) -> Option<View> {
    let ok = v.position.is_finite()
        && v.direction.is_finite()
        && v.direction.length_squared() > 0.0
        && v.direction.cross(v.up).length_squared() > 1e-12;
    ok.then_some(v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn room() -> View {
        View::parse("-vtv -vp 1 2 1.5 -vd 1 0.2 0.1 -vu 0 0 1 -vh 60 -vv 45").unwrap()
    }

    /// Where `p` shows in `v` (0..1 image coordinates).
    fn shows(v: &View, p: DVec3) -> (f64, f64) {
        let (x, y, _) = v.project(p).unwrap();
        (x, y)
    }

    #[test]
    fn n_forward_steps_leave_ninety_percent_to_the_nth_and_the_point_in_place() {
        let v = room();
        let target = v.position + DVec3::new(4.0, 1.0, -0.5);
        let before = shows(&v, target);
        let mut w = v.clone();
        for _ in 0..7 {
            w = step(&w, target, Step::Forward, false).unwrap();
        }
        let left = (target - w.position).length() / (target - v.position).length();
        assert!((left - 0.9f64.powi(7)).abs() < 1e-12, "{left}");
        assert_eq!(w.direction, v.direction);
        let after = shows(&w, target);
        assert!((after.0 - before.0).abs() < 1e-12 && (after.1 - before.1).abs() < 1e-12);
        let back = step(&w, target, Step::Backward, false).unwrap();
        let ratio = (target - back.position).length() / (target - w.position).length();
        assert!((ratio - 1.1).abs() < 1e-12, "{ratio}");
    }

    #[test]
    fn orbiting_keeps_the_distance_and_the_point_on_screen() {
        let v = room();
        let target = v.position + DVec3::new(3.0, 0.5, -0.2);
        let before = shows(&v, target);
        // Over the point, the view keeps its up vector, so only a point on
        // the center line stays exactly in place: orbit about that one.
        let center = v.position + v.direction.normalize() * 3.0;
        let w = step(&v, center, Step::OrbitOver(2.0), false).unwrap();
        let (x, y) = shows(&w, center);
        assert!((x - 0.5).abs() < 1e-9 && (y - 0.5).abs() < 1e-9, "{x} {y}");
        assert!(w.position.z > v.position.z);
        for s in [Step::OrbitAcross(1.0), Step::OrbitAcross(-3.0)] {
            let w = step(&v, target, s, false).unwrap();
            let d = (target - w.position).length() - (target - v.position).length();
            assert!(d.abs() < 1e-9, "{s:?}: {d}");
            let after = shows(&w, target);
            assert!(
                (after.0 - before.0).abs() < 1e-9 && (after.1 - before.1).abs() < 1e-9,
                "{s:?}"
            );
            assert!(w.position.distance(v.position) > 0.01, "{s:?} moved the eye");
        }
        // An orbit across swings the eye by the step's angle about the point.
        let w = step(&v, target, Step::OrbitAcross(1.0), false).unwrap();
        let (a, b) = ((v.position - target).truncate(), (w.position - target).truncate());
        let turned = a.angle_to(b).abs().to_degrees();
        assert!((turned - ORBIT_DEGREES).abs() < 1e-9, "{turned}");
    }

    #[test]
    fn a_fixed_head_keeps_the_eye_height() {
        let v = room();
        let below = v.position + DVec3::new(3.0, 0.0, -1.4);
        let w = step(&v, below, Step::Forward, true).unwrap();
        assert!((w.position.z - v.position.z).abs() < 1e-12);
        assert!(w.position.x > v.position.x);
        let free = step(&v, below, Step::Forward, false).unwrap();
        assert!(free.position.z < v.position.z);
    }

    #[test]
    fn holding_the_turn_moves_a_little_each_step_not_the_whole_angle() {
        let v = View::parse("-vtv -vp 0 0 1 -vd 1 0 0 -vu 0 0 1 -vh 60 -vv 45").unwrap();
        // A point 24 degrees to the right of the center.
        let x = 0.5 + (24f64.to_radians().tan() / (30f64.to_radians().tan() * 2.0));
        let at = ImagePoint { x, y: 0.5 };
        let step = turn_partly(&v, at, 1.0 / 30.0).unwrap();
        let turned = v.direction.angle_between(step.direction).to_degrees();
        assert!(
            (turned - 0.8).abs() < 0.05,
            "one step of 1/30 s turns 0.8 degrees: {turned}"
        );
        // A second of steps turns about the offset, never a full spin.
        let mut w = v.clone();
        for _ in 0..30 {
            w = turn_partly(&w, at, 1.0 / 30.0).unwrap();
        }
        let total = v.direction.angle_between(w.direction).to_degrees();
        assert!((20.0..=26.0).contains(&total), "{total}");
        let centered = turn_partly(&v, ImagePoint { x: 0.5, y: 0.5 }, 1.0 / 30.0).unwrap();
        assert!(v.direction.angle_between(centered.direction) < 1e-12);
    }

    #[test]
    fn turning_toward_the_center_changes_nothing_and_toward_a_corner_looks_there() {
        let v = room();
        let same = turn_toward(&v, ImagePoint { x: 0.5, y: 0.5 }).unwrap();
        assert!(same.direction.distance(v.direction.normalize()) < 1e-12);
        let corner = ImagePoint { x: 0.9, y: 0.8 };
        let (_, ray) = v.ray(corner.x, corner.y).unwrap();
        let w = turn_toward(&v, corner).unwrap();
        assert_eq!(w.position, v.position);
        assert!(w.direction.distance(ray) < 1e-12);
    }

    #[test]
    fn framing_puts_the_rectangle_center_in_the_middle_and_narrows_the_field() {
        let v = room();
        let aspect = 4.0 / 3.0;
        let (a, b) = (ImagePoint { x: 0.6, y: 0.5 }, ImagePoint { x: 0.8, y: 0.65 });
        let w = frame(&v, a, b, aspect).unwrap();
        let (_, c) = v.ray(0.7, 0.575).unwrap();
        let p = v.position + c * 5.0;
        let (x, y) = shows(&w, p);
        assert!((x - 0.5).abs() < 1e-9 && (y - 0.5).abs() < 1e-9, "{x} {y}");
        assert!(w.horizontal < v.horizontal / 3.0, "{}", w.horizontal);
        let want = (w.horizontal.to_radians() / 2.0).tan() / (w.vertical.to_radians() / 2.0).tan();
        assert!((want - aspect).abs() < 1e-9);
    }

    proptest! {
        #[test]
        fn steps_keep_the_point_under_the_cursor(
            dx in -5.0..5.0f64, dy in -5.0..5.0f64, dz in -2.0..2.0f64, n in 0.2..3.0f64, which in 0..3usize
        ) {
            let v = room();
            let target = v.position + DVec3::new(3.0 + dx.abs(), dy, dz);
            let before = v.project(target);
            prop_assume!(before.is_some());
            let s = [Step::Forward, Step::Backward, Step::OrbitAcross(n)][which];
            if let Some(w) = step(&v, target, s, false) {
                let (b, a) = (before.unwrap(), w.project(target).unwrap());
                prop_assert!((a.0 - b.0).abs() < 1e-7 && (a.1 - b.1).abs() < 1e-7);
            }
        }
    }
}
