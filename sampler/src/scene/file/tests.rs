//! Scene file tests: a scene with a builtin, geometry files and sections;
//! round trips through `write_scene`; errors that name the file and the key.

use super::*;
use crate::scene::export::write_scene;
use crate::scene::hash::content_hash;
use holodeck_protocol::SectionKind;

const OBJ: &str = "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl paint\nf 1 2 3\nusemtl gold\nf 1 3 2\n";
const MTL: &str = "newmtl paint\nKd 0.1 0.2 0.3\nnewmtl gold\nillum 3\nKd 0 0 0\nKs 1 0.8 0.3\n";

const SCENE: &str = r#"
[sky]
type = "constant"
radiance = [0.5, 0.5, 0.5]

[materials.white]
type = "lambertian"
albedo = [0.8, 0.8, 0.8]

[materials.paint]
type = "plastic"
albedo = [0.9, 0.1, 0.1]
roughness = 0.2

[[builtin]]
name = "mandelbulb"
resolution = 12

[[geometry]]
file = "mesh/tri.obj"
material = "white"
translate = [1, 2, 3]
rotate = [90, 0, 90]
scale = 2

[[section]]
kind = "exterior"
origin = [-1, -1, 0]
axes = [[2, 0, 0], [0, 2, 0], [0, 0, 2]]
grid = [10, 10, 10]

[[section]]
origin = [5, 5, 5]
axes = [[6, 0, 0], [0, 4, 0], [0, 0, 2.5]]
"#;

fn scene_dir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("mesh")).unwrap();
    std::fs::write(dir.path().join("mesh/tri.obj"), OBJ).unwrap();
    std::fs::write(dir.path().join("mesh/m.mtl"), MTL).unwrap();
    dir
}

#[test]
fn loads_builtin_geometry_materials_sky_and_sections() {
    let dir = scene_dir();
    let path = dir.path().join("scene.toml");
    std::fs::write(&path, SCENE).unwrap();
    let s = load_scene(&path).unwrap();
    assert_eq!(
        &s.material_names[..2],
        ["white", "paint"],
        "file materials first, in file order"
    );
    assert_eq!(s.sky, Sky::Constant { radiance: [0.5; 3] });
    assert_eq!(s.sections.len(), 2);
    assert_eq!(s.sections[0].grid(), [10, 10, 10]);
    assert_eq!(s.sections[0].kind(), SectionKind::Exterior);
    assert_eq!(s.sections[1].kind(), SectionKind::Interior);
    assert!((100_000..225_000).contains(&s.sections[1].beam_count()));
    let bulb = s.material_names.iter().position(|n| n == "bulb").unwrap() as u32;
    let bulb_tris = s.triangles.iter().filter(|t| t.material == bulb).count();
    assert!(bulb_tris > 100);
    // The OBJ's two triangles come last: scaled by 2, rotated x then z by 90°, translated.
    let n = s.triangles.len();
    assert_eq!(n, bulb_tris + 2 + 2, "bulb, ground quad, the OBJ");
    let [a, b, c] = s.vertices(n - 2);
    let close = |p: Vec3, q: Vec3| (p - q).length() < 1e-5;
    assert!(close(a, Vec3::new(1.0, 2.0, 3.0)), "{a}");
    assert!(close(b, Vec3::new(1.0, 4.0, 3.0)), "x -> y: {b}");
    assert!(close(c, Vec3::new(1.0, 2.0, 5.0)), "y -> z -> z: {c}");
    let mat = |t: usize| s.material_names[s.triangles[t].material as usize].as_str();
    assert_eq!(mat(n - 2), "paint", "the scene's paint overrides the MTL's");
    assert_eq!(
        s.materials[1],
        Material::Plastic {
            albedo: [0.9, 0.1, 0.1],
            roughness: 0.2,
            ior: 1.5
        }
    );
    assert_eq!(mat(n - 1), "gold");
    assert!(matches!(
        s.materials[s.triangles[n - 1].material as usize],
        Material::Metal { .. }
    ));
}

#[test]
fn builtin_sky_and_sections_apply_when_the_file_has_none() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    std::fs::write(
        &path,
        "[[builtin]]\nname = \"room\"\n\n[materials.wall]\ntype = \"lambertian\"\nalbedo = [0.2, 0.2, 0.2]\n",
    )
    .unwrap();
    let s = load_scene(&path).unwrap();
    assert!(matches!(s.sky, Sky::Sun { .. }));
    assert_eq!(s.sections.len(), 1);
    assert_eq!(s.material_names[0], "wall");
    assert_eq!(
        s.materials[0],
        Material::lambertian([0.2; 3]),
        "the file restyles the builtin's walls"
    );
    assert!(s.triangles.iter().any(|t| t.material == 0));
}

