//! The library does what the command does, from Rust: a scene loaded, a
//! file filled for a view in this process, the view drawn from the file,
//! and a scene that cannot be loaded refused with what and why.

use holodeck::{fill, recall, DriverChoice, Error, FillOptions, SceneInput, ViewFill};
use holodeck_display::request::RequestOptions;
use holodeck_display::Viewport;
use holodeck_file::{HoloFile, OpenOptions, Settings};
use holodeck_protocol::View;

/// The built-in room, and a new empty holodeck file of it in `dir`.
fn empty_room(dir: &std::path::Path) -> (SceneInput, Settings, HoloFile) {
    let scene = SceneInput::open("builtin:room", None, None).unwrap();
    let path = dir.join("room.hdk");
    let settings = Settings::with_sections(scene.sections().to_vec());
    HoloFile::create(&path, &settings).unwrap();
    let file = HoloFile::open(&path, &OpenOptions::default()).unwrap();
    (scene, settings, file)
}

#[test]
fn a_file_filled_for_a_view_draws_that_view_with_every_ray() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, settings, mut file) = empty_room(dir.path());
    let view = View::parse(holodeck::ROOM_VIEW).unwrap();
    let views = ViewFill::new(
        &settings.sections,
        std::slice::from_ref(&view),
        RequestOptions::default().eye_radius,
    );
    let mut options = FillOptions::default();
    (options.rays, options.views) = (Some(100_000), Some(views));
    let filled = fill(&scene.tracer(Default::default()), &mut file, &options, &|_| {}).unwrap();
    assert!(filled.rays >= 100_000, "{}", filled.rays);
    assert_eq!(file.summary().rays(), filled.rays);
    let driver = DriverChoice::plain("quadtree", Default::default());
    let viewport = Viewport::new(view, 256, 192).unwrap();
    let (mut d, recalled) = recall(&mut file, viewport, &driver, 2, 1).unwrap();
    assert_eq!(
        recalled.samples, filled.rays,
        "the view sees every beam it was filled for"
    );
    let picture = d.render();
    let lit = picture.pixels.iter().filter(|p| p.max_element() > 0.0).count();
    assert!(lit > 256 * 192 * 9 / 10, "{lit} of {} pixels lit", 256 * 192);
}

#[test]
fn a_scene_that_cannot_be_loaded_says_which_and_why() {
    let e = SceneInput::open("no/such/scene.obj", None, None).err().unwrap();
    assert!(matches!(e, Error::LoadScene { .. }), "{e:?}");
    assert_eq!(e.to_string(), "loading scene no/such/scene.obj");
    let why = std::error::Error::source(&e)
        .map(ToString::to_string)
        .unwrap_or_default();
    assert!(why.contains("no/such/scene.obj"), "{why}");
    let e = SceneInput::open("builtin:nothing", None, None).err().unwrap();
    assert!(matches!(e, Error::Generate { .. }), "{e:?}");
}

/// A file of the room in `dir` filled by volume with `rays` (a few in
/// every beam: sparse for any one view), and its path.
fn sparse_room(dir: &std::path::Path, rays: u64) -> (std::path::PathBuf, HoloFile) {
    let (scene, _, mut file) = empty_room(dir);
    let options = FillOptions {
        rays: Some(rays),
        ..FillOptions::default()
    };
    fill(&scene.tracer(Default::default()), &mut file, &options, &|_| {}).unwrap();
    (dir.join("room.hdk"), file)
}

