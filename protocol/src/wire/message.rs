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

/// What a connection may do, from the token it presented: the server issues
/// one token per level. Ordered: each level may do all the one below may.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum Access {
    /// Reads beams; sends no control command.
    Viewer,
    /// Also traces (samplers), and pauses and resumes the fill.
    Writer,
    /// Also kills and restarts samplers, clobbers, adopts a new scene, quits.
    Admin,
}

impl Access {
    /// The level in words, as messages name it.
    pub fn name(self) -> &'static str {
        match self {
            Access::Viewer => "viewer",
            Access::Writer => "writer",
            Access::Admin => "admin",
        }
    }
}

impl std::fmt::Display for Access {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
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
    /// One of the server's access tokens: it decides the [`Access`].
    pub token: String,
    /// Asks for viewer access whatever the token allows (a display that
    /// promises to change nothing). It can only lower the access, never raise it.
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

/// Commands to the server, each allowed from [`Control::needs`] up.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
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
    /// The scene was edited (paper 2.4.1): disconnect the samplers of the old
    /// scene, delete its rays (or keep them, marked stale, with `keep`),
    /// record the new scene's hash in the file durably, and let samplers of
    /// the new scene in (a restart).
    Adopt {
        /// Content hash of the new scene, as its samplers prove it.
        scene: String,
        /// Keep the old scene's rays (the file then says they are stale).
        keep: bool,
    },
}

impl Control {
    /// The access a connection needs to send this command.
    pub fn needs(&self) -> Access {
        match self {
            Control::Pause | Control::Resume => Access::Writer,
            Control::KillSamplers | Control::Restart | Control::Clobber | Control::Quit | Control::Adopt { .. } => {
                Access::Admin
            }
        }
    }
}

/// How the server answered a control command.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ControlOutcome {
    /// Carried out.
    Done,
    /// Not allowed for this connection; the reason names the command and the
    /// access held.
    Refused {
        /// Why.
        reason: String,
    },
    /// Allowed, but it failed (the file could not be written, say).
    Failed {
        /// What went wrong.
        error: String,
    },
}

impl std::fmt::Display for ControlOutcome {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ControlOutcome::Done => f.write_str("was carried out"),
            ControlOutcome::Refused { reason } => write!(f, "was refused: {reason}"),
            ControlOutcome::Failed { error } => write!(f, "failed: {error}"),
        }
    }
}

/// The server's answer to one control command.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ControlReply {
    /// The command answered.
    pub control: Control,
    /// What became of it.
    pub outcome: ControlOutcome,
}

/// The server's report, sent to every display about once a second (and
/// once at once when it connects).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Progress {
    /// Rays stored in the file.
    pub rays: u64,
    /// Rays stored per second over the last five seconds.
    pub rays_per_second: f64,
    /// File size in bytes.
    pub file_bytes: u64,
    /// Beams holding rays.
    pub beams_filled: u64,
    /// All beams.
    pub beams: u64,
    /// Samplers connected.
    pub samplers: u32,
    /// Displays connected (admin connections not counted).
    pub displays: u32,
    /// True while an admin or writer has paused the fill.
    pub paused: bool,
}

/// Every message except ray payloads.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Message {
    /// Peer's greeting.
    Hello(Hello),
    /// The server accepts: here are the holodeck's sections, and the file's
    /// settings samplers must obey.
    Welcome {
        /// The sections, in index order.
        sections: Vec<SectionSpec>,
        /// Sections may contain geometry: trace from the entry wall.
        obstructions: bool,
        /// Record virtual distances through flat mirrors and thin glass (VDISTANCE).
        vdistance: bool,
        /// What this connection may do.
        access: Access,
    },
    /// The server refuses the peer, and says why; also sent to samplers as
    /// an admin disconnects them.
    Refused {
        /// Why.
        reason: String,
        /// Trying again later makes sense: samplers are stopped by an admin
        /// for now, and a restart (or adopting a new scene) lets them in.
        retry: bool,
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
    /// The answer to a command, sent for every one.
    ControlReply(ControlReply),
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
