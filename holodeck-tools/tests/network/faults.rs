//! Samplers across network faults: a server and sampler processes joined
//! through the fault-injecting proxy (latency, a slow link, every connection
//! reset, a 30 s partition), a sampler frozen by SIGSTOP, and (where the
//! test may) samplers in another network namespace across a veth pair. After each
//! fault the server still answers a display, the fill resumes, no ray is
//! stored twice, and the file checks clean; at the end the rays the
//! samplers say they traced, less those stored, are the rays lost in flight
//! (none where no connection broke). What each fault cost is printed
//! (`cargo test -p holodeck-tools --test network faults -- --nocapture`).

use std::collections::{HashMap, HashSet};
use std::path::Path;
use std::time::{Duration, Instant};

use holodeck_file::{HoloFile, OpenOptions};
use holodeck_protocol::wire::{client, Control, Role};
use holodeck_protocol::BeamKey;

use crate::common::process::Proc;
use crate::common::text;
use crate::harness::*;
use crate::proxy::{Faults, Proxy};

/// The admin token of the servers here (the writer's is generated into its
/// file, which pins the certificate: the samplers speak TLS).
const TOKEN: &str = "faults";

/// How long the samplers keep reconnecting after they lose the server.
const RETRY: &str = "10s";

/// Every ray of a closed file, and how many of them were stored twice: a
/// packet stored twice repeats its run of records in its beam (batch
/// packets hold several rays), so a ray counts as a copy when it and the
/// ray before it repeat two consecutive rays stored earlier in the beam.
/// A lone ray equal to another is chance, not a copy: two random rays of a
/// beam agree in all ten bytes (their sub-cells, colour and depth) about
/// once in four billion pairs, and a test stores millions of rays in a
/// hundred thousand beams; those are counted apart (the third number).
fn duplicates(file: &Path) -> (u64, u64, u64) {
    let mut f = HoloFile::open(file, &OpenOptions::read_only()).unwrap();
    let keys: Vec<BeamKey> = (0..f.sections()[0].beam_count())
        .map(|b| BeamKey::new(0, b))
        .filter(|k| f.beam_len(*k).unwrap() > 0)
        .collect();
    let (mut rays, mut copies, mut alike) = (0u64, 0u64, 0u64);
    f.read_beams(&keys, |_, records| {
        let mut seen = HashSet::with_capacity(records.len());
        let mut pairs = HashSet::with_capacity(records.len());
        for (i, r) in records.iter().enumerate() {
            rays += 1;
            if !seen.insert(*r) {
                alike += 1;
            }
            if i > 0 && !pairs.insert((records[i - 1], *r)) {
                copies += 1;
            }
        }
    })
    .unwrap();
    (rays, copies, alike)
}

/// The arguments of a sampler of the room (one thread, no bounces)
/// connecting to `addr` with the token file `writer`, reconnecting for
/// `retry` after it loses the server.
fn sampler_args(addr: &str, writer: &str, retry: &str, seed: u32) -> Vec<String> {
    let seed = seed.to_string();
    [
        "sample",
        "builtin:room",
        "--connect",
        addr,
        "--token-file",
        writer,
        "-j",
        "1",
        "--bounces",
        "0",
        "--retry-for",
        retry,
        "--seed",
        &seed,
    ]
    .map(String::from)
    .to_vec()
}

/// A sampler process of the room connecting to `addr` with the writer token
/// of `file`, reconnecting for `retry` after it loses the server.
fn sampler_via(addr: &str, file: &Path, seed: u32, retry: &str) -> Proc {
    let writer = format!("{}.writer.token", file.display());
    Proc::start(bin().args(sampler_args(addr, &writer, retry, seed)))
}

/// A display connected straight to the server asks for rays of a few beams
/// and gets an answer: the server keeps serving displays.
fn display_is_served(addr: &str) {
    let (mut display, _) = Client::connect(addr, Role::Display, TOKEN);
    let want: Vec<(BeamKey, u32)> = (0..4).map(|b| (BeamKey::new(0, 500 + 7 * b), 1)).collect();
    let got: HashMap<BeamKey, usize> = display.request(&want, None).into_iter().collect();
    assert!(got.keys().all(|k| want.iter().any(|w| w.0 == *k)), "{got:?}");
}

