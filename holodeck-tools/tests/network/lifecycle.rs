//! A server's life: peers it refuses, samplers that come and die, a crash
//! and a restart on the same file, `holodeck run`, TIME, and the signals
//! that stop it. Whatever it reported stored must be in its file afterwards.

use std::io::Write;
use std::net::TcpStream;

use holodeck_file::{HoloFile, OpenOptions, StorageError};
use holodeck_protocol::wire::client::ClientError;
use holodeck_protocol::wire::{Frame, Message, Role, PROTOCOL_VERSION};
use holodeck_protocol::{BeamKey, Section};

use crate::common::process::Proc;
use crate::common::{check_rays_against_room, holodeck, text};
use crate::harness::*;

#[test]
fn server_samplers_display_and_quit() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let f = file.to_str().unwrap();
    let specs: Vec<_> = HoloFile::open(&file, &OpenOptions::read_only())
        .unwrap()
        .sections()
        .iter()
        .map(Section::spec)
        .collect();
    let initial = rays_in(&file);
    let token = "test-token";
    let (mut server, addr) = start_server_with(f, "127.0.0.1:0", token, &["--report", "0.2s"]);

    // Refused peers: wrong token, wrong scene, garbage. The server keeps serving.
    let bad_token = sampler(&addr, "nope", &["builtin:room"]).finish();
    assert!(
        !bad_token.status.success() && text(&bad_token).contains("wrong access token"),
        "{}",
        text(&bad_token)
    );
    let bad_scene = sampler(&addr, token, &["builtin:landscape", "--triangles", "2000"]).finish();
    assert!(
        !bad_scene.status.success() && text(&bad_scene).contains("does not match the holodeck's scene"),
        "{}",
        text(&bad_scene)
    );
    let mut garbage = TcpStream::connect(&addr).unwrap();
    garbage.write_all(&[0xff; 64]).unwrap();
    drop(garbage);

    // A future protocol version and an oversized frame are refused too.
    {
        match Client::hello(&addr, Role::Display, token, PROTOCOL_VERSION + 1, false) {
            Err(ClientError::Refused { reason, .. }) => assert!(reason.contains("protocol version"), "{reason}"),
            Err(e) => panic!("{e}"),
            Ok(_) => panic!("a future protocol version was welcomed"),
        }
        let mut raw = socket(&addr);
        raw.write_all(&[0xff, 0xff, 0xff, 0x7f, 0]).unwrap();
        match Client::over(raw).recv() {
            Frame::Message(Message::Refused { reason, .. }) => assert!(reason.contains("larger than"), "{reason}"),
            other => panic!("{other:?}"),
        }
    }

    // Two samplers fill; one is killed mid-run (both are at work once the
    // file has grown by a few packets) and the other carries on.
    let mut log = server.mark();
    let mut a = sampler(&addr, token, &["builtin:room"]);
    let b = sampler(&addr, token, &["builtin:room"]);
    reported_above(&server, &mut log, initial + 500, "both samplers at work");
    a.kill(); // SIGKILL
    let at_kill = next_report(&server, &mut log);
    reported_above(&server, &mut log, at_kill + 2_000, "the surviving sampler's rays");

    // A display asks for beams and gets them.
    let (mut display, welcome) = Client::connect(&addr, Role::Display, token);
    let sections: Vec<_> = welcome.sections.iter().map(Section::spec).collect();
    assert_eq!(sections, specs, "the display is told the file's sections");
    let keys: Vec<(BeamKey, u32)> = (0..50).map(|b| (BeamKey::new(0, b * 97), 10)).collect();
    let got = display.request(&keys, None);
    assert!(got.iter().all(|(k, _)| keys.iter().any(|w| w.0 == *k)));
    let rays: usize = got.iter().map(|g| g.1).sum();
    assert!(rays > 50, "the requested beams hold rays ({rays})");
    // A second display, asking for other beams at the same time, gets its own.
    let (mut other, _) = Client::connect(&addr, Role::Display, token);
    let theirs: Vec<(BeamKey, u32)> = (0..30).map(|b| (BeamKey::new(0, 13 + b * 101), 10)).collect();
    let got_theirs = other.request(&theirs, None);
    assert!(!got_theirs.is_empty());
    assert!(
        got_theirs.iter().all(|(k, _)| theirs.iter().any(|w| w.0 == *k)),
        "{got_theirs:?}"
    );
    let again = display.request(&keys, None);
    assert!(again.iter().all(|(k, _)| keys.iter().any(|w| w.0 == *k)), "{again:?}");

    // An admin quits: the server flushes and exits; the surviving sampler ends cleanly.
    quit(&addr, token);
    assert!(server.wait().success(), "{}", server.text());
    let b = b.finish();
    assert!(b.status.success(), "{}", text(&b));
    let closed = rays_at_close(&server);
    let reported = reports(&server);
    assert!(
        reported.iter().all(|r| *r <= closed),
        "every ray reported stored was kept: {reported:?}, {closed} at close"
    );
    assert_eq!(rays_in(&file), closed);
    assert_eq!(assert_clean(&file), closed);
}

