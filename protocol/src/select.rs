//! Beam selection (paper, 2.4.2): which beams a view sees, and how many
//! samples each should get so that the view refines uniformly.
//!
//! Jittered view rays at low density are intersected with every section the
//! eye may use; the beam each ray's line falls in gets a count. A line is
//! counted whether the section lies in front of the eye, behind it, or
//! around it: samples are traced along the view direction, so a beam behind
//! the eye still carries what the eye sees (as long as nothing stands
//! between), and with the eye inside an interior section most of the line is
//! behind it.
//!
//! An eye inside an interior section uses only the interior sections around
//! it: another section's rays start at that section's walls, and between
//! them and the eye may stand anything (the wall of the room the eye is in,
//! seen from a section outdoors), which its rays never met. An eye inside no
//! interior section looks into every section.
//!
//! Pure arithmetic, shared by displays (to request beams) and the server (to
//! limit a batch fill to what given views see).

use crate::beam::BeamKey;
use crate::section::{Section, SectionKind};
use crate::view::View;

/// Beams seen by a view, with the number of view rays that fell in each.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ViewBeams {
    /// (beam, view rays in it), sorted by beam.
    pub counts: Vec<(BeamKey, u32)>,
    /// View rays shot (inside the image; fisheye corners are not shot).
    pub rays: u32,
    /// View rays whose line crossed no section.
    pub missed: u32,
    /// For each beam of `counts`, the summed weight of its view rays when
    /// selected with [`ViewBeams::select_weighted`] (empty otherwise).
    pub weights: Vec<f64>,
}

/// The indices of the sections an eye at `eye` may use: the interior
/// sections around it, or every section when it is in none.
pub fn usable_sections(sections: &[Section], eye: glam::DVec3) -> Vec<usize> {
    let inside: Vec<usize> = (0..sections.len())
        .filter(|&i| sections[i].kind() == SectionKind::Interior && sections[i].contains(eye))
        .collect();
    if inside.is_empty() {
        (0..sections.len()).collect()
    } else {
        inside
    }
}

/// A small deterministic generator (SplitMix64): jitter must repeat for a
/// given view so that requests do not flicker between identical frames.
struct Jitter(u64);

impl Jitter {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

impl ViewBeams {
    /// Shoots `columns` x `rows` jittered view rays (one per cell of a grid
    /// over the image) and counts the beams of `sections` their lines fall in.
    pub fn select(sections: &[Section], view: &View, columns: u32, rows: u32, seed: u64) -> ViewBeams {
        let mut vb = ViewBeams::select_weighted(sections, view, columns, rows, seed, |_, _| 1.0);
        vb.weights.clear();
        vb
    }

    /// [`ViewBeams::select`] with each view ray weighted by `weight` at its
    /// image point (x, y): how much the pixels there need samples, so that
    /// beams over noisy pixels get more.
    pub fn select_weighted(
        sections: &[Section],
        view: &View,
        columns: u32,
        rows: u32,
        seed: u64,
        weight: impl Fn(f64, f64) -> f64,
    ) -> ViewBeams {
        let mut jitter = Jitter(seed ^ 0x5eed_f00d);
        let rays_of = view.rays();
        let around: Vec<usize> = usable_sections(sections, view.position);
        let mut hits: Vec<(BeamKey, f64)> = Vec::new();
        let (mut rays, mut missed) = (0u32, 0u32);
        for row in 0..rows {
            for col in 0..columns {
                let x = (f64::from(col) + jitter.next()) / f64::from(columns);
                let y = (f64::from(row) + jitter.next()) / f64::from(rows);
                let Some((origin, dir)) = rays_of.ray(x, y) else {
                    continue;
                };
                rays += 1;
                let before = hits.len();
                let w = weight(x, y);
                let w = if w.is_finite() && w > 0.0 { w } else { 0.0 };
                for &si in &around {
                    if let Some(at) = sections[si].locate(origin, dir) {
                        hits.push((BeamKey::new(si as u32, at.beam), w));
                    }
                }
                if hits.len() == before {
                    missed += 1;
                }
            }
        }
        hits.sort_unstable_by_key(|h| h.0);
        let mut counts: Vec<(BeamKey, u32)> = Vec::new();
        let mut weights: Vec<f64> = Vec::new();
        for (k, w) in hits {
            match counts.last_mut() {
                Some((last, n)) if *last == k => {
                    *n += 1;
                    if let Some(s) = weights.last_mut() {
                        *s += w;
                    }
                }
                _ => {
                    counts.push((k, 1));
                    weights.push(w);
                }
            }
        }
        ViewBeams {
            counts,
            rays,
            missed,
            weights,
        }
    }