/// Waits until the server has stored `more` rays beyond what it reported
/// last; the time that took.
fn resumes(server: &Proc, from: &mut usize, more: u64, what: &str) -> Duration {
    let start = Instant::now();
    let now = reports(server).last().copied().unwrap_or(0);
    reported_above(server, from, now + more, what);
    start.elapsed()
}

/// The rays a sampler says it traced and handed to the server
/// (`traced N rays for ADDR`, its last words however it ended).
fn traced_rays(output: &str) -> Option<u64> {
    let line = output.lines().rev().find_map(|l| l.strip_prefix("traced "))?;
    line.split_once(" rays")?.0.replace(',', "").parse().ok()
}

/// What became of the samplers' rays.
struct Account {
    /// Rays the samplers added to the file.
    stored: u64,
    /// Rays the samplers traced and handed to their connections that the
    /// file does not hold: in flight when a connection broke.
    lost: u64,
}

/// Pauses the fill until nothing more arrives (the samplers return what
/// they hold), quits the server and the samplers, and checks the file:
/// clean, no ray stored twice, and every ray stored beyond the `initial`
/// ones a ray a sampler traced. Returns what became of the samplers' rays.
fn close_and_check(server: Proc, addr: &str, samplers: Vec<Proc>, file: &Path, initial: u64, what: &str) -> Account {
    let mut server = server;
    client::send_control(addr, TOKEN, Control::Pause).unwrap();
    let mut at = server.text().lines().count();
    steady(&server, &mut at, 2, "the paused fill to settle");
    quit(addr, TOKEN);
    assert!(server.wait().success(), "{}", server.text());
    let mut traced = 0;
    for s in samplers {
        // A sampler still retrying is ended by SIGTERM, and says what it
        // traced as it goes; any other end must be a success.
        let mut s = s;
        let deadline = Instant::now() + Duration::from_secs(15);
        while s.try_wait().is_none() && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(100));
        }
        if s.try_wait().is_none() {
            s.signal(libc::SIGTERM);
        }
        let o = s.finish();
        assert!(o.status.success() || o.status.code() == Some(143), "{}", text(&o));
        traced += traced_rays(&String::from_utf8_lossy(&o.stdout))
            .unwrap_or_else(|| panic!("a sampler did not say what it traced: {}", text(&o)));
    }
    assert_clean(file);
    let (rays, copies, alike) = duplicates(file);
    eprintln!("{what}: {alike} rays equal to another of their beam by chance, none in a run");
    assert_eq!(copies, 0, "{what}: rays stored twice");
    let stored = rays - initial;
    assert!(stored <= traced, "{what}: {stored} rays stored, only {traced} traced");
    let lost = traced - stored;
    eprintln!("{what}: {traced} rays traced, {stored} stored, {lost} lost in flight, none stored twice");
    Account { stored, lost }
}

/// A server of a small room file reporting every second, with `extra`
/// flags: its folder (kept while the test runs), file, process, address,
/// and the rays the file held before it started.
fn served(extra: &[&str]) -> (tempfile::TempDir, std::path::PathBuf, Proc, String, u64) {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let initial = rays_in(&file);
    let mut flags = vec!["--report", "1s"];
    flags.extend_from_slice(extra);
    let (server, addr) = start_server_with(file.to_str().unwrap(), "127.0.0.1:0", TOKEN, &flags);
    (dir, file, server, addr, initial)
}

#[test]
fn latency_and_a_slow_link_slow_the_fill_and_lose_nothing() {
    let (_dir, file, server, addr, initial) = served(&[]);
    let proxy = Proxy::start(&addr);
    proxy.set(Faults {
        latency: Duration::from_millis(50),
        bandwidth: 200 << 10,
        partitioned: false,
    });
    let samplers = vec![
        sampler_via(&proxy.addr, &file, 1, RETRY),
        sampler_via(&proxy.addr, &file, 2, RETRY),
    ];
    let mut from = 0;
    let took = resumes(&server, &mut from, 5_000, "a fill over 50 ms and 200 KiB/s");
    eprintln!("latency 50 ms, 200 KiB/s: 5,000 rays stored in {took:.1?}");
    display_is_served(&addr);
    let account = close_and_check(server, &addr, samplers, &file, initial, "latency and a slow link");
    // No connection broke: every ray traced was stored.
    assert_eq!(account.lost, 0);
    assert!(account.stored >= 5_000);
}