#[test]
fn a_killed_server_restarts_on_its_file_and_workers_come_back() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let f = file.to_str().unwrap();
    let initial = rays_in(&file);
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let addr = format!("127.0.0.1:{port}");
    let token = "t";
    let (mut first, _) = start_server(f, &addr, token);
    let mut worker = Proc::start(bin().args([
        "sample",
        "builtin:room",
        "--connect",
        &addr,
        "--token",
        token,
        "-j",
        "1",
        "--bounces",
        "1",
        "--retry-for",
        "30s",
    ]));
    // A periodic flush (every 2 s) commits some of the worker's rays.
    let durable = first.wait_line("a periodic flush of the worker's rays", &mut 0, |l| {
        durable_rays(l).filter(|n| *n > initial)
    });
    first.kill(); // SIGKILL: no flush, no goodbye

    let after_crash = rays_in(&file);
    assert!(
        after_crash >= durable,
        "rays flushed before the crash survive ({durable} were durable, {after_crash} are in the file)"
    );
    assert_clean(&file);

    // Same file, same address: the worker reconnects by itself.
    let (mut second, _) = start_server(f, &addr, token);
    let came_back = second.wait_line("a periodic flush of rays traced after the restart", &mut 0, |l| {
        durable_rays(l).filter(|n| *n > after_crash)
    });
    quit(&addr, token);
    assert!(second.wait().success(), "{}", second.text());
    worker.kill();
    let finally = rays_in(&file);
    assert!(
        finally >= came_back,
        "the worker came back to the restarted server ({after_crash} -> {came_back} durable, {finally} in the file)"
    );
    assert_eq!(finally, rays_at_close(&second));
    assert_eq!(assert_clean(&file), finally);
}

