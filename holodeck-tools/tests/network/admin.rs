//! Control commands: what admins may do to a running server (pause, resume,
//! kill samplers, restart, clobber, quit), what writers and viewers may not,
//! the tokens that decide which is which, and DISKSPACE stopping the fill by
//! itself.

use std::collections::HashMap;

use holodeck_protocol::wire::{Access, Control, ControlOutcome, Frame, Message, Role};
use holodeck_protocol::BeamKey;

use crate::common::process::{wait_for, Proc, DEADLINE};
use crate::common::text;
use crate::harness::*;

#[test]
fn admins_pause_resume_kill_restart_and_clobber() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let f = file.to_str().unwrap();
    let initial = rays_in(&file);
    let beams = beams_of(&file);
    let token = "t";
    let (mut server, addr) = start_server_with(f, "127.0.0.1:0", token, &["--report", "0.2s"]);
    let mut worker = sampler(&addr, token, &["builtin:room"]);
    let (mut admin, _) = Client::connect(&addr, Role::Admin, token);
    let mut log = 0;
    reported_above(&server, &mut log, initial, "the fill to start");

    // Paused: no packets go out. Once those already out are back, the file
    // stops growing, and a display's request is not traced either.
    admin.send(&Frame::Message(Message::Control(Control::Pause)));
    carried_out(&server, &mut log, Control::Pause);
    let paused = steady(&server, &mut log, 2, "the fill to stop while paused");
    let mut display = Client::read_only_display(&addr, token);
    let want: Vec<(BeamKey, u32)> = (0..8).map(|b| (BeamKey::new(0, 1000 + b), 40)).collect();
    let base: HashMap<BeamKey, usize> = display.request(&want, None).into_iter().collect();
    // Two more flushes, at least 2 s apart, find nothing new.
    for _ in 0..2 {
        assert_eq!(next_flush(&server, &mut log), paused, "nothing is traced while paused");
    }
    assert!(display.pending().is_none(), "no rays for the display while paused");
    // Resume hands work out again: the display's request is traced.
    admin.send(&Frame::Message(Message::Control(Control::Resume)));
    let mut have = HashMap::new();
    let held = collect_until(&mut display, &want, &mut have, &base);
    assert!(want.iter().all(|(k, n)| held[k] >= *n as usize), "{held:?}");

    // KillSamplers disconnects them and keeps new ones out until Restart:
    // they wait (and would reload an edited scene) rather than end.
    admin.send(&Frame::Message(Message::Control(Control::KillSamplers)));
    carried_out(&server, &mut log, Control::KillSamplers);
    let stopped = "samplers were stopped by an admin; a restart command lets them in again";
    worker.wait_line("the killed sampler told why", &mut 0, |l| {
        l.contains(stopped).then_some(())
    });
    let mut waiting = sampler(&addr, token, &["builtin:room"]);
    waiting.wait_line("a new sampler refused for now", &mut 0, |l| {
        (l.contains("refused for now") && l.contains(stopped)).then_some(())
    });
    assert!(
        worker.try_wait().is_none(),
        "the killed sampler waits to be let in again"
    );
    assert!(waiting.try_wait().is_none(), "the refused sampler waits to be let in");

    // Clobber empties the file (no sampler is running to refill it).
    // Every beam, wanting nothing more: the answer is everything stored.
    let all: Vec<(BeamKey, u32)> = (0..beams).map(|b| (BeamKey::new(0, b), 0)).collect();
    let before = display.stored(&all);
    assert!(before > initial, "the fill had stored rays ({initial} -> {before})");
    let (mut clobberer, _) = Client::connect(&addr, Role::Admin, token);
    assert_eq!(clobberer.command(Control::Clobber), ControlOutcome::Done);
    carried_out(&server, &mut log, Control::Clobber);
    assert_eq!(
        display.stored(&all),
        0,
        "clobber empties every beam ({before} rays before)"
    );

    // Restart lets the waiting samplers in again, and the fill goes on.
    admin.send(&Frame::Message(Message::Control(Control::Restart)));
    carried_out(&server, &mut log, Control::Restart);
    stored_above(&mut display, &all, 0, "the fill after a restart");
    admin.send(&Frame::Message(Message::Control(Control::Quit)));
    assert!(server.wait().success(), "{}", server.text());
    for w in [worker, waiting] {
        let out = w.finish();
        assert!(out.status.success(), "{}", text(&out));
    }
    let after_clobber = rays_in(&file);
    assert!(after_clobber > 0);
    assert_eq!(after_clobber, rays_at_close(&server));
    assert_eq!(assert_clean(&file), after_clobber);
}

