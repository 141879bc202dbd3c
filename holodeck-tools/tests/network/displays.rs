//! Displays: requests traced near the eye and streamed (over a Unix
//! socket), a file replayed by a server with no fill, still views that keep
//! converging, work a stalled sampler held given to another, the progress
//! reports every display gets, and a modest display served while a greedy
//! one waits.

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use holodeck_file::{HoloFile, OpenOptions};
use holodeck_protocol::wire::{client, Control, ControlOutcome, EyePoint, Frame, Message, Role};
use holodeck_protocol::{BeamKey, RayRecord, Section, View, ViewBeams};

use crate::common::process::{wait_for, Proc, DEADLINE};
use crate::common::{holodeck, text};
use crate::harness::*;

/// The traced rays a sampler's last line says it sent (`traced N rays for ADDR`).
fn traced(out: &str) -> u64 {
    out.lines()
        .find_map(|l| {
            l.strip_prefix("traced ")?
                .split_once(" rays for ")?
                .0
                .replace(',', "")
                .parse()
                .ok()
        })
        .unwrap_or_else(|| panic!("no count of rays traced: {out}"))
}

#[test]
fn display_requests_are_traced_near_the_eye_and_streamed_over_a_unix_socket() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let initial = rays_in(&file);
    let sock = dir.path().join("room.sock");
    let token = "t";
    let (mut server, _) = start_server_with(
        file.to_str().unwrap(),
        "127.0.0.1:0",
        token,
        &["--no-fill", "--unix", sock.to_str().unwrap()],
    );
    let unix = format!("unix:{}", sock.display());
    let listening = format!("listening on {unix}");
    server.wait_line(&listening, &mut 0, |l| (l == listening).then_some(()));
    let worker = sampler(&unix, token, &["builtin:room"]);

    let (mut display, welcome) = Client::connect(&unix, Role::Display, token);
    let sections: Vec<Section> = welcome.sections;
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
    let mut have: HashMap<BeamKey, Vec<RayRecord>> = HashMap::new();
    let base_near: HashMap<BeamKey, usize> = display.request(&want_near, Some(eye_point)).into_iter().collect();
    let held = collect_until(&mut display, &want_near, &mut have, &base_near);
    assert!(held.values().all(|n| *n == 60), "exactly the rays asked for: {held:?}");
    // Then the same number of uniform rays for the other beams, on a new request.
    let want_far: Vec<(BeamKey, u32)> = far.iter().map(|(_, k)| (*k, 60)).collect();
    let mut have_far: HashMap<BeamKey, Vec<RayRecord>> = HashMap::new();
    let base_far: HashMap<BeamKey, usize> = display.request(&want_far, None).into_iter().collect();
    let held = collect_until(&mut display, &want_far, &mut have_far, &base_far);
    assert!(held.values().all(|n| *n == 60), "exactly the rays asked for: {held:?}");

    // How close do the rays pass to the eye?
    let near_fraction = |rays: &HashMap<BeamKey, Vec<RayRecord>>| {
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
    quit(&unix, token);
    assert!(server.wait().success(), "{}", server.text());
    assert!(!sock.exists(), "the socket file is removed");
    let w = worker.finish();
    assert!(w.status.success(), "{}", text(&w));
    let keys: Vec<BeamKey> = want_near.iter().chain(&want_far).map(|w| w.0).collect();
    assert!(beam_lens(&file, &keys).iter().all(|n| *n == 60), "{keys:?}");
    let asked: u64 = base_near
        .iter()
        .chain(&base_far)
        .map(|(_, n)| *n as u64)
        .fold(60 * keys.len() as u64, |left, n| left - n);
    assert_eq!(rays_in(&file), initial + asked, "no ray beyond the requests");
    assert!(traced(&String::from_utf8_lossy(&w.stdout)) >= asked, "{}", text(&w));
}

