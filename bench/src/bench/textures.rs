//! `holodeck bench textures`: what textures cost. The gallery (the
//! landscape with a textured rug, painting, brick wall and leaf-masked
//! plant) written as a scene file with its PNG textures, beside the same
//! scene with every texture baked to its mean colour (no coordinates, maps
//! or images), in the same run: loading the scene file, building the
//! tracer, the memory the textures take, and path-traced samples per
//! second of a view that looks at the textured things.

use std::time::Instant;

use anyhow::{Context, Result};
use holodeck_protocol::View;
use holodeck_sampler::render::{render, RenderOptions};
use holodeck_sampler::scene::gen::{generate, GenParams};
use holodeck_sampler::scene::{load_scene, write_scene};
use holodeck_sampler::{TraceOptions, Tracer};

use super::report::median;
use holodeck_cli::human::{bytes, count};

/// A view from the back of the room over the rug to the window, the brick
/// wall on its right and the plant by the window.
pub const VIEW: &str = "-vtv -vp 1.0 3.2 1.6 -vd 1 -0.7 -0.35 -vu 0 0 1 -vh 80 -vv 60";

/// Arguments of `holodeck bench textures`.
#[derive(clap::Args)]
#[command(after_help = "\
Loads, builds and renders the gallery with its textures and with each texture baked to its
mean colour, alternating, and prints the textured figures beside the untextured ones.

Example:
  holodeck bench textures --repeats 5")]
pub struct Args {
    /// Triangles of the terrain and forest outside the room.
    #[arg(long, default_value_t = 200_000)]
    pub triangles: u64,
    /// Runs of each measurement; the median is reported.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub repeats: u32,
    /// Samples per pixel of the 320 x 240 render.
    #[arg(long, default_value_t = 8)]
    pub spp: u32,
    #[command(flatten)]
    pub files: super::Files,
}

/// Runs `holodeck bench textures`.
pub fn run_args(a: &Args) -> Result<std::process::ExitCode> {
    let dir = a.files.dir.join("textures");
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let params = GenParams {
        triangles: Some(a.triangles),
        ..GenParams::default()
    };
    let textured = generate("gallery", &params)?;
    let mut plain = textured.clone();
    plain.bake_textures();
    let paths = [dir.join("textured.toml"), dir.join("untextured.toml")];
    write_scene(&textured, &paths[0])?;
    write_scene(&plain, &paths[1])?;
    let view = View::parse(VIEW)?;
    let options = RenderOptions {
        width: 320,
        height: 240,
        spp: a.spp,
        seed: 1,
    };
    // [textured, untextured] per measurement, alternating so drift hits both.
    let (mut load, mut build, mut speed) = ([vec![], vec![]], [vec![], vec![]], [vec![], vec![]]);
    let mut memory = [0usize; 2];
    for _ in 0..a.repeats {
        for (k, path) in paths.iter().enumerate() {
            let start = Instant::now();
            let scene = load_scene(path)?;
            load[k].push(start.elapsed().as_secs_f64());
            memory[k] = scene.textures.bytes() + scene.uvs.len() * 8;
            let start = Instant::now();
            let tracer = Tracer::new(scene, TraceOptions::default());
            build[k].push(start.elapsed().as_secs_f64());
            let start = Instant::now();
            render(&tracer, &view, &options, &|_, _| {})?;
            let samples = f64::from(options.width * options.height * options.spp);
            speed[k].push(samples / start.elapsed().as_secs_f64());
        }
    }
    let m = |v: &Vec<f64>| median(v);
    println!(
        "gallery with {} triangles, {} textures ({} with mip levels, {} of texture coordinates); median of {} runs\n",
        count(textured.triangles.len() as u64),
        textured.textures.len(),
        bytes(textured.textures.bytes() as u64),
        bytes((textured.uvs.len() * 8) as u64),
        a.repeats
    );
    println!("| measurement | textured | untextured (same run) | ratio |");
    println!("|---|---|---|---|");
    let ms = |v: f64| format!("{:.0} ms", v * 1e3);
    super::row(
        "load the scene file",
        ms(m(&load[0])),
        ms(m(&load[1])),
        m(&load[0]) / m(&load[1]),
    );
    super::row(
        "build the tracer",
        ms(m(&build[0])),
        ms(m(&build[1])),
        m(&build[0]) / m(&build[1]),
    );
    println!(
        "| texture memory (images, mip levels, coordinates) | {} | {} | - |",
        bytes(memory[0] as u64),
        bytes(memory[1] as u64)
    );
    let rate = |v: f64| format!("{:.2} M samples/s", v / 1e6);
    super::row(
        "path-traced samples of the view",
        rate(m(&speed[0])),
        rate(m(&speed[1])),
        m(&speed[0]) / m(&speed[1]),
    );
    if !a.files.keep {
        let _ = std::fs::remove_dir_all(&dir);
    }
    Ok(std::process::ExitCode::SUCCESS)
}
