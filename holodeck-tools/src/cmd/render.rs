//! `holodeck render`: the direct reference renderer (no holodeck involved).

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use holodeck_protocol::View;
use holodeck_sampler::render::{self, RenderOptions};
use holodeck_sampler::TraceOptions;

use holodeck::truth::{denoise_oidn, lod_ratio};
use holodeck::{SceneInput, ROOM_VIEW};
use holodeck_cli::args::{frame_size, MAX_TRIANGLES, SIDE};
use holodeck_cli::human::{count, count_in};

/// Arguments of `holodeck render`.
#[derive(clap::Args)]
#[command(after_help = "\
SCENE is a scene file (see `holodeck scene gen`) or builtin:NAME for a generated scene
(room, landscape, mandelbulb, bunny). Views use Radiance's options: -vtv perspective,
-vta angular fisheye, -vth hemispherical, -vtl parallel; -vp position, -vd direction,
-vu up, -vh/-vv fields of view in degrees.

Examples:
  holodeck render builtin:room -o room.png
  holodeck render builtin:room --spp 256 -x 1024 -y 768 -o room.hdr
  holodeck render scene.toml --view '-vta -vp 3 2 1.5 -vd 1 0 0 -vu 0 0 1 -vh 180 -vv 180' -o fisheye.png
  holodeck render land.hds --scene-memory 2G --lod 1 --lod-secondary 1 -o land.png
  holodeck render land.hds --out-of-core -o land.png      (prints what the view needed of the file)
  holodeck render builtin:room --spp 4 --albedo a.hdr --normal n.hdr -o noisy.hdr
  holodeck render builtin:room --spp 4 --denoise oidn -o clean.png   (a build with --features oidn)

--albedo and --normal write the auxiliary pictures a denoiser takes (the first surface's albedo,
and its world-space normal n as the colour (n + 1) / 2, through mirrors and glass to what they
show).
--denoise oidn cleans the picture with Intel Open Image Denoise, given both.")]
pub struct Args {
    /// Scene file, or builtin:NAME.
    scene: String,
    /// View options (Radiance notation); the default looks at the built-in room's window.
    /// A Radiance view line (`rview -vtv -vp …`, `VIEW= …`) works as written;
    /// `-vo`/`-va` clip fore and aft, `-vs`/`-vl` shift and lift, `-vf FILE`
    /// reads a view file or a Radiance picture's header.
    #[arg(long, default_value = ROOM_VIEW, allow_hyphen_values = true)]
    view: String,
    /// Image width.
    #[arg(short = 'x', long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(SIDE))]
    width: u32,
    /// Image height.
    #[arg(short = 'y', long, default_value_t = 384, value_parser = clap::value_parser!(u32).range(SIDE))]
    height: u32,
    /// Samples per pixel.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..))]
    spp: u32,
    /// Largest number of bounces.
    #[arg(long, default_value_t = 8)]
    bounces: u32,
    /// Seed of the random sequence (renders are deterministic for a seed).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Exposure for PNG output; automatic if omitted.
    #[arg(long)]
    exposure: Option<f32>,
    /// Triangles for builtin:landscape (K, M suffixes).
    #[arg(long, value_parser = count_in(1, MAX_TRIANGLES))]
    triangles: Option<u64>,
    /// For a .hds scene file: decompressed blocks kept in memory (K, M, G;
    /// default: all of them). When they all fit (and memory allows, and LOD
    /// is off) the file is assembled into the in-core tree at the start.
    #[arg(long, value_parser = holodeck_file::settings::parse_size)]
    scene_memory: Option<u64>,
    /// For a .hds scene file: trace it out of core even when it would fit in
    /// memory (to see what a view needs of it: its working set).
    #[arg(long)]
    out_of_core: bool,
    /// For a .hds scene file: pixels of error; a voxel whose projected area is
    /// below this many pixels stands in for its subtree (0: exact triangles).
    #[arg(long, default_value_t = 0.0, value_parser = holodeck_cli::args::non_negative)]
    lod: f64,
    /// For a .hds scene file: the same for bounce and shadow rays, as an angle
    /// in milliradians: a voxel whose radius is below this angle as seen from
    /// the ray's origin stands in for its subtree (0: exact triangles).
    #[arg(long, default_value_t = 0.0, value_parser = holodeck_cli::args::non_negative, value_name = "MRAD")]
    lod_secondary: f64,
    /// Write the first surfaces' albedo here (.hdr or .png), for denoisers.
    #[arg(long)]
    albedo: Option<PathBuf>,
    /// Write the first surfaces' normals here (.hdr: x, y, z as RGB), for denoisers.
    #[arg(long)]
    normal: Option<PathBuf>,
    /// Denoise the picture: `off`, or `oidn` (Intel Open Image Denoise with the albedo
    /// and normals; needs a build with `--features oidn`).
    #[arg(long, default_value = "off")]
    denoise: String,
    /// Output picture: .png (tone-mapped) or .hdr (Radiance RGBE, linear).
    #[arg(short, long)]
    output: PathBuf,
}

/// The extension of a picture path, checked.
fn picture_ext(path: &Path, what: &str) -> Result<String> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    if ext != "png" && ext != "hdr" {
        bail!("{what} {} must end in .png or .hdr", path.display());
    }
    Ok(ext)
}

