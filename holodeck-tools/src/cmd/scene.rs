//! `holodeck scene`: generate built-in scenes as scene files, and inspect scene files.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use holodeck_sampler::scene::gen::mandelbulb::{DEFAULT_RESOLUTION, MAX_RESOLUTION, MAX_STREAM_RESOLUTION};
use holodeck_sampler::scene::gen::{self, GenParams};
use holodeck_sampler::scene::{content_hash, load_scene, write_scene};
use holodeck_sampler::{Material, Scene, Sky};

use holodeck_cli::args::MAX_TRIANGLES;
use holodeck_cli::human::{count, count_in};
use holodeck_cli::progress::{Progress, Unit};

/// Arguments of `holodeck scene`.
#[derive(clap::Args)]
#[command(after_help = "\
A scene file is TOML: [sky], [materials.NAME] tables, [[geometry]] files (OBJ, PLY,
glTF/GLB) with translate/rotate/scale, [[builtin]] generated scenes and [[section]]
tables. See README.md, section Scenes.

Examples:
  holodeck scene gen room -o scenes/room.toml
  holodeck scene gen landscape --triangles 100M --seed 7 -o big/landscape.toml
  holodeck scene gen mandelbulb --resolution 256 -o bulb.toml
  holodeck scene gen bunny -o bunny.toml
  holodeck scene gen bunny --bunny my-bunny.obj -o my-bunny.toml
  holodeck scene info scenes/room.toml
  holodeck scene build builtin:landscape --triangles 300M --memory 2G -o landscape.hds
  holodeck scene build builtin:mandelbulb --resolution 4096 -o bulb.hds
  holodeck scene recode landscape.hds --codec zstd -o landscape-zstd.hds
  holodeck scene info landscape.hds")]
pub struct Args {
    #[command(subcommand)]
    command: SceneCommand,
}

#[derive(clap::Subcommand)]
enum SceneCommand {
    /// Generate a built-in scene: writes OUT.toml, its mesh OUT.ply and its textures (OUT-K.png) next to it.
    Gen(GenArgs),
    /// Load a scene file; print its triangles, materials, bounds, sections and content hash.
    Info(InfoArgs),
    /// Build a scene file for out-of-core tracing (.hds): kd-tree, LOD voxels, compressed blocks.
    Build(BuildArgs),
    /// Rewrite a scene file (.hds) with another block codec, without building it again.
    Recode(RecodeArgs),
    /// Propose a section that fits the scene: the largest free box around an eye, or the box around it all.
    Section(SectionArgs),
}

/// Arguments of `holodeck scene section`.
#[derive(clap::Args)]
#[command(after_help = "\
An interior section is where the eye moves: no geometry may reach into it (what does draws
as black wedges). With --eye, proposes the largest axis-aligned box around that point that no
triangle enters, kept --margin from every surface; with --exterior, the box around all the
geometry, --margin larger on every side. Prints it as `holodeck create --section` takes it
and as a scene file's [[section]] table.

Examples:
  holodeck scene section builtin:room --eye 3 2 1.6
  holodeck scene section sponza.toml --eye 0 0 2 --margin 0.2
  holodeck scene section bunny.toml --exterior")]
pub struct SectionArgs {
    /// Scene file, or builtin:NAME.
    scene: String,
    /// The point the interior section grows around.
    #[arg(long, num_args = 3, value_names = ["X", "Y", "Z"], allow_hyphen_values = true, required_unless_present = "exterior")]
    eye: Option<Vec<f64>>,
    /// Propose the exterior section around all the geometry instead.
    #[arg(long, conflicts_with = "eye")]
    exterior: bool,
    /// Distance kept from every surface (interior) or added around the geometry (exterior), meters.
    #[arg(long, default_value_t = 0.1)]
    margin: f64,
    /// Triangles for builtin:landscape (K, M suffixes).
    #[arg(long, value_parser = count_in(1, MAX_TRIANGLES))]
    triangles: Option<u64>,
}

/// Arguments of `holodeck scene recode`.
#[derive(clap::Args)]
#[command(after_help = "\
Reads every block of IN (checking its checksum), decompresses it and compresses it with
--codec into OUT; the tree, LOD voxels and header carry over. OUT may be IN: the new file
replaces it only once complete. zstd files are smaller, lz4 files decompress faster.

