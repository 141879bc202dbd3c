//! `holodeck pict`: pictures straight from a holodeck file (like Radiance's
//! rhpict): select the beams a view sees, read them in file order, hand the
//! samples to a display driver, and write the frame.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use holodeck_display::denoise::Denoiser;
use holodeck_display::{output, Viewport};
use holodeck_file::{HoloFile, OpenOptions};
use holodeck_protocol::View;

use holodeck::recall::draw;
use holodeck_cli::human::count;

/// Arguments of `holodeck pict`.
#[derive(clap::Args)]
#[command(after_help = "\
Reads FILE directly (no server: to draw from a file a server holds, use `holodeck view`), gathers the
beams each view sees, reconstructs the picture with a display driver and writes it: .hdr
(Radiance RGBE, linear, nothing lost) or .png (tone mapped: camera, human or exposure:X).
With --views, every line of the file is one frame and OUTPUT holds %d or %04d for its number.
With --neighbour-beams, pixels the view's beams give no ray (a sparse file) take the rays of the
beams next to theirs, which pass near the eye; pixels with a ray are left as they are, and the
summary says how many were filled that way (with --window, the status line says it for each
view once motion stops). Without it, the driver fills them by interpolation.

Examples:
  holodeck pict room.hdk -o room.png
  holodeck pict room.hdk --view '-vtv -vp 1 2 1.5 -vd 1 0 0 -vu 0 0 1 -vh 60 -vv 45' -o v.hdr
  holodeck pict room.hdk --views walk.vf -o frames/walk_%04d.png --tone human
  holodeck pict sparse.hdk --neighbour-beams -o sparse.png    # a short fill by volume
  holodeck pict room.hdk --window --driver quadtree     # walk through it, no server
  holodeck pict sparse.hdk --window --neighbour-beams   # the same, gaps filled from neighbours

With --window there is no output file: the view opens in a window with the walkthrough's input
model (see `holodeck view --help`), and every view's beams are read from FILE as motion stops.
Nothing is traced, so it runs on machines with no GPU and no samplers.")]
pub struct Args {
    /// The holodeck file.
    file: PathBuf,
    /// View options (Radiance notation); default: the built-in room's view.
    /// A Radiance view line (`rview -vtv -vp …`, `VIEW= …`) works as written;
    /// `-vo`/`-va` clip fore and aft, `-vs`/`-vl` shift and lift, `-vf FILE`
    /// reads a view file or a Radiance picture's header.
    #[arg(long, default_value = holodeck::ROOM_VIEW, allow_hyphen_values = true, conflicts_with = "views")]
    view: String,
    /// A file of views, one per line (a scripted path): numbered frames.
    #[arg(long)]
    views: Option<PathBuf>,
    #[command(flatten)]
    frame: holodeck_cli::args::FrameArgs,
    /// Beam selection: one view ray per this many pixels across and down.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(holodeck_cli::args::SIDE))]
    stride: u32,
    /// Fill pixels that the view's beams give no ray (a sparse file) from
    /// the rays of the beams next to theirs, which pass near the eye; pixels
    /// with a ray are left as they are.
    #[arg(long)]
    neighbour_beams: bool,
    /// Output picture (.png or .hdr); with --views, a name holding %d or %04d.
    #[arg(short, long, required_unless_present = "window")]
    output: Option<PathBuf>,
    /// Open a window and walk through the file (display-only replay).
    #[arg(long, conflicts_with = "output")]
    window: bool,
    /// Read window commands from standard input (see `holodeck view --help`).
    #[arg(short = 'i', long, requires = "window")]
    script: bool,
}

/// The output name of frame `n`: `%d` or `%0Nd` replaced by the number.
fn numbered(pattern: &Path, n: usize) -> Result<PathBuf> {
    let s = pattern.to_str().context("the output name must be valid UTF-8")?;
    let Some(at) = s.find('%') else {
        bail!("with --views, the output name must hold %d or %04d for the frame number")
    };
    let rest = &s[at + 1..];
    let digits: String = rest.chars().take_while(|c| c.is_ascii_digit()).collect();
    if !rest[digits.len()..].starts_with('d') {
        bail!("the output name {s:?} must use %d or %0Nd for the frame number");
    }
    let width: usize = digits.parse().unwrap_or(0);
    Ok(PathBuf::from(format!(
        "{}{n:0width$}{}",
        &s[..at],
        &rest[digits.len() + 1..]
    )))
}

