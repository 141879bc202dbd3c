//! Every build records the commit it was built from (`HOLODECK_COMMIT`),
//! which generated documents name.

use std::path::PathBuf;
use std::process::Command;

fn main() {
    commit();
}

/// The checkout's commit, or "unknown" outside a git checkout; the build
/// runs again when HEAD moves.
fn commit() {
    let git = |args: &[&str]| {
        Command::new("git")
            .args(args)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .and_then(|o| String::from_utf8(o.stdout).ok())
            .map(|s| s.trim().to_string())
    };
    let commit = git(&["rev-parse", "--short=12", "HEAD"]).unwrap_or_else(|| "unknown".into());
    println!("cargo:rustc-env=HOLODECK_COMMIT={commit}");
    if let Some(dir) = git(&["rev-parse", "--git-dir"]) {
        let dir = PathBuf::from(dir);
        // Only paths that exist: a missing one would rebuild every time.
        for p in [dir.join("HEAD"), dir.join("refs/heads"), dir.join("packed-refs")] {
            if p.exists() {
                println!("cargo:rerun-if-changed={}", p.display());
            }
        }
    }
}
