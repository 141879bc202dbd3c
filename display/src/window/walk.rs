//! A walkthrough: the current view, its driver and its source, and what
//! happens when the view moves. During motion the driver only reprojects
//! what it holds (no requests: the paper's driver "does not request new rays
//! from the server until motion has stopped"); once motion stops the view's
//! beams are requested, stored samples arrive at once, and while the view
//! stays its density is raised as samples arrive. Nothing here knows about
//! windows, so a script can drive it as well as a mouse.

use std::time::{Duration, Instant};

use glam::DVec3;
use holodeck_protocol::wire::Control;
use holodeck_protocol::{Picture, View};

use holodeck_protocol::wire::Progress;

use super::source::{Delivery, Source, SourceError};
use crate::gather::Gather;
use crate::output::parse_tone;
use crate::request::{outstanding, BeamRequest, Refinement, RequestOptions};
use crate::status::RateMeter;
use crate::tonemap::{DisplayRange, Histogram, ToneMap};
use crate::{Driver, DriverError, Sample, Viewport};

/// A still view that got nothing for this long asks for more at once.
const QUIET: Duration = Duration::from_secs(1);

/// Hands what a source delivered to `driver`: samples through `batch`,
/// stored beams at once (after the samples before them).
fn deliver(batch: &mut Gather, delivery: Delivery<'_>, driver: &mut dyn Driver) {
    match delivery {
        Delivery::Samples(s) => batch.add(s, driver),
        Delivery::Beams(decoder, chunks) => {
            batch.flush(driver);
            driver.add_beams(decoder, chunks);
        }
    }
}

/// Hands what a source delivered for pixels without a ray to `driver`:
/// only those pixels take it.
fn deliver_where_empty(delivery: Delivery<'_>, driver: &mut dyn Driver) {
    match delivery {
        Delivery::Samples(s) => driver.add_where_empty(s),
        Delivery::Beams(decoder, chunks) => driver.add_beams_where_empty(decoder, chunks),
    }
}

/// How a walkthrough asks for samples and shows them.
#[derive(Clone, Debug, PartialEq)]
pub struct WalkOptions {
    /// Samples per pixel asked for when a view settles.
    pub density: f64,
    /// Most samples per pixel a still view asks for.
    pub max_density: f64,
    /// Beam selection and proximity sampling.
    pub request: RequestOptions,
    /// Tone mapping: camera, human, exposure:X or exposure:auto.
    pub tone: String,
    /// Pixels that a settled view's beams leave without a ray (a sparse
    /// file) take the stored rays of the beams next to theirs, as `holodeck
    /// pict --neighbour-beams` does (see [`Source::neighbours`]).
    pub neighbours: bool,
}

impl Default for WalkOptions {
    fn default() -> Self {
        WalkOptions {
            density: 1.0,
            max_density: 1024.0,
            request: RequestOptions::default(),
            tone: "camera".into(),
            neighbours: false,
        }
    }
}

