//! Serving one sampler: keep its queue filled to what it traces within the
//! target latency (measured, per sampler), store what comes back, and pass
//! new rays on to the displays that asked for them.
//!
//! The queue is topped up as results arrive rather than refilled when empty,
//! so the worker never idles for a round trip; and its length follows the
//! worker's own measured speed, so a slow worker holds little work hostage
//! and a fast one never starves.

use std::time::{Duration, Instant};

use holodeck_protocol::wire::{Frame, Message, TracePacket, MAX_PACKET_RAYS};
use holodeck_protocol::BeamKey;
use rustc_hash::FxHashMap;
use tokio::sync::mpsc;

use super::connection::{Connection, ConnectionError};
use super::state::Shared;
use crate::schedule::Work;

/// Most rays queued to one sampler, however fast it claims to be.
const MAX_QUEUE: u64 = 1 << 18;
/// Fewest rays queued (so the measurement has something to measure).
const MIN_QUEUE: u64 = 16;

/// How long a killed sampler has to hang up after being told why.
const KILL_GRACE: Duration = Duration::from_secs(5);

/// A batch that cannot be written within this long ends the connection.
const WRITE_TIMEOUT: Duration = Duration::from_secs(30);

/// A sampler's measured speed.
#[derive(Debug)]
pub(super) struct Meter {
    /// Rays per second, smoothed.
    rate: Option<f64>,
    window_start: Option<Instant>,
    window_rays: u64,
}

impl Meter {
    pub fn new() -> Meter {
        Meter {
            rate: None,
            window_start: None,
            window_rays: 0,
        }
    }

    /// The worker got work while it had none: it is busy from now on.
    pub fn started(&mut self, now: Instant) {
        if self.window_start.is_none() {
            self.window_start = Some(now);
            self.window_rays = 0;
        }
    }

    /// `rays` came back; `idle` says whether the worker now has nothing left.
    pub fn finished(&mut self, rays: u64, now: Instant, idle: bool) {
        self.window_rays += rays;
        let Some(start) = self.window_start else { return };
        let elapsed = now.duration_since(start).as_secs_f64();
        // Results come in bursts; average over at least 50 ms of work.
        if elapsed >= 0.05 || (idle && elapsed > 0.0) {
            let sample = self.window_rays as f64 / elapsed.max(1e-6);
            self.rate = Some(match self.rate {
                Some(r) => 0.5 * r + 0.5 * sample,
                None => sample,
            });
            self.window_rays = 0;
            self.window_start = (!idle).then_some(now);
        }
        if idle {
            self.window_start = None;
        }
    }

    /// Rays to keep queued so the queue drains within `latency`.
    pub fn queue(&self, latency: Duration, initial: u64) -> u64 {
        match self.rate {
            Some(r) => ((r * latency.as_secs_f64()) as u64).clamp(MIN_QUEUE, MAX_QUEUE),
            None => initial.clamp(MIN_QUEUE, MAX_QUEUE),
        }
    }

    /// Rays per second, once known.
    pub fn rate(&self) -> Option<f64> {
        self.rate
    }
}

