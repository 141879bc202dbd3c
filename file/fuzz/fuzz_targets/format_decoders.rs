//! Every decoder of holodeck file parts, fed arbitrary bytes: none may panic.
#![no_main]

use holodeck_file::settings::Settings;
use holodeck_file::storage::format;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = format::decode_prefix(data, 0);
    let _ = format::decode_slot(data, 64);
    if let Ok(text) = format::decode_text(data, 192) {
        let _ = Settings::from_text(&text);
    }
    let _ = Settings::from_text(&String::from_utf8_lossy(data));
    let _ = Settings::from_toml(&String::from_utf8_lossy(data));
    let beams: Vec<u32> = data.iter().take(3).map(|b| u32::from(*b) * 7 + 1).collect();
    let _ = format::decode_root(data, 0, 1, &beams);
    let first = data.get(3).map_or(0, |b| u32::from(*b) * 100);
    let count = data.get(1).map_or(30, |b| u32::from(*b) * 7);
    let _ = format::decode_directory(data, 0, 0, first, count, 8192);
});