#[test]
fn diskspace_stops_the_fill_within_its_limit() {
    // A server whose file may grow by 1.5 MiB stops by itself within it.
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let f = file.to_str().unwrap();
    let initial = rays_in(&file);
    let token = "t";
    let limit = std::fs::metadata(&file).unwrap().len() + (3 << 19);
    let (mut server, addr) = start_server_with(f, "127.0.0.1:0", token, &["--diskspace", &limit.to_string()]);
    let w = sampler(&addr, token, &["builtin:room"]);
    let status = wait_for("the server to stop at DISKSPACE", DEADLINE, || {
        let size = std::fs::metadata(&file).unwrap().len();
        assert!(size <= limit, "the file grew past DISKSPACE: {size} > {limit}");
        server.try_wait()
    });
    assert!(status.success(), "{}", server.text());
    assert!(server.text().contains("DISKSPACE reached"), "{}", server.text());
    let w = w.finish();
    assert!(w.status.success(), "{}", text(&w));
    let size = std::fs::metadata(&file).unwrap().len();
    assert!(size <= limit, "{size} > {limit}");
    let rays = rays_in(&file);
    let before_fill = limit - (3 << 19);
    eprintln!(
        "DEBUG the fill used the space it had ({initial} -> {rays} rays, {before_fill} -> {size} bytes of {limit})"
    );
    assert!(
        rays > initial + 10_000 && size - before_fill > (3 << 19) * 3 / 5,
        "the fill used the space it had ({initial} -> {rays} rays, {before_fill} -> {size} bytes of {limit})"
    );
    assert_eq!(assert_clean(&file), rays);
}

/// The reason the server gives for refusing `c` to a connection with `held` access.
fn refusal(c: &Control, held: &str) -> ControlOutcome {
    ControlOutcome::Refused {
        reason: format!("{c:?} needs {} access; this connection has {held} access", c.needs()),
    }
}

#[test]
fn viewers_may_not_quit_kill_restart_clobber_or_pause() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let f = file.to_str().unwrap();
    let initial = rays_in(&file);
    let token = "t";
    let (mut server, addr) = start_server_with(
        f,
        "127.0.0.1:0",
        token,
        &["--report", "0.2s", "--writer-token", "w", "--viewer-token", "v"],
    );
    let mut worker = sampler(&addr, "w", &["builtin:room"]);
    let mut log = 0;
    reported_above(&server, &mut log, initial, "the fill to start");

    // A viewer's token, claiming not to be read-only, and the admin's token
    // asking to be read-only: both are viewers, and refused every command.
    let (mut viewer, welcome) = Client::connect(&addr, Role::Display, "v");
    assert_eq!(welcome.access, Access::Viewer);
    let mut lowered = Client::read_only_display(&addr, token);
    // Adopt empties the file (its rays belong to the old scene): admins only.
    let adopt = Control::Adopt {
        scene: "blake3:0000".into(),
        keep: false,
    };
    let all = [
        Control::Quit,
        Control::KillSamplers,
        Control::Restart,
        Control::Clobber,
        adopt.clone(),
        Control::Pause,
        Control::Resume,
    ];
    for display in [&mut viewer, &mut lowered] {
        for c in &all {
            assert_eq!(display.command(c.clone()), refusal(c, "viewer"), "{c:?}");
        }
    }
    // None was carried out: the sampler is still connected and the fill goes
    // on, nothing was emptied, and the display is still served.
    let refused_at = next_report(&server, &mut log);
    reported_above(&server, &mut log, refused_at + 1_000, "the fill after the refusals");
    assert!(worker.try_wait().is_none(), "the sampler was not killed");
    let keys: Vec<(BeamKey, u32)> = (0..20).map(|b| (BeamKey::new(0, b * 1009), 1)).collect();
    let got = viewer.request(&keys, None);
    assert!(got.iter().all(|(k, _)| keys.iter().any(|w| w.0 == *k)), "{got:?}");
    assert!(!got.is_empty(), "the viewer reads the rays stored");
    assert!(!server.text().contains("control: "), "{}", server.text());
    let reported = reports(&server);
    assert!(
        reported.windows(2).all(|w| w[0] <= w[1]),
        "the stored rays never dropped: {reported:?}"
    );

    quit(&addr, token);
    assert!(server.wait().success(), "{}", server.text());
    let w = worker.finish();
    assert!(w.status.success(), "{}", text(&w));
    let closed = rays_at_close(&server);
    assert!(reported.iter().all(|r| *r <= closed), "{reported:?}, {closed} at close");
    assert_eq!(rays_in(&file), closed);
}

