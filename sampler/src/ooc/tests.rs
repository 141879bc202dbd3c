//! End-to-end checks of scene files: built out of core, traced exactly like
//! the in-core tracer, converging from a cold cache, refusing damage.

use std::path::{Path, PathBuf};

use glam::Vec3;
use rand::{Rng, SeedableRng};

use super::build::{
    build_scene_file, BuildSettings, LandscapeSource, MandelbulbSource, SceneSource, TriangleSource,
    BUILD_BYTES_PER_TRIANGLE,
};
use super::*;
use crate::accel::{BuildOptions, KdTree};
use crate::geom::Ray;
use crate::scene::gen::{generate, GenParams};
use crate::shade::lights::Lights;

fn landscape(triangles: u64) -> Scene {
    generate(
        "landscape",
        &GenParams {
            triangles: Some(triangles),
            ..GenParams::default()
        },
    )
    .unwrap()
}

fn build(scene: &Scene, dir: &Path, memory_triangles: u64, codec: Codec) -> (PathBuf, BuildReport) {
    let out = dir.join("scene.hds");
    let settings = BuildSettings {
        memory: memory_triangles * BUILD_BYTES_PER_TRIANGLE,
        codec,
        block_bytes: 16 << 10,
    };
    let report = build_scene_file(&SceneSource::new(scene.clone()), &out, &settings, &|_, _, _| {}).unwrap();
    (out, report)
}

/// Rays from inside the room, from above the terrain and from far away.
fn rays(scene: &Scene, n: usize, seed: u64) -> Vec<Ray> {
    let (lo, hi) = scene.bounds();
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    (0..n)
        .map(|k| {
            let origin = match k % 3 {
                0 => Vec3::new(
                    rng.gen_range(0.5..5.5),
                    rng.gen_range(0.5..3.5),
                    rng.gen_range(0.3..2.4),
                ),
                1 => Vec3::new(rng.gen_range(lo.x..hi.x), rng.gen_range(lo.y..hi.y), hi.z + 5.0),
                _ => Vec3::new(rng.gen_range(lo.x..hi.x), lo.y - 50.0, rng.gen_range(lo.z..hi.z + 30.0)),
            };
            let dir = Vec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            );
            let dir = match k % 3 {
                1 => Vec3::new(dir.x, dir.y, -dir.z.abs() - 0.2),
                2 => Vec3::new(dir.x * 0.3, 1.0, dir.z * 0.2),
                _ => dir,
            };
            Ray::new(origin, dir.normalize())
        })
        .collect()
}

fn same_hit(ooc: Option<OocHit>, core: Option<crate::accel::Hit>) -> bool {
    match (ooc, core) {
        (None, None) => true,
        (Some(a), Some(b)) => {
            let OocSurface::Triangle { .. } = a.surface else {
                return false;
            };
            a.t == b.t || (a.t - b.t).abs() <= 1e-6 * b.t
        }
        _ => false,
    }
}

#[test]
fn an_out_of_core_build_traces_exactly_like_the_in_core_tree() {
    let dir = tempfile::tempdir().unwrap();
    let scene = landscape(40_000);
    let n = scene.triangles.len() as u64;
    // A memory budget for a sixth of the scene: the build must go out of core.
    let (path, report) = build(&scene, dir.path(), n / 6, Codec::Lz4);
    assert!(report.chunks >= 6, "{report:?}");
    assert!(report.largest_chunk <= n / 6, "{report:?}");
    assert_eq!(report.triangles, n);
    let file = OocScene::open(&path, None, 1).unwrap();
    assert_eq!(file.header().content_hash, crate::scene::content_hash(&scene));
    assert_eq!(file.header().emitters.len(), Lights::new(&scene).len());
    let tree = KdTree::build(&scene, &BuildOptions::default());
    let (mut hits, mut same_tri) = (0, 0);
    for (k, ray) in rays(&scene, 6000, 1).iter().enumerate() {
        let a = file.intersect(ray, 0.0, &mut Fetch::load());
        let b = tree.intersect(ray);
        assert!(same_hit(a, b), "ray {k} {ray:?}: out of core {a:?}, in core {b:?}");
        if let (
            Some(OocHit {
                surface: OocSurface::Triangle { id, .. },
                ..
            }),
            Some(b),
        ) = (a, b)
        {
            hits += 1;
            same_tri += usize::from(id == b.tri);
        }
        let blocked = file.occluded_by(
            &Ray {
                t_max: b.map_or(1e30, |h| h.t * 1.001),
                ..*ray
            },
            0.0,
            &mut Fetch::load(),
            |_, _, _| true,
        );
        assert_eq!(blocked, b.is_some(), "ray {k}");
    }
    assert!(hits > 3000, "{hits}");
    // Only rays through shared edges may name the neighbouring triangle.
    assert!(same_tri * 1000 >= hits * 999, "{same_tri} of {hits}");
}

