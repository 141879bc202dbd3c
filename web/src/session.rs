//! A display session driven by events, as a web page runs one: the bytes
//! the server sends go in ([`Session::receive`]), the bytes for the server
//! come out ([`Session::take_output`]), and nothing here blocks, opens a
//! socket or reads a clock (the page passes the time in, in seconds).
//!
//! It asks for beams as the native window does: nothing while the view
//! moves (the driver reprojects what it holds), the view's beams when it
//! settles (the stored rays arrive at once), and, while it stays, a density
//! doubled each time most of what was asked for has come.

use std::collections::{HashMap, HashSet, VecDeque};

use holodeck_display::command::{command_name, Command};
use holodeck_display::denoise::{Denoised, Denoiser};
use holodeck_display::gaps;
use holodeck_display::gather::Gather;
use holodeck_display::motion::{Held, Motion};
use holodeck_display::output::parse_tone;
use holodeck_display::request::{outstanding, BeamRequest, Refinement, RequestOptions};
use holodeck_display::status::RateMeter;
use holodeck_display::tonemap::{DisplayRange, Histogram, ToneMap};
use holodeck_display::{navigate, Driver, EstimatorOptions, Sample, SampleDecoder, Viewport};
use holodeck_protocol::site::SiteIndex;
use holodeck_protocol::wire::{
    encode_frame, Access, Control, ControlOutcome, Frame, FrameBuffer, Hello, Message, Progress, Role, PROTOCOL_VERSION,
};
use holodeck_protocol::{BeamKey, Picture, RayRecord, Section, View};

use crate::fetch::{plan, Fetch};

/// A still view that got nothing for this long (seconds) asks for more at once.
const QUIET: f64 = 1.0;

/// How a page's display draws and asks.
#[derive(Clone, Debug, PartialEq)]
pub struct SessionOptions {
    /// The driver: "quadtree" or "splat" (CPU), "voronoi" or "mesh" (WebGL2;
    /// the quadtree where the page has none).
    pub driver: String,
    /// Clean frames with the à-trous filter.
    pub denoise: bool,
    /// Samples per pixel asked for when a view settles.
    pub density: f64,
    /// Most samples per pixel a still view asks for (its density doubles
    /// up to this while it stays; the first density: never more).
    pub max_density: f64,
    /// In a replayed site, pixels that a settled view's beams leave without
    /// a ray (a sparse file) take the rays of the beams next to theirs, as
    /// `holodeck pict --neighbour-beams` does.
    pub neighbours: bool,
}

impl Default for SessionOptions {
    fn default() -> Self {
        SessionOptions {
            driver: "quadtree".into(),
            denoise: true,
            density: 1.0,
            max_density: 1024.0,
            neighbours: false,
        }
    }
}

/// Why the session cannot go on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SessionError {
    /// The server refused this display (a wrong token, say).
    #[error("the server refused this display: {0}")]
    Refused(String),
    /// The server sent bytes that are not the protocol.
    #[error("the server sent a bad frame: {0}")]
    Frame(String),
    /// The server sent something out of turn.
    #[error("protocol error: {0}")]
    Protocol(String),
    /// A replayed site's index or bytes are wrong.
    #[error("the site: {0}")]
    Site(String),
    /// The frame size or view cannot be drawn.
    #[error("{0}")]
    Driver(String),
    /// The driver named is not one the page has.
    #[error("the page has no driver {0:?} (it has quadtree, splat, voronoi and mesh)")]
    UnknownDriver(String),
}

/// Where the samples come from.
enum Link {
    /// The Hello is sent; the Welcome is due.
    Greeting,
    /// Welcomed by a server.
    Open { decoder: SampleDecoder, access: Access },
    /// A static site's file, replayed: its index, and the beams fetched.
    Site {
        decoder: SampleDecoder,
        index: SiteIndex,
        loaded: HashSet<BeamKey>,
    },
}

/// One display's session with a server, as a page runs it.
pub struct Session {
    driver: Box<dyn Driver>,
    frames: FrameBuffer,
    out: Vec<u8>,
    link: Link,
    batch: Gather,
    scratch: Vec<Sample>,
    request: Option<BeamRequest>,
    refinement: Refinement,
    /// Rays received per beam (since the last request that asked to resend).
    received: HashMap<BeamKey, u64>,
    /// Immediate transfers asked for and not yet delivered.
    transfers: u32,
    requests: u64,
    /// The driver dropped its estimates: the next request must have everything sent again.
    resend: bool,
    /// The view before the last settled change (`last` goes back to it).
    previous: Option<View>,
    settled: View,
    /// The view came in the link or a command: the Welcome does not replace it.
    view_given: bool,
    last_arrival: f64,
    progress: Option<Progress>,
    notices: Vec<String>,
    samples: u64,
    meter: RateMeter,
    tone: Option<ToneMap>,
    /// A motion in progress, and the button holding it.
    held: Option<(Held, u32)>,
    /// Keep the eye's height while moving.
    head_fixed: bool,
    options: SessionOptions,
    /// The connection was lost: the next Welcome drops the estimates.
    reconnecting: bool,
    /// A replay's ranges to fetch, not yet taken by the page.
    fetches: VecDeque<Fetch>,
    /// Ranges taken by the page, awaiting their bytes, in order.
    awaiting: VecDeque<Fetch>,
    /// Pixels without a ray when the last gap-filling transfer was asked
    /// for, how many it filled, and its rays so far (they join at once when
    /// it ends, as `pict` adds a sparse file's neighbours in one go: a pixel
    /// empty before takes the rays of every neighbouring beam).
    gaps: u64,
    filled: u64,
    gap_samples: Vec<Sample>,
}

