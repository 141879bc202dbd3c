//! The state every connection task shares (mini-redis's `db.rs`): the
//! scheduler, the storage handle, the connected displays' mailboxes, and the
//! control commands that change them. No socket in sight: the tasks in
//! [`super::service`], [`super::display`] and [`super::sampler`] hold a
//! `&Shared`, and this module imports none of them.

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::Arc;

use holodeck_protocol::wire::{Control, Progress};
use holodeck_protocol::{BeamKey, Section};
use tokio::sync::{watch, Notify};

use super::config::{Fill, ServerConfig};
use super::file_thread::FileThread;
use crate::schedule::{BatchSchedule, Scheduler};
use holodeck_file::storage::StorageError;

/// A display's mailbox: beams with new rays, and a wake-up.
#[derive(Default)]
pub(super) struct DisplayLink {
    dirty: std::sync::Mutex<HashSet<BeamKey>>,
    pub wake: Notify,
}

impl DisplayLink {
    /// Notes that `key` has new rays.
    pub fn mark(&self, key: BeamKey) {
        self.dirty.lock().unwrap_or_else(|p| p.into_inner()).insert(key);
        self.wake.notify_one();
    }

    /// The beams marked since the last take.
    pub fn take(&self) -> HashSet<BeamKey> {
        std::mem::take(&mut *self.dirty.lock().unwrap_or_else(|p| p.into_inner()))
    }
}

/// State every connection task shares.
pub(super) struct Shared {
    pub config: ServerConfig,
    pub obstructions: bool,
    /// The file's VDISTANCE setting, which samplers must obey.
    pub vdistance: bool,
    /// The scene samplers must prove they have (an admin may adopt another).
    pub scene: std::sync::Mutex<Option<String>>,
    pub sections: Vec<Section>,
    pub scheduler: std::sync::Mutex<Scheduler>,
    pub store: FileThread,
    pub next_id: AtomicU64,
    /// Wakes samplers waiting for work (new requests, resume, restart).
    pub work: Notify,
    /// Connected displays, by id, for forwarding new rays.
    pub displays: std::sync::Mutex<HashMap<u64, Arc<DisplayLink>>>,
    /// Bumped to disconnect every sampler.
    pub kill_samplers: watch::Sender<u64>,
    /// False after KillSamplers until Restart: samplers are refused.
    pub samplers_allowed: AtomicBool,
    /// Bumped by Clobber: displays then count their beams from the start.
    pub generation: AtomicU64,
    pub shutdown: watch::Sender<bool>,
    /// Samplers connected now.
    pub samplers: AtomicU32,
    /// Displays connected now (admin connections not counted).
    pub display_count: AtomicU32,
    /// The latest report, renewed about once a second; displays send each
    /// new one on.
    pub progress: watch::Sender<Progress>,
}

/// Counts a connection in `counter` while it lives (however its task ends).
pub(super) struct Counted<'a>(&'a AtomicU32);

impl<'a> Counted<'a> {
    /// Counts one more.
    pub fn new(counter: &'a AtomicU32) -> Counted<'a> {
        counter.fetch_add(1, Ordering::SeqCst);
        Counted(counter)
    }
}

impl Drop for Counted<'_> {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

impl Shared {
    pub fn lock_scheduler(&self) -> std::sync::MutexGuard<'_, Scheduler> {
        // A panic while holding the lock leaves consistent-enough counts: keep serving.
        self.scheduler.lock().unwrap_or_else(|p| p.into_inner())
    }

    pub fn lock_displays(&self) -> std::sync::MutexGuard<'_, HashMap<u64, Arc<DisplayLink>>> {
        self.displays.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// A report of the file and the connections now; `rate` (the reports
    /// before) gives the rays' rate over the last few seconds.
    pub async fn progress_now(&self, rate: &mut super::rate::RateWindow) -> Progress {
        let summary = self.store.summary().await;
        let rays = summary.as_ref().map_or(0, |s| s.rays());
        let rays_per_second = rate.push(rays, std::time::Instant::now());
        let (beams_filled, beams) = summary.as_ref().map_or((0, 0), |s| {
            s.sections
                .iter()
                .fold((0, 0), |(f, b), x| (f + u64::from(x.1), b + u64::from(x.0)))
        });
        Progress {
            rays,
            rays_per_second,
            file_bytes: summary.map_or(0, |s| s.file_bytes),
            beams_filled,
            beams,
            samplers: self.samplers.load(Ordering::SeqCst),
            displays: self.display_count.load(Ordering::SeqCst),
            paused: self.lock_scheduler().paused(),
        }
    }

