//! The landscape's room furnished with textured things, every texture made
//! by code: a patterned rug on the floor (a colour map), a painting on the
//! west wall (a colour map), a brick panel on the south wall (a colour map
//! and a height map) and a potted plant of leaf cards cut out by an alpha
//! mask (its shadows fall through the gaps). Texture coordinates are
//! multiples of 1/64, so a written-out gallery reads back bit for bit.

use glam::{Vec2, Vec3};

use super::landscape::add_landscape;
use super::{material, GenParams, Setting};
use crate::error::SceneError;
use crate::scene::builder::SceneBuilder;
use crate::scene::maps::{Channel, Coverage, MaterialMaps, Relief, TexRef, UvTransform};
use crate::scene::material::Material;
use crate::scene::texture::{Encoding, Texture, Wrap};

/// Side of the square textures, texels.
const SIZE: u32 = 256;

/// The rug: stripes and a diamond lattice in madder red, indigo and ivory.
fn rug() -> Vec<[u8; 4]> {
    texels(|u, v| {
        let border = !(0.08..=0.92).contains(&u) || !(0.08..=0.92).contains(&v);
        let stripe = ((u * 24.0) as i32) % 4 == 0 || ((v * 24.0) as i32) % 4 == 0;
        let (du, dv) = ((u * 6.0).fract() - 0.5, (v * 6.0).fract() - 0.5);
        let diamond = du.abs() + dv.abs() < 0.3;
        if border {
            [40, 45, 110]
        } else if diamond {
            [230, 220, 190]
        } else if stripe {
            [200, 150, 60]
        } else {
            [150, 30, 35]
        }
    })
}

/// The painting: a sunset over hills.
fn painting() -> Vec<[u8; 4]> {
    texels(|u, v| {
        let hill = 0.62 + 0.08 * (u * 9.0).sin() + 0.05 * (u * 23.0).cos();
        let sun = (u - 0.7).powi(2) + (v - 0.38).powi(2) < 0.006;
        if v > hill {
            let shade = (v - hill) / (1.0 - hill);
            [(40.0 + 30.0 * shade) as u8, (110.0 - 50.0 * shade) as u8, 45]
        } else if sun {
            [255, 220, 120]
        } else {
            let t = v / hill;
            [
                (60.0 + 190.0 * t) as u8,
                (90.0 + 80.0 * t) as u8,
                (170.0 - 90.0 * t) as u8,
            ]
        }
    })
}

/// Whether (u, v) falls on mortar of a running-bond brick wall (8 courses).
fn mortar(u: f32, v: f32) -> bool {
    let course = (v * 8.0) as i32;
    let shift = if course % 2 == 0 { 0.0 } else { 0.125 };
    let across = ((u + shift) * 4.0).fract();
    (v * 8.0).fract() < 0.08 || across < 0.04
}

/// The bricks' colour: red with darker speckles, grey mortar.
fn bricks() -> Vec<[u8; 4]> {
    texels(|u, v| {
        if mortar(u, v) {
            return [170, 165, 150];
        }
        let speckle = ((u * 197.0).sin() * (v * 311.0).cos() * 43758.5).fract().abs();
        let d = (speckle * 40.0) as u8;
        [165 - d, 70 - d / 2, 50 - d / 3]
    })
}

/// The bricks' heights: mortar joints sunk.
fn brick_heights() -> Vec<[u8; 4]> {
    texels(|u, v| if mortar(u, v) { [0; 3] } else { [255; 3] })
}

/// A leaf: a green ellipse with a paler midrib, transparent around it.
fn leaf() -> Vec<[u8; 4]> {
    (0..SIZE * SIZE)
        .map(|i| {
            let (x, y) = (i % SIZE, i / SIZE);
            let (u, v) = ((x as f32 + 0.5) / SIZE as f32, (y as f32 + 0.5) / SIZE as f32);
            let (du, dv) = ((u - 0.5) / 0.32, (v - 0.5) / 0.48);
            if du * du + dv * dv > 1.0 {
                return [0, 0, 0, 0];
            }
            if (u - 0.5).abs() < 0.012 {
                [150, 190, 90, 255]
            } else {
                [50, 120 + (40.0 * v) as u8, 40, 255]
            }
        })
        .collect()
}

/// Opaque texels from a colour function of (u, v) in [0, 1)², rows from the top.
fn texels(f: impl Fn(f32, f32) -> [u8; 3]) -> Vec<[u8; 4]> {
    (0..SIZE * SIZE)
        .map(|i| {
            let (x, y) = (i % SIZE, i / SIZE);
            let [r, g, b] = f((x as f32 + 0.5) / SIZE as f32, (y as f32 + 0.5) / SIZE as f32);
            [r, g, b, 255]
        })
        .collect()
}

/// Adds a texture made in memory, named for reports.
fn texture(b: &mut SceneBuilder, name: &str, texels: Vec<[u8; 4]>, encoding: Encoding) -> Result<u32, SceneError> {
    let t = Texture::from_rgba8(name, SIZE, SIZE, texels, encoding).map_err(|e| SceneError::Invalid {
        what: format!("gallery texture {name}"),
        message: e.to_string(),
    })?;
    Ok(b.textures().add(t))
}

/// A textured quad: corners counter-clockwise seen from the front, texture
/// coordinates (0, 1), (r, 1), (r, 1 - s), (0, 1 - s) at them (the image
/// upright, repeated r times across and s times up).
fn quad(
    b: &mut SceneBuilder,
    what: &str,
    corners: [Vec3; 4],
    repeat: [f32; 2],
    material: u32,
) -> Result<(), SceneError> {
    let [r, s] = repeat;
    let uvs = [
        Vec2::new(0.0, 1.0),
        Vec2::new(r, 1.0),
        Vec2::new(r, 1.0 - s),
        Vec2::new(0.0, 1.0 - s),
    ];
    b.add_mesh_uv(
        what,
        &corners,
        Some(&uvs),
        &[[0, 1, 2], [0, 2, 3]],
        &[material],
        glam::Mat4::IDENTITY,
    )
}