/// Serves one sampler until it leaves, stalls, is killed by an admin, or
/// the server stops: hands it work as its measured rate allows, stores what
/// it traces, and gives back to the schedule whatever it still had.
pub(super) async fn serve_sampler(conn: Connection, shared: &Shared) -> Result<(), ConnectionError> {
    let (mut reader, mut writer) = conn.split();
    // The writer runs on its own task: while a big batch goes out the
    // sampler's results keep being read, so neither side can block the other
    // with full socket buffers. One batch waits at most.
    let (batches, mut to_write) = mpsc::channel::<Vec<Frame>>(1);
    let mut writing = tokio::spawn(async move {
        while let Some(frames) = to_write.recv().await {
            match tokio::time::timeout(WRITE_TIMEOUT, writer.write_all(&frames)).await {
                Ok(Ok(())) => {}
                // Dropping the receiver tells the reader the sampler is gone.
                _ => return,
            }
        }
    });
    // A stopped process or a half-open connection must not hold beams.
    let stall = shared.config.stall.max(shared.config.latency * 4);
    let mut stop = shared.shutdown.subscribe();
    let mut kill = shared.kill_samplers.subscribe();
    let mut work = Outstanding::new();
    // Timers made once: a sampler sends a frame per packet, and a timer per
    // frame would cost more than the frame.
    let mut idle = tokio::time::interval(Duration::from_millis(250));
    let mut watchdog = tokio::time::interval(Duration::from_secs(1));
    let mut killed = false;
    let result = loop {
        if *stop.borrow() {
            break Ok(());
        }
        // Registered before asking, so a wake-up between the two is not lost.
        let woken = shared.work.notified();
        tokio::pin!(woken);
        woken.as_mut().enable();
        if let Err(e) = work.hand_out(shared, &batches) {
            break Err(e);
        }
        let mut frame = tokio::select! {
            f = reader.read() => f,
            _ = &mut woken, if work.pending.is_empty() => continue,
            // Nothing to do (paused, or the file is full): look again now and then.
            _ = idle.tick(), if work.pending.is_empty() || batches.capacity() == 0 => continue,
            _ = watchdog.tick(), if !work.pending.is_empty() => {
                if work.progress.elapsed() > stall {
                    break Err(ConnectionError::Stalled(format!("no results for {stall:?} with work outstanding")));
                }
                continue;
            }
            _ = stop.changed() => Ok(None),
            _ = kill.changed() => {
                killed = true;
                Ok(None)
            }
        };
        // That frame and every one that came with it, before looking for more work.
        let end = loop {
            match frame {
                Ok(Some(f)) => work.take(&batches, f),
                Ok(None) => break Some(Ok(())),
                Err(e) => break Some(Err(e)),
            }
            frame = match reader.buffered() {
                Ok(Some(f)) => Ok(Some(f)),
                Ok(None) => break None,
                Err(e) => Err(e),
            };
        };
        work.store(shared).await;
        if let Some(end) = end {
            break end;
        }
    };
    if killed {
        // Tell it why, so that it waits to be let in again rather than ends
        // (a server that quits just closes the connection).
        let reason = "samplers were stopped by an admin; a restart command lets them in again".to_string();
        let notice = vec![Frame::Message(Message::Refused { reason, retry: true })];
        let _ = tokio::time::timeout(Duration::from_secs(1), batches.send(notice)).await;
        drop(batches);
        let _ = tokio::time::timeout(Duration::from_secs(1), &mut writing).await;
        // Closing with its results unread would reset the connection and
        // could lose the notice: read (and drop) them until it hangs up.
        let _ = tokio::time::timeout(KILL_GRACE, async { while let Ok(Some(_)) = reader.read().await {} }).await;
    }
    writing.abort();
    work.give_back(shared);
    result
}

/// The work a sampler holds: packets sent and not yet finished.
struct Outstanding {
    /// By packet id (ids are a counter: no hash flooding to fear).
    pending: FxHashMap<u64, Work>,
    /// Rays in `pending`.
    rays: u64,
    /// The sampler's rate, measured.
    meter: Meter,
    /// When it last made progress (or was given work with none out).
    progress: Instant,
    /// Finished packets to store, with their rays.
    done: Vec<(Work, Vec<holodeck_protocol::RayRecord>)>,
    /// Rays in `done` not yet reported to the meter.
    returned: u64,
}

impl Outstanding {
    fn new() -> Outstanding {
        Outstanding {
            pending: FxHashMap::default(),
            rays: 0,
            meter: Meter::new(),
            progress: Instant::now(),
            done: Vec::new(),
            returned: 0,
        }
    }

    /// Tops the sampler's queue up to what its rate covers in the target
    /// latency, once half of it is done, unless the file refuses rays or the
    /// last batch is still going out.
    fn hand_out(&mut self, shared: &Shared, batches: &mpsc::Sender<Vec<Frame>>) -> Result<(), ConnectionError> {
        let target = self
            .meter
            .queue(shared.config.latency, u64::from(shared.config.initial_queue));
        if self.rays > target / 2 || shared.store.refusing() {
            return Ok(());
        }
        let slot = match batches.try_reserve() {
            Ok(slot) => slot,
            Err(mpsc::error::TrySendError::Closed(())) => {
                return Err(ConnectionError::Stalled("the sampler stopped taking work".into()));
            }
            // The last batch is still going out: top up once it has.
            Err(mpsc::error::TrySendError::Full(())) => return Ok(()),
        };
        let work = shared.lock_scheduler().next(
            target - self.rays,
            shared.config.request_packet.min(MAX_PACKET_RAYS),
            shared.config.packet.min(MAX_PACKET_RAYS),
        );
        if work.is_empty() {
            return Ok(());
        }
        if self.pending.is_empty() {
            self.progress = Instant::now();
        }
        let mut frames = Vec::with_capacity(work.len());
        for w in work {
            let id = shared.id();
            self.rays += u64::from(w.rays);
            self.pending.insert(id, w);
            frames.push(Frame::Message(Message::Trace(TracePacket {
                id,
                key: w.key,
                rays: w.rays,
                mode: w.mode,
            })));
        }
        self.meter.started(Instant::now());
        slot.send(frames);
        Ok(())
    }

