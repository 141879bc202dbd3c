//! What the network tests share: the `holodeck` processes they start (each
//! under a [`Proc`] guard, waited on for what it prints), a protocol client
//! whose reads time out (raw, for the tests that send malformed bytes), and
//! checks of what a server leaves on disk.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use holodeck_file::{HoloFile, OpenOptions};
use holodeck_protocol::wire::client::{self, ClientError, ClientStream, Welcome};
use holodeck_protocol::wire::{
    Control, ControlOutcome, ControlReply, Frame, FrameLink, Hello, Message, Progress, Role, PROTOCOL_VERSION,
};
use holodeck_protocol::{BeamKey, RayRecord};

use crate::common::process::{wait_for, Proc, DEADLINE};

/// The `holodeck` binary.
pub fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_holodeck"))
}

/// What a server under test logs: control commands carried out, the signal
/// that stopped it, each periodic flush's durable ray count, the rays at close.
const SERVER_LOG: &str = "info,holodeck_server=debug";

/// A sampler worker (one thread, two bounces) that gives up as soon as the
/// server is gone.
pub fn sampler(addr: &str, token: &str, scene: &[&str]) -> Proc {
    sampler_retrying(addr, token, scene, "0s")
}

/// [`sampler`] that reconnects for `retry_for` after the server lets it go
/// (where a loaded machine could make a short stall timeout drop it).
pub fn sampler_retrying(addr: &str, token: &str, scene: &[&str], retry_for: &str) -> Proc {
    Proc::start(bin().arg("sample").args(scene).args([
        "--connect",
        addr,
        "--token",
        token,
        "-j",
        "1",
        "--bounces",
        "2",
        "--retry-for",
        retry_for,
    ]))
}

/// A holodeck file of the built-in room that records its scene.
pub fn small_room(dir: &Path) -> PathBuf {
    let file = dir.join("room.hdk");
    crate::common::fill_room(&file, "1K", "0");
    file
}

/// Starts `holodeck serve` and returns it with the address it listens on.
pub fn start_server(f: &str, addr: &str, token: &str) -> (Proc, String) {
    start_server_with(f, addr, token, &[])
}

/// Starts `holodeck serve` with more flags; returns it once it listens, with
/// its first (TCP) address.
pub fn start_server_with(f: &str, addr: &str, token: &str, extra: &[&str]) -> (Proc, String) {
    let server = Proc::start(
        bin()
            .args(["serve", f, "--listen", addr, "--token", token])
            .args(extra)
            .env("HOLODECK_LOG", SERVER_LOG)
            .env("NO_COLOR", "1"),
    );
    let addr = server.wait_line("the address the server listens on", &mut 0, |l| {
        l.strip_prefix("listening on ").map(str::to_string)
    });
    (server, addr)
}

/// Asks the server at `addr` to flush and quit, as an admin.
pub fn quit(addr: &str, token: &str) {
    client::send_control(addr, token, Control::Quit).unwrap();
}

/// The rays a server's REPORT line says are stored (`progress: N rays, ...`):
/// those written to the file, which lags the rays received by up to a flush.
pub fn reported_rays(line: &str) -> Option<u64> {
    line.strip_prefix("progress: ")?.split_once(" rays, ")?.0.parse().ok()
}

/// The rays a periodic flush made durable (`periodic flush: N rays durable`).
pub fn durable_rays(line: &str) -> Option<u64> {
    line.split_once("periodic flush: ")?
        .1
        .strip_suffix(" rays durable")?
        .parse()
        .ok()
}

/// The rays in the file when the server closed it
/// (`flushed and closed: N rays in the file`).
pub fn closed_rays(line: &str) -> Option<u64> {
    line.split_once("flushed and closed: ")?
        .1
        .strip_suffix(" rays in the file")?
        .parse()
        .ok()
}

/// Every ray count a server reported, in order.
pub fn reports(server: &Proc) -> Vec<u64> {
    server.text().lines().filter_map(reported_rays).collect()
}

