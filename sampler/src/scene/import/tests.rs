//! Importer tests on small files written into a temporary directory.

use std::collections::HashMap;
use std::path::Path;

use glam::{Mat4, Vec3};

use super::*;
use crate::scene::Scene;

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn material_of(s: &Scene, t: usize) -> (&str, &Material) {
    let m = s.triangles[t].material as usize;
    (&s.material_names[m], &s.materials[m])
}

const MTL: &str = "\
newmtl red
Kd 1.5 0 0
newmtl lamp
Kd 0 0 0
Ke 5 4 3
newmtl glassy
Kd 1 1 1
d 0.5
Ni 1.33
newmtl shiny
Kd 0.2 0.3 0.4
Ks 0.5 0.5 0.5
Ns 98
newmtl chrome
illum 3
Kd 0 0 0
Ks 0.9 0.8 0.7
Ns 0
newmtl white
Kd 0.1 0.1 0.1
";

const OBJ: &str = "\
mtllib scene.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
f 1 2 3
usemtl red
f 1 2 3 4
usemtl lamp
f 1 2 3
usemtl glassy
f 1 2 3
usemtl shiny
f 1 2 3
usemtl chrome
f 1 2 3
usemtl white
f 1 2 3
";

#[test]
fn obj_with_mtl_materials_overrides_and_default() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "scene.mtl", MTL);
    let obj = write(dir.path(), "scene.obj", OBJ);
    let mut b = SceneBuilder::new();
    let grey = b.material("grey", Material::lambertian([0.5; 3])).unwrap();
    let white = b.material("white", Material::lambertian([0.9; 3])).unwrap();
    let overrides = HashMap::from([("white".to_string(), white)]);
    let t = Mat4::from_translation(Vec3::new(10.0, 0.0, 0.0));
    import_file(&mut b, &obj, t, Some(grey), &overrides).unwrap();
    let s = b.finish();
    assert_eq!(s.triangles.len(), 8, "a quad makes two triangles");
    assert_eq!(
        s.vertices(0),
        [
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(11.0, 0.0, 0.0),
            Vec3::new(11.0, 1.0, 0.0)
        ]
    );
    assert_eq!(material_of(&s, 0).0, "grey", "faces before any usemtl get the default");
    assert_eq!(material_of(&s, 1), ("red", &Material::lambertian([1.0, 0.0, 0.0])));
    assert_eq!(material_of(&s, 2).0, "red");
    assert_eq!(
        material_of(&s, 3),
        (
            "lamp",
            &Material::Emitter {
                radiance: [5.0, 4.0, 3.0]
            }
        )
    );
    assert_eq!(
        material_of(&s, 4),
        (
            "glassy",
            &Material::Glass {
                ior: 1.33,
                color: [1.0; 3],
                thin: false
            }
        )
    );
    let rough = (2.0f32 / 100.0).sqrt();
    assert_eq!(
        material_of(&s, 5),
        (
            "shiny",
            &Material::Plastic {
                albedo: [0.2, 0.3, 0.4],
                roughness: rough,
                ior: 1.5
            }
        )
    );
    assert_eq!(
        material_of(&s, 6),
        (
            "chrome",
            &Material::Metal {
                color: [0.9, 0.8, 0.7],
                roughness: 1.0
            }
        )
    );
    assert_eq!(
        material_of(&s, 7),
        ("white", &Material::lambertian([0.9; 3])),
        "the scene's white wins"
    );
}

#[test]
fn obj_same_material_name_in_two_files_with_different_parameters_is_renamed() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "scene.mtl", MTL);
    let obj = write(dir.path(), "scene.obj", OBJ);
    let other = dir.path().join("other");
    std::fs::create_dir(&other).unwrap();
    write(&other, "scene.mtl", MTL.replace("Kd 1.5 0 0", "Kd 0 1 0"));
    let obj2 = write(&other, "scene.obj", OBJ);
    let mut b = SceneBuilder::new();
    let grey = b.material("grey", Material::lambertian([0.5; 3])).unwrap();
    import_file(&mut b, &obj, Mat4::IDENTITY, Some(grey), &HashMap::new()).unwrap();
    import_file(&mut b, &obj, Mat4::IDENTITY, Some(grey), &HashMap::new()).unwrap();
    import_file(&mut b, &obj2, Mat4::IDENTITY, Some(grey), &HashMap::new()).unwrap();
    let s = b.finish();
    assert_eq!(
        s.material_names.iter().filter(|n| n.starts_with("red")).count(),
        2,
        "{:?}",
        s.material_names
    );
    assert_eq!(material_of(&s, 17), ("red#2", &Material::lambertian([0.0, 1.0, 0.0])));
    assert_eq!(material_of(&s, 9).0, "red", "the same parameters share one material");
}