Examples:
  holodeck scene recode landscape.hds --codec zstd -o landscape-zstd.hds
  holodeck scene recode bulb.hds --codec lz4 -o bulb.hds")]
pub struct RecodeArgs {
    /// The scene file to read (.hds).
    input: PathBuf,
    /// The scene file to write (.hds).
    #[arg(short, long, value_name = "HDS")]
    output: PathBuf,
    /// Block compression of the new file: lz4 or zstd.
    #[arg(long)]
    codec: holodeck_sampler::ooc::Codec,
}

/// Arguments of `holodeck scene build`.
#[derive(clap::Args)]
#[command(after_help = "\
Builds SCENE (a scene file or builtin:NAME) into one .hds file that samplers, `render`, `fill`
and `run` trace out of core: only the blocks rays need are decompressed, into a cache of
--scene-memory bytes. The build itself stays within --memory: triangles are sorted into
chunks at spatial medians on disk, and each chunk is built in memory. builtin:landscape and
builtin:mandelbulb are generated as streams, so their triangles never all exist at once (the
bulb's --resolution may go to 8192 here); other scenes are loaded first. A killed build can
simply be run again. The file carries the scene's content hash (a scene file and its .hds
serve the same holodecks).

Examples:
  holodeck scene build scenes/room.toml -o room.hds
  holodeck scene build builtin:landscape --triangles 300M --memory 2G -o landscape.hds
  holodeck scene build builtin:mandelbulb --resolution 4096 -o bulb.hds
  holodeck scene build big.toml --memory 8G --codec zstd -o big.hds")]
pub struct BuildArgs {
    /// Scene file, or builtin:NAME.
    scene: String,
    /// The scene file to write (.hds).
    #[arg(short, long, value_name = "HDS")]
    output: PathBuf,
    /// Memory the build may use (K, M, G suffixes).
    #[arg(long, default_value = "2G", value_parser = holodeck_file::settings::parse_size)]
    memory: u64,
    /// Block compression: lz4 (fast to decompress) or zstd (smaller).
    #[arg(long, default_value = "lz4")]
    codec: holodeck_sampler::ooc::Codec,
    /// Decompressed block size to aim at (K, M suffixes).
    #[arg(long, default_value = "64K", value_parser = holodeck_file::settings::parse_size)]
    block_size: u64,
    /// Triangles for builtin:landscape; suffixes K, M, G as powers of 1000.
    #[arg(long, value_parser = count_in(1, u64::from(u32::MAX)))]
    triangles: Option<u64>,
    /// Grid cells per axis for builtin:mandelbulb (default 128).
    #[arg(long, value_parser = clap::value_parser!(u32).range(4..=i64::from(MAX_STREAM_RESOLUTION)))]
    resolution: Option<u32>,
    /// Random seed (landscape).
    #[arg(long, default_value_t = 0)]
    seed: u64,
}

/// Arguments of `holodeck scene gen`.
#[derive(clap::Args)]
#[command(after_help = "\
Scenes (z up, meters):
  room        a furnished 6 x 4 x 2.7 m room with a window, mirror, glass sphere, area light
  landscape   the room looking out on fBm terrain and a forest; --triangles (default 1M)
  gallery     the landscape with textured things in the room: a rug, a painting, a brick wall
              with a height map and a plant of alpha-masked leaves (textures written as PNG)
  arcade      a courtyard's arcade lit mostly by sunlight bounced off the courtyard
  blind       a room lit through a venetian blind
  mandelbulb  the power-8 Mandelbulb on a ground plane; --resolution (default 128)
  bunny       the Stanford bunny on a table in a lit room; built in, or --bunny FILE.obj (Y up)

The same name and parameters always give the same scene (the same content hash).

Examples:
  holodeck scene gen room -o room.toml
  holodeck scene gen landscape --triangles 10M --seed 2 -o landscape.toml")]
