//! `holodeck sample` as a real process against a server that is not there,
//! and against a stand-in server that hands out one packet and quits.

use std::net::TcpListener;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use holodeck_protocol::wire::{Access, Frame, FrameLink, Message, SamplingMode, TracePacket};
use holodeck_protocol::{BeamKey, Section, SectionKind};

mod common;
use common::text;

/// A `holodeck` process killed when dropped, so a failing test leaves none behind.
struct Running(Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Runs `holodeck` with `args` and waits for it to end, at most two minutes.
fn holodeck_within_deadline(args: &[&str]) -> Output {
    let mut child = Running(
        Command::new(env!("CARGO_BIN_EXE_holodeck"))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap(),
    );
    let deadline = Instant::now() + Duration::from_secs(120);
    while child.0.try_wait().unwrap().is_none() {
        assert!(
            Instant::now() < deadline,
            "holodeck {args:?} did not end within two minutes"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let Running(c) = &mut child;
    let (mut out, mut err) = (Vec::new(), Vec::new());
    use std::io::Read;
    c.stdout.take().unwrap().read_to_end(&mut out).unwrap();
    c.stderr.take().unwrap().read_to_end(&mut err).unwrap();
    Output {
        status: c.try_wait().unwrap().unwrap(),
        stdout: out,
        stderr: err,
    }
}

#[test]
fn a_sampler_that_never_reaches_its_server_fails_naming_the_address() {
    // A port that was just free: nothing listens there.
    let addr = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .to_string();
    let o = holodeck_within_deadline(&[
        "sample",
        "builtin:room",
        "--connect",
        &addr,
        "--token",
        "t",
        "--retry-for",
        "0s",
        "-j",
        "2",
    ]);
    let t = text(&o);
    assert!(!o.status.success(), "{t}");
    assert!(t.contains(&addr) && t.to_lowercase().contains("refused"), "{t}");
    assert!(!t.contains("traced 0 rays"), "{t}");
}

#[test]
fn a_sampler_whose_server_quits_after_its_work_exits_zero() {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap().to_string();
    // The stand-in server: welcome the sampler, hand it one packet of 4
    // rays, take the answer, and close the connection (a normal quit).
    let server = std::thread::spawn(move || {
        let (stream, _) = listener.accept().unwrap();
        stream.set_read_timeout(Some(Duration::from_secs(120))).unwrap();
        let mut link = FrameLink::new(stream);
        let Some(Frame::Message(Message::Hello(_))) = link.read().unwrap() else {
            panic!("the sampler did not say hello")
        };
        let section = Section::new(
            [0.0; 3],
            [[6.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 2.5]],
            [4, 4, 4],
            SectionKind::Interior,
        )
        .unwrap();
        let welcome = Message::Welcome {
            sections: vec![section.spec()],
            obstructions: false,
            vdistance: false,
            access: Access::Writer,
        };
        link.write(&Frame::Message(welcome)).unwrap();
        let packet = TracePacket {
            id: 7,
            key: BeamKey::new(0, 100),
            rays: 4,
            mode: SamplingMode::Uniform,
        };
        link.write(&Frame::Message(Message::Trace(packet))).unwrap();
        link.flush().unwrap();
        match link.read().unwrap() {
            Some(Frame::Finished { id: 7, records, .. }) => records.len(),
            other => panic!("expected the finished packet, got {other:?}"),
        }
    });
    let o = holodeck_within_deadline(&[
        "sample",
        "builtin:room",
        "--connect",
        &addr,
        "--token",
        "t",
        "--retry-for",
        "0s",
        "-j",
        "1",
    ]);
    let traced = server.join().unwrap();
    assert_eq!(traced, 4);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains(&format!("traced 4 rays for {addr}")), "{t}");
}