#[test]
fn run_fills_with_local_samplers_and_stops_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    // Long enough never to end by itself: the test quits its server once
    // the samplers have stored enough, and `run` must then stop cleanly.
    let run = Proc::start(bin().args([
        "run",
        "builtin:room",
        file.to_str().unwrap(),
        "-n",
        "2",
        "--time",
        "10m",
        "--bounces",
        "0",
    ]));
    run_stores_then_quit(&run, &file, 10_000, "run's samplers at work");
    let o = run.finish();
    assert!(o.status.success(), "{}", text(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    let added: u64 = stdout
        .lines()
        .find_map(|l| {
            let head = l.split_once(" rays added")?.0;
            head.rsplit(' ').next()?.replace(',', "").parse().ok()
        })
        .unwrap_or_else(|| panic!("no count of rays added: {stdout}"));
    let mut hdk = HoloFile::open(&file, &OpenOptions::read_only()).unwrap();
    let rays = hdk.summary().rays();
    assert_eq!(added, rays, "run reports the rays its samplers added: {stdout}");
    assert!(rays > 10_000, "{rays}");
    // What the two sampler processes sent is what the scene shows along those rays.
    let (checked, lights) = check_rays_against_room(&mut hdk);
    assert_eq!(checked, rays);
    assert!(lights > 0);
    drop(hdk);
    assert_eq!(assert_clean(&file), rays);
    // With a display: it walks two views and draws frames while samplers
    // fill, for TIME (frames are drawn however few samples came).
    let views = dir.path().join("walk.vf");
    std::fs::write(
        &views,
        "-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56\n-vp 1.2 2 1.5\n",
    )
    .unwrap();
    let frames = dir.path().join("frames");
    let o = holodeck(&[
        "run",
        "builtin:room",
        file.to_str().unwrap(),
        "--time",
        "3s",
        "--bounces",
        "1",
        "-o",
        "quadtree",
        "--headless",
        "-x",
        "64",
        "-y",
        "48",
        "--views",
        views.to_str().unwrap(),
        "--frames",
        frames.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    for f in ["view0001_00.png", "view0001_02.png", "view0002_02.png"] {
        assert!(frames.join(f).exists(), "{f}: {stdout}");
    }
    let o = holodeck(&[
        "run",
        "builtin:room",
        file.to_str().unwrap(),
        "--time",
        "1s",
        "-o",
        "mesh",
        "--headless",
        "--frames",
        dir.path().join("mesh").to_str().unwrap(),
    ]);
    // The GPU drivers draw too (on Mesa's software Vulkan without a GPU).
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("pixel estimates"), "{}", text(&o));
    assert!(dir.path().join("mesh/view0001_00.png").exists());
}

/// A REPORT line, strictly: `progress: R rays, S rays/s, F of B beams hold
/// rays (P%), file N bytes, M free in K fragments`; returns (R, F, B).
fn parse_report(line: &str) -> Option<(u64, u64, u64)> {
    let rest = line.strip_prefix("progress: ")?;
    let (rays, rest) = rest.split_once(" rays, ")?;
    let (rate, rest) = rest.split_once(" rays/s, ")?;
    let (filled, rest) = rest.split_once(" of ")?;
    let (beams, rest) = rest.split_once(" beams hold rays (")?;
    let (percent, rest) = rest.split_once("%), file ")?;
    let (bytes, rest) = rest.split_once(" bytes, ")?;
    let (free, fragments) = rest.split_once(" free in ")?;
    let fragments = fragments.strip_suffix(" fragments")?;
    rate.parse::<f64>().ok()?;
    percent.parse::<f64>().ok()?;
    bytes.parse::<u64>().ok()?;
    free.parse::<u64>().ok()?;
    fragments.parse::<u64>().ok()?;
    Some((rays.parse().ok()?, filled.parse().ok()?, beams.parse().ok()?))
}

#[test]
fn serve_reports_progress_and_stops_when_its_time_is_up() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let f = file.to_str().unwrap();
    let beams = beams_of(&file);
    let token = "t";
    let (mut server, addr) = start_server_with(f, "127.0.0.1:0", token, &["--time", "6s", "--report", "0.5s"]);
    let worker = sampler(&addr, token, &["builtin:room"]);
    assert!(server.wait().success(), "{}", server.text());
    let out = server.text();
    assert!(out.contains("TIME is up"), "TIME stopped the server:\n{out}");
    let progress: Vec<&str> = out.lines().filter(|l| l.starts_with("progress:")).collect();
    assert!(progress.len() >= 2, "a report every 0.5 s of 6 s:\n{out}");
    let parsed: Vec<(u64, u64, u64)> = progress
        .iter()
        .map(|l| parse_report(l).unwrap_or_else(|| panic!("malformed report {l:?}")))
        .collect();
    for w in parsed.windows(2) {
        assert!(w[0].0 <= w[1].0 && w[0].1 <= w[1].1, "{out}");
    }
    assert!(parsed.iter().all(|p| p.2 == u64::from(beams) && p.1 <= p.2), "{out}");
    let closed = rays_at_close(&server);
    assert!(parsed.last().unwrap().0 <= closed, "{out}");
    assert_eq!(rays_in(&file), closed);
    let w = worker.finish();
    assert!(w.status.success(), "{}", text(&w));
}

/// A server stopped by `signal` flushes and closes: it exits with status 0
/// by itself, every ray it reported stored is in the file, and the file's
/// lock is released.
fn a_signal_makes_the_server_flush_and_close(signal: libc::c_int, name: &str) {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let f = file.to_str().unwrap();
    let initial = rays_in(&file);
    let token = "t";
    let (mut server, addr) = start_server_with(f, "127.0.0.1:0", token, &["--report", "0.2s"]);
    let worker = sampler(&addr, token, &["builtin:room"]);
    // While it serves, no other process may write the file.
    match HoloFile::open(&file, &OpenOptions::default()) {
        Err(StorageError::Locked { .. }) => {}
        Err(e) => panic!("expected the file to be locked: {e}"),
        Ok(_) => panic!("a second writer opened a file the server holds"),
    }
    let mut log = 0;
    let reported = reported_above(&server, &mut log, initial + 1_000, "the sampler's rays");
    server.signal(signal);
    let status = server.wait();
    let out = server.text();
    assert_eq!(status.code(), Some(0), "{name} stops the server cleanly:\n{out}");
    assert!(out.contains(&format!("{name}: stopping")), "{out}");
    assert!(out.contains(&format!("{f}: flushed and closed")), "{out}");
    let closed = rays_at_close(&server);
    let last = reports(&server).into_iter().max().unwrap_or(0);
    assert!(
        reported <= closed && last <= closed,
        "every ray reported stored ({last}) is in the file at close ({closed})"
    );
    // The lock is gone with the server: a writer opens the file at once.
    let hdk = HoloFile::open(&file, &OpenOptions::default()).unwrap_or_else(|e| panic!("after {name}: {e}"));
    assert_eq!(hdk.summary().rays(), closed);
    hdk.close().unwrap();
    assert_eq!(assert_clean(&file), closed);
    let w = worker.finish();
    assert!(w.status.success(), "{}", text(&w));
}

#[test]
fn sigterm_makes_the_server_flush_and_close() {
    a_signal_makes_the_server_flush_and_close(libc::SIGTERM, "SIGTERM");
}

#[test]
fn sigint_makes_the_server_flush_and_close() {
    a_signal_makes_the_server_flush_and_close(libc::SIGINT, "SIGINT");
}