pub struct GenArgs {
    /// Which scene.
    #[arg(value_parser = gen::NAMES)]
    name: String,
    /// Target triangle count (landscape); suffixes K, M, G as powers of 1000.
    #[arg(long, value_parser = count_in(1, MAX_TRIANGLES))]
    triangles: Option<u64>,
    /// Grid cells per axis (mandelbulb).
    #[arg(long, value_parser = clap::value_parser!(u32).range(4..=i64::from(MAX_RESOLUTION)))]
    resolution: Option<u32>,
    /// Random seed (landscape).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// A bunny OBJ file (Y up) instead of the built-in one (bunny).
    #[arg(long, value_name = "OBJ")]
    bunny: Option<PathBuf>,
    /// The scene file to write; the mesh goes to the same name with .ply.
    #[arg(short, long, value_name = "TOML")]
    output: PathBuf,
    /// Replace the scene file and its mesh where they exist.
    #[arg(long)]
    force: bool,
}

/// Arguments of `holodeck scene info`.
#[derive(clap::Args)]
#[command(after_help = "\
Examples:
  holodeck scene info room.toml")]
pub struct InfoArgs {
    /// The scene file.
    file: PathBuf,
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    match a.command {
        SceneCommand::Gen(g) => generate(g),
        SceneCommand::Info(i) => info(i),
        SceneCommand::Section(a) => propose_section(a),
        SceneCommand::Build(b) => build(b),
        SceneCommand::Recode(r) => recode(r),
    }
}

fn spinner(message: String) -> Progress {
    Progress::waiting(&message)
}

fn generate(a: GenArgs) -> Result<ExitCode> {
    let ply = a.output.with_extension("ply");
    if !a.force {
        if let Some(there) = [&a.output, &ply].into_iter().find(|p| p.exists()) {
            anyhow::bail!(
                "{} exists; give --force to replace it (and its scene's other files)",
                there.display()
            );
        }
    }
    let params = GenParams {
        triangles: a.triangles,
        resolution: a.resolution,
        seed: a.seed,
        bunny_path: a.bunny,
    };
    let start = Instant::now();
    let bar = spinner(format!("generating {}", a.name));
    let scene = gen::generate(&a.name, &params)
        .map_err(flat)
        .with_context(|| format!("generating scene {:?}", a.name))?;
    let generated = start.elapsed();
    bar.set_label(&format!("writing {}", a.output.display()));
    if let Some(dir) = a.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let ply = write_scene(&scene, &a.output)
        .map_err(flat)
        .context("writing the scene")?;
    bar.finish();
    tracing::info!(
        "generated in {:.2} s, written in {:.2} s",
        generated.as_secs_f64(),
        (start.elapsed() - generated).as_secs_f64()
    );
    summary!(
        "wrote {} and {}: {} triangles, {} materials, {} section(s)",
        a.output.display(),
        ply.display(),
        count(scene.triangles.len() as u64),
        scene.materials.len(),
        scene.sections.len()
    );
    summary!("content hash {}", content_hash(&scene));
    Ok(ExitCode::SUCCESS)
}

