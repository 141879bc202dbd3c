//! Argument groups several subcommands share.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};

/// How a client proves it may talk to the server.
#[derive(clap::Args)]
pub struct TokenArgs {
    /// Access token.
    #[arg(long, conflicts_with = "token_file")]
    token: Option<String>,
    /// File holding the access token (as `holodeck serve` writes it).
    #[arg(long)]
    token_file: Option<PathBuf>,
}

impl TokenArgs {
    /// The token, from the flag or the file.
    pub fn token(&self) -> Result<String> {
        Ok(match (&self.token, &self.token_file) {
            (Some(t), _) => t.clone(),
            (None, Some(p)) => std::fs::read_to_string(p)
                .with_context(|| format!("reading {}", p.display()))?
                .trim()
                .to_string(),
            (None, None) => bail!("give --token or --token-file (the server writes FILE.token)"),
        })
    }
}

/// How a display draws its frames.
#[derive(clap::Args)]
pub struct FrameArgs {
    /// Frame width.
    #[arg(short = 'x', long, default_value_t = 512)]
    pub width: u32,
    /// Frame height.
    #[arg(short = 'y', long, default_value_t = 384)]
    pub height: u32,
    /// Display driver: quadtree, or splat (plain points, the baseline).
    #[arg(long, default_value = "quadtree")]
    pub driver: String,
    /// Tone mapping for PNG: camera, human, exposure:X or exposure:auto.
    #[arg(long, default_value = "camera")]
    pub tone: String,
}
