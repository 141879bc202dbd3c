//! The library does what the command does, from Rust: a scene loaded, a
//! file filled for a view in this process, the view drawn from the file,
//! and a scene that cannot be loaded refused with what and why.

use holodeck::{fill, recall, DriverChoice, Error, FillOptions, SceneInput, ViewFill};
use holodeck_display::request::RequestOptions;
use holodeck_display::Viewport;
use holodeck_file::{HoloFile, OpenOptions, Settings};
use holodeck_protocol::View;

#[test]
fn a_file_filled_for_a_view_draws_that_view_with_every_ray() {
    let scene = SceneInput::open("builtin:room", None, None).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("room.hdk");
    let settings = Settings::with_sections(scene.sections().to_vec());
    HoloFile::create(&path, &settings).unwrap();
    let mut file = HoloFile::open(&path, &OpenOptions::default()).unwrap();
    let view = View::parse("-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56").unwrap();
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
