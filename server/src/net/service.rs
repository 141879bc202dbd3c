//! Accepting peers and serving them by role. Each connection is one task:
//! a handshake (protocol version, access token, scene hash), then
//! - samplers are handed packets from the shared batch schedule and send back
//!   traced rays, which go to the storage thread;
//! - displays send beam requests and get the beams' rays streamed back;
//! - admins (and writable displays) may quit the server.
//!
//! Packets a sampler never finished (it died, or sent garbage) are given back
//! to the schedule: nothing is stored twice and nothing is lost.

use std::collections::HashMap;
use std::sync::Arc;
use std::time::Duration;

use holodeck_protocol::wire::{Control, Frame, Hello, Message, Role, SamplingMode, TracePacket, PROTOCOL_VERSION};
use holodeck_protocol::{BeamKey, Section};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{watch, Mutex};

use super::connection::{Connection, ConnectionError};
use super::store::Store;
use crate::schedule::BatchSchedule;
use crate::storage::{HoloFile, StorageError};

/// How the server runs.
#[derive(Clone, Debug)]
pub struct ServerConfig {
    /// The token every peer must present.
    pub token: String,
    /// Rays per trace packet.
    pub packet: u32,
    /// Packets a sampler works on at once.
    pub batch: usize,
    /// Stop (flushing) after this long (the TIME setting).
    pub time: Option<Duration>,
    /// Print a progress line this often (the REPORT setting).
    pub report: Option<Duration>,
}

