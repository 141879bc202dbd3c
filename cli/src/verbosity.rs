//! The verbosity a process was given (`-v` count, `-q`): printing obeys
//! it, and the `holodeck` processes it starts log as it does.

use std::sync::OnceLock;

/// `(-v count, -q)`, set once at start.
static VERBOSITY: OnceLock<(u8, bool)> = OnceLock::new();

/// Records the verbosity the command line gave (the first call wins).
pub fn set(verbose: u8, quiet: bool) {
    let _ = VERBOSITY.set((verbose, quiet));
}

/// The arguments that give a child `holodeck` this process's verbosity.
pub fn child_args() -> Vec<&'static str> {
    match VERBOSITY.get().copied().unwrap_or((0, false)) {
        (_, true) => vec!["-q"],
        (n, false) => vec!["-v"; usize::from(n.min(4))],
    }
}

/// Whether `-q` asked for errors only (messages printed directly obey it too).
pub fn quiet() -> bool {
    VERBOSITY.get().is_some_and(|v| v.1)
}
