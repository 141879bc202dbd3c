//! Textured scenes written by the tests, rendered: texels come back as the
//! image's colours, alpha masks let every ray through their holes, normal
//! maps bend the shading, and MTL and glTF materials mean what their
//! formats say.

use std::collections::HashMap;
use std::path::Path;

use glam::{Mat4, Vec3};
use holodeck_sampler::scene::texture::srgb_to_linear;
use holodeck_sampler::scene::{import_file, ImportOptions};
use holodeck_sampler::{Material, Rng, Scene, SceneBuilder, Sky, TraceOptions, Tracer};

/// Writes `text` to `dir/name`.
fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A 4×4 image whose every texel differs: texel (x, y) is
/// (40 + 50x, 30 + 60y, 200 - 40x, alpha) with alpha from `alpha`.
fn palette(alpha: impl Fn(u32, u32) -> u8) -> image::RgbaImage {
    image::RgbaImage::from_fn(4, 4, |x, y| {
        image::Rgba([
            (40 + 50 * x) as u8,
            (30 + 60 * y) as u8,
            (200 - 40 * x) as u8,
            alpha(x, y),
        ])
    })
}

/// A unit quad in z = `z` facing +z, with OBJ texture coordinates
/// (0, 0) at its (0, 0) corner and (1, 1) at (1, 1).
fn quad_obj(mtl: &str, material: &str, z: f32) -> String {
    format!(
        "mtllib {mtl}\nv 0 0 {z}\nv 1 0 {z}\nv 1 1 {z}\nv 0 1 {z}\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl {material}\nf 1/1 2/2 3/3 4/4\n"
    )
}

fn import(path: &Path, b: &mut SceneBuilder) {
    import_file(b, path, Mat4::IDENTITY, None, &HashMap::new()).unwrap();
}

/// The mean radiance of `n` paths from `origin` along `dir`.
fn radiance(t: &Tracer, origin: Vec3, dir: Vec3, n: u64) -> Vec3 {
    let mut sum = Vec3::ZERO;
    for i in 0..n {
        let mut rng = Rng::new(11, i);
        sum += t.trace(origin, dir.normalize(), &mut rng).radiance;
    }
    sum / n as f32
}

/// The point of the unit quad at the centre of texel (x, y) of a 4×4
/// image (row 0 at the top, which OBJ maps to v = 1, y = 1).
fn texel_centre(x: u32, y: u32) -> Vec3 {
    Vec3::new((x as f32 + 0.5) / 4.0, 1.0 - (y as f32 + 0.5) / 4.0, 0.0)
}

#[test]
fn a_checkerboard_quad_shows_its_texels_in_linear_light() {
    let dir = tempfile::tempdir().unwrap();
    palette(|_, _| 255).save(dir.path().join("palette.png")).unwrap();
    // The same colours as floats in a Radiance HDR image: read as linear.
    let hdr = image::Rgb32FImage::from_fn(4, 4, |x, y| image::Rgb([0.1 * x as f32, 0.2 * y as f32, 0.5]));
    image::DynamicImage::ImageRgb32F(hdr)
        .save(dir.path().join("linear.hdr"))
        .unwrap();
    write(
        dir.path(),
        "q.mtl",
        "newmtl srgb\nKd 1 1 1\nmap_Kd palette.png\nnewmtl linear\nKd 1 1 1\nmap_Kd linear.hdr\n",
    );
    for (material, expect) in [
        (
            "srgb",
            Box::new(|x: u32, y: u32| {
                Vec3::new(
                    srgb_to_linear((40 + 50 * x) as f32 / 255.0),
                    srgb_to_linear((30 + 60 * y) as f32 / 255.0),
                    srgb_to_linear((200 - 40 * x) as f32 / 255.0),
                )
            }) as Box<dyn Fn(u32, u32) -> Vec3>,
        ),
        (
            "linear",
            Box::new(|x, y| Vec3::new(0.1 * x as f32, 0.2 * y as f32, 0.5)),
        ),
    ] {
        let obj = write(
            dir.path(),
            &format!("{material}.obj"),
            &quad_obj("q.mtl", material, 0.0),
        );
        let mut b = SceneBuilder::new();
        import(&obj, &mut b);
        b.sky(Sky::Constant { radiance: [1.0; 3] }).unwrap();
        let scene = b.finish();
        assert_eq!(scene.textures.len(), 1);
        let t = Tracer::new(scene, TraceOptions::default());
        for (x, y) in [(0, 0), (3, 0), (1, 2), (2, 3), (3, 3)] {
            let p = texel_centre(x, y);
            // A diffuse surface under a sky of radiance 1 reflects its albedo.
            let seen = radiance(&t, p + Vec3::Z, -Vec3::Z, 4);
            let want = expect(x, y);
            // Radiance HDR keeps 8 bits of mantissa: 0.3 is stored as 0.297.
            let tolerance = if material == "linear" { 0.01 } else { 2e-3 };
            assert!(
                (seen - want).abs().max_element() < tolerance,
                "{material} texel ({x}, {y}): saw {seen}, the image holds {want}"
            );
        }
    }
}

