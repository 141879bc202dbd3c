//! The furnished room: 6 x 4 x 2.7 m (x, y, z; floor at z = 0), closed but for
//! a 2 x 1.2 m window in the east wall (x = 6) with a thin glass pane. Inside:
//! a glossy table with a glass sphere on it, a mirror on the north wall, two
//! chairs, two boxes, and a 1 x 1 m area light on the ceiling. Walls are
//! single-sided quads facing inward; faces meet only at shared corners, so
//! welding the shell by position leaves boundary edges only around the window.
//!
//! Lighting (linear radiance units): the ceiling light emits 8 (about 2
//! irradiance on the table 1.9 m below); the sun (radiance 1e5 over a 0.53°
//! disk, 25° high, shining in through the window) gives about 6.7 on the floor
//! patch it reaches; the sky (zenith 0.5, horizon 0.95) about 2 outdoors.

use glam::Vec3;
use holodeck_protocol::SectionKind;

use super::shapes::MeshBuf;
use super::{material, section_error, GenParams, Setting};
use crate::error::SceneError;
use crate::scene::builder::SceneBuilder;
use crate::scene::material::{Material, Sky};
use crate::scene::section::box_section;

/// Inside size of the room, meters.
pub const ROOM_SIZE: Vec3 = Vec3::new(6.0, 4.0, 2.7);

/// An opening in the east wall (x = size.x): y and z extents, meters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Window {
    /// From and to along y.
    pub y: [f32; 2],
    /// From and to along z (sill and head height).
    pub z: [f32; 2],
}

/// The room's window.
pub const ROOM_WINDOW: Window = Window {
    y: [1.0, 3.0],
    z: [0.9, 2.1],
};

/// Materials of a room's shell.
#[derive(Clone, Copy, Debug)]
pub struct ShellMaterials {
    /// Floor (z = 0).
    pub floor: u32,
    /// The four walls.
    pub wall: u32,
    /// Ceiling.
    pub ceiling: u32,
}

/// Material ids every furnished interior shares.
pub struct Furnishing {
    /// Floor, walls and ceiling.
    pub shell: ShellMaterials,
    /// The glossy table top.
    pub table: u32,
    /// The ceiling light.
    pub light: u32,
}

/// Adds the shell, table and ceiling-light materials of the built-in interiors.
pub fn add_furnishing_materials(b: &mut SceneBuilder) -> Result<Furnishing, SceneError> {
    let shell = ShellMaterials {
        floor: material(
            b,
            "floor",
            Material::Plastic {
                albedo: [0.45, 0.32, 0.2],
                roughness: 0.35,
                ior: 1.5,
            },
        )?,
        wall: material(b, "wall", Material::lambertian([0.75, 0.73, 0.7]))?,
        ceiling: material(b, "ceiling", Material::lambertian([0.8, 0.8, 0.8]))?,
    };
    let table = material(
        b,
        "table",
        Material::Plastic {
            albedo: [0.4, 0.22, 0.1],
            roughness: 0.15,
            ior: 1.5,
        },
    )?;
    let light = material(
        b,
        "light",
        Material::Emitter {
            radiance: [8.0, 8.0, 8.0],
        },
    )?;
    Ok(Furnishing { shell, table, light })
}

/// The clear-day sky of the built-in scenes: sun 25° high, a little south of
/// east (+x), so that it shines through the room's window.
pub fn daylight() -> Sky {
    Sky::Sun {
        direction: [0.875, 0.235, 0.423],
        sun_radiance: [1.0e5, 0.96e5, 0.88e5],
        diameter_deg: 0.53,
        zenith: [0.3, 0.45, 0.8],
        horizon: [0.85, 0.9, 0.95],
        ground: [0.2, 0.18, 0.15],
    }
}

/// The inward-facing shell of a box room from the origin to `size`, with an
/// optional `window` opening in the wall x = size.x. Every face is split on
/// the same grid lines (those of the window), so neighbouring faces share
/// their edges exactly.
pub fn add_shell(mesh: &mut MeshBuf, size: Vec3, window: Option<Window>, m: ShellMaterials) {
    let (ys, zs) = match window {
        Some(w) => (vec![0.0, w.y[0], w.y[1], size.y], vec![0.0, w.z[0], w.z[1], size.z]),
        None => (vec![0.0, size.y], vec![0.0, size.z]),
    };
    let coords = [vec![0.0, size.x], ys, zs];
    for axis in 0..3 {
        for side in 0..2 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let mut normal = Vec3::ZERO;
            normal[axis] = if side == 0 { 1.0 } else { -1.0 };
            let plane = if side == 0 { 0.0 } else { size[axis] };
            let mat = match (axis, side) {
                (2, 0) => m.floor,
                (2, 1) => m.ceiling,
                _ => m.wall,
            };
            for i in 0..coords[u].len() - 1 {
                for j in 0..coords[v].len() - 1 {
                    let is_window = axis == 0
                        && side == 1
                        && window.is_some_and(|w| coords[u][i] == w.y[0] && coords[v][j] == w.z[0]);
                    if is_window {
                        continue;
                    }
                    let point = |a: usize, b: usize| {
                        let mut p = Vec3::ZERO;
                        p[axis] = plane;
                        p[u] = coords[u][a];
                        p[v] = coords[v][b];
                        p
                    };
                    mesh.quad(
                        [point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1)],
                        normal,
                        mat,
                    );
                }
            }
        }
    }
}

