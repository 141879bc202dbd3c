//! Whole frames over any blocking byte stream (the sampler's and the headless
//! display's side of a connection). Writes are queued and go out in one
//! system call when the caller flushes or is about to wait for a frame; the
//! caller owns the socket (this crate opens none).

use std::io::{Read, Write};

use super::frame::{encode_frame, Frame, FrameBuffer, FrameError};

/// What can go wrong on a link.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The stream failed.
    #[error("{0}")]
    Io(#[from] std::io::Error),
    /// The peer sent bytes that are not a valid frame.
    #[error("bad frame: {0}")]
    Frame(#[from] FrameError),
    /// The peer closed the connection in the middle of a frame.
    #[error("the peer closed the connection mid-frame")]
    Truncated,
}

impl LinkError {
    /// True when the peer went away (closed, reset) rather than misbehaved.
    pub fn is_gone(&self) -> bool {
        use std::io::ErrorKind::*;
        match self {
            LinkError::Io(e) => matches!(
                e.kind(),
                ConnectionReset | ConnectionAborted | BrokenPipe | UnexpectedEof
            ),
            LinkError::Truncated => true,
            LinkError::Frame(_) => false,
        }
    }
}

/// A framed blocking connection.
pub struct FrameLink<S> {
    stream: S,
    frames: FrameBuffer,
    out: Vec<u8>,
}

impl<S: Read + Write> FrameLink<S> {
    /// Wraps a connected stream.
    pub fn new(stream: S) -> FrameLink<S> {
        FrameLink {
            stream,
            frames: FrameBuffer::new(),
            out: Vec::new(),
        }
    }

    /// The next frame, or `None` when the peer closed cleanly between frames.
    /// Queued writes are flushed first: the peer may be waiting for them.
    pub fn read(&mut self) -> Result<Option<Frame>, LinkError> {
        loop {
            if let Some(frame) = self.frames.next_frame()? {
                return Ok(Some(frame));
            }
            self.flush()?;
            let mut chunk = [0u8; 64 << 10];
            let n = self.stream.read(&mut chunk)?;
            if n == 0 {
                return if self.frames.is_empty() {
                    Ok(None)
                } else {
                    Err(LinkError::Truncated)
                };
            }
            self.frames.push(&chunk[..n]);
        }
    }

    /// The next frame if its bytes have already arrived with earlier ones,
    /// without waiting on the stream (a peer that sends several frames at
    /// once: the rest of them).
    pub fn read_buffered(&mut self) -> Result<Option<Frame>, LinkError> {
        Ok(self.frames.next_frame()?)
    }

    /// Queues a frame; it goes out with the next flush (at the latest before
    /// the next blocking read, or once 1 MiB is queued).
    pub fn write(&mut self, frame: &Frame) -> Result<(), LinkError> {
        encode_frame(frame, &mut self.out)?;
        if self.out.len() >= 1 << 20 {
            self.flush()?;
        }
        Ok(())
    }

    /// Bytes queued and not yet sent.
    pub fn queued(&self) -> usize {
        self.out.len()
    }

    /// Sends everything queued.
    pub fn flush(&mut self) -> Result<(), LinkError> {
        if self.out.is_empty() {
            return Ok(());
        }
        let r = self.stream.write_all(&self.out);
        self.out.clear();
        r?;
        Ok(())
    }

    /// The stream (to set timeouts, say).
    pub fn stream(&self) -> &S {
        &self.stream
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::Message;

    /// A stream that reads from a script in small pieces and records writes.
    struct Script {
        input: Vec<u8>,
        at: usize,
        piece: usize,
        written: Vec<u8>,
    }

    impl Read for Script {
        fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
            let n = self.piece.min(out.len()).min(self.input.len() - self.at);
            out[..n].copy_from_slice(&self.input[self.at..self.at + n]);
            self.at += n;
            Ok(n)
        }
    }

    impl Write for Script {
        fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
            self.written.extend_from_slice(b);
            Ok(b.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn frames_split_anywhere_arrive_whole_and_writes_go_out_before_reads() {
        let frames = vec![
            Frame::Message(Message::Delivered { beams: 1, rays: 2 }),
            Frame::Message(Message::Error {
                message: "x".repeat(300),
            }),
        ];
        let mut input = Vec::new();
        for f in &frames {
            encode_frame(f, &mut input).unwrap();
        }
        for piece in [1, 3, 7, 1000] {
            let mut link = FrameLink::new(Script {
                input: input.clone(),
                at: 0,
                piece,
                written: Vec::new(),
            });
            link.write(&frames[0]).unwrap();
            assert!(link.queued() > 0);
            assert_eq!(link.read().unwrap().as_ref(), Some(&frames[0]));
            assert_eq!(link.queued(), 0, "flushed before waiting");
            assert_eq!(link.read().unwrap().as_ref(), Some(&frames[1]));
            assert!(link.read().unwrap().is_none());
        }
        // Cut mid-frame: an error, not a hang or a panic.
        let mut link = FrameLink::new(Script {
            input: input[..input.len() - 3].to_vec(),
            at: 0,
            piece: 5,
            written: Vec::new(),
        });
        link.read().unwrap();
        assert!(matches!(link.read(), Err(LinkError::Truncated)));
    }

    /// Frames that came in one read are handed out without another; once
    /// they are used up, nothing is read from the stream.
    #[test]
    fn buffered_frames_come_without_waiting() {
        let frames: Vec<Frame> = (0..3)
            .map(|rays| Frame::Message(Message::Delivered { beams: 1, rays }))
            .collect();
        let mut input = Vec::new();
        for f in &frames {
            encode_frame(f, &mut input).unwrap();
        }
        let mut link = FrameLink::new(Script {
            input,
            at: 0,
            piece: 1 << 20,
            written: Vec::new(),
        });
        assert!(link.read_buffered().unwrap().is_none(), "nothing read yet");
        assert_eq!(link.read().unwrap().as_ref(), Some(&frames[0]));
        assert_eq!(link.read_buffered().unwrap().as_ref(), Some(&frames[1]));
        assert_eq!(link.read_buffered().unwrap().as_ref(), Some(&frames[2]));
        assert!(link.read_buffered().unwrap().is_none());
        assert!(link.read().unwrap().is_none());
    }
}
