//! Fills a holodeck file with the built-in room's rays for one view, then
//! draws that view from the file: `cargo run --release -p holodeck-lib --example fill_and_draw`.

use holodeck::{fill, recall, DriverChoice, FillOptions, SceneInput, ViewFill};
use holodeck_display::{output, request::RequestOptions, tonemap::Histogram, Viewport};
use holodeck_file::{HoloFile, OpenOptions, Settings};
use holodeck_protocol::View;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let scene = SceneInput::open("builtin:room", None, None)?;
    let dir = tempfile::tempdir()?;
    let path = dir.path().join("room.hdk");
    let settings = Settings::with_sections(scene.sections().to_vec());
    HoloFile::create(&path, &settings)?;
    let mut file = HoloFile::open(&path, &OpenOptions::default())?;
    let view = View::parse("-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56")?;
    let views = ViewFill::new(
        &settings.sections,
        std::slice::from_ref(&view),
        RequestOptions::default().eye_radius,
    );
    let mut options = FillOptions::default();
    (options.rays, options.views) = (Some(1_000_000), Some(views));
    let filled = fill(&scene.tracer(Default::default()), &mut file, &options, &|_| {})?;
    let driver = DriverChoice::plain("quadtree", Default::default());
    let (mut d, recalled) = recall(&mut file, Viewport::new(view.clone(), 320, 240)?, &driver, 2, 1)?;
    let picture = d.render();
    let tone = output::parse_tone("camera", Some(&picture))?;
    let histogram = Histogram::from_picture(&picture);
    output::save(&picture, &histogram, tone, "room.png".as_ref(), Some(&view))?;
    println!("{} rays filled, {} drawn into room.png", filled.rays, recalled.samples);
    Ok(())
}
