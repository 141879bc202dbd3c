//! Generator tests at small sizes: counts, validity, closedness, determinism.

use std::collections::HashMap;

use glam::Vec3;
use holodeck_protocol::SectionKind;

use super::*;
use crate::scene::hash::content_hash;
use crate::scene::Triangle;

/// Every triangle indexes real vertices and has a finite, non-zero area.
fn assert_valid(s: &Scene) {
    assert_eq!((s.stats.degenerate, s.stats.non_finite), (0, 0));
    for t in 0..s.triangles.len() {
        assert!(s.triangles[t].v.iter().all(|&i| (i as usize) < s.positions.len()));
        assert!((s.triangles[t].material as usize) < s.materials.len());
        let [a, b, c] = s.vertices(t);
        let area = (b - a).cross(c - a).length();
        assert!(area.is_finite() && area > 0.0, "triangle {t}: {a} {b} {c}");
    }
}

/// Directed edges of `tris` after welding vertices with identical positions.
fn welded_edges(s: &Scene, tris: &[&Triangle]) -> HashMap<(u32, u32), u32> {
    let mut ids: HashMap<[u32; 3], u32> = HashMap::new();
    let mut edges = HashMap::new();
    for t in tris {
        let v = t.v.map(|i| {
            let key = s.positions[i as usize].to_array().map(f32::to_bits);
            let n = ids.len() as u32;
            *ids.entry(key).or_insert(n)
        });
        for k in 0..3 {
            *edges.entry((v[k], v[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    edges
}

/// Undirected edges used once (the boundary) and whether all others are used
/// exactly twice with opposite directions.
fn boundary(edges: &HashMap<(u32, u32), u32>) -> (usize, bool) {
    let mut open = 0;
    let mut manifold = true;
    for (&(a, b), &n) in edges {
        match (n, edges.get(&(b, a)).copied().unwrap_or(0)) {
            (1, 0) => open += 1,
            (1, 1) => {}
            _ => manifold = false,
        }
    }
    (open, manifold)
}

fn named<'a>(s: &'a Scene, name: &str) -> (u32, &'a Material) {
    let k = s
        .material_names
        .iter()
        .position(|n| n == name)
        .unwrap_or_else(|| panic!("no material {name}"));
    (k as u32, &s.materials[k])
}

#[test]
fn room_is_furnished_lit_and_closed_but_for_the_window() {
    let s = generate("room", &GenParams::default()).unwrap();
    assert_valid(&s);
    assert!(matches!(named(&s, "window").1, Material::Glass { thin: true, .. }));
    assert!(matches!(named(&s, "glass").1, Material::Glass { thin: false, ior, .. } if *ior == 1.5));
    assert!(matches!(named(&s, "mirror").1, Material::Mirror { .. }));
    assert!(matches!(named(&s, "table").1, Material::Plastic { .. }));
    assert_eq!(named(&s, "light").1, &Material::Emitter { radiance: [8.0; 3] });
    for name in ["floor", "wall", "ceiling", "box", "chair"] {
        let (id, _) = named(&s, name);
        assert!(s.triangles.iter().any(|t| t.material == id), "{name} unused");
    }
    assert!(matches!(s.sky, Sky::Sun { .. }));

    let shell_ids = ["floor", "wall", "ceiling"].map(|n| named(&s, n).0);
    let shell: Vec<&Triangle> = s.triangles.iter().filter(|t| shell_ids.contains(&t.material)).collect();
    let edges = welded_edges(&s, &shell);
    let (open, manifold) = boundary(&edges);
    assert!(manifold);
    assert_eq!(open, 4, "the only opening is the window's four edges");
    let window = named(&s, "window").0;
    let with_pane: Vec<&Triangle> = s
        .triangles
        .iter()
        .filter(|t| shell_ids.contains(&t.material) || t.material == window)
        .collect();
    assert_eq!(
        boundary(&welded_edges(&s, &with_pane)),
        (0, true),
        "shell + pane: closed and consistently oriented"
    );
    // Every shell face points into the room.
    let center = Vec3::new(3.0, 2.0, 1.35);
    for t in &shell {
        let [a, b, c] = t.v.map(|i| s.positions[i as usize]);
        assert!((b - a).cross(c - a).dot(center - a) > 0.0);
    }

    assert_eq!(s.sections.len(), 1);
    let sec = &s.sections[0];
    assert_eq!(sec.kind(), SectionKind::Interior);
    assert!((100_000..225_000).contains(&sec.beam_count()), "{}", sec.beam_count());
    let clear = s.positions.iter().all(|p| !sec.contains(p.as_dvec3()));
    assert!(clear, "no geometry inside the interior section");
    assert_eq!(
        content_hash(&s),
        content_hash(&generate("room", &GenParams::default()).unwrap())
    );
}

#[test]
fn landscape_triangle_count_follows_the_request_and_seed_decides_it() {
    let p = |triangles, seed| GenParams {
        triangles: Some(triangles),
        seed,
        ..Default::default()
    };
    let s = generate("landscape", &p(200_000, 1)).unwrap();
    let n = s.triangles.len() as f64;
    assert!((n - 200_000.0).abs() <= 20_000.0, "{n}");
    assert_valid(&s);
    for name in ["grass", "bark", "foliage", "window", "light"] {
        named(&s, name);
    }
    let small = generate("landscape", &p(50_000, 1)).unwrap();
    let ratio = n / small.triangles.len() as f64;
    assert!((3.6..4.4).contains(&ratio), "{ratio}");
    assert_eq!(
        content_hash(&small),
        content_hash(&generate("landscape", &p(50_000, 1)).unwrap())
    );
    assert_ne!(
        content_hash(&small),
        content_hash(&generate("landscape", &p(50_000, 2)).unwrap())
    );
    // Trees stand outside the room's clearing and on the terrain.
    let foliage = named(&small, "foliage").0;
    for t in small.triangles.iter().filter(|t| t.material == foliage) {
        let p = small.positions[t.v[0] as usize];
        assert!(Vec3::new(p.x - 3.0, p.y - 2.0, 0.0).length() > 10.0, "{p}");
    }
    let plan = landscape::plan(100_000_000);
    let total = 2 * u64::from(plan.cells).pow(2) + plan.trees * 44;
    assert!((total as f64 - 1e8).abs() < 1e6, "{plan:?}");
}

#[test]
fn mandelbulb_is_a_closed_oriented_manifold() {
    let params = GenParams {
        resolution: Some(32),
        ..Default::default()
    };
    let s = generate("mandelbulb", &params).unwrap();
    assert_valid(&s);
    let bulb = named(&s, "bulb").0;
    let tris: Vec<&Triangle> = s.triangles.iter().filter(|t| t.material == bulb).collect();
    assert!(tris.len() > 2_000, "{}", tris.len());
    // Welded by construction: check on the vertex indices themselves, not positions.
    let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &tris {
        for k in 0..3 {
            *edges.entry((t.v[k], t.v[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    assert_eq!(
        boundary(&edges),
        (0, true),
        "every edge used exactly twice, in opposite directions"
    );
    let volume: f32 = tris
        .iter()
        .map(|t| {
            let [a, b, c] = t.v.map(|i| s.positions[i as usize]);
            a.dot(b.cross(c)) / 6.0
        })
        .sum();
    assert!(volume > 0.5, "outward faces enclose a positive volume: {volume}");
    let (lo, _) = s.bounds();
    assert_eq!(lo.z, 0.0, "ground plane at z = 0");
    assert_eq!(s.sections[0].kind(), SectionKind::Exterior);
    let coarse = generate(
        "mandelbulb",
        &GenParams {
            resolution: Some(16),
            ..Default::default()
        },
    )
    .unwrap();
    let ratio = tris.len() as f64 / coarse.triangles.len() as f64;
    assert!(
        (2.5..6.0).contains(&ratio),
        "surface triangles grow as resolution²: {ratio}"
    );
    assert_eq!(
        content_hash(&s),
        content_hash(&generate("mandelbulb", &params).unwrap())
    );
    let err = generate(
        "mandelbulb",
        &GenParams {
            resolution: Some(2),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(err.to_string().contains("resolution 2"), "{err}");
}

#[test]
fn bunny_stands_up_on_the_table() {
    let dir = tempfile::tempdir().unwrap();
    // A Y-up tetrahedron with its apex at +y, 2 units tall.
    let obj = dir.path().join("tetra.obj");
    std::fs::write(
        &obj,
        "v 0 0 0\nv 1 0 0\nv 0 0 -1\nv 0.2 2 -0.2\nf 1 2 4\nf 2 3 4\nf 3 1 4\nf 1 3 2\n",
    )
    .unwrap();
    let s = generate(
        "bunny",
        &GenParams {
            bunny_path: Some(obj),
            ..Default::default()
        },
    )
    .unwrap();
    assert_valid(&s);
    let skin = named(&s, "bunny").0;
    let verts: Vec<Vec3> = s
        .triangles
        .iter()
        .filter(|t| t.material == skin)
        .flat_map(|t| t.v.map(|i| s.positions[i as usize]))
        .collect();
    assert_eq!(verts.len(), 12);
    let top = verts.iter().fold(f32::MIN, |m, p| m.max(p.z));
    let bottom = verts.iter().fold(f32::MAX, |m, p| m.min(p.z));
    assert!(
        (bottom - 0.75).abs() < 1e-5 && (top - bottom - 0.3).abs() < 1e-5,
        "{bottom} {top}"
    );
    let apex = verts.iter().find(|p| (p.z - top).abs() < 1e-6).unwrap();
    // The apex (0.2, 2, -0.2) turned z-up and scaled by 0.15: x and y offsets from the foot stay small.
    assert!((apex.x - 2.0 - (0.2 - 0.5) * 0.15).abs() < 1e-5, "{apex}");
    assert!((apex.y - 2.0 - (0.2 - 0.5) * 0.15).abs() < 1e-5, "{apex}");
    assert_eq!(s.sections[0].kind(), SectionKind::Exterior);
    assert!(s
        .triangles
        .iter()
        .any(|t| s.materials[t.material as usize] == Material::Emitter { radiance: [8.0; 3] }));

    let err = generate(
        "bunny",
        &GenParams {
            bunny_path: Some(dir.path().join("none.obj")),
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(
        err.to_string().contains("none.obj") && err.to_string().contains("--bunny"),
        "{err}"
    );
}

#[test]
fn the_built_in_bunny_has_all_its_triangles_and_is_the_asset_file() {
    let s = generate("bunny", &GenParams::default()).unwrap();
    let skin = named(&s, "bunny").0;
    assert_eq!(s.triangles.iter().filter(|t| t.material == skin).count(), 3674);
    assert_valid(&s);
    // The file it was built from, given by path, makes the same scene.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/bunny.obj");
    let from_file = generate(
        "bunny",
        &GenParams {
            bunny_path: Some(path),
            ..Default::default()
        },
    )
    .unwrap();
    assert_eq!(crate::scene::content_hash(&from_file), crate::scene::content_hash(&s));
}

#[test]
fn unknown_name_lists_the_known_ones() {
    let err = generate("castle", &GenParams::default()).unwrap_err().to_string();
    assert!(err.contains("castle") && err.contains("mandelbulb"), "{err}");
}
