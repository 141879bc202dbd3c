//! The networked holodeck with real processes on loopback: a server, sampler
//! workers (one killed with SIGKILL mid-run), refused peers, a display, quit.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use holodeck_protocol::wire::{Control, EyePoint, Frame, FrameLink, Hello, Message, Role, PROTOCOL_VERSION};
use holodeck_protocol::BeamKey;
use holodeck_sampler::worker::{connect, ServerStream};
use holodeck_server::{HoloFile, OpenOptions};

mod common;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_holodeck"))
}

fn sampler(addr: &str, token: &str, scene: &[&str]) -> Child {
    bin()
        .arg("sample")
        .args(scene)
        .args([
            "--connect",
            addr,
            "--token",
            token,
            "-j",
            "1",
            "--bounces",
            "2",
            "--retry-for",
            "0s",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// A raw client: handshake as `role`, then exchange frames.
struct Client {
    link: FrameLink<Box<dyn ServerStream>>,
}

impl Client {
    fn connect(addr: &str, role: Role, token: &str) -> (Client, Frame) {
        Client::hello(addr, role, token, PROTOCOL_VERSION)
    }
    fn hello(addr: &str, role: Role, token: &str, version: u32) -> (Client, Frame) {
        let mut c = Client::raw(addr);
        let hello = Hello {
            version,
            role,
            scene: String::new(),
            token: token.into(),
            read_only: false,
        };
        c.send(&Frame::Message(Message::Hello(hello)));
        let answer = c.recv();
        (c, answer)
    }
    fn raw(addr: &str) -> Client {
        let stream = connect(addr).unwrap();
        Client {
            link: FrameLink::new(stream),
        }
    }
    fn send(&mut self, f: &Frame) {
        self.link.write(f).unwrap();
        self.link.flush().unwrap();
    }
    fn recv(&mut self) -> Frame {
        self.link.read().unwrap().expect("server closed the connection")
    }
    /// Asks for beams (replacing earlier requests) and collects every
    /// stored ray that arrives up to the server's Delivered mark: (beam,
    /// rays) per Beam frame.
    fn request(&mut self, beams: &[(BeamKey, u32)], eye: Option<EyePoint>) -> Vec<(BeamKey, usize)> {
        self.request_with(beams, eye, true)
    }
    /// [`Client::request`] that, without `resend`, gets only rays this
    /// connection was not sent before.
    fn request_with(&mut self, beams: &[(BeamKey, u32)], eye: Option<EyePoint>, resend: bool) -> Vec<(BeamKey, usize)> {
        self.send(&Frame::Message(Message::BeamRequest {
            beams: beams.to_vec(),
            eye,
            replace: true,
            resend,
        }));
        let mut got = Vec::new();
        loop {
            match self.recv() {
                Frame::Beam { key, records } => got.push((key, records.len())),
                Frame::Message(Message::Delivered { beams, rays }) => {
                    let sum: usize = got.iter().map(|g| g.1).sum();
                    assert!(sum as u64 >= rays && got.len() >= beams as usize);
                    return got;
                }
                other => panic!("expected beam data, got {other:?}"),
            }
        }
    }
}

#[test]
fn server_samplers_display_and_quit() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let f = file.to_str().unwrap();
    let token = "test-token";
    let (mut server, addr) = start_server(f, "127.0.0.1:0", token);

    // Refused peers: wrong token, wrong scene, garbage. The server keeps serving.
    let bad_token = sampler(&addr, "nope", &["builtin:room"]).wait_with_output().unwrap();
    assert!(!bad_token.status.success());
    assert!(String::from_utf8_lossy(&bad_token.stderr).contains("wrong access token"));
    let bad_scene = sampler(&addr, token, &["builtin:landscape", "--triangles", "2000"])
        .wait_with_output()
        .unwrap();
    assert!(String::from_utf8_lossy(&bad_scene.stderr).contains("does not match the holodeck's scene"));
    let mut garbage = TcpStream::connect(&addr).unwrap();
    garbage.write_all(&[0xff; 64]).unwrap();
    drop(garbage);

    // A future protocol version and an oversized frame are refused too.
    {
        let (_, answer) = Client::hello(&addr, Role::Display, token, PROTOCOL_VERSION + 1);
        match answer {
            Frame::Message(Message::Refused { reason }) => assert!(reason.contains("protocol version"), "{reason}"),
            other => panic!("{other:?}"),
        }
        let mut raw = TcpStream::connect(&addr).unwrap();
        raw.write_all(&[0xff, 0xff, 0xff, 0x7f, 0]).unwrap();
        let mut c = Client {
            link: FrameLink::new(Box::new(raw)),
        };
        match c.recv() {
            Frame::Message(Message::Refused { reason }) => assert!(reason.contains("larger than"), "{reason}"),
            other => panic!("{other:?}"),
        }
    }

    // Two samplers fill; one is killed mid-run and the other carries on.
    let mut a = sampler(&addr, token, &["builtin:room"]);
    let b = sampler(&addr, token, &["builtin:room"]);
    std::thread::sleep(Duration::from_millis(1500));
    a.kill().unwrap(); // SIGKILL
    a.wait().unwrap();
    std::thread::sleep(Duration::from_millis(1500));

    // A display asks for beams and gets them.
    let (mut display, welcome) = Client::connect(&addr, Role::Display, token);
    let Frame::Message(Message::Welcome { sections, .. }) = welcome else {
        panic!("{welcome:?}")
    };
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
    assert!(sections[0].grid[0] > 0);

    // An admin quits: the server flushes and exits; the surviving sampler ends cleanly.
    let (mut admin, _) = Client::connect(&addr, Role::Admin, token);
    admin.send(&Frame::Message(Message::Control(Control::Quit)));
    let start = Instant::now();
    let status = loop {
        if let Some(s) = server.try_wait().unwrap() {
            break s;
        }
        assert!(start.elapsed() < Duration::from_secs(20), "the server did not stop");
        std::thread::sleep(Duration::from_millis(50));
    };
    assert!(status.success());
    let b = b.wait_with_output().unwrap();
    assert!(b.status.success(), "{}", String::from_utf8_lossy(&b.stderr));

    let hdk = HoloFile::open(&file, &OpenOptions::read_only()).unwrap();
    let stored = hdk.summary().rays();
    assert!(stored > 5_000, "the samplers' rays were stored ({stored})");
    assert_clean(&file);
}

/// A holodeck file of the built-in room that records its scene.
fn small_room(dir: &std::path::Path) -> std::path::PathBuf {
    let file = dir.join("room.hdk");
    let o = bin()
        .args([
            "fill",
            "builtin:room",
            file.to_str().unwrap(),
            "--rays",
            "1K",
            "--bounces",
            "0",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    file
}

/// Starts `holodeck serve` and returns it with the address it listens on.
fn start_server(f: &str, addr: &str, token: &str) -> (Server, String) {
    start_server_with(f, addr, token, &[])
}

/// Starts `holodeck serve` with more flags.
fn start_server_with(f: &str, addr: &str, token: &str, extra: &[&str]) -> (Server, String) {
    let mut server = bin()
        .args(["serve", f, "--listen", addr, "--token", token])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(server.stdout.as_mut().unwrap())
        .read_line(&mut line)
        .unwrap();
    let addr = line
        .trim()
        .strip_prefix("listening on ")
        .expect("the server prints its address")
        .to_string();
    (Server(server), addr)
}

/// A server process that is killed if a failing test leaves it running.
struct Server(Child);

impl std::ops::Deref for Server {
    type Target = Child;
    fn deref(&self) -> &Child {
        &self.0
    }
}

impl std::ops::DerefMut for Server {
    fn deref_mut(&mut self) -> &mut Child {
        &mut self.0
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if self.0.try_wait().ok().flatten().is_none() {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
}

#[test]
fn a_killed_server_restarts_on_its_file_and_workers_come_back() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let f = file.to_str().unwrap();
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let addr = format!("127.0.0.1:{port}");
    let token = "t";
    let (mut first, _) = start_server(f, &addr, token);
    let mut worker = bin()
        .args([
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
        ])
        .args(["--retry-for", "30s"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Long enough for a periodic flush (every 2 s) to commit some rays.
    std::thread::sleep(Duration::from_millis(3500));
    first.kill().unwrap(); // SIGKILL: no flush, no goodbye
    first.wait().unwrap();

    let after_crash = rays_in(&file);
    assert!(
        after_crash > 1_000,
        "rays flushed before the crash survive ({after_crash})"
    );
    assert_clean(&file);

    // Same file, same address: the worker reconnects by itself.
    let (mut second, _) = start_server(f, &addr, token);
    std::thread::sleep(Duration::from_millis(3000));
    let (mut admin, _) = Client::connect(&addr, Role::Admin, token);
    admin.send(&Frame::Message(Message::Control(Control::Quit)));
    assert!(second.wait().unwrap().success());
    worker.kill().unwrap();
    worker.wait().unwrap();
    let finally = rays_in(&file);
    assert!(
        finally > after_crash,
        "the worker came back to the restarted server ({after_crash} -> {finally})"
    );
    assert_clean(&file);
}

#[test]
fn run_fills_with_local_samplers_and_stops_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let o = bin()
        .args([
            "run",
            "builtin:room",
            file.to_str().unwrap(),
            "-n",
            "2",
            "--time",
            "2s",
            "--bounces",
            "0",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("rays added"));
    let mut hdk = HoloFile::open(&file, &OpenOptions::read_only()).unwrap();
    let rays = hdk.summary().rays();
    assert!(rays > 10_000, "{rays}");
    // What the two sampler processes sent is what the scene shows along those rays.
    let (checked, lights) = common::check_rays_against_room(&mut hdk);
    assert_eq!(checked, rays);
    assert!(lights > 0);
    drop(hdk);
    assert_clean(&file);
    // With a display: it walks two views and draws frames while samplers fill.
    let views = dir.path().join("walk.vf");
    std::fs::write(
        &views,
        "-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56\n-vp 1.2 2 1.5\n",
    )
    .unwrap();
    let frames = dir.path().join("frames");
    let o = bin()
        .args([
            "run",
            "builtin:room",
            file.to_str().unwrap(),
            "--time",
            "3s",
            "--bounces",
            "1",
        ])
        .args([
            "-o",
            "quadtree",
            "-x",
            "64",
            "-y",
            "48",
            "--views",
            views.to_str().unwrap(),
        ])
        .arg("--frames")
        .arg(&frames)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    for f in ["view0001_00.png", "view0001_02.png", "view0002_02.png"] {
        assert!(frames.join(f).exists(), "{f}: {stdout}");
    }
    let o = bin()
        .args([
            "run",
            "builtin:room",
            file.to_str().unwrap(),
            "--time",
            "1s",
            "-o",
            "mesh",
        ])
        .output()
        .unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("GPU front end"));
}

#[test]
fn serve_reports_progress_and_stops_when_its_time_is_up() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let f = file.to_str().unwrap();
    let token = "t";
    let mut server = bin()
        .args([
            "serve",
            f,
            "--listen",
            "127.0.0.1:0",
            "--token",
            token,
            "--time",
            "3s",
            "--report",
            "0.5s",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut out = BufReader::new(server.stdout.take().unwrap());
    let mut line = String::new();
    out.read_line(&mut line).unwrap();
    let addr = line.trim().strip_prefix("listening on ").unwrap().to_string();
    let worker = sampler(&addr, token, &["builtin:room"]);
    let start = Instant::now();
    let mut rest = String::new();
    out.read_to_string(&mut rest).unwrap(); // ends when the server exits
    assert!(server.wait().unwrap().success());
    assert!(start.elapsed() < Duration::from_secs(15), "TIME stops the server");
    let progress: Vec<&str> = rest.lines().filter(|l| l.starts_with("progress:")).collect();
    assert!(progress.len() >= 3, "{rest}");
    assert!(progress.last().unwrap().contains("rays/s"), "{rest}");
    assert!(worker.wait_with_output().unwrap().status.success());
}

/// Rays received after a request's immediate transfer until every beam holds
/// `want` counting the `base` rays it held before.
fn collect_until(
    client: &mut Client,
    want: &[(BeamKey, u32)],
    have: &mut std::collections::HashMap<BeamKey, Vec<holodeck_protocol::RayRecord>>,
    base: &std::collections::HashMap<BeamKey, usize>,
) {
    let held = |have: &std::collections::HashMap<BeamKey, Vec<_>>, k: &BeamKey| {
        have.get(k).map_or(0, Vec::len) + base.get(k).copied().unwrap_or(0)
    };
    let start = Instant::now();
    while want.iter().any(|(k, n)| held(have, k) < *n as usize) {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "requested rays did not all arrive"
        );
        match client.recv() {
            Frame::Beam { key, records } => have.entry(key).or_default().extend(records),
            other => panic!("expected beam data, got {other:?}"),
        }
    }
    for (k, n) in want {
        assert_eq!(held(have, k), *n as usize, "{k:?}: exactly the rays asked for");
    }
}

#[test]
fn display_requests_are_traced_near_the_eye_and_streamed_over_a_unix_socket() {
    use holodeck_protocol::{Section, View, ViewBeams};
    use std::collections::HashMap;
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let sock = dir.path().join("room.sock");
    let token = "t";
    let mut server = bin()
        .args([
            "serve",
            file.to_str().unwrap(),
            "--listen",
            "127.0.0.1:0",
            "--token",
            token,
            "--no-fill",
        ])
        .args(["--unix", sock.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map(Server)
        .unwrap();
    let mut out = BufReader::new(server.stdout.take().unwrap());
    let (mut l1, mut l2) = (String::new(), String::new());
    out.read_line(&mut l1).unwrap();
    out.read_line(&mut l2).unwrap();
    let unix = format!("unix:{}", sock.display());
    assert_eq!(l2.trim(), format!("listening on {unix}"));
    let worker = sampler(&unix, token, &["builtin:room"]);

    let (mut display, welcome) = Client::connect(&unix, Role::Display, token);
    let Frame::Message(Message::Welcome { sections, .. }) = welcome else {
        panic!("{welcome:?}")
    };
    let sections: Vec<Section> = sections.into_iter().map(|s| Section::try_from(s).unwrap()).collect();
    let s = &sections[0];
    let eye = s.origin() + (s.axes()[0] + s.axes()[1] + s.axes()[2]) * 0.5;
    let view = View::parse(&format!(
        "-vtv -vp {} {} {} -vd 1 0.2 0 -vu 0 0 1 -vh 40 -vv 30",
        eye.x, eye.y, eye.z
    ))
    .unwrap();
    let seen = ViewBeams::select(&sections, &view, 6, 4, 1);
    let (near, far): (Vec<_>, Vec<_>) = seen
        .counts
        .iter()
        .map(|c| c.0)
        .take(24)
        .enumerate()
        .partition(|(i, _)| i % 2 == 0);
    let radius = 0.004 * s.diagonal();
    let eye_point = EyePoint {
        position: eye.to_array(),
        radius,
        frustum: None,
    };

    // Near-eye requests first; every beam must reach 60 rays, traced for us and streamed.
    let want_near: Vec<(BeamKey, u32)> = near.iter().map(|(_, k)| (*k, 60)).collect();
    let mut have: HashMap<BeamKey, Vec<holodeck_protocol::RayRecord>> = HashMap::new();
    let base: HashMap<BeamKey, usize> = display.request(&want_near, Some(eye_point)).into_iter().collect();
    collect_until(&mut display, &want_near, &mut have, &base);
    // Then the same number of uniform rays for the other beams, on a new request.
    let want_far: Vec<(BeamKey, u32)> = far.iter().map(|(_, k)| (*k, 60)).collect();
    let mut have_far: HashMap<BeamKey, Vec<holodeck_protocol::RayRecord>> = HashMap::new();
    let base: HashMap<BeamKey, usize> = display.request(&want_far, None).into_iter().collect();
    collect_until(&mut display, &want_far, &mut have_far, &base);

    // How close do the rays pass to the eye?
    let near_fraction = |rays: &HashMap<BeamKey, Vec<holodeck_protocol::RayRecord>>| {
        let (mut close, mut all) = (0usize, 0usize);
        for (k, recs) in rays {
            for r in recs {
                let d = s.decode_record(k.beam, r).unwrap();
                let miss = (eye - d.ray.origin).cross(d.ray.direction).length();
                close += usize::from(miss <= radius * 1.01);
                all += 1;
            }
        }
        close as f64 / all.max(1) as f64
    };
    let (fn_, ff) = (near_fraction(&have), near_fraction(&have_far));
    eprintln!("near-eye fraction: proximity {fn_:.3}, uniform {ff:.3}");
    assert!(
        fn_ > 0.6,
        "proximity sampling: {fn_:.2} of the rays pass within the radius"
    );
    assert!(
        fn_ > 3.0 * ff,
        "uniform sampling passes near the eye far less often ({fn_:.2} vs {ff:.2})"
    );

    // Nothing but requests was traced: the file holds exactly what was asked for.
    let (mut admin, _) = Client::connect(&unix, Role::Admin, token);
    admin.send(&Frame::Message(Message::Control(Control::Quit)));
    assert!(server.wait().unwrap().success());
    assert!(!sock.exists(), "the socket file is removed");
    worker.wait_with_output().unwrap();
    let hdk = HoloFile::open(&file, &OpenOptions::read_only()).unwrap();
    for (k, _) in want_near.iter().chain(&want_far) {
        assert_eq!(hdk.beam_len(*k).unwrap(), 60, "{k:?}");
    }
}

/// Rays that arrive for the current request within `within` (the socket has
/// a short read timeout, so an empty spell ends the wait too).
fn arriving(client: &mut Client, within: Duration) -> usize {
    let start = Instant::now();
    let mut n = 0;
    while start.elapsed() < within {
        match client.link.read() {
            Ok(Some(Frame::Beam { records, .. })) => n += records.len(),
            Ok(Some(other)) => panic!("{other:?}"),
            Ok(None) => break,
            Err(e) if e.is_gone() => break,
            Err(_) => {} // timed out: look again
        }
    }
    n
}

#[test]
fn admins_pause_resume_kill_restart_and_clobber_and_diskspace_stops_the_fill() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let f = file.to_str().unwrap();
    let token = "t";
    let (mut server, addr) = start_server(f, "127.0.0.1:0", token);
    let worker = sampler(&addr, token, &["builtin:room"]);
    let (mut admin, _) = Client::connect(&addr, Role::Admin, token);

    // Paused: no packets go out, so a display's request gets nothing new.
    admin.send(&Frame::Message(Message::Control(Control::Pause)));
    std::thread::sleep(Duration::from_millis(500)); // packets already out drain
    let tcp = TcpStream::connect(&addr).unwrap();
    let timeouts = tcp.try_clone().unwrap();
    let mut display = Client {
        link: FrameLink::new(Box::new(tcp)),
    };
    let hello = Hello {
        version: PROTOCOL_VERSION,
        role: Role::Display,
        scene: String::new(),
        token: token.into(),
        read_only: true,
    };
    display.send(&Frame::Message(Message::Hello(hello)));
    assert!(matches!(display.recv(), Frame::Message(Message::Welcome { .. })));
    let want: Vec<(BeamKey, u32)> = (0..8).map(|b| (BeamKey::new(0, 1000 + b), 40)).collect();
    display.request(&want, None);
    timeouts.set_read_timeout(Some(Duration::from_millis(100))).unwrap();
    assert_eq!(
        arriving(&mut display, Duration::from_millis(800)),
        0,
        "nothing traced while paused"
    );
    admin.send(&Frame::Message(Message::Control(Control::Resume)));
    let (start, mut resumed) = (Instant::now(), 0);
    while resumed == 0 && start.elapsed() < Duration::from_secs(20) {
        resumed += arriving(&mut display, Duration::from_millis(500));
    }
    assert!(resumed > 0, "resume hands work out again");
    // This display is read-only: it may not quit the server.
    timeouts.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    display.send(&Frame::Message(Message::Control(Control::Quit)));
    loop {
        match display.recv() {
            Frame::Beam { .. } => continue,
            Frame::Message(Message::Error { message }) => {
                assert!(message.contains("read-only"), "{message}");
                break;
            }
            other => panic!("{other:?}"),
        }
    }

    // KillSamplers disconnects them and keeps new ones out until Restart.
    admin.send(&Frame::Message(Message::Control(Control::KillSamplers)));
    let out = worker.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let refused = sampler(&addr, token, &["builtin:room"]).wait_with_output().unwrap();
    assert!(
        String::from_utf8_lossy(&refused.stderr).contains("restart"),
        "{}",
        String::from_utf8_lossy(&refused.stderr)
    );

    // Clobber empties the file (no sampler is running to refill it).
    // Every beam, wanting nothing more: the answer is everything stored.
    let beams = match display_sections(&addr, token) {
        n if n > 0 => n,
        _ => panic!("no beams"),
    };
    let others: Vec<(BeamKey, u32)> = (0..beams).map(|b| (BeamKey::new(0, b), 0)).collect();
    let held = |got: Vec<(BeamKey, usize)>| got.iter().map(|g| g.1).sum::<usize>();
    let before = held(display.request(&others, None));
    admin.send(&Frame::Message(Message::Control(Control::Clobber)));
    // The command is carried out when the server gets to it (a loaded machine
    // may take a while).
    let start = Instant::now();
    let mut after = before;
    while after * 2 >= before && start.elapsed() < Duration::from_secs(20) {
        std::thread::sleep(Duration::from_millis(100));
        after = after.min(held(display.request(&others, None)));
    }
    assert!(
        after * 2 < before,
        "the beams were emptied ({before} rays, then {after})"
    );

    // Restart lets samplers in again, and the fill goes on.
    admin.send(&Frame::Message(Message::Control(Control::Restart)));
    let start = Instant::now();
    let mut again = sampler(&addr, token, &["builtin:room"]);
    while held(display.request(&others, None)) <= after {
        assert!(start.elapsed() < Duration::from_secs(30), "no fill after a restart");
        if again.try_wait().unwrap().is_some() {
            // It came before the restart did, and was refused: try again.
            again = sampler(&addr, token, &["builtin:room"]);
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    admin.send(&Frame::Message(Message::Control(Control::Quit)));
    assert!(server.wait().unwrap().success());
    again.wait_with_output().unwrap();
    let after_clobber = rays_in(&file);
    assert_clean(&file);

    // DISKSPACE: a server whose file may grow by 1.5 MiB stops by itself within it.
    let limit = std::fs::metadata(&file).unwrap().len() + (3 << 19);
    let (mut server, addr) = start_server_with(f, "127.0.0.1:0", token, &["--diskspace", &limit.to_string()]);
    let w = sampler(&addr, token, &["builtin:room"]);
    let start = Instant::now();
    let status = loop {
        if let Some(s) = server.try_wait().unwrap() {
            break s;
        }
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "the server did not stop at DISKSPACE"
        );
        assert!(
            std::fs::metadata(&file).unwrap().len() <= limit,
            "the file grew past DISKSPACE"
        );
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(status.success());
    w.wait_with_output().unwrap();
    let size = std::fs::metadata(&file).unwrap().len();
    assert!(size <= limit, "{size} > {limit}");
    let rays = rays_in(&file);
    let before_fill = limit - (3 << 19);
    assert!(
        rays > after_clobber + 10_000 && size - before_fill > (3 << 19) * 3 / 5,
        "the fill used the space it had ({after_clobber} -> {rays} rays, {before_fill} -> {size} bytes of {limit})"
    );
    assert_clean(&file);
}

#[test]
fn a_display_only_server_replays_the_file_to_a_headless_view() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let o = bin()
        .args([
            "fill",
            "builtin:room",
            file.to_str().unwrap(),
            "--rays",
            "500K",
            "--bounces",
            "1",
        ])
        .output()
        .unwrap();
    assert!(o.status.success());
    let (mut server, addr) = start_server_with(file.to_str().unwrap(), "127.0.0.1:0", "t", &["--no-fill"]);
    let views = dir.path().join("v.vf");
    std::fs::write(
        &views,
        "-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56\n-vd 0 1 0\n",
    )
    .unwrap();
    let frames = dir.path().join("frames");
    let o = bin()
        .args(["view", "--connect", &addr, "--token", "t", "--headless", "--read-only"])
        .arg("--views")
        .arg(&views)
        .arg("-o")
        .arg(&frames)
        .args(["-x", "64", "-y", "48", "--format", "hdr"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    // One frame per view, each drawn from the stored samples alone.
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "{out}");
    for l in &lines {
        let n: u64 = l
            .split(" new samples")
            .next()
            .unwrap()
            .rsplit(' ')
            .next()
            .unwrap()
            .replace(',', "")
            .parse()
            .unwrap();
        assert!(n > 100, "{l}");
    }
    let p = holodeck_display::image_io::read_picture(&frames.join("view0002_00.hdr")).unwrap();
    assert!(p.pixels.iter().filter(|c| c.max_element() > 0.0).count() > p.pixels.len() / 2);
    // Read-only: the server is still there for the next display.
    assert!(server.try_wait().unwrap().is_none());
    // A beam asked for three times is sent once; a request for more beams
    // than the holodeck has is refused with a reason.
    let (mut display, _) = Client::connect(&addr, Role::Display, "t");
    let k = BeamKey::new(0, 4242);
    let got = display.request(&[(k, 5), (k, 9), (k, 7)], None);
    assert!(got.len() <= 1 && got.iter().all(|g| g.0 == k), "{got:?}");
    // What a display was sent is not sent again unless it asks to resend
    // (it keeps its estimates across views); beams it was never sent come whole.
    let seen: Vec<(BeamKey, u32)> = (0..40).map(|b| (BeamKey::new(0, b * 211), 1)).collect();
    let first: usize = display.request(&seen, None).iter().map(|g| g.1).sum();
    assert!(first > 0);
    let again: usize = display.request_with(&seen, None, false).iter().map(|g| g.1).sum();
    assert_eq!(again, 0, "a file with no samplers has nothing new");
    let more: Vec<(BeamKey, u32)> = (0..40).map(|b| (BeamKey::new(0, b * 211 + 5), 1)).collect();
    let fresh: usize = display.request_with(&more, None, false).iter().map(|g| g.1).sum();
    assert!(fresh > 0, "beams never sent come whole");
    let resent: usize = display.request_with(&seen, None, true).iter().map(|g| g.1).sum();
    assert_eq!(resent, first);
    display.send(&Frame::Message(Message::BeamRequest {
        beams: vec![(k, 1); 200_000],
        eye: None,
        replace: true,
        resend: false,
    }));
    match display.recv() {
        Frame::Message(Message::Error { message }) => assert!(message.contains("beams requested"), "{message}"),
        other => panic!("{other:?}"),
    }
    // Before its Hello, a peer may not send a big frame.
    let mut raw = TcpStream::connect(&addr).unwrap();
    let mut big = vec![0u8; 5 + (100 << 10)];
    big[..4].copy_from_slice(&((100u32 << 10) + 1).to_le_bytes());
    let _ = raw.write_all(&big);
    let mut c = Client {
        link: FrameLink::new(Box::new(raw)),
    };
    match c.recv() {
        Frame::Message(Message::Refused { reason }) => assert!(reason.contains("65536 allowed"), "{reason}"),
        other => panic!("{other:?}"),
    }
    let (mut admin, _) = Client::connect(&addr, Role::Admin, "t");
    admin.send(&Frame::Message(Message::Control(Control::Quit)));
    assert!(server.wait().unwrap().success());
}

/// The samples each frame line of `holodeck view` reports as new.
fn new_samples(out: &str) -> Vec<u64> {
    out.lines()
        .filter_map(|l| {
            l.split(" new samples")
                .next()?
                .rsplit(' ')
                .next()?
                .replace(',', "")
                .parse()
                .ok()
        })
        .collect()
}

#[test]
fn still_views_keep_converging_while_samplers_work() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let (mut server, addr) = start_server(file.to_str().unwrap(), "127.0.0.1:0", "t");
    let _samplers: Vec<Server> = (0..2).map(|_| Server(sampler(&addr, "t", &["builtin:room"]))).collect();
    // Two displays at once, each on its own still view for 6 s, two frames.
    let mut displays = Vec::new();
    for (i, spec) in [
        "-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56",
        "-vtv -vp 3 1 1.5 -vd 0 1 0 -vu 0 0 1 -vh 60 -vv 45",
    ]
    .iter()
    .enumerate()
    {
        let views = dir.path().join(format!("v{i}.vf"));
        std::fs::write(&views, format!("{spec}\n")).unwrap();
        let child = bin()
            .args(["view", "--connect", &addr, "--token", "t", "--headless"])
            .arg("--views")
            .arg(&views)
            .arg("-o")
            .arg(dir.path().join(format!("frames{i}")))
            .args([
                "-x", "32", "-y", "24", "--wait", "6s", "--steps", "2", "--format", "hdr",
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        displays.push(Server(child));
    }
    for mut d in displays {
        let mut out = String::new();
        d.stdout.take().unwrap().read_to_string(&mut out).unwrap();
        let status = d.wait().unwrap();
        assert!(status.success(), "{out}");
        let n = new_samples(&out);
        assert_eq!(n.len(), 3, "{out}");
        // The first density (one sample a pixel) is met early; the display
        // asks for more and samples keep coming in the second half.
        assert!(n[2] > 0, "nothing arrived in the second half: {out}");
        let total: u64 = n.iter().sum();
        assert!(
            total > 4 * 32 * 24,
            "the view asked for more than one sample a pixel: {out}"
        );
    }
    let (mut admin, _) = Client::connect(&addr, Role::Admin, "t");
    admin.send(&Frame::Message(Message::Control(Control::Quit)));
    assert!(server.wait().unwrap().success());
}

/// Rays a closed holodeck file holds.
fn rays_in(file: &std::path::Path) -> u64 {
    HoloFile::open(file, &OpenOptions::read_only())
        .unwrap()
        .summary()
        .rays()
}

/// The file passes a full check.
fn assert_clean(file: &std::path::Path) {
    assert!(holodeck_server::storage::check(file, |_, _| {}).unwrap().is_clean());
}

/// Beams of section 0 of the holodeck a server serves.
fn display_sections(addr: &str, token: &str) -> u32 {
    let (_, welcome) = Client::connect(addr, Role::Display, token);
    let Frame::Message(Message::Welcome { sections, .. }) = welcome else {
        panic!("{welcome:?}")
    };
    holodeck_protocol::Section::try_from(sections[0].clone())
        .unwrap()
        .beam_count()
}

#[test]
fn a_sampler_that_stops_answering_is_dropped_and_its_work_traced_by_another() {
    use std::collections::HashMap;
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let scene = HoloFile::open(&file, &OpenOptions::read_only())
        .unwrap()
        .settings()
        .scene
        .clone()
        .unwrap();
    let token = "t";
    let (mut server, addr) = start_server_with(
        file.to_str().unwrap(),
        "127.0.0.1:0",
        token,
        &["--no-fill", "--stall-timeout", "1s"],
    );
    // A "sampler" that takes packets and never answers (a stopped process).
    let mut silent = Client::raw(&addr);
    silent.send(&Frame::Message(Message::Hello(Hello {
        version: PROTOCOL_VERSION,
        role: Role::Sampler,
        scene,
        token: token.into(),
        read_only: true,
    })));
    assert!(matches!(silent.recv(), Frame::Message(Message::Welcome { .. })));
    let (mut display, _) = Client::connect(&addr, Role::Display, token);
    let want: Vec<(BeamKey, u32)> = (0..4).map(|b| (BeamKey::new(0, 3000 + 11 * b), 50)).collect();
    let base: HashMap<BeamKey, usize> = display.request(&want, None).into_iter().collect();
    assert!(
        matches!(silent.recv(), Frame::Message(Message::Trace(_))),
        "the work went to it"
    );
    // The server gives up on it: the connection ends.
    let start = Instant::now();
    while let Ok(Some(_)) = silent.link.read() {
        assert!(start.elapsed() < Duration::from_secs(20), "never dropped");
    }
    // Its packets were given back: a working sampler traces all of them.
    let worker = sampler(&addr, token, &["builtin:room"]);
    let mut have = HashMap::new();
    collect_until(&mut display, &want, &mut have, &base);
    let (mut admin, _) = Client::connect(&addr, Role::Admin, token);
    admin.send(&Frame::Message(Message::Control(Control::Quit)));
    assert!(server.wait().unwrap().success());
    worker.wait_with_output().unwrap();
}
