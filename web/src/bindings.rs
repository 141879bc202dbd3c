//! What the page's JavaScript calls: one [`WebDisplay`] per page, fed the
//! WebSocket's bytes and the page's input events, drawing RGBA frames for a
//! canvas.

use holodeck_display::command;
use holodeck_protocol::View;
use wasm_bindgen::prelude::*;

use crate::session::{Session, SessionError, SessionOptions};

#[wasm_bindgen]
extern "C" {
    /// The browser console's `console.error`.
    #[wasm_bindgen(js_namespace = console, js_name = error)]
    fn console_error(message: &str);
}

/// Run once when the module loads: a panic (a defect, never bad input) says
/// what and where on the browser's console before the page stops.
#[wasm_bindgen(start)]
fn start() {
    std::panic::set_hook(Box::new(|info| console_error(&format!("holodeck: {info}"))));
}

fn js(e: SessionError) -> JsError {
    JsError::new(&e.to_string())
}

/// A display in a web page.
#[wasm_bindgen]
pub struct WebDisplay {
    session: Session,
}

#[wasm_bindgen]
impl WebDisplay {
    /// A display of `width` x `height` pixels drawn by `driver` ("quadtree",
    /// "splat", or on WebGL2 "voronoi" or "mesh"), denoised by the à-trous filter when `denoise`, asking
    /// for `density` samples per pixel when a view settles and doubling it
    /// up to `max_density` while the view stays; it starts at `view`
    /// (Radiance view options; empty: the holodeck's default view).
    #[wasm_bindgen(constructor)]
    pub fn new(
        view: &str,
        width: u32,
        height: u32,
        driver: &str,
        denoise: bool,
        density: f64,
        max_density: f64,
    ) -> Result<WebDisplay, JsError> {
        let view = if view.trim().is_empty() {
            None
        } else {
            Some(
                View::default()
                    .with(view)
                    .map_err(|e| JsError::new(&format!("view: {e}")))?,
            )
        };
        let options = SessionOptions {
            driver: driver.to_string(),
            denoise,
            density,
            max_density,
            neighbours: false,
        };
        let session = Session::new(view, width, height, options).map_err(js)?;
        Ok(WebDisplay { session })
    }

    /// In a replayed site, fills the pixels a settled view's beams leave
    /// without a ray from the beams next to theirs (see `SessionOptions::neighbours`).
    pub fn set_neighbours(&mut self, on: bool) {
        self.session.set_neighbours(on);
    }

    /// Replays a static site's file (its `holodeck.idx`) instead of joining
    /// a server.
    pub fn open_site(&mut self, index: &[u8], now: f64) -> Result<(), JsError> {
        self.session.open_site(index, now).map_err(js)
    }

    /// The byte ranges to fetch now, three numbers each: chunk, first byte,
    /// past the last byte. Their bytes go to `add_fetched` in this order.
    pub fn take_fetches(&mut self) -> Vec<f64> {
        self.session
            .take_fetches()
            .into_iter()
            .flat_map(|(c, a, b)| [f64::from(c), a as f64, b as f64])
            .collect()
    }

    /// The bytes of the oldest range taken (`failed`: it could not be
    /// fetched; its beams are asked for again at the next settle).
    pub fn add_fetched(&mut self, chunk: u32, start: f64, bytes: &[u8], failed: bool, now: f64) -> Result<(), JsError> {
        let bytes = (!failed).then_some(bytes);
        self.session.add_fetched(chunk, start as u64, bytes, now).map_err(js)
    }

    /// Greets the server (after every connect) with the access token.
    pub fn hello(&mut self, token: &str, read_only: bool) {
        self.session.hello(token, read_only);
    }

    /// The connection was lost; the picture stays until the next Welcome.
    pub fn reconnect(&mut self) {
        self.session.reconnect();
    }

    /// Bytes to send to the server (empty: nothing).
    pub fn take_output(&mut self) -> Vec<u8> {
        self.session.take_output()
    }

    /// Bytes from the server, at `now` seconds.
    pub fn receive(&mut self, bytes: &[u8], now: f64) -> Result<(), JsError> {
        self.session.receive(bytes, now).map_err(js)
    }

