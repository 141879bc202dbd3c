//! A fault-injecting TCP proxy for the network tests: peers connect to it,
//! it forwards their bytes to the server and back, and the test turns on
//! latency, a bandwidth limit, a partition (bytes held, nothing delivered,
//! no connection closed) or resets every connection it carries.

use std::io::{Read, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, RwLock};
use std::time::Duration;

/// What the proxy does to the bytes it carries now.
#[derive(Clone, Copy, Debug, Default)]
pub struct Faults {
    /// Each chunk is held this long before it goes on (each way).
    pub latency: Duration,
    /// Bytes per second each way, per connection (0: no limit).
    pub bandwidth: u64,
    /// Nothing is delivered (held until the partition heals).
    pub partitioned: bool,
}

/// The shared state of a proxy.
struct State {
    /// Read-held by a carrier from its check of the faults until its chunk
    /// is delivered and counted, so that [`Proxy::set`] returns only once
    /// no chunk let through under the old faults is still on its way.
    faults: RwLock<Faults>,
    /// Connections carried, both halves, so that they can be reset.
    streams: Mutex<Vec<TcpStream>>,
    /// Bytes delivered, both ways.
    delivered: AtomicU64,
    stop: AtomicBool,
}

/// A proxy listening on loopback; ends its threads when dropped.
pub struct Proxy {
    /// Where peers connect.
    pub addr: String,
    state: Arc<State>,
}

impl Proxy {
    /// Listens on a free loopback port and forwards to `upstream`.
    pub fn start(upstream: &str) -> Proxy {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        listener.set_nonblocking(true).unwrap();
        let addr = listener.local_addr().unwrap().to_string();
        let state = Arc::new(State {
            faults: RwLock::new(Faults::default()),
            streams: Mutex::new(Vec::new()),
            delivered: AtomicU64::new(0),
            stop: AtomicBool::new(false),
        });
        let (upstream, s) = (upstream.to_string(), Arc::clone(&state));
        std::thread::spawn(move || {
            while !s.stop.load(Ordering::Relaxed) {
                match listener.accept() {
                    Ok((down, _)) => {
                        let _ = down.set_nonblocking(false);
                        let Ok(up) = TcpStream::connect(&upstream) else {
                            continue;
                        };
                        let _ = (up.set_nodelay(true), down.set_nodelay(true));
                        // A peer that stops reading breaks its connection
                        // rather than holding the faults for ever.
                        let limit = Some(Duration::from_secs(20));
                        let _ = (up.set_write_timeout(limit), down.set_write_timeout(limit));
                        if let (Ok(a), Ok(b)) = (down.try_clone(), up.try_clone()) {
                            s.streams.lock().unwrap().extend([a, b]);
                        }
                        for (from, to) in [(&down, &up), (&up, &down)] {
                            let (from, to) = (from.try_clone().unwrap(), to.try_clone().unwrap());
                            let s = Arc::clone(&s);
                            std::thread::spawn(move || carry(from, to, &s));
                        }
                    }
                    Err(_) => std::thread::sleep(Duration::from_millis(10)),
                }
            }
        });
        Proxy { addr, state }
    }

    /// Sets what the proxy does from now on; returns once every chunk let
    /// through before has been delivered and counted.
    pub fn set(&self, faults: Faults) {
        *self.state.faults.write().unwrap() = faults;
    }

    /// Resets every connection it carries (both ends see the connection
    /// break at once, as when a middlebox drops its state).
    pub fn reset_all(&self) {
        for s in self.state.streams.lock().unwrap().drain(..) {
            let _ = s.shutdown(Shutdown::Both);
        }
    }

    /// Bytes delivered so far, both ways.
    pub fn delivered(&self) -> u64 {
        self.state.delivered.load(Ordering::Relaxed)
    }
}

impl Drop for Proxy {
    fn drop(&mut self) {
        self.state.stop.store(true, Ordering::Relaxed);
        self.reset_all();
    }
}

/// Copies `from` to `to` under the faults of the moment, until either ends.
fn carry(mut from: TcpStream, mut to: TcpStream, s: &State) {
    let mut buf = vec![0u8; 16 << 10];
    loop {
        let n = match from.read(&mut buf) {
            Ok(0) | Err(_) => break,
            Ok(n) => n,
        };
        // A chunk is checked, delayed, written and counted under one read
        // hold of the faults; a partition releases it while waiting.
        let delivered = loop {
            let f = s.faults.read().unwrap();
            if f.partitioned && !s.stop.load(Ordering::Relaxed) {
                drop(f);
                std::thread::sleep(Duration::from_millis(20));
                continue;
            }
            if !f.latency.is_zero() {
                std::thread::sleep(f.latency);
            }
            if f.bandwidth > 0 {
                std::thread::sleep(Duration::from_secs_f64(n as f64 / f.bandwidth as f64));
            }
            let ok = to.write_all(&buf[..n]).is_ok();
            if ok {
                s.delivered.fetch_add(n as u64, Ordering::Relaxed);
            }
            break ok;
        };
        if !delivered {
            break;
        }
    }
    let _ = to.shutdown(Shutdown::Both);
    let _ = from.shutdown(Shutdown::Both);
}
