//! Accepting peers and serving them by role. Each connection is one task:
//! a handshake (protocol version, access token, scene hash), then
//! - samplers get work from the shared [`Scheduler`] and send back traced
//!   rays, which go to the storage thread and on to displays that want them
//!   ([`super::sampler`]);
//! - displays send beam requests and get the beams' rays streamed back, stored
//!   rays at once and new ones as they are traced ([`super::display`]);
//! - admins and displays send control commands, each carried out only if the
//!   token the peer presented allows it (see [`super::config::Tokens`]), and
//!   each answered.
//!
//! No task waits on another peer: a stalled display or sampler only slows
//! itself. Work a sampler never finished is given back to the schedule:
//! nothing is stored twice and nothing is lost.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use holodeck_protocol::wire::{Access, Frame, Hello, Message, Progress, Role, PROTOCOL_VERSION};
use holodeck_protocol::Section;
use tokio::sync::{mpsc, watch, Notify};

use super::config::ServerConfig;
use super::connection::{Connection, ConnectionError, Stream};
use super::file_thread::FileThread;
use super::listener::{Accepted, Listener};
use super::state::{Counted, Shared};
use super::tls::Spoken;
use crate::schedule::Scheduler;
use holodeck_file::storage::{HoloFile, StorageError};

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

/// Serves `file` on `listeners` until an admin says quit, TIME is up, or the
/// process gets SIGINT/SIGTERM; then flushes and closes the file.
pub async fn serve(listeners: Vec<Listener>, file: HoloFile, config: ServerConfig) -> Result<(), ServeError> {
    if listeners.is_empty() {
        return Err(ServeError::NoListener);
    }
    let (shared, store, thread, stopped) = start_state(file, config);
    let lens = store.lens().await?;
    let batch = shared.batch(&lens)?;
    {
        let mut scheduler = shared.lock_scheduler();
        scheduler.restart(batch);
        scheduler.requests().set_share(shared.config.share);
    }
    let flusher = spawn_flusher(store.clone());
    let reports = spawn_reports(&shared).await;
    let reporter = shared
        .config
        .report
        .map(|every| tokio::spawn(report(store.clone(), every)));
    let (acceptors, peers) = spawn_acceptors(listeners);
    let mut tasks = tokio::task::JoinSet::new();
    run_until_stopped(&shared, &store, peers, stopped, &mut tasks).await;
    let background = Background {
        acceptors,
        flusher,
        reports,
        reporter,
    };
    let rays = close(shared, store, thread, tasks, background).await?;
    tracing::info!("flushed and closed: {rays} rays in the file");
    Ok(())
}

/// The state every connection shares, around the file's thread; and the
/// receiver that learns when an admin says quit.
fn start_state(
    file: HoloFile,
    config: ServerConfig,
) -> (
    Arc<Shared>,
    FileThread,
    super::file_thread::StoreThread,
    watch::Receiver<bool>,
) {
    let sections = file.sections().to_vec();
    let scene = file.settings().scene.clone();
    let obstructions = file.settings().obstructions;
    let vdistance = file.settings().vdistance;
    let (store, thread) = FileThread::spawn(file);
    let (shutdown, stopped) = watch::channel(false);
    let shared = Arc::new(Shared {
        config,
        obstructions,
        vdistance,
        scene: std::sync::Mutex::new(scene),
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
        samplers: AtomicU32::new(0),
        display_count: AtomicU32::new(0),
        progress: watch::channel(Progress::default()).0,
    });
    (shared, store, thread, stopped)
}

/// Flushes the file every two seconds.
fn spawn_flusher(store: FileThread) -> tokio::task::JoinHandle<()> {
    tokio::spawn(async move {
        let mut tick = tokio::time::interval(Duration::from_secs(2));
        loop {
            tick.tick().await;
            let started = std::time::Instant::now();
            match store.flush().await {
                // Says what a crash can no longer take away (tests wait on it).
                Ok(rays) => {
                    tracing::debug!("periodic flush: {rays} rays durable");
                    // The commit's latency (`holodeck bench scale` reads it).
                    tracing::debug!("periodic flush took {:.1} ms", started.elapsed().as_secs_f64() * 1e3);
                }
                Err(e) => tracing::error!("periodic flush: {e}"),
            }
        }
    })
}

/// Sends displays the first progress report now, and a new one each
/// second.
async fn spawn_reports(shared: &Arc<Shared>) -> tokio::task::JoinHandle<()> {
    let mut rate = super::rate::RateWindow::default();
    let first = shared.progress_now(&mut rate).await;
    shared.progress.send_replace(first);
    let shared = Arc::clone(shared);
    {
        tokio::spawn(async move {
            let mut tick = tokio::time::interval(PROGRESS_EVERY);
            tick.tick().await;
            loop {
                tick.tick().await;
                let p = shared.progress_now(&mut rate).await;
                shared.progress.send_replace(p);
            }
        })
    }
}

