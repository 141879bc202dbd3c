//! The window's event loop: mouse and keys (and, with a script, lines on
//! standard input) become motion steps and commands of a [`Walkthrough`];
//! each frame is drawn by its driver, tone mapped, overlaid and presented.
//!
//! Motion runs one step per frame while a button is held, at most
//! [`STEP_RATE`] steps a second so that a fast machine does not fly; samples
//! are asked for when the button is released. While the view is still, new
//! samples are taken in short polls between events, and a frame is drawn
//! when some came.

use std::io::{BufRead, Write};
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use holodeck_protocol::wire::Control;
use holodeck_protocol::View;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::ModifiersState;
use winit::window::{Window, WindowId};

use super::command::{self, Command};
use super::navigate::{self, ImagePoint};
use super::overlay::{self, Canvas};
use super::present::Presenter;
use super::walk::Walkthrough;
use super::WindowError;
use crate::motion;

pub use crate::navigate::STEP_RATE;

/// How long one poll for new samples may hold the event loop.
const POLL: Duration = Duration::from_millis(15);

/// How long the server's answer to a command stays on the status line.
const NOTICE: Duration = Duration::from_secs(4);

/// Frames of a still view are drawn at most this often.
const STILL_FRAME: Duration = Duration::from_millis(100);

/// How the window runs.
#[derive(Clone, Debug, Default)]
pub struct WindowOptions {
    /// Read commands from standard input, one per line, and print what
    /// scripts need (views, motion summaries, answers) on standard output.
    pub script: bool,
    /// Extra words for the title.
    pub title: String,
}

/// Events from other threads.
#[derive(Debug)]
enum UserEvent {
    /// A line of standard input.
    Line(String),
    /// Standard input ended.
    End,
}

/// A motion in progress: its steps (the rule the web page shares), and
/// what the window reports of it.
#[derive(Debug)]
struct Held {
    step: motion::Held,
    button: MouseButton,
    pressed: Instant,
    /// From the press to the first frame that showed a step.
    first_shown: Option<Duration>,
    /// Times of the frames drawn during the motion.
    frames: Vec<Duration>,
}

struct App {
    walk: Walkthrough,
    options: WindowOptions,
    window: Option<Arc<Window>>,
    presenter: Option<Presenter>,
    cursor: (f64, f64),
    mods: ModifiersState,
    held: Option<Held>,
    /// A focus rectangle being dragged (start, now), in pixels.
    dragging: Option<((f64, f64), (f64, f64))>,
    /// The focus rectangle, in image coordinates.
    focus: Option<(ImagePoint, ImagePoint)>,
    /// Samples came in or the view changed since the last frame.
    dirty: bool,
    last_frame: Instant,
    /// When the window opened: the origin of [`App::clock`].
    opened: Instant,
    frame_time: Duration,
    /// The server's last answer, and when it came.
    notice: Option<(String, Instant)>,
    /// When the last motion stopped, until the next frame is drawn.
    settled_at: Option<(Instant, u64)>,
    error: Option<WindowError>,
}

/// Opens the window and runs the walkthrough until the user quits (or the
/// script says `quit`); the walkthrough is settled at its first view first.
pub fn run(walk: Walkthrough, options: WindowOptions) -> Result<(), WindowError> {
    let event_loop = EventLoop::<UserEvent>::with_user_event()
        .build()
        .map_err(|e| WindowError::Open(e.to_string()))?;
    if options.script {
        let proxy = event_loop.create_proxy();
        std::thread::spawn(move || {
            for line in std::io::stdin().lock().lines() {
                let Ok(line) = line else { break };
                if proxy.send_event(UserEvent::Line(line)).is_err() {
                    return;
                }
            }
            let _ = proxy.send_event(UserEvent::End);
        });
    }
    let mut app = App {
        walk,
        options,
        window: None,
        presenter: None,
        cursor: (0.0, 0.0),
        mods: ModifiersState::empty(),
        held: None,
        dragging: None,
        focus: None,
        dirty: true,
        last_frame: Instant::now(),
        opened: Instant::now(),
        frame_time: Duration::ZERO,
        settled_at: None,
        notice: None,
        error: None,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| WindowError::Open(e.to_string()))?;
    app.error.map_or(Ok(()), Err)
}

/// Prints a line for scripts (standard output may be gone: no matter).
fn say(line: &str) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{line}");
    let _ = out.flush();
}

impl App {
    fn fail(&mut self, event_loop: &ActiveEventLoop, e: impl Into<WindowError>) {
        self.error.get_or_insert(e.into());
        event_loop.exit();
    }

    fn size(&self) -> (u32, u32) {
        let vp = self.walk.viewport();
        (vp.width, vp.height)
    }