#[test]
fn a_display_only_server_replays_the_file_to_a_headless_view() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    crate::common::fill_room(&file, "500K", "1");
    // What the server will send, read from the file before it is served.
    let probe: Vec<BeamKey> = (4242..4342).map(|b| BeamKey::new(0, b)).collect();
    let k = *probe
        .iter()
        .zip(beam_lens(&file, &probe))
        .find(|(_, n)| *n > 0)
        .expect("a beam near 4242 holds rays")
        .0;
    let k_len = beam_lens(&file, &[k])[0] as usize;
    let seen: Vec<(BeamKey, u32)> = (0..40).map(|b| (BeamKey::new(0, b * 211), 1)).collect();
    let more: Vec<(BeamKey, u32)> = (0..40).map(|b| (BeamKey::new(0, b * 211 + 5), 1)).collect();
    let held = |beams: &[(BeamKey, u32)]| -> usize {
        let keys: Vec<BeamKey> = beams.iter().map(|b| b.0).collect();
        beam_lens(&file, &keys).iter().sum::<u64>() as usize
    };
    let (held_seen, held_more) = (held(&seen), held(&more));
    assert!(held_seen > 0 && held_more > 0);

    let (mut server, addr) = start_server_with(file.to_str().unwrap(), "127.0.0.1:0", "t", &["--no-fill"]);
    let views = dir.path().join("v.vf");
    std::fs::write(
        &views,
        "-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56\n-vd 0 1 0\n",
    )
    .unwrap();
    let frames = dir.path().join("frames");
    let frames_dir = frames.to_str().unwrap();
    let o = holodeck(&[
        "view",
        "--connect",
        &addr,
        "--token",
        "t",
        "--headless",
        "--read-only",
        "--views",
        views.to_str().unwrap(),
        "--frames",
        frames_dir,
        "-x",
        "64",
        "-y",
        "48",
        "--format",
        "hdr",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    // One frame per view, each drawn from the stored samples alone.
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 2, "{out}");
    for l in &lines {
        let n = new_samples(l).unwrap_or_else(|| panic!("no sample count in {l:?}"));
        assert!(n > 100, "{l}");
    }
    let p = holodeck_display::image_io::read_picture(&frames.join("view0002_00.hdr")).unwrap();
    assert!(p.pixels.iter().filter(|c| c.max_element() > 0.0).count() > p.pixels.len() / 2);
    // Read-only: the server is still there for the next display.
    assert!(server.try_wait().is_none(), "{}", server.text());
    // A beam asked for three times is sent once; a request for more beams
    // than the holodeck has is refused with a reason.
    let (mut display, _) = Client::connect(&addr, Role::Display, "t");
    let got = display.request(&[(k, 5), (k, 9), (k, 7)], None);
    assert_eq!(got, vec![(k, k_len)], "every ray of {k:?}, once");
    // What a display was sent is not sent again unless it asks to resend
    // (it keeps its estimates across views); beams it was never sent come whole.
    let sum = |got: Vec<(BeamKey, usize)>| got.iter().map(|g| g.1).sum::<usize>();
    let first = sum(display.request(&seen, None));
    assert_eq!(first, held_seen);
    let again = sum(display.request_with(&seen, None, false));
    assert_eq!(again, 0, "a file with no samplers has nothing new");
    let fresh = sum(display.request_with(&more, None, false));
    assert_eq!(fresh, held_more, "beams never sent come whole");
    let resent = sum(display.request_with(&seen, None, true));
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
    let mut raw = socket(&addr);
    let mut big = vec![0u8; 5 + (100 << 10)];
    big[..4].copy_from_slice(&((100u32 << 10) + 1).to_le_bytes());
    let _ = std::io::Write::write_all(&mut raw, &big);
    match Client::over(raw).recv() {
        Frame::Message(Message::Refused { reason, .. }) => assert!(reason.contains("65536 allowed"), "{reason}"),
        other => panic!("{other:?}"),
    }
    quit(&addr, "t");
    assert!(server.wait().success(), "{}", server.text());
}

/// The samples a frame line of `holodeck view` reports as new.
fn new_samples(line: &str) -> Option<u64> {
    line.split_once(" new samples")?
        .0
        .rsplit(' ')
        .next()?
        .replace(',', "")
        .parse()
        .ok()
}

/// The samples a frame line of `holodeck view` says the view holds in all.
fn samples_in_all(line: &str) -> Option<u64> {
    line.split_once(" in all, ")?
        .0
        .rsplit_once('(')?
        .1
        .replace(',', "")
        .parse()
        .ok()
}

