//! A stream of arbitrary bytes fed to the frame decoder, as a hostile peer
//! would send it: errors are fine, panics and runaway allocations are not.
#![no_main]

use holodeck_protocol::wire::{decode_frame, encode_frame};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut at = 0;
    while let Ok(Some((frame, used))) = decode_frame(&data[at..]) {
        // What decodes must encode again to the same bytes.
        let mut out = Vec::new();
        if encode_frame(&frame, &mut out).is_ok() {
            assert_eq!(decode_frame(&out).ok().flatten().map(|(f, _)| f), Some(frame));
        }
        at += used;
    }
});