fn build(a: BuildArgs) -> Result<ExitCode> {
    use holodeck_sampler::ooc::build::{
        build_scene_file, BuildSettings, LandscapeSource, MandelbulbSource, SceneSource, TriangleSource,
    };
    if !holodeck_sampler::ooc::is_scene_file(&a.output) {
        anyhow::bail!("{}: a scene file's name ends in .hds", a.output.display());
    }
    let params = GenParams {
        triangles: a.triangles,
        resolution: a.resolution,
        seed: a.seed,
        ..GenParams::default()
    };
    let source: Box<dyn TriangleSource> = if a.scene == "builtin:landscape" {
        Box::new(LandscapeSource::new(params).context("builtin:landscape")?)
    } else if a.scene == "builtin:mandelbulb" {
        let resolution = a.resolution.unwrap_or(DEFAULT_RESOLUTION);
        Box::new(MandelbulbSource::new(resolution).context("builtin:mandelbulb")?)
    } else {
        let bar = spinner(format!("loading {}", a.scene));
        let scene = if let Some(name) = a.scene.strip_prefix("builtin:") {
            gen::generate(name, &params).map_err(flat)?
        } else {
            load_scene(std::path::Path::new(&a.scene)).map_err(flat)?
        };
        bar.finish();
        Box::new(SceneSource::new(scene))
    };
    if let Some(dir) = a.output.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let settings = BuildSettings {
        memory: a.memory,
        codec: a.codec,
        block_bytes: usize::try_from(a.block_size)
            .unwrap_or(64 << 10)
            .clamp(4 << 10, 16 << 20),
    };
    let bar = Progress::counting("scanning", Unit::Triangles, None);
    let progress = |phase: &str, done: u64, total: u64| {
        // Writing counts blocks; the other phases count triangles. Scanning
        // is the pass that finds the total.
        let unit = if phase == "writing" {
            Unit::Blocks
        } else {
            Unit::Triangles
        };
        bar.phase(phase, unit, done, (total > 0).then_some(total));
    };
    let r = build_scene_file(source.as_ref(), &a.output, &settings, &progress)
        .with_context(|| format!("building {}", a.output.display()))?;
    bar.finish();
    summary!(
        "wrote {}: {} triangles ({} references) in {} chunks, {} blocks in {} levels; {} decompressed, {} compressed ({:.1}%, {}), file {}; {:.1} s ({:.1} s partitioning, {:.1} s building)",
        a.output.display(),
        count(r.triangles),
        count(r.references),
        r.chunks,
        count(u64::from(r.blocks)),
        r.levels,
        holodeck_cli::human::bytes(r.decompressed_bytes),
        holodeck_cli::human::bytes(r.compressed_bytes),
        100.0 * r.compressed_bytes as f64 / r.decompressed_bytes.max(1) as f64,
        a.codec.name(),
        holodeck_cli::human::bytes(r.file_bytes),
        r.seconds,
        r.partition_seconds,
        r.chunk_seconds
    );
    Ok(ExitCode::SUCCESS)
}

fn recode(a: RecodeArgs) -> Result<ExitCode> {
    if !holodeck_sampler::ooc::is_scene_file(&a.output) {
        anyhow::bail!("{}: a scene file's name ends in .hds", a.output.display());
    }
    let bar = Progress::counting("recoding", Unit::Blocks, Some(0));
    let progress = |done: u64, total: u64| {
        bar.set_total(total);
        bar.set(done);
    };
    let r = holodeck_sampler::ooc::recode(&a.input, &a.output, a.codec, &progress)
        .with_context(|| format!("recoding {} into {}", a.input.display(), a.output.display()))?;
    bar.finish();
    let pct = |b: u64| 100.0 * b as f64 / r.decompressed_bytes.max(1) as f64;
    summary!(
        "wrote {}: {} blocks, {} decompressed; {} compressed ({:.1}%, {}) where {} had {} ({:.1}%); file {}; {:.1} s",
        a.output.display(),
        count(u64::from(r.blocks)),
        holodeck_cli::human::bytes(r.decompressed_bytes),
        holodeck_cli::human::bytes(r.after_bytes),
        pct(r.after_bytes),
        a.codec.name(),
        a.input.display(),
        holodeck_cli::human::bytes(r.before_bytes),
        pct(r.before_bytes),
        holodeck_cli::human::bytes(r.file_bytes),
        r.seconds
    );
    Ok(ExitCode::SUCCESS)
}

fn info(a: InfoArgs) -> Result<ExitCode> {
    if holodeck_sampler::ooc::is_scene_file(&a.file) {
        let f = holodeck_sampler::ooc::OocScene::open(&a.file, Some(1), 0)
            .with_context(|| format!("opening {}", a.file.display()))?;
        let h = f.header();
        let [lo, hi] = h.bounds;
        println!("{:<13}{}", "triangles", count(h.triangles));
        println!(
            "{:<13}{} ({} per triangle)",
            "references",
            count(h.references),
            format_args!("{:.2}", h.references as f64 / h.triangles.max(1) as f64)
        );
        println!(
            "{:<13}{} in {} levels, {} codec",
            "blocks",
            count(u64::from(h.blocks)),
            h.levels,
            h.codec.name()
        );
        println!(
            "{:<13}{} decompressed, file {}",
            "size",
            holodeck_cli::human::bytes(h.decompressed_bytes),
            holodeck_cli::human::bytes(std::fs::metadata(&a.file).map(|m| m.len()).unwrap_or(0))
        );
        println!(
            "{:<13}x {:.3} .. {:.3}, y {:.3} .. {:.3}, z {:.3} .. {:.3} m",
            "bounds", lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]
        );
        println!("{:<13}{}", "materials", h.materials.len());
        println!("{:<13}{}", "emitters", count(h.emitters.len() as u64));
        println!("{:<13}{}", "sky", sky(&h.sky));
        println!("{:<13}{}", "sections", h.sections.len());
        println!("{:<13}{}", "content hash", h.content_hash);
        return Ok(ExitCode::SUCCESS);
    }
    let bar = spinner(format!("loading {}", a.file.display()));
    let scene = load_scene(&a.file).map_err(flat).context("loading the scene")?;
    bar.finish();
    print!("{}", describe(&scene));
    Ok(ExitCode::SUCCESS)
}

