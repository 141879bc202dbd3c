//! The wire protocol between the server and its peers (samplers, displays,
//! admin tools): typed messages in length-prefixed frames. Control messages are
//! postcard-encoded; ray payloads travel as raw 10-byte records. Encoding is
//! pure; [`client`] alone opens sockets, for the blocking peers' side of the
//! handshake, over TLS ([`tls`]) where the address asks for it. Every decoder takes untrusted bytes and never panics.

#[cfg(feature = "net")]
pub mod client;
mod frame;
mod link;
mod message;
#[cfg(feature = "net")]
pub mod tls;

pub use frame::{decode_frame, encode_frame, Frame, FrameBuffer, FrameError, FRAME_HEADER, MAX_FRAME};
pub use link::{FrameLink, LinkError};
pub use message::{
    Access, Control, ControlOutcome, ControlReply, EyePoint, Hello, Message, MessageError, Progress, Role,
    SamplingMode, TracePacket,
};

/// Most rays one trace packet may ask for; samplers trace at most this many.
pub const MAX_PACKET_RAYS: u32 = 1 << 16;

/// Version of the protocol; peers with another version are refused.
pub const PROTOCOL_VERSION: u32 = 5;