#[test]
fn an_alpha_masked_card_lets_camera_and_shadow_rays_through_its_holes() {
    let dir = tempfile::tempdir().unwrap();
    // Left half of the card is a hole.
    palette(|x, _| if x < 2 { 0 } else { 255 })
        .save(dir.path().join("leaf.png"))
        .unwrap();
    write(
        dir.path(),
        "leaf.mtl",
        "newmtl leaf\nKd 0.5 0.5 0.5\nmap_d leaf.png\nnewmtl floor\nKd 0.8 0.8 0.8\n",
    );
    let card = write(dir.path(), "card.obj", &quad_obj("leaf.mtl", "leaf", 1.0));
    let floor = write(
        dir.path(),
        "floor.obj",
        "mtllib leaf.mtl\nv -5 -5 0\nv 6 -5 0\nv 6 6 0\nv -5 6 0\nusemtl floor\nf 1 2 3 4\n",
    );
    let mut b = SceneBuilder::new();
    import(&card, &mut b);
    import(&floor, &mut b);
    // The sun straight overhead, no sky: only direct sunlight lights the floor.
    b.sky(Sky::Sun {
        direction: [0.0, 0.0, 1.0],
        sun_radiance: [1e4; 3],
        diameter_deg: 0.53,
        zenith: [0.0; 3],
        horizon: [0.0; 3],
        ground: [0.0; 3],
    })
    .unwrap();
    let scene = b.finish();
    let t = Tracer::new(scene, TraceOptions::default());
    // From above: the hole shows the floor (2 away), the solid half the card (1 away).
    let mut rng = Rng::new(1, 0);
    let hole = t.trace(Vec3::new(0.25, 0.5, 2.0), -Vec3::Z, &mut rng);
    let solid = t.trace(Vec3::new(0.75, 0.5, 2.0), -Vec3::Z, &mut rng);
    assert!(
        (hole.distance - 2.0).abs() < 1e-4,
        "through the hole: {}",
        hole.distance
    );
    assert!((solid.distance - 1.0).abs() < 1e-4, "on the card: {}", solid.distance);
    // Shadow rays: the floor under the hole is sunlit, under the solid half it is not.
    let below = |x: f32| radiance(&t, Vec3::new(x, 0.5, 0.5), Vec3::new(0.0, 0.3, -1.0), 64);
    let (lit, shaded) = (below(0.25), below(0.75));
    let sun_solid_angle = std::f32::consts::TAU * (1.0 - (0.265f32.to_radians()).cos());
    let expected = 0.8 / std::f32::consts::PI * 1e4 * sun_solid_angle;
    assert!(
        (lit.x - expected).abs() < 0.05 * expected,
        "lit floor {lit}, expected {expected}"
    );
    // What reaches the shaded floor is light the card's underside reflects from the lit floor.
    assert!(
        shaded.max_element() < 0.05 * expected,
        "the card's solid half shades the floor: {shaded}"
    );
}