/// A scene error as one message: its text already carries its cause, which
/// the error chain would otherwise print twice.
fn flat(e: holodeck_sampler::SceneError) -> anyhow::Error {
    anyhow::anyhow!("{e}")
}

/// The report `scene info` prints.
fn describe(s: &Scene) -> String {
    let mut out = String::new();
    let mut line = |k: &str, v: String| out.push_str(&format!("{k:<13}{v}\n"));
    line("triangles", count(s.triangles.len() as u64));
    line("vertices", count(s.positions.len() as u64));
    let mats: Vec<String> = s
        .material_names
        .iter()
        .zip(&s.materials)
        .map(|(n, m)| format!("{n} ({})", kind(m)))
        .collect();
    line("materials", format!("{}: {}", s.materials.len(), mats.join(", ")));
    let (lo, hi) = s.bounds();
    line(
        "bounds",
        format!(
            "x {:.3} .. {:.3}, y {:.3} .. {:.3}, z {:.3} .. {:.3} m",
            lo.x, hi.x, lo.y, hi.y, lo.z, hi.z
        ),
    );
    let st = &s.stats;
    line(
        "skipped",
        format!(
            "{} degenerate, {} non-finite triangles; {} empty meshes",
            count(st.degenerate),
            count(st.non_finite),
            st.empty_meshes
        ),
    );
    if !s.textures.is_empty() {
        line(
            "textures",
            format!(
                "{} images, {} in memory with their mip levels",
                s.textures.len(),
                holodeck_cli::human::bytes(s.textures.bytes() as u64)
            ),
        );
    }
    line("sky", sky(&s.sky));
    for cut in holodeck_cli::prepare::section_cuts(s, &s.sections) {
        line("warning", cut);
    }
    for (k, sec) in s.sections.iter().enumerate() {
        let (o, ax, g) = (sec.origin(), sec.axes(), sec.grid());
        line(
            &format!("section {k}"),
            format!(
                "{} origin {:.3},{:.3},{:.3} size {:.3} x {:.3} x {:.3} m, grid {} x {} x {}, {} beams",
                sec.kind().name(),
                o.x,
                o.y,
                o.z,
                ax[0].length(),
                ax[1].length(),
                ax[2].length(),
                g[0],
                g[1],
                g[2],
                count(u64::from(sec.beam_count()))
            ),
        );
    }
    if s.sections.is_empty() {
        line("sections", "none".to_string());
    }
    line("content hash", content_hash(s));
    for note in &s.notes {
        line("import note", note.to_string());
    }
    out
}

