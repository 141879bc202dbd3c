//! The control messages (everything but ray payloads).

use serde::{Deserialize, Serialize};

use crate::beam::BeamKey;
use crate::section::{Section, SectionError, SectionSpec};
use crate::view::Frustum;

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
        /// The directions the eye's frame shows, if known: rays are chosen
        /// in it, so that they land where the display looks.
        frustum: Option<Frustum>,
    },
}

/// A display's eye, for proximity sampling.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct EyePoint {
    /// Eye position, world units.
    pub position: [f64; 3],
    /// How near new rays should pass, world units (0: uniform sampling).
    pub radius: f64,
    /// The directions the display's frame shows, if bounded by four planes.
    pub frustum: Option<Frustum>,
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
    /// A display's beams with the sample counts it wants. The server sends the
    /// rays it has at once, then new rays of these beams as they are traced.
    BeamRequest {
        /// (beam, desired rays in total).
        beams: Vec<(BeamKey, u32)>,
        /// Where the display's eye is: new rays are traced near it (Appendix A).
        eye: Option<EyePoint>,
        /// True: these beams replace the display's earlier requests (a new
        /// view); false: they are added to them (or raise their counts).
        replace: bool,
        /// True: send every stored ray of these beams, also those sent to this
        /// display before (it forgot them); false: only rays it was not sent
        /// yet (it keeps what it was sent, reprojected into the new view).
        resend: bool,
    },
    /// The server has sent every stored ray of a display's last request (the
    /// end of the paper's "immediate transfer").
    Delivered {
        /// Beams sent.
        beams: u32,
        /// Rays sent.
        rays: u64,
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

/// Why a decoded message cannot be used: what decoding alone does not check.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MessageError {
    /// A section of a `Welcome` is invalid.
    #[error("section {index}: {error}")]
    Section {
        /// Its index in the message.
        index: usize,
        /// Why (part of this message, not a separate cause).
        error: SectionError,
    },
    /// A number that must be finite is NaN or infinite.
    #[error("{what} is {value}")]
    NonFinite {
        /// Which number.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// A radius that must not be negative is.
    #[error("{what} {value} is negative")]
    Negative {
        /// Which number.
        what: &'static str,
        /// Its value.
        value: f64,
    },
    /// A frustum with a NaN or infinite plane.
    #[error("the frustum is not finite")]
    Frustum,
}

impl Message {
    /// Checks what decoding alone cannot: finite numbers and valid sections.
    pub fn validate(&self) -> Result<(), MessageError> {
        let finite = |what: &'static str, value: f64| {
            if value.is_finite() {
                Ok(())
            } else {
                Err(MessageError::NonFinite { what, value })
            }
        };
        let eye = |position: &[f64; 3], radius: f64, frustum: &Option<Frustum>, what: &'static str| {
            for v in position {
                finite("eye coordinate", *v)?;
            }
            if frustum.is_some_and(|f| !f.is_finite()) {
                return Err(MessageError::Frustum);
            }
            finite(what, radius)?;
            if radius < 0.0 {
                return Err(MessageError::Negative { what, value: radius });
            }
            Ok(())
        };
        match self {
            Message::Welcome { sections, .. } => {
                for (index, s) in sections.iter().enumerate() {
                    Section::try_from(s.clone()).map_err(|error| MessageError::Section { index, error })?;
                }
                Ok(())
            }
            Message::Trace(TracePacket {
                mode:
                    SamplingMode::NearEye {
                        eye: e,
                        radius,
                        frustum,
                    },
                ..
            }) => eye(e, *radius, frustum, "radius"),
            Message::Progress(p) => finite("rays per second", p.rays_per_second),
            Message::BeamRequest { eye: Some(e), .. } => eye(&e.position, e.radius, &e.frustum, "eye radius"),
            _ => Ok(()),
        }
    }
}