/// A table: a `top` slab (lo, hi corners) on four 5 cm legs down to the floor.
pub fn add_table(mesh: &mut MeshBuf, lo: Vec3, hi: Vec3, material: u32) {
    mesh.cuboid(lo, hi, material);
    let leg = 0.05;
    for (x, y) in [
        (lo.x + leg, lo.y + leg),
        (hi.x - 2.0 * leg, lo.y + leg),
        (lo.x + leg, hi.y - 2.0 * leg),
        (hi.x - 2.0 * leg, hi.y - 2.0 * leg),
    ] {
        mesh.cuboid(Vec3::new(x, y, 0.0), Vec3::new(x + leg, y + leg, lo.z), material);
    }
}

/// A chair with its seat's corner at (x, y), back toward -x (`back_low`) or +x.
fn add_chair(mesh: &mut MeshBuf, x: f32, y: f32, back_low: bool, material: u32) {
    let (w, seat, leg) = (0.45, 0.45, 0.04);
    add_table(
        mesh,
        Vec3::new(x, y, seat),
        Vec3::new(x + w, y + w, seat + 0.04),
        material,
    );
    let bx = if back_low { x } else { x + w - leg };
    mesh.cuboid(
        Vec3::new(bx, y, seat + 0.04),
        Vec3::new(bx + leg, y + w, 0.95),
        material,
    );
}

/// A downward-facing rectangular area light just under a ceiling at height `z`.
pub fn add_ceiling_light(mesh: &mut MeshBuf, lo: [f32; 2], hi: [f32; 2], z: f32, material: u32) {
    let h = z - 0.01;
    let c = [
        Vec3::new(lo[0], lo[1], h),
        Vec3::new(hi[0], lo[1], h),
        Vec3::new(hi[0], hi[1], h),
        Vec3::new(lo[0], hi[1], h),
    ];
    mesh.quad(c, -Vec3::Z, material);
}

/// Adds the furnished room (see the module comment); returns the daylight sky
/// and one interior section (0.5 m from the walls, 1.2 to 2.2 m high, clear of
/// the furniture and the light) with about 150,000 beams.
pub fn add_room(b: &mut SceneBuilder, params: &GenParams) -> Result<Setting, SceneError> {
    if params.triangles.is_some() || params.resolution.is_some() {
        tracing::warn!("room: --triangles and --resolution do not apply; ignored");
    }
    let Furnishing { shell, table, light } = add_furnishing_materials(b)?;
    let pane = material(
        b,
        "window",
        Material::Glass {
            ior: 1.5,
            color: [0.96, 0.98, 0.97],
            thin: true,
        },
    )?;
    let mirror = material(
        b,
        "mirror",
        Material::Mirror {
            color: [0.95, 0.95, 0.95],
        },
    )?;
    let glass = material(
        b,
        "glass",
        Material::Glass {
            ior: 1.5,
            color: [1.0, 1.0, 1.0],
            thin: false,
        },
    )?;
    let boxes = material(b, "box", Material::lambertian([0.6, 0.5, 0.35]))?;
    let chair = material(
        b,
        "chair",
        Material::Plastic {
            albedo: [0.15, 0.2, 0.35],
            roughness: 0.4,
            ior: 1.5,
        },
    )?;

    let mut mesh = MeshBuf::new();
    let (size, w) = (ROOM_SIZE, ROOM_WINDOW);
    add_shell(&mut mesh, size, Some(w), shell);
    let x = size.x;
    let hole = [
        Vec3::new(x, w.y[0], w.z[0]),
        Vec3::new(x, w.y[1], w.z[0]),
        Vec3::new(x, w.y[1], w.z[1]),
        Vec3::new(x, w.y[0], w.z[1]),
    ];
    mesh.quad(hole, -Vec3::X, pane);
    add_table(&mut mesh, Vec3::new(2.2, 1.5, 0.72), Vec3::new(3.8, 2.5, 0.77), table);
    mesh.icosphere(Vec3::new(3.2, 2.0, 0.77 + 0.15), 0.15, 3, glass);
    let my = size.y - 0.02;
    mesh.quad(
        [
            Vec3::new(2.0, my, 0.9),
            Vec3::new(4.0, my, 0.9),
            Vec3::new(4.0, my, 2.1),
            Vec3::new(2.0, my, 2.1),
        ],
        -Vec3::Y,
        mirror,
    );
    add_ceiling_light(&mut mesh, [2.5, 1.5], [3.5, 2.5], size.z, light);
    mesh.cuboid(Vec3::new(0.4, 0.4, 0.0), Vec3::new(0.9, 0.9, 0.5), boxes);
    mesh.cuboid(Vec3::new(0.5, 3.0, 0.0), Vec3::new(1.0, 3.6, 0.35), boxes);
    add_chair(&mut mesh, 1.6, 1.8, true, chair);
    add_chair(&mut mesh, 3.95, 1.8, false, chair);
    mesh.flush(b, "room")?;

    let section =
        box_section(SectionKind::Interior, [0.5, 0.5, 1.2], [5.0, 3.0, 1.0]).map_err(|e| section_error("room", e))?;
    Ok(Setting {
        sky: daylight(),
        sections: vec![section],
    })
}
