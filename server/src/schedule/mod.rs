//! What samplers trace next. Displays' requests come first, shared fairly
//! between the displays that wait and neediest first (computed / desired)
//! within each display's request; when no display wants anything, the batch list keeps
//! the workers busy filling the holodeck by beam volume (or for given views),
//! so an interactive session also leaves a more useful file behind. Pure
//! scheduling; no I/O.

mod batch;
mod requests;

pub use batch::BatchSchedule;
pub use requests::{DisplayId, RequestList, RequestPacket, Share};

use holodeck_protocol::wire::SamplingMode;
use holodeck_protocol::BeamKey;

/// Where a packet came from, so that its rays are accounted in the right list.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// A display asked for the beam.
    Request,
    /// The batch fill.
    Batch,
}

/// Work handed to a sampler.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Work {
    /// The beam.
    pub key: BeamKey,
    /// Rays to trace.
    pub rays: u32,
    /// How to choose them.
    pub mode: SamplingMode,
    /// Which list it came from.
    pub source: Source,
}

/// The server's scheduler: display requests over the batch list.
pub struct Scheduler {
    batch: Option<BatchSchedule>,
    requests: RequestList,
    paused: bool,
    /// Counts finished packets; with `finished_at`, tells a display which of
    /// its beams got rays while it was reading them.
    epoch: u64,
    finished_at: std::collections::HashMap<BeamKey, u64>,
    /// Displays between [`Scheduler::watch`] and [`Scheduler::landed_since`]:
    /// only then is `finished_at` kept (it costs a map insert per packet).
    watchers: usize,
}

impl Scheduler {
    /// A scheduler that fills by `batch` when displays want nothing (`None`:
    /// samplers idle then).
    pub fn new(batch: Option<BatchSchedule>) -> Scheduler {
        Scheduler {
            batch,
            requests: RequestList::new(),
            paused: false,
            epoch: 0,
            finished_at: std::collections::HashMap::new(),
            watchers: 0,
        }
    }

    /// A display starts reading beams: returns the epoch to pass to
    /// [`Scheduler::landed_since`], which it must call afterwards.
    pub fn watch(&mut self) -> u64 {
        self.watchers += 1;
        self.epoch
    }

    /// Which of `keys` got rays after `epoch` (from [`Scheduler::watch`]);
    /// ends the watch.
    pub fn landed_since(&mut self, keys: &[BeamKey], epoch: u64) -> Vec<BeamKey> {
        let landed = keys
            .iter()
            .copied()
            .filter(|k| self.finished_at.get(k).is_some_and(|&e| e > epoch))
            .collect();
        self.watchers = self.watchers.saturating_sub(1);
        if self.watchers == 0 {
            self.finished_at.clear();
        }
        landed
    }

    /// Stops (or resumes) handing out work.
    pub fn set_paused(&mut self, paused: bool) {
        self.paused = paused;
    }

    /// True while paused.
    pub fn paused(&self) -> bool {
        self.paused
    }

    /// Up to `budget` rays of work: requested beams in packets of at most
    /// `request_packet` rays, then batch beams `batch_packet` rays each.
    pub fn next(&mut self, budget: u64, request_packet: u32, batch_packet: u32) -> Vec<Work> {
        if self.paused || budget == 0 {
            return Vec::new();
        }
        let mut out: Vec<Work> = self
            .requests
            .next(budget, request_packet)
            .into_iter()
            .map(|p| Work {
                key: p.key,
                rays: p.rays,
                mode: match p.eye {
                    Some(e) => SamplingMode::NearEye {
                        eye: e.position,
                        radius: e.radius,
                        frustum: e.frustum,
                    },
                    None => SamplingMode::Uniform,
                },
                source: Source::Request,
            })
            .collect();
        let used: u64 = out.iter().map(|w| u64::from(w.rays)).sum();
        if let Some(batch) = &mut self.batch {
            let batch_packet = batch_packet.max(1);
            let mut used = used;
            // Empty beams get single rays, so one pass may fall short of the budget.
            while used < budget {
                let count = (budget - used).div_ceil(u64::from(batch_packet)) as usize;
                let got = batch.next(count, batch_packet);
                if got.is_empty() {
                    break;
                }
                used += got.iter().map(|g| u64::from(g.1)).sum::<u64>();
                out.extend(got.into_iter().map(|(key, rays)| Work {
                    key,
                    rays,
                    mode: SamplingMode::Uniform,
                    source: Source::Batch,
                }));
            }
        }
        out
    }

