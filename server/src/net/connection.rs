//! Whole frames over one socket: buffered reads until a frame is complete,
//! writes of one encoded frame (or a batch of them) at a time.

use holodeck_protocol::wire::{encode_frame, Frame, FrameBuffer, FrameError};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt, ReadHalf, WriteHalf};

/// A byte stream a peer is connected by: TCP or a Unix socket.
pub trait Stream: AsyncRead + AsyncWrite + Unpin + Send {}

impl<T: AsyncRead + AsyncWrite + Unpin + Send> Stream for T {}

/// What can go wrong on a connection.
#[derive(Debug, thiserror::Error)]
pub enum ConnectionError {
    /// The socket failed.
    #[error("connection: {0}")]
    Io(#[from] std::io::Error),
    /// The peer sent bytes that are not a valid frame.
    #[error("peer sent a bad frame: {0}")]
    Frame(#[from] FrameError),
    /// The peer closed the connection in the middle of a frame.
    #[error("peer closed the connection mid-frame")]
    Truncated,
    /// The peer held work without answering, or did not read what was sent.
    #[error("peer stalled: {0}")]
    Stalled(String),
}

impl ConnectionError {
    /// True when the peer went away (closed or reset the connection, as a
    /// display does when its window closes) rather than misbehaved.
    pub fn is_gone(&self) -> bool {
        use std::io::ErrorKind::*;
        match self {
            ConnectionError::Io(e) => matches!(
                e.kind(),
                ConnectionReset | ConnectionAborted | BrokenPipe | UnexpectedEof
            ),
            ConnectionError::Truncated => true,
            ConnectionError::Frame(_) | ConnectionError::Stalled(_) => false,
        }
    }
}

/// A framed connection: a reader and a writer half, which a task may also
/// drive separately (see [`Connection::split`]).
pub struct Connection {
    reader: FrameReader,
    writer: FrameWriter,
}

/// The receiving half.
pub struct FrameReader {
    stream: ReadHalf<Box<dyn Stream>>,
    frames: FrameBuffer,
}

/// The sending half.
pub struct FrameWriter {
    stream: WriteHalf<Box<dyn Stream>>,
    out: Vec<u8>,
}

impl Connection {
    /// Wraps a connected socket.
    pub fn new(stream: Box<dyn Stream>) -> Connection {
        let (read, write) = tokio::io::split(stream);
        Connection {
            reader: FrameReader {
                stream: read,
                frames: FrameBuffer::new(),
            },
            writer: FrameWriter {
                stream: write,
                out: Vec::new(),
            },
        }
    }

    /// The two halves, for a peer that must be read while a long write is
    /// under way (samplers: each side may be writing to the other at once).
    pub fn split(self) -> (FrameReader, FrameWriter) {
        (self.reader, self.writer)
    }

    /// Accepts only frames up to `max` bytes from now on.
    pub fn set_max_frame(&mut self, max: usize) {
        self.reader.frames.set_max_frame(max);
    }

    /// See [`FrameReader::read`].
    pub async fn read(&mut self) -> Result<Option<Frame>, ConnectionError> {
        self.reader.read().await
    }

    /// See [`FrameWriter::write_all`].
    pub async fn write_all(&mut self, frames: &[Frame]) -> Result<(), ConnectionError> {
        self.writer.write_all(frames).await
    }

    /// See [`FrameWriter::write`].
    pub async fn write(&mut self, frame: &Frame) -> Result<(), ConnectionError> {
        self.writer.write(frame).await
    }
}

impl FrameReader {
    /// The next frame if one is already buffered, without waiting.
    pub fn buffered(&mut self) -> Result<Option<Frame>, ConnectionError> {
        Ok(self.frames.next_frame()?)
    }

    /// The next frame, or `None` when the peer closed cleanly between frames.
    /// Cancel-safe: bytes already received stay buffered.
    pub async fn read(&mut self) -> Result<Option<Frame>, ConnectionError> {
        loop {
            if let Some(frame) = self.frames.next_frame()? {
                return Ok(Some(frame));
            }
            let mut chunk = [0u8; 64 << 10];
            let n = self.stream.read(&mut chunk).await?;
            if n == 0 {
                return if self.frames.is_empty() {
                    Ok(None)
                } else {
                    Err(ConnectionError::Truncated)
                };
            }
            self.frames.push(&chunk[..n]);
        }
    }
}

impl FrameWriter {
    /// Sends several frames in one write.
    pub async fn write_all(&mut self, frames: &[Frame]) -> Result<(), ConnectionError> {
        self.out.clear();
        for f in frames {
            encode_frame(f, &mut self.out)?;
        }
        self.stream.write_all(&self.out).await?;
        // A big batch leaves a big buffer: give it back, so that idle
        // connections hold little memory.
        if self.out.capacity() > 1 << 20 {
            self.out = Vec::new();
        }
        Ok(())
    }

    /// Sends one frame.
    pub async fn write(&mut self, frame: &Frame) -> Result<(), ConnectionError> {
        self.out.clear();
        encode_frame(frame, &mut self.out)?;
        self.stream.write_all(&self.out).await?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{Error, ErrorKind};

    #[test]
    fn a_peer_that_leaves_is_told_from_one_that_misbehaves() {
        for kind in [
            ErrorKind::ConnectionReset,
            ErrorKind::BrokenPipe,
            ErrorKind::UnexpectedEof,
        ] {
            assert!(ConnectionError::Io(Error::from(kind)).is_gone(), "{kind:?}");
        }
        assert!(ConnectionError::Truncated.is_gone());
        assert!(!ConnectionError::Io(Error::from(ErrorKind::PermissionDenied)).is_gone());
        assert!(!ConnectionError::Stalled("held work".into()).is_gone());
    }
}