#[test]
fn still_views_keep_converging_while_samplers_work() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let (mut server, addr) = start_server(file.to_str().unwrap(), "127.0.0.1:0", "t");
    let _samplers: Vec<Proc> = (0..2).map(|_| sampler(&addr, "t", &["builtin:room"])).collect();
    let pixels = 32 * 24;
    // Two displays at once, each on its own still view, a frame a second
    // for as long as the test watches.
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
        let frames = dir.path().join(format!("frames{i}"));
        let display = Proc::start(
            bin()
                .args(["view", "--connect", &addr, "--token", "t", "--headless"])
                .arg("--views")
                .arg(&views)
                .arg("--frames")
                .arg(&frames)
                .args([
                    "-x", "32", "-y", "24", "--wait", "10m", "--steps", "600", "--format", "hdr",
                ])
                .env("HOLODECK_LOG", "info")
                .env("NO_COLOR", "1"),
        );
        displays.push((display, frames));
    }
    for (display, frames) in &displays {
        // The first density (one sample a pixel) is met; the display asks
        // for more, twice, and samples keep coming after that.
        let mut at = 0;
        display.wait_line("a second raise of the density", &mut at, |l| {
            l.contains("asking for 4 samples per pixel").then_some(())
        });
        let (frame, total) = display.wait_line("a frame of more than four samples a pixel", &mut at, |l| {
            let total = samples_in_all(l).filter(|t| *t > 4 * pixels)?;
            (new_samples(l)? > 0).then(|| (l.split(':').next().unwrap_or_default().to_string(), total))
        });
        let p = holodeck_display::image_io::read_picture(std::path::Path::new(&frame)).unwrap();
        assert!(frame.starts_with(frames.to_str().unwrap()), "{frame}");
        assert_eq!((p.width, p.height), (32, 24));
        let lit = p
            .pixels
            .iter()
            .filter(|c| c.is_finite() && c.max_element() > 0.0)
            .count();
        assert!(
            lit > p.pixels.len() / 2,
            "{total} samples lit only {lit} pixels of {frame}"
        );
    }
    drop(displays);
    quit(&addr, "t");
    assert!(server.wait().success(), "{}", server.text());
}

#[test]
fn a_sampler_that_stops_answering_is_dropped_and_its_work_traced_by_another() {
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
    let (mut silent, _) = Client::greet(&addr, client::hello(Role::Sampler, token, &scene, false)).unwrap();
    let (mut display, _) = Client::connect(&addr, Role::Display, token);
    let want: Vec<(BeamKey, u32)> = (0..4).map(|b| (BeamKey::new(0, 3000 + 11 * b), 50)).collect();
    let base: HashMap<BeamKey, usize> = display.request(&want, None).into_iter().collect();
    assert!(
        matches!(silent.recv(), Frame::Message(Message::Trace(_))),
        "the work went to it"
    );
    // The server gives up on it: the connection ends (within the read
    // timeout, or the test fails).
    let start = std::time::Instant::now();
    loop {
        match silent.link.read() {
            Ok(Some(_)) => assert!(start.elapsed() < DEADLINE, "the server kept the silent sampler"),
            Ok(None) => break,
            Err(e) if e.is_gone() => break,
            Err(e) => panic!("the server never dropped the silent sampler: {e}"),
        }
    }
    // Its packets were given back: a working sampler traces all of them
    // (reconnecting should a busy moment of a second make the server drop
    // it too).
    let worker = sampler_retrying(&addr, token, &["builtin:room"], "5s");
    let mut have = HashMap::new();
    let held = collect_until(&mut display, &want, &mut have, &base);
    assert!(held.values().all(|n| *n == 50), "exactly the rays asked for: {held:?}");
    quit(&addr, token);
    assert!(server.wait().success(), "{}", server.text());
    let w = worker.finish();
    assert!(w.status.success(), "{}", text(&w));
}