    /// Takes one frame from the sampler: a finished packet that matches one
    /// sent is set aside to be stored (with the frames that came with it, by
    /// [`Outstanding::store`]); anything else is answered with an error.
    fn take(&mut self, batches: &mpsc::Sender<Vec<Frame>>, frame: Frame) {
        let message = match frame {
            Frame::Finished { id, key, records } => match self.pending.get(&id) {
                Some(w) if w.key == key && records.len() == w.rays as usize => {
                    let w = *w;
                    self.pending.remove(&id);
                    self.rays -= u64::from(w.rays);
                    self.returned += u64::from(w.rays);
                    self.done.push((w, records));
                    return;
                }
                _ => format!("packet {id} does not match any packet sent to you"),
            },
            _ => "samplers send finished packets only".to_string(),
        };
        let _ = batches.try_send(vec![Frame::Message(Message::Error { message })]);
    }

    /// Stores the finished packets set aside, in the order they came: their
    /// rays in one request to the file's thread, the schedule told under one
    /// lock, and the displays that want their beams woken.
    async fn store(&mut self, shared: &Shared) {
        if self.done.is_empty() {
            return;
        }
        // One reading of the clock for every frame that came together.
        self.progress = Instant::now();
        self.meter.finished(
            std::mem::take(&mut self.returned),
            self.progress,
            self.pending.is_empty(),
        );
        let done = std::mem::take(&mut self.done);
        let finished: Vec<Work> = done.iter().map(|(w, _)| *w).collect();
        shared
            .store
            .append_many(done.into_iter().map(|(w, records)| (w.key, records)).collect())
            .await;
        let woken: Vec<(BeamKey, Vec<u64>)> = {
            let mut scheduler = shared.lock_scheduler();
            finished
                .iter()
                .map(|w| (w.key, scheduler.finished(w.key, w.rays, w.source)))
                .collect()
        };
        for (key, displays) in woken {
            forward(shared, key, &displays);
        }
    }

    /// Whatever the sampler still had is traced again by someone else.
    fn give_back(&self, shared: &Shared) {
        let mut scheduler = shared.lock_scheduler();
        for w in self.pending.values() {
            scheduler.give_back(w.key, w.rays, w.source);
        }
        drop(scheduler);
        if let Some(r) = self.meter.rate() {
            let queue = self
                .meter
                .queue(shared.config.latency, u64::from(shared.config.initial_queue));
            // `holodeck bench scale` reads the queue.
            tracing::debug!("a sampler left after tracing at {r:.0} rays/s (queue {queue} rays)");
        }
    }
}

/// Tells the displays that want `key` that it has new rays.
fn forward(shared: &Shared, key: BeamKey, displays: &[u64]) {
    if displays.is_empty() {
        return;
    }
    let links = shared.lock_displays();
    for id in displays {
        if let Some(link) = links.get(id) {
            link.mark(key);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_queue_follows_the_measured_speed() {
        let mut m = Meter::new();
        let t0 = Instant::now();
        assert_eq!(m.queue(Duration::from_millis(250), 256), 256);
        m.started(t0);
        m.finished(10_000, t0 + Duration::from_millis(100), true);
        // 100k rays/s: a quarter second is 25k rays.
        assert_eq!(m.queue(Duration::from_millis(250), 256), 25_000);
        m.started(t0 + Duration::from_secs(1));
        m.finished(1_000, t0 + Duration::from_secs(2), true);
        // Smoothed halfway to 1k rays/s.
        let q = m.queue(Duration::from_millis(250), 256);
        assert_eq!(q, ((0.5 * 100_000.0 + 0.5 * 1_000.0) * 0.25) as u64);
        // Idle time between bursts does not count against the worker.
        let mut m = Meter::new();
        m.started(t0);
        m.finished(500, t0 + Duration::from_millis(10), true);
        m.started(t0 + Duration::from_secs(5));
        m.finished(500, t0 + Duration::from_secs(5) + Duration::from_millis(10), true);
        assert_eq!(m.rate().map(|r| r.round()), Some(50_000.0));
    }
}