impl Session {
    /// A session drawing `width` x `height` frames as `options` say; it
    /// starts at `view` if given, else at the holodeck's default view once
    /// the server's Welcome names the sections.
    pub fn new(view: Option<View>, width: u32, height: u32, options: SessionOptions) -> Result<Session, SessionError> {
        let view_given = view.is_some();
        let view = navigate::fit_aspect(&view.unwrap_or_default(), width, height);
        let viewport = Viewport::new(view.clone(), width, height).map_err(|e| SessionError::Driver(e.to_string()))?;
        let estimates = EstimatorOptions::default();
        let mut notices = Vec::new();
        let cpu = |viewport| holodeck_display::quadtree::QuadtreeDriver::with_options(viewport, estimates);
        let inner: Box<dyn Driver> = match options.driver.as_str() {
            "quadtree" => Box::new(cpu(viewport)),
            "splat" => Box::new(holodeck_display::splat::SplatDriver::with_options(viewport, estimates)),
            name @ ("voronoi" | "mesh") => {
                let setup = holodeck_display::DriverSetup {
                    options: estimates,
                    geometry: None,
                };
                match holodeck_display::make_driver(name, viewport.clone(), setup) {
                    Ok(d) => d,
                    // No WebGL2 here: the CPU draws.
                    Err(e) => {
                        notices.push(format!(
                            "the {name} driver cannot run here ({e}): the quadtree draws instead"
                        ));
                        Box::new(cpu(viewport))
                    }
                }
            }
            other => return Err(SessionError::UnknownDriver(other.to_string())),
        };
        let driver: Box<dyn Driver> = if options.denoise {
            Box::new(Denoised::new(inner, Denoiser::Atrous(Default::default())))
        } else {
            inner
        };
        Ok(Session {
            driver,
            frames: FrameBuffer::new(),
            out: Vec::new(),
            link: Link::Greeting,
            batch: Gather::default(),
            scratch: Vec::new(),
            request: None,
            refinement: Refinement::new(options.density, options.max_density),
            received: HashMap::new(),
            transfers: 0,
            requests: 0,
            resend: true,
            previous: None,
            settled: view,
            view_given,
            last_arrival: 0.0,
            progress: None,
            notices,
            samples: 0,
            meter: RateMeter::default(),
            tone: None,
            held: None,
            head_fixed: false,
            reconnecting: false,
            options,
            fetches: VecDeque::new(),
            awaiting: VecDeque::new(),
            gaps: 0,
            filled: 0,
            gap_samples: Vec::new(),
        })
    }

    fn send(&mut self, f: &Frame) {
        // Only messages this session makes are encoded: they always fit.
        if let Err(e) = encode_frame(f, &mut self.out) {
            self.notices.push(format!("could not encode a message: {e}"));
        }
    }

    /// Greets the server with `token` (the Hello goes out with the next
    /// [`Session::take_output`]); `read_only` asks for viewer access
    /// whatever the token allows.
    pub fn hello(&mut self, token: &str, read_only: bool) {
        self.send(&Frame::Message(Message::Hello(Hello {
            version: PROTOCOL_VERSION,
            role: Role::Display,
            scene: String::new(),
            token: token.to_string(),
            read_only,
        })));
    }

    /// The connection was lost: the next one starts with a new [`Session::hello`].
    /// The picture stays until the new connection's Welcome, when the
    /// estimates are dropped and every stored ray of the view is asked for
    /// again (the server may have more, or have been restarted on another
    /// file).
    pub fn reconnect(&mut self) {
        self.frames = FrameBuffer::new();
        self.out.clear();
        self.link = Link::Greeting;
        self.transfers = 0;
        self.held = None;
        self.reconnecting = true;
    }

    /// The bytes for the server since the last call.
    pub fn take_output(&mut self) -> Vec<u8> {
        std::mem::take(&mut self.out)
    }

    /// Takes bytes the server sent (any split: frames are put together
    /// here) at time `now`.
    pub fn receive(&mut self, bytes: &[u8], now: f64) -> Result<(), SessionError> {
        self.frames.push(bytes);
        loop {
            let frame = self
                .frames
                .next_frame()
                .map_err(|e| SessionError::Frame(e.to_string()))?;
            let Some(frame) = frame else { break };
            self.take(frame, now)?;
        }
        Ok(())
    }

    fn take(&mut self, frame: Frame, now: f64) -> Result<(), SessionError> {
        match frame {
            Frame::Message(Message::Welcome { sections, access, .. }) => {
                let sections = sections
                    .into_iter()
                    .map(Section::try_from)
                    .collect::<Result<Vec<_>, _>>()
                    .map_err(|e| SessionError::Protocol(format!("a section of the Welcome: {e}")))?;
                if std::mem::take(&mut self.reconnecting) {
                    self.batch.flush(self.driver.as_mut());
                    self.driver.clear();
                    self.view_given = true;
                }
                self.start_view(&sections)?;
                self.link = Link::Open {
                    decoder: SampleDecoder::new(sections),
                    access,
                };
                self.view_given = true;
                self.ask(true, now);
            }
            Frame::Message(Message::Refused { reason, .. }) => return Err(SessionError::Refused(reason)),
            Frame::Beam { key, records } => {
                let Link::Open { decoder, .. } = &self.link else {
                    return Err(SessionError::Protocol("beam data before the Welcome".into()));
                };
                *self.received.entry(key).or_default() += records.len() as u64;
                self.scratch.clear();
                decoder.decode(key.section, key.beam, &records, &mut self.scratch);
                self.batch.add(&self.scratch, self.driver.as_mut());
                let n = records.len() as u64;
                self.samples += n;
                self.meter.add(n, now);
                if n > 0 {
                    self.last_arrival = now;
                }
            }
            Frame::Message(Message::Delivered { .. }) => {
                // The batches end where `pict`'s chunks do (the beam that
                // reaches a chunk's size, or the transfer's end), so the
                // page's estimates are the file's.
                self.batch.flush(self.driver.as_mut());
                self.transfers = self.transfers.saturating_sub(1);
            }
            Frame::Message(Message::Progress(p)) => self.progress = Some(p),
            Frame::Message(Message::ControlReply(r)) => {
                let name = command_name(&r.control);
                self.notices.push(match r.outcome {
                    ControlOutcome::Done => format!("{name} done"),
                    other => format!("{name} {other}"),
                });
            }
            Frame::Message(Message::Error { message }) => self.notices.push(format!("server: {message}")),
            other => return Err(SessionError::Protocol(format!("unexpected {other:?}"))),
        }
        Ok(())
    }

