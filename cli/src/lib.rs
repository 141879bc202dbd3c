//! What the holodeck's command lines share: the `holodeck` command and the
//! benchmarks (`holodeck-bench`) print, parse and show progress the same
//! way through this crate.
//!
//! * `args` — argument groups and value parsers several commands take.
//! * `chart` — line charts as SVG and PNG.
//! * `generated` — generated result documents and the blocks that quote them.
//! * `human` — numbers for people.
//! * `outfile` — writing an output file without clobbering an input.
//! * `prepare` — a scene's file opened for filling, with what was found said.
//! * `progress` — progress on stderr, in one style.
//! * `verbosity` — `-v`/`-q` as given, for printing and for child processes.
//! * `view_arg` — a view given as an rview line, a file, or `last`.

pub mod args;
pub mod chart;
pub mod generated;
pub mod human;
pub mod outfile;
pub mod prepare;
pub mod progress;
pub mod verbosity;
pub mod view_arg;

pub use verbosity::quiet;

/// Prints a line saying what a command did (a summary, a file written) to
/// standard output, unless `-q` asked for errors only. What a command was
/// asked to show (`info`, `check`, `compare`, tables) is printed as usual.
#[macro_export]
macro_rules! summary {
    ($($arg:tt)*) => {
        if !$crate::quiet() {
            println!($($arg)*);
        }
    };
}

/// A note or warning on standard error, unless `-q` asked for errors only.
#[macro_export]
macro_rules! note {
    ($($arg:tt)*) => {
        if !$crate::quiet() {
            eprintln!($($arg)*);
        }
    };
}

/// Prints a line of a command's results (a table row, its heading) to
/// standard output; with `--markdown` the command also keeps it for the
/// document it generates (see `generated::record`).
#[macro_export]
macro_rules! out {
    () => {
        $crate::generated::out_line("")
    };
    ($($arg:tt)*) => {
        $crate::generated::out_line(&format!($($arg)*))
    };
}
