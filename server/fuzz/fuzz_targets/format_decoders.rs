//! Every decoder of holodeck file parts, fed arbitrary bytes: none may panic.
#![no_main]

use holodeck_server::settings::Settings;
use holodeck_server::storage::format;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = format::decode_prefix(data);
    let _ = format::decode_slot(data, 64);
    if let Ok(text) = format::decode_text(data) {
        let _ = Settings::from_text(&text);
    }
    let _ = Settings::from_text(&String::from_utf8_lossy(data));
    let _ = Settings::from_toml(&String::from_utf8_lossy(data));
    let sections = data.first().map_or(1, |b| usize::from(b % 4));
    let _ = format::decode_root(data, 0, 1, sections);
    let beams = data.get(1).map_or(30, |b| u32::from(*b) * 7);
    let _ = format::decode_directory(data, 0, 0, beams, 192, 1 << 30);
});
