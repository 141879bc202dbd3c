//! The sampler's side of the wire: connect to a holodeck server, prove the
//! scene, and trace the packets it hands out until it closes the connection.
//! Blocking I/O on one connection per worker thread: tracing, not the network,
//! is what takes the time.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use holodeck_protocol::wire::client::{self, ClientError, ClientStream};
use holodeck_protocol::wire::{Frame, FrameLink, LinkError, Message, Role, TracePacket, MAX_PACKET_RAYS};
use holodeck_protocol::SectionError;

use crate::beam::{trace_tasks, BeamTask, FileRules};
use crate::shade::{Rng, Tracer};

/// Why a worker stopped.
#[derive(Debug, thiserror::Error)]
pub enum WorkerError {
    /// Connecting or the handshake failed (the server refused this sampler, say).
    #[error(transparent)]
    Connect(#[from] ClientError),
    /// The connection failed after the handshake.
    #[error("connection to {addr}: {source}")]
    Io {
        /// The server.
        addr: String,
        /// Why.
        source: LinkError,
    },
    /// The server broke the protocol.
    #[error("protocol error: {0}")]
    Protocol(String),
    /// A section the server described is invalid.
    #[error("section from the server: {0}")]
    Section(#[from] SectionError),
    /// No server answered at the address in all the time given to retrying.
    #[error("no holodeck server reached at {addr} (retried for {secs} s): {error}", secs = retried.as_secs_f64())]
    Unreachable {
        /// The server's address.
        addr: String,
        /// How long connecting was retried.
        retried: Duration,
        /// Why the last attempt failed (part of this message).
        error: Box<ClientError>,
    },
}

/// Finished rays wait at most this long before they are sent, so displays
/// see progress even while the queue from the server never runs dry.
const SEND_EVERY: Duration = Duration::from_millis(20);

/// Rays a worker gathers from packets that arrived together before it
/// traces them as one batch, where its tracer sorts batches: enough for
/// [`crate::Reorder::Auto`] to sort them.
const GATHER_RAYS: u64 = 2 * crate::shade::AUTO_MIN_PATHS as u64;

/// Traces packets from the server at `addr` until it closes the connection;
/// returns the rays traced. `scene` is the content hash of `tracer`'s scene.
pub fn run_worker(addr: &str, tracer: &Tracer, scene: &str, token: &str, seed: u64) -> Result<u64, WorkerError> {
    run_session(addr, tracer, scene, token, seed, &AtomicU64::new(0)).map(|(traced, _)| traced)
}

/// One connection's work: adds every ray it traces and hands to the
/// connection to `traced` as it goes (so that others may read the count at
/// any time, and a session ended by an error still counts them), and
/// returns the rays this session traced and whether it ended because an
/// admin stopped the samplers (rather than the server closing).
fn run_session(
    addr: &str,
    tracer: &Tracer,
    scene: &str,
    token: &str,
    seed: u64,
    traced: &AtomicU64,
) -> Result<(u64, bool), WorkerError> {
    let io = |source: LinkError| WorkerError::Io {
        addr: client::shown(addr).to_string(),
        source,
    };
    let (mut link, welcome): (FrameLink<ClientStream>, _) =
        client::open(addr, client::hello(Role::Sampler, token, scene, false))?;
    let sections = welcome.sections;
    // The file's settings, not this process's options, decide how it is filled.
    let rules = FileRules {
        obstructions: welcome.obstructions,
        vdistance: welcome.vdistance,
    };
    let mut session = 0u64;
    let mut n = 0u64;
    let mut last_send = Instant::now();
    // Packets that arrive together are traced as one batch where the tracer
    // may sort batches of rays (a scene larger than the caches, or sorting
    // asked for); elsewhere
    // one packet at a time, so results go back as soon as each is done. The
    // records are the same either way.
    let gather = if tracer.may_reorder(usize::MAX) { GATHER_RAYS } else { 0 };
    'session: loop {
        let mut packets: Vec<TracePacket> = Vec::new();
        let mut gathered = 0u64;
        let mut frame = match link.read() {
            Ok(Some(f)) => f,
            Ok(None) => break,
            // The server stopping (or restarting) ends this worker's run.
            Err(e) if e.is_gone() => break,
            Err(e) => return Err(io(e)),
        };
        loop {
            match frame {
                Frame::Message(Message::Trace(p)) => {
                    gathered += u64::from(p.rays);
                    packets.push(p);
                }
                Frame::Message(Message::Error { message }) => tracing::warn!("server: {message}"),
                Frame::Message(Message::Refused { reason, retry }) => {
                    if retry {
                        tracing::warn!("{}: {reason}", client::shown(addr));
                        return Ok((session, true));
                    }
                    return Err(WorkerError::Connect(ClientError::Refused {
                        addr: client::shown(addr).to_string(),
                        role: client::role_name(Role::Sampler),
                        reason,
                        retry,
                    }));
                }
                _ => return Err(WorkerError::Protocol("expected trace packets".into())),
            }
            if gathered >= gather {
                break;
            }
            frame = match link.read_buffered() {
                Ok(Some(f)) => f,
                Ok(None) => break,
                Err(e) => return Err(io(e)),
            };
        }
        let mut tasks = Vec::with_capacity(packets.len());
        for packet in &packets {
            let section = sections
                .get(packet.key.section as usize)
                .ok_or_else(|| WorkerError::Protocol(format!("packet for unknown section {}", packet.key.section)))?;
            tasks.push(BeamTask {
                section,
                beam: packet.key.beam,
                rays: packet.rays.min(MAX_PACKET_RAYS) as usize,
                mode: packet.mode,
                rng: Rng::new(seed, n),
            });
            n += 1;
        }
        for (packet, records) in packets.iter().zip(trace_tasks(tracer, rules, tasks)) {
            let records = records?;
            let rays = records.len() as u64;
            let sent = link
                .write(&Frame::Finished {
                    id: packet.id,
                    key: packet.key,
                    records,
                })
                .and_then(|()| {
                    if last_send.elapsed() >= SEND_EVERY {
                        last_send = Instant::now();
                        link.flush()
                    } else {
                        Ok(())
                    }
                });
            match sent {
                Ok(()) => {
                    session += rays;
                    traced.fetch_add(rays, Ordering::Relaxed);
                }
                Err(e) if e.is_gone() => break 'session,
                Err(e) => return Err(io(e)),
            }
        }
    }
    tracing::info!(
        "{}: the server closed the connection after {session} rays",
        client::shown(addr)
    );
    Ok((session, false))
}

/// What a worker traces: a tracer of the scene, and the scene's content hash.
pub type SceneSource<'a> = dyn Fn() -> (Arc<Tracer>, String) + Sync + 'a;

/// Runs [`run_worker`] and reconnects with growing delays while the server is
/// away (restarting, say), for up to `retry_for` after it was last seen
/// working. While an admin has stopped the samplers (the server says
/// trying again makes sense), it keeps trying, however long that takes;
/// `scene` is asked for the scene before every attempt, so that one edited
/// meanwhile is the one proved next. Any other refusal, or a protocol
/// error, ends it at once. Adds to `traced` every ray it traces and hands
/// to a connection, as it goes, those of sessions a broken connection
/// ended included (what the server did not store of them was lost in
/// flight), so that the count can be read at any time. A worker that never
/// reached a server fails with [`WorkerError::Unreachable`]; one whose server
/// went away after it was reached ends normally.
pub fn run_worker_retrying(
    addr: &str,
    scene: &SceneSource<'_>,
    token: &str,
    seed: u64,
    retry_for: Duration,
    traced: &AtomicU64,
) -> Result<(), WorkerError> {
    let (mut round, mut reached) = (0u64, false);
    let mut delay = Duration::from_millis(250);
    let mut lost_since: Option<Instant> = None;
    loop {
        let round_seed = seed.wrapping_add(round.wrapping_mul(0x9E37_79B9));
        let (tracer, hash) = scene();
        let (failure, stopped) = match run_session(addr, &tracer, &hash, token, round_seed, traced) {
            Ok((n, stopped)) => {
                reached = true;
                // This worker's own progress (others share `traced`).
                if n > 0 {
                    delay = Duration::from_millis(250);
                    lost_since = None;
                }
                (None, stopped)
            }
            Err(WorkerError::Connect(ClientError::Refused {
                reason, retry: true, ..
            })) => {
                tracing::warn!("{}: refused for now ({reason}); retrying", client::shown(addr));
                reached = true;
                (None, true)
            }
            Err(WorkerError::Io { addr, source }) => (Some(ClientError::Link { addr, source }), false),
            Err(WorkerError::Connect(e)) if e.is_unreachable() => (Some(e), false),
            Err(e) => return Err(e),
        };
        round += 1;
        if stopped {
            // The server is there and says to wait: no deadline.
            lost_since = None;
            std::thread::sleep(delay);
            delay = (delay * 2).min(MAX_STOPPED_DELAY);
            continue;
        }
        let since = *lost_since.get_or_insert_with(Instant::now);
        if since.elapsed() >= retry_for {
            return match failure {
                Some(error) if !reached => Err(WorkerError::Unreachable {
                    addr: client::shown(addr).to_string(),
                    retried: retry_for,
                    error: Box::new(error),
                }),
                _ => Ok(()),
            };
        }
        tracing::info!("{}: server unavailable; retrying in {delay:?}", client::shown(addr));
        std::thread::sleep(delay.min(retry_for.saturating_sub(since.elapsed())));
        delay = (delay * 2).min(Duration::from_secs(10));
    }
}

/// Longest wait between attempts while samplers are stopped: a restart lets
/// them in again within this.
const MAX_STOPPED_DELAY: Duration = Duration::from_secs(2);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;
    use crate::shade::TraceOptions;

