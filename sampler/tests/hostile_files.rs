//! Files crafted to crash or stall importers: each must give an error that
//! names the file (or import with a warning), never a panic, a hang or an
//! unbounded read.

use std::collections::HashMap;
use std::path::Path;

use glam::Mat4;
use holodeck_sampler::scene::import::import_file;
use holodeck_sampler::{Material, SceneBuilder};

fn import(path: &Path) -> Result<usize, String> {
    let mut b = SceneBuilder::new();
    let m = b
        .material("default", Material::lambertian([0.5; 3]))
        .map_err(|e| e.to_string())?;
    import_file(&mut b, path, Mat4::IDENTITY, Some(m), &HashMap::new()).map_err(|e| e.to_string())?;
    Ok(b.finish().triangles.len())
}

fn expect_error(path: &Path, needle: &str) {
    let e = import(path).expect_err("a hostile file must be refused");
    assert!(e.contains(&path.display().to_string()), "error must name the file: {e}");
    assert!(e.contains(needle), "expected {needle:?} in: {e}");
}

const TRIANGLE_GLTF_HEAD: &str = r#"{"asset":{"version":"2.0"},
 "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}],
 "bufferViews":[{"buffer":0,"byteLength":36}],
 "meshes":[{"primitives":[{"attributes":{"POSITION":0}}]}],"#;

#[test]
fn gltf_with_bad_uris_and_node_graphs_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    for (name, buffers, nodes, needle) in [
        (
            "percent.gltf",
            r#"[{"byteLength":36,"uri":"%FF.bin"}]"#,
            r#"[{"mesh":0}]"#,
            "not a relative file path",
        ),
        (
            "device.gltf",
            r#"[{"byteLength":36,"uri":"file:///dev/zero"}]"#,
            r#"[{"mesh":0}]"#,
            "not a relative file path",
        ),
        (
            "escape.gltf",
            r#"[{"byteLength":36,"uri":"../../etc/passwd"}]"#,
            r#"[{"mesh":0}]"#,
            "not a relative file path",
        ),
        (
            "shared.gltf",
            r#"[{"byteLength":36,"uri":"data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}]"#,
            r#"[{"children":[1,1]},{"mesh":0}]"#,
            "not a tree",
        ),
    ] {
        let path = dir.path().join(name);
        let scene_nodes = r#""scenes":[{"nodes":[0]}],"scene":0}"#;
        let text = format!("{TRIANGLE_GLTF_HEAD} \"buffers\":{buffers}, \"nodes\":{nodes}, {scene_nodes}");
        std::fs::write(&path, text).unwrap();
        expect_error(&path, needle);
    }
}

#[test]
fn ply_with_absurd_headers_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let huge = dir.path().join("huge.ply");
    std::fs::write(
        &huge,
        "ply\nformat ascii 1.0\nelement vertex 99999999999999999999\nproperty float x\nend_header\n",
    )
    .unwrap();
    let e = import(&huge).expect_err("refused");
    assert!(e.contains("huge.ply"), "{e}");
    let empty = dir.path().join("empty.ply");
    std::fs::write(
        &empty,
        "ply\nformat binary_little_endian 1.0\nelement pad 18446744073709551615\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
    )
    .unwrap();
    expect_error(&empty, "no properties");
}

#[test]
fn obj_with_broken_or_device_material_libraries() {
    let dir = tempfile::tempdir().unwrap();
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    // A material library that is a device: skipped with a warning, default material used.
    let dev = dir.path().join("dev.obj");
    std::fs::write(&dev, format!("mtllib /dev/zero\n{tri}usemtl x\nf 1 2 3\n")).unwrap();
    assert_eq!(import(&dev).unwrap(), 1);
    // A malformed material library line (one number where Kd wants three)
    // is a broken library like any other: skipped with a warning, and the
    // faces get the default material.
    std::fs::write(dir.path().join("bad.mtl"), "newmtl x\nKd 0.5\n").unwrap();
    let bad = dir.path().join("bad.obj");
    std::fs::write(&bad, format!("mtllib bad.mtl\n{tri}usemtl x\nf 1 2 3\n")).unwrap();
    assert_eq!(import(&bad).unwrap(), 1);
}

#[test]
fn geometry_that_is_not_a_regular_file_is_refused() {
    expect_error(Path::new("/dev/zero"), "not a regular file");
    let dir = tempfile::tempdir().unwrap();
    let sub = dir.path().join("folder.obj");
    std::fs::create_dir(&sub).unwrap();
    expect_error(&sub, "not a regular file");
}