#[test]
fn writers_pause_and_resume_but_only_admins_clobber_and_viewers_cannot_sample() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let f = file.to_str().unwrap();
    let beams = beams_of(&file);
    let initial = rays_in(&file);
    // No token given: the server makes all three, readable by the owner only.
    let mut server = Proc::start(
        bin()
            .args(["serve", f, "--listen", "127.0.0.1:0", "--report", "0.2s"])
            .env("HOLODECK_LOG", "info,holodeck_server=debug")
            .env("NO_COLOR", "1"),
    );
    let addr = server.wait_line("the address the server listens on", &mut 0, |l| {
        l.strip_prefix("listening on ").map(str::to_string)
    });
    let read = |suffix: &str| {
        use std::os::unix::fs::PermissionsExt;
        let path = format!("{f}{suffix}");
        let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o600, "{path} is readable by the owner only");
        let text = std::fs::read_to_string(&path).unwrap();
        let mut lines = text.lines();
        let t = lines.next().unwrap().trim().to_string();
        assert_eq!(t.len(), 32, "{path}: {t:?}");
        let pin = lines.next().unwrap_or("");
        assert!(
            pin.starts_with("tls-sha256 ") && pin.len() == "tls-sha256 ".len() + 64,
            "{path} pins the server's certificate: {pin:?}"
        );
        t
    };
    let (admin, writer, viewer) = (read(".token"), read(".writer.token"), read(".viewer.token"));
    assert!(admin != writer && writer != viewer && viewer != admin);

    // A viewer's token cannot connect a sampler; a writer's can.
    let refused = sampler(&addr, &viewer, &["builtin:room"]).finish();
    assert!(
        !refused.status.success()
            && text(&refused).contains("a sampler needs writer access; this connection has viewer access"),
        "{}",
        text(&refused)
    );
    let worker = sampler(&addr, &writer, &["builtin:room"]);
    let mut log = 0;
    reported_above(&server, &mut log, initial, "the writer's sampler at work");

    // A writer pauses and resumes, and may not clobber.
    let (mut w, welcome) = Client::connect(&addr, Role::Display, &writer);
    assert_eq!(welcome.access, Access::Writer);
    assert_eq!(w.command(Control::Pause), ControlOutcome::Done);
    carried_out(&server, &mut log, Control::Pause);
    let all: Vec<(BeamKey, u32)> = (0..beams).map(|b| (BeamKey::new(0, b), 0)).collect();
    let before = w.stored(&all);
    assert_eq!(w.command(Control::Clobber), refusal(&Control::Clobber, "writer"));
    assert_eq!(
        w.command(Control::KillSamplers),
        refusal(&Control::KillSamplers, "writer")
    );
    let adopt = Control::Adopt {
        scene: "blake3:0000".into(),
        keep: false,
    };
    for c in [Control::Restart, Control::Quit, adopt] {
        assert_eq!(w.command(c.clone()), refusal(&c, "writer"), "{c:?}");
    }
    let kept = w.stored(&all);
    assert!(
        kept >= before && before > 1_000,
        "the writer's clobber emptied nothing ({before} rays before it, {kept} after)"
    );
    assert!(!server.text().contains("control: Clobber"), "{}", server.text());
    assert_eq!(w.command(Control::Resume), ControlOutcome::Done);
    carried_out(&server, &mut log, Control::Resume);

    // The admin's clobber empties the file (after pausing, so nothing lands after it).
    let (mut a, welcome) = Client::connect(&addr, Role::Admin, &admin);
    assert_eq!(welcome.access, Access::Admin);
    assert_eq!(a.command(Control::Pause), ControlOutcome::Done);
    carried_out(&server, &mut log, Control::Pause);
    steady(&server, &mut log, 2, "the fill to stop while paused");
    assert_eq!(a.command(Control::Clobber), ControlOutcome::Done);
    carried_out(&server, &mut log, Control::Clobber);
    assert_eq!(
        w.stored(&all),
        0,
        "the admin's clobber empties every beam ({kept} rays before)"
    );
    assert_eq!(a.command(Control::Quit), ControlOutcome::Done);
    assert!(server.wait().success(), "{}", server.text());
    let out = worker.finish();
    assert!(out.status.success(), "{}", text(&out));
    assert_eq!(rays_in(&file), 0);
}