/// The ray count of the next REPORT line from line `*from` on.
pub fn next_report(server: &Proc, from: &mut usize) -> u64 {
    server.wait_line("a progress report", from, reported_rays)
}

/// Waits for a REPORT line, from line `*from` on, of more than `rays` rays
/// stored; returns its count.
pub fn reported_above(server: &Proc, from: &mut usize, rays: u64, what: &str) -> u64 {
    let what = format!("{what} (a report of more than {rays} rays)");
    server.wait_line(&what, from, |l| reported_rays(l).filter(|n| *n > rays))
}

/// Waits for `flushes` periodic flushes in a row (every 2 s) that found the
/// same rays durable: nothing was stored in between. Returns that count.
/// (REPORT lines cannot tell: they count rays written, which lags.)
pub fn steady(server: &Proc, from: &mut usize, flushes: usize, what: &str) -> u64 {
    let (mut last, mut run) = (None, 0);
    server.wait_line(what, from, |l| {
        let n = durable_rays(l)?;
        run = if last == Some(n) { run + 1 } else { 1 };
        last = Some(n);
        (run >= flushes).then_some(n)
    })
}

/// The durable ray count of the next periodic flush from line `*from` on.
pub fn next_flush(server: &Proc, from: &mut usize) -> u64 {
    server.wait_line("a periodic flush", from, durable_rays)
}

/// Waits for the log line saying the server carried out `control`.
pub fn carried_out(server: &Proc, from: &mut usize, control: Control) {
    let line = format!("control: {control:?}");
    server.wait_line(&line, from, |l| l.ends_with(&line).then_some(()));
}

/// The rays the server said its file held when it closed it.
pub fn rays_at_close(server: &Proc) -> u64 {
    server.wait_line("the ray count at close", &mut 0, closed_rays)
}

/// Rays a closed holodeck file holds.
pub fn rays_in(file: &Path) -> u64 {
    HoloFile::open(file, &OpenOptions::read_only())
        .unwrap()
        .summary()
        .rays()
}

/// Rays each of `keys` holds in a closed holodeck file.
pub fn beam_lens(file: &Path, keys: &[BeamKey]) -> Vec<u64> {
    let f = HoloFile::open(file, &OpenOptions::read_only()).unwrap();
    keys.iter().map(|k| f.beam_len(*k).unwrap()).collect()
}

/// Beams of section 0 of a closed holodeck file.
pub fn beams_of(file: &Path) -> u32 {
    HoloFile::open(file, &OpenOptions::read_only()).unwrap().sections()[0].beam_count()
}

/// The file passes a full check; returns the rays that verified.
pub fn assert_clean(file: &Path) -> u64 {
    let report = holodeck_file::storage::check(file, |_, _| {}).unwrap();
    assert!(report.is_clean(), "corrupt beams: {:?}", report.corrupt);
    report.rays_ok
}

/// Connects to `host:port` or `unix:PATH`; reads time out after [`DEADLINE`].
pub fn socket(addr: &str) -> ClientStream {
    let s = client::connect(addr).unwrap();
    s.set_read_timeout(Some(DEADLINE)).unwrap();
    s
}

/// A protocol client: handshake as some role, then exchange frames.
pub struct Client {
    /// The framed connection.
    pub link: FrameLink<ClientStream>,
    /// The latest progress report read.
    pub progress: Option<Progress>,
}

impl Client {
    /// Connects and says hello as `role`; returns what the server's welcome
    /// said too. Fails the test if the server refuses.
    pub fn connect(addr: &str, role: Role, token: &str) -> (Client, Welcome) {
        Client::hello(addr, role, token, PROTOCOL_VERSION, false)
            .unwrap_or_else(|e| panic!("connecting as {role:?}: {e}"))
    }

    /// A display that may not change the server's state.
    pub fn read_only_display(addr: &str, token: &str) -> Client {
        Client::hello(addr, Role::Display, token, PROTOCOL_VERSION, true)
            .unwrap_or_else(|e| panic!("connecting a read-only display: {e}"))
            .0
    }