    /// Desired samples per beam for `samples` samples over the whole view
    /// (typically the pixel count times a density): each beam gets its share
    /// of the view rays (or of their weights, when weighted), rounded up, so
    /// every beam seen gets at least one.
    pub fn desired(&self, samples: u64) -> Vec<(BeamKey, u32)> {
        let weighted = self.weights.len() == self.counts.len() && self.weights.iter().sum::<f64>() > 0.0;
        let total = if weighted {
            self.weights.iter().sum::<f64>() * f64::from(self.rays.max(1))
                / f64::from(self.counts.iter().map(|c| c.1).sum::<u32>().max(1))
        } else {
            f64::from(self.rays.max(1))
        };
        let per = samples as f64 / total;
        self.counts
            .iter()
            .enumerate()
            .map(|(i, &(k, n))| {
                let share = if weighted { self.weights[i] } else { f64::from(n) };
                (k, (share * per).ceil().clamp(1.0, f64::from(u32::MAX)) as u32)
            })
            .collect()
    }

    /// The number of beams seen.
    pub fn len(&self) -> usize {
        self.counts.len()
    }

    /// True when the view sees no beam.
    pub fn is_empty(&self) -> bool {
        self.counts.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::section::SectionKind;

    fn room() -> Section {
        Section::new(
            [0.0; 3],
            [[4.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 2.0]],
            [8, 6, 4],
            SectionKind::Interior,
        )
        .unwrap()
    }

    fn view(spec: &str) -> View {
        View::parse(spec).unwrap()
    }

    #[test]
    fn every_view_ray_inside_a_section_lands_in_the_beam_its_line_belongs_to() {
        let s = room();
        let v = view("-vtv -vp 2 1.5 1 -vd 1 0.3 0.1 -vu 0 0 1 -vh 60 -vv 45");
        let got = ViewBeams::select(std::slice::from_ref(&s), &v, 16, 12, 7);
        assert_eq!(got.rays, 16 * 12);
        assert_eq!(got.missed, 0, "an eye inside the section sees it everywhere");
        let total: u32 = got.counts.iter().map(|c| c.1).sum();
        assert_eq!(total, got.rays);
        // A parallel view a hair wide: every ray lies in the central ray's beam.
        let v = view("-vtl -vp 2 1.5 1 -vd 1 0.3 0.1 -vu 0 0 1 -vh 0.0001 -vv 0.0001");
        let (o, d) = v.ray(0.5, 0.5).unwrap();
        let central = s.locate(o, d).unwrap().beam;
        let got = ViewBeams::select(std::slice::from_ref(&s), &v, 4, 4, 7);
        assert_eq!(got.counts, vec![(BeamKey::new(0, central), 16)]);
    }

    #[test]
    fn an_eye_in_an_interior_section_uses_only_the_sections_around_it() {
        // The room, and a second interior section outdoors beyond its east wall.
        let outdoors = Section::new(
            [6.0, 0.0, 0.0],
            [[4.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 2.0]],
            [8, 6, 4],
            SectionKind::Interior,
        )
        .unwrap();
        let both = [room(), outdoors];
        let east = "-vd 1 0 0 -vu 0 0 1 -vh 40 -vv 30";
        let inside = ViewBeams::select(&both, &view(&format!("-vtv -vp 2 1.5 1 {east}")), 8, 6, 3);
        assert!(inside.counts.iter().all(|(k, _)| k.section == 0), "{:?}", inside.counts);
        let out = ViewBeams::select(&both, &view(&format!("-vtv -vp 8 1.5 1 {east}")), 8, 6, 3);
        assert!(out.counts.iter().all(|(k, _)| k.section == 1));
        // Between the two: in neither, so both are looked into.
        let between = ViewBeams::select(
            &both,
            &view("-vtv -vp 5 -3 1 -vd 0 1 0 -vu 0 0 1 -vh 170 -vv 60"),
            32,
            6,
            3,
        );
        assert!(
            between.counts.iter().any(|(k, _)| k.section == 0) && between.counts.iter().any(|(k, _)| k.section == 1)
        );
        assert_eq!(usable_sections(&both, glam::DVec3::new(2.0, 1.5, 1.0)), vec![0]);
        assert_eq!(usable_sections(&both, glam::DVec3::new(5.0, 9.0, 1.0)), vec![0, 1]);
    }

    #[test]
    fn sections_behind_the_eye_count_and_views_that_miss_count_as_missed() {
        let s = room();
        // Outside the room looking away from it: the lines still cross it behind the eye.
        let v = view("-vtv -vp 8 1.5 1 -vd 1 0 0 -vu 0 0 1 -vh 20 -vv 20");
        let got = ViewBeams::select(std::slice::from_ref(&s), &v, 4, 4, 1);
        assert_eq!(got.missed, 0);
        assert!(!got.is_empty());
        // Looking up from far away: no line crosses the room.
        let v = view("-vtv -vp 100 100 100 -vd 0 0 1 -vu 0 1 0 -vh 10 -vv 10");
        let got = ViewBeams::select(std::slice::from_ref(&s), &v, 4, 4, 1);
        assert_eq!((got.missed, got.len()), (16, 0));
        assert!(got.desired(1000).is_empty());
    }

    #[test]
    fn rays_along_a_wall_do_not_panic_and_two_sections_both_count() {
        let a = room();
        let b = Section::new(
            [4.0, 0.0, 0.0],
            [[4.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 2.0]],
            [8, 6, 4],
            SectionKind::Interior,
        )
        .unwrap();
        // The eye on the shared wall, looking along it.
        let v = view("-vtv -vp 4 0 1 -vd 0 1 0 -vu 0 0 1 -vh 1 -vv 1");
        let got = ViewBeams::select(&[a.clone(), b.clone()], &v, 8, 8, 3);
        assert_eq!(got.rays, 64);
        // On the shared wall the eye is in both, and looks into both.
        assert!(got.counts.iter().any(|c| c.0.section == 0) && got.counts.iter().any(|c| c.0.section == 1));
        // Looking along x from inside one: only its own section counts,
        // though every line crosses both.
        let v = view("-vtv -vp 1 1.5 1 -vd 1 0 0 -vu 0 0 1 -vh 10 -vv 10");
        let got = ViewBeams::select(&[a.clone(), b.clone()], &v, 8, 8, 3);
        let total: u32 = got.counts.iter().map(|c| c.1).sum();
        assert_eq!(total, 64);
        assert!(got.counts.iter().all(|c| c.0.section == 0));
        // From outside both, every line crosses both.
        let v = view("-vtv -vp -1 1.5 1 -vd 1 0 0 -vu 0 0 1 -vh 10 -vv 10");
        let got = ViewBeams::select(&[a, b], &v, 8, 8, 3);
        let total: u32 = got.counts.iter().map(|c| c.1).sum();
        assert_eq!(total, 128);
    }

    #[test]
    fn desired_counts_share_the_samples_by_view_rays() {
        let vb = ViewBeams {
            counts: vec![(BeamKey::new(0, 1), 3), (BeamKey::new(0, 2), 1)],
            rays: 4,
            missed: 0,
            weights: Vec::new(),
        };
        assert_eq!(
            vb.desired(400),
            vec![(BeamKey::new(0, 1), 300), (BeamKey::new(0, 2), 100)]
        );
        assert_eq!(vb.desired(1), vec![(BeamKey::new(0, 1), 1), (BeamKey::new(0, 2), 1)]);
    }

    #[test]
    fn weighted_selection_shares_the_samples_by_need() {
        let s = room();
        let v = view("-vtv -vp 2 1.5 1 -vd 1 0 0 -vu 0 0 1 -vh 60 -vv 45");
        let plain = ViewBeams::select(std::slice::from_ref(&s), &v, 32, 24, 5);
        // Even weights change nothing.
        let even = ViewBeams::select_weighted(std::slice::from_ref(&s), &v, 32, 24, 5, |_, _| 3.0);
        assert_eq!(even.counts, plain.counts);
        assert_eq!(even.desired(10_000), plain.desired(10_000));
        // The right half needs nine times more: its beams get about nine times the left's.
        let needy =
            ViewBeams::select_weighted(
                std::slice::from_ref(&s),
                &v,
                32,
                24,
                5,
                |x, _| if x > 0.5 { 9.0 } else { 1.0 },
            );
        let want = needy.desired(100_000);
        let total: u64 = want.iter().map(|w| u64::from(w.1)).sum();
        assert!((100_000..100_000 + want.len() as u64).contains(&total), "{total}");
        let right: u64 = want
            .iter()
            .zip(&needy.weights)
            .zip(&needy.counts)
            .filter(|((_, w), c)| **w >= 9.0 * f64::from(c.1) - 1e-9)
            .map(|((d, _), _)| u64::from(d.1))
            .sum();
        assert!(right as f64 > 0.85 * total as f64, "{right} of {total}");
        assert!(
            ViewBeams::select_weighted(std::slice::from_ref(&s), &v, 4, 3, 5, |_, _| f64::NAN)
                .desired(100)
                .iter()
                .all(|d| d.1 >= 1)
        );
    }

    #[test]
    fn selection_repeats_for_a_seed() {
        let s = room();
        let v = view("-vtv -vp 1 1 1 -vd 1 1 0 -vu 0 0 1 -vh 90 -vv 60");
        let a = ViewBeams::select(std::slice::from_ref(&s), &v, 32, 24, 9);
        let b = ViewBeams::select(std::slice::from_ref(&s), &v, 32, 24, 9);
        assert_eq!(a, b);
        let c = ViewBeams::select(std::slice::from_ref(&s), &v, 32, 24, 10);
        assert_ne!(a.counts, c.counts, "the jitter follows the seed");
    }
}