#[test]
fn the_streamed_landscape_is_the_generated_one() {
    let params = GenParams {
        triangles: Some(20_000),
        seed: 3,
        ..GenParams::default()
    };
    let scene = generate("landscape", &params).unwrap();
    let source = LandscapeSource::new(params).unwrap();
    let mut streamed = Vec::new();
    source
        .stream(&mut |b| {
            streamed.extend(
                b.iter()
                    .map(|t| (t.v.map(|p| p.to_array().map(f32::to_bits)), t.material)),
            );
            Ok(())
        })
        .unwrap();
    let mut generated: Vec<_> = (0..scene.triangles.len())
        .map(|i| {
            (
                scene.vertices(i).map(|p| p.to_array().map(f32::to_bits)),
                scene.triangles[i].material,
            )
        })
        .collect();
    assert_eq!(source.meta().materials, scene.materials);
    assert_eq!(source.meta().sections, scene.sections);
    streamed.sort_unstable();
    generated.sort_unstable();
    assert_eq!(streamed.len(), generated.len());
    assert!(streamed == generated);
}

#[test]
fn the_streamed_mandelbulb_is_the_generated_one_and_builds_out_of_core() {
    let params = GenParams {
        resolution: Some(24),
        ..GenParams::default()
    };
    let scene = generate("mandelbulb", &params).unwrap();
    let source = MandelbulbSource::new(24).unwrap();
    assert!(
        source.sections().is_err(),
        "sections follow the geometry: not known before streaming"
    );
    let bits = |v: [Vec3; 3]| v.map(|p| p.to_array().map(f32::to_bits));
    let mut streamed = Vec::new();
    source
        .stream(&mut |b| {
            streamed.extend(b.iter().map(|t| (bits(t.v), t.material, t.id)));
            Ok(())
        })
        .unwrap();
    let generated: Vec<_> = (0..scene.triangles.len())
        .map(|i| (bits(scene.vertices(i)), scene.triangles[i].material, i as u32))
        .collect();
    assert_eq!(streamed.len(), generated.len());
    assert!(streamed == generated, "same triangles, same order, same ids");
    assert_eq!(source.meta().materials, scene.materials);
    assert_eq!(source.sections().unwrap(), scene.sections);
    assert!(MandelbulbSource::new(3).is_err());

    // Built from the stream with a memory budget for a fifth of it: the hits are the in-core tree's.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bulb.hds");
    let n = scene.triangles.len() as u64;
    let settings = BuildSettings {
        memory: n / 5 * BUILD_BYTES_PER_TRIANGLE,
        codec: Codec::Lz4,
        block_bytes: 16 << 10,
    };
    let report = build_scene_file(&source, &out, &settings, &|_, _, _| {}).unwrap();
    assert!(report.chunks >= 5, "{report:?}");
    let file = OocScene::open(&out, None, 1).unwrap();
    assert_eq!(file.header().sections, scene.sections);
    let tree = KdTree::build(&scene, &BuildOptions::default());
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let mut hits = 0;
    for k in 0..3000 {
        let origin = Vec3::new(
            rng.gen_range(-3.0..3.0),
            rng.gen_range(-3.0..3.0),
            rng.gen_range(0.2..3.0),
        );
        let target = Vec3::new(
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
            rng.gen_range(0.0..2.4),
        );
        let ray = Ray::new(origin, (target - origin).normalize());
        let a = file.intersect(&ray, 0.0, &mut Fetch::load());
        let b = tree.intersect(&ray);
        assert!(same_hit(a, b), "ray {k} {ray:?}: out of core {a:?}, in core {b:?}");
        hits += usize::from(b.is_some());
    }
    assert!(hits > 2000, "{hits}");
}