#[test]
fn pixels_a_sparse_file_leaves_without_a_ray_take_the_rays_of_neighbouring_beams() {
    let dir = tempfile::tempdir().unwrap();
    let (_, mut file) = sparse_room(dir.path(), 300_000);
    let view = View::parse(holodeck::ROOM_VIEW).unwrap();
    let viewport = Viewport::new(view, 160, 120).unwrap();
    let mut choice = DriverChoice::plain("quadtree", Default::default());
    assert!(!choice.neighbours, "off unless asked for");
    let (alone, by_itself) = recall(&mut file, viewport.clone(), &choice, 2, 1).unwrap();
    choice.neighbours = true;
    let (helped, with) = recall(&mut file, viewport, &choice, 2, 1).unwrap();
    let empty = |d: &dyn holodeck_display::Driver| d.empty_pixels().iter().filter(|e| **e).count() as u64;
    let (before, after) = (empty(alone.as_ref()), empty(helped.as_ref()));
    assert_eq!((by_itself.neighbour_beams, by_itself.filled), (0, 0));
    assert!(
        before > 160 * 120 / 4,
        "{before} pixels without a ray: the file is not sparse"
    );
    assert!(with.neighbour_beams > 0);
    // What the pixels filled are, counted both ways; at least twice the
    // pixels have a ray (4.5 times, measured).
    assert_eq!(with.filled, before - after);
    let pixels = 160 * 120;
    assert!(
        pixels - after >= 2 * (pixels - before),
        "{before} then {after} pixels without a ray"
    );
    assert!(with.samples > by_itself.samples);
    // Estimates were added where there were none (the store's own tests
    // check that those already there do not change).
    let (a, h) = (alone.stats(), helped.stats());
    assert!(h.kept > a.kept, "{a:?} {h:?}");
    assert!(
        h.passed_over > 0,
        "neighbouring rays landing on pixels with rays are passed over: {h:?}"
    );
}

/// The window's replay of a sparse file fills its gaps from neighbouring
/// beams as `pict --neighbour-beams` does: the same picture, bit for bit,
/// and the pixels filled counted.
#[cfg(feature = "window")]
#[test]
fn the_window_fills_a_sparse_files_gaps_from_neighbouring_beams_as_pict_does() {
    use holodeck_display::window::{WalkOptions, Walkthrough};
    let dir = tempfile::tempdir().unwrap();
    let (path, mut file) = sparse_room(dir.path(), 200_000);
    let viewport = Viewport::new(View::parse(holodeck::ROOM_VIEW).unwrap(), 128, 96).unwrap();
    let mut choice = DriverChoice::plain("quadtree", Default::default());
    choice.neighbours = true;
    // `pict`'s selection for the view is the window's (seed 0).
    let (mut pict, recalled) = recall(&mut file, viewport.clone(), &choice, 2, 0).unwrap();
    assert!(recalled.filled > 1000, "{recalled:?}");
    file.close().unwrap();

    let walk = |neighbours: bool| {
        let file = HoloFile::open(&path, &OpenOptions::read_only()).unwrap();
        let source = holodeck::replay::FileSource::new(file, "sparse.hdk".into());
        let driver = DriverChoice::plain("quadtree", Default::default())
            .make(viewport.clone())
            .unwrap();
        // `pict`'s beam selection: one view ray per 2 pixels (as `pict --window` asks).
        let mut options = WalkOptions {
            neighbours,
            ..Default::default()
        };
        options.request.stride = 2;
        let mut w = Walkthrough::new(Box::new(source), driver, options);
        let samples = w.settle().unwrap();
        (w, samples)
    };
    let (mut plain, alone) = walk(false);
    let (mut helped, with) = walk(true);
    assert_eq!(plain.filled(), 0);
    assert_eq!(helped.filled(), recalled.filled, "the pixels filled are pict's");
    assert_eq!(with, recalled.samples, "every ray pict read, the neighbours' too");
    assert!(with > alone);
    let empty = |w: &Walkthrough| w.driver().empty_pixels().iter().filter(|e| **e).count() as u64;
    assert_eq!(empty(&plain) - empty(&helped), helped.filled());
    let (_, picture) = helped.frame().unwrap();
    assert!(picture == pict.render(), "the window shows what pict draws");
    let (_, without) = plain.frame().unwrap();
    assert!(picture != without);
    // Settling again asks for more of the view (other beams): the gaps
    // left are fewer, and those filled again are counted anew.
    let left = empty(&helped);
    helped.settle().unwrap();
    assert!(empty(&helped) <= left);
    assert!(helped.filled() <= left, "{} of {left}", helped.filled());
}

