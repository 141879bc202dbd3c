//! Arbitrary text as a file of views (a user's or a script's): errors name a
//! line, nothing panics, and every view that parses is one the projection
//! code can take (finite, non-degenerate).
#![no_main]

use holodeck_protocol::View;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    match View::parse_list(text) {
        Ok(views) => {
            for v in views {
                assert!(v.position.is_finite() && v.direction.is_finite());
                let _ = v.ray(0.5, 0.5);
                let _ = v.project(v.position + v.direction);
            }
        }
        Err((line, _)) => assert!(line >= 1 && line <= text.lines().count().max(1)),
    }
});
