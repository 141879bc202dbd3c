//! The networked holodeck with real processes on loopback: a server, sampler
//! workers (one killed with SIGKILL mid-run), refused peers, a display, quit.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use holodeck_protocol::wire::{decode_frame, encode_frame, Control, Frame, Hello, Message, Role, PROTOCOL_VERSION};
use holodeck_protocol::BeamKey;
use holodeck_server::{HoloFile, OpenOptions};

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
    stream: TcpStream,
    buf: Vec<u8>,
}

impl Client {
    fn connect(addr: &str, role: Role, token: &str) -> (Client, Frame) {
        let stream = TcpStream::connect(addr).unwrap();
        stream.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
        let mut c = Client {
            stream,
            buf: Vec::new(),
        };
        let hello = Hello {
            version: PROTOCOL_VERSION,
            role,
            scene: String::new(),
            token: token.into(),
            read_only: false,
        };
        c.send(&Frame::Message(Message::Hello(hello)));
        let answer = c.recv();
        (c, answer)
    }
    fn send(&mut self, f: &Frame) {
        let mut out = Vec::new();
        encode_frame(f, &mut out).unwrap();
        self.stream.write_all(&out).unwrap();
    }
    fn recv(&mut self) -> Frame {
        loop {
            if let Some((f, used)) = decode_frame(&self.buf).unwrap() {
                self.buf.drain(..used);
                return f;
            }
            let mut chunk = [0u8; 65536];
            let n = self.stream.read(&mut chunk).unwrap();
            assert!(n > 0, "server closed the connection");
            self.buf.extend_from_slice(&chunk[..n]);
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
        let mut c = Client {
            stream: TcpStream::connect(&addr).unwrap(),
            buf: Vec::new(),
        };
        c.stream.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
        let hello = Hello {
            version: PROTOCOL_VERSION + 1,
            role: Role::Display,
            scene: String::new(),
            token: token.into(),
            read_only: true,
        };
        c.send(&Frame::Message(Message::Hello(hello)));
        match c.recv() {
            Frame::Message(Message::Refused { reason }) => assert!(reason.contains("protocol version"), "{reason}"),
            other => panic!("{other:?}"),
        }
        let mut c = Client {
            stream: TcpStream::connect(&addr).unwrap(),
            buf: Vec::new(),
        };
        c.stream.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
        c.stream.write_all(&[0xff, 0xff, 0xff, 0x7f, 0]).unwrap();
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
    display.send(&Frame::Message(Message::BeamRequest { beams: keys.clone() }));
    let mut rays = 0;
    for _ in 0..keys.len() {
        match display.recv() {
            Frame::Beam { key, records } => {
                assert!(keys.iter().any(|(k, _)| *k == key));
                rays += records.len();
            }
            other => panic!("expected beam data, got {other:?}"),
        }
    }
    assert!(rays > 50, "the requested beams hold rays ({rays})");
    // A second display, asking for other beams at the same time, gets its own.
    let (mut other, _) = Client::connect(&addr, Role::Display, token);
    let theirs: Vec<(BeamKey, u32)> = (0..30).map(|b| (BeamKey::new(0, 13 + b * 101), 10)).collect();
    other.send(&Frame::Message(Message::BeamRequest { beams: theirs.clone() }));
    display.send(&Frame::Message(Message::BeamRequest { beams: keys.clone() }));
    for (client, wanted) in [(&mut other, &theirs), (&mut display, &keys)] {
        for _ in 0..wanted.len() {
            match client.recv() {
                Frame::Beam { key, .. } => assert!(wanted.iter().any(|(k, _)| *k == key), "{key:?} was not asked for"),
                f => panic!("expected beam data, got {f:?}"),
            }
        }
    }
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
    assert!(holodeck_server::storage::check(&file, |_, _| {}).unwrap().is_clean());
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
fn start_server(f: &str, addr: &str, token: &str) -> (Child, String) {
    let mut server = bin()
        .args(["serve", f, "--listen", addr, "--token", token])
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
    (server, addr)
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

    let after_crash = HoloFile::open(&file, &OpenOptions::read_only())
        .unwrap()
        .summary()
        .rays();
    assert!(
        after_crash > 1_000,
        "rays flushed before the crash survive ({after_crash})"
    );
    assert!(holodeck_server::storage::check(&file, |_, _| {}).unwrap().is_clean());

    // Same file, same address: the worker reconnects by itself.
    let (mut second, _) = start_server(f, &addr, token);
    std::thread::sleep(Duration::from_millis(3000));
    let (mut admin, _) = Client::connect(&addr, Role::Admin, token);
    admin.send(&Frame::Message(Message::Control(Control::Quit)));
    assert!(second.wait().unwrap().success());
    worker.kill().unwrap();
    worker.wait().unwrap();
    let finally = HoloFile::open(&file, &OpenOptions::read_only())
        .unwrap()
        .summary()
        .rays();
    assert!(
        finally > after_crash,
        "the worker came back to the restarted server ({after_crash} -> {finally})"
    );
    assert!(holodeck_server::storage::check(&file, |_, _| {}).unwrap().is_clean());
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
            "1",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("rays added"));
    let rays = HoloFile::open(&file, &OpenOptions::read_only())
        .unwrap()
        .summary()
        .rays();
    assert!(rays > 10_000, "{rays}");
    assert!(holodeck_server::storage::check(&file, |_, _| {}).unwrap().is_clean());
    let o = bin()
        .args([
            "run",
            "builtin:room",
            file.to_str().unwrap(),
            "--time",
            "1s",
            "-o",
            "quadtree",
        ])
        .output()
        .unwrap();
    assert!(!o.status.success() && String::from_utf8_lossy(&o.stderr).contains("not available yet"));
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