#[test]
fn a_cold_small_cache_converges_to_the_exact_hits() {
    let dir = tempfile::tempdir().unwrap();
    let scene = landscape(100_000);
    let (path, report) = build(&scene, dir.path(), 1 << 20, Codec::Zstd);
    // A tenth of the decompressed scene.
    let budget = (report.decompressed_bytes / 10) as usize;
    let file = OocScene::open(&path, Some(budget), 2).unwrap();
    let tree = KdTree::build(&scene, &BuildOptions::default());
    // Primary rays of one view from the room out of its window: a working set
    // that fits in the budget, as a view's does.
    let rays: Vec<Ray> = (0..64)
        .map(|k| {
            let (x, y) = ((k % 8) as f32 / 7.0 - 0.5, (k / 8) as f32 / 7.0 - 0.5);
            Ray::new(
                Vec3::new(1.0, 2.0, 1.5),
                Vec3::new(1.0, x * 0.4, y * 0.3 - 0.1).normalize(),
            )
        })
        .collect();
    let want: Vec<_> = rays.iter().map(|r| tree.intersect(r)).collect();
    let mut rounds = 0;
    let mut first_missing = 0;
    loop {
        let batch = file.cache().begin_batch();
        let mut missing = 0;
        let mut requests = Vec::new();
        for (ray, want) in rays.iter().zip(&want) {
            let mut fetch = Fetch::proxy();
            let got = file.intersect(ray, 0.0, &mut fetch);
            if fetch.missed {
                missing += 1;
                // A proxy is a voxel hit that says so.
                assert!(matches!(
                    got,
                    Some(OocHit {
                        surface: OocSurface::Voxel { missing: true, .. },
                        ..
                    })
                ));
                requests.extend(fetch.requests);
            } else {
                assert!(same_hit(got, *want), "{got:?} vs {want:?}");
            }
        }
        file.cache().end_batch(batch);
        if rounds == 0 {
            first_missing = missing;
        }
        if missing == 0 {
            break;
        }
        file.cache().request(&requests);
        requests.sort_unstable();
        requests.dedup();
        file.cache().wait_resident(&requests, std::time::Duration::from_secs(5));
        rounds += 1;
        assert!(rounds < 40, "still {missing} rays missing data");
    }
    assert_eq!(first_missing, rays.len(), "a cold cache holds nothing");
    let stats = file.cache().stats();
    assert!(stats.resident_bytes <= budget + (64 << 10), "{stats:?}");
    assert!(stats.loads > 0);
}

#[test]
fn the_tracer_never_keeps_a_result_made_from_missing_data() {
    let dir = tempfile::tempdir().unwrap();
    let scene = landscape(20_000);
    let (path, report) = build(&scene, dir.path(), 1 << 20, Codec::Lz4);
    let file = Arc::new(OocScene::open(&path, Some((report.decompressed_bytes / 10) as usize), 2).unwrap());
    let options = crate::TraceOptions {
        max_bounces: 0,
        ..crate::TraceOptions::default()
    };
    let core = crate::Tracer::new(scene.clone(), options);
    let ooc = crate::Tracer::out_of_core(file, options);
    let rays = rays(&scene, 400, 9);
    let mut rng = crate::Rng::new(1, 1);
    let got = ooc.trace_batch(rays.len(), &mut rng, |k, rng, fetch| {
        (k, ooc.trace_with(rays[k].origin, rays[k].dir, false, rng, fetch))
    });
    assert_eq!(got.len(), rays.len());
    for (k, s) in got {
        let want = core.trace_with(
            rays[k].origin,
            rays[k].dir,
            false,
            &mut crate::Rng::new(1, 1),
            &mut Fetch::load(),
        );
        assert!(
            s.distance == want.distance || (s.distance - want.distance).abs() <= 1e-5 * want.distance,
            "ray {k}: {} vs {}",
            s.distance,
            want.distance
        );
    }
    // Rays traced as a sampler traces a beam's: every one comes back, exact.
    let pairs: Vec<(glam::Vec3, glam::Vec3)> = rays.iter().map(|r| (r.origin, r.dir)).collect();
    let from_file = ooc.trace_rays(&pairs, false, crate::FirstHits::Measured, &mut crate::Rng::new(2, 2));
    let in_core = core.trace_rays(&pairs, false, crate::FirstHits::Packets, &mut crate::Rng::new(2, 2));
    assert_eq!(from_file.len(), rays.len());
    for (k, (f, c)) in from_file.iter().zip(&in_core).enumerate() {
        let (f, c) = (f.unwrap(), c.unwrap());
        assert!(
            f.distance == c.distance || (f.distance - c.distance).abs() <= 1e-5 * c.distance,
            "ray {k}: {} vs {}",
            f.distance,
            c.distance
        );
    }
}

