//! `holodeck bench publish`: tables a script measured, read from standard
//! input, written as a generated results document headed by the script's
//! command, the commit and the date (as `--markdown` does for the commands
//! that measure themselves).

use std::io::Read;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context, Result};

/// Most bytes read from standard input.
const MAX_INPUT: u64 = 16 << 20;

/// Arguments of `holodeck bench publish`.
#[derive(clap::Args)]
#[command(after_help = "\
Reads Markdown (a script's tables) from standard input and writes it as DIR/NAME.md, headed
by --command, this build's commit and the date, then refreshes the blocks quoting it in the
Markdown files of DIR's parent (docs/RESULTS.md quotes docs/results/NAME.md).

Examples:
  docs/results/memory.sh | holodeck bench publish model --command docs/results/memory.sh --markdown docs/results")]
pub struct Args {
    /// The document's name: it is written as DIR/NAME.md.
    name: String,
    /// The command whose output standard input holds (named in the document's first line).
    #[arg(long)]
    command: String,
    /// Where to write it.
    #[arg(long, value_name = "DIR")]
    markdown: PathBuf,
}

/// Runs the command.
pub fn run(a: &Args) -> Result<ExitCode> {
    if a.name.is_empty()
        || !a
            .name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
    {
        bail!(
            "NAME {:?} must be letters, digits, - and _ (it names DIR/NAME.md)",
            a.name
        );
    }
    let mut text = String::new();
    std::io::stdin()
        .take(MAX_INPUT + 1)
        .read_to_string(&mut text)
        .context("reading standard input")?;
    if text.len() as u64 > MAX_INPUT {
        bail!("standard input holds more than {MAX_INPUT} bytes");
    }
    if text.trim().is_empty() {
        bail!("standard input is empty: nothing to publish");
    }
    holodeck_cli::generated::publish_with_charts(&a.markdown, &a.name, &a.command, text, &[])?;
    Ok(ExitCode::SUCCESS)
}
