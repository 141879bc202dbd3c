//! Arbitrary bytes read as a Radiance holodeck: the header, the section chain
//! and every beam. Errors are fine, panics and runaway allocations are not.
#![no_main]

use holodeck_server::radiance::RadianceFile;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(file) = RadianceFile::parse(data) else { return };
    let _ = file.header.variables();
    for (s, section) in file.sections.iter().enumerate() {
        for number in 1..=section.beams.len() as u64 {
            let rays = file.read_beam(data, s, number).expect("a parsed beam lies in the file");
            assert_eq!(rays.len() as u64, u64::from(section.beams[(number - 1) as usize].0));
        }
    }
});
