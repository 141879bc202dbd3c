//! The sampler's side of the wire: connect to a holodeck server, prove the
//! scene, and trace the packets it hands out until it closes the connection.
//! Blocking I/O on one connection per worker thread: tracing, not the network,
//! is what takes the time.

use std::io::{Read, Write};
use std::net::TcpStream;

use glam::DVec3;
use holodeck_protocol::wire::{
    decode_frame, encode_frame, Frame, FrameError, Hello, Message, Role, SamplingMode, PROTOCOL_VERSION,
};
use holodeck_protocol::{RayRecord, Section, SectionError};

use crate::beam::{proximity_rays, trace_sample, uniform_rays};
use crate::shade::{Rng, Tracer};

/// Why a worker stopped.
#[derive(Debug, thiserror::Error)]
pub enum WorkerError {
    /// The connection failed.
    #[error("connection to {addr}")]
    Io {
        /// The server.
        addr: String,
        /// Why.
        source: std::io::Error,
    },
    /// The server refused this worker.
    #[error("the server refused this sampler: {0}")]
    Refused(String),
    /// The server sent something that is not a valid frame.
    #[error("bad frame from the server: {0}")]
    Frame(#[from] FrameError),
    /// The server broke the protocol.
    #[error("protocol error: {0}")]
    Protocol(String),
    /// A section the server described is invalid.
    #[error("section from the server: {0}")]
    Section(#[from] SectionError),
}

struct Link {
    stream: TcpStream,
    addr: String,
    buf: Vec<u8>,
    out: Vec<u8>,
}

impl Link {
    fn io(&self) -> impl FnOnce(std::io::Error) -> WorkerError + '_ {
        move |source| WorkerError::Io {
            addr: self.addr.clone(),
            source,
        }
    }

    fn read(&mut self) -> Result<Option<Frame>, WorkerError> {
        loop {
            if let Some((frame, used)) = decode_frame(&self.buf)? {
                self.buf.drain(..used);
                return Ok(Some(frame));
            }
            // About to wait for the server: send what is finished first.
            self.flush()?;
            let mut chunk = [0u8; 16 << 10];
            let n = self.stream.read(&mut chunk).map_err(|e| WorkerError::Io {
                addr: self.addr.clone(),
                source: e,
            })?;
            if n == 0 {
                return Ok(None);
            }
            self.buf.extend_from_slice(&chunk[..n]);
        }
    }

    /// Queues a frame; it goes out with the next flush (before any blocking read).
    fn write(&mut self, frame: &Frame) -> Result<(), WorkerError> {
        encode_frame(frame, &mut self.out)?;
        if self.out.len() >= 1 << 20 {
            self.flush()?;
        }
        Ok(())
    }

    fn flush(&mut self) -> Result<(), WorkerError> {
        if self.out.is_empty() {
            return Ok(());
        }
        let out = std::mem::take(&mut self.out);
        let r = self.stream.write_all(&out).map_err(self.io());
        self.out = out;
        self.out.clear();
        r
    }
}

/// Traces packets from the server at `addr` until it closes the connection;
/// returns the rays traced. `scene` is the content hash of `tracer`'s scene.
pub fn run_worker(addr: &str, tracer: &Tracer, scene: &str, token: &str, seed: u64) -> Result<u64, WorkerError> {
    let stream = TcpStream::connect(addr).map_err(|source| WorkerError::Io {
        addr: addr.to_string(),
        source,
    })?;
    let _ = stream.set_nodelay(true);
    let mut link = Link {
        stream,
        addr: addr.to_string(),
        buf: Vec::new(),
        out: Vec::new(),
    };
    let hello = Hello {
        version: PROTOCOL_VERSION,
        role: Role::Sampler,
        scene: scene.into(),
        token: token.into(),
        read_only: true,
    };
    link.write(&Frame::Message(Message::Hello(hello)))?;
    let (sections, obstructions) = match link.read()? {
        Some(Frame::Message(Message::Welcome { sections, obstructions })) => {
            let sections: Vec<Section> = sections.into_iter().map(Section::try_from).collect::<Result<_, _>>()?;
            (sections, obstructions)
        }
        Some(Frame::Message(Message::Refused { reason })) => return Err(WorkerError::Refused(reason)),
        Some(_) => return Err(WorkerError::Protocol("expected Welcome or Refused".into())),
        None => {
            return Err(WorkerError::Protocol(
                "the server closed the connection during the handshake".into(),
            ))
        }
    };
    let mut traced = 0u64;
    let mut n = 0u64;
    loop {
        let frame = match link.read() {
            Ok(Some(f)) => f,
            Ok(None) => break,
            // The server stopping (or restarting) ends this worker's run.
            Err(WorkerError::Io { source, .. }) if gone(&source) => break,
            Err(e) => return Err(e),
        };
        let packet = match frame {
            Frame::Message(Message::Trace(p)) => p,
            Frame::Message(Message::Error { message }) => {
                tracing::warn!("server: {message}");
                continue;
            }
            _ => return Err(WorkerError::Protocol("expected trace packets".into())),
        };
        let section = sections
            .get(packet.key.section as usize)
            .ok_or_else(|| WorkerError::Protocol(format!("packet for unknown section {}", packet.key.section)))?;
        let mut rng = Rng::new(seed, n);
        n += 1;
        let count = packet.rays.min(1 << 16) as usize;
        let samples = match packet.mode {
            SamplingMode::Uniform => uniform_rays(section, packet.key.beam, count, &mut rng)?,
            SamplingMode::NearEye { eye, radius } => {
                proximity_rays(section, packet.key.beam, count, DVec3::from(eye), radius, &mut rng)?.0
            }
        };
        let records: Vec<RayRecord> = samples
            .iter()
            .map(|s| trace_sample(tracer, section, obstructions, s, &mut rng))
            .collect();
        let rays = records.len() as u64;
        match link.write(&Frame::Finished {
            id: packet.id,
            key: packet.key,
            records,
        }) {
            Ok(()) => traced += rays,
            Err(WorkerError::Io { source, .. }) if gone(&source) => break,
            Err(e) => return Err(e),
        }
    }
    tracing::info!("{addr}: the server closed the connection after {traced} rays");
    Ok(traced)
}

/// True for errors that mean the server went away.
fn gone(e: &std::io::Error) -> bool {
    use std::io::ErrorKind::*;
    matches!(
        e.kind(),
        ConnectionReset | ConnectionAborted | BrokenPipe | UnexpectedEof
    )
}
