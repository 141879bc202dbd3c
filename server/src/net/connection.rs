//! Whole frames over one socket: buffered reads until a frame is complete,
//! writes of one encoded frame (or a batch of them) at a time.

use holodeck_protocol::wire::{encode_frame, Frame, FrameBuffer, FrameError};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};

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
}

/// A framed connection.
pub struct Connection {
    stream: Box<dyn Stream>,
    frames: FrameBuffer,
    out: Vec<u8>,
}

impl Connection {
    /// Wraps a connected socket.
    pub fn new(stream: Box<dyn Stream>) -> Connection {
        Connection {
            stream,
            frames: FrameBuffer::new(),
            out: Vec::new(),
        }
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

    /// Sends several frames in one write.
    pub async fn write_all(&mut self, frames: &[Frame]) -> Result<(), ConnectionError> {
        self.out.clear();
        for f in frames {
            encode_frame(f, &mut self.out)?;
        }
        self.stream.write_all(&self.out).await?;
        self.trim();
        Ok(())
    }

    /// Gives back a write buffer a big batch left large, so that idle
    /// connections hold little memory.
    fn trim(&mut self) {
        if self.out.capacity() > 1 << 20 {
            self.out = Vec::new();
        }
    }

    /// Sends one frame.
    pub async fn write(&mut self, frame: &Frame) -> Result<(), ConnectionError> {
        self.out.clear();
        encode_frame(frame, &mut self.out)?;
        self.stream.write_all(&self.out).await?;
        Ok(())
    }
}