/// Writes `picture` as .hdr (linear) or .png (at `exposure`, automatic if none).
fn write_picture(picture: &holodeck_protocol::Picture, path: &Path, exposure: Option<f32>, view: &View) -> Result<()> {
    match picture_ext(path, "output")?.as_str() {
        "hdr" => holodeck_display::image_io::write_hdr_view(picture, path, Some(view))?,
        _ => holodeck_display::image_io::write_png(picture, path, exposure.unwrap_or_else(|| picture.auto_exposure()))?,
    }
    Ok(())
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    frame_size(a.width, a.height)?;
    let view = holodeck_cli::view_arg::parse(&a.view).with_context(|| format!("--view {:?}", a.view))?;
    picture_ext(&a.output, "output")?;
    for (p, what) in [(&a.albedo, "--albedo"), (&a.normal, "--normal")] {
        if let Some(p) = p {
            picture_ext(p, what)?;
        }
    }
    let oidn = match a.denoise.as_str() {
        "off" => false,
        "oidn" if cfg!(feature = "oidn") => true,
        "oidn" => bail!("--denoise oidn: {}", holodeck_display::denoise::DenoiseError::NoOidn),
        other => bail!("--denoise {other:?}: known are off and oidn"),
    };
    let scene = SceneInput::open(&a.scene, a.triangles, a.scene_memory)?;
    let triangles = scene.triangles();
    let start = Instant::now();
    let tracer = scene.tracer_with(
        TraceOptions {
            max_bounces: a.bounces,
            lod_primary: lod_ratio(a.lod, &view, a.width),
            lod_secondary: (a.lod_secondary / 1000.0) as f32,
            ..TraceOptions::default()
        },
        !a.out_of_core,
    );
    let build = start.elapsed().as_secs_f64();
    tracing::info!(
        "kd-tree and wide BVH over {} triangles built in {build:.2} s: {:?}, {:?}",
        count(triangles),
        tracer.caster().tree().map(|t| t.stats()),
        tracer.caster().bvh().map(|b| b.stats())
    );
    let bar = holodeck_cli::progress::Progress::counting(
        "rendering",
        holodeck_cli::progress::Unit::Rows,
        Some(u64::from(a.height)),
    );
    let options = RenderOptions {
        width: a.width,
        height: a.height,
        spp: a.spp,
        seed: a.seed,
    };
    let start = Instant::now();
    let picture = render::render(&tracer, &view, &options, &|done, _| bar.set(done as u64))
        .context("-x/--width, -y/--height or --spp")?;
    bar.finish();
    if let Some(e) = tracer.caster().file().and_then(|f| f.cache().error()) {
        bail!("{}: {e}", a.scene);
    }
    let secs = start.elapsed().as_secs_f64();
    let aovs = if a.albedo.is_some() || a.normal.is_some() || oidn {
        let start = Instant::now();
        let aovs = render::render_aovs(&tracer, &view, &options)?;
        tracing::info!("albedo and normals in {:.2} s", start.elapsed().as_secs_f64());
        Some(aovs)
    } else {
        None
    };
    if let Some((albedo, normal)) = &aovs {
        write_aovs(&a, albedo, normal, &view)?;
    }
    let picture = match (&aovs, oidn) {
        (Some((albedo, normal)), true) => denoise_oidn(&picture, albedo, normal)?,
        _ => picture,
    };
    write_picture(&picture, &a.output, a.exposure, &view)?;
    let samples = u64::from(a.width) * u64::from(a.height) * u64::from(a.spp);
    summary!(
        "{}: {} x {} at {} spp in {secs:.2} s ({:.2} M samples/s, {} threads); {} triangles, tree {build:.2} s",
        a.output.display(),
        a.width,
        a.height,
        a.spp,
        samples as f64 / secs / 1e6,
        rayon::current_num_threads(),
        count(triangles)
    );
    say_what_the_scene_file_took(&tracer);
    Ok(ExitCode::SUCCESS)
}

/// Writes the auxiliary pictures asked for: the albedo, and the normals as
/// colours.
fn write_aovs(
    a: &Args,
    albedo: &holodeck_protocol::Picture,
    normal: &holodeck_protocol::Picture,
    view: &View,
) -> Result<()> {
    if let Some(p) = &a.albedo {
        write_picture(albedo, p, Some(1.0), view)?;
    }
    if let Some(p) = &a.normal {
        // Unit vectors as colours: (n + 1) / 2, which RGBE and PNG can hold.
        let shown = holodeck_protocol::Picture {
            width: normal.width,
            height: normal.height,
            pixels: normal.pixels.iter().map(|n| (*n + glam::Vec3::ONE) * 0.5).collect(),
        };
        write_picture(&shown, p, Some(1.0), view)?;
    }
    Ok(())
}

/// Says what assembling or walking a scene file took, and how many
/// estimates were replaced by black.
fn say_what_the_scene_file_took(tracer: &holodeck_sampler::Tracer) {
    if let Some(r) = tracer.assembled() {
        summary!(
            "scene file: assembled in memory ({} blocks, {} MB, {:.2} s); --out-of-core to trace it through the block cache",
            count(u64::from(r.blocks)),
            r.bytes >> 20,
            r.seconds
        );
    }
    if let Some(f) = tracer.caster().file() {
        // What this view needed of the scene file: its working set, when the cache held it all.
        let st = f.cache().stats();
        summary!(
            "scene file: {} of {} blocks loaded ({} MB read, {} MB decompressed), {} MB resident of a {} MB cache, {} evicted",
            count(st.loads),
            count(u64::from(f.header().blocks)),
            st.read_bytes >> 20,
            st.loaded_bytes >> 20,
            st.resident_bytes >> 20,
            f.cache().budget() >> 20,
            count(st.evictions)
        );
    }
    if tracer.non_finite_count() > 0 {
        summary!(
            "warning: {} non-finite estimates were replaced by black",
            tracer.non_finite_count()
        );
    }
}
