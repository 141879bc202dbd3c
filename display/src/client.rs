//! A display's connection to a holodeck server: handshake, beam requests, and
//! the samples that come back, decoded. A reader thread turns the socket into
//! a channel so the display can wait for samples with a deadline while it
//! keeps drawing.

use std::collections::HashMap;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use holodeck_protocol::wire::client::{self, ClientStream};
use holodeck_protocol::wire::{Access, Control, ControlReply, Frame, FrameLink, LinkError, Message, Progress, Role};
use holodeck_protocol::{BeamKey, Section};

use crate::request::BeamRequest;
use crate::sample::{Sample, SampleDecoder};

/// Why a display session failed.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    /// Connecting failed, or the server refused this display.
    #[error(transparent)]
    Connect(#[from] client::ClientError),
    /// Talking to the server failed.
    #[error("server {addr}: {source}")]
    Link {
        /// The server.
        addr: String,
        /// Why.
        source: LinkError,
    },
    /// The server sent something out of turn.
    #[error("protocol error: {0}")]
    Protocol(String),
    /// The server closed the connection.
    #[error("the server closed the connection")]
    Closed,
    /// The server sent nothing for too long while an answer was due.
    #[error("server {addr} sent nothing for {secs} s while a request's answer was due")]
    Timeout {
        /// The server.
        addr: String,
        /// How long it was silent.
        secs: u64,
    },
}

/// How long a request's answer may pause before the server counts as hung.
pub const ANSWER_TIMEOUT: Duration = Duration::from_secs(60);

/// What one immediate transfer brought.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Transfer {
    /// Beams received.
    pub beams: u64,
    /// Samples received.
    pub samples: u64,
    /// Records that did not decode (unknown beams).
    pub undecodable: u64,
    /// From the request to the last byte.
    pub elapsed: Duration,
}

/// A connected display.
pub struct DisplaySession {
    addr: String,
    writer: FrameLink<ClientStream>,
    frames: Receiver<Result<Frame, LinkError>>,
    decoder: SampleDecoder,
    scratch: Vec<Sample>,
    /// Rays received per beam (since the last request that asked to resend).
    received: HashMap<BeamKey, u64>,
    /// What the server lets this session do.
    access: Access,
    /// Answers to control commands not yet taken by the caller.
    notices: Vec<ControlReply>,
    /// The server's latest report.
    progress: Option<Progress>,
    /// How long a request's answer may pause ([`ANSWER_TIMEOUT`]).
    timeout: Duration,
}

impl Drop for DisplaySession {
    fn drop(&mut self) {
        // The reader thread holds its own handle of the socket: shut it down,
        // so the server sees this display leave now, not at its next frame.
        self.writer.stream().shutdown();
    }
}