#[test]
fn a_normal_map_bends_the_shading_as_its_texels_say() {
    let dir = tempfile::tempdir().unwrap();
    // Tangent-space normal tilted 30 degrees toward +u (+x on this quad).
    let (s, c) = 30f32.to_radians().sin_cos();
    let enc = |v: f32| ((v * 0.5 + 0.5) * 255.0).round() as u8;
    image::RgbaImage::from_pixel(4, 4, image::Rgba([enc(s), enc(0.0), enc(c), 255]))
        .save(dir.path().join("tilt.png"))
        .unwrap();
    image::RgbaImage::from_pixel(4, 4, image::Rgba([128, 128, 255, 255]))
        .save(dir.path().join("flat.png"))
        .unwrap();
    write(
        dir.path(),
        "n.mtl",
        "newmtl tilted\nKd 0.5 0.5 0.5\nnorm tilt.png\nnewmtl flat\nKd 0.5 0.5 0.5\nnorm flat.png\nnewmtl plain\nKd 0.5 0.5 0.5\n",
    );
    // The sun 30 degrees from the zenith toward +x.
    let sun = Sky::Sun {
        direction: [s, 0.0, c],
        sun_radiance: [1e4; 3],
        diameter_deg: 0.53,
        zenith: [0.0; 3],
        horizon: [0.0; 3],
        ground: [0.0; 3],
    };
    let seen = |material: &str| {
        let obj = write(
            dir.path(),
            &format!("{material}.obj"),
            &quad_obj("n.mtl", material, 0.0),
        );
        let mut b = SceneBuilder::new();
        import(&obj, &mut b);
        b.sky(sun.clone()).unwrap();
        let t = Tracer::new(b.finish(), TraceOptions::default());
        radiance(&t, Vec3::new(0.5, 0.5, 1.0), -Vec3::Z, 64).x
    };
    let (tilted, flat, plain) = (seen("tilted"), seen("flat"), seen("plain"));
    assert!(
        (flat - plain).abs() < 0.01 * plain,
        "a flat normal map changes nothing: {flat} vs {plain}"
    );
    // Facing the sun squarely instead of at 30 degrees: 1 / cos 30 brighter.
    let ratio = tilted / plain;
    assert!(
        (ratio - 1.0 / c).abs() < 0.02,
        "tilted / plain = {ratio}, expected {}",
        1.0 / c
    );
}

#[test]
fn mtl_models_mean_what_the_format_says_and_what_was_dropped_is_noted() {
    let dir = tempfile::tempdir().unwrap();
    let mtl = "\
newmtl floor
illum 2
Kd 0.6 0.5 0.4
Ks 0 0 0
d 0.000000
newmtl varnish
illum 2
Kd 0.6 0.5 0.4
Ks 0.2 0.2 0.2
Ns 20
newmtl window
illum 4
Ni 1.5
newmtl unlit
illum 0
Kd 0.3 0.3 0.3
newmtl mirrorish
illum 3
Kd 0 0 0
Ks 0.9 0.9 0.9
newmtl textured
Kd 1 1 1
map_Ks spec.png
map_Kd -s 2 2 1 missing.png
";
    write(dir.path(), "m.mtl", mtl);
    let mut obj = String::from("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\n");
    for m in ["floor", "varnish", "window", "unlit", "mirrorish", "textured"] {
        obj.push_str(&format!("usemtl {m}\nf 1 2 3\n"));
    }
    let path = write(dir.path(), "m.obj", &obj);
    let mut b = SceneBuilder::new();
    import(&path, &mut b);
    let s: Scene = b.finish();
    let by_name = |n: &str| {
        let i = s.material_names.iter().position(|m| m == n).unwrap();
        s.materials[i].clone()
    };
    assert_eq!(
        by_name("floor"),
        Material::lambertian([0.6, 0.5, 0.4]),
        "d 0 with illum 2 is opaque"
    );
    assert!(matches!(by_name("varnish"), Material::Plastic { .. }));
    assert!(matches!(by_name("window"), Material::Glass { ior, .. } if ior == 1.5));
    assert_eq!(by_name("unlit"), Material::lambertian([0.3; 3]));
    assert!(matches!(by_name("mirrorish"), Material::Metal { .. }));
    let notes: Vec<String> = s.notes.iter().map(|n| n.to_string()).collect();
    let has = |needle: &str| notes.iter().any(|n| n.contains(needle));
    assert!(has("d 0 ignored: illum 2 is an opaque model"), "{notes:#?}");
    assert!(has("illum 0"), "{notes:#?}");
    assert!(has("map_Ks is not used"), "{notes:#?}");
    assert!(has("missing.png"), "the path tried is named: {notes:#?}");
    assert!(s.maps.iter().all(|m| m.is_empty()), "a missing texture is dropped");
}

