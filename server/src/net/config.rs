//! How a server runs: what its operator chose on the command line, fixed for
//! the server's life. Plain data; nothing here touches a socket or the file.

use std::time::Duration;

use holodeck_protocol::BeamKey;

/// What a batch fill covers when no display wants anything.
#[derive(Clone, Debug, PartialEq)]
pub enum Fill {
    /// Every beam, by volume.
    All,
    /// Only beams some views see, weighted by the view rays in each.
    Views(Vec<(BeamKey, u32)>),
    /// Nothing: samplers trace only what displays request.
    Off,
}

/// How the server runs.
#[derive(Clone, Debug)]
pub struct ServerConfig {
    /// The token every peer must present.
    pub token: String,
    /// Rays per batch-fill packet (one beam each).
    pub packet: u32,
    /// Most rays in a packet for a display's request.
    pub request_packet: u32,
    /// Rays queued to a sampler before its speed is known.
    pub initial_queue: u32,
    /// Each sampler's queue is sized to drain within this long.
    pub latency: Duration,
    /// The batch fill.
    pub fill: Fill,
    /// Stop (flushing) after this long (the TIME setting).
    pub time: Option<Duration>,
    /// Print a progress line this often (the REPORT setting).
    pub report: Option<Duration>,
    /// Stop once the file refuses rays (DISKSPACE reached, or a write failed) and no display is connected.
    pub stop_when_full: bool,
    /// A sampler that returns nothing for this long while it holds work is
    /// dropped and its work given back.
    pub stall: Duration,
}

impl ServerConfig {
    /// Defaults for a server with this token.
    pub fn new(token: String) -> ServerConfig {
        ServerConfig {
            token,
            packet: 4,
            request_packet: 32,
            initial_queue: 256,
            latency: Duration::from_millis(250),
            fill: Fill::All,
            time: None,
            report: None,
            stop_when_full: true,
            stall: Duration::from_secs(30),
        }
    }
}