fn damaged(path: &Path, f: impl FnOnce(&mut Vec<u8>)) -> Result<OocScene, OocError> {
    let mut bytes = std::fs::read(path).unwrap();
    f(&mut bytes);
    let out = path.with_file_name("damaged.hds");
    std::fs::write(&out, bytes).unwrap();
    OocScene::open(&out, None, 0)
}

#[test]
fn damaged_files_are_refused_with_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let scene = generate("room", &GenParams::default()).unwrap();
    let (path, _) = build(&scene, dir.path(), 1 << 20, Codec::Lz4);
    let good = OocScene::open(&path, None, 0).unwrap();
    let first = good.cache().entry(0).copied().unwrap();
    for id in 0..good.header().blocks {
        good.cache().read(id).unwrap();
    }
    let len = std::fs::metadata(&path).unwrap().len() as usize;
    for cut in [0, 10, 100, first.offset as usize + 3, len - 40, len - 1] {
        let e = damaged(&path, |b| b.truncate(cut))
            .err()
            .unwrap_or_else(|| panic!("cut at {cut} opened"));
        assert!(
            matches!(
                e,
                OocError::Truncated(_) | OocError::NotASceneFile | OocError::Checksum(_)
            ),
            "cut at {cut}: {e}"
        );
    }
    assert_eq!(damaged(&path, |b| b[8] = 9).err(), Some(OocError::Version(9)));
    assert!(matches!(
        damaged(&path, |b| b[40] ^= 1).err(),
        Some(OocError::Checksum(_))
    ));
    assert_eq!(damaged(&path, |b| b[0] = b'X').err(), Some(OocError::NotASceneFile));
    // A flipped bit inside a block: the file opens, the block is refused when read.
    let hurt = damaged(&path, |b| b[first.offset as usize + 5] ^= 0x10).unwrap();
    let e = hurt.cache().read(0).unwrap_err();
    assert!(matches!(e, OocError::Checksum(_)), "{e}");
    assert!(e.to_string().contains("block 0"), "{e}");
    // Tracing through it neither panics nor invents geometry silently.
    let tracer = crate::Tracer::out_of_core(Arc::new(hurt), crate::TraceOptions::default());
    let mut rng = crate::Rng::new(1, 2);
    let kept = tracer.trace_batch(10, &mut rng, |_, rng, fetch| {
        tracer.trace_with(Vec3::new(3.0, 2.0, 1.2), Vec3::X, false, rng, fetch)
    });
    assert!(kept.len() <= 10);
    assert!(tracer.caster().file().unwrap().cache().error().is_some());
}

#[test]
fn an_empty_scene_builds_and_traces_to_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (path, report) = build(&Scene::default(), dir.path(), 1 << 20, Codec::Lz4);
    assert_eq!(report.triangles, 0);
    let file = OocScene::open(&path, None, 1).unwrap();
    assert_eq!(
        file.intersect(&Ray::new(Vec3::ZERO, Vec3::X), 0.0, &mut Fetch::load()),
        None
    );
}

#[test]
fn lod_stops_at_voxels_that_look_small() {
    let dir = tempfile::tempdir().unwrap();
    let scene = landscape(30_000);
    let (path, _) = build(&scene, dir.path(), 1 << 20, Codec::Lz4);
    let file = OocScene::open(&path, None, 1).unwrap();
    let tree = KdTree::build(&scene, &BuildOptions::default());
    let (mut voxels, mut near, mut empty) = (0, 0, 0);
    for ray in rays(&scene, 1500, 3) {
        let exact = tree.intersect(&ray);
        match file.intersect(&ray, 0.05, &mut Fetch::load()) {
            Some(OocHit {
                t,
                surface: OocSurface::Voxel { radius, missing, .. },
            }) => {
                assert!(!missing);
                voxels += 1;
                assert!(radius <= 0.05 * t * 1.0001);
                // A voxel fills its node's box: a ray through the box's empty
                // part may see it where the triangles let it pass.
                let Some(e) = exact else {
                    empty += 1;
                    continue;
                };
                // It lies in front of the surface, usually close (rays may pass
                // through the empty part of a voxel's box).
                assert!(t <= e.t * 1.0001 + 1e-4, "{t} {radius} {e:?}");
                near += usize::from(e.t - t <= 2.0 * radius);
            }
            other => assert!(same_hit(other, exact)),
        }
    }
    assert!(voxels > 50, "{voxels}");
    assert!(near * 2 > voxels, "{near} of {voxels}");
    assert!(empty * 4 < voxels, "{empty} of {voxels} voxels where nothing is");
}

