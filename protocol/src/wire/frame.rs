//! Frames: a 4-byte little-endian payload length, a kind byte, the payload.
//!
//! | kind | payload |
//! |---|---|
//! | 0 | a postcard-encoded [`Message`] |
//! | 1 | beam data: section u32, beam u32, then 10-byte records |
//! | 2 | a finished packet: id u64, section u32, beam u32, then 10-byte records |

use crate::beam::BeamKey;
use crate::record::{RayRecord, RAY_RECORD_BYTES};

use super::message::{Message, MessageError};

/// Bytes before the payload: length (4) and kind (1).
pub const FRAME_HEADER: usize = 5;

/// Largest payload accepted: 16 MiB, 1.6 million rays.
pub const MAX_FRAME: usize = 16 << 20;

const KIND_MESSAGE: u8 = 0;
const KIND_BEAM: u8 = 1;
const KIND_FINISHED: u8 = 2;

/// One decoded frame.
#[derive(Clone, Debug, PartialEq)]
pub enum Frame {
    /// A control message.
    Message(Message),
    /// Rays of a beam sent to a display.
    Beam {
        /// The beam.
        key: BeamKey,
        /// Its rays.
        records: Vec<RayRecord>,
    },
    /// A sampler's answer to a trace packet.
    Finished {
        /// The packet's id.
        id: u64,
        /// The beam.
        key: BeamKey,
        /// The traced rays.
        records: Vec<RayRecord>,
    },
}

/// Why bytes are not a valid frame.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrameError {
    /// The declared payload is larger than [`MAX_FRAME`].
    #[error("frame of {len} bytes is larger than the {max} allowed")]
    TooLarge {
        /// Its declared length.
        len: usize,
        /// The most allowed here.
        max: usize,
    },
    /// An unknown kind byte.
    #[error("unknown frame kind {0}")]
    UnknownKind(u8),
    /// A payload that does not parse.
    #[error("malformed {kind} frame: {detail}")]
    Malformed {
        /// Which kind of frame.
        kind: &'static str,
        /// What is wrong.
        detail: String,
    },
    /// A message that decodes but whose contents are impossible.
    #[error("invalid message: {0}")]
    Invalid(MessageError),
}

impl From<MessageError> for FrameError {
    fn from(e: MessageError) -> Self {
        FrameError::Invalid(e)
    }
}

