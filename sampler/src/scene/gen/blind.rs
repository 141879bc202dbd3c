//! The blind room: a 5 x 4 x 2.7 m room with no lamp, lit only through a
//! 2 x 1.4 m window in its east wall (x = 5) behind a venetian blind of
//! horizontal slats 7 cm deep, 8 cm apart, tilted 20° up toward the room.
//! They stop most of the low sun (25° high, from the east); what comes
//! through the gaps falls as thin stripes on the floor; the sky and the ground outside show through
//! the slats. Everything else in the room, the walls, the ceiling, a sofa,
//! a low table and a shelf, is lit by light those stripes and the slats
//! throw back: a picture lit almost wholly indirectly, with bright thin
//! features beside dark corners.

use glam::Vec3;
use holodeck_protocol::SectionKind;

use super::room::{add_shell, daylight, ShellMaterials, Window};
use super::shapes::MeshBuf;
use super::{material, section_error, GenParams, Setting};
use crate::error::SceneError;
use crate::scene::builder::SceneBuilder;
use crate::scene::material::Material;
use crate::scene::section::box_section;

/// Inside size of the room, meters.
pub const BLIND_ROOM: Vec3 = Vec3::new(5.0, 4.0, 2.7);

/// The window the blind covers.
pub const BLIND_WINDOW: Window = Window {
    y: [1.0, 3.0],
    z: [0.8, 2.2],
};

/// A view from the back of the room toward the window and the stripes on
/// the floor.
pub const BLIND_VIEW: &str = "-vtv -vp 0.8 0.9 1.5 -vd 1 0.45 -0.3 -vu 0 0 1 -vh 75 -vv 56";

/// Slat pitch, depth and tilt (degrees up toward the room).
const SLAT_PITCH: f32 = 0.08;
const SLAT_DEPTH: f32 = 0.07;
const SLAT_TILT: f32 = 20.0;

/// Adds the blind room (see the module comment); returns the daylight sky
/// and one interior section in the middle of the room.
pub fn add_blind(b: &mut SceneBuilder, params: &GenParams) -> Result<Setting, SceneError> {
    if params.triangles.is_some() || params.resolution.is_some() {
        tracing::warn!("blind: --triangles and --resolution do not apply; ignored");
    }
    let shell = ShellMaterials {
        floor: material(
            b,
            "oak floor",
            Material::Plastic {
                albedo: [0.5, 0.34, 0.2],
                roughness: 0.3,
                ior: 1.5,
            },
        )?,
        wall: material(b, "white wall", Material::lambertian([0.8, 0.78, 0.74]))?,
        ceiling: material(b, "ceiling", Material::lambertian([0.85, 0.85, 0.85]))?,
    };
    let slat = material(b, "slat", Material::lambertian([0.85, 0.84, 0.8]))?;
    let sofa = material(b, "sofa", Material::lambertian([0.25, 0.32, 0.45]))?;
    let wood = material(
        b,
        "table",
        Material::Plastic {
            albedo: [0.35, 0.2, 0.1],
            roughness: 0.2,
            ior: 1.5,
        },
    )?;
    let ground = material(b, "ground", Material::lambertian([0.25, 0.3, 0.18]))?;

    let (size, w) = (BLIND_ROOM, BLIND_WINDOW);
    let mut mesh = MeshBuf::new();
    add_shell(&mut mesh, size, Some(w), shell);
    // Slats just inside the window: thin tilted plates, front edge higher.
    let (tilt_s, tilt_c) = SLAT_TILT.to_radians().sin_cos();
    let x = size.x - 0.06;
    let mut z = w.z[1] - SLAT_PITCH / 2.0;
    while z > w.z[0] {
        let back = Vec3::new(x + SLAT_DEPTH / 2.0 * tilt_c, 0.0, z - SLAT_DEPTH / 2.0 * tilt_s);
        let front = Vec3::new(x - SLAT_DEPTH / 2.0 * tilt_c, 0.0, z + SLAT_DEPTH / 2.0 * tilt_s);
        let (y0, y1) = (w.y[0] + 0.01, w.y[1] - 0.01);
        mesh.quad(
            [
                Vec3::new(back.x, y0, back.z),
                Vec3::new(back.x, y1, back.z),
                Vec3::new(front.x, y1, front.z),
                Vec3::new(front.x, y0, front.z),
            ],
            Vec3::new(tilt_s, 0.0, tilt_c),
            slat,
        );
        z -= SLAT_PITCH;
    }
    // Outside: a ground plane below the sill, so the slats see it lit.
    let g = 40.0;
    mesh.quad(
        [
            Vec3::new(size.x, -g, -0.05),
            Vec3::new(size.x + g, -g, -0.05),
            Vec3::new(size.x + g, g, -0.05),
            Vec3::new(size.x, g, -0.05),
        ],
        Vec3::Z,
        ground,
    );
    // A sofa against the north wall, a low table, a shelf on the west wall.
    mesh.cuboid(Vec3::new(1.2, 3.1, 0.0), Vec3::new(3.4, 3.95, 0.42), sofa);
    mesh.cuboid(Vec3::new(1.2, 3.7, 0.42), Vec3::new(3.4, 3.95, 0.85), sofa);
    mesh.cuboid(Vec3::new(1.7, 1.9, 0.0), Vec3::new(2.9, 2.6, 0.4), wood);
    mesh.cuboid(Vec3::new(0.0, 0.8, 1.2), Vec3::new(0.3, 2.6, 1.24), wood);
    mesh.cuboid(Vec3::new(0.0, 0.8, 1.7), Vec3::new(0.3, 2.6, 1.74), wood);
    mesh.flush(b, "blind")?;

    let section =
        box_section(SectionKind::Interior, [0.5, 0.5, 1.1], [3.5, 2.4, 1.0]).map_err(|e| section_error("blind", e))?;
    Ok(Setting {
        sky: daylight(),
        sections: vec![section],
    })
}
