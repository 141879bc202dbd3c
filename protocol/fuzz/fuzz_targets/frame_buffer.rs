//! Bytes arriving in arbitrary pieces, as a connection delivers them, through
//! the frame buffer both links use, and every decoded message validated:
//! errors are fine, panics are not; what comes out must not depend on how
//! the bytes were cut.
#![no_main]

use holodeck_protocol::wire::{decode_frame, Frame, FrameBuffer};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&cut, bytes)) = data.split_first() else { return };
    let piece = usize::from(cut).max(1);
    let mut buffer = FrameBuffer::new();
    let mut pieces = Vec::new();
    'outer: for chunk in bytes.chunks(piece) {
        buffer.push(chunk);
        loop {
            match buffer.next_frame() {
                Ok(Some(f)) => {
                    if let Frame::Message(m) = &f {
                        let _ = m.validate();
                    }
                    pieces.push(f);
                }
                Ok(None) => break,
                Err(_) => break 'outer,
            }
        }
    }
    // The same bytes decoded in one piece give the same frames, in order.
    let mut whole = Vec::new();
    let mut at = 0;
    while let Ok(Some((f, used))) = decode_frame(&bytes[at..]) {
        whole.push(f);
        at += used;
    }
    assert_eq!(&whole[..pieces.len().min(whole.len())], &pieces[..pieces.len().min(whole.len())]);
});