    /// `report` with the connections and the pause as they are now.
    pub fn progress_now_counts(&self, report: Progress) -> Progress {
        Progress {
            samplers: self.samplers.load(Ordering::SeqCst),
            displays: self.display_count.load(Ordering::SeqCst),
            paused: self.lock_scheduler().paused(),
            ..report
        }
    }

    pub fn id(&self) -> u64 {
        self.next_id.fetch_add(1, Ordering::Relaxed)
    }

    /// The batch list for the configured fill, from the rays stored now.
    pub fn batch(&self, lens: &[Vec<u64>]) -> Result<Option<BatchSchedule>, holodeck_protocol::SectionError> {
        let stored = |k: BeamKey| {
            lens.get(k.section as usize)
                .and_then(|s| s.get(k.beam as usize))
                .copied()
                .unwrap_or(0)
        };
        Ok(match &self.config.fill {
            Fill::All => Some(BatchSchedule::new(&self.sections, stored)?),
            Fill::Views(seen) => Some(BatchSchedule::for_views(&self.sections, seen, stored)),
            Fill::Off => None,
        })
    }

    /// The scene samplers must prove they have, if the file records one.
    pub fn scene(&self) -> Option<String> {
        self.scene.lock().unwrap_or_else(|p| p.into_inner()).clone()
    }

    /// Starts the batch list afresh from what the file holds now.
    async fn restart_schedule(&self, forget: bool) -> Result<(), ControlError> {
        let lens = self.store.lens().await?;
        let batch = self.batch(&lens)?;
        let mut scheduler = self.lock_scheduler();
        scheduler.restart(batch);
        if forget {
            scheduler.requests().forget_stored();
        }
        Ok(())
    }

    /// Carries out a control command (the caller checked it is allowed).
    pub async fn control(&self, c: &Control) -> Result<(), ControlError> {
        match c {
            Control::Pause => self.lock_scheduler().set_paused(true),
            Control::Resume => {
                self.lock_scheduler().set_paused(false);
                self.work.notify_waiters();
            }
            Control::KillSamplers => {
                self.samplers_allowed.store(false, Ordering::SeqCst);
                self.kill_samplers.send_modify(|n| *n += 1);
            }
            Control::Restart => {
                self.restart_schedule(false).await?;
                self.samplers_allowed.store(true, Ordering::SeqCst);
                self.work.notify_waiters();
            }
            Control::Clobber => {
                self.store.clobber().await?;
                self.generation.fetch_add(1, Ordering::SeqCst);
                self.restart_schedule(true).await?;
                self.work.notify_waiters();
            }
            Control::Adopt { scene, keep } => {
                // No sampler of the old scene may add to the file from here on.
                self.samplers_allowed.store(false, Ordering::SeqCst);
                self.kill_samplers.send_modify(|n| *n += 1);
                self.store.adopt(scene.clone(), *keep).await?;
                if !keep {
                    self.generation.fetch_add(1, Ordering::SeqCst);
                }
                *self.scene.lock().unwrap_or_else(|p| p.into_inner()) = Some(scene.clone());
                self.restart_schedule(!keep).await?;
                self.samplers_allowed.store(true, Ordering::SeqCst);
                self.work.notify_waiters();
            }
            Control::Quit => {
                let _ = self.shutdown.send(true);
            }
        }
        tracing::info!("control: {c:?}");
        Ok(())
    }
}

/// Why a control command could not be carried out.
#[derive(Debug, thiserror::Error)]
pub enum ControlError {
    /// The file could not be read or written.
    #[error(transparent)]
    Storage(#[from] StorageError),
    /// A new schedule could not be made from the file's sections.
    #[error(transparent)]
    Schedule(#[from] holodeck_protocol::SectionError),
}