#[test]
fn recoding_changes_the_codec_and_nothing_else() {
    let dir = tempfile::tempdir().unwrap();
    let scene = landscape(20_000);
    let (path, report) = build(&scene, dir.path(), 1 << 20, Codec::Lz4);
    let zstd = dir.path().join("zstd.hds");
    let r = recode(&path, &zstd, Codec::Zstd, &|_, _| {}).unwrap();
    assert_eq!(r.blocks, report.blocks);
    assert_eq!(r.decompressed_bytes, report.decompressed_bytes);
    assert_eq!(r.before_bytes, report.compressed_bytes);
    assert!(r.after_bytes < r.before_bytes, "{r:?}");
    let file = OocScene::open(&zstd, None, 1).unwrap();
    assert_eq!(file.header().codec, Codec::Zstd);
    let tree = KdTree::build(&scene, &BuildOptions::default());
    for ray in rays(&scene, 1500, 4) {
        let a = file.intersect(&ray, 0.0, &mut Fetch::load());
        assert!(same_hit(a, tree.intersect(&ray)), "{ray:?}");
    }
    // LZ4 is deterministic: back again gives the very same file.
    let back = dir.path().join("back.hds");
    recode(&zstd, &back, Codec::Lz4, &|_, _| {}).unwrap();
    assert!(std::fs::read(&back).unwrap() == std::fs::read(&path).unwrap());

    // A damaged block is refused, and nothing is written.
    let mut bytes = std::fs::read(&path).unwrap();
    let f = OocScene::open(&path, None, 0).unwrap();
    let e = *f.cache().entry(f.header().blocks / 2).unwrap();
    bytes[e.offset as usize + 3] ^= 0x40;
    let bad = dir.path().join("bad.hds");
    std::fs::write(&bad, &bytes).unwrap();
    let out = dir.path().join("never.hds");
    let err = recode(&bad, &out, Codec::Zstd, &|_, _| {}).unwrap_err();
    assert!(err.to_string().contains("checksum"), "{err}");
    assert!(!out.exists() && !dir.path().join("never.hds.partial").exists());
}

#[test]
fn a_batch_bigger_than_the_cache_loads_each_block_a_few_times_not_once_per_ray() {
    let dir = tempfile::tempdir().unwrap();
    let scene = landscape(100_000);
    let (path, report) = build(&scene, dir.path(), 1 << 20, Codec::Lz4);
    let tree = KdTree::build(&scene, &BuildOptions::default());
    let rays = rays(&scene, 3000, 11);
    let trace = |file: &OocScene| file.exact_batch(rays.len(), |k, fetch| file.intersect(&rays[k], 0.0, fetch));
    // What the batch needs: every block it loads into a cache that holds everything.
    let roomy = OocScene::open(&path, None, 2).unwrap();
    trace(&roomy);
    let needed = roomy.cache().stats().loads;
    let needed_bytes = roomy.cache().stats().resident_bytes;
    // A cache for a quarter of that.
    let budget = needed_bytes / 4;
    assert!((budget as u64) < report.decompressed_bytes / 4);
    let small = OocScene::open(&path, Some(budget), 2).unwrap();
    let got = trace(&small);
    for (k, (g, ray)) in got.iter().zip(&rays).enumerate() {
        let g = g.expect("every block is readable");
        assert!(same_hit(g, tree.intersect(ray)), "ray {k}");
    }
    let loads = small.cache().stats().loads;
    // Rays that wait for the same block go on together and evictions take the
    // least recently used blocks: each block is loaded a few times, not once per ray.
    assert!(loads <= 6 * needed, "{loads} loads for {needed} blocks");
    assert!(small.cache().stats().resident_bytes <= budget + (64 << 10));
}

