//! Helpers shared by the integration tests that run the `holodeck` binary.

use std::process::{Command, Output};

/// Runs `holodeck` with `args` and waits for it.
pub fn holodeck(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_holodeck"))
        .args(args)
        .output()
        .unwrap()
}

/// Standard output and standard error together, as text.
pub fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}
