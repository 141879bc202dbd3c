//! Accepting peers and serving them by role. Each connection is one task:
//! a handshake (protocol version, access token, scene hash), then
//! - samplers get work from the shared [`Scheduler`] and send back traced
//!   rays, which go to the storage thread and on to displays that want them
//!   ([`super::sampler`]);
//! - displays send beam requests and get the beams' rays streamed back, stored
//!   rays at once and new ones as they are traced ([`super::display`]);
//! - admins (and writable displays) send control commands.
//!
//! No task waits on another peer: a stalled display or sampler only slows
//! itself. Work a sampler never finished is given back to the schedule:
//! nothing is stored twice and nothing is lost.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use holodeck_protocol::wire::{Control, Frame, Hello, Message, Role, PROTOCOL_VERSION};
use holodeck_protocol::{BeamKey, Section};
use tokio::sync::{mpsc, watch, Notify};

use super::connection::{Connection, ConnectionError, Stream};
use super::display::DisplayLink;
use super::listener::Listener;
use super::store::Store;
use crate::schedule::{BatchSchedule, Scheduler, Share};
use crate::storage::{HoloFile, StorageError};

/// What a batch fill covers when no display wants anything.
#[derive(Clone, Debug, PartialEq)]
pub enum Fill {
    /// Every beam, by volume.
    All,
    /// Only beams some views see, weighted by the view rays in each.
    Views(Vec<(BeamKey, u32)>),
    /// Nothing: samplers trace only what displays request.
    Off,
}

/// How the server runs.
#[derive(Clone, Debug)]
pub struct ServerConfig {
    /// The token every peer must present.
    pub token: String,
    /// Rays per batch-fill packet (one beam each).
    pub packet: u32,
    /// Most rays in a packet for a display's request.
    pub request_packet: u32,
    /// Rays queued to a sampler before its speed is known.
    pub initial_queue: u32,
    /// Each sampler's queue is sized to drain within this long.
    pub latency: Duration,
    /// The batch fill.
    pub fill: Fill,
    /// Stop (flushing) after this long (the TIME setting).
    pub time: Option<Duration>,
    /// Print a progress line this often (the REPORT setting).
    pub report: Option<Duration>,
    /// Stop once the file refuses rays (DISKSPACE reached, or a write failed) and no display is connected.
    pub stop_when_full: bool,
    /// A sampler that returns nothing for this long while it holds work is
    /// dropped and its work given back.
    pub stall: Duration,
    /// How display requests divide the samplers' rays.
    pub share: Share,
}

impl ServerConfig {
    /// Defaults for a server with this token.
    pub fn new(token: String) -> ServerConfig {
        ServerConfig {
            token,
            packet: 4,
            request_packet: 32,
            initial_queue: 256,
            latency: Duration::from_millis(250),
            fill: Fill::All,
            time: None,
            report: None,
            stop_when_full: true,
            stall: Duration::from_secs(30),
            share: Share::Fair,
        }
    }
}