#[test]
fn obj_missing_mtl_uses_default_or_says_which_file_needs_one() {
    let dir = tempfile::tempdir().unwrap();
    let obj = write(dir.path(), "lonely.obj", OBJ);
    let mut b = SceneBuilder::new();
    let grey = b.material("grey", Material::lambertian([0.5; 3])).unwrap();
    import_file(&mut b, &obj, Mat4::IDENTITY, Some(grey), &HashMap::new()).unwrap();
    let s = b.finish();
    assert_eq!(s.triangles.len(), 8);
    assert!(s.triangles.iter().all(|t| t.material == grey));

    let err = import_file(&mut SceneBuilder::new(), &obj, Mat4::IDENTITY, None, &HashMap::new()).unwrap_err();
    assert!(matches!(err, SceneError::MissingMaterial { .. }), "{err}");
    assert!(err.to_string().contains("lonely.obj"), "{err}");
}

#[test]
fn malformed_and_missing_files_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let none = HashMap::new();
    let mut b = SceneBuilder::new();
    let m = b.material("m", Material::lambertian([0.5; 3])).unwrap();
    let cases = [
        write(dir.path(), "bad_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n"),
        write(dir.path(), "garbage.gltf", "{ this is not json"),
        write(dir.path(), "garbage.glb", b"glTF\x02\x00\x00\x00garbage"),
        write(dir.path(), "garbage.ply", "ply\nformat ascii 1.0\nelement vertex one\nend_header\n"),
        write(dir.path(), "short.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n"),
        write(dir.path(), "noface.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n"),
        dir.path().join("missing.obj"),
        dir.path().join("missing.ply"),
        dir.path().join("missing.glb"),
        write(dir.path(), "model.stl", "solid"),
    ];
    for path in &cases {
        let err = import_file(&mut b, path, Mat4::IDENTITY, Some(m), &none).unwrap_err();
        let name = path.file_name().unwrap().to_str().unwrap();
        assert!(err.to_string().contains(name), "{name}: {err}");
        if name.starts_with("missing") {
            assert!(matches!(err, SceneError::Io { .. }), "{err}");
        }
    }
    assert!(matches!(
        import_file(&mut b, &cases[9], Mat4::IDENTITY, Some(m), &none),
        Err(SceneError::UnsupportedFormat { .. })
    ));
    assert_eq!(b.finish().triangles.len(), 0, "nothing half-imported");
}

/// The PLY test mesh: a unit quad (fan-triangulated) with material 1 and a triangle with material 0.
const PLY_VERTICES: [[f64; 3]; 5] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
    [0.5, 0.5, 2.25],
];

fn ply_header(format: &str) -> String {
    format!(
        "ply\nformat {format} 1.0\ncomment test\nelement vertex 5\nproperty double x\nproperty double y\nproperty double z\n\
         property uchar red\nelement face 2\nproperty list uchar int vertex_indices\nproperty ushort material_index\n\
         element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n"
    )
}

fn ply_binary(big: bool) -> Vec<u8> {
    let mut out = ply_header(if big {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    })
    .into_bytes();
    let f64b = |v: f64| if big { v.to_be_bytes() } else { v.to_le_bytes() };
    let i32b = |v: i32| if big { v.to_be_bytes() } else { v.to_le_bytes() };
    let u16b = |v: u16| if big { v.to_be_bytes() } else { v.to_le_bytes() };
    for v in PLY_VERTICES {
        for c in v {
            out.extend(f64b(c));
        }
        out.push(200);
    }
    out.push(4);
    for i in [0, 1, 2, 3] {
        out.extend(i32b(i));
    }
    out.extend(u16b(1));
    out.push(3);
    for i in [0, 1, 4] {
        out.extend(i32b(i));
    }
    out.extend(u16b(0));
    out.extend(i32b(0));
    out.extend(i32b(4));
    out
}

fn import_ply(path: &Path) -> Result<Scene, SceneError> {
    import_ply_with(path, Mat4::from_scale(Vec3::splat(2.0)))
}

fn import_ply_with(path: &Path, transform: Mat4) -> Result<Scene, SceneError> {
    let mut b = SceneBuilder::new();
    let a = b.material("a", Material::lambertian([0.5; 3])).unwrap();
    let c = b.material("c", Material::Mirror { color: [0.9; 3] }).unwrap();
    let options = ImportOptions {
        default_material: None,
        overrides: None,
        face_materials: &[c, a],
        up: None,
    };
    import_file_with(&mut b, path, transform, &options)?;
    Ok(b.finish())
}