    /// Connects and says hello with every field chosen; the server's answer.
    pub fn hello(
        addr: &str,
        role: Role,
        token: &str,
        version: u32,
        read_only: bool,
    ) -> Result<(Client, Welcome), ClientError> {
        Client::greet(
            addr,
            Hello {
                version,
                ..client::hello(role, token, "", read_only)
            },
        )
    }

    /// Connects and sends `hello`; the server's answer.
    pub fn greet(addr: &str, hello: Hello) -> Result<(Client, Welcome), ClientError> {
        let mut c = Client::raw(addr);
        let welcome = client::handshake(&mut c.link, addr, hello)?;
        Ok((c, welcome))
    }

    /// Connects without a handshake.
    pub fn raw(addr: &str) -> Client {
        Client::over(socket(addr))
    }

    /// A client on a connected socket.
    pub fn over(socket: ClientStream) -> Client {
        Client {
            link: FrameLink::new(socket),
            progress: None,
        }
    }

    /// Sends one frame now.
    pub fn send(&mut self, f: &Frame) {
        self.link.write(f).unwrap();
        self.link.flush().unwrap();
    }

    /// The next frame other than a progress report (the latest is kept in
    /// `progress`); fails if the server closes the connection or says
    /// nothing for [`DEADLINE`].
    pub fn recv(&mut self) -> Frame {
        loop {
            match self.link.read() {
                Ok(Some(Frame::Message(Message::Progress(p)))) => self.progress = Some(p),
                Ok(Some(f)) => return f,
                Ok(None) => panic!("the server closed the connection"),
                Err(e) => panic!("no frame from the server (waited up to {DEADLINE:?}): {e}"),
            }
        }
    }

    /// A frame other than a progress report already sent to us, if there is
    /// one (waits a moment only for bytes in flight on loopback).
    pub fn pending(&mut self) -> Option<Frame> {
        self.link
            .stream()
            .set_read_timeout(Some(Duration::from_millis(50)))
            .unwrap();
        let got = loop {
            match self.link.read() {
                Ok(Some(Frame::Message(Message::Progress(p)))) => self.progress = Some(p),
                Ok(f) => break f,
                Err(holodeck_protocol::wire::LinkError::Io(e))
                    if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) =>
                {
                    break None
                }
                Err(e) => panic!("reading from the server: {e}"),
            }
        };
        self.link.stream().set_read_timeout(Some(DEADLINE)).unwrap();
        got
    }

    /// Waits for a progress report that `accept` takes; returns it.
    pub fn progress_where(&mut self, what: &str, mut accept: impl FnMut(&Progress) -> bool) -> Progress {
        let start = Instant::now();
        loop {
            assert!(
                start.elapsed() < DEADLINE,
                "waited {DEADLINE:?} for a report of {what}, in vain"
            );
            match self.link.read() {
                Ok(Some(Frame::Message(Message::Progress(p)))) => {
                    self.progress = Some(p);
                    if accept(&p) {
                        return p;
                    }
                }
                Ok(Some(_)) => {}
                Ok(None) => panic!("the server closed the connection while we waited for {what}"),
                Err(e) => panic!("no report of {what} (waited up to {DEADLINE:?}): {e}"),
            }
        }
    }

    /// Sends a control command and returns the server's answer to it (rays
    /// streamed for earlier requests meanwhile are passed over).
    pub fn command(&mut self, c: Control) -> ControlOutcome {
        self.send(&Frame::Message(Message::Control(c.clone())));
        loop {
            match self.recv() {
                Frame::Message(Message::ControlReply(ControlReply { control, outcome })) => {
                    assert_eq!(control, c, "the answer names the command");
                    return outcome;
                }
                Frame::Beam { .. } => {}
                other => panic!("expected the answer to {c:?}, got {other:?}"),
            }
        }
    }

    /// Asks for beams (replacing earlier requests) and collects every
    /// stored ray that arrives up to the server's Delivered mark: (beam,
    /// rays) per Beam frame.
    pub fn request(
        &mut self,
        beams: &[(BeamKey, u32)],
        eye: Option<holodeck_protocol::wire::EyePoint>,
    ) -> Vec<(BeamKey, usize)> {
        self.request_with(beams, eye, true)
    }

    /// [`Client::request`] that, without `resend`, gets only rays this
    /// connection was not sent before.
    pub fn request_with(
        &mut self,
        beams: &[(BeamKey, u32)],
        eye: Option<holodeck_protocol::wire::EyePoint>,
        resend: bool,
    ) -> Vec<(BeamKey, usize)> {
        self.transfer(beams, eye, resend).0
    }

    /// Rays stored in `beams` now: what the server counts in its immediate
    /// transfer (rays streamed in as they are traced are not counted).
    pub fn stored(&mut self, beams: &[(BeamKey, u32)]) -> u64 {
        self.transfer(beams, None, true).1
    }

    /// Sends a request and reads up to its Delivered mark: the Beam frames
    /// that came (beam, rays), and the rays the server counted as delivered.
    fn transfer(
        &mut self,
        beams: &[(BeamKey, u32)],
        eye: Option<holodeck_protocol::wire::EyePoint>,
        resend: bool,
    ) -> (Vec<(BeamKey, usize)>, u64) {
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
                    return (got, rays);
                }
                other => panic!("expected beam data, got {other:?}"),
            }
        }
    }
}