/// A glTF file with one textured triangle, its buffers and images inline,
/// and `material` as the material's JSON.
fn gltf_triangle(material: &str, images: &[&[u8]]) -> String {
    gltf_triangle_with(material, images, None)
}

/// [`gltf_triangle`] with a TANGENT for every vertex where given.
fn gltf_triangle_with(material: &str, images: &[&[u8]], tangent: Option<[f32; 4]>) -> String {
    use base64::encode;
    let mut bin = Vec::new();
    for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]] {
        for c in p {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    // Texture coordinates: the whole image on the triangle's right angle.
    for uv in [[0.0f32, 1.0], [1.0, 1.0], [0.0, 0.0]] {
        for c in uv {
            bin.extend_from_slice(&c.to_le_bytes());
        }
    }
    if let Some(t) = tangent {
        for _ in 0..3 {
            for c in t {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    let (tangent_attribute, tangent_accessor, tangent_view) = if tangent.is_some() {
        (
            ",\"TANGENT\":2",
            ",{\"bufferView\":2,\"componentType\":5126,\"count\":3,\"type\":\"VEC4\"}",
            ",{\"buffer\":0,\"byteOffset\":60,\"byteLength\":48}",
        )
    } else {
        ("", "", "")
    };
    let images: Vec<String> = images
        .iter()
        .map(|png| format!("{{\"uri\":\"data:image/png;base64,{}\"}}", encode(png)))
        .collect();
    let textures: Vec<String> = (0..images.len()).map(|i| format!("{{\"source\":{i}}}")).collect();
    format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{"POSITION":0,"TEXCOORD_0":1{tangent_attribute}}},"material":0}}]}}],
"materials":[{material}],
"textures":[{}],"images":[{}],
"extensionsUsed":["KHR_texture_transform","KHR_materials_sheen"],
"accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,-1],"max":[1,0,0]}},
{{"bufferView":1,"componentType":5126,"count":3,"type":"VEC2"}}{tangent_accessor}],
"bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":24}}{tangent_view}],
"buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{}"}}]}}"#,
        textures.join(","),
        images.join(","),
        bin.len(),
        encode(&bin)
    )
}

fn png(image: &image::RgbaImage) -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    image.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

#[test]
fn a_gltf_with_only_textures_takes_their_colours_and_is_not_metal() {
    let dir = tempfile::tempdir().unwrap();
    let colour = png(&palette(|_, _| 255));
    // Roughness 1 (green), metalness 0 (blue): leather, not metal.
    let mr = png(&image::RgbaImage::from_pixel(2, 2, image::Rgba([0, 255, 0, 255])));
    let material = r#"{"name":"leather","pbrMetallicRoughness":{"baseColorTexture":{"index":0},"metallicRoughnessTexture":{"index":1}}}"#;
    let path = write(dir.path(), "t.gltf", &gltf_triangle(material, &[&colour, &mr]));
    let mut b = SceneBuilder::new();
    holodeck_sampler::scene::import_file_with(&mut b, &path, Mat4::IDENTITY, &ImportOptions::default()).unwrap();
    b.sky(Sky::Constant { radiance: [1.0; 3] }).unwrap();
    let s = b.finish();
    assert!(
        matches!(s.materials[0], Material::Lambertian { .. }),
        "the texture says rough dielectric: {:?}",
        s.materials[0]
    );
    assert!(
        s.notes.iter().any(|n| n.what.contains("KHR_materials_sheen")),
        "{:?}",
        s.notes
    );
    // glTF is +y up; imported +z up, the triangle lies in z = 0 facing +z
    // with texture (0, 0) at (0, 1, 0): texel (x, y) at ((x + .5) / 4, 1 - (y + .5) / 4).
    let t = Tracer::new(s, TraceOptions::default());
    for (x, y) in [(0, 1), (1, 2), (0, 3)] {
        let p = texel_centre(x, y);
        let seen = radiance(&t, p + Vec3::Z, -Vec3::Z, 4);
        let want = Vec3::new(
            srgb_to_linear((40 + 50 * x) as f32 / 255.0),
            srgb_to_linear((30 + 60 * y) as f32 / 255.0),
            srgb_to_linear((200 - 40 * x) as f32 / 255.0),
        );
        assert!(
            (seen - want).abs().max_element() < 2e-3,
            "texel ({x}, {y}): {seen} vs {want}"
        );
    }
}

