//! The control messages (everything but ray payloads).

use serde::{Deserialize, Serialize};

use crate::beam::BeamKey;
use crate::section::SectionSpec;

/// What a peer is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Role {
    /// Traces packets.
    Sampler,
    /// Requests beams and shows them.
    Display,
    /// Sends control commands only.
    Admin,
}

/// The first message of every connection, from the peer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Hello {
    /// [`super::PROTOCOL_VERSION`] of the peer.
    pub version: u32,
    /// What the peer is.
    pub role: Role,
    /// Content hash of the scene the peer has (samplers) or expects.
    pub scene: String,
    /// The server's access token.
    pub token: String,
    /// A display that may not clobber, kill or quit.
    pub read_only: bool,
}

/// How a sampler chooses the rays of a packet.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum SamplingMode {
    /// Four random sub-cell bytes per ray (batch filling).
    Uniform,
    /// Rays passing near an eye point (interactive views; paper's Appendix A).
    NearEye {
        /// Eye position, world units.
        eye: [f64; 3],
        /// How near, world units.
        radius: f64,
    },
}

/// Work for a sampler: trace `rays` rays of one beam.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TracePacket {
    /// Identifies the packet in its answer.
    pub id: u64,
    /// The beam.
    pub key: BeamKey,
    /// Rays wanted.
    pub rays: u32,
    /// How to choose them.
    pub mode: SamplingMode,
}

/// Commands an admin (or a writable display) may send.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Control {
    /// Stop handing out packets.
    Pause,
    /// Hand out packets again.
    Resume,
    /// Disconnect every sampler.
    KillSamplers,
    /// Drop all requests and start scheduling afresh.
    Restart,
    /// Delete every ray in the file.
    Clobber,
    /// Flush and stop the server.
    Quit,
}

/// The server's periodic report.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Progress {
    /// Rays stored in the file.
    pub rays: u64,
    /// Rays stored per second lately.
    pub rays_per_second: f64,
    /// File size in bytes.
    pub file_bytes: u64,
    /// Beams holding rays.
    pub beams_filled: u64,
    /// All beams.
    pub beams: u64,
}

/// Every message except ray payloads.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Message {
    /// Peer's greeting.
    Hello(Hello),
    /// The server accepts: here are the holodeck's sections.
    Welcome {
        /// The sections, in index order.
        sections: Vec<SectionSpec>,
        /// Sections may contain geometry: trace from the entry wall.
        obstructions: bool,
    },
    /// The server refuses the peer, and says why.
    Refused {
        /// Why.
        reason: String,
    },
    /// A display's beams with the sample counts it wants.
    BeamRequest {
        /// (beam, desired rays).
        beams: Vec<(BeamKey, u32)>,
    },
    /// Work for a sampler.
    Trace(TracePacket),
    /// A report.
    Progress(Progress),
    /// A command.
    Control(Control),
    /// Something went wrong with the last message.
    Error {
        /// What.
        message: String,
    },
}

impl Message {
    /// Checks what decoding alone cannot: finite numbers and valid sections.
    /// Returns what is wrong.
    pub fn validate(&self) -> Result<(), String> {
        let finite = |what: &str, v: f64| {
            if v.is_finite() {
                Ok(())
            } else {
                Err(format!("{what} is {v}"))
            }
        };
        match self {
            Message::Welcome { sections, .. } => {
                for (i, s) in sections.iter().enumerate() {
                    crate::section::Section::try_from(s.clone()).map_err(|e| format!("section {i}: {e}"))?;
                }
                Ok(())
            }
            Message::Trace(TracePacket {
                mode: SamplingMode::NearEye { eye, radius },
                ..
            }) => {
                for v in eye {
                    finite("eye coordinate", *v)?;
                }
                finite("radius", *radius)?;
                if *radius < 0.0 {
                    return Err(format!("radius {radius} is negative"));
                }
                Ok(())
            }
            Message::Progress(p) => finite("rays per second", p.rays_per_second),
            _ => Ok(()),
        }
    }
}