/// Asks `display` for `beams` until they hold more than `rays` stored rays;
/// returns how many they then hold.
pub fn stored_above(display: &mut Client, beams: &[(BeamKey, u32)], rays: u64, what: &str) -> u64 {
    wait_for(&format!("{what} (more than {rays} rays stored)"), DEADLINE, || {
        // Each look reads every beam asked for: a few looks a second, not more.
        std::thread::sleep(Duration::from_millis(100));
        Some(display.stored(beams)).filter(|n| *n > rays)
    })
}

/// Collects rays streamed after a request's immediate transfer until every
/// beam of `want` holds its count, counting the `base` rays it held before.
/// Returns what each beam then holds.
pub fn collect_until(
    client: &mut Client,
    want: &[(BeamKey, u32)],
    have: &mut HashMap<BeamKey, Vec<RayRecord>>,
    base: &HashMap<BeamKey, usize>,
) -> HashMap<BeamKey, usize> {
    let held = |have: &HashMap<BeamKey, Vec<_>>, k: &BeamKey| {
        have.get(k).map_or(0, Vec::len) + base.get(k).copied().unwrap_or(0)
    };
    let start = Instant::now();
    while want.iter().any(|(k, n)| held(have, k) < *n as usize) {
        assert!(
            start.elapsed() < DEADLINE,
            "waited {DEADLINE:?} for the requested rays, in vain: {:?} of {want:?}",
            want.iter().map(|(k, _)| held(have, k)).collect::<Vec<_>>()
        );
        match client.recv() {
            Frame::Beam { key, records } => have.entry(key).or_default().extend(records),
            other => panic!("expected beam data, got {other:?}"),
        }
    }
    want.iter().map(|(k, _)| (*k, held(have, k))).collect()
}

/// Waits for `holodeck run`'s server (started on `file`) to print its
/// address, then until the beams of its first section hold more than `rays`
/// stored rays, and asks the server to quit. `run` is left to finish.
pub fn run_stores_then_quit(run: &Proc, file: &Path, rays: u64, what: &str) {
    let addr = run.wait_line("the address of run's server", &mut 0, |l| {
        let rest = l.split_once("(server ")?.1;
        rest.split([';', ')']).next().map(str::to_string)
    });
    let token = std::fs::read_to_string(format!("{}.token", file.display()))
        .unwrap()
        .lines()
        .next()
        .unwrap()
        .trim()
        .to_string();
    let beams: Vec<(BeamKey, u32)> = {
        let (_, welcome) = Client::connect(&addr, Role::Display, &token);
        let n = welcome.sections[0].beam_count();
        (0..n).map(|b| (BeamKey::new(0, b), 0)).collect()
    };
    let (mut display, _) = Client::connect(&addr, Role::Display, &token);
    stored_above(&mut display, &beams, rays, what);
    drop(display);
    quit(&addr, &token);
}