    /// Starts at the holodeck's default view unless one was given.
    fn start_view(&mut self, sections: &[Section]) -> Result<(), SessionError> {
        if !self.view_given {
            if let Some(first) = sections.first() {
                let vp = self.driver.viewport();
                let view = navigate::fit_aspect(&navigate::default_view(first), vp.width, vp.height);
                self.set_view(view)?;
                self.settled = self.view().clone();
            }
        }
        Ok(())
    }

    /// Replays a static site's file instead of joining a server: `index`
    /// is its `holodeck.idx`. The view's beams are then asked for as byte
    /// ranges ([`Session::take_fetches`]) and come in through
    /// [`Session::add_fetched`].
    pub fn open_site(&mut self, index: &[u8], now: f64) -> Result<(), SessionError> {
        let index = SiteIndex::decode(index).map_err(|e| SessionError::Site(e.to_string()))?;
        let sections = index.header.sections.clone();
        self.start_view(&sections)?;
        self.view_given = true;
        self.link = Link::Site {
            decoder: SampleDecoder::new(sections),
            index,
            loaded: HashSet::new(),
        };
        self.ask(true, now);
        Ok(())
    }

    /// Whether a replayed site fills its views' gaps from neighbouring
    /// beams ([`SessionOptions::neighbours`]); from the next view on.
    pub fn set_neighbours(&mut self, on: bool) {
        self.options.neighbours = on;
    }

    /// The byte ranges the page should fetch now, in order: (chunk, first
    /// byte, past the last byte). Their bytes must come back through
    /// [`Session::add_fetched`] in this order.
    pub fn take_fetches(&mut self) -> Vec<(u32, u64, u64)> {
        let taken: Vec<(u32, u64, u64)> = self.fetches.iter().map(|f| (f.chunk, f.start, f.end)).collect();
        self.awaiting.extend(self.fetches.drain(..));
        taken
    }

    /// The bytes of the oldest range taken ([`Session::take_fetches`]);
    /// `None`: it could not be fetched (its beams are asked for again when
    /// the view next settles).
    pub fn add_fetched(&mut self, chunk: u32, start: u64, bytes: Option<&[u8]>, now: f64) -> Result<(), SessionError> {
        let Some(fetch) = self.awaiting.pop_front() else {
            return Err(SessionError::Site("bytes came that no range asked for".into()));
        };
        if (fetch.chunk, fetch.start) != (chunk, start) {
            return Err(SessionError::Site(format!(
                "bytes of chunk {chunk} at {start} came where chunk {} at {} was due",
                fetch.chunk, fetch.start
            )));
        }
        if let Some(bytes) = bytes {
            if bytes.len() as u64 != fetch.end - fetch.start {
                return Err(SessionError::Site(format!(
                    "{} bytes of chunk {chunk} at {start} came for a range of {}",
                    bytes.len(),
                    fetch.end - fetch.start
                )));
            }
            let Link::Site { decoder, loaded, .. } = &mut self.link else {
                return Err(SessionError::Site("this display replays no site".into()));
            };
            for b in &fetch.beams {
                let from = (u64::from(b.offset) - fetch.start) as usize;
                let to = (b.end() - fetch.start) as usize;
                let Some(records) = RayRecord::slice_from_bytes(&bytes[from..to]) else {
                    return Err(SessionError::Site(format!("beam {:?}: not whole records", b.key)));
                };
                if fetch.gaps {
                    // Not loaded: a view that sees this beam takes all its rays.
                    decoder.decode(b.key.section, b.key.beam, records, &mut self.gap_samples);
                } else {
                    loaded.insert(b.key);
                    self.scratch.clear();
                    decoder.decode(b.key.section, b.key.beam, records, &mut self.scratch);
                    self.batch.add(&self.scratch, self.driver.as_mut());
                }
                self.samples += records.len() as u64;
                self.meter.add(records.len() as u64, now);
            }
            self.last_arrival = now;
        }
        if fetch.closes_transfer {
            self.batch.flush(self.driver.as_mut());
            self.transfers = self.transfers.saturating_sub(1);
            if fetch.gaps {
                self.driver.add_where_empty(&self.gap_samples);
                self.gap_samples = Vec::new();
                self.filled = self.gaps.saturating_sub(gaps::count(&self.driver.empty_pixels()));
            } else if self.options.neighbours {
                self.fill_gaps();
            }
        }
        Ok(())
    }

