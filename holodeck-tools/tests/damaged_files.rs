//! Damaged and contested holodeck files through the command line: what
//! `check`, `info`, `fill` and `optimize` say and do, and two commands
//! creating one file at once.

mod common;

use std::fs;
use std::path::Path;
use std::process::{Command, Output};

use common::process::{run, Proc};
use common::text;
use holodeck_file::testing::metadata_map;

/// A small filled holodeck of the built-in room.
fn filled(dir: &Path) -> std::path::PathBuf {
    let file = dir.join("room.hdk");
    common::fill_room(&file, "3K", "0");
    file
}

fn hd(args: &[&str], file: &Path) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_holodeck"));
    cmd.args(args).arg(file);
    run(&mut cmd)
}

fn fill_more(file: &Path, extra: &[&str]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_holodeck"));
    cmd.args(["fill", "builtin:room"])
        .arg(file)
        .args(["--rays", "1K", "--bounces", "0"])
        .args(extra);
    run(&mut cmd)
}

#[test]
fn a_flipped_bit_near_the_end_is_reported_lost_nothing_and_is_mended_by_the_next_write() {
    let dir = tempfile::tempdir().unwrap();
    let file = filled(dir.path());
    let mut bytes = fs::read(&file).unwrap();
    let n = bytes.len();
    bytes[n - 3000] ^= 16;
    fs::write(&file, &bytes).unwrap();
    let o = hd(&["check"], &file);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("nothing is lost"), "{}", text(&o));
    assert!(text(&o).contains("3,000 rays verified"), "{}", text(&o));
    let o = hd(&["info"], &file);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(text(&o).contains("damaged copy"), "{}", text(&o));
    // Nothing is lost, so writing needs no consent, and it mends the copy.
    let o = fill_more(&file, &[]);
    assert!(o.status.success(), "{}", text(&o));
    let o = hd(&["check"], &file);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    assert!(text(&o).contains("4,000 rays verified"), "{}", text(&o));
}

#[test]
fn a_damaged_newest_commit_is_refused_for_writing_until_the_loss_is_accepted() {
    let dir = tempfile::tempdir().unwrap();
    let file = filled(dir.path());
    // Both copies of the first directory block.
    let map = metadata_map(&file);
    let first = map.iter().find_map(|m| m.beams).unwrap();
    let mut bytes = fs::read(&file).unwrap();
    for m in map.iter().filter(|m| m.beams == Some(first)) {
        bytes[m.extent.offset as usize + 9] ^= 1;
    }
    fs::write(&file, &bytes).unwrap();
    let o = hd(&["check"], &file);
    let t = text(&o);
    assert_eq!(o.status.code(), Some(2), "{t}");
    assert!(t.contains("(the newest) is damaged") && t.contains("loses"), "{t}");
    assert!(t.contains("--repair NEW_FILE` saves"), "{t}");
    let o = hd(&["info"], &file);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("DAMAGED"), "{}", text(&o));
    // Writing on top would make the loss permanent: refused, and the file untouched.
    let o = fill_more(&file, &[]);
    assert!(!o.status.success());
    assert!(text(&o).contains("--accept-loss"), "{}", text(&o));
    assert_eq!(fs::read(&file).unwrap(), bytes);
    // The salvage keeps every beam that verifies.
    let saved = dir.path().join("saved.hdk");
    let o = run(Command::new(env!("CARGO_BIN_EXE_holodeck"))
        .args(["check"])
        .arg(&file)
        .arg("--repair")
        .arg(&saved));
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(hd(&["check"], &saved).status.code(), Some(0));
    // With consent, writing goes on from what can be read.
    let o = fill_more(&file, &["--accept-loss"]);
    assert!(o.status.success(), "{}", text(&o));
    let o = hd(&["check"], &file);
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
}

#[test]
fn a_truncated_file_fails_check_and_optimize_leaves_it_alone() {
    let dir = tempfile::tempdir().unwrap();
    let file = filled(dir.path());
    let bytes = fs::read(&file).unwrap();
    fs::write(&file, &bytes[..bytes.len() / 2]).unwrap();
    let o = hd(&["check"], &file);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("truncated"), "{}", text(&o));
    let o = hd(&["optimize"], &file);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("is damaged"), "{}", text(&o));
    assert_eq!(fs::read(&file).unwrap(), &bytes[..bytes.len() / 2]);
}