/// One accept loop per socket, all feeding one queue of new peers.
#[allow(clippy::type_complexity)]
fn spawn_acceptors(listeners: Vec<Listener>) -> (Vec<tokio::task::JoinHandle<()>>, mpsc::Receiver<Accepted>) {
    let (peers_tx, peers) = mpsc::channel::<Accepted>(64);
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
    (acceptors, peers)
}

/// Serves peers as they come until an admin says quit, TIME is up, the
/// file refuses rays with no display left to serve, or a signal.
async fn run_until_stopped(
    shared: &Arc<Shared>,
    store: &FileThread,
    mut peers: mpsc::Receiver<Accepted>,
    mut stopped: watch::Receiver<bool>,
    tasks: &mut tokio::task::JoinSet<()>,
) {
    let time_limit = shared.config.time;
    let deadline = async move {
        match time_limit {
            Some(t) => tokio::time::sleep(t).await,
            None => std::future::pending::<()>().await,
        }
    };
    tokio::pin!(deadline);
    let mut full_check = tokio::time::interval(Duration::from_millis(200));
    // Made once: a signal arriving between two turns of the loop is not lost.
    let interrupted = tokio::signal::ctrl_c();
    let terminated = terminate();
    tokio::pin!(interrupted, terminated);
    loop {
        tokio::select! {
            Some(accepted) = peers.recv() => {
                let shared = Arc::clone(shared);
                tasks.spawn(async move {
                    let peer = accepted.peer();
                    let Some((stream, network)) = spoken(accepted, &shared).await else { return };
                    let refuse_plain = network && !shared.config.plain_from_network;
                    match handle(stream, &shared, refuse_plain).await {
                        Ok(()) => {}
                        // A peer that leaves without saying goodbye (a closed window) is no fault.
                        Err(e) if e.is_gone() => tracing::info!("{peer} went away: {e}"),
                        Err(e) => tracing::warn!("{peer}: {e}"),
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
}

/// The server's background tasks, ended at close.
struct Background {
    acceptors: Vec<tokio::task::JoinHandle<()>>,
    flusher: tokio::task::JoinHandle<()>,
    reports: tokio::task::JoinHandle<()>,
    reporter: Option<tokio::task::JoinHandle<()>>,
}

/// Tells every connection to stop, ends those that do not (packets they
/// had out are simply never stored), flushes and closes the file; the rays
/// in it.
async fn close(
    shared: Arc<Shared>,
    store: FileThread,
    thread: super::file_thread::StoreThread,
    mut tasks: tokio::task::JoinSet<()>,
    b: Background,
) -> Result<u64, ServeError> {
    let Background {
        acceptors,
        flusher,
        reports,
        reporter,
    } = b;
    let _ = shared.shutdown.send(true);
    for a in &acceptors {
        a.abort();
    }
    tasks.shutdown().await;
    tracing::info!("shutting down: flushing the file");
    flusher.abort();
    reports.abort();
    if let Some(r) = reporter {
        r.abort();
    }
    let flushed = store.flush().await;
    drop(store);
    // The report task held the shared state (and a storage handle): gone
    // before the storage thread is waited for.
    let _ = reports.await;
    drop(shared);
    drop(acceptors);
    // The storage thread exits once every handle is gone; wait for it even
    // when the flush failed, so that closing does not race the exit.
    let closed = tokio::task::spawn_blocking(move || thread.join())
        .await
        .unwrap_or(Ok(()));
    let rays = flushed?;
    closed?;
    Ok(rays)
}

/// Prints a progress line every `every`: rays stored, the rate since the last
/// line, beams holding rays, the file size and its fragmentation.
async fn report(store: FileThread, every: Duration) {
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

/// How often displays get a progress report.
const PROGRESS_EVERY: Duration = Duration::from_secs(1);

/// Frames a peer may send before its Hello is checked.
const HANDSHAKE_FRAME: usize = 64 << 10;

/// Why a peer is refused.
enum Refusal {
    /// For good (as far as this server can tell).
    Final(String),
    /// For now: samplers are stopped by an admin.
    Retry(String),
}

/// What the peer may do, or why it is refused.
fn check(hello: &Hello, shared: &Shared) -> Result<Access, Refusal> {
    if hello.version != PROTOCOL_VERSION {
        return Err(Refusal::Final(format!(
            "protocol version {} is not this server's {PROTOCOL_VERSION}",
            hello.version
        )));
    }
    let Some(mut access) = shared.config.tokens.access(&hello.token) else {
        return Err(Refusal::Final("wrong access token".into()));
    };
    if hello.read_only {
        access = access.min(Access::Viewer);
    }
    if hello.role == Role::Sampler {
        if access < Access::Writer {
            return Err(Refusal::Final(format!(
                "a sampler needs writer access; this connection has {access} access"
            )));
        }
        let stopped = !shared.samplers_allowed.load(Ordering::SeqCst);
        match (shared.scene(), stopped) {
            (None, _) => {
                return Err(Refusal::Final(
                    "the holodeck file records no scene (an imported Radiance holodeck?), so no sampler can \
                     prove it matches: continue it with `holodeck run SCENE FILE` or `holodeck fill SCENE FILE`, \
                     or `holodeck admin ... adopt SCENE --keep-rays` on this server"
                        .into(),
                ))
            }
            (Some(s), true) if s != hello.scene => {
                return Err(Refusal::Retry(format!(
                    "samplers were stopped by an admin, and scene {} is not the holodeck's scene {s}; \
                     adopting this scene lets its samplers in",
                    hello.scene
                )))
            }
            (Some(_), true) => {
                return Err(Refusal::Retry(
                    "samplers were stopped by an admin; a restart command lets them in again".into(),
                ))
            }
            (Some(s), false) if s != hello.scene => {
                return Err(Refusal::Final(format!(
                    "scene {} does not match the holodeck's scene {s}",
                    hello.scene
                )))
            }
            (Some(_), false) => {}
        }
    }
    Ok(access)
}

/// The byte stream of an accepted peer: TLS or plain (and then whether it
/// came from another host); `None` where it left or its handshake failed.
async fn spoken(accepted: Accepted, shared: &Shared) -> Option<(Box<dyn Stream>, bool)> {
    match accepted {
        Accepted::Unix(s, _) => Some((Box::new(s), false)),
        // Plain HTTP from another host: the token crossed the network in clear text.
        Accepted::Web(s, peer) => Some((s, !peer.secure && !peer.addr.ip().is_loopback())),
        Accepted::Tcp(s, peer) => match super::tls::accept(s, peer, shared.config.tls.as_ref()).await? {
            Spoken::Tls(s) => Some((s, false)),
            Spoken::Plain { stream, network } => Some((stream, network)),
        },
    }
}

/// What a server that takes TLS from other hosts answers a plain one.
const PLAIN_REFUSED: &str = "this server takes peers on other hosts over TLS only (their tokens \
would cross the network in clear text): connect with the token file `holodeck serve` wrote, which \
pins the server's certificate, or open the web display's https:// link";

async fn handle(stream: Box<dyn Stream>, shared: &Shared, refuse_plain: bool) -> Result<(), ConnectionError> {
    let mut conn = Connection::new(stream);
    if refuse_plain {
        tracing::warn!("refused a peer on another host speaking the plain protocol");
        let reason = PLAIN_REFUSED.to_string();
        conn.write(&Frame::Message(Message::Refused { reason, retry: false }))
            .await?;
        return Ok(());
    }
    // Nobody unauthenticated gets to make the server buffer 16 MiB.
    conn.set_max_frame(HANDSHAKE_FRAME);
    let first = tokio::time::timeout(Duration::from_secs(10), conn.read()).await;
    let hello = match first {
        Ok(Ok(Some(Frame::Message(Message::Hello(h))))) => h,
        Ok(Ok(None)) => return Ok(()),
        Ok(Err(e)) => {
            let _ = conn
                .write(&Frame::Message(Message::Refused {
                    reason: e.to_string(),
                    retry: false,
                }))
                .await;
            return Err(e);
        }
        Ok(Ok(Some(_))) | Err(_) => {
            let reason = "expected a Hello message first".to_string();
            conn.write(&Frame::Message(Message::Refused { reason, retry: false }))
                .await?;
            return Ok(());
        }
    };
    let access = match check(&hello, shared) {
        Ok(a) => a,
        Err(refusal) => {
            let (reason, retry) = match refusal {
                Refusal::Final(r) => (r, false),
                Refusal::Retry(r) => (r, true),
            };
            tracing::warn!("refused a {:?}: {reason}", hello.role);
            conn.write(&Frame::Message(Message::Refused { reason, retry })).await?;
            return Ok(());
        }
    };
    conn.set_max_frame(holodeck_protocol::wire::MAX_FRAME);
    let sections = shared.sections.iter().map(Section::spec).collect();
    let obstructions = shared.obstructions;
    conn.write(&Frame::Message(Message::Welcome {
        sections,
        obstructions,
        vdistance: shared.vdistance,
        access,
    }))
    .await?;
    match hello.role {
        Role::Sampler => {
            let _counted = Counted::new(&shared.samplers);
            super::sampler::serve_sampler(conn, shared).await
        }
        Role::Display => {
            let _counted = Counted::new(&shared.display_count);
            super::display::serve_display(conn, shared, access).await
        }
        Role::Admin => super::display::serve_display(conn, shared, access).await,
    }
}