    /// In a replayed site, once a view's beams are in: the ranges of the
    /// beams next to those its pixels without a ray look through (not
    /// fetched as the view's own), to fill those pixels.
    fn fill_gaps(&mut self) {
        let Link::Site { decoder, index, loaded } = &self.link else {
            return;
        };
        self.filled = 0;
        let empty = self.driver.empty_pixels();
        self.gaps = gaps::count(&empty);
        if self.gaps == 0 {
            return;
        }
        let mut given: Vec<BeamKey> = loaded.iter().copied().collect();
        given.sort_unstable();
        let near = gaps::neighbour_beams(decoder.sections(), self.driver.viewport(), &empty, &given);
        let mut fetches = plan(index, &near);
        for f in &mut fetches {
            f.gaps = true;
        }
        if !fetches.is_empty() {
            self.transfers += 1;
            self.fetches.extend(fetches);
        }
    }

    fn set_view(&mut self, view: View) -> Result<(), SessionError> {
        self.batch.flush(self.driver.as_mut());
        let vp = self.driver.viewport();
        let viewport = Viewport::new(view, vp.width, vp.height).map_err(|e| SessionError::Driver(e.to_string()))?;
        let drops = self.driver.stats().cache_drops;
        self.driver.set_view(viewport);
        self.resend |= self.driver.stats().cache_drops > drops;
        Ok(())
    }

    /// Asks for the view's beams (all their stored rays with `resend`).
    fn ask(&mut self, resend: bool, now: f64) {
        if let Link::Site { decoder, index, loaded } = &mut self.link {
            // A replay: the view's beams not fetched yet, as byte ranges.
            if resend {
                loaded.clear();
            }
            let request = BeamRequest::for_viewport(
                decoder.sections(),
                self.driver.viewport(),
                &RequestOptions::default(),
                0,
            );
            let mut keys: Vec<BeamKey> = request
                .beams
                .iter()
                .map(|b| b.0)
                .filter(|k| !loaded.contains(k))
                .collect();
            keys.sort_unstable();
            let fetches = plan(index, &keys);
            if !fetches.is_empty() {
                self.transfers += 1;
                self.fetches.extend(fetches);
            }
            self.resend = false;
            self.last_arrival = now;
            return;
        }
        let Link::Open { decoder, .. } = &self.link else { return };
        let sections = decoder.sections();
        self.refinement = Refinement::new(self.options.density, self.options.max_density);
        self.requests += 1;
        let options = RequestOptions {
            density: self.options.density,
            ..RequestOptions::default()
        };
        let viewport = self.driver.viewport().clone();
        if resend {
            self.received.clear();
        }
        let request = if resend {
            // The same selection as `holodeck pict` makes for the view.
            BeamRequest::for_viewport(sections, &viewport, &options, 0)
        } else {
            let want = self.driver.needs(options.density as f32);
            let received = &self.received;
            BeamRequest::refining(sections, &viewport, &options, self.requests, &want, &|k| {
                received.get(&k).copied().unwrap_or(0)
            })
        };
        self.refinement
            .asked(outstanding(&request, &|k| self.received.get(&k).copied().unwrap_or(0)));
        self.send(&Frame::Message(Message::BeamRequest {
            beams: request.beams.clone(),
            eye: request.eye,
            replace: true,
            resend,
        }));
        self.transfers += 1;
        self.resend = false;
        self.request = Some(request);
        self.last_arrival = now;
    }

    /// Called about once a frame: while the view stays, raises its density
    /// once most of what it asked for has come (or nothing came lately),
    /// and takes motion steps while a button is held.
    pub fn tick(&mut self, now: f64) -> Result<(), SessionError> {
        self.step(now)?;
        if self.held.is_some() || self.transfers > 0 {
            return Ok(());
        }
        let Link::Open { decoder, .. } = &self.link else {
            return Ok(());
        };
        let Some(request) = &self.request else { return Ok(()) };
        let received = &self.received;
        let missing = outstanding(request, &|k| received.get(&k).copied().unwrap_or(0));
        if let Some(density) = self.refinement.raise(missing, now - self.last_arrival >= QUIET) {
            self.last_arrival = now;
            let options = RequestOptions {
                density,
                ..RequestOptions::default()
            };
            let want = self.driver.needs(density as f32);
            let request = BeamRequest::refining(
                decoder.sections(),
                self.driver.viewport(),
                &options,
                self.requests,
                &want,
                &|k| received.get(&k).copied().unwrap_or(0),
            );
            self.refinement
                .asked(outstanding(&request, &|k| received.get(&k).copied().unwrap_or(0)));
            self.send(&Frame::Message(Message::BeamRequest {
                beams: request.beams.clone(),
                eye: request.eye,
                replace: false,
                resend: false,
            }));
            self.request = Some(request);
        }
        Ok(())
    }

    /// The view stopped moving (or jumped): its beams are asked for.
    pub fn settle(&mut self, now: f64) {
        let view = self.view().clone();
        if view != self.settled {
            self.previous = Some(std::mem::replace(&mut self.settled, view));
        }
        self.ask(self.resend, now);
    }

    /// Moves to `view` and settles there.
    pub fn jump(&mut self, view: View, now: f64) -> Result<(), SessionError> {
        let vp = self.driver.viewport();
        let view = navigate::fit_aspect(&view, vp.width, vp.height);
        self.set_view(view)?;
        self.view_given = true;
        self.settle(now);
        Ok(())
    }

    /// Changes the frame size, keeping the horizontal field, and settles.
    pub fn resize(&mut self, width: u32, height: u32, now: f64) -> Result<(), SessionError> {
        let view = navigate::fit_aspect(self.view(), width, height);
        let viewport = Viewport::new(view, width, height).map_err(|e| SessionError::Driver(e.to_string()))?;
        self.batch.flush(self.driver.as_mut());
        self.driver.set_view(viewport);
        self.resend = true;
        self.tone = None;
        self.settle(now);
        Ok(())
    }

