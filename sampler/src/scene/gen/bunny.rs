//! The Stanford bunny (an OBJ, Y up: the one built into the program, or a
//! file given instead) turned Z up, scaled to 0.3 m tall and set on a table in
//! a closed 4 x 4 x 2.6 m room lit by a 1 x 1 m ceiling light, with an
//! exterior section around the bunny.

use std::path::Path;

use glam::{Mat4, Vec3};
use holodeck_protocol::SectionKind;

use super::room::{add_ceiling_light, add_furnishing_materials, add_shell, add_table, Furnishing};
use super::shapes::MeshBuf;
use super::{material, section_error, GenParams, Setting};
use crate::error::SceneError;
use crate::scene::builder::SceneBuilder;
use crate::scene::import::{import_file_with, import_obj_bytes, ImportOptions, UpAxis};
use crate::scene::material::{Material, Sky};
use crate::scene::section::box_section;

/// The low-resolution Stanford bunny (3,674 triangles, public domain; see
/// `sampler/assets/README.md`), built in so that the scene needs no file.
pub const BUILT_IN_BUNNY_OBJ: &[u8] = include_bytes!("../../../assets/bunny.obj");
/// Height of the placed bunny, meters.
pub const BUNNY_HEIGHT: f32 = 0.3;
/// Room size, meters.
const SIZE: Vec3 = Vec3::new(4.0, 4.0, 2.6);
/// Table top height, meters.
const TABLE_TOP: f32 = 0.75;

/// The transform that turns a Y-up mesh with bounds (`lo`, `hi`) Z up, scales
/// it to `height`, and stands it with its bottom center at `foot`.
pub fn stand_up(lo: Vec3, hi: Vec3, height: f32, foot: Vec3) -> Mat4 {
    let s = if hi.y > lo.y { height / (hi.y - lo.y) } else { 1.0 };
    // Rotating +90° about x maps (x, y, z) to (x, -z, y): +y becomes +z.
    let rotate = Mat4::from_rotation_x(std::f32::consts::FRAC_PI_2);
    let center = Vec3::new((lo.x + hi.x) / 2.0, -(lo.z + hi.z) / 2.0, lo.y) * s;
    Mat4::from_translation(foot - center) * Mat4::from_scale(Vec3::splat(s)) * rotate
}

/// Adds the bunny room; returns no sky (the room is closed) and a section around the bunny.
pub fn add_bunny(b: &mut SceneBuilder, params: &GenParams) -> Result<Setting, SceneError> {
    if params.triangles.is_some() || params.resolution.is_some() {
        tracing::warn!("bunny: --triangles and --resolution do not apply; ignored");
    }
    let bunny = read_mesh(params.bunny_path.as_deref())?;
    let name = params
        .bunny_path
        .as_ref()
        .map_or_else(|| "built-in bunny".to_string(), |p| p.display().to_string());
    let (lo, hi) = bunny.bounds();
    let foot = Vec3::new(SIZE.x / 2.0, SIZE.y / 2.0, TABLE_TOP);
    let transform = stand_up(lo, hi, BUNNY_HEIGHT, foot);

    let Furnishing { shell, table, light } = add_furnishing_materials(b)?;
    let skin = material(
        b,
        "bunny",
        Material::Plastic {
            albedo: [0.8, 0.78, 0.74],
            roughness: 0.3,
            ior: 1.5,
        },
    )?;

    let mut mesh = MeshBuf::new();
    add_shell(&mut mesh, SIZE, None, shell);
    let c = foot;
    add_table(
        &mut mesh,
        Vec3::new(c.x - 0.5, c.y - 0.4, TABLE_TOP - 0.05),
        Vec3::new(c.x + 0.5, c.y + 0.4, TABLE_TOP),
        table,
    );
    add_ceiling_light(&mut mesh, [c.x - 0.5, c.y - 0.5], [c.x + 0.5, c.y + 0.5], SIZE.z, light);
    mesh.flush(b, "bunny room")?;
    let triangles: Vec<[u32; 3]> = bunny.triangles.iter().map(|t| t.v).collect();
    b.add_mesh(&name, &bunny.positions, &triangles, &[skin], transform)?;

    let corners = [lo, hi].map(|p| transform.transform_point3(p));
    let (wlo, whi) = (
        corners[0].min(corners[1]).as_dvec3(),
        corners[0].max(corners[1]).as_dvec3(),
    );
    let m = 0.03;
    let bottom = f64::from(TABLE_TOP) + 0.002;
    let size = [whi.x - wlo.x + 2.0 * m, whi.y - wlo.y + 2.0 * m, whi.z + m - bottom];
    let section = box_section(SectionKind::Exterior, [wlo.x - m, wlo.y - m, bottom], size)
        .map_err(|e| section_error("bunny", e))?;
    Ok(Setting {
        sky: Sky::None,
        sections: vec![section],
    })
}

/// The bunny as one mesh in its own coordinates (any materials it names are
/// ignored): the file at `path`, else the built-in one.
fn read_mesh(path: Option<&Path>) -> Result<crate::scene::Scene, SceneError> {
    let mut temp = SceneBuilder::new();
    let m = temp.material("bunny", Material::lambertian([0.8; 3]))?;
    let Some(path) = path else {
        import_obj_bytes(
            &mut temp,
            BUILT_IN_BUNNY_OBJ,
            Path::new("built-in bunny"),
            Mat4::IDENTITY,
            Some(m),
        )?;
        return Ok(temp.finish());
    };
    // A file given explicitly is read as OBJ whatever its axes convention:
    // stand_up turns it Z up.
    let options = ImportOptions {
        default_material: Some(m),
        up: Some(UpAxis::Z),
        ..ImportOptions::default()
    };
    import_file_with(&mut temp, path, Mat4::IDENTITY, &options).map_err(|e| match e {
        SceneError::Io { path, source } => SceneError::Io {
            source: std::io::Error::new(
                source.kind(),
                format!("{source} (give the bunny OBJ with --bunny PATH)"),
            ),
            path,
        },
        e => e,
    })?;
    Ok(temp.finish())
}
