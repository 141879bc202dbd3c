//! The README's quick starts, run as a newcomer would run them from a fresh
//! clone, shortened: the commands are read from README.md itself, so the
//! README cannot drift from what works. Only the substitutions below change
//! them (shorter times, a free port, a headless display), and each
//! substitution must find its text, so a changed README fails here rather
//! than running something else.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::process::Proc;
use common::text;

/// The README's `## Quick start` section: its `sh` code blocks, in order.
fn quick_starts() -> Vec<String> {
    let readme = Path::new(env!("CARGO_MANIFEST_DIR")).join("../README.md");
    let text = std::fs::read_to_string(&readme).unwrap();
    let start = text
        .find("\n## Quick start\n")
        .expect("README.md has a Quick start section");
    let section = &text[start + 1..];
    let section = &section[..section[3..].find("\n## ").map_or(section.len(), |e| e + 3)];
    let mut blocks = Vec::new();
    let mut rest = section;
    while let Some(b) = rest.find("```sh\n") {
        let body = &rest[b + 6..];
        let e = body.find("```").expect("a closed code block");
        blocks.push(body[..e].to_string());
        rest = &body[e + 3..];
    }
    blocks
}

/// `block` with each `(from, to)` replaced; every `from` must be there.
fn shortened(block: &str, substitutions: &[(&str, String)]) -> Vec<String> {
    let mut b = block.to_string();
    for (from, to) in substitutions {
        assert!(b.contains(from), "the quick start no longer says {from:?}:\n{block}");
        b = b.replace(from, to);
    }
    b.lines().filter(|l| !l.trim().is_empty()).map(str::to_string).collect()
}

/// A shell running `line` in `dir`, with this build's `holodeck` first on the PATH.
fn shell(dir: &Path, line: &str) -> Command {
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_holodeck"));
    let path = format!(
        "{}:{}",
        bin.parent().unwrap().display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let mut cmd = Command::new("sh");
    cmd.arg("-c")
        .arg(format!("exec {line}"))
        .current_dir(dir)
        .env("PATH", path);
    cmd
}

/// Runs `line` to the end; fails the test with its output unless it succeeds.
fn ok(dir: &Path, line: &str) -> String {
    let o = Proc::start(&mut shell(dir, line)).finish();
    assert!(o.status.success(), "{line}: {}", text(&o));
    text(&o)
}

/// A TCP port nobody listens on now.
fn free_port() -> u16 {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    l.local_addr().unwrap().port()
}

#[test]
fn the_readme_quick_starts_work() {
    let blocks = quick_starts();
    assert_eq!(
        blocks.len(),
        4,
        "four quick starts: a session, a batch fill, a replay, a walkthrough in the browser"
    );

    // A walkthrough session, headless here: the server, two samplers and a
    // display, and a second display joining on the session's port.
    let session = tempfile::tempdir().unwrap();
    let port = free_port();
    std::fs::write(
        session.path().join("views.vf"),
        "-vtv -vp 1.5 2 1.6 -vd 1 0 0 -vu 0 0 1 -vh 60 -vv 45\n",
    )
    .unwrap();
    let lines = shortened(
        &blocks[0],
        &[
            (
                "--listen 127.0.0.1:7777",
                format!("--listen 127.0.0.1:{port} --headless --time 8s --bounces 1"),
            ),
            (
                "--connect 127.0.0.1:7777 --token-file room.hdk.viewer.token",
                format!(
                    "--connect 127.0.0.1:{port} --token-file room.hdk.viewer.token --headless \
                     --views views.vf --frames second -x 64 -y 48 --wait 1s"
                ),
            ),
        ],
    );
    assert_eq!(lines.len(), 2, "{lines:?}");
    let run = Proc::start(&mut shell(session.path(), &lines[0]));
    let mut from = 0;
    run.wait_line("the session to start", &mut from, |l| {
        l.contains("another display joins with").then_some(())
    });
    let second = ok(session.path(), &lines[1]);
    assert!(second.contains("new samples"), "{second}");
    assert!(session.path().join("second/view0001_00.png").is_file(), "{second}");
    let o = run.finish();
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("rays added"), "{}", text(&o));
    assert!(session.path().join("room.hdk").is_file());

    // A headless batch fill, then its file replayed with no server.
    let batch = tempfile::tempdir().unwrap();
    for line in shortened(&blocks[1], &[("--time 10m", "--time 3s --bounces 1".to_string())]) {
        let out = ok(batch.path(), &line);
        if line.contains(" check ") {
            assert!(out.contains("verif"), "{out}");
        }
    }
    for line in shortened(&blocks[2], &[]) {
        ok(batch.path(), &line);
    }
    for picture in ["room.png", "frames/walk_0001.png", "frames/walk_0002.png"] {
        assert!(batch.path().join(picture).is_file(), "{picture} was drawn");
    }

    // A walkthrough in the browser: the session serves the page (fetched
    // here over HTTP as a browser would; the browser tests drive a real
    // one), then the file becomes a static site.
    let web = tempfile::tempdir().unwrap();
    let port = free_port();
    let lines = shortened(
        &blocks[3],
        &[
            ("--time 1h", "--time 6s --bounces 1".to_string()),
            ("--web 127.0.0.1:8080", format!("--web 127.0.0.1:{port}")),
        ],
    );
    assert_eq!(lines.len(), 2, "{lines:?}");
    let run = Proc::start(&mut shell(web.path(), &lines[0]));
    let link = run.wait_line("the page's link", &mut 0, |l| {
        Some(l.split_once("a viewer's link: ")?.1.trim_end_matches(')').to_string())
    });
    assert!(link.starts_with(&format!("http://127.0.0.1:{port}/#token=")), "{link}");
    let page = http_get(port, "/");
    assert!(
        page.starts_with("HTTP/1.1 200") && page.contains("<title>Holodeck</title>"),
        "{page}"
    );
    let o = run.finish();
    assert!(o.status.success(), "{}", text(&o));
    ok(web.path(), &lines[1]);
    for f in [
        "site/index.html",
        "site/holodeck_web_bg.wasm",
        "site/holodeck.idx",
        "site/beams-0000.bin",
    ] {
        assert!(web.path().join(f).is_file(), "the export wrote no {f}");
    }
}

/// A plain HTTP/1.1 GET of `path` on this machine's `port`: the whole answer.
fn http_get(port: u16, path: &str) -> String {
    use std::io::{Read, Write};
    let mut s = std::net::TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_read_timeout(Some(common::process::DEADLINE)).unwrap();
    write!(s, "GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n").unwrap();
    let mut answer = String::new();
    s.read_to_string(&mut answer).unwrap();
    answer
}
