//! What `holodeck view` and `holodeck pict --window` share to open the
//! walkthrough window: the arguments and the first view (a replay straight
//! from a file takes its samples from `holodeck::replay::FileSource`).

use anyhow::{Context, Result};
use holodeck_display::request::RequestOptions;
use holodeck_display::window::{self, Source, WalkOptions, WindowOptions};
use holodeck_display::Viewport;
use holodeck_protocol::View;

use holodeck_cli::args::FrameArgs;

/// Arguments of the window (shared by `view` and `pict --window`).
#[derive(clap::Args, Clone, Debug)]
pub struct WindowArgs {
    /// Read commands from standard input, one per line (view options,
    /// last, where, frame, pause, resume, redraw, refresh, kill, restart,
    /// clobber, quit, head fix|release, tone, save FILE, sync), and print
    /// views and answers on standard output.
    #[arg(short = 'i', long)]
    pub script: bool,
    /// Beam selection: one view ray per this many pixels across and down.
    #[arg(long, default_value_t = RequestOptions::default().stride, value_parser = clap::value_parser!(u32).range(holodeck_cli::args::SIDE))]
    pub stride: u32,
}

/// Opens the window on `source`, starting at `view`, and runs it until the
/// user quits.
pub fn open(
    source: Box<dyn Source>,
    view: View,
    frame: &FrameArgs,
    args: &WindowArgs,
    walk: WalkOptions,
) -> Result<()> {
    let view = window::navigate::fit_aspect(&view, frame.width, frame.height);
    let viewport = Viewport::new(view, frame.width, frame.height)?;
    let driver = frame.driver_choice()?.make(viewport)?;
    let walk = window::Walkthrough::new(
        source,
        driver,
        WalkOptions {
            tone: frame.tone.clone(),
            request: RequestOptions {
                stride: args.stride,
                ..walk.request
            },
            ..walk
        },
    );
    let options = WindowOptions {
        script: args.script,
        title: format!("({})", frame.driver),
    };
    match window::run(walk, options) {
        Err(e) if e.server_ended() => {
            note!("holodeck: the server ended the session; the window closed");
            Ok(())
        }
        r => r.context("the walkthrough window"),
    }
}