    /// Rays came back; returns the displays that want them.
    pub fn finished(&mut self, key: BeamKey, rays: u32, source: Source) -> Vec<DisplayId> {
        self.epoch += 1;
        if self.watchers > 0 {
            self.finished_at.insert(key, self.epoch);
        }
        if source == Source::Request {
            if let Some(b) = &mut self.batch {
                b.credit(key, rays);
            }
        }
        self.requests.finished(key, rays, source == Source::Request)
    }

    /// Work that will never come back (its sampler left).
    pub fn give_back(&mut self, key: BeamKey, rays: u32, source: Source) {
        match source {
            Source::Request => self.requests.give_back(key, rays),
            Source::Batch => {
                if let Some(b) = &mut self.batch {
                    b.give_back(key, rays);
                }
            }
        }
    }

    /// The display request list.
    pub fn requests(&mut self) -> &mut RequestList {
        &mut self.requests
    }

    /// Starts the batch list afresh (the Restart command, and after a
    /// Clobber); displays' requests stay, so their refinement goes on.
    pub fn restart(&mut self, batch: Option<BatchSchedule>) {
        self.batch = batch;
    }
}

/// A small interior section for the schedulers' tests.
#[cfg(test)]
pub(crate) fn test_section() -> holodeck_protocol::Section {
    holodeck_protocol::Section::new(
        [0.0; 3],
        [[4.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 2.0]],
        [4, 3, 2],
        holodeck_protocol::SectionKind::Interior,
    )
    .unwrap()
}

#[cfg(test)]
mod tests {
    use super::*;
    use holodeck_protocol::wire::EyePoint;

    fn section() -> holodeck_protocol::Section {
        test_section()
    }

    #[test]
    fn requests_come_before_the_batch_fill_and_carry_the_eye() {
        let s = section();
        let batch = BatchSchedule::new(std::slice::from_ref(&s), |_| 0).unwrap();
        let mut sched = Scheduler::new(Some(batch));
        let eye = EyePoint {
            position: [1.0, 1.0, 1.0],
            radius: 0.05,
            frustum: None,
        };
        sched
            .requests()
            .request(7, &[(BeamKey::new(0, 11), 12, 0)], Some(eye), true);
        let work = sched.next(40, 8, 4);
        assert_eq!(work[0].key, BeamKey::new(0, 11));
        assert_eq!(work[0].rays, 8);
        assert_eq!(work[1].rays, 4);
        assert_eq!(work[2].rays, 1, "an empty beam gets a single ray first");
        assert!(matches!(work[0].mode, SamplingMode::NearEye { radius, .. } if radius == 0.05));
        assert_eq!(work[0].source, Source::Request);
        let total: u64 = work.iter().map(|w| u64::from(w.rays)).sum();
        assert_eq!(total, 40, "the rest of the budget goes to the batch fill");
        assert!(work[2..]
            .iter()
            .all(|w| w.source == Source::Batch && w.mode == SamplingMode::Uniform));
        assert_eq!(sched.finished(BeamKey::new(0, 11), 8, Source::Request), vec![7]);
        sched.set_paused(true);
        assert!(sched.next(40, 8, 4).is_empty());
    }

    #[test]
    fn a_display_learns_which_beams_got_rays_while_it_read_them() {
        let mut sched = Scheduler::new(None);
        let (a, b) = (BeamKey::new(0, 1), BeamKey::new(0, 2));
        sched.finished(a, 4, Source::Batch);
        let before = sched.watch();
        sched.finished(b, 4, Source::Batch);
        assert_eq!(sched.landed_since(&[a, b], before), vec![b]);
        // Nobody watching: nothing is kept.
        sched.finished(a, 4, Source::Batch);
        assert!(sched.finished_at.is_empty());
    }

    #[test]
    fn without_a_batch_list_samplers_idle_once_requests_are_met() {
        let mut sched = Scheduler::new(None);
        sched.requests().request(1, &[(BeamKey::new(0, 1), 3, 0)], None, true);
        assert_eq!(sched.next(100, 10, 4).len(), 1);
        assert!(sched.next(100, 10, 4).is_empty());
    }
}
