//! What the quick benchmarks of `bench all` are given: each benchmark's
//! module has a `fast` function that takes it.

use std::path::PathBuf;

/// What every fast benchmark is given.
pub struct Fast {
    /// Where to write its files.
    pub dir: PathBuf,
    /// Repeats of each figure.
    pub repeats: usize,
}