#[test]
fn displays_get_a_progress_report_with_connections_pause_and_rate() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let initial = rays_in(&file);
    let beams = u64::from(beams_of(&file));
    let token = "t";
    let (mut server, addr) = start_server(file.to_str().unwrap(), "127.0.0.1:0", token);
    let (mut display, _) = Client::connect(&addr, Role::Display, token);
    // The first report comes at once: the file as it is, nobody tracing
    // and counting this display.
    let first = display.progress_where("the first report", |_| true);
    assert_eq!(
        (first.rays, first.beams, first.samplers, first.paused),
        (initial, beams, 0, false)
    );
    assert!(first.beams_filled > 0 && first.beams_filled <= beams, "{first:?}");
    display.progress_where("this display counted", |p| p.displays == 1);
    // A sampler and a second display are counted (an admin is not), and the
    // rays it stores show in the count and the rate.
    let worker = sampler(&addr, token, &["builtin:room"]);
    let (mut other, _) = Client::connect(&addr, Role::Display, token);
    let (mut admin, _) = Client::connect(&addr, Role::Admin, token);
    let busy = display.progress_where("a sampler at work and two displays", |p| {
        p.samplers == 1 && p.displays == 2 && p.rays > initial && p.rays_per_second > 0.0
    });
    assert!(busy.file_bytes > 0 && !busy.paused, "{busy:?}");
    // Pausing shows too, on every display.
    assert_eq!(admin.command(Control::Pause), ControlOutcome::Done);
    let paused = other.progress_where("the pause", |p| p.paused);
    assert_eq!((paused.samplers, paused.displays), (1, 2));
    drop(other);
    display.progress_where("the second display gone", |p| p.displays == 1 && p.paused);
    assert_eq!(admin.command(Control::Quit), ControlOutcome::Done);
    assert!(server.wait().success(), "{}", server.text());
    let w = worker.finish();
    assert!(w.status.success(), "{}", text(&w));
}

/// The beams `view` sees in the room, from a grid of `columns` x `rows` view rays.
fn beams_seen(sections: &[Section], view: &str, columns: u32, rows: u32) -> Vec<BeamKey> {
    let view = View::parse(view).unwrap();
    ViewBeams::select(sections, &view, columns, rows, 1)
        .counts
        .into_iter()
        .map(|c| c.0)
        .collect()
}

