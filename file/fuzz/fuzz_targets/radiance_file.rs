//! Arbitrary bytes read as a Radiance holodeck: the header, the section chain
//! and every beam, strictly and with loss accepted (what cannot be read left
//! out). Errors are fine, panics and runaway allocations are not, and every
//! beam either reading keeps lies in the file.
#![no_main]

use holodeck_file::radiance::RadianceFile;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let strict = RadianceFile::parse(data).ok();
    let Ok(salvaged) = RadianceFile::parse_salvaging(data, true) else {
        assert!(strict.is_none(), "what parses strictly also parses with loss accepted");
        return;
    };
    if let Some(file) = &strict {
        assert!(salvaged.lost.is_empty(), "a file that parses whole loses nothing");
        assert_eq!(file.rays(), salvaged.rays());
    }
    let _ = salvaged.header.variables();
    for (s, section) in salvaged.sections.iter().enumerate() {
        for number in 1..=section.beams.len() as u64 {
            let rays = salvaged.read_beam(data, s, number).expect("a kept beam lies in the file");
            assert_eq!(rays.len() as u64, u64::from(section.beams[(number - 1) as usize].0));
        }
    }
});
