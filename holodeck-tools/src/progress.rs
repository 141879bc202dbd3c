//! Progress bars on stderr for long work; hidden when stderr is not a terminal.

use indicatif::{ProgressBar, ProgressStyle};

/// A progress bar with a message, counting as `counts` says after the bar.
fn bar(message: &'static str, counts: &str) -> ProgressBar {
    let bar = ProgressBar::new(0);
    let style = ProgressStyle::with_template(&format!("{{msg}} [{{bar:30}}] {counts}"))
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ");
    bar.set_style(style);
    bar.set_message(message);
    bar
}

/// A byte-count progress bar with a message.
pub fn bytes_bar(message: &'static str) -> ProgressBar {
    bar(message, "{bytes}/{total_bytes} ({bytes_per_sec}, {eta})")
}

/// A ray-count progress bar with a message.
pub fn rays_bar(message: &'static str) -> ProgressBar {
    bar(message, "{human_pos}/{human_len} rays ({per_sec}, {eta})")
}

/// A progress bar counting `len` steps of work, with a message.
pub fn count_bar(message: &'static str, len: u64) -> ProgressBar {
    let b = bar(message, "{pos}/{len} ({eta})");
    b.set_length(len);
    b
}