#[test]
fn after_every_connection_is_reset_and_a_30_s_partition_the_fill_resumes() {
    let (_dir, file, server, addr, initial) = served(&["--stall-timeout", "5s"]);
    let proxy = Proxy::start(&addr);
    // Longer than the partition: they keep trying across it.
    let samplers = vec![
        sampler_via(&proxy.addr, &file, 1, "60s"),
        sampler_via(&proxy.addr, &file, 2, "60s"),
    ];
    let mut from = 0;
    resumes(&server, &mut from, 10_000, "the fill through the proxy");
    // Every connection reset: the samplers reconnect and go on.
    proxy.reset_all();
    let took = resumes(&server, &mut from, 10_000, "the fill after every connection was reset");
    eprintln!("connections reset: 10,000 more rays stored {took:.1?} later");
    // A partition: nothing gets through for 30 s, no connection closes.
    proxy.set(Faults {
        partitioned: true,
        ..Faults::default()
    });
    let start = Instant::now();
    let before = proxy.delivered();
    // The server drops the silent samplers (their work goes back to the
    // schedule) and keeps answering a display the whole time.
    while start.elapsed() < Duration::from_secs(30) {
        display_is_served(&addr);
        std::thread::sleep(Duration::from_secs(2));
    }
    assert_eq!(proxy.delivered(), before, "nothing crossed the partition");
    proxy.set(Faults::default());
    let took = resumes(&server, &mut from, 10_000, "the fill after a 30 s partition");
    eprintln!("30 s partition healed: 10,000 more rays stored {took:.1?} later");
    let account = close_and_check(server, &addr, samplers, &file, initial, "resets and a partition");
    assert!(account.stored >= 30_000);
}

#[test]
fn a_frozen_sampler_host_loses_its_work_to_the_others() {
    let (_dir, file, server, addr, initial) = served(&["--stall-timeout", "3s"]);
    let frozen = sampler_via(&addr, &file, 1, RETRY);
    let mut samplers = vec![sampler_via(&addr, &file, 2, RETRY)];
    let mut from = 0;
    resumes(&server, &mut from, 5_000, "the fill by two samplers");
    frozen.signal(libc::SIGSTOP);
    let start = Instant::now();
    let mut at = 0;
    server.wait_line("the frozen sampler dropped", &mut at, |l| {
        (l.contains("no results for") || l.contains("stopped")).then_some(())
    });
    eprintln!("a sampler frozen by SIGSTOP: dropped after {:.1?}", start.elapsed());
    let took = resumes(&server, &mut from, 5_000, "the fill by the other sampler");
    eprintln!("its work traced by the other: 5,000 more rays {took:.1?} later");
    display_is_served(&addr);
    frozen.signal(libc::SIGCONT);
    samplers.push(frozen);
    let account = close_and_check(server, &addr, samplers, &file, initial, "a frozen sampler");
    assert!(account.stored >= 10_000);
}

/// Two network namespaces joined by a veth pair (the server's end
/// 10.77.N.1, the samplers' 10.77.N.2), deleted again when dropped; `None`
/// where this process may not make namespaces (no root, no CAP_NET_ADMIN).
struct Namespaces {
    server: String,
    samplers: String,
}

impl Namespaces {
    fn make() -> Option<Namespaces> {
        let id = std::process::id() % 200 + 20;
        let ns = Namespaces {
            server: format!("hd-srv-{id}"),
            samplers: format!("hd-smp-{id}"),
        };
        let ip = |args: &[&str]| {
            std::process::Command::new("ip")
                .args(args)
                .output()
                .is_ok_and(|o| o.status.success())
        };
        if !ip(&["netns", "add", &ns.server]) {
            return None;
        }
        let (a, b) = (format!("hdva{id}"), format!("hdvb{id}"));
        let ok = ip(&["netns", "add", &ns.samplers])
            && ip(&["link", "add", &a, "type", "veth", "peer", "name", &b])
            && ip(&["link", "set", &a, "netns", &ns.server])
            && ip(&["link", "set", &b, "netns", &ns.samplers])
            && [(&ns.server, &a, 1), (&ns.samplers, &b, 2)]
                .iter()
                .all(|(n, dev, host)| {
                    let addr = format!("10.77.{id}.{host}/24");
                    ip(&["-n", n, "addr", "add", &addr, "dev", dev])
                        && ip(&["-n", n, "link", "set", dev, "up"])
                        && ip(&["-n", n, "link", "set", "lo", "up"])
                });
        ok.then_some(ns)
    }