/// Why the server stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The file failed.
    #[error(transparent)]
    Storage(#[from] StorageError),
    /// The schedule could not be built.
    #[error("building the schedule: {0}")]
    Schedule(#[from] holodeck_protocol::SectionError),
    /// No listening socket was given.
    #[error("no socket to listen on")]
    NoListener,
}

/// State every connection task shares.
pub(super) struct Shared {
    pub config: ServerConfig,
    pub obstructions: bool,
    pub scene: Option<String>,
    pub sections: Vec<Section>,
    pub scheduler: std::sync::Mutex<Scheduler>,
    pub store: Store,
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
}

impl Shared {
    pub fn lock_scheduler(&self) -> std::sync::MutexGuard<'_, Scheduler> {
        // A panic while holding the lock leaves consistent-enough counts: keep serving.
        self.scheduler.lock().unwrap_or_else(|p| p.into_inner())
    }

    pub fn lock_displays(&self) -> std::sync::MutexGuard<'_, HashMap<u64, Arc<DisplayLink>>> {
        self.displays.lock().unwrap_or_else(|p| p.into_inner())
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

    /// Carries out a control command from a writable display or an admin.
    pub async fn control(&self, c: Control) -> Result<(), ControlError> {
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
                let lens = self.store.lens().await?;
                let batch = self.batch(&lens)?;
                self.lock_scheduler().restart(batch);
                self.samplers_allowed.store(true, Ordering::SeqCst);
                self.work.notify_waiters();
            }
            Control::Clobber => {
                self.store.clobber().await?;
                self.generation.fetch_add(1, Ordering::SeqCst);
                let lens = self.store.lens().await?;
                let batch = self.batch(&lens)?;
                let mut scheduler = self.lock_scheduler();
                scheduler.restart(batch);
                scheduler.requests().forget_stored();
                drop(scheduler);
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

/// Serves `file` on `listeners` until an admin says quit, TIME is up, or the
/// process gets SIGINT/SIGTERM; then flushes and closes the file.
pub async fn serve(listeners: Vec<Listener>, file: HoloFile, config: ServerConfig) -> Result<(), ServeError> {
    if listeners.is_empty() {
        return Err(ServeError::NoListener);
    }
    let sections = file.sections().to_vec();
    let scene = file.settings().scene.clone();
    let obstructions = file.settings().obstructions;
    let (store, thread) = Store::spawn(file);
    let (shutdown, mut stopped) = watch::channel(false);
    let shared = Arc::new(Shared {
        config,
        obstructions,
        scene,
        sections,
        scheduler: std::sync::Mutex::new(Scheduler::new(None)),
        store: store.clone(),
        next_id: AtomicU64::new(1),
        work: Notify::new(),
        displays: std::sync::Mutex::new(HashMap::new()),
        kill_samplers: watch::channel(0).0,
        samplers_allowed: AtomicBool::new(true),
        generation: AtomicU64::new(0),
        shutdown,
    });
    let lens = store.lens().await?;
    let batch = shared.batch(&lens)?;
    {
        let mut scheduler = shared.lock_scheduler();
        scheduler.restart(batch);
        scheduler.requests().set_share(shared.config.share);
    }
    let flusher = {
        let store = store.clone();
        tokio::spawn(async move {
            let mut tick = tokio::time::interval(Duration::from_secs(2));
            loop {
                tick.tick().await;
                match store.flush().await {
                    // Says what a crash can no longer take away (tests wait on it).
                    Ok(rays) => tracing::debug!("periodic flush: {rays} rays durable"),
                    Err(e) => tracing::error!("periodic flush: {e}"),
                }
            }
        })
    };
    let reporter = shared
        .config
        .report
        .map(|every| tokio::spawn(report(store.clone(), every)));
    let time_limit = shared.config.time;
    let deadline = async move {
        match time_limit {
            Some(t) => tokio::time::sleep(t).await,
            None => std::future::pending::<()>().await,
        }
    };
    tokio::pin!(deadline);
    // One accept loop per socket, all feeding one queue.
    let (peers_tx, mut peers) = mpsc::channel::<(Box<dyn Stream>, String)>(64);
    let mut acceptors = Vec::new();
    for l in listeners {
        let tx = peers_tx.clone();
        acceptors.push(tokio::spawn(async move {
            loop {
                match l.accept().await {
                    Ok(p) => {
                        if tx.send(p).await.is_err() {
                            return;
                        }
                    }
                    // Out of descriptors and the like: back off instead of spinning.
                    Err(e) => {
                        tracing::warn!("accepting on {}: {e}", l.address());
                        tokio::time::sleep(Duration::from_millis(100)).await;
                    }
                }
            }
        }));
    }
    drop(peers_tx);
    let mut full_check = tokio::time::interval(Duration::from_millis(200));
    let mut tasks = tokio::task::JoinSet::new();
    // Made once: a signal arriving between two turns of the loop is not lost.
    let interrupted = tokio::signal::ctrl_c();
    let terminated = terminate();
    tokio::pin!(interrupted, terminated);
    loop {
        tokio::select! {
            Some((stream, peer)) = peers.recv() => {
                let shared = Arc::clone(&shared);
                tasks.spawn(async move {
                    if let Err(e) = handle(stream, &shared).await {
                        tracing::warn!("{peer}: {e}");
                    }
                });
            }
            Some(_) = tasks.join_next(), if !tasks.is_empty() => {}
            _ = stopped.changed() => break,
            _ = &mut deadline => {
                tracing::info!("TIME is up");
                break;
            }
            _ = full_check.tick() => {
                if shared.config.stop_when_full && store.refusing() && shared.lock_displays().is_empty() {
                    let why = store.refusal().unwrap_or_else(|| "it refuses them".into());
                    tracing::warn!("no more rays can be stored ({why}): stopping");
                    break;
                }
            }
            _ = &mut interrupted => {
                tracing::info!("SIGINT: stopping");
                break;
            }
            _ = &mut terminated => {
                tracing::info!("SIGTERM: stopping");
                break;
            }
        }
    }
    // Tell every connection to stop, then end those that do not: packets they
    // had out are simply never stored.
    let _ = shared.shutdown.send(true);
    for a in &acceptors {
        a.abort();
    }
    tasks.shutdown().await;
    tracing::info!("shutting down: flushing the file");
    flusher.abort();
    if let Some(r) = reporter {
        r.abort();
    }
    let flushed = store.flush().await;
    drop(store);
    drop(shared);
    drop(acceptors);
    // The storage thread exits once every handle is gone; wait for it even
    // when the flush failed, so that closing does not race the exit.
    let closed = tokio::task::spawn_blocking(move || thread.join())
        .await
        .unwrap_or(Ok(()));
    let rays = flushed?;
    closed?;
    tracing::info!("flushed and closed: {rays} rays in the file");
    Ok(())
}

/// Prints a progress line every `every`: rays stored, the rate since the last
/// line, beams holding rays, the file size and its fragmentation.
async fn report(store: Store, every: Duration) {
    let mut tick = tokio::time::interval(every);
    tick.tick().await;
    let mut last: Option<(u64, std::time::Instant)> = None;
    loop {
        tick.tick().await;
        let Some(s) = store.summary().await else { return };
        let (rays, now) = (s.rays(), std::time::Instant::now());
        let rate = last.map_or(0.0, |(r, t)| {
            (rays.saturating_sub(r)) as f64 / now.duration_since(t).as_secs_f64()
        });
        let (filled, beams): (u64, u64) = s
            .sections
            .iter()
            .fold((0, 0), |(f, b), x| (f + u64::from(x.1), b + u64::from(x.0)));
        println!(
            "progress: {rays} rays, {rate:.0} rays/s, {filled} of {beams} beams hold rays ({:.1}%), file {} bytes, {} free in {} fragments",
            100.0 * filled as f64 / beams.max(1) as f64,
            s.file_bytes,
            s.free_bytes,
            s.fragments
        );
        use std::io::Write as _;
        let _ = std::io::stdout().flush();
        last = Some((rays, now));
    }
}

#[cfg(unix)]
async fn terminate() {
    match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
        Ok(mut s) => {
            s.recv().await;
        }
        Err(_) => std::future::pending::<()>().await,
    }
}

#[cfg(not(unix))]
async fn terminate() {
    std::future::pending::<()>().await
}

/// Compares two secrets in time that does not depend on where they differ.
fn same_secret(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    let mut diff = u8::from(a.len() != b.len());
    for i in 0..a.len().max(b.len()) {
        diff |= a.get(i).copied().unwrap_or(0) ^ b.get(i).copied().unwrap_or(0);
    }
    diff == 0
}

/// Frames a peer may send before its Hello is checked.
const HANDSHAKE_FRAME: usize = 64 << 10;

/// Why a peer is refused, if it is.
fn check(hello: &Hello, shared: &Shared) -> Option<String> {
    if hello.version != PROTOCOL_VERSION {
        return Some(format!(
            "protocol version {} is not this server's {PROTOCOL_VERSION}",
            hello.version
        ));
    }
    if !same_secret(&hello.token, &shared.config.token) {
        return Some("wrong access token".into());
    }
    match (&shared.scene, hello.role) {
        (None, Role::Sampler) => Some("the holodeck file records no scene, so no sampler can prove it matches".into()),
        (Some(s), Role::Sampler) if *s != hello.scene => {
            Some(format!("scene {} does not match the holodeck's scene {s}", hello.scene))
        }
        (_, Role::Sampler) if !shared.samplers_allowed.load(Ordering::SeqCst) => {
            Some("samplers were stopped by an admin; a restart command lets them in again".into())
        }
        _ => None,
    }
}

async fn handle(stream: Box<dyn Stream>, shared: &Shared) -> Result<(), ConnectionError> {
    let mut conn = Connection::new(stream);
    // Nobody unauthenticated gets to make the server buffer 16 MiB.
    conn.set_max_frame(HANDSHAKE_FRAME);
    let first = tokio::time::timeout(Duration::from_secs(10), conn.read()).await;
    let hello = match first {
        Ok(Ok(Some(Frame::Message(Message::Hello(h))))) => h,
        Ok(Ok(None)) => return Ok(()),
        Ok(Err(e)) => {
            let _ = conn
                .write(&Frame::Message(Message::Refused { reason: e.to_string() }))
                .await;
            return Err(e);
        }
        Ok(Ok(Some(_))) | Err(_) => {
            let reason = "expected a Hello message first".to_string();
            conn.write(&Frame::Message(Message::Refused { reason })).await?;
            return Ok(());
        }
    };
    if let Some(reason) = check(&hello, shared) {
        tracing::warn!("refused a {:?}: {reason}", hello.role);
        conn.write(&Frame::Message(Message::Refused { reason })).await?;
        return Ok(());
    }
    conn.set_max_frame(holodeck_protocol::wire::MAX_FRAME);
    let sections = shared.sections.iter().map(Section::spec).collect();
    let obstructions = shared.obstructions;
    conn.write(&Frame::Message(Message::Welcome { sections, obstructions }))
        .await?;
    match hello.role {
        Role::Sampler => super::sampler::serve_sampler(conn, shared).await,
        Role::Display | Role::Admin => super::display::serve_display(conn, shared, hello.read_only).await,
    }
}