/// The textured things, added to a scene that has the built-in room.
///
/// Long because it is the gallery's inventory: each piece's texture,
/// material and placement in turn, read top to bottom like a list.
pub fn add_gallery_pieces(b: &mut SceneBuilder) -> Result<(), SceneError> {
    let plain = |t: u32| TexRef::new(t);
    let rug_tex = texture(b, "gallery:rug", rug(), Encoding::Srgb)?;
    let painting_tex = texture(b, "gallery:painting", painting(), Encoding::Srgb)?;
    let bricks_tex = texture(b, "gallery:bricks", bricks(), Encoding::Srgb)?;
    let heights_tex = texture(b, "gallery:brick-heights", brick_heights(), Encoding::Linear)?;
    let leaf_tex = texture(b, "gallery:leaf", leaf(), Encoding::Srgb)?;
    let textured = |b: &mut SceneBuilder, name: &str, m: Material, maps: MaterialMaps| match b.material_id(name) {
        Some(id) => Ok(id),
        None => b.material_with_maps(name, m, maps),
    };
    let rug = textured(
        b,
        "rug",
        Material::lambertian([1.0; 3]),
        MaterialMaps {
            base_color: Some(plain(rug_tex)),
            ..MaterialMaps::default()
        },
    )?;
    let painting = textured(
        b,
        "painting",
        Material::lambertian([1.0; 3]),
        MaterialMaps {
            base_color: Some(plain(painting_tex)),
            ..MaterialMaps::default()
        },
    )?;
    let bricks = TexRef {
        texture: bricks_tex,
        wrap: [Wrap::Repeat; 2],
        transform: UvTransform::default(),
    };
    let brick = textured(
        b,
        "brick",
        Material::lambertian([1.0; 3]),
        MaterialMaps {
            base_color: Some(bricks),
            relief: Some((
                TexRef {
                    texture: heights_tex,
                    ..bricks
                },
                Relief::Height { scale: 0.5 },
            )),
            ..MaterialMaps::default()
        },
    )?;
    let leaves = textured(
        b,
        "leaf",
        Material::lambertian([1.0; 3]),
        MaterialMaps {
            base_color: Some(plain(leaf_tex)),
            coverage: Some((Some((plain(leaf_tex), Channel::Alpha)), Coverage::Mask { cutoff: 0.5 })),
            ..MaterialMaps::default()
        },
    )?;
    let pot = material(b, "pot", Material::lambertian([0.55, 0.3, 0.2]))?;

    // A 2 x 1.5 m rug between the table and the window, 2 mm above the floor.
    let z = 0.002;
    quad(
        b,
        "gallery rug",
        [
            Vec3::new(3.9, 1.25, z),
            Vec3::new(5.9, 1.25, z),
            Vec3::new(5.9, 2.75, z),
            Vec3::new(3.9, 2.75, z),
        ],
        [1.0, 1.0],
        rug,
    )?;
    // A 1.2 x 0.8 m painting on the west wall (x = 0), facing the window.
    let x = 0.01;
    quad(
        b,
        "gallery painting",
        [
            Vec3::new(x, 2.6, 1.1),
            Vec3::new(x, 1.4, 1.1),
            Vec3::new(x, 1.4, 1.9),
            Vec3::new(x, 2.6, 1.9),
        ],
        [1.0, 1.0],
        painting,
    )?;
    // Bricks over the south wall (y = 0) from x 1.5 to 5.5, floor to 2 m:
    // the image (1 m square, 8 courses) tiled 4 across and 2 up.
    let y = 0.01;
    quad(
        b,
        "gallery bricks",
        [
            Vec3::new(1.5, y, 0.0),
            Vec3::new(5.5, y, 0.0),
            Vec3::new(5.5, y, 2.0),
            Vec3::new(1.5, y, 2.0),
        ],
        [4.0, 2.0],
        brick,
    )?;
    // A pot in the room's north-east corner, with eight leaf cards around it.
    let (cx, cy) = (5.4, 3.4);
    let mut pot_mesh = super::shapes::MeshBuf::new();
    pot_mesh.cuboid(
        Vec3::new(cx - 0.15, cy - 0.15, 0.0),
        Vec3::new(cx + 0.15, cy + 0.15, 0.35),
        pot,
    );
    pot_mesh.flush(b, "gallery pot")?;
    for k in 0..8 {
        let a = k as f32 * std::f32::consts::TAU / 8.0;
        let (s, c) = a.sin_cos();
        let tilt = 0.25 + 0.1 * (k % 3) as f32;
        let base = Vec3::new(cx + 0.05 * c, cy + 0.05 * s, 0.35);
        let out = Vec3::new(c, s, 0.0);
        let side = Vec3::new(-s, c, 0.0) * 0.18;
        let tip = base + out * (0.55 * tilt.sin() + 0.1) + Vec3::Z * (0.55 * tilt.cos() + 0.3);
        quad(
            b,
            "gallery leaf",
            [base - side, base + side, tip + side, tip - side],
            [1.0, 1.0],
            leaves,
        )?;
    }
    Ok(())
}

/// The landscape (room, terrain, forest) with the textured things in the room.
pub fn add_gallery(b: &mut SceneBuilder, params: &GenParams) -> Result<Setting, SceneError> {
    let setting = add_landscape(b, params)?;
    add_gallery_pieces(b)?;
    Ok(setting)
}
