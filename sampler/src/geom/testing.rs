//! Test helpers shared by the triangle tests.

use glam::Vec3;
use proptest::prelude::*;

/// Points where rays meet edges and vertices exactly (small integers and
/// halves), and anywhere.
pub(crate) fn vec3() -> impl Strategy<Value = Vec3> {
    prop_oneof![
        (-4i32..4, -4i32..4, -4i32..4).prop_map(|(x, y, z)| Vec3::new(x as f32, y as f32, z as f32) * 0.5),
        (-4f32..4.0, -4f32..4.0, -4f32..4.0).prop_map(|(x, y, z)| Vec3::new(x, y, z)),
    ]
}