    /// The current view.
    pub fn view(&self) -> &View {
        &self.driver.viewport().view
    }

    /// The current viewport.
    pub fn viewport(&self) -> &Viewport {
        self.driver.viewport()
    }

    /// A mouse button (0 left, 1 middle, 2 right, as the web numbers them)
    /// or a touch went down at pixel (`x`, `y`); `shift` orbits instead.
    pub fn press(&mut self, button: u32, shift: bool, x: f64, y: f64) {
        if let Some(motion) = Motion::of_button(button, shift) {
            self.held = Some((Held::new(motion, (x, y)), button));
        }
    }

    /// The pointer moved to pixel (`x`, `y`).
    pub fn pointer(&mut self, x: f64, y: f64) {
        if let Some((h, _)) = &mut self.held {
            h.cursor = (x, y);
        }
    }

    /// The button was released: the motion ends and the view settles.
    /// Returns the steps taken.
    pub fn release(&mut self, button: u32, now: f64) -> u32 {
        match self.held.take() {
            Some((h, b)) if b == button => {
                self.settle(now);
                h.steps
            }
            other => {
                self.held = other;
                0
            }
        }
    }

    fn step(&mut self, now: f64) -> Result<(), SessionError> {
        let vp = self.driver.viewport();
        let (w, h) = (vp.width, vp.height);
        let head = self.head_fixed;
        let view = vp.view.clone();
        let driver = &self.driver;
        let Some((held, _)) = &mut self.held else { return Ok(()) };
        let Some(next) = held.next(&view, now, w, h, head, &|c, r| driver.point_at(c, r)) else {
            return Ok(());
        };
        self.set_view(next)
    }

    /// Carries out `c`; returns what the user should read (the view line
    /// for `where`, why a command could not be carried out), if anything.
    pub fn command(&mut self, c: Command, now: f64) -> Result<Option<String>, SessionError> {
        let control = |s: &mut Session, c: Control| {
            if let Link::Site { .. } = s.link {
                return Ok(Some(format!(
                    "{} needs a server: this is a replay of a file",
                    command_name(&c)
                )));
            }
            s.send(&Frame::Message(Message::Control(c)));
            Ok(None)
        };
        match c {
            Command::View(spec) => match self.view().clone().with(&spec) {
                Ok(v) => {
                    self.jump(v, now)?;
                    Ok(None)
                }
                Err(e) => Ok(Some(format!("view: {e}"))),
            },
            Command::Last => match self.previous.clone() {
                Some(v) => {
                    self.jump(v, now)?;
                    Ok(None)
                }
                None => Ok(Some("last: no earlier view".into())),
            },
            Command::Where => Ok(Some(format!("VIEW= {}", self.view().to_spec()))),
            Command::Frame(rect) => {
                let vp = self.driver.viewport();
                let aspect = f64::from(vp.width) / f64::from(vp.height);
                let framed = match rect {
                    Some(r) => navigate::frame(
                        &vp.view,
                        navigate::ImagePoint { x: r[0], y: r[1] },
                        navigate::ImagePoint { x: r[2], y: r[3] },
                        aspect,
                    ),
                    None => navigate::turn_toward(&vp.view, navigate::ImagePoint { x: 0.5, y: 0.5 }),
                };
                match framed {
                    Some(v) => {
                        self.jump(v, now)?;
                        Ok(None)
                    }
                    None => Ok(Some("frame: no valid view frames that".into())),
                }
            }
            Command::Pause => control(self, Control::Pause),
            Command::Resume => control(self, Control::Resume),
            Command::Kill => control(self, Control::KillSamplers),
            Command::Restart => control(self, Control::Restart),
            Command::Clobber => control(self, Control::Clobber),
            Command::Redraw | Command::Sync => Ok(None),
            Command::Refresh => {
                self.batch.flush(self.driver.as_mut());
                self.driver.clear();
                self.ask(true, now);
                Ok(None)
            }
            Command::HeadFixed(on) => {
                self.head_fixed = on;
                Ok(None)
            }
            Command::Tone => {
                self.tone = None;
                Ok(None)
            }
            Command::Quit => Ok(Some("quit: close the page to leave".into())),
            Command::Save(_) => Ok(Some("save: use the page's save button".into())),
            Command::Bench(_) => Ok(Some("bench: not in the page".into())),
        }
    }

    /// The frame in linear radiance, top row first. While an immediate
    /// transfer is under way the frame shows its whole batches only (the
    /// batches are part of what makes the picture); afterwards, every
    /// sample received.
    pub fn picture(&mut self) -> Picture {
        if self.transfers == 0 {
            self.batch.flush(self.driver.as_mut());
        }
        self.driver.render()
    }

    /// The frame tone mapped to RGBA bytes (top row first), as a canvas
    /// takes them; the tone map is made from the first frame with light
    /// (and again after [`Command::Tone`] or a resize).
    pub fn frame_rgba(&mut self) -> Vec<u8> {
        let picture = self.picture();
        if self.tone.is_none() && picture.pixels.iter().any(|p| p.max_element() > 0.0) {
            if let Ok(mode) = parse_tone("camera", Some(&picture)) {
                self.tone = Some(ToneMap::new(
                    &Histogram::from_picture(&picture),
                    mode,
                    DisplayRange::default(),
                ));
            }
        }
        let mut rgba = Vec::with_capacity(picture.pixels.len() * 4);
        match &self.tone {
            Some(map) => {
                for px in map.apply(&picture).chunks_exact(3) {
                    rgba.extend_from_slice(&[px[0], px[1], px[2], 255]);
                }
            }
            None => {
                for _ in 0..picture.pixels.len() {
                    rgba.extend_from_slice(&[0, 0, 0, 255]);
                }
            }
        }
        rgba
    }