#[test]
fn ply_ascii_and_binary_of_both_endiannesses_agree() {
    let dir = tempfile::tempdir().unwrap();
    let mut ascii = ply_header("ascii");
    for v in PLY_VERTICES {
        ascii += &format!("{} {} {} 200\n", v[0], v[1], v[2]);
    }
    ascii += "4 0 1 2 3 1\n3 0 1 4 0\n0 4\n";
    let files = [
        write(dir.path(), "a.ply", ascii),
        write(dir.path(), "le.ply", ply_binary(false)),
        write(dir.path(), "be.ply", ply_binary(true)),
    ];
    let scenes: Vec<Scene> = files.iter().map(|f| import_ply(f).unwrap()).collect();
    let s = &scenes[0];
    assert_eq!(s.triangles.len(), 3);
    assert_eq!(s.positions[4], Vec3::new(1.0, 1.0, 4.5), "scaled by 2");
    assert_eq!(s.triangles[0].v, [0, 1, 2]);
    assert_eq!(s.triangles[1].v, [0, 2, 3]);
    assert_eq!(s.triangles[2].v, [0, 1, 4]);
    assert_eq!(
        [
            s.triangles[0].material,
            s.triangles[1].material,
            s.triangles[2].material
        ],
        [0, 0, 1]
    );
    for other in &scenes[1..] {
        assert_eq!(other.positions, s.positions);
        assert_eq!(other.triangles, s.triangles);
    }
}

#[test]
fn ply_truncated_bad_material_and_missing_list_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let full = ply_binary(false);
    for cut in [full.len() - 12, full.len() - 30, full.len() - 100] {
        let p = write(dir.path(), "cut.ply", &full[..cut]);
        let err = import_ply(&p).unwrap_err();
        assert!(matches!(err, SceneError::Parse { .. }), "{err}");
        assert!(
            err.to_string().contains("cut.ply") && err.to_string().contains("truncated"),
            "{err}"
        );
    }
    let mut bad = full.clone();
    let at = bad.len() - 8 - 2 - 12 - 1 - 2;
    bad[at..at + 2].copy_from_slice(&7u16.to_le_bytes());
    let err = import_ply(&write(dir.path(), "badmat.ply", bad)).unwrap_err();
    assert!(err.to_string().contains("material_index 7"), "{err}");
    let mut b = SceneBuilder::new();
    let err = import_file(
        &mut b,
        &write(dir.path(), "nomat.ply", &full),
        Mat4::IDENTITY,
        None,
        &HashMap::new(),
    )
    .unwrap_err();
    assert!(matches!(err, SceneError::MissingMaterial { .. }), "{err}");
}