    fn image_point(&self, at: (f64, f64)) -> ImagePoint {
        let (w, h) = self.size();
        ImagePoint::of_pixel(at.0.floor(), at.1.floor(), w, h)
    }

    /// Runs one command; answers go to standard output in script mode and
    /// to the log otherwise.
    fn execute(&mut self, event_loop: &ActiveEventLoop, c: Command) -> Result<(), WindowError> {
        let tell = |script: bool, line: String| {
            if script {
                say(&line);
            } else {
                tracing::info!("{line}");
            }
        };
        let script = self.options.script;
        let control = |app: &mut App, name: &str, c: Control| -> Result<(), WindowError> {
            // The server's answer comes later, among its notices.
            if let Err(e) = app.walk.control(c) {
                tell(script, format!("{name}: {e}"));
            }
            Ok(())
        };
        match c {
            Command::View(spec) => match self.walk.view().clone().with(&spec) {
                Ok(v) => {
                    let v = navigate::fit_aspect(&v, self.size().0, self.size().1);
                    self.walk.jump(v)?;
                }
                Err(e) => tell(script, format!("view: {e}")),
            },
            Command::Last => {
                if self.walk.last()?.is_none() {
                    tell(script, "last: no earlier view".into());
                }
            }
            Command::Where => say(&view_line(self.walk.view())),
            Command::Frame(rect) => {
                let rect = rect
                    .map(|r| (ImagePoint { x: r[0], y: r[1] }, ImagePoint { x: r[2], y: r[3] }))
                    .or(self.focus);
                let (w, h) = self.size();
                let framed = match rect {
                    Some((a, b)) => navigate::frame(self.walk.view(), a, b, f64::from(w) / f64::from(h)),
                    None => navigate::turn_toward(self.walk.view(), self.image_point(self.cursor)),
                };
                match framed {
                    Some(v) => {
                        self.focus = None;
                        self.walk.jump(v)?;
                    }
                    None => tell(script, "frame: no valid view frames that".into()),
                }
            }
            Command::Pause => control(self, "pause", Control::Pause)?,
            Command::Resume => control(self, "resume", Control::Resume)?,
            Command::Kill => control(self, "kill", Control::KillSamplers)?,
            Command::Restart => control(self, "restart", Control::Restart)?,
            Command::Clobber => control(self, "clobber", Control::Clobber)?,
            Command::Redraw => {}
            Command::Refresh => {
                self.walk.refresh()?;
            }
            Command::Quit => event_loop.exit(),
            Command::HeadFixed(on) => self.walk.head_fixed = on,
            Command::Tone => self.walk.retone()?,
            Command::Save(path) => {
                let (frame, _) = self.walk.frame()?;
                save(&path, &frame)?;
                tell(script, format!("saved {}", path.display()));
            }
            Command::Bench(n) => {
                let mut times = Vec::with_capacity(n as usize);
                for _ in 0..n {
                    let start = Instant::now();
                    self.draw()?;
                    times.push(start.elapsed().as_secs_f64() * 1e3);
                }
                let mean = times.iter().sum::<f64>() / f64::from(n);
                let (min, max) = times.iter().fold((f64::MAX, 0.0f64), |(a, b), &t| (a.min(t), b.max(t)));
                say(&format!(
                    "frames: {n} drawn, {mean:.1} ms mean ({:.1} frames/s), {min:.1} to {max:.1} ms",
                    1e3 / mean.max(1e-9)
                ));
            }
            Command::Sync => {
                // What a script does next (a screenshot, say) sees every
                // earlier command on screen.
                self.draw()?;
                say("sync");
            }
        }
        self.dirty = true;
        self.redraw();
        Ok(())
    }

    fn redraw(&self) {
        if let Some(w) = &self.window {
            w.request_redraw();
        }
    }

    /// Seconds since the window opened: the clock of the motion steps.
    fn clock(&self) -> f64 {
        self.opened.elapsed().as_secs_f64()
    }

    /// One motion step, if one is due.
    fn step(&mut self) -> Result<(), WindowError> {
        let (w, h) = self.size();
        let (now, head) = (self.clock(), self.walk.head_fixed);
        let view = self.walk.view().clone();
        let walk = &self.walk;
        let Some(held) = &mut self.held else { return Ok(()) };
        held.step.cursor = self.cursor;
        if let Some(v) = held.step.next(&view, now, w, h, head, &|c, r| walk.point_at(c, r)) {
            self.walk.move_to(v)?;
            self.dirty = true;
        }
        Ok(())
    }

    fn press(&mut self, button: MouseButton) {
        let shift = self.mods.shift_key();
        if shift && self.mods.control_key() {
            if button == MouseButton::Left {
                self.dragging = Some((self.cursor, self.cursor));
            }
            return;
        }
        let number = match button {
            MouseButton::Left => 0,
            MouseButton::Middle => 1,
            MouseButton::Right => 2,
            _ => return,
        };
        let Some(motion) = motion::Motion::of_button(number, shift) else {
            return;
        };
        self.held = Some(Held {
            step: motion::Held::new(motion, self.cursor),
            button,
            pressed: Instant::now(),
            first_shown: None,
            frames: Vec::new(),
        });
        self.redraw();
    }