#[test]
fn khr_texture_transform_places_the_texture() {
    let dir = tempfile::tempdir().unwrap();
    let colour = png(&palette(|_, _| 255));
    // Scale by one half and offset by a half: the triangle's (u, v) reads (0.5 + u / 2, 0.5 + v / 2).
    let material = r#"{"name":"placed","pbrMetallicRoughness":{"roughnessFactor":1.0,"metallicFactor":0.0,
"baseColorTexture":{"index":0,"extensions":{"KHR_texture_transform":{"offset":[0.5,0.5],"scale":[0.5,0.5]}}}}}"#;
    let path = write(dir.path(), "p.gltf", &gltf_triangle(material, &[&colour]));
    let mut b = SceneBuilder::new();
    holodeck_sampler::scene::import_file_with(&mut b, &path, Mat4::IDENTITY, &ImportOptions::default()).unwrap();
    b.sky(Sky::Constant { radiance: [1.0; 3] }).unwrap();
    let t = Tracer::new(b.finish(), TraceOptions::default());
    // Texture coordinate (0.25, 0.75) on the surface, at (0.25, 0.25, 0),
    // reads (0.625, 0.875): the centre of texel (2, 3).
    let p = Vec3::new(0.25, 0.25, 0.0);
    let seen = radiance(&t, p + Vec3::Z, -Vec3::Z, 4);
    let want = Vec3::new(
        srgb_to_linear(140.0 / 255.0),
        srgb_to_linear(210.0 / 255.0),
        srgb_to_linear(120.0 / 255.0),
    );
    assert!(
        (seen - want).abs().max_element() < 2e-3,
        "{seen} vs texel (2, 3) {want}"
    );
}

#[test]
fn baking_textures_keeps_their_mean_and_hashes_apart() {
    let dir = tempfile::tempdir().unwrap();
    // Half black, half white: the mean colour is linear 0.5 times Kd.
    image::RgbaImage::from_fn(4, 4, |x, _| {
        if x < 2 {
            image::Rgba([0, 0, 0, 255])
        } else {
            image::Rgba([255; 4])
        }
    })
    .save(dir.path().join("half.png"))
    .unwrap();
    write(dir.path(), "h.mtl", "newmtl half\nKd 0.8 0.8 0.8\nmap_Kd half.png\n");
    let obj = write(dir.path(), "h.obj", &quad_obj("h.mtl", "half", 0.0));
    let mut b = SceneBuilder::new();
    import(&obj, &mut b);
    let textured = b.finish();
    let before = holodeck_sampler::scene::content_hash(&textured);
    let mut baked = textured.clone();
    assert!(baked.bake_textures());
    // The mean is kept in an 8-bit sRGB mip level: 0.5 reads 0.503.
    match baked.materials[0] {
        Material::Lambertian { albedo, .. } => assert!((albedo[0] - 0.4).abs() < 0.004, "{albedo:?}"),
        ref other => panic!("{other:?}"),
    }
    assert!(baked.uvs.is_empty() && baked.textures.is_empty());
    assert_ne!(holodeck_sampler::scene::content_hash(&baked), before);
}

