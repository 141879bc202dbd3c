//! `holodeck run` and its children live and die together: killing `run`
//! stops its server (which flushes) and samplers, and a child that dies by a
//! signal makes `run` say so and fail.

mod common;

use std::process::Command;

use common::process::{wait_for, Proc, DEADLINE};
use holodeck_file::{storage, HoloFile, OpenOptions};

/// Live processes (not zombies) in process group `group`, with their command lines.
fn group_members(group: u32) -> Vec<(u32, String)> {
    let mut out = Vec::new();
    let Ok(dir) = std::fs::read_dir("/proc") else {
        return out;
    };
    for entry in dir.flatten() {
        let Some(pid) = entry.file_name().to_str().and_then(|s| s.parse::<u32>().ok()) else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
            continue;
        };
        // "pid (comm) state ppid pgrp ...": the command may hold spaces and parentheses.
        let Some(rest) = stat.rfind(')').map(|i| &stat[i + 1..]) else {
            continue;
        };
        let fields: Vec<&str> = rest.split_whitespace().collect();
        if fields.len() < 3 || fields[0] == "Z" || fields[2].parse::<u32>().ok() != Some(group) {
            continue;
        }
        let cmdline = std::fs::read(format!("/proc/{pid}/cmdline"))
            .map(|b| String::from_utf8_lossy(&b).replace('\0', " "))
            .unwrap_or_default();
        out.push((pid, cmdline));
    }
    out
}

fn start_run(file: &std::path::Path) -> Proc {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_holodeck"));
    cmd.args(["run", "builtin:room"])
        .arg(file)
        .args(["-n", "2", "--time", "10m", "--bounces", "1"])
        .env("HOLODECK_LOG", "info,holodeck_server=debug");
    let run = Proc::start(&mut cmd);
    let mut from = 0;
    run.wait_line("run to start filling", &mut from, |l| {
        l.starts_with("filling").then_some(())
    });
    run
}

#[test]
fn killing_run_stops_its_server_and_samplers_and_the_file_is_flushed() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let mut run = start_run(&file);
    let group = run.id();
    // A child just forked has no command line until it execs: wait for the
    // three to show theirs.
    let count = |c: &[(u32, String)], what: &str| c.iter().filter(|(_, l)| l.contains(what)).count();
    let children = wait_for("the server and two samplers", DEADLINE, || {
        let c: Vec<_> = group_members(group).into_iter().filter(|(p, _)| *p != group).collect();
        (c.len() == 3 && count(&c, " serve ") + count(&c, " sample ") == 3).then_some(c)
    });
    assert_eq!(count(&children, " serve "), 1, "{children:?}");
    assert_eq!(count(&children, " sample "), 2, "{children:?}");
    // Let rays reach the file, as the server's periodic flush says.
    let mut from = 0;
    run.wait_line("a flush that made rays durable", &mut from, |l| {
        let n: u64 = l.split("periodic flush: ").nth(1)?.split(' ').next()?.parse().ok()?;
        (n > 0).then_some(())
    });
    run.signal(libc::SIGKILL);
    // The children notice on their own (run's guard would kill its group only when reaped).
    wait_for("run's children to stop after it was killed", DEADLINE, || {
        group_members(group).is_empty().then_some(())
    });
    let status = run.wait();
    assert_eq!(status.code(), None, "run died by the signal");
    // The server flushed and let go of the file: a writer may open it, and it checks clean.
    drop(HoloFile::open(&file, &OpenOptions::default()).expect("the lock was released"));
    let report = storage::check(&file, |_, _| {}).unwrap();
    assert!(report.is_clean(), "{report:?}");
    assert!(report.rays_ok > 0);
}

#[test]
fn run_fails_saying_so_when_its_server_is_killed() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let mut run = start_run(&file);
    let group = run.id();
    let server = wait_for("the server", DEADLINE, || {
        group_members(group)
            .into_iter()
            .find(|(_, c)| c.contains(" serve "))
            .map(|(p, _)| p)
    });
    // SAFETY: kill has no memory effects; the server is alive (just listed).
    assert_eq!(unsafe { libc::kill(server as libc::pid_t, libc::SIGKILL) }, 0);
    let status = run.wait();
    assert_eq!(status.code(), Some(1), "{}", run.text());
    assert!(
        run.text().contains("the server was killed by signal 9 (SIGKILL)"),
        "{}",
        run.text()
    );
    // What the server had committed is intact.
    assert!(storage::check(&file, |_, _| {}).unwrap().is_clean());
}

#[test]
fn sigterm_or_sigint_to_run_stops_it_cleanly_with_a_summary() {
    for (signal, code) in [(libc::SIGTERM, 143), (libc::SIGINT, 130)] {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("room.hdk");
        let mut run = start_run(&file);
        let mut from = 0;
        run.wait_line("a flush that made rays durable", &mut from, |l| {
            let n: u64 = l.split("periodic flush: ").nth(1)?.split(' ').next()?.parse().ok()?;
            (n > 0).then_some(())
        });
        // To run's PID alone, as `kill PID` sends it.
        // SAFETY: kill has no memory effects; run is alive (it just printed).
        assert_eq!(unsafe { libc::kill(run.id() as libc::pid_t, signal) }, 0);
        let status = run.wait();
        let text = run.text();
        assert_eq!(status.code(), Some(code), "{text}");
        assert!(text.contains("rays added") && text.contains("interrupted by"), "{text}");
        let report = storage::check(&file, |_, _| {}).unwrap();
        assert!(report.is_clean() && report.rays_ok > 0, "{report:?}");
    }
}