    fn release(&mut self, button: MouseButton) -> Result<(), WindowError> {
        if let Some((a, b)) = self.dragging.take() {
            if button == MouseButton::Left {
                let (pa, pb) = (self.image_point(a), self.image_point(b));
                self.focus = (pa.x != pb.x && pa.y != pb.y).then_some((pa, pb));
                self.dirty = true;
                self.redraw();
            }
            return Ok(());
        }
        if self.held.as_ref().is_some_and(|h| h.button == button) {
            if let Some(held) = self.held.take() {
                if self.options.script {
                    match held.step.target() {
                        Some(p) => say(&format!(
                            "moved: {} steps about {} {} {}",
                            held.step.steps, p.x, p.y, p.z
                        )),
                        None => say(&format!("moved: {} steps", held.step.steps)),
                    }
                }
                let frames = held.frames.len().max(1) as f64;
                let per_frame = held.frames.iter().sum::<Duration>().as_secs_f64() / frames;
                let report = format!(
                    "motion: {} frames, {:.1} ms per frame ({:.1} frames/s), first step on screen {:.0} ms after the press",
                    held.frames.len(),
                    per_frame * 1e3,
                    1.0 / per_frame.max(1e-9),
                    held.first_shown.unwrap_or_default().as_secs_f64() * 1e3
                );
                if self.options.script {
                    say(&report);
                } else {
                    tracing::debug!("{report}");
                }
                let start = Instant::now();
                let n = self.walk.settle()?;
                self.settled_at = Some((start, n));
                self.dirty = true;
                self.redraw();
            }
        }
        Ok(())
    }

    fn draw(&mut self) -> Result<(), WindowError> {
        // New samples are taken between events (`about_to_wait`), not here.
        let start = Instant::now();
        let (frame, _) = self.walk.frame()?;
        let (w, h) = (frame.width, frame.height);
        let mut rgba = Vec::with_capacity(frame.rgb.len() / 3 * 4);
        for px in frame.rgb.chunks_exact(3) {
            rgba.extend_from_slice(&[px[0], px[1], px[2], 255]);
        }
        let mut canvas = Canvas {
            rgba: &mut rgba,
            width: w,
            height: h,
        };
        if self.held.is_some() {
            canvas.grids(self.walk.view(), self.walk.sections());
        }
        let corner = |p: ImagePoint| [p.x * f64::from(w), (1.0 - p.y) * f64::from(h)];
        if let Some((a, b)) = self.dragging {
            canvas.rect([a.0, a.1], [b.0, b.1], overlay::FOCUS);
        } else if let Some((a, b)) = self.focus {
            canvas.rect(corner(a), corner(b), overlay::FOCUS);
        }
        canvas.status(&self.status_line());
        if let Some(p) = &mut self.presenter {
            p.present(&rgba, w, h)?;
        }
        self.frame_time = start.elapsed();
        self.last_frame = Instant::now();
        self.dirty = false;
        if let Some(held) = &mut self.held {
            held.frames.push(self.frame_time);
            if held.step.steps > 0 && held.first_shown.is_none() {
                held.first_shown = Some(held.pressed.elapsed());
            }
        } else if let Some((at, n)) = self.settled_at.take() {
            let report = format!(
                "refined: first frame {:.0} ms after the motion stopped, with {n} samples sent at once",
                at.elapsed().as_secs_f64() * 1e3
            );
            if self.options.script {
                say(&report);
            } else {
                tracing::debug!("{report}");
            }
        }
        Ok(())
    }

    /// Passes on what the server answered: printed for scripts, logged,
    /// and shown on the status line for a while.
    fn take_notices(&mut self) {
        for n in self.walk.notices() {
            if self.options.script {
                say(&n);
            } else {
                tracing::info!("server: {n}");
            }
            self.notice = Some((n, Instant::now()));
            self.dirty = true;
        }
    }

    fn status_line(&mut self) -> String {
        self.take_notices();
        if let Some((n, at)) = &self.notice {
            if at.elapsed() < NOTICE {
                return n.clone();
            }
        }
        let (received, rate) = self.walk.received();
        crate::status::Status {
            rate,
            received,
            shown: self.walk.driver().stats().kept,
            frame_ms: self.frame_time.as_secs_f64() * 1e3,
            server: self.walk.server(),
            head_fixed: self.walk.head_fixed,
            filled: self.walk.filled(),
        }
        .line()
    }
}

