//! The arcade: a 12 x 12 m courtyard open to the sky, ringed by a 3 m deep
//! covered walkway (18 x 18 m outside, roof slab 4 to 4.3 m high) whose
//! inner edge stands on square columns every 2 m. A low fountain basin sits
//! in the middle of the courtyard.
//!
//! Lighting: the sun stands 45° high in the east (+x), so it lights most of
//! the courtyard floor and reaches under the west walkway's roof, while the
//! east walkway stays in the shade of its own roof and outer wall: there
//! everything the eye sees is lit by the sky through the courtyard and by
//! light the sunlit stone throws back, the lighting of real arcades and
//! cloisters. Its interior section runs along the east walkway.

use glam::Vec3;
use holodeck_protocol::SectionKind;

use super::shapes::MeshBuf;
use super::{material, section_error, GenParams, Setting};
use crate::error::SceneError;
use crate::scene::builder::SceneBuilder;
use crate::scene::material::{Material, Sky};
use crate::scene::section::box_section;

/// Outside size of the arcade (x and y), meters.
pub const ARCADE_SIZE: f32 = 18.0;
/// Depth of the walkway around the courtyard.
pub const WALKWAY: f32 = 3.0;
/// Height of the underside of the roof.
pub const ROOF: f32 = 4.0;

/// A view from the shaded east walkway, looking north along it with the
/// sunlit courtyard on the left.
pub const ARCADE_VIEW: &str = "-vtv -vp 16.6 2.2 1.6 -vd -0.25 1 -0.05 -vu 0 0 1 -vh 75 -vv 56";

/// The sky of the arcade: the built-in clear day with the sun 45° high.
pub fn arcade_sky() -> Sky {
    Sky::Sun {
        direction: [0.67, 0.2, 0.714],
        sun_radiance: [1.0e5, 0.96e5, 0.88e5],
        diameter_deg: 0.53,
        zenith: [0.3, 0.45, 0.8],
        horizon: [0.85, 0.9, 0.95],
        ground: [0.2, 0.18, 0.15],
    }
}

/// Adds the arcade (see the module comment); returns its sky and one
/// interior section along the east walkway.
pub fn add_arcade(b: &mut SceneBuilder, params: &GenParams) -> Result<Setting, SceneError> {
    if params.triangles.is_some() || params.resolution.is_some() {
        tracing::warn!("arcade: --triangles and --resolution do not apply; ignored");
    }
    let stone = material(
        b,
        "stone floor",
        Material::Plastic {
            albedo: [0.55, 0.5, 0.42],
            roughness: 0.5,
            ior: 1.5,
        },
    )?;
    let court = material(b, "courtyard", Material::lambertian([0.62, 0.58, 0.5]))?;
    let plaster = material(b, "plaster", Material::lambertian([0.78, 0.7, 0.58]))?;
    let column = material(b, "column", Material::lambertian([0.7, 0.68, 0.64]))?;
    let roof = material(b, "roof", Material::lambertian([0.55, 0.35, 0.28]))?;
    let water = material(
        b,
        "basin",
        Material::Plastic {
            albedo: [0.2, 0.3, 0.32],
            roughness: 0.1,
            ior: 1.33,
        },
    )?;

    let (s, w, h) = (ARCADE_SIZE, WALKWAY, ROOF);
    let mut mesh = MeshBuf::new();
    // Floors: the walkway ring (four strips, inner corners shared) and the courtyard.
    let z = 0.0;
    for (lo, hi) in [
        ([0.0, 0.0], [s, w]),
        ([0.0, s - w], [s, s]),
        ([0.0, w], [w, s - w]),
        ([s - w, w], [s, s - w]),
    ] {
        mesh.quad(
            [
                Vec3::new(lo[0], lo[1], z),
                Vec3::new(hi[0], lo[1], z),
                Vec3::new(hi[0], hi[1], z),
                Vec3::new(lo[0], hi[1], z),
            ],
            Vec3::Z,
            stone,
        );
    }
    mesh.quad(
        [
            Vec3::new(w, w, z),
            Vec3::new(s - w, w, z),
            Vec3::new(s - w, s - w, z),
            Vec3::new(w, s - w, z),
        ],
        Vec3::Z,
        court,
    );
    // Outer walls as slabs, the roof over the ring as four slabs.
    let t = 0.3;
    mesh.cuboid(Vec3::new(-t, -t, 0.0), Vec3::new(0.0, s + t, h + t), plaster);
    mesh.cuboid(Vec3::new(s, -t, 0.0), Vec3::new(s + t, s + t, h + t), plaster);
    mesh.cuboid(Vec3::new(0.0, -t, 0.0), Vec3::new(s, 0.0, h + t), plaster);
    mesh.cuboid(Vec3::new(0.0, s, 0.0), Vec3::new(s, s + t, h + t), plaster);
    mesh.cuboid(Vec3::new(0.0, 0.0, h), Vec3::new(s, w, h + t), roof);
    mesh.cuboid(Vec3::new(0.0, s - w, h), Vec3::new(s, s, h + t), roof);
    mesh.cuboid(Vec3::new(0.0, w, h), Vec3::new(w, s - w, h + t), roof);
    mesh.cuboid(Vec3::new(s - w, w, h), Vec3::new(s, s - w, h + t), roof);
    // Columns every 2 m along the courtyard's edge, and a beam over them.
    let c = 0.2;
    let mut at = w;
    while at <= s - w + 1e-3 {
        for (x, y) in [(w, at), (s - w, at), (at, w), (at, s - w)] {
            mesh.cuboid(Vec3::new(x - c, y - c, 0.0), Vec3::new(x + c, y + c, h), column);
        }
        at += 2.0;
    }
    // The fountain basin: a low rim around dark water.
    let (m, r) = (s / 2.0, 1.6);
    mesh.cuboid(Vec3::new(m - r, m - r, 0.0), Vec3::new(m + r, m + r, 0.45), column);
    mesh.cuboid(
        Vec3::new(m - r + 0.2, m - r + 0.2, 0.45),
        Vec3::new(m + r - 0.2, m + r - 0.2, 0.47),
        water,
    );
    mesh.flush(b, "arcade")?;

    let section = box_section(
        SectionKind::Interior,
        [f64::from(s - w) + 0.5, 1.0, 1.2],
        [2.0, f64::from(s) - 2.0, 1.0],
    )
    .map_err(|e| section_error("arcade", e))?;
    Ok(Setting {
        sky: arcade_sky(),
        sections: vec![section],
    })
}