#[test]
fn a_walk_in_one_driver_reads_each_ray_once_and_draws_what_a_fresh_recall_draws() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, settings, mut file) = empty_room(dir.path());
    let view = View::parse(holodeck::ROOM_VIEW).unwrap();
    let walk = holodeck::truth::walk(&view, 3, 0.3, 8.0);
    let fills = ViewFill::new(&settings.sections, &walk, RequestOptions::default().eye_radius);
    let mut options = FillOptions::default();
    (options.rays, options.views) = (Some(60_000), Some(fills));
    fill(&scene.tracer(Default::default()), &mut file, &options, &|_| {}).unwrap();
    let choice = DriverChoice::plain("quadtree", Default::default());
    let (w, h) = (128, 96);
    let viewport = |v: &View| Viewport::new(v.clone(), w, h).unwrap();

    // The first view, followed by a fresh driver: every ray a recall reads,
    // and the same picture.
    let (mut fresh, recalled) = recall(&mut file, viewport(&walk[0]), &choice, 2, 0).unwrap();
    let mut d = choice.make(viewport(&walk[0])).unwrap();
    let mut given = std::collections::HashMap::new();
    let first = holodeck::recall::follow(&mut file, d.as_mut(), viewport(&walk[0]), &mut given, 2, 0).unwrap();
    assert_eq!(first.samples, recalled.samples);
    assert_eq!(first.beams, recalled.beams);
    assert_eq!(d.render(), fresh.render());

    // The same view again: nothing is read twice.
    let again = holodeck::recall::follow(&mut file, d.as_mut(), viewport(&walk[0]), &mut given, 2, 0).unwrap();
    assert_eq!(again.samples, 0);

    // Further views: only the rays of beams not given before, and every ray
    // given counted once.
    let mut total = first.samples;
    for v in &walk[1..] {
        let next = holodeck::recall::follow(&mut file, d.as_mut(), viewport(v), &mut given, 2, 0).unwrap();
        let (_, whole) = recall(&mut file, viewport(v), &choice, 2, 0).unwrap();
        assert!(next.samples < whole.samples, "{} of {}", next.samples, whole.samples);
        total += next.samples;
        let lit = d.render().pixels.iter().filter(|p| p.max_element() > 0.0).count();
        assert!(lit > (w * h) as usize * 8 / 10, "{lit} of {} pixels lit", w * h);
    }
    assert_eq!(total, given.values().sum::<u64>());
    assert!(total <= file.summary().rays());

    // A turn far past the paper's 20 degrees drops the estimates: the new view
    // is read whole, as a fresh recall reads it.
    let mut turned = walk[0].clone();
    let d0 = turned.direction;
    let (c, s) = (90f64.to_radians().cos(), 90f64.to_radians().sin());
    turned.direction = glam::DVec3::new(d0.x * c - d0.y * s, d0.x * s + d0.y * c, d0.z);
    let drops = d.stats().cache_drops;
    holodeck::recall::follow(&mut file, d.as_mut(), viewport(&turned), &mut given, 2, 0).unwrap();
    assert_eq!(d.stats().cache_drops, drops + 1);
    // Turning back to the first view, whose beams were all given before the
    // drop, reads them all again.
    let back = holodeck::recall::follow(&mut file, d.as_mut(), viewport(&walk[0]), &mut given, 2, 0).unwrap();
    let (mut whole, recalled) = recall(&mut file, viewport(&walk[0]), &choice, 2, 0).unwrap();
    assert_eq!(back.samples, recalled.samples);
    assert_eq!(d.render(), whole.render());
}