/// 1234567 as "1.2M".
/// Writes a frame as a PNG.
fn save(path: &Path, frame: &super::walk::Frame) -> Result<(), WindowError> {
    crate::image_io::write_rgb8(path, frame.width as usize, frame.height as usize, &frame.rgb)?;
    Ok(())
}

impl ApplicationHandler<UserEvent> for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_some() {
            return;
        }
        let (w, h) = self.size();
        let title = format!("holodeck: {} {}", self.walk.source_name(), self.options.title);
        let attributes = Window::default_attributes()
            .with_title(title.trim_end())
            .with_inner_size(PhysicalSize::new(w, h));
        let window = match event_loop.create_window(attributes) {
            Ok(w) => Arc::new(w),
            Err(e) => return self.fail(event_loop, WindowError::Open(e.to_string())),
        };
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_with_display_handle_from_env(Box::new(
            event_loop.owned_display_handle(),
        )));
        match Presenter::new(&instance, Arc::clone(&window)) {
            Ok(p) => {
                tracing::info!("window drawn with {}", p.adapter);
                self.presenter = Some(p);
            }
            Err(e) => return self.fail(event_loop, e),
        }
        self.window = Some(window);
        if let Err(e) = self.walk.settle() {
            return self.fail(event_loop, e);
        }
        if self.options.script {
            say(&format!("ready: {w} x {h}"));
        }
        self.redraw();
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        let result = match event {
            WindowEvent::CloseRequested => {
                event_loop.exit();
                Ok(())
            }
            WindowEvent::Resized(size) => {
                if size.width > 0 && size.height > 0 && (size.width, size.height) != self.size() {
                    if let Some(p) = &mut self.presenter {
                        p.resize(size.width, size.height);
                    }
                    let r = self.walk.resize(size.width, size.height).map_err(WindowError::from);
                    self.dirty = true;
                    self.redraw();
                    r
                } else {
                    if let Some(p) = &mut self.presenter {
                        p.resize(size.width, size.height);
                    }
                    Ok(())
                }
            }
            // A release that happens elsewhere never comes: the motion ends here.
            WindowEvent::Focused(false) => match self.held.as_ref().map(|h| h.button) {
                Some(button) => self.release(button),
                None => Ok(()),
            },
            WindowEvent::ModifiersChanged(m) => {
                self.mods = m.state();
                Ok(())
            }
            WindowEvent::CursorMoved { position, .. } => {
                self.cursor = (position.x, position.y);
                if let Some((a, _)) = self.dragging {
                    self.dragging = Some((a, self.cursor));
                    self.redraw();
                }
                Ok(())
            }
            WindowEvent::MouseInput { state, button, .. } => match state {
                ElementState::Pressed => {
                    self.press(button);
                    Ok(())
                }
                ElementState::Released => self.release(button),
            },
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                match command::key(&event.logical_key, self.mods) {
                    Some(c) => self.execute(event_loop, c),
                    None => Ok(()),
                }
            }
            WindowEvent::RedrawRequested => self.step().and_then(|()| self.draw()),
            _ => Ok(()),
        };
        if let Err(e) = result {
            self.fail(event_loop, e);
        }
    }

    fn user_event(&mut self, event_loop: &ActiveEventLoop, event: UserEvent) {
        match event {
            UserEvent::Line(line) => match command::parse(&line) {
                Ok(Some(c)) => {
                    if let Err(e) = self.execute(event_loop, c) {
                        self.fail(event_loop, e);
                    }
                }
                Ok(None) => {}
                Err(e) => say(&format!("error: {e}")),
            },
            UserEvent::End => tracing::debug!("standard input ended"),
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        if let Some(held) = &self.held {
            // A frame per motion step while the button is held.
            let next = held
                .step
                .next_step_at()
                .map_or_else(Instant::now, |t| self.opened + Duration::from_secs_f64(t));
            if Instant::now() >= next {
                self.redraw();
                event_loop.set_control_flow(ControlFlow::Poll);
            } else {
                event_loop.set_control_flow(ControlFlow::WaitUntil(next));
            }
            return;
        }
        match self.walk.poll(Instant::now() + POLL) {
            Ok(n) => self.dirty |= n > 0,
            Err(e) => return self.fail(event_loop, e),
        }
        self.take_notices();
        if self.notice.as_ref().is_some_and(|(_, at)| at.elapsed() >= NOTICE) {
            // Back to the figures.
            self.notice = None;
            self.dirty = true;
        }
        if self.dirty && self.last_frame.elapsed() >= STILL_FRAME {
            self.redraw();
        }
        event_loop.set_control_flow(ControlFlow::WaitUntil(Instant::now() + POLL));
    }
}

/// A view's line for the log: what `where` prints.
pub fn view_line(v: &View) -> String {
    format!("VIEW= {}", v.to_spec())
}