/// Why a walkthrough step failed.
#[derive(Debug, thiserror::Error)]
pub enum WalkError {
    /// The source failed.
    #[error(transparent)]
    Source(#[from] SourceError),
    /// The view or frame cannot be drawn.
    #[error(transparent)]
    Driver(#[from] DriverError),
    /// A tone-mapping mode that does not parse.
    #[error(transparent)]
    Tone(#[from] crate::output::ToneError),
}

/// One drawn frame: tone-mapped RGB bytes, top row first.
#[derive(Clone, Debug)]
pub struct Frame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// 3 bytes per pixel.
    pub rgb: Vec<u8>,
    /// Drawing it took this long (the driver's frame and the tone mapping).
    pub took: Duration,
}

/// The state of a walkthrough.
pub struct Walkthrough {
    source: Box<dyn Source>,
    driver: Box<dyn Driver>,
    /// Samples received and not yet handed to the driver.
    batch: Gather,
    options: WalkOptions,
    /// The view before the last settled change (`last` goes back to it).
    previous: Option<View>,
    /// The view when the current one settled.
    settled: View,
    request: Option<BeamRequest>,
    refinement: Refinement,
    last_arrival: Instant,
    /// Requests made: seeds each one's jittered beam selection.
    requests: u64,
    /// The driver dropped its estimates (a large turn): the next request
    /// must have everything sent again.
    resend: bool,
    tone: Option<ToneMap>,
    received: u64,
    /// Pixels the last settled view filled from neighbouring beams.
    filled: u64,
    meter: RateMeter,
    /// When the walkthrough began: the origin of the meter's clock.
    opened: Instant,
    /// Keep the eye's height while moving.
    pub head_fixed: bool,
}

impl Walkthrough {
    /// A walkthrough starting at `driver`'s viewport; nothing is requested
    /// until [`Walkthrough::settle`].
    pub fn new(source: Box<dyn Source>, driver: Box<dyn Driver>, options: WalkOptions) -> Walkthrough {
        let settled = driver.viewport().view.clone();
        Walkthrough {
            refinement: Refinement::new(options.density, options.max_density),
            source,
            driver,
            batch: Gather::default(),
            options,
            previous: None,
            settled,
            request: None,
            last_arrival: Instant::now(),
            requests: 0,
            resend: true,
            tone: None,
            received: 0,
            filled: 0,
            meter: RateMeter::default(),
            opened: Instant::now(),
            head_fixed: false,
        }
    }

    /// The current viewport.
    pub fn viewport(&self) -> &Viewport {
        self.driver.viewport()
    }

    /// The current view.
    pub fn view(&self) -> &View {
        &self.driver.viewport().view
    }

    /// The holodeck's sections.
    pub fn sections(&self) -> &[holodeck_protocol::Section] {
        self.source.sections()
    }

    /// The driver.
    pub fn driver(&self) -> &dyn Driver {
        self.driver.as_ref()
    }

    /// The source's name.
    pub fn source_name(&self) -> String {
        self.source.name()
    }

    /// Moves the view without asking for anything (during motion).
    pub fn move_to(&mut self, view: View) -> Result<(), WalkError> {
        let vp = self.driver.viewport();
        let viewport = Viewport::new(view, vp.width, vp.height)?;
        let drops = self.driver.stats().cache_drops;
        self.driver.set_view(viewport);
        self.resend |= self.driver.stats().cache_drops > drops;
        Ok(())
    }

    /// Changes the frame size (a window resize), keeping the horizontal field.
    pub fn resize(&mut self, width: u32, height: u32) -> Result<(), WalkError> {
        let view = super::navigate::fit_aspect(self.view(), width, height);
        let viewport = Viewport::new(view, width, height)?;
        let drops = self.driver.stats().cache_drops;
        self.driver.set_view(viewport);
        self.resend |= self.driver.stats().cache_drops > drops;
        Ok(())
    }

    /// Motion stopped (or the view jumped): the view's beams are requested
    /// and the stored samples the display lacks arrive now. Returns them.
    pub fn settle(&mut self) -> Result<u64, WalkError> {
        let view = self.view().clone();
        if view != self.settled {
            self.previous = Some(std::mem::replace(&mut self.settled, view));
        }
        self.ask(self.resend)
    }

    /// Jumps to `view` (a view line, `last`, `frame`) and settles there.
    pub fn jump(&mut self, view: View) -> Result<u64, WalkError> {
        self.move_to(view)?;
        self.settle()
    }

    /// Goes back to the view before the last change (and from there, back again).
    pub fn last(&mut self) -> Result<Option<u64>, WalkError> {
        match self.previous.clone() {
            Some(v) => self.jump(v).map(Some),
            None => Ok(None),
        }
    }

    /// Forgets every sample and has the source send them all again.
    pub fn refresh(&mut self) -> Result<u64, WalkError> {
        self.driver.clear();
        self.ask(true)
    }

    fn ask(&mut self, resend: bool) -> Result<u64, WalkError> {
        let viewport = self.driver.viewport().clone();
        self.refinement = Refinement::new(self.options.density, self.options.max_density);
        self.requests += 1;
        let options = RequestOptions {
            density: self.options.density,
            ..self.options.request
        };
        let request = if resend {
            // The same selection as `holodeck pict` makes for the view.
            BeamRequest::for_viewport(self.source.sections(), &viewport, &options, 0)
        } else {
            self.refining(self.options.density)
        };
        {
            let source = &self.source;
            self.refinement
                .asked(outstanding(&request, &|k| if resend { 0 } else { source.received(k) }));
        }
        let (driver, batch) = (&mut self.driver, &mut self.batch);
        let n = self.source.request(&request, resend, &mut |d: Delivery<'_>| {
            deliver(batch, d, driver.as_mut())
        })?;
        batch.flush(driver.as_mut());
        let n = n + if self.options.neighbours {
            self.fill_gaps(&request)?
        } else {
            0
        };
        self.resend = false;
        self.request = Some(request);
        self.last_arrival = Instant::now();
        self.received += n;
        self.meter.add(n, self.opened.elapsed().as_secs_f64());
        Ok(n)
    }

    /// Pixels that `request`'s beams left without a ray take the stored
    /// rays of the beams next to theirs; returns the samples handed over.
    fn fill_gaps(&mut self, request: &BeamRequest) -> Result<u64, WalkError> {
        self.filled = 0;
        let empty = self.driver.empty_pixels();
        let gaps = crate::gaps::count(&empty);
        if gaps == 0 {
            return Ok(0);
        }
        let mut given: Vec<holodeck_protocol::BeamKey> = request.beams.iter().map(|b| b.0).collect();
        given.sort_unstable();
        let near = crate::gaps::neighbour_beams(self.source.sections(), self.driver.viewport(), &empty, &given);
        let driver = &mut self.driver;
        let n = self
            .source
            .neighbours(&near, &mut |d: Delivery<'_>| deliver_where_empty(d, driver.as_mut()))?;
        self.filled = gaps - crate::gaps::count(&self.driver.empty_pixels());
        Ok(n)
    }

    /// Pixels the last settled view filled from the rays of neighbouring
    /// beams (with [`WalkOptions::neighbours`]).
    pub fn filled(&self) -> u64 {
        self.filled
    }

    /// A request for `density` samples per pixel that asks each beam for
    /// what the display holds plus its pixels' share of what they still want.
    fn refining(&self, density: f64) -> BeamRequest {
        let options = RequestOptions {
            density,
            ..self.options.request
        };
        let want = self.driver.needs(density as f32);
        let source = &self.source;
        BeamRequest::refining(
            source.sections(),
            self.driver.viewport(),
            &options,
            self.requests,
            &want,
            &|k| source.received(k),
        )
    }

    /// Takes the samples traced for the view until `deadline`, raising the
    /// view's density once most of what it asked for is in. Returns the
    /// samples taken.
    pub fn poll(&mut self, deadline: Instant) -> Result<u64, WalkError> {
        let (driver, batch) = (&mut self.driver, &mut self.batch);
        let n = self
            .source
            .poll(deadline, &mut |s: &[Sample]| batch.add(s, driver.as_mut()))?;
        batch.flush(driver.as_mut());
        self.received += n;
        self.meter.add(n, self.opened.elapsed().as_secs_f64());
        if n > 0 {
            self.last_arrival = Instant::now();
        }
        let Some(request) = &self.request else { return Ok(n) };
        let source = &self.source;
        let missing = outstanding(request, &|k| source.received(k));
        if let Some(density) = self.refinement.raise(missing, self.last_arrival.elapsed() >= QUIET) {
            self.last_arrival = Instant::now();
            let request = self.refining(density);
            let source = &self.source;
            self.refinement.asked(outstanding(&request, &|k| source.received(k)));
            tracing::debug!("asking for {density} samples per pixel");
            self.source.raise(&request)?;
            self.request = Some(request);
        }
        Ok(n)
    }

    /// The world point under pixel (`col`, `row`), if the frame shows one.
    pub fn point_at(&self, col: u32, row: u32) -> Option<DVec3> {
        self.driver.point_at(col, row)
    }

    /// Draws the frame, tone mapped with the held tone map (made from the
    /// first frame with samples, and again on [`Walkthrough::retone`]).
    pub fn frame(&mut self) -> Result<(Frame, Picture), WalkError> {
        let start = Instant::now();
        let picture = self.driver.render();
        if self.tone.is_none() && picture.pixels.iter().any(|p| p.max_element() > 0.0) {
            self.retone_from(&picture)?;
        }
        let rgb = match &self.tone {
            Some(map) => map.apply(&picture),
            None => vec![0; picture.pixels.len() * 3],
        };
        let frame = Frame {
            width: picture.width as u32,
            height: picture.height as u32,
            rgb,
            took: start.elapsed(),
        };
        Ok((frame, picture))
    }

    /// Makes the tone map again from what is on screen now, as `holodeck
    /// pict` does for its pictures.
    pub fn retone(&mut self) -> Result<(), WalkError> {
        let picture = self.driver.render();
        self.retone_from(&picture)
    }

    fn retone_from(&mut self, picture: &Picture) -> Result<(), WalkError> {
        let mode = parse_tone(&self.options.tone, Some(picture))?;
        self.tone = Some(ToneMap::new(
            &Histogram::from_picture(picture),
            mode,
            DisplayRange::default(),
        ));
        Ok(())
    }

    /// Sends a command to the server.
    pub fn control(&mut self, c: Control) -> Result<(), WalkError> {
        Ok(self.source.control(c)?)
    }

    /// Samples received in all, and per second lately.
    pub fn received(&self) -> (u64, f64) {
        (self.received, self.meter.rate())
    }

    /// The server's last report.
    pub fn server(&self) -> Option<Progress> {
        self.source.status()
    }

    /// Messages for the user since the last call.
    pub fn notices(&mut self) -> Vec<String> {
        self.source.notices()
    }
}