#[test]
fn blocks_hold_subtrees_and_come_out_coarse_levels_first() {
    let dir = tempfile::tempdir().unwrap();
    let scene = landscape(40_000);
    let (path, report) = build(&scene, dir.path(), scene.triangles.len() as u64 / 4, Codec::Lz4);
    let file = OocScene::open(&path, None, 1).unwrap();
    let cache = file.cache();
    let entries: Vec<format::IndexEntry> = (0..cache.blocks() as u32).map(|id| *cache.entry(id).unwrap()).collect();
    // Stored breadth first by level: offsets grow with the level.
    let mut by_offset = entries.clone();
    by_offset.sort_by_key(|e| e.offset);
    assert!(by_offset.windows(2).all(|w| w[0].level <= w[1].level));
    assert_eq!(report.levels, u32::from(by_offset.last().unwrap().level) + 1);
    // Most links stay inside their block: a ray changes blocks only every few
    // treelet levels. Every block but the root's is reached from another.
    let (mut inside, mut total) = (0usize, 0usize);
    let mut entered = vec![0u32; entries.len()];
    for id in 0..entries.len() as u32 {
        let b = cache.read(id).unwrap();
        for l in &b.links {
            total += 1;
            if l.block == id {
                inside += 1;
            } else {
                entered[l.block as usize] += 1;
            }
        }
    }
    assert!(inside * 2 > total, "{inside} of {total} links inside their block");
    let roots = entered.iter().filter(|&&n| n == 0).count();
    assert_eq!(roots, 1, "blocks reached from no other block: {roots}");
}

#[test]
fn links_that_cycle_between_blocks_end_the_walk_as_corrupt() {
    let dir = tempfile::tempdir().unwrap();
    let scene = landscape(20_000);
    let (path, _) = build(&scene, dir.path(), 1 << 20, Codec::Lz4);
    let good = OocScene::open(&path, None, 0).unwrap();
    let root = *good.root();
    // Every link out of a block leads back to the root treelet: well-formed
    // blocks with checksums that match, but a tree that never ends.
    let out = dir.path().join("cycle.hds");
    let mut w = writer::FileWriter::create(&dir.path().join("cycle.partial"), good.header()).unwrap();
    let mut redirected = 0;
    for id in 0..good.header().blocks {
        let mut b = good.cache().read(id).unwrap();
        for l in &mut b.links {
            if l.block != id {
                (l.block, l.node) = (root.block, root.node);
                redirected += 1;
            }
        }
        let raw = b.encode();
        let e = good.cache().entry(id).unwrap();
        w.block(id, &Codec::Lz4.compress(&raw), raw.len() as u32, e.level)
            .unwrap();
    }
    w.finish(&out).unwrap();
    assert!(redirected > 0);
    let bad = OocScene::open(&out, None, 1).unwrap();
    for ray in rays(&scene, 200, 3) {
        // Ends (or this test would hang), with or without a hit.
        let _ = bad.intersect(&ray, 0.0, &mut Fetch::load());
    }
    assert!(bad.corrupt_links() > 0);
    let e = bad.in_core().err().unwrap();
    assert!(e.to_string().contains("cycle"), "{e}");
}

#[test]
fn a_scene_file_assembled_in_memory_traces_like_the_in_core_tree() {
    let dir = tempfile::tempdir().unwrap();
    let scene = landscape(40_000);
    let (path, _) = build(&scene, dir.path(), scene.triangles.len() as u64 / 5, Codec::Lz4);
    let file = OocScene::open(&path, None, 1).unwrap();
    let (mesh, tree, report) = file.in_core().unwrap();
    assert_eq!(report.blocks, file.header().blocks);
    // Blocks are read past the cache: nothing stays resident.
    assert_eq!(file.cache().stats().resident_bytes, 0);
    assert_eq!(mesh.triangles.len(), scene.triangles.len());
    assert_eq!(mesh.materials, scene.materials);
    // Triangles keep their ids: the same corners, the same materials.
    for (id, t) in scene.triangles.iter().enumerate() {
        assert_eq!(mesh.vertices(id), scene.vertices(id), "triangle {id}");
        assert_eq!(mesh.triangles[id].material, t.material);
    }
    let original = KdTree::build(&scene, &BuildOptions::default());
    for (k, ray) in rays(&scene, 6000, 4).iter().enumerate() {
        let a = tree.intersect(ray);
        let b = original.intersect(ray);
        assert_eq!(a.map(|h| h.t), b.map(|h| h.t), "ray {k}");
        let c = file.intersect(ray, 0.0, &mut Fetch::load());
        assert_eq!(c.map(|h| h.t), a.map(|h| h.t), "ray {k}");
    }
    let tracer = crate::Tracer::in_core_from_file(&file, crate::TraceOptions::default()).unwrap();
    assert!(tracer.caster().file().is_none());
    assert_eq!(tracer.assembled().map(|r| r.blocks), Some(file.header().blocks));
}