/// Standard base64 (the test's glTF embeds its buffer as a data URI).
fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for c in bytes.chunks(3) {
        let n =
            (u32::from(c[0]) << 16) | (u32::from(*c.get(1).unwrap_or(&0)) << 8) | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                out.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// A glTF document: two nodes (a translated parent with a scaled child), one
/// mesh with a triangle-list primitive per material, u8/u16/u32 indices, and a
/// line primitive that must be skipped.
fn gltf_parts() -> (String, Vec<u8>) {
    let mut bin = Vec::new();
    for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]] {
        for c in p {
            bin.extend(c.to_le_bytes());
        }
    }
    bin.extend([0u8, 1, 2, 0]); // u8 indices at 48 (3 used)
    for i in [0u16, 2, 3, 0] {
        bin.extend(i.to_le_bytes()); // u16 at 52 (3 used)
    }
    for i in [0u32, 1, 2, 0, 2, 3] {
        bin.extend(i.to_le_bytes()); // u32 at 60
    }
    let json = r#"{
      "asset": {"version": "2.0"},
      "scene": 0,
      "scenes": [{"nodes": [0]}],
      "nodes": [
        {"translation": [0, 0, 5], "children": [1], "mesh": 0},
        {"scale": [2, 2, 2], "mesh": 0}
      ],
      "meshes": [{"primitives": [
        {"attributes": {"POSITION": 0}, "indices": 1, "material": 0},
        {"attributes": {"POSITION": 0}, "indices": 2, "material": 1},
        {"attributes": {"POSITION": 0}, "indices": 3, "material": 2},
        {"attributes": {"POSITION": 0}, "material": 3, "mode": 1}
      ]}],
      "materials": [
        {"name": "neon", "emissiveFactor": [2, 1, 0.5]},
        {"pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.8, 0.7, 1], "metallicFactor": 1, "roughnessFactor": 0.2}},
        {"name": "satin", "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.4, 0.6, 1], "metallicFactor": 0, "roughnessFactor": 0.5}},
        {"name": "chalk", "pbrMetallicRoughness": {"metallicFactor": 0, "roughnessFactor": 1}}
      ],
      "buffers": [BUFFER],
      "bufferViews": [
        {"buffer": 0, "byteOffset": 0, "byteLength": 48},
        {"buffer": 0, "byteOffset": 48, "byteLength": 3},
        {"buffer": 0, "byteOffset": 52, "byteLength": 6},
        {"buffer": 0, "byteOffset": 60, "byteLength": 24}
      ],
      "accessors": [
        {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
        {"bufferView": 1, "componentType": 5121, "count": 3, "type": "SCALAR"},
        {"bufferView": 2, "componentType": 5123, "count": 3, "type": "SCALAR"},
        {"bufferView": 3, "componentType": 5125, "count": 6, "type": "SCALAR"}
      ]
    }"#;
    (json.to_string(), bin)
}

/// A glTF box 1 wide (x), 2 tall (y, glTF's up) and 3 deep (z) with its
/// low corner at the origin, its buffer embedded.
pub(crate) fn gltf_box() -> String {
    let mut bin = Vec::new();
    for k in 0..8u32 {
        let corner = [k & 1, (k >> 1) & 1, (k >> 2) & 1];
        for (c, size) in corner.iter().zip([1.0f32, 2.0, 3.0]) {
            bin.extend((*c as f32 * size).to_le_bytes());
        }
    }
    // Two triangles per face, wound outward.
    let faces: [[u16; 4]; 6] = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    for [a, b, c, d] in faces {
        for i in [a, b, c, a, c, d] {
            bin.extend(i.to_le_bytes());
        }
    }
    format!(
        r#"{{
      "asset": {{"version": "2.0"}},
      "scenes": [{{"nodes": [0]}}],
      "nodes": [{{"mesh": 0}}],
      "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1}}]}}],
      "buffers": [{{"byteLength": {}, "uri": "data:application/octet-stream;base64,{}"}}],
      "bufferViews": [
        {{"buffer": 0, "byteOffset": 0, "byteLength": 96}},
        {{"buffer": 0, "byteOffset": 96, "byteLength": 72}}
      ],
      "accessors": [
        {{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3", "min": [0, 0, 0], "max": [1, 2, 3]}},
        {{"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}}
      ]
    }}"#,
        bin.len(),
        base64(&bin)
    )
}

#[test]
fn gltf_models_stand_up_in_the_z_up_scene() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "box.gltf", gltf_box());
    let import = |up: Option<UpAxis>| {
        let mut b = SceneBuilder::new();
        let white = b.material("white", Material::lambertian([0.5; 3])).unwrap();
        let options = ImportOptions {
            default_material: Some(white),
            up,
            ..ImportOptions::default()
        };
        import_file_with(&mut b, &path, Mat4::IDENTITY, &options).unwrap();
        let s = b.finish();
        assert_eq!(s.triangles.len(), 12);
        s.bounds()
    };
    // glTF's +y is up: the box is 1 wide, 3 deep and 2 tall, and its
    // depth (glTF's +z, toward the viewer) runs along -y.
    let (lo, hi) = import(None);
    assert_eq!(hi - lo, Vec3::new(1.0, 3.0, 2.0));
    assert_eq!((lo, hi), (Vec3::new(0.0, -3.0, 0.0), Vec3::new(1.0, 0.0, 2.0)));
    assert_eq!(import(Some(UpAxis::Y)), (lo, hi));
    // A file whose author used z up is taken as it is.
    let (lo, hi) = import(Some(UpAxis::Z));
    assert_eq!((lo, hi), (Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0)));
}

#[test]
fn y_up_conversion_keeps_handedness_and_outward_faces() {
    let m = UpAxis::Y.to_z_up();
    assert_eq!(m.transform_point3(Vec3::new(1.0, 2.0, 3.0)), Vec3::new(1.0, -3.0, 2.0));
    assert!(m.determinant() > 0.0, "a rotation, not a mirror");
    assert_eq!(UpAxis::Z.to_z_up(), Mat4::IDENTITY);
    assert_eq!(UpAxis::default_for(Path::new("a.GLB")), UpAxis::Y);
    assert_eq!(UpAxis::default_for(Path::new("a.obj")), UpAxis::Z);
}