#[test]
fn a_greedy_display_does_not_starve_a_modest_one() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let token = "t";
    let (mut server, addr) = start_server_with(file.to_str().unwrap(), "127.0.0.1:0", token, &["--no-fill"]);
    let _worker = sampler(&addr, token, &["builtin:room"]);
    let (mut greedy, welcome) = Client::connect(&addr, Role::Display, token);
    let sections: Vec<Section> = welcome.sections;
    // Two windows on the room: a fisheye asking for many rays in each of
    // its hundreds of beams, and a narrow view from elsewhere that asks for
    // few (none of its beams shared).
    let s = &sections[0];
    let eye = |f: [f64; 3]| {
        let p = s.origin() + s.axes()[0] * f[0] + s.axes()[1] * f[1] + s.axes()[2] * f[2];
        format!("-vp {} {} {} -vu 0 0 1", p.x, p.y, p.z)
    };
    let wide = beams_seen(
        &sections,
        &format!("-vta {} -vd 1 0 0 -vh 180 -vv 180", eye([0.2, 0.3, 0.5])),
        400,
        300,
    );
    let narrow: Vec<BeamKey> = beams_seen(
        &sections,
        &format!("-vtv {} -vd 0.2 1 0.4 -vh 40 -vv 30", eye([0.5, 0.5, 0.9])),
        8,
        6,
    )
    .into_iter()
    .filter(|k| !wide.contains(k))
    .collect();
    assert!(
        wide.len() > 20 * narrow.len() && narrow.len() >= 10,
        "{} and {} beams",
        wide.len(),
        narrow.len()
    );
    let want_greedy: Vec<(BeamKey, u32)> = wide.iter().map(|k| (*k, 5000)).collect();
    let want_modest: Vec<(BeamKey, u32)> = narrow.iter().map(|k| (*k, 40)).collect();
    let greedy_asked = 5000 * wide.len() as u64;

    // The greedy display asks first and is served alone until its rays stream in.
    greedy.request(&want_greedy, None);
    let received = Arc::new(AtomicU64::new(0));
    let reader = {
        let received = Arc::clone(&received);
        std::thread::spawn(move || {
            let mut keys = HashSet::new();
            loop {
                match greedy.link.read() {
                    Ok(Some(Frame::Beam { key, records })) => {
                        keys.insert(key);
                        received.fetch_add(records.len() as u64, Ordering::SeqCst);
                    }
                    Ok(Some(other)) => panic!("the greedy display got {other:?}"),
                    Ok(None) => break,
                    Err(e) if e.is_gone() => break,
                    Err(e) => panic!("reading the greedy display's rays: {e}"),
                }
            }
            keys
        })
    };
    let now = || received.load(Ordering::SeqCst);
    wait_for("the greedy display's first traced rays", DEADLINE, || {
        (now() > 0).then_some(())
    });

    // The modest display's request is met in full while the greedy one's is far from it.
    // Counted from the moment it asks: a test thread kept waiting before
    // that must not count against the server.
    let (mut modest, _) = Client::connect(&addr, Role::Display, token);
    let greedy_before = now();
    let base: HashMap<BeamKey, usize> = modest.request(&want_modest, None).into_iter().collect();
    let mut have = HashMap::new();
    let held = collect_until(&mut modest, &want_modest, &mut have, &base);
    let greedy_then = now() - greedy_before;
    assert!(held.values().all(|n| *n == 40), "exactly the rays asked for: {held:?}");
    assert!(have.keys().all(|k| narrow.contains(k)), "only its own view's beams");
    eprintln!(
        "modest request of {} rays met; the greedy display had received {greedy_then} more of {greedy_asked}",
        40 * narrow.len()
    );
    // Meanwhile the greedy display got what the sampler had queued for it
    // when the modest request came (a server queues at most 2^18 rays to a
    // sampler) and about as much again as the modest display got; served in
    // one neediest-first list, the modest beams would have waited until
    // the greedy ones were 80% full.
    assert!(
        greedy_then < greedy_asked / 4,
        "the modest request waited while the greedy display got {greedy_then} of its {greedy_asked} rays"
    );
    quit(&addr, token);
    assert!(server.wait().success(), "{}", server.text());
    let keys = reader.join().expect("the greedy display's reader failed");
    assert!(keys.iter().all(|k| wide.contains(k)), "only its own view's beams");
    assert!(
        beam_lens(&file, &narrow).iter().all(|n| *n == 40),
        "a met request takes no more rays"
    );
}

/// A display's request to a server that stops answering (SIGSTOP) fails
/// with a timeout naming the server, instead of waiting forever.
#[test]
fn a_request_to_a_hung_server_fails_with_a_timeout() {
    use holodeck_display::client::{ClientError, DisplaySession};
    use holodeck_display::request::BeamRequest;
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let (server, addr) = start_server(file.to_str().unwrap(), "127.0.0.1:0", "t");
    let mut session = DisplaySession::connect(&addr, "t", true).unwrap();
    let req = BeamRequest {
        beams: (0..50).map(|b| (BeamKey::new(0, b), 1)).collect(),
        eye: None,
        seen: ViewBeams::default(),
    };
    // Answered while the server runs (with the default timeout: a loaded
    // machine may take more than a second).
    session.request(&req, true, &mut |_| {}).unwrap();
    session.set_timeout(std::time::Duration::from_secs(1));
    server.signal(libc::SIGSTOP);
    // The signal is delivered asynchronously: wait until the kernel
    // reports the child stopped (waitpid returns once it has; it does not
    // reap it), or it may still answer.
    let mut wstatus = 0;
    // SAFETY: waitpid writes only the status word it is given.
    let rc = unsafe { libc::waitpid(server.id() as libc::pid_t, &mut wstatus, libc::WUNTRACED) };
    assert!(
        rc > 0 && libc::WIFSTOPPED(wstatus),
        "the server did not stop: {rc} {wstatus}"
    );
    let e = session.request(&req, true, &mut |_| {}).unwrap_err();
    server.signal(libc::SIGCONT);
    assert!(matches!(e, ClientError::Timeout { secs: 1, .. }), "{e}");
    assert!(e.to_string().contains(&addr), "{e}");
}