#[test]
fn a_damaged_scene_file_is_not_assembled() {
    let dir = tempfile::tempdir().unwrap();
    let scene = generate("room", &GenParams::default()).unwrap();
    let (path, _) = build(&scene, dir.path(), 1 << 20, Codec::Lz4);
    let first = OocScene::open(&path, None, 0)
        .unwrap()
        .cache()
        .entry(0)
        .copied()
        .unwrap();
    let hurt = damaged(&path, |b| b[first.offset as usize + 5] ^= 0x10).unwrap();
    let e = hurt.in_core().err().unwrap();
    assert!(matches!(e, OocError::Checksum(_)), "{e}");
}

#[test]
fn blocks_decoded_ahead_are_taken_without_reading_them_again() {
    let dir = tempfile::tempdir().unwrap();
    let scene = landscape(20_000);
    let (path, _) = build(&scene, dir.path(), 1 << 20, Codec::Lz4);
    let file = OocScene::open(&path, None, 2).unwrap();
    let cache = file.cache();
    let ids = [3u32, 1, 2];
    let packed: u64 = ids.iter().map(|&id| u64::from(cache.entry(id).unwrap().packed)).sum();
    let batch = cache.begin_batch();
    cache.decode_ahead(&ids);
    assert!(
        cache.wait_decoded_ahead(std::time::Duration::from_secs(60)),
        "the fetchers never decoded ahead"
    );
    assert_eq!(cache.stats().read_bytes, packed);
    // Decoded, but not in the cache until a ray needs them.
    assert_eq!(cache.stats().resident_blocks, 0);
    let guard = crossbeam_epoch::pin();
    for &id in &ids {
        assert_eq!(cache.load_now(id, &guard).unwrap(), &cache.read(id).unwrap());
    }
    // Three reads ahead and three here for the comparison: none by load_now.
    assert_eq!(cache.stats().read_bytes, 2 * packed);
    assert_eq!(cache.stats().resident_blocks, 3);
    cache.end_batch(batch);
}

#[test]
fn among_blocks_last_used_together_the_finer_is_evicted_first() {
    let dir = tempfile::tempdir().unwrap();
    let scene = landscape(20_000);
    let (path, _) = build(&scene, dir.path(), 1 << 20, Codec::Lz4);
    let probe = OocScene::open(&path, None, 0).unwrap();
    let size = |id: u32| probe.cache().read(id).unwrap().memory();
    // Room for block 1 and one of blocks 2 and 3.
    let budget = size(1) + size(2).max(size(3));
    let file = OocScene::open(&path, Some(budget), 0).unwrap();
    let cache = file.cache();
    let guard = crossbeam_epoch::pin();
    cache.load_now(1, &guard).unwrap();
    cache.load_now(2, &guard).unwrap();
    // A tick of the clock, then both used at the same time, the finer first.
    cache.end_batch(cache.begin_batch());
    assert!(cache.get(2, &guard).is_some() && cache.get(1, &guard).is_some());
    cache.load_now(3, &guard).unwrap();
    assert!(cache.is_resident(1), "the coarser block was evicted");
    assert!(!cache.is_resident(2));
    assert!(cache.is_resident(3));
    assert_eq!(cache.stats().evictions, 1);
}