#[test]
fn a_missing_file_cannot_be_read_which_is_not_damage_and_errors_say_each_cause_once() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.hdk");
    let o = hd(&["check"], &missing);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let t = text(&o);
    assert!(t.contains("cannot check") && !t.contains("damaged"), "{t}");
    assert_eq!(t.matches("No such file or directory").count(), 1, "{t}");
    // An empty file: no rays, and no absurd bytes per ray.
    let empty = dir.path().join("empty.hdk");
    let o = run(Command::new(env!("CARGO_BIN_EXE_holodeck"))
        .args(["create"])
        .arg(&empty)
        .args([
            "--section",
            "interior origin=0,0,0 x=2,0,0 y=0,2,0 z=0,0,2",
            "--grid",
            "0.5",
        ]));
    assert!(o.status.success(), "{}", text(&o));
    let o = hd(&["info"], &empty);
    assert!(
        text(&o).contains("no rays") && !text(&o).contains("bytes per ray"),
        "{}",
        text(&o)
    );
}

#[test]
fn of_two_commands_creating_one_file_at_once_exactly_one_wins() {
    let dir = tempfile::tempdir().unwrap();
    for round in 0..12 {
        let file = dir.path().join(format!("race{round}.hdk"));
        let start = || {
            let mut cmd = Command::new(env!("CARGO_BIN_EXE_holodeck"));
            cmd.args(["create"]).arg(&file).args([
                "--section",
                "interior origin=0,0,0 x=2,0,0 y=0,2,0 z=0,0,2",
                "--grid",
                "0.5",
            ]);
            Proc::start(&mut cmd)
        };
        let (a, b) = (start(), start());
        let (a, b) = (a.finish(), b.finish());
        let wins = [&a, &b].iter().filter(|o| o.status.success()).count();
        assert_eq!(wins, 1, "round {round}: {}\n{}", text(&a), text(&b));
        let loser = if a.status.success() { &b } else { &a };
        assert!(text(loser).contains("already exists"), "round {round}: {}", text(loser));
        let o = hd(&["check"], &file);
        assert_eq!(o.status.code(), Some(0), "round {round}: {}", text(&o));
        // Nothing is left beside it.
        let left: Vec<_> = fs::read_dir(dir.path())
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
            .collect();
        assert!(left.is_empty(), "round {round}: {left:?}");
    }
    // Two fills: one creates the file, the other opens it or says it is in use.
    for round in 0..4 {
        let file = dir.path().join(format!("fill{round}.hdk"));
        let start = || {
            let mut cmd = Command::new(env!("CARGO_BIN_EXE_holodeck"));
            cmd.args(["fill", "builtin:room"])
                .arg(&file)
                .args(["--rays", "500", "--bounces", "0"]);
            Proc::start(&mut cmd)
        };
        let (a, b) = (start(), start());
        let outs = [a.finish(), b.finish()];
        for o in &outs {
            assert!(
                o.status.success() || text(o).contains("in use by another holodeck process"),
                "round {round}: {}",
                text(o)
            );
        }
        assert!(outs.iter().any(|o| o.status.success()));
        assert_eq!(hd(&["check"], &file).status.code(), Some(0));
    }
}

#[test]
fn serve_names_the_token_file_it_cannot_write_and_leaves_nothing_behind() {
    let dir = tempfile::tempdir().unwrap();
    let file = filled(dir.path());
    // A directory where the token file should go: no token can be written there.
    let token = dir.path().join("room.hdk.token");
    fs::create_dir(&token).unwrap();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_holodeck"));
    cmd.arg("serve").arg(&file).args(["--listen", "127.0.0.1:0"]);
    let o = run(&mut cmd);
    assert!(!o.status.success());
    let t = text(&o);
    assert!(
        t.contains(&format!("writing the access token to {}", token.display())),
        "{t}"
    );
    let left: Vec<_> = fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
    assert_eq!(hd(&["check"], &file).status.code(), Some(0));
}