#[test]
fn an_emission_texture_glows_where_it_is_bright_and_lights_the_room_as_it_says() {
    let dir = tempfile::tempdir().unwrap();
    // Left half white, right half black (fine enough that filtering blurs
    // only a sliver between them).
    image::RgbaImage::from_fn(64, 4, |x, _| {
        if x < 32 {
            image::Rgba([255; 4])
        } else {
            image::Rgba([0, 0, 0, 255])
        }
    })
    .save(dir.path().join("glow.png"))
    .unwrap();
    write(
        dir.path(),
        "g.mtl",
        "newmtl panel\nillum 1\nKd 0 0 0\nKe 2 2 2\nmap_Ke -clamp on glow.png\nnewmtl lamp\nKe 2 2 2\nnewmtl dark\nKd 0 0 0\nnewmtl floor\nKd 0.5 0.5 0.5\n",
    );
    // The panel faces down from z = 1 over a floor at z = 0.
    let panel = "mtllib g.mtl\nv 0 0 1\nv 0 1 1\nv 1 1 1\nv 1 0 1\nvt 0 0\nvt 0 1\nvt 1 1\nvt 1 0\nusemtl panel\nf 1/1 2/2 3/3 4/4\n";
    // The same light made of two plain quads: a lamp on the left half, black on the right.
    let halves = "mtllib g.mtl\nv 0 0 1\nv 0 1 1\nv 0.5 1 1\nv 0.5 0 1\nv 1 1 1\nv 1 0 1\nusemtl lamp\nf 1 2 3 4\nusemtl dark\nf 4 3 5 6\n";
    let floor = "mtllib g.mtl\nv -3 -3 0\nv 4 -3 0\nv 4 4 0\nv -3 4 0\nusemtl floor\nf 1 2 3 4\n";
    let build = |light: &str| {
        let obj = write(dir.path(), "light.obj", light);
        let fl = write(dir.path(), "floor.obj", floor);
        let mut b = SceneBuilder::new();
        import(&obj, &mut b);
        import(&fl, &mut b);
        let s = b.finish();
        Tracer::new(s, TraceOptions::default())
    };
    let textured = build(panel);
    let plain = build(halves);
    // The textured room as a scene file, traced out of core: its lights
    // are the header's emitters, the panel among them.
    let hds = dir.path().join("glow.hds");
    let source = holodeck_sampler::ooc::build::SceneSource::new(textured.scene().clone());
    holodeck_sampler::ooc::build_scene_file(&source, &hds, &Default::default(), &|_, _, _| {}).unwrap();
    let file = std::sync::Arc::new(holodeck_sampler::ooc::OocScene::open(&hds, None, 1).unwrap());
    assert_eq!(file.header().emitters.len(), 2, "the panel's two triangles emit");
    let from_file = Tracer::out_of_core(file, TraceOptions::default());
    // Seen from below: the white half glows at 2, the black half not at all.
    let white = radiance(&textured, Vec3::new(0.25, 0.5, 0.5), Vec3::Z, 4);
    let black = radiance(&textured, Vec3::new(0.75, 0.5, 0.5), Vec3::Z, 4);
    assert!((white.x - 2.0).abs() < 1e-3 && black.x < 1e-3, "{white} {black}");
    // The floor below, lit by light sampling and by bounces: the same as the plain halves.
    for x in [0.25f32, 0.75, 1.5] {
        let at = Vec3::new(x, 0.5, 0.3);
        let dir = Vec3::new(0.0, 0.1, -1.0);
        let (a, b) = (radiance(&textured, at, dir, 20_000), radiance(&plain, at, dir, 20_000));
        assert!(
            (a.x - b.x).abs() < 0.03 * b.x.max(0.01),
            "floor at x {x}: textured {a}, halves {b}"
        );
        let f = radiance(&from_file, at, dir, 20_000);
        assert!(
            (f.x - b.x).abs() < 0.03 * b.x.max(0.01),
            "floor at x {x}: scene file {f}, halves {b}"
        );
    }
}