#[test]
fn a_textured_scene_file_keeps_its_textures_and_renders_as_the_scene_does() {
    use crate::render::{render, RenderOptions};
    let dir = tempfile::tempdir().unwrap();
    let params = GenParams {
        triangles: Some(20_000),
        ..GenParams::default()
    };
    let mut scene = generate("gallery", &params).unwrap();
    // Tangents, as a glTF file gives them, on every vertex.
    scene.tangents = (0..scene.positions.len())
        .map(|i| glam::Vec4::new(1.0, 0.0, 0.0, if i % 2 == 0 { 1.0 } else { -1.0 }))
        .collect();
    let (path, _) = build(&scene, dir.path(), scene.triangles.len() as u64, Codec::Lz4);
    let file = Arc::new(OocScene::open(&path, None, 1).unwrap());
    let h = file.header();
    assert_eq!(
        h.content_hash,
        crate::scene::content_hash(&scene),
        "it is the same scene"
    );
    assert_eq!(h.textures.len(), scene.textures.len());
    let shell = file.shell();
    assert_eq!(shell.maps, scene.maps);
    let textured: Vec<usize> = (0..scene.triangles.len())
        .filter(|&t| scene.maps_of(scene.triangles[t].material).is_some())
        .collect();
    assert!(textured.len() >= 20, "{}", textured.len());
    for &t in &textured {
        assert_eq!(file.triangle_uvs(t as u32), Some(scene.triangle_uvs(t)), "triangle {t}");
        assert_eq!(
            file.triangle_tangents(t as u32),
            scene.triangle_tangents(t),
            "triangle {t}"
        );
    }
    assert_eq!(file.triangle_uvs(0), None, "the terrain has none");
    // The room toward the rug, the bricks and the plant, three ways.
    let view = holodeck_protocol::View::parse("-vtv -vp 1.0 3.2 1.6 -vd 1 -0.7 -0.35 -vu 0 0 1 -vh 80 -vv 60").unwrap();
    let options = RenderOptions {
        width: 48,
        height: 36,
        spp: 16,
        seed: 3,
    };
    let picture = |t: &crate::Tracer| render(t, &view, &options, &|_, _| {}).unwrap();
    let core = picture(&crate::Tracer::new(scene.clone(), crate::TraceOptions::default()));
    let out_of_core = picture(&crate::Tracer::out_of_core(
        file.clone(),
        crate::TraceOptions::default(),
    ));
    let assembled = picture(&crate::Tracer::in_core_from_file(&file, crate::TraceOptions::default()).unwrap());
    let mut baked = scene.clone();
    baked.bake_textures();
    let untextured = picture(&crate::Tracer::new(baked, crate::TraceOptions::default()));
    let rel = |a: &crate::render::Picture, b: &crate::render::Picture| a.mse(b).unwrap().sqrt() / b.mean_luminance();
    assert!(
        rel(&out_of_core, &core) < 0.02,
        "out of core {}",
        rel(&out_of_core, &core)
    );
    assert!(rel(&assembled, &core) < 0.02, "assembled {}", rel(&assembled, &core));
    assert!(
        rel(&untextured, &core) > 0.05,
        "textures show: {}",
        rel(&untextured, &core)
    );
}

#[test]
fn blocks_used_by_a_batch_in_flight_are_not_evicted_for_fetched_ones() {
    let dir = tempfile::tempdir().unwrap();
    let (path, _) = build(&landscape(20_000), dir.path(), 1 << 20, Codec::Lz4);
    let probe = OocScene::open(&path, None, 1).unwrap();
    let blocks: Vec<(u32, usize)> = (0..probe.cache().blocks() as u32)
        .filter_map(|id| probe.cache().read(id).ok().map(|b| (id, b.memory())))
        .take(2)
        .collect();
    let [(a, size_a), (b, size_b)] = blocks[..] else {
        panic!("the scene file has two treelet blocks")
    };
    drop(probe);
    // Room for either block, never both.
    let scene = OocScene::open(&path, Some(size_a + size_b - 1), 1).unwrap();
    let cache = scene.cache();
    let timeout = std::time::Duration::from_secs(60);
    let batch = cache.begin_batch();
    {
        let guard = crossbeam_epoch::pin();
        cache.load_now(a, &guard).unwrap();
    }
    // A fetched block may not push out one the batch in flight has used:
    // it is turned away instead.
    cache.request(&[b]);
    assert!(!cache.wait_resident(&[b], timeout), "b was cached by evicting a");
    assert!(cache.is_resident(a), "a block the batch used was evicted");
    // Once the batch is done, the same request evicts it.
    cache.end_batch(batch);
    cache.request(&[b]);
    assert!(cache.wait_resident(&[b], timeout));
    assert!(!cache.is_resident(a));
}
