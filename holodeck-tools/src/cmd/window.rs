//! What `holodeck view` and `holodeck pict --window` share to open the
//! walkthrough window: the arguments, the first view, and the source of
//! samples for a replay straight from a holodeck file (no server).

use std::collections::HashMap;
use std::time::Instant;

use anyhow::{Context, Result};
use holodeck_display::request::{BeamRequest, RequestOptions};
use holodeck_display::window::{self, Source, SourceError, WalkOptions, WindowOptions};
use holodeck_display::{Sample, SampleDecoder, Viewport};
use holodeck_file::HoloFile;
use holodeck_protocol::wire::Control;
use holodeck_protocol::{BeamKey, Section, View};

use super::args::FrameArgs;

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
    #[arg(long, default_value_t = RequestOptions::default().stride, value_parser = clap::value_parser!(u32).range(super::args::SIDE))]
    pub stride: u32,
}

/// A view from the middle of `section` along its first axis, level, 75 x 56 degrees.
pub fn default_view(section: &Section) -> String {
    let [x, y, z] = section.axes();
    let c = section.origin() + (x + y + z) * 0.5;
    let d = x.normalize_or_zero();
    format!(
        "-vtv -vp {} {} {} -vd {} {} {} -vu 0 0 1 -vh 75 -vv 56",
        c.x, c.y, c.z, d.x, d.y, d.z
    )
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

/// Samples straight from a holodeck file: a request reads the stored rays
/// of its beams that were not handed out yet; nothing new ever arrives, and
/// there is no server to command.
pub struct FileSource {
    file: HoloFile,
    name: String,
    decoder: SampleDecoder,
    sent: HashMap<BeamKey, u64>,
    scratch: Vec<Sample>,
}

impl FileSource {
    /// Replays `file` (opened read-only), named `name` in the title.
    pub fn new(file: HoloFile, name: String) -> FileSource {
        let decoder = SampleDecoder::new(file.sections().to_vec());
        FileSource {
            file,
            name,
            decoder,
            sent: HashMap::new(),
            scratch: Vec::new(),
        }
    }
}

impl Source for FileSource {
    fn sections(&self) -> &[Section] {
        self.decoder.sections()
    }

    fn request(
        &mut self,
        request: &BeamRequest,
        resend: bool,
        sink: &mut dyn FnMut(&[Sample]),
    ) -> Result<u64, SourceError> {
        if resend {
            self.sent.clear();
        }
        // Beams already sent in full are not read again (their lengths are
        // in the file's directory, in memory).
        let (file, sent) = (&self.file, &self.sent);
        let mut keys: Vec<BeamKey> = request
            .beams
            .iter()
            .map(|b| b.0)
            .filter(|&k| {
                file.beam_len(k)
                    .map_or(true, |n| n > sent.get(&k).copied().unwrap_or(0))
            })
            .collect();
        keys.sort_unstable();
        let (decoder, sent, scratch) = (&self.decoder, &mut self.sent, &mut self.scratch);
        let mut total = 0u64;
        self.file
            .read_beams(&keys, |k, rays| {
                let had = sent.entry(k).or_default();
                let from = (*had as usize).min(rays.len());
                scratch.clear();
                decoder.decode(k.section, k.beam, &rays[from..], scratch);
                *had = rays.len() as u64;
                total += scratch.len() as u64;
                sink(scratch);
            })
            .map_err(|e| SourceError::File(format!("{}: {e}", self.name)))?;
        Ok(total)
    }

    fn raise(&mut self, _request: &BeamRequest) -> Result<(), SourceError> {
        Ok(())
    }

    fn poll(&mut self, _deadline: Instant, _sink: &mut dyn FnMut(&[Sample])) -> Result<u64, SourceError> {
        Ok(0)
    }

    fn received(&self, key: BeamKey) -> u64 {
        self.sent.get(&key).copied().unwrap_or(0)
    }

    fn control(&mut self, control: Control) -> Result<(), SourceError> {
        Err(SourceError::NoServer(format!("{control:?}")))
    }

    fn status(&self) -> Option<holodeck_protocol::wire::Progress> {
        None
    }

    fn notices(&mut self) -> Vec<String> {
        Vec::new()
    }

    fn name(&self) -> String {
        self.name.clone()
    }
}
