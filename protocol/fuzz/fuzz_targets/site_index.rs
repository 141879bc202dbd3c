//! Arbitrary bytes read as a static site's index (`holodeck.idx`), as a
//! page would fetch a hostile one: errors are fine, panics and runaway
//! allocations are not.
#![no_main]

use holodeck_protocol::site::SiteIndex;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(index) = SiteIndex::decode(data) {
        // What decodes encodes again to an index that decodes the same.
        let again = index.encode().expect("a decoded index encodes");
        assert_eq!(SiteIndex::decode(&again).ok(), Some(index));
    }
});