/// `holodeck scene section`: a section that fits the scene.
fn propose_section(a: SectionArgs) -> Result<ExitCode> {
    use holodeck_sampler::scene::section_fit::{around, cut, free_box};
    if !(a.margin.is_finite() && a.margin >= 0.0) {
        anyhow::bail!("--margin {} must be a distance of at least 0", a.margin);
    }
    let scene = holodeck::load(&a.scene, a.triangles)?;
    let (lo, hi) = scene.bounds();
    let extent = (hi - lo).max_element().max(1.0) as f64;
    let (kind, (lo, hi)) = match &a.eye {
        Some(eye) => {
            let eye = glam::DVec3::new(eye[0], eye[1], eye[2]);
            if !eye.is_finite() {
                anyhow::bail!("--eye must be three finite numbers");
            }
            let found = free_box(&scene, eye, a.margin, 2.0 * extent).with_context(|| {
                format!(
                    "a surface passes within --margin {} m of the eye {eye}: move the eye or lower the margin",
                    a.margin
                )
            })?;
            (holodeck_protocol::SectionKind::Interior, found)
        }
        None => (
            holodeck_protocol::SectionKind::Exterior,
            around(&scene, a.margin).context("the scene has no geometry")?,
        ),
    };
    let size = hi - lo;
    let section = holodeck_sampler::scene::section::box_section(kind, lo.to_array(), size.to_array())
        .map_err(|e| anyhow::anyhow!("no section fits there: {e}"))?;
    if let Some(c) = cut(&scene, &section) {
        anyhow::bail!("the proposed section still cuts {} triangles (a bug)", c.triangles);
    }
    let f = |v: glam::DVec3| format!("{:.4},{:.4},{:.4}", v.x, v.y, v.z);
    let name = kind.name();
    let axes = [
        glam::DVec3::new(size.x, 0.0, 0.0),
        glam::DVec3::new(0.0, size.y, 0.0),
        glam::DVec3::new(0.0, 0.0, size.z),
    ];
    println!(
        "{name} section {:.3} x {:.3} x {:.3} m, {} beams",
        size.x,
        size.y,
        size.z,
        count(u64::from(section.beam_count()))
    );
    println!(
        "--section '{name} origin={} x={} y={} z={}'",
        f(lo),
        f(axes[0]),
        f(axes[1]),
        f(axes[2])
    );
    let t = |v: glam::DVec3| format!("[{:.4}, {:.4}, {:.4}]", v.x, v.y, v.z);
    println!(
        "\n[[section]]\nkind = \"{name}\"\norigin = {}\naxes = [{}, {}, {}]",
        t(lo),
        t(axes[0]),
        t(axes[1]),
        t(axes[2])
    );
    Ok(ExitCode::SUCCESS)
}

fn kind(m: &Material) -> &'static str {
    match m {
        Material::Lambertian { .. } => "lambertian",
        Material::Plastic { .. } => "plastic",
        Material::Metal { .. } => "metal",
        Material::Mirror { .. } => "mirror",
        Material::Glass { .. } => "glass",
        Material::Emitter { .. } => "emitter",
    }
}

fn sky(s: &Sky) -> String {
    match s {
        Sky::None => "none".to_string(),
        Sky::Constant { radiance } => format!("constant {radiance:?}"),
        Sky::Sun {
            direction,
            sun_radiance,
            zenith,
            horizon,
            ground,
            ..
        } => format!(
            "sun toward {direction:?}, radiance {sun_radiance:?}; sky {zenith:?} at the zenith, {horizon:?} at the horizon, ground {ground:?}"
        ),
        Sky::Radiance { distribution, sun, .. } => {
            use holodeck_sampler::scene::sky_distribution::{CieSky, SkyDistribution};
            let model = match distribution {
                SkyDistribution::Cie { kind, .. } => match kind {
                    CieSky::Clear => "CIE clear sky (skybright.cal)",
                    CieSky::Overcast => "CIE overcast sky (skybright.cal)",
                    CieSky::Uniform => "uniform sky (skybright.cal)",
                    CieSky::Intermediate => "CIE intermediate sky (skybright.cal)",
                },
                SkyDistribution::Perez { .. } => "Perez all-weather sky (perezlum.cal)",
            };
            // What rays see, as traced.
            let traced = holodeck_sampler::shade::sky::SkyModel::new(s);
            let at = |d: glam::Vec3| traced.background(d.normalize()).to_array();
            let mut out = format!(
                "{model}: radiance {:?} at the zenith, {:?} at the horizon to the south (-y), ground {:?}",
                at(glam::Vec3::Z),
                at(glam::Vec3::new(0.0, -1.0, 0.01)),
                at(-glam::Vec3::Z)
            );
            if let Some(s) = sun {
                out.push_str(&format!(
                    "; sun toward {:?}, radiance {:?}, {} degrees",
                    s.direction, s.radiance, s.diameter_deg
                ));
            }
            out
        }
    }
}