#[test]
fn generated_scenes_round_trip_with_the_same_hash() {
    let dir = tempfile::tempdir().unwrap();
    for (name, params) in [
        ("room", GenParams::default()),
        (
            "mandelbulb",
            GenParams {
                resolution: Some(16),
                ..Default::default()
            },
        ),
        (
            "landscape",
            GenParams {
                triangles: Some(20_000),
                seed: 3,
                ..Default::default()
            },
        ),
        (
            "gallery",
            GenParams {
                triangles: Some(20_000),
                ..Default::default()
            },
        ),
    ] {
        let s = gen::generate(name, &params).unwrap();
        let path = dir.path().join(format!("{name}.toml"));
        let ply = write_scene(&s, &path).unwrap();
        assert_eq!(ply, dir.path().join(format!("{name}.ply")));
        let back = load_scene(&path).unwrap();
        assert_eq!(back.triangles.len(), s.triangles.len());
        assert_eq!(back.material_names, s.material_names);
        assert_eq!(back.materials, s.materials);
        assert_eq!(back.sky, s.sky);
        assert_eq!(back.sections, s.sections);
        assert_eq!(back.uvs, s.uvs, "{name}: texture coordinates read back bit for bit");
        assert_eq!(
            back.maps.iter().filter(|m| !m.is_empty()).count(),
            s.maps.iter().filter(|m| !m.is_empty()).count()
        );
        assert_eq!(content_hash(&back), content_hash(&s), "{name}");
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.contains(&content_hash(&s)));
        assert!(
            !text.contains("0.800000011920929"),
            "floats written in their short form:\n{text}"
        );
        if name == "gallery" {
            assert!(
                text.contains("[textures.rug]") && text.contains("bump_scale = 0.5"),
                "{text}"
            );
            assert!(
                dir.path().join("gallery-0.png").is_file(),
                "textures written beside the scene"
            );
        }
    }
}

#[test]
fn texture_tables_texture_ply_geometry_and_bad_ones_name_the_table() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    image::RgbaImage::from_pixel(2, 2, image::Rgba([255, 0, 0, 255]))
        .save(p.join("red.png"))
        .unwrap();
    // An ASCII PLY with s, t texture coordinates (t upward, as Blender writes it).
    std::fs::write(
        p.join("q.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
         property float s\nproperty float t\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
         0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 0.25\n3 0 1 2\n",
    )
    .unwrap();
    let scene = |textures: &str| {
        let text = format!(
            "[materials.paint]\ntype = \"lambertian\"\nalbedo = [1, 1, 1]\n\n[[geometry]]\nfile = \"q.ply\"\nmaterial = \"paint\"\n\n{textures}"
        );
        std::fs::write(p.join("s.toml"), text).unwrap();
        load_scene(&p.join("s.toml"))
    };
    let s = scene("[textures.paint]\nbase_color = \"red.png\"\nscale = [2, 2]\nwrap = \"clamp\"\n").unwrap();
    assert_eq!(s.uvs[2], glam::Vec2::new(0.0, 0.75), "t flipped to grow downward");
    let maps = s.maps_of(0).unwrap();
    let base = maps.base_color.unwrap();
    assert_eq!(
        (base.transform.scale, base.wrap),
        ([2.0, 2.0], [crate::scene::texture::Wrap::Clamp; 2])
    );
    let err = scene("[textures.nothing]\nbase_color = \"red.png\"\n").unwrap_err();
    assert!(err.to_string().contains("nothing"), "{err}");
    let err = scene("[textures.paint]\nbase_color = \"blue.png\"\n").unwrap_err();
    assert!(
        err.to_string().contains("[textures.paint] base_color") && err.to_string().contains("blue.png"),
        "{err}"
    );
}

#[test]
fn errors_name_the_file_and_the_key() {
    let dir = scene_dir();
    let path = dir.path().join("bad.toml");
    let load = |text: &str| {
        std::fs::write(&path, text).unwrap();
        load_scene(&path).unwrap_err().to_string()
    };
    let err = load("[[geometry]]\nfile = \"mesh/tri.obj\"\nmaterial = \"white\"\ncolour = 3\n");
    assert!(err.contains("bad.toml") && err.contains("colour"), "{err}");
    let err = load("[materials.white]\ntype = \"lambertian\"\nalbedo = [1, 1, 1]\nshine = 1\n");
    assert!(err.contains("bad.toml") && err.contains("shine"), "{err}");
    let err = load("[[section]]\norigin = [0, 0, 0]\naxes = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]\nbeam = 5\n");
    assert!(err.contains("bad.toml") && err.contains("beam"), "{err}");
    let err = load("skyy = 1\n");
    assert!(err.contains("skyy"), "{err}");

    std::fs::write(&path, "[materials.white]\ntype = \"lambertian\"\nalbedo = [1, 1, 1]\n[materials.red]\ntype = \"lambertian\"\nalbedo = [1, 0, 0]\n[[geometry]]\nfile = \"mesh/tri.obj\"\nmaterial = \"blue\"\n").unwrap();
    let e = load_scene(&path).unwrap_err();
    assert!(
        matches!(&e, SceneError::UnknownMaterial { name, known, .. } if name == "blue" && known == "white, red"),
        "{e}"
    );
    assert!(
        e.to_string().contains("bad.toml") && e.to_string().contains("tri.obj"),
        "{e}"
    );

    let err = load("[[builtin]]\nname = \"castle\"\n");
    assert!(
        err.contains("bad.toml") && err.contains("castle") && err.contains("landscape"),
        "{err}"
    );
    let err = load("[materials.hot]\ntype = \"lambertian\"\nalbedo = [2, 1, 1]\n");
    assert!(
        err.contains("bad.toml") && err.contains("hot") && err.contains("albedo"),
        "{err}"
    );
    let err = load("[[geometry]]\nfile = \"mesh/tri.obj\"\nscale = 0\n");
    assert!(err.contains("bad.toml") && err.contains("scale"), "{err}");
    std::fs::write(&path, "[[geometry]]\nfile = \"mesh/tri.obj\"\nrotate = [0, nan, 0]\n").unwrap();
    let e = load_scene(&path).unwrap_err();
    assert!(
        matches!(&e, SceneError::Transform { source: TransformError::Rotate(r), .. } if r.y.is_nan()),
        "{e}"
    );
    let err = load("[[section]]\norigin = [0, 0, 0]\naxes = [[1, 0, 0], [2, 0, 0], [0, 0, 1]]\n");
    assert!(err.contains("bad.toml") && err.contains("[[section]] 1"), "{err}");
    let err = load("[[geometry]]\nfile = \"mesh/none.obj\"\nmaterial = \"x\"\n");
    assert!(err.contains("bad.toml") && err.contains("\"x\""), "{err}");
    std::fs::remove_file(&path).unwrap();
    assert!(load_scene(&path).unwrap_err().to_string().contains("bad.toml"));
}

