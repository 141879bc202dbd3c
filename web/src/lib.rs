//! The holodeck's web display: the display's sample store, its CPU drivers
//! (quadtree, splat), its GPU drivers (voronoi, mesh: on WebGL2, falling
//! back to the quadtree where the browser has none) and its à-trous
//! denoiser, compiled to WebAssembly for a page that speaks the display
//! protocol over a WebSocket.
//!
//! * [`session`] — a display session driven by the page's events (bytes in,
//!   bytes out, the time passed in), testable natively.
//! * [`fetch`] — a replayed site's beams as byte ranges of its chunk files.
//! * `bindings` — what the page's JavaScript calls (wasm32 only).
//!
//! `holodeck serve --web` serves the page with this crate built for
//! `wasm32-unknown-unknown` (the `holodeck` binary embeds it), and
//! `holodeck export web` writes it into a static site that replays a file
//! with no server.

#[cfg(target_arch = "wasm32")]
mod bindings;
pub mod fetch;
pub mod session;

pub use session::{Session, SessionError, SessionOptions};