    /// Draws `n` frames afresh (a denoiser's kept frame dropped before each)
    /// and returns the mean milliseconds of one: what `holodeck view
    /// --headless` reports as a frame's drawing, for benchmarks.
    pub fn bench_render(&mut self, n: u32) -> f64 {
        self.batch.flush(self.driver.as_mut());
        let start = web_time::Instant::now();
        for _ in 0..n.max(1) {
            // Taking the store to change drops what a wrapper kept.
            let _ = self.driver.store_mut();
            std::hint::black_box(self.driver.render());
        }
        start.elapsed().as_secs_f64() * 1e3 / f64::from(n.max(1))
    }

    /// What the server and this display said since the last call.
    pub fn take_notices(&mut self) -> Vec<String> {
        std::mem::take(&mut self.notices)
    }

    /// Whether the Welcome came (or a site's index was read).
    pub fn is_open(&self) -> bool {
        matches!(self.link, Link::Open { .. } | Link::Site { .. })
    }

    /// The access the server granted, once welcomed.
    pub fn access(&self) -> Option<Access> {
        match &self.link {
            Link::Open { access, .. } => Some(*access),
            Link::Greeting | Link::Site { .. } => None,
        }
    }

    /// Immediate transfers asked for and not yet complete (0: every stored
    /// ray of the view has arrived).
    pub fn transfers(&self) -> u32 {
        self.transfers
    }

    /// A GPU driver's frame is still on its way back: the last frame drawn
    /// was the one before; draw again soon.
    pub fn frame_pending(&self) -> bool {
        self.driver.frame_pending()
    }

