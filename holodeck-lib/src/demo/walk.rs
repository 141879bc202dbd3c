//! The demo's walkthrough: a path through the furnished room toward its
//! window, and out across the clearing beyond it, looking around as a person
//! walking does, ending with a look back at the house. Every view's eye is
//! inside one of the landscape's two sections (the room's, and the one
//! outdoors), so the holodeck can serve it.

use glam::DVec3;
use holodeck_protocol::View;

/// The share of the walk spent inside the room.
const INSIDE: f64 = 0.55;

/// `n` views (at least one) along the path, evenly spaced in its parameter.
pub fn path(n: usize) -> Vec<View> {
    let n = n.max(1);
    (0..n)
        .map(|i| {
            let t = if n == 1 { 0.0 } else { i as f64 / (n - 1) as f64 };
            at(t)
        })
        .collect()
}

/// The view at `t` (0..=1) along the path.
fn at(t: f64) -> View {
    use std::f64::consts::PI;
    let smooth = |a: f64, b: f64, x: f64| {
        let u = ((x - a) / (b - a)).clamp(0.0, 1.0);
        u * u * (3.0 - 2.0 * u)
    };
    let (position, yaw_deg, pitch) = if t < INSIDE {
        // From the back of the room to just short of the window, weaving a
        // little and looking left and right.
        let s = t / INSIDE;
        (
            DVec3::new(0.8 + 4.5 * s, 2.0 + 0.3 * (2.0 * PI * s).sin(), 1.5),
            25.0 * (3.0 * PI * s).sin(),
            -0.1,
        )
    } else {
        // Outdoors, from just past the window out over the clearing, then
        // turning to look back at the house; looking 8.5 degrees down, so
        // the sun (25 degrees high) stays above the frame.
        let s = (t - INSIDE) / (1.0 - INSIDE);
        (
            DVec3::new(7.5 + 7.0 * s, 2.0 + 0.8 * (PI * s).sin(), 1.6),
            35.0 * (2.0 * PI * s).sin() + 160.0 * smooth(0.7, 1.0, s),
            -0.15,
        )
    };
    let (sy, cy) = yaw_deg.to_radians().sin_cos();
    View {
        position,
        direction: DVec3::new(cy, sy, pitch).normalize(),
        up: DVec3::Z,
        horizontal: 75.0,
        vertical: 56.0,
        ..View::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_path_starts_in_the_room_and_ends_outdoors_looking_back() {
        let views = path(32);
        assert_eq!(views.len(), 32);
        let inside = |v: &View| (0.5..5.5).contains(&v.position.x) && (0.5..3.5).contains(&v.position.y);
        let outside = |v: &View| (7.0..15.0).contains(&v.position.x) && (0.5..3.5).contains(&v.position.y);
        assert!(views.iter().all(|v| inside(v) || outside(v)));
        assert!(views.iter().all(|v| (1.2..2.2).contains(&v.position.z)));
        assert!(inside(&views[0]) && outside(&views[31]));
        assert!(views.iter().filter(|v| inside(v)).count() >= 16);
        // It ends looking back west, at the house.
        assert!(views[31].direction.x < -0.8, "{:?}", views[31].direction);
        // One view is the start of the walk.
        assert_eq!(path(1)[0].position, views[0].position);
    }
}