    /// The server's address across the pair.
    fn server_addr(&self) -> String {
        let id = self.server.rsplit('-').next().unwrap_or("0");
        format!("10.77.{id}.1:7777")
    }

    /// `holodeck ARGS` inside namespace `ns`.
    fn holodeck(ns: &str) -> std::process::Command {
        let mut c = std::process::Command::new("ip");
        c.args(["netns", "exec", ns, env!("CARGO_BIN_EXE_holodeck")]);
        c
    }
}

impl Drop for Namespaces {
    fn drop(&mut self) {
        for n in [&self.server, &self.samplers] {
            let _ = std::process::Command::new("ip").args(["netns", "del", n]).output();
        }
    }
}

#[test]
fn samplers_in_another_network_namespace_fill_over_tls() {
    let Some(ns) = Namespaces::make() else {
        eprintln!("this process cannot make network namespaces (it needs CAP_NET_ADMIN): skipped");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let f = file.to_str().unwrap();
    let addr = ns.server_addr();
    let server = Proc::start(
        Namespaces::holodeck(&ns.server)
            .args(["serve", f, "--listen", &addr, "--token", TOKEN, "--report", "1s"])
            .env("NO_COLOR", "1"),
    );
    server.wait_line("the server listening", &mut 0, |l| {
        l.starts_with("listening on ").then_some(())
    });
    let writer = format!("{f}.writer.token");
    let sampler =
        |seed: u32| Proc::start(Namespaces::holodeck(&ns.samplers).args(sampler_args(&addr, &writer, "5s", seed)));
    let samplers = vec![sampler(1), sampler(2)];
    let mut from = 0;
    let took = resumes(&server, &mut from, 10_000, "samplers across the veth pair");
    eprintln!("another namespace, over TLS: 10,000 rays stored in {took:.1?}");
    // `admin status` from the samplers' namespace with the token alone.
    let status = |extra: &[&str]| {
        let args = ["admin", "--connect", &addr, "--token", TOKEN]
            .into_iter()
            .chain(extra.iter().copied());
        crate::common::process::run(Namespaces::holodeck(&ns.samplers).args(args.chain(["status"])))
    };
    // A token alone is not sent across: another host, and nothing pinned.
    let o = status(&[]);
    assert!(!o.status.success());
    assert!(text(&o).contains("clear text"), "{}", text(&o));
    // Plain text insisted on: the server refuses it from another host.
    let o = status(&["--plain-text"]);
    assert!(!o.status.success());
    assert!(text(&o).contains("over TLS only"), "{}", text(&o));
    // The admin token with the certificate pinned by hand: quit, over TLS.
    let writer_file = std::fs::read_to_string(&writer).unwrap();
    let pin = writer_file
        .lines()
        .find_map(|l| l.strip_prefix("tls-sha256 "))
        .unwrap_or_else(|| panic!("the writer token file pins no certificate: {writer_file:?}"));
    let o = crate::common::process::run(Namespaces::holodeck(&ns.samplers).args([
        "admin",
        "--connect",
        &addr,
        "--token",
        TOKEN,
        "--tls-fingerprint",
        pin,
        "quit",
    ]));
    assert!(o.status.success(), "{}", text(&o));
    let mut server = server;
    assert!(server.wait().success(), "{}", server.text());
    for s in samplers {
        let o = s.finish();
        assert!(o.status.success(), "{}", text(&o));
    }
    assert_clean(&file);
    let (rays, copies, alike) = duplicates(&file);
    eprintln!("another namespace: {rays} rays stored, {copies} stored twice, {alike} equal to another by chance");
    assert_eq!(copies, 0);
}