    /// The driver drawing ("quadtree", "mesh", ...): a GPU driver asked
    /// for falls back to the quadtree where the page has no WebGL2.
    pub fn driver_name(&self) -> &'static str {
        self.driver.name()
    }

    /// Samples received in all.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// The status line the native window shows (`frame_ms`: the last
    /// frame's time, which the page measures).
    pub fn status_line(&self, frame_ms: f64) -> String {
        let mut line = holodeck_display::status::Status {
            rate: self.meter.rate(),
            received: self.samples,
            shown: self.driver.stats().kept,
            frame_ms,
            server: self.progress,
            head_fixed: self.head_fixed,
            filled: self.filled,
        }
        .line();
        match &self.link {
            Link::Open { access, .. } => line += &format!("  {access}"),
            Link::Site { .. } => line += "  replay of a file",
            Link::Greeting => {}
        }
        line
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use holodeck_display::quadtree::QuadtreeDriver;
    use holodeck_protocol::{DepthCode, RayRecord, Rgbe, SectionKind};

    fn section() -> Section {
        Section::new(
            [0.0; 3],
            [[4.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 4.0]],
            [4, 4, 4],
            SectionKind::Interior,
        )
        .unwrap()
    }

    fn view() -> View {
        View::parse("-vtv -vp 2 2 2 -vd 1 0.2 0 -vu 0 0 1 -vh 60 -vv 45").unwrap()
    }

    fn frames(bytes: &[u8]) -> Vec<Frame> {
        let mut b = FrameBuffer::new();
        b.push(bytes);
        std::iter::from_fn(|| b.next_frame().unwrap()).collect()
    }

    fn encode(f: &Frame) -> Vec<u8> {
        let mut out = Vec::new();
        encode_frame(f, &mut out).unwrap();
        out
    }

    fn welcome(access: Access) -> Vec<u8> {
        encode(&Frame::Message(Message::Welcome {
            sections: vec![section().spec()],
            obstructions: false,
            vdistance: false,
            access,
        }))
    }

    /// Rays of `key`: every entry and exit cell pattern the seed gives,
    /// each hitting a surface half a diagonal along.
    fn records(key: BeamKey, n: usize) -> Vec<RayRecord> {
        let diagonal = section().diagonal();
        (0..n)
            .map(|i| {
                let b = (i as u32)
                    .wrapping_mul(2_654_435_761)
                    .wrapping_add(key.beam)
                    .to_le_bytes();
                let light = 0.1 + (i % 7) as f32 * 0.1;
                RayRecord::new(
                    [b[0], b[1]],
                    [b[2], b[3]],
                    Rgbe::from_rgb([light, light * 0.8, 0.5]),
                    DepthCode::encode(diagonal * (0.3 + (i % 5) as f64 * 0.1), diagonal),
                )
            })
            .collect()
    }

    /// A site of `sections` whose beams hold the rays given, in order, in
    /// one chunk: its index and the chunk's bytes.
    fn one_chunk_site(
        sections: &[Section],
        beams: impl Iterator<Item = (BeamKey, Vec<RayRecord>)>,
    ) -> (SiteIndex, Vec<u8>) {
        let (mut chunk, mut rows) = (Vec::new(), Vec::new());
        for (key, r) in beams {
            rows.push(holodeck_protocol::site::SiteBeam {
                key,
                chunk: 0,
                offset: chunk.len() as u32,
                rays: r.len() as u32,
            });
            chunk.extend_from_slice(RayRecord::slice_as_bytes(&r));
        }
        let index = SiteIndex {
            header: holodeck_protocol::site::SiteHeader {
                sections: sections.to_vec(),
                chunks: vec![chunk.len() as u64],
            },
            beams: rows,
        };
        (index, chunk)
    }

    fn session() -> Session {
        Session::new(
            Some(view()),
            64,
            48,
            SessionOptions {
                denoise: false,
                max_density: 1.0,
                ..SessionOptions::default()
            },
        )
        .unwrap()
    }

    #[test]
    fn a_session_asks_for_its_view_and_draws_what_a_driver_given_the_same_rays_draws() {
        let mut s = session();
        s.hello("secret", true);
        let hello = frames(&s.take_output());
        assert!(matches!(&hello[..], [Frame::Message(Message::Hello(h))] if h.token == "secret" && h.read_only));
        // The Welcome split anywhere is put together.
        let w = welcome(Access::Viewer);
        s.receive(&w[..3], 0.0).unwrap();
        assert!(!s.is_open());
        s.receive(&w[3..], 0.0).unwrap();
        assert_eq!(s.access(), Some(Access::Viewer));
        let asked = frames(&s.take_output());
        let sections = vec![section()];
        let expected = BeamRequest::for_viewport(&sections, s.viewport(), &RequestOptions::default(), 0);
        let Frame::Message(Message::BeamRequest {
            beams, replace, resend, ..
        }) = &asked[0]
        else {
            panic!("{asked:?}")
        };
        assert_eq!((beams, *replace, *resend), (&expected.beams, true, true));
        assert_eq!(s.transfers(), 1);

        // The server's answer, in pieces of any size: every beam, then Delivered.
        let mut stream = Vec::new();
        let mut reference = QuadtreeDriver::with_options(s.viewport().clone(), EstimatorOptions::default());
        let decoder = SampleDecoder::new(sections.clone());
        let mut all = Vec::new();
        for &(key, _) in beams {
            let r = records(key, 40);
            decoder.decode(key.section, key.beam, &r, &mut all);
            stream.extend(encode(&Frame::Beam { key, records: r }));
        }
        stream.extend(encode(&Frame::Message(Message::Delivered {
            beams: beams.len() as u32,
            rays: all.len() as u64,
        })));
        for piece in stream.chunks(1000) {
            s.receive(piece, 0.5).unwrap();
        }
        assert_eq!(s.transfers(), 0);
        assert_eq!(s.samples(), all.len() as u64);
        reference.add(&all);
        let (got, want) = (s.picture(), reference.render());
        assert!(want.pixels.iter().filter(|p| p.max_element() > 0.0).count() > 100);
        assert_eq!(got, want, "the page's picture is the driver's, bit for bit");
        // Tone mapped for a canvas: RGBA, opaque, not black.
        let rgba = s.frame_rgba();
        assert_eq!(rgba.len(), 64 * 48 * 4);
        assert!(rgba.chunks_exact(4).all(|p| p[3] == 255) && rgba.iter().any(|&v| v > 0 && v < 255));
    }

    #[test]
    fn a_site_replay_fetches_the_views_beams_by_range_and_draws_them() {
        let sections = vec![section()];
        let mut s = session();
        let wanted = BeamRequest::for_viewport(&sections, s.viewport(), &RequestOptions::default(), 0);
        let mut keys: Vec<BeamKey> = wanted.beams.iter().map(|b| b.0).collect();
        keys.sort_unstable();
        // Every wanted beam but the first holds rays, in one chunk.
        let mut all = Vec::new();
        let decoder = SampleDecoder::new(sections.clone());
        for &key in &keys[1..] {
            decoder.decode(key.section, key.beam, &records(key, 30), &mut all);
        }
        let (index, chunk) = one_chunk_site(&sections, keys[1..].iter().map(|&k| (k, records(k, 30))));
        s.open_site(&index.encode().unwrap(), 0.0).unwrap();
        assert!(s.is_open() && s.transfers() == 1);
        let fetches = s.take_fetches();
        assert_eq!(fetches, vec![(0, 0, chunk.len() as u64)], "near beams share one range");
        assert!(s.take_fetches().is_empty());
        // Bytes for a range not asked for are refused.
        let mut t = session();
        t.open_site(&index.encode().unwrap(), 0.0).unwrap();
        t.take_fetches();
        assert!(matches!(
            t.add_fetched(0, 10, Some(&chunk[10..]), 0.0),
            Err(SessionError::Site(_))
        ));
        s.add_fetched(0, 0, Some(&chunk), 0.5).unwrap();
        assert_eq!((s.transfers(), s.samples()), (0, all.len() as u64));
        let mut reference = QuadtreeDriver::with_options(s.viewport().clone(), EstimatorOptions::default());
        reference.add(&all);
        assert_eq!(s.picture(), reference.render());
        // A replay has no server to command; a still view fetches nothing more.
        let said = s.command(Command::Pause, 1.0).unwrap().unwrap();
        assert_eq!(said, "pause needs a server: this is a replay of a file");
        s.settle(2.0);
        assert!(s.take_fetches().is_empty() && s.take_output().is_empty());
        assert!(s.status_line(1.0).ends_with("replay of a file"));
    }

    #[test]
    fn a_sparse_site_fills_its_gaps_from_neighbouring_beams_as_pict_does() {
        let sections = vec![section()];
        let decoder = SampleDecoder::new(sections.clone());
        // Two rays in every beam of the section: a fill by volume, sparse.
        let rays: HashMap<BeamKey, Vec<RayRecord>> = (0..sections[0].beam_count())
            .map(|b| (BeamKey::new(0, b), records(BeamKey::new(0, b), 2)))
            .collect();
        let mut keys: Vec<BeamKey> = rays.keys().copied().collect();
        keys.sort_unstable();
        let (index, chunk) = one_chunk_site(&sections, keys.iter().map(|k| (*k, rays[k].clone())));
        let index = index.encode().unwrap();
        let replay = |neighbours: bool| {
            let mut s = session();
            s.set_neighbours(neighbours);
            s.open_site(&index, 0.0).unwrap();
            let mut rounds = 0;
            loop {
                let fetches = s.take_fetches();
                if fetches.is_empty() {
                    break;
                }
                rounds += 1;
                for (c, a, b) in fetches {
                    s.add_fetched(c, a, Some(&chunk[a as usize..b as usize]), 0.5).unwrap();
                }
            }
            assert_eq!(s.transfers(), 0);
            (s, rounds)
        };
        let ((mut plain, one), (mut filled, two)) = (replay(false), replay(true));
        assert_eq!((one, two), (1, 2), "the view's beams, then their neighbours'");

        // What pict does: the view's rays, then the neighbours' where empty.
        let mut reference = QuadtreeDriver::with_options(plain.viewport().clone(), EstimatorOptions::default());
        let wanted = BeamRequest::for_viewport(&sections, plain.viewport(), &RequestOptions::default(), 0);
        let mut keys: Vec<BeamKey> = wanted.beams.iter().map(|b| b.0).collect();
        keys.sort_unstable();
        let decode = |keys: &[BeamKey]| {
            let mut all = Vec::new();
            for k in keys {
                decoder.decode(k.section, k.beam, &rays[k], &mut all);
            }
            all
        };
        reference.add(&decode(&keys));
        assert_eq!(plain.picture(), reference.render());
        let empty = reference.empty_pixels();
        let before = gaps::count(&empty);
        assert!(
            before > 64 * 48 / 4,
            "{before} pixels without a ray: the site is not sparse"
        );
        let near = gaps::neighbour_beams(&sections, reference.viewport(), &empty, &keys);
        reference.add_where_empty(&decode(&near));
        let after = gaps::count(&reference.empty_pixels());
        assert!(filled.picture() == reference.render(), "the page draws what pict draws");
        // These rays hit points floating in the section, most of them off
        // the pixels without one: a few are filled.
        assert_eq!(filled.filled, before - after);
        assert!(filled.filled > 0 && !near.is_empty());
        assert!(
            filled
                .status_line(1.0)
                .contains(&format!("{} px from neighbouring beams", filled.filled)),
            "{}",
            filled.status_line(1.0)
        );
        assert!(!plain.status_line(1.0).contains("neighbouring"));
    }

    #[test]
    fn a_refusal_ends_the_session_with_the_servers_reason() {
        let mut s = session();
        let refused = encode(&Frame::Message(Message::Refused {
            reason: "wrong access token".into(),
            retry: false,
        }));
        assert_eq!(
            s.receive(&refused, 0.0),
            Err(SessionError::Refused("wrong access token".into()))
        );
        let bad = [255, 255, 255, 127, 0];
        assert!(matches!(session().receive(&bad, 0.0), Err(SessionError::Frame(_))));
    }

    #[test]
    fn a_reconnected_session_keeps_its_picture_until_welcomed_then_asks_for_everything() {
        let mut s = session();
        s.receive(&welcome(Access::Writer), 0.0).unwrap();
        let Frame::Message(Message::BeamRequest { beams, .. }) = frames(&s.take_output()).remove(0) else {
            panic!()
        };
        let key = beams[0].0;
        let mut data = encode(&Frame::Beam {
            key,
            records: records(key, 200),
        });
        data.extend(encode(&Frame::Message(Message::Delivered { beams: 1, rays: 200 })));
        s.receive(&data, 0.1).unwrap();
        let before = s.picture();
        s.reconnect();
        assert_eq!(s.picture(), before, "the picture stays while the server is away");
        assert!(!s.is_open());
        s.hello("t", false);
        s.receive(&welcome(Access::Writer), 5.0).unwrap();
        let out = frames(&s.take_output());
        assert!(matches!(
            &out[1],
            Frame::Message(Message::BeamRequest {
                resend: true,
                replace: true,
                ..
            })
        ));
        assert!(
            s.picture().pixels.iter().all(|p| *p == glam::Vec3::ZERO),
            "the old rays are dropped"
        );
        assert_eq!(s.view(), &navigate::fit_aspect(&view(), 64, 48), "the view is kept");
    }

    #[test]
    fn commands_answer_as_the_window_does_and_controls_go_to_the_server() {
        let mut s = session();
        s.receive(&welcome(Access::Viewer), 0.0).unwrap();
        s.take_output();
        let line = s.command(Command::Where, 0.0).unwrap().unwrap();
        assert_eq!(View::parse(&line).unwrap(), *s.view());
        assert_eq!(s.command(Command::Last, 0.0).unwrap().unwrap(), "last: no earlier view");
        s.command(Command::View("-vp 1 1 1".into()), 0.0).unwrap();
        assert_eq!(s.view().position, glam::DVec3::ONE);
        s.command(Command::Last, 0.0).unwrap();
        assert_eq!(s.view().position, glam::DVec3::splat(2.0));
        s.take_output();
        s.command(Command::Kill, 0.0).unwrap();
        let out = frames(&s.take_output());
        assert_eq!(out, vec![Frame::Message(Message::Control(Control::KillSamplers))]);
        let reply = encode(&Frame::Message(Message::ControlReply(
            holodeck_protocol::wire::ControlReply {
                control: Control::KillSamplers,
                outcome: ControlOutcome::Refused {
                    reason: "it needs admin access".into(),
                },
            },
        )));
        s.receive(&reply, 0.0).unwrap();
        assert_eq!(
            s.take_notices(),
            vec!["kill was refused: it needs admin access".to_string()]
        );
    }
}