    #[test]
    fn a_worker_that_never_reaches_a_server_says_where_it_looked() {
        let tracer = Arc::new(Tracer::new(Scene::default(), TraceOptions::default()));
        // A port that was just free: nothing listens there.
        let addr = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .to_string();
        let scene = || (Arc::clone(&tracer), "scene".to_string());
        let e = run_worker_retrying(&addr, &scene, "token", 1, Duration::ZERO, &AtomicU64::new(0)).unwrap_err();
        let WorkerError::Unreachable {
            addr: at,
            retried,
            error,
        } = &e
        else {
            panic!("{e:?}")
        };
        let ClientError::Link {
            source: LinkError::Io(io),
            ..
        } = error.as_ref()
        else {
            panic!("{e:?}")
        };
        assert_eq!((at.as_str(), *retried), (addr.as_str(), Duration::ZERO));
        assert_eq!(io.kind(), std::io::ErrorKind::ConnectionRefused);
        assert!(e.to_string().contains(&addr), "{e}");
    }

    /// A fake server on a real socket hands out packets in one write; the
    /// worker, sorting batches, traces them together and answers each with
    /// exactly the records that packet gets traced alone.
    #[test]
    fn packets_that_arrive_together_get_the_records_they_get_alone() {
        use crate::scene::{generate, GenParams};
        use holodeck_protocol::wire::{Access, SamplingMode};
        use holodeck_protocol::BeamKey;
        use std::net::TcpListener;

        let room = generate("room", &GenParams::default()).unwrap();
        let sections = room.sections.clone();
        let tracer = Tracer::new(
            room,
            TraceOptions {
                reorder: crate::Reorder::HitPoint,
                ..TraceOptions::default()
            },
        );
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let packets: Vec<TracePacket> = (0..40u32)
            .map(|i| TracePacket {
                id: 100 + u64::from(i),
                key: BeamKey::new(i % sections.len() as u32, 31 * i),
                rays: 1 + i % 9,
                mode: SamplingMode::Uniform,
            })
            .collect();
        let served = packets.clone();
        let spec = sections.iter().map(|s| s.spec()).collect();
        let server = std::thread::spawn(move || {
            let (socket, _) = listener.accept().unwrap();
            let mut link = FrameLink::new(socket);
            assert!(matches!(link.read().unwrap(), Some(Frame::Message(Message::Hello(_)))));
            link.write(&Frame::Message(Message::Welcome {
                sections: spec,
                obstructions: false,
                vdistance: false,
                access: Access::Writer,
            }))
            .unwrap();
            for p in &served {
                link.write(&Frame::Message(Message::Trace(*p))).unwrap();
            }
            link.flush().unwrap();
            let mut answers = Vec::new();
            while answers.len() < served.len() {
                match link.read().unwrap() {
                    Some(Frame::Finished { id, key, records }) => answers.push((id, key, records)),
                    other => panic!("{other:?}"),
                }
            }
            answers
        });
        let traced = run_worker(&addr, &tracer, "scene", "token", 7);
        let answers = server.join().unwrap();
        assert_eq!(traced.unwrap(), packets.iter().map(|p| u64::from(p.rays)).sum::<u64>());
        let rules = FileRules::default();
        for (n, (p, (id, key, records))) in packets.iter().zip(answers).enumerate() {
            assert_eq!((id, key), (p.id, p.key));
            let alone = trace_tasks(
                &tracer,
                rules,
                vec![BeamTask {
                    section: &sections[p.key.section as usize],
                    beam: p.key.beam,
                    rays: p.rays as usize,
                    mode: p.mode,
                    rng: Rng::new(7, n as u64),
                }],
            );
            assert_eq!(records, *alone[0].as_ref().unwrap(), "packet {n}");
        }
    }
}