/// Appends the encoding of `frame` to `out`.
pub fn encode_frame(frame: &Frame, out: &mut Vec<u8>) -> Result<(), FrameError> {
    let start = out.len();
    out.extend_from_slice(&[0; FRAME_HEADER]);
    let kind = match frame {
        Frame::Message(m) => {
            let bytes = postcard::to_allocvec(m).map_err(|e| FrameError::Malformed {
                kind: "message",
                detail: e.to_string(),
            })?;
            out.extend_from_slice(&bytes);
            KIND_MESSAGE
        }
        Frame::Beam { key, records } => {
            out.extend_from_slice(&key.section.to_le_bytes());
            out.extend_from_slice(&key.beam.to_le_bytes());
            out.extend_from_slice(RayRecord::slice_as_bytes(records));
            KIND_BEAM
        }
        Frame::Finished { id, key, records } => {
            out.extend_from_slice(&id.to_le_bytes());
            out.extend_from_slice(&key.section.to_le_bytes());
            out.extend_from_slice(&key.beam.to_le_bytes());
            out.extend_from_slice(RayRecord::slice_as_bytes(records));
            KIND_FINISHED
        }
    };
    let len = out.len() - start - FRAME_HEADER;
    if len > MAX_FRAME {
        out.truncate(start);
        return Err(FrameError::TooLarge { len, max: MAX_FRAME });
    }
    out[start..start + 4].copy_from_slice(&(len as u32).to_le_bytes());
    out[start + 4] = kind;
    Ok(())
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn records(kind: &'static str, bytes: &[u8]) -> Result<Vec<RayRecord>, FrameError> {
    RayRecord::vec_from_bytes(bytes).ok_or_else(|| FrameError::Malformed {
        kind,
        detail: format!(
            "{} bytes of records is not a multiple of {RAY_RECORD_BYTES}",
            bytes.len()
        ),
    })
}

/// Decodes the first frame in `buf`: `Ok(None)` if more bytes are needed,
/// else the frame and the bytes it took. An oversized length is refused as
/// soon as the header arrives, before any payload is buffered.
pub fn decode_frame(buf: &[u8]) -> Result<Option<(Frame, usize)>, FrameError> {
    if buf.len() < FRAME_HEADER {
        return Ok(None);
    }
    let len = u32_at(buf, 0) as usize;
    if len > MAX_FRAME {
        return Err(FrameError::TooLarge { len, max: MAX_FRAME });
    }
    if buf.len() < FRAME_HEADER + len {
        return Ok(None);
    }
    let payload = &buf[FRAME_HEADER..FRAME_HEADER + len];
    let frame = match buf[4] {
        KIND_MESSAGE => {
            let m: Message = postcard::from_bytes(payload).map_err(|e| FrameError::Malformed {
                kind: "message",
                detail: e.to_string(),
            })?;
            m.validate()?;
            Frame::Message(m)
        }
        KIND_BEAM => {
            if payload.len() < 8 {
                return Err(FrameError::Malformed {
                    kind: "beam",
                    detail: "shorter than its header".into(),
                });
            }
            let key = BeamKey::new(u32_at(payload, 0), u32_at(payload, 4));
            Frame::Beam {
                key,
                records: records("beam", &payload[8..])?,
            }
        }
        KIND_FINISHED => {
            if payload.len() < 16 {
                return Err(FrameError::Malformed {
                    kind: "finished",
                    detail: "shorter than its header".into(),
                });
            }
            let mut id = [0u8; 8];
            id.copy_from_slice(&payload[..8]);
            let key = BeamKey::new(u32_at(payload, 8), u32_at(payload, 12));
            Frame::Finished {
                id: u64::from_le_bytes(id),
                key,
                records: records("finished", &payload[16..])?,
            }
        }
        other => return Err(FrameError::UnknownKind(other)),
    };
    Ok(Some((frame, FRAME_HEADER + len)))
}

/// Bytes received and not yet decoded: the half of a connection that the
/// blocking and the async links share. Bytes go in as they arrive; whole
/// frames come out.
#[derive(Debug, Default)]
pub struct FrameBuffer {
    buf: Vec<u8>,
    start: usize,
    /// Largest frame accepted (at most [`MAX_FRAME`]; 0 means [`MAX_FRAME`]).
    max: usize,
}

impl FrameBuffer {
    /// An empty buffer.
    pub fn new() -> FrameBuffer {
        FrameBuffer {
            buf: Vec::with_capacity(64 << 10),
            start: 0,
            max: MAX_FRAME,
        }
    }

    /// Accepts frames of at most `max` bytes from now on (capped at
    /// [`MAX_FRAME`]): a server takes only small frames before a peer has
    /// shown its token.
    pub fn set_max_frame(&mut self, max: usize) {
        self.max = max.min(MAX_FRAME);
    }

    /// The next whole frame, if the bytes so far hold one.
    pub fn next_frame(&mut self) -> Result<Option<Frame>, FrameError> {
        let pending = &self.buf[self.start..];
        let max = if self.max == 0 { MAX_FRAME } else { self.max };
        if pending.len() >= 4 {
            let len = u32::from_le_bytes([pending[0], pending[1], pending[2], pending[3]]) as usize;
            if len > max {
                return Err(FrameError::TooLarge { len, max });
            }
        }
        let Some((frame, used)) = decode_frame(&self.buf[self.start..])? else {
            return Ok(None);
        };
        self.start += used;
        if self.start == self.buf.len() {
            self.buf.clear();
            self.start = 0;
        }
        Ok(Some(frame))
    }

    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        if self.start > 0 {
            self.buf.drain(..self.start);
            self.start = 0;
        }
        self.buf.extend_from_slice(bytes);
    }

    /// True when no partial frame is waiting (a peer closing now closed cleanly).
    pub fn is_empty(&self) -> bool {
        self.start == self.buf.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::depth::DepthCode;
    use crate::rgbe::Rgbe;
    use crate::section::{Section, SectionKind};
    use crate::wire::message::{
        Access, Control, ControlOutcome, ControlReply, EyePoint, Hello, Progress, Role, SamplingMode, TracePacket,
    };
    use proptest::prelude::*;

    fn samples() -> Vec<Frame> {
        let section = Section::new(
            [0.0; 3],
            [[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]],
            [2, 3, 4],
            SectionKind::Interior,
        )
        .unwrap();
        let recs: Vec<RayRecord> = (0..5u8)
            .map(|i| RayRecord::new([i, 1], [2, i], Rgbe([i, 9, 8, 130]), DepthCode(u16::from(i) * 300)))
            .collect();
        vec![
            Frame::Message(Message::Hello(Hello {
                version: 1,
                role: Role::Sampler,
                scene: "blake3:ab".into(),
                token: "secret".into(),
                read_only: false,
            })),
            Frame::Message(Message::Welcome {
                sections: vec![section.spec()],
                obstructions: true,
                vdistance: true,
                access: Access::Writer,
            }),
            Frame::Message(Message::Refused {
                reason: "wrong token".into(),
                retry: true,
            }),
            Frame::Message(Message::BeamRequest {
                beams: vec![(BeamKey::new(0, 7), 40), (BeamKey::new(1, 2), 3)],
                eye: Some(EyePoint {
                    position: [1.0, 2.0, 3.0],
                    radius: 0.25,
                    frustum: crate::View::parse("-vtv -vd 1 0 0").unwrap().frustum(),
                }),
                replace: true,
                resend: false,
            }),
            Frame::Message(Message::Delivered { beams: 3, rays: 1234 }),
            Frame::Message(Message::Trace(TracePacket {
                id: 99,
                key: BeamKey::new(0, 12),
                rays: 21,
                mode: SamplingMode::NearEye {
                    eye: [1.0, 2.0, 1.5],
                    radius: 0.2,
                    frustum: None,
                },
            })),
            Frame::Message(Message::Progress(Progress {
                rays: 5,
                rays_per_second: 2.5,
                file_bytes: 100,
                beams_filled: 3,
                beams: 30,
                samplers: 4,
                displays: 2,
                paused: true,
            })),
            Frame::Message(Message::Control(Control::Quit)),
            Frame::Message(Message::Control(Control::Adopt {
                scene: "blake3:cd".into(),
                keep: true,
            })),
            Frame::Message(Message::ControlReply(ControlReply {
                control: Control::Clobber,
                outcome: ControlOutcome::Refused {
                    reason: "Clobber needs admin access".into(),
                },
            })),
            Frame::Beam {
                key: BeamKey::new(0, 3),
                records: recs.clone(),
            },
            Frame::Finished {
                id: u64::MAX,
                key: BeamKey::new(2, 1),
                records: recs,
            },
            Frame::Beam {
                key: BeamKey::new(0, 0),
                records: vec![],
            },
        ]
    }

    #[test]
    fn every_frame_round_trips_also_when_split_and_concatenated() {
        let mut stream = Vec::new();
        for f in samples() {
            encode_frame(&f, &mut stream).unwrap();
        }
        // Fed one byte at a time, the decoder asks for more until each frame is whole.
        let mut got = Vec::new();
        let mut at = 0;
        let mut end = 0;
        while at < stream.len() {
            end = (end + 1).min(stream.len());
            if let Some((f, used)) = decode_frame(&stream[at..end]).unwrap() {
                got.push(f);
                at += used;
            }
        }
        assert_eq!(got, samples());
    }

    #[test]
    fn bad_frames_are_refused_with_reasons() {
        let mut huge = ((MAX_FRAME + 1) as u32).to_le_bytes().to_vec();
        huge.push(0);
        assert_eq!(
            decode_frame(&huge),
            Err(FrameError::TooLarge {
                len: MAX_FRAME + 1,
                max: MAX_FRAME
            })
        );
        assert_eq!(decode_frame(&[0, 0, 0, 0, 7]), Err(FrameError::UnknownKind(7)));
        // Records that are not whole.
        let mut odd = vec![11, 0, 0, 0, KIND_BEAM];
        odd.extend_from_slice(&[0; 11]);
        assert!(matches!(
            decode_frame(&odd),
            Err(FrameError::Malformed { kind: "beam", .. })
        ));
        // A well-formed message with an impossible value.
        let nan = Frame::Message(Message::Trace(TracePacket {
            id: 1,
            key: BeamKey::new(0, 0),
            rays: 1,
            mode: SamplingMode::NearEye {
                eye: [f64::NAN, 0.0, 0.0],
                radius: 1.0,
                frustum: None,
            },
        }));
        let mut out = Vec::new();
        encode_frame(&nan, &mut out).unwrap();
        let e = decode_frame(&out).unwrap_err();
        assert!(
            matches!(
                e,
                FrameError::Invalid(MessageError::NonFinite {
                    what: "eye coordinate",
                    ..
                })
            ),
            "{e:?}"
        );
        assert!(e.to_string().contains("eye coordinate is NaN"), "{e}");
        let mut garbage = vec![3, 0, 0, 0, KIND_MESSAGE];
        garbage.extend_from_slice(&[200, 201, 202]);
        assert!(matches!(
            decode_frame(&garbage),
            Err(FrameError::Malformed { kind: "message", .. })
        ));
        let too_many = Frame::Beam {
            key: BeamKey::new(0, 0),
            records: vec![RayRecord::default(); MAX_FRAME / 10 + 1],
        };
        let mut out = Vec::new();
        assert!(matches!(
            encode_frame(&too_many, &mut out),
            Err(FrameError::TooLarge { .. })
        ));
        assert!(out.is_empty(), "a refused frame leaves nothing behind");
    }

    proptest! {
        #[test]
        fn decoding_arbitrary_bytes_never_panics(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
            let mut at = 0;
            while let Ok(Some((_, used))) = decode_frame(&bytes[at..]) {
                at += used;
            }
        }

        #[test]
        fn ray_payloads_round_trip(raw in prop::collection::vec(any::<u8>(), 0..50), id in any::<u64>(), s in any::<u32>(), b in any::<u32>()) {
            let records: Vec<RayRecord> = raw.chunks_exact(10).map(bytemuck::pod_read_unaligned).collect();
            let f = Frame::Finished { id, key: BeamKey::new(s, b), records };
            let mut out = Vec::new();
            encode_frame(&f, &mut out).unwrap();
            let (back, used) = decode_frame(&out).unwrap().unwrap();
            prop_assert_eq!(used, out.len());
            prop_assert_eq!(back, f);
        }
    }
}
