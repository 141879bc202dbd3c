//! A replayed site's fetches: the beams a view wants, as byte ranges of the
//! site's chunk files (see [`holodeck_protocol::site`]). Beams that lie
//! close together in one chunk share a range (the bytes between them are
//! fetched and skipped), so a view costs a few requests, not one per beam.

use holodeck_protocol::site::{SiteBeam, SiteIndex};
use holodeck_protocol::BeamKey;

/// Bytes between two beams below which they share a range.
pub const GAP: u64 = 64 << 10;

/// Longest range asked for at once.
pub const MOST: u64 = 4 << 20;

/// One byte range to fetch, and the beams in it.
#[derive(Clone, Debug, PartialEq)]
pub struct Fetch {
    /// The chunk file.
    pub chunk: u32,
    /// First byte.
    pub start: u64,
    /// Past the last byte.
    pub end: u64,
    /// The beams it holds, in order.
    pub beams: Vec<SiteBeam>,
    /// The last range of its view's transfer.
    pub closes_transfer: bool,
    /// Its beams are the neighbours of a view's beams, fetched for the
    /// pixels the view's own left without a ray: only those take its rays
    /// ([`holodeck_display::gaps`]).
    pub gaps: bool,
}

/// The ranges that hold `keys` (sorted; keys without rays are skipped), in
/// the index's order; the last one closes the transfer.
pub fn plan(index: &SiteIndex, keys: &[BeamKey]) -> Vec<Fetch> {
    let mut out: Vec<Fetch> = Vec::new();
    for b in keys.iter().filter_map(|k| index.beam(*k)) {
        let start = u64::from(b.offset);
        match out.last_mut() {
            Some(f) if f.chunk == b.chunk && start >= f.end && start - f.end <= GAP && b.end() - f.start <= MOST => {
                f.end = b.end();
                f.beams.push(*b);
            }
            _ => out.push(Fetch {
                chunk: b.chunk,
                start,
                end: b.end(),
                beams: vec![*b],
                closes_transfer: false,
                gaps: false,
            }),
        }
    }
    if let Some(last) = out.last_mut() {
        last.closes_transfer = true;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use holodeck_protocol::site::SiteHeader;

    fn row(beam: u32, chunk: u32, offset: u32, rays: u32) -> SiteBeam {
        SiteBeam {
            key: BeamKey::new(0, beam),
            chunk,
            offset,
            rays,
        }
    }

    #[test]
    fn near_beams_share_a_range_and_far_ones_do_not() {
        let index = SiteIndex {
            header: SiteHeader {
                sections: Vec::new(),
                chunks: vec![1 << 30, 1 << 30],
            },
            beams: vec![
                row(1, 0, 0, 10),
                row(2, 0, 100, 10),
                row(3, 0, 200_000, 10),
                row(4, 1, 0, 10),
            ],
        };
        let keys: Vec<BeamKey> = [1, 2, 3, 4, 9].iter().map(|&b| BeamKey::new(0, b)).collect();
        let p = plan(&index, &keys);
        let ranges: Vec<(u32, u64, u64, usize, bool)> = p
            .iter()
            .map(|f| (f.chunk, f.start, f.end, f.beams.len(), f.closes_transfer))
            .collect();
        assert_eq!(
            ranges,
            [
                (0, 0, 200, 2, false),
                (0, 200_000, 200_100, 1, false),
                (1, 0, 100, 1, true)
            ]
        );
        assert!(plan(&index, &[BeamKey::new(0, 9)]).is_empty());
    }
}