impl DisplaySession {
    /// Connects to `addr` (`host:port` or `unix:PATH`) as a display.
    pub fn connect(addr: &str, token: &str, read_only: bool) -> Result<DisplaySession, ClientError> {
        let (writer, welcome) = client::open(addr, client::hello(Role::Display, token, "", read_only))?;
        let reader = writer.stream().try_clone().map_err(|e| ClientError::Link {
            addr: client::shown(addr).to_string(),
            source: LinkError::Io(e),
        })?;
        let (tx, frames) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut link = FrameLink::new(reader);
            loop {
                match link.read() {
                    Ok(Some(f)) => {
                        if tx.send(Ok(f)).is_err() {
                            return;
                        }
                    }
                    Ok(None) => return,
                    Err(e) => {
                        let _ = tx.send(Err(e));
                        return;
                    }
                }
            }
        });
        Ok(DisplaySession {
            addr: client::shown(addr).to_string(),
            writer,
            frames,
            decoder: SampleDecoder::new(welcome.sections),
            scratch: Vec::new(),
            received: HashMap::new(),
            timeout: ANSWER_TIMEOUT,
            access: welcome.access,
            notices: Vec::new(),
            progress: None,
        })
    }

    /// The holodeck's sections.
    pub fn sections(&self) -> &[Section] {
        self.decoder.sections()
    }

    /// Sets how long a request's answer may pause before the call fails
    /// with [`ClientError::Timeout`] (default [`ANSWER_TIMEOUT`]).
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// What the server lets this session do (its token, lowered to viewer
    /// access if it connected read-only).
    pub fn access(&self) -> Access {
        self.access
    }

    /// The server's answers to control commands that came since the last
    /// call, oldest first: each says whether its command was carried out,
    /// refused (and why) or failed. A refusal is news for the user, not an
    /// error of the session.
    pub fn take_notices(&mut self) -> Vec<ControlReply> {
        std::mem::take(&mut self.notices)
    }

    /// The server's latest report (sent about once a second), if one came.
    pub fn progress(&self) -> Option<&Progress> {
        self.progress.as_ref()
    }

    /// Keeps what the server says besides beam data; false for any other frame.
    fn note(&mut self, f: &Frame) -> bool {
        match f {
            Frame::Message(Message::ControlReply(r)) => self.notices.push(r.clone()),
            Frame::Message(Message::Progress(p)) => self.progress = Some(*p),
            _ => return false,
        }
        true
    }

    /// The next frame, waiting at most until `deadline` (`None`: forever).
    /// `Ok(None)` when the deadline passed.
    fn next(&mut self, deadline: Option<Instant>) -> Result<Option<Frame>, ClientError> {
        let got = match deadline {
            None => self.frames.recv().map_err(|_| RecvTimeoutError::Disconnected),
            Some(d) => self.frames.recv_timeout(d.saturating_duration_since(Instant::now())),
        };
        match got {
            Ok(Ok(f)) => Ok(Some(f)),
            Ok(Err(source)) => Err(ClientError::Link {
                addr: self.addr.clone(),
                source,
            }),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => Err(ClientError::Closed),
        }
    }

    fn send(&mut self, f: &Frame) -> Result<(), ClientError> {
        let addr = &self.addr;
        self.writer
            .write(f)
            .and_then(|()| self.writer.flush())
            .map_err(|source| ClientError::Link {
                addr: addr.clone(),
                source,
            })
    }

    /// Asks for a view's beams (replacing the last request) and receives at
    /// once the stored samples this session was not sent before (all of
    /// them with `resend`: after the display forgot what it had), handing
    /// them to `sink` beam by beam.
    pub fn request(
        &mut self,
        req: &BeamRequest,
        resend: bool,
        sink: &mut dyn FnMut(&[Sample]),
    ) -> Result<Transfer, ClientError> {
        let start = Instant::now();
        if resend {
            self.received.clear();
        }
        self.send(&Frame::Message(Message::BeamRequest {
            beams: req.beams.clone(),
            eye: req.eye,
            replace: true,
            resend,
        }))?;
        let mut t = Transfer::default();
        loop {
            // A hung server fails the call instead of holding it forever.
            let Some(f) = self.next(Some(Instant::now() + self.timeout))? else {
                return Err(ClientError::Timeout {
                    addr: self.addr.clone(),
                    secs: self.timeout.as_secs(),
                });
            };
            if self.note(&f) {
                continue;
            }
            match f {
                Frame::Beam { key, records } => {
                    t.beams += 1;
                    t.samples += records.len() as u64;
                    t.undecodable += self.take(key, &records, sink) as u64;
                }
                Frame::Message(Message::Delivered { .. }) => break,
                Frame::Message(Message::Error { message }) => return Err(ClientError::Protocol(message)),
                other => return Err(ClientError::Protocol(format!("expected beam data, got {other:?}"))),
            }
        }
        t.elapsed = start.elapsed();
        Ok(t)
    }

    /// Raises the counts of the current view's beams to `req`'s (the view
    /// has not changed): the server traces more for them; what it has
    /// already sent is not sent again, and new samples come through
    /// [`DisplaySession::refine`].
    pub fn raise(&mut self, req: &BeamRequest) -> Result<(), ClientError> {
        self.send(&Frame::Message(Message::BeamRequest {
            beams: req.beams.clone(),
            eye: req.eye,
            replace: false,
            resend: false,
        }))
    }

    /// Receives newly traced samples of the requested beams until `deadline`;
    /// returns how many came.
    pub fn refine(&mut self, deadline: Instant, sink: &mut dyn FnMut(&[Sample])) -> Result<u64, ClientError> {
        let mut n = 0u64;
        while let Some(f) = self.next(Some(deadline))? {
            if self.note(&f) {
                continue;
            }
            match f {
                Frame::Beam { key, records } => {
                    n += records.len() as u64;
                    self.take(key, &records, sink);
                }
                Frame::Message(Message::Error { message }) => return Err(ClientError::Protocol(message)),
                // The end of the (empty) immediate transfer of a raise.
                Frame::Message(Message::Delivered { .. }) => {}
                other => return Err(ClientError::Protocol(format!("unexpected {other:?}"))),
            }
        }
        Ok(n)
    }

    /// Rays of `key` this session was sent (since the last request that
    /// asked to resend): what a refining request counts on.
    pub fn received(&self, key: BeamKey) -> u64 {
        self.received.get(&key).copied().unwrap_or(0)
    }

    fn take(
        &mut self,
        key: BeamKey,
        records: &[holodeck_protocol::RayRecord],
        sink: &mut dyn FnMut(&[Sample]),
    ) -> usize {
        *self.received.entry(key).or_default() += records.len() as u64;
        self.scratch.clear();
        let bad = self.decoder.decode(key.section, key.beam, records, &mut self.scratch);
        sink(&self.scratch);
        bad
    }

    /// Sends a control command. The server answers every one (see
    /// [`DisplaySession::take_notices`]); it carries out only those
    /// [`DisplaySession::access`] allows (see [`Control::needs`]).
    pub fn control(&mut self, c: Control) -> Result<(), ClientError> {
        self.send(&Frame::Message(Message::Control(c)))
    }
}