#[test]
fn gltf_tangents_orient_the_normal_map_where_given() {
    let dir = tempfile::tempdir().unwrap();
    // A normal tilted 30 degrees toward the tangent.
    let (s, c) = 30f32.to_radians().sin_cos();
    let enc = |v: f32| ((v * 0.5 + 0.5) * 255.0).round() as u8;
    let map = png(&image::RgbaImage::from_pixel(
        4,
        4,
        image::Rgba([enc(s), enc(0.0), enc(c), 255]),
    ));
    let material = r#"{"name":"bumpy","pbrMetallicRoughness":{"baseColorFactor":[0.5,0.5,0.5,1],"metallicFactor":0.0,"roughnessFactor":1.0},"normalTexture":{"index":0}}"#;
    // The sun 30 degrees from the zenith toward +x; u grows toward +x.
    let sun = Sky::Sun {
        direction: [s, 0.0, c],
        sun_radiance: [1e4; 3],
        diameter_deg: 0.53,
        zenith: [0.0; 3],
        horizon: [0.0; 3],
        ground: [0.0; 3],
    };
    let seen = |tangent: Option<[f32; 4]>| {
        let path = write(dir.path(), "n.gltf", &gltf_triangle_with(material, &[&map], tangent));
        let mut b = SceneBuilder::new();
        holodeck_sampler::scene::import_file_with(&mut b, &path, Mat4::IDENTITY, &ImportOptions::default()).unwrap();
        b.sky(sun.clone()).unwrap();
        let t = Tracer::new(b.finish(), TraceOptions::default());
        radiance(&t, Vec3::new(0.25, 0.25, 1.0), -Vec3::Z, 64).x
    };
    // Generated from the coordinates, the tangent is +x: the normal faces the sun.
    let generated = seen(None);
    // The file says the tangent is -x: the normal tilts away, 60 degrees from the sun.
    let reversed = seen(Some([-1.0, 0.0, 0.0, 1.0]));
    let along = seen(Some([1.0, 0.0, 0.0, 1.0]));
    assert!((along / generated - 1.0).abs() < 0.01, "{along} {generated}");
    assert!(
        (reversed / generated - 0.5).abs() < 0.02,
        "cos 60 / cos 0: {reversed} / {generated}"
    );
}

#[test]
fn a_clear_coat_turns_a_rough_dielectric_into_polished_plastic_and_leaves_metal_alone() {
    let dir = tempfile::tempdir().unwrap();
    let white = png(&image::RgbaImage::from_pixel(2, 2, image::Rgba([255; 4])));
    let load = |material: &str| {
        let path = write(dir.path(), "c.gltf", &gltf_triangle(material, &[&white]));
        let mut b = SceneBuilder::new();
        holodeck_sampler::scene::import_file_with(&mut b, &path, Mat4::IDENTITY, &ImportOptions::default()).unwrap();
        b.finish()
    };
    // A rough red dielectric (diffuse) under a polished coat: plastic with
    // the coat's roughness, albedo kept.
    let coated = load(
        r#"{"name":"lacquer","pbrMetallicRoughness":{"baseColorFactor":[0.8,0.1,0.1,1],"metallicFactor":0,"roughnessFactor":1},
            "extensions":{"KHR_materials_clearcoat":{"clearcoatFactor":1,"clearcoatRoughnessFactor":0.1,"clearcoatTexture":{"index":0}}}}"#,
    );
    assert_eq!(
        coated.materials[0],
        Material::Plastic {
            albedo: [0.8, 0.1, 0.1],
            roughness: 0.1,
            ior: 1.5
        }
    );
    assert!(
        coated
            .notes
            .iter()
            .any(|n| n.what.contains("clearcoatTexture is not used")),
        "{:?}",
        coated.notes
    );
    // The same without the coat is diffuse; a faint coat (0.2) rounds to none, noted.
    let bare = load(
        r#"{"name":"matte","pbrMetallicRoughness":{"baseColorFactor":[0.8,0.1,0.1,1],"metallicFactor":0,"roughnessFactor":1},
            "extensions":{"KHR_materials_clearcoat":{"clearcoatFactor":0.2}}}"#,
    );
    assert!(
        matches!(bare.materials[0], Material::Lambertian { .. }),
        "{:?}",
        bare.materials[0]
    );
    assert!(
        bare.notes.iter().any(|n| n.what.contains("factor 0.2 rounded to 0")),
        "{:?}",
        bare.notes
    );
    // A coat over metal: the metal alone, noted.
    let metal = load(
        r#"{"name":"car","pbrMetallicRoughness":{"baseColorFactor":[0.9,0.9,0.9,1],"metallicFactor":1,"roughnessFactor":0.5},
            "extensions":{"KHR_materials_clearcoat":{"clearcoatFactor":1}}}"#,
    );
    assert!(
        matches!(metal.materials[0], Material::Metal { .. }),
        "{:?}",
        metal.materials[0]
    );
    assert!(
        metal.notes.iter().any(|n| n.what.contains("over metal")),
        "{:?}",
        metal.notes
    );
}
