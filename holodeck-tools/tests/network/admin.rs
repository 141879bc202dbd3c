//! Control commands: what admins may do to a running server (pause, resume,
//! kill samplers, restart, clobber, quit), what a read-only display may not,
//! and DISKSPACE stopping the fill by itself.

use std::collections::HashMap;

use holodeck_protocol::wire::{Control, Frame, Message, Role};
use holodeck_protocol::BeamKey;

use crate::common::process::{wait_for, DEADLINE};
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
    let worker = sampler(&addr, token, &["builtin:room"]);
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

    // KillSamplers disconnects them and keeps new ones out until Restart.
    admin.send(&Frame::Message(Message::Control(Control::KillSamplers)));
    let out = worker.finish();
    assert!(out.status.success(), "{}", text(&out));
    carried_out(&server, &mut log, Control::KillSamplers);
    let refused = sampler(&addr, token, &["builtin:room"]).finish();
    assert!(
        !refused.status.success() && text(&refused).contains("restart"),
        "{}",
        text(&refused)
    );

    // Clobber empties the file (no sampler is running to refill it).
    // Every beam, wanting nothing more: the answer is everything stored.
    let all: Vec<(BeamKey, u32)> = (0..beams).map(|b| (BeamKey::new(0, b), 0)).collect();
    let before = display.stored(&all);
    assert!(before > initial, "the fill had stored rays ({initial} -> {before})");
    admin.send(&Frame::Message(Message::Control(Control::Clobber)));
    carried_out(&server, &mut log, Control::Clobber);
    assert_eq!(
        display.stored(&all),
        0,
        "clobber empties every beam ({before} rays before)"
    );

    // Restart lets samplers in again, and the fill goes on.
    admin.send(&Frame::Message(Message::Control(Control::Restart)));
    carried_out(&server, &mut log, Control::Restart);
    let again = sampler(&addr, token, &["builtin:room"]);
    stored_above(&mut display, &all, 0, "the fill after a restart");
    admin.send(&Frame::Message(Message::Control(Control::Quit)));
    assert!(server.wait().success(), "{}", server.text());
    let again = again.finish();
    assert!(again.status.success(), "{}", text(&again));
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

#[test]
fn a_read_only_display_is_refused_quit_kill_restart_and_clobber() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let f = file.to_str().unwrap();
    let initial = rays_in(&file);
    let token = "t";
    let (mut server, addr) = start_server_with(f, "127.0.0.1:0", token, &["--report", "0.2s"]);
    let mut worker = sampler(&addr, token, &["builtin:room"]);
    let mut log = 0;
    reported_above(&server, &mut log, initial, "the fill to start");

    let mut display = Client::read_only_display(&addr, token);
    for c in [Control::Quit, Control::KillSamplers, Control::Restart, Control::Clobber] {
        display.send(&Frame::Message(Message::Control(c)));
        match display.recv() {
            Frame::Message(Message::Error { message }) => {
                assert_eq!(message, format!("{c:?} is not allowed for a read-only display"))
            }
            other => panic!("{c:?}: {other:?}"),
        }
    }
    // None was carried out: the sampler is still connected and the fill goes
    // on, nothing was emptied, and the display is still served.
    let refused_at = next_report(&server, &mut log);
    reported_above(&server, &mut log, refused_at + 1_000, "the fill after the refusals");
    assert!(worker.try_wait().is_none(), "the sampler was not killed");
    let keys: Vec<(BeamKey, u32)> = (0..20).map(|b| (BeamKey::new(0, b * 1009), 1)).collect();
    let got = display.request(&keys, None);
    assert!(got.iter().all(|(k, _)| keys.iter().any(|w| w.0 == *k)), "{got:?}");
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