/// Why the server stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// The file failed.
    #[error(transparent)]
    Storage(#[from] StorageError),
    /// The listening socket failed.
    #[error("accepting connections: {0}")]
    Accept(std::io::Error),
    /// The schedule could not be built.
    #[error("building the schedule: {0}")]
    Schedule(#[from] holodeck_protocol::SectionError),
}

struct Shared {
    config: ServerConfig,
    obstructions: bool,
    scene: Option<String>,
    sections: Vec<Section>,
    schedule: Mutex<BatchSchedule>,
    store: Store,
    next_id: std::sync::atomic::AtomicU64,
    shutdown: watch::Sender<bool>,
}

/// Serves `file` on `listener` until an admin says quit or the process gets
/// SIGINT/SIGTERM; then flushes and closes the file.
pub async fn serve(listener: TcpListener, file: HoloFile, config: ServerConfig) -> Result<(), ServeError> {
    let sections = file.sections().to_vec();
    let scene = file.settings().scene.clone();
    let obstructions = file.settings().obstructions;
    let schedule = BatchSchedule::new(&sections, |k| file.beam_len(k).unwrap_or(0))?;
    let (store, thread) = Store::spawn(file);
    let (shutdown, mut stopped) = watch::channel(false);
    let shared = Arc::new(Shared {
        config,
        obstructions,
        scene,
        sections,
        schedule: Mutex::new(schedule),
        store: store.clone(),
        next_id: std::sync::atomic::AtomicU64::new(1),
        shutdown,
    });
    let flusher = {
        let store = store.clone();
        tokio::spawn(async move {
            let mut tick = tokio::time::interval(Duration::from_secs(2));
            loop {
                tick.tick().await;
                if let Err(e) = store.flush().await {
                    tracing::error!("periodic flush: {e}");
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
    let mut tasks = tokio::task::JoinSet::new();
    loop {
        tokio::select! {
            accepted = listener.accept() => {
                let (stream, peer) = accepted.map_err(ServeError::Accept)?;
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
            _ = tokio::signal::ctrl_c() => break,
            _ = terminate() => break,
        }
    }
    // Tell every connection to stop, then end those that do not: packets they
    // had out are simply never stored.
    let _ = shared.shutdown.send(true);
    tasks.shutdown().await;
    tracing::info!("shutting down: flushing the file");
    flusher.abort();
    if let Some(r) = reporter {
        r.abort();
    }
    let flushed = store.flush().await;
    drop(store);
    drop(shared);
    flushed?;
    // The storage thread exits once every handle is gone (connection tasks
    // still running hold one; the runtime drops them when the caller returns).
    tokio::task::spawn_blocking(move || thread.join())
        .await
        .unwrap_or(Ok(()))?;
    Ok(())
}

/// Prints a progress line every `every`: rays stored, the rate since the last
/// line, beams holding rays, and the file size.
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
            "progress: {rays} rays, {rate:.0} rays/s, {filled} of {beams} beams hold rays ({:.1}%), file {} bytes",
            100.0 * filled as f64 / beams.max(1) as f64,
            s.file_bytes
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

/// Why a peer is refused, if it is.
fn check(hello: &Hello, shared: &Shared) -> Option<String> {
    if hello.version != PROTOCOL_VERSION {
        return Some(format!(
            "protocol version {} is not this server's {PROTOCOL_VERSION}",
            hello.version
        ));
    }
    if hello.token != shared.config.token {
        return Some("wrong access token".into());
    }
    match (&shared.scene, hello.role) {
        (None, Role::Sampler) => Some("the holodeck file records no scene, so no sampler can prove it matches".into()),
        (Some(s), Role::Sampler) if *s != hello.scene => {
            Some(format!("scene {} does not match the holodeck's scene {s}", hello.scene))
        }
        _ => None,
    }
}

async fn handle(stream: TcpStream, shared: &Shared) -> Result<(), ConnectionError> {
    let mut conn = Connection::new(stream);
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
    let sections = shared.sections.iter().map(Section::spec).collect();
    let obstructions = shared.obstructions;
    conn.write(&Frame::Message(Message::Welcome { sections, obstructions }))
        .await?;
    match hello.role {
        Role::Sampler => sampler(conn, shared).await,
        Role::Display | Role::Admin => display(conn, shared, hello.read_only).await,
    }
}

async fn sampler(mut conn: Connection, shared: &Shared) -> Result<(), ConnectionError> {
    let mut stop = shared.shutdown.subscribe();
    loop {
        if *stop.borrow() {
            return Ok(());
        }
        let batch = shared
            .schedule
            .lock()
            .await
            .next(shared.config.batch, shared.config.packet);
        let mut pending: HashMap<u64, (BeamKey, u32)> = HashMap::with_capacity(batch.len());
        let mut frames = Vec::with_capacity(batch.len());
        for (key, rays) in batch {
            let id = shared.next_id.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            pending.insert(id, (key, rays));
            frames.push(Frame::Message(Message::Trace(TracePacket {
                id,
                key,
                rays,
                mode: SamplingMode::Uniform,
            })));
        }
        // One write for the whole batch: per-packet writes cost more than the packets.
        if let Err(e) = conn.write_all(&frames).await {
            give_back(shared, &pending).await;
            return Err(e);
        }
        while !pending.is_empty() {
            let frame = tokio::select! {
                f = conn.read() => f,
                _ = stop.changed() => Ok(None),
            };
            match frame {
                Ok(Some(Frame::Finished { id, key, records })) => match pending.get(&id) {
                    Some(&(k, n)) if k == key && records.len() == n as usize => {
                        pending.remove(&id);
                        shared.store.append(key, records);
                    }
                    _ => {
                        let message = format!("packet {id} does not match any packet sent to you");
                        conn.write(&Frame::Message(Message::Error { message })).await?;
                    }
                },
                Ok(Some(_)) => {
                    let message = "samplers send finished packets only".to_string();
                    conn.write(&Frame::Message(Message::Error { message })).await?;
                }
                Ok(None) => {
                    give_back(shared, &pending).await;
                    return Ok(());
                }
                Err(e) => {
                    give_back(shared, &pending).await;
                    return Err(e);
                }
            }
        }
    }
}

async fn give_back(shared: &Shared, pending: &HashMap<u64, (BeamKey, u32)>) {
    let mut schedule = shared.schedule.lock().await;
    for &(key, rays) in pending.values() {
        schedule.give_back(key, rays);
    }
}

async fn display(mut conn: Connection, shared: &Shared, read_only: bool) -> Result<(), ConnectionError> {
    while let Some(frame) = conn.read().await? {
        match frame {
            Frame::Message(Message::BeamRequest { beams }) => {
                let bad = beams.iter().find(|(k, _)| {
                    shared
                        .sections
                        .get(k.section as usize)
                        .is_none_or(|s| k.beam >= s.beam_count())
                });
                if let Some((k, _)) = bad {
                    let message = format!("no beam {} in section {}", k.beam, k.section);
                    conn.write(&Frame::Message(Message::Error { message })).await?;
                    continue;
                }
                let keys = beams.iter().map(|(k, _)| *k).collect();
                match shared.store.read(keys).await {
                    Ok(found) => {
                        for (key, records) in found {
                            conn.write(&Frame::Beam { key, records }).await?;
                        }
                    }
                    Err(e) => {
                        conn.write(&Frame::Message(Message::Error { message: e.to_string() }))
                            .await?;
                    }
                }
            }
            Frame::Message(Message::Control(Control::Quit)) if !read_only => {
                let _ = shared.shutdown.send(true);
                return Ok(());
            }
            Frame::Message(Message::Control(c)) => {
                let message = if read_only {
                    format!("{c:?} is not allowed for a read-only display")
                } else {
                    format!("{c:?} is not supported yet")
                };
                conn.write(&Frame::Message(Message::Error { message })).await?;
            }
            _ => {
                let message = "displays send beam requests and control commands".to_string();
                conn.write(&Frame::Message(Message::Error { message })).await?;
            }
        }
    }
    Ok(())
}