#[test]
fn geometry_up_axes_default_by_format_and_can_be_overridden() {
    let dir = scene_dir();
    std::fs::write(
        dir.path().join("mesh/box.gltf"),
        crate::scene::import::tests::gltf_box(),
    )
    .unwrap();
    let path = dir.path().join("up.toml");
    let bounds = |geometry: &str| {
        let text = format!("[materials.white]\ntype = \"lambertian\"\nalbedo = [0.5, 0.5, 0.5]\n[[geometry]]\nmaterial = \"white\"\n{geometry}");
        std::fs::write(&path, text).unwrap();
        let (lo, hi) = load_scene(&path).unwrap().bounds();
        hi - lo
    };
    // glTF: 1 wide, 2 tall in its +y, 3 deep; the scene is +z up.
    assert_eq!(bounds("file = \"mesh/box.gltf\"\n"), Vec3::new(1.0, 3.0, 2.0));
    assert_eq!(
        bounds("file = \"mesh/box.gltf\"\nup = \"z\"\n"),
        Vec3::new(1.0, 2.0, 3.0)
    );
    // The conversion comes first: scale then applies along the scene's axes.
    assert_eq!(
        bounds("file = \"mesh/box.gltf\"\nscale = [1, 1, 10]\n"),
        Vec3::new(1.0, 3.0, 20.0)
    );
    // OBJ is taken as +z up unless the entry says otherwise: the triangle in
    // the xy plane stands up in the xz plane.
    assert_eq!(bounds("file = \"mesh/tri.obj\"\n"), Vec3::new(1.0, 1.0, 0.0));
    assert_eq!(
        bounds("file = \"mesh/tri.obj\"\nup = \"y\"\n"),
        Vec3::new(1.0, 0.0, 1.0)
    );
    std::fs::write(&path, "[[geometry]]\nfile = \"mesh/tri.obj\"\nup = \"x\"\n").unwrap();
    let err = load_scene(&path).unwrap_err().to_string();
    assert!(err.contains("up.toml") && err.contains("unknown variant `x`"), "{err}");
}

#[test]
fn a_row_major_matrix_places_geometry_and_bad_matrices_say_why() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("t.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let scene = |matrix: &str| {
        let text = format!(
            "[materials.m]\ntype = \"lambertian\"\nalbedo = [0.5, 0.5, 0.5]\n\n[[geometry]]\nfile = \"t.obj\"\nmaterial = \"m\"\ntranslate = [0, 0, 10]\nmatrix = {matrix}\n"
        );
        let path = dir.path().join("s.toml");
        std::fs::write(&path, text).unwrap();
        load_scene(&path)
    };
    // Rotate 90 degrees about z, then move by (5, 6, 7), written row-major;
    // `translate` applies after it.
    let s = scene("[[0, -1, 0, 5], [1, 0, 0, 6], [0, 0, 1, 7], [0, 0, 0, 1]]").unwrap();
    assert_eq!(
        s.vertices(0),
        [
            Vec3::new(5.0, 6.0, 17.0),
            Vec3::new(5.0, 7.0, 17.0),
            Vec3::new(4.0, 6.0, 17.0)
        ]
    );
    let err = scene("[[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 1, 0], [5, 6, 7, 1]]").unwrap_err();
    assert!(err.to_string().contains("column-major"), "{err}");
    let err = scene("[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 1]]").unwrap_err();
    assert!(err.to_string().contains("singular"), "{err}");
    let err = scene("[[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 2]]").unwrap_err();
    assert!(err.to_string().contains("affine"), "{err}");
    assert!(err.to_string().contains("[[geometry]] 1"), "the entry is named: {err}");
}