    /// Once a frame: motion steps and the still view's refinement.
    pub fn tick(&mut self, now: f64) -> Result<(), JsError> {
        self.session.tick(now).map_err(js)
    }

    /// A button (0 left, 1 middle, 2 right) went down at pixel (x, y).
    pub fn press(&mut self, button: u32, shift: bool, x: f64, y: f64) {
        self.session.press(button, shift, x, y);
    }

    /// The pointer moved.
    pub fn pointer(&mut self, x: f64, y: f64) {
        self.session.pointer(x, y);
    }

    /// The button went up: the view settles. Returns the steps taken.
    pub fn release(&mut self, button: u32, now: f64) -> u32 {
        self.session.release(button, now)
    }

    /// A key (`KeyboardEvent.key`) as the window's letters; returns what to
    /// tell the user, if anything ("" for nothing).
    pub fn key(&mut self, key: &str, ctrl: bool, now: f64) -> Result<String, JsError> {
        match command::key(key, ctrl) {
            Some(c) => Ok(self.session.command(c, now).map_err(js)?.unwrap_or_default()),
            None => Ok(String::new()),
        }
    }

    /// A typed command line (a view line, `last`, `where`, `pause`, ...);
    /// returns what to tell the user ("" for nothing).
    pub fn line(&mut self, line: &str, now: f64) -> Result<String, JsError> {
        match command::parse(line) {
            Ok(Some(c)) => Ok(self.session.command(c, now).map_err(js)?.unwrap_or_default()),
            Ok(None) => Ok(String::new()),
            Err(e) => Ok(e.to_string()),
        }
    }

    /// The current view as a Radiance view line.
    pub fn view_line(&self) -> String {
        format!("VIEW= {}", self.session.view().to_spec())
    }

    /// Changes the frame size.
    pub fn resize(&mut self, width: u32, height: u32, now: f64) -> Result<(), JsError> {
        self.session.resize(width, height, now).map_err(js)
    }

    /// Frame width in pixels.
    pub fn width(&self) -> u32 {
        self.session.viewport().width
    }

    /// Frame height in pixels.
    pub fn height(&self) -> u32 {
        self.session.viewport().height
    }

    /// The frame, tone mapped, as RGBA bytes for `ImageData`.
    pub fn frame(&mut self) -> Vec<u8> {
        self.session.frame_rgba()
    }

    /// The frame in linear radiance: RGB floats, top row first.
    pub fn picture(&mut self) -> Vec<f32> {
        self.session
            .picture()
            .pixels
            .iter()
            .flat_map(|p| p.to_array())
            .collect()
    }

    /// Draws `n` frames afresh; the mean milliseconds of one (benchmarks).
    pub fn bench_render(&mut self, n: u32) -> f64 {
        self.session.bench_render(n)
    }

    /// The status line (`frame_ms`: the last frame's time).
    pub fn status(&self, frame_ms: f64) -> String {
        self.session.status_line(frame_ms)
    }

    /// What the server and the display said since the last call, one per line.
    pub fn notices(&mut self) -> String {
        self.session.take_notices().join("\n")
    }

    /// Whether the server welcomed this display.
    pub fn is_open(&self) -> bool {
        self.session.is_open()
    }

    /// Immediate transfers not yet complete (0: every stored ray of the view is in).
    pub fn transfers(&self) -> u32 {
        self.session.transfers()
    }

    /// The driver drawing, and where: "mesh on WebGL2 (ANGLE ...)" or
    /// "quadtree on the CPU".
    pub fn driver(&self) -> String {
        let name = self.session.driver_name();
        if holodeck_display::GPU_DRIVERS.contains(&name) {
            match holodeck_display::gpu::GpuContext::shared() {
                Ok(gpu) => format!("{name} on {}", gpu.describe()),
                Err(e) => format!("{name} ({e})"),
            }
        } else {
            format!("{name} on the CPU")
        }
    }

    /// A GPU driver's frame is still on the GPU: draw again at the next
    /// animation frame (the last frame stands in meanwhile).
    pub fn frame_pending(&self) -> bool {
        self.session.frame_pending()
    }

    /// Samples received in all.
    pub fn samples(&self) -> f64 {
        self.session.samples() as f64
    }
}