fn check_gltf_scene(s: &Scene) {
    // Each node draws 1 + 1 + 2 triangles; the line primitive is skipped.
    assert_eq!(s.triangles.len(), 8, "{:?}", s.material_names);
    // glTF (x, y, z) lands at (x, -z, y): glTF's up is the scene's +z.
    let all: Vec<Vec3> = (0..8).flat_map(|t| s.vertices(t)).collect();
    assert!(all.contains(&Vec3::new(1.0, -5.0, 1.0)), "parent: translated");
    assert!(
        all.contains(&Vec3::new(2.0, -5.0, 2.0)),
        "child: scaled, then the parent's translation"
    );
    let find = |name: &str| &s.materials[s.material_names.iter().position(|n| n == name).unwrap()];
    assert_eq!(
        find("neon"),
        &Material::Emitter {
            radiance: [2.0, 1.0, 0.5]
        }
    );
    assert_eq!(
        find("gltf:1"),
        &Material::Metal {
            color: [0.9, 0.8, 0.7],
            roughness: 0.2
        }
    );
    assert_eq!(
        find("satin"),
        &Material::Plastic {
            albedo: [0.2, 0.4, 0.6],
            roughness: 0.5,
            ior: 1.5
        }
    );
    assert!(
        !s.material_names.iter().any(|n| n == "chalk"),
        "only used materials are added"
    );
}

#[test]
fn gltf_embedded_buffer_nodes_transforms_and_materials() {
    let dir = tempfile::tempdir().unwrap();
    let (json, bin) = gltf_parts();
    let uri = format!(
        r#"{{"byteLength": {}, "uri": "data:application/octet-stream;base64,{}"}}"#,
        bin.len(),
        base64(&bin)
    );
    let path = write(dir.path(), "model.gltf", json.replace("BUFFER", &uri));
    let mut b = SceneBuilder::new();
    import_file(&mut b, &path, Mat4::IDENTITY, None, &HashMap::new()).unwrap();
    check_gltf_scene(&b.finish());
}

#[test]
fn glb_binary_container() {
    let dir = tempfile::tempdir().unwrap();
    let (json, mut bin) = gltf_parts();
    let mut json = json
        .replace("BUFFER", &format!(r#"{{"byteLength": {}}}"#, bin.len()))
        .into_bytes();
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let mut glb = b"glTF".to_vec();
    glb.extend(2u32.to_le_bytes());
    glb.extend(((12 + 8 + json.len() + 8 + bin.len()) as u32).to_le_bytes());
    glb.extend((json.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&json);
    glb.extend((bin.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(&bin);
    let path = write(dir.path(), "model.glb", &glb);
    let mut b = SceneBuilder::new();
    import_file(&mut b, &path, Mat4::IDENTITY, None, &HashMap::new()).unwrap();
    check_gltf_scene(&b.finish());

    let err = import_file(
        &mut SceneBuilder::new(),
        &write(dir.path(), "cut.glb", &glb[..glb.len() - 20]),
        Mat4::IDENTITY,
        None,
        &HashMap::new(),
    )
    .unwrap_err();
    assert!(err.to_string().contains("cut.glb"), "{err}");
}

#[test]
fn written_ply_reads_back_bit_exact() {
    let dir = tempfile::tempdir().unwrap();
    let mut b = SceneBuilder::new();
    let a = b.material("a", Material::lambertian([0.5; 3])).unwrap();
    let c = b.material("c", Material::Mirror { color: [0.9; 3] }).unwrap();
    let p = [
        Vec3::new(0.1, -0.0, 1e-7),
        Vec3::new(3.3, 0.2, 0.0),
        Vec3::new(0.0, 7.1, 1e6),
    ];
    b.add_mesh("t", &p, &[[0, 1, 2], [2, 1, 0]], &[a, c], Mat4::IDENTITY)
        .unwrap();
    let s = b.finish();
    let path = dir.path().join("out.ply");
    crate::scene::export::write_ply(&s, &path).unwrap();
    let back = import_ply_with(&path, Mat4::IDENTITY).unwrap();
    assert_eq!(back.triangles.len(), 2);
    let bits = |v: &[Vec3]| v.iter().map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
    assert_eq!(
        bits(&back.positions),
        bits(&s.positions),
        "-0.0 and tiny values survive"
    );
    // Material index k maps through the list [c, a].
    assert_eq!(back.triangles[0].material, 1);
    assert_eq!(back.triangles[1].material, 0);
}