/// Rays per pixel below which a picture is blocky, and `pict` says how to get more.
const COARSE: f64 = 1.0;

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    a.frame.check()?;
    let views = match &a.views {
        Some(path) => {
            let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
            let v = View::parse_list(&text).map_err(|(line, e)| anyhow::anyhow!("{}:{line}: {e}", path.display()))?;
            if v.is_empty() {
                bail!("{} holds no views", path.display());
            }
            v
        }
        None => vec![holodeck_cli::view_arg::parse(&a.view).context("--view")?],
    };
    let mut file =
        HoloFile::open(&a.file, &OpenOptions::read_only()).with_context(|| format!("opening {}", a.file.display()))?;
    if a.window {
        let view = views.into_iter().next().context("no view")?;
        let source = holodeck::replay::FileSource::new(file, a.file.display().to_string());
        let args = crate::window::WindowArgs {
            script: a.script,
            stride: a.stride,
        };
        let walk = holodeck_display::window::WalkOptions {
            neighbours: a.neighbour_beams,
            ..Default::default()
        };
        crate::window::open(Box::new(source), view, &a.frame, &args, walk)?;
        return Ok(ExitCode::SUCCESS);
    }
    let Some(output) = &a.output else {
        bail!("-o is needed without --window");
    };
    let mut driver = a.frame.driver_choice()?;
    driver.neighbours = a.neighbour_beams;
    for (i, view) in views.into_iter().enumerate() {
        let out = if a.views.is_some() {
            numbered(output, i + 1)?
        } else {
            output.clone()
        };
        let viewport = Viewport::new(view.clone(), a.frame.width, a.frame.height)?;
        let (picture, hist, s) = draw(&mut file, viewport, &driver, a.stride, i as u64)?;
        let mode = output::parse_tone(&a.frame.tone, Some(&picture))?;
        if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        output::save(&picture, &hist, mode, &out, Some(&view))?;
        if s.samples == 0 {
            note!(
                "holodeck pict: warning: {} is black: the view sees no rays of {} (is the eye inside an \
                 interior section, or outside looking at an exterior one? `holodeck info` lists the sections)",
                out.display(),
                a.file.display()
            );
        }
        let per_pixel = s.samples as f64 / (f64::from(a.frame.width) * f64::from(a.frame.height));
        if s.samples > 0 && per_pixel < COARSE {
            note!(
                "holodeck pict: note: {} is coarse: the view sees {per_pixel:.2} rays per pixel of {}. A fill by \
                 volume spreads its rays over every beam of the section; fill for the views you want \
                 (`holodeck fill SCENE FILE --views VIEWS --rays N`) or watch them fill with a display \
                 (`holodeck run SCENE FILE --driver quadtree`)",
                out.display(),
                a.file.display()
            );
        }
        let secs = s.recall.as_secs_f64();
        let ms = |d: Duration| d.as_secs_f64() * 1e3;
        tracing::info!(
            "{}: read {:.1} ms, decode and project {:.1} ms beside sort and merge {:.1} ms, together {:.1} ms, frame {:.1} ms",
            out.display(),
            ms(s.stages.read),
            ms(s.stages.decode),
            ms(s.stages.insert),
            ms(s.recall.saturating_sub(s.stages.read)),
            ms(s.render)
        );
        let denoised = match driver.denoise {
            Denoiser::Off => String::new(),
            d => format!(" (denoised: {})", d.resolved().name()),
        };
        let neighbours = if s.stages.filled > 0 {
            format!(
                "; {} pixels without a ray filled from {} neighbouring beams",
                count(s.stages.filled),
                count(s.stages.neighbour_beams as u64)
            )
        } else {
            String::new()
        };
        summary!(
            "{}: {} samples from {} beams read and drawn in {:.1} ms ({}/s), frame in {:.1} ms{denoised}; {} pixel estimates, {} rays behind a nearer surface{neighbours}",
            out.display(),
            count(s.samples),
            count(s.beams as u64),
            secs * 1e3,
            count((s.samples as f64 / secs.max(1e-9)) as u64),
            s.render.as_secs_f64() * 1e3,
            count(s.driver.kept),
            count(s.driver.discarded + s.driver.replaced),
        );
    }
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_names_take_the_number() {
        assert_eq!(
            numbered(Path::new("f_%04d.png"), 7).unwrap(),
            PathBuf::from("f_0007.png")
        );
        assert_eq!(numbered(Path::new("d/%d.hdr"), 12).unwrap(), PathBuf::from("d/12.hdr"));
        assert!(numbered(Path::new("f.png"), 1).is_err());
        assert!(numbered(Path::new("f%x.png"), 1).is_err());
    }
}
