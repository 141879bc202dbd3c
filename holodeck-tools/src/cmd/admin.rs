//! `holodeck admin`: one control command to a running server, as its admin.

use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use holodeck_protocol::wire::client::{self, ClientError};
use holodeck_protocol::wire::{Control, Frame, Message, Progress, Role};

use holodeck_cli::args::{TokenArgs, MAX_TRIANGLES};
use holodeck_cli::human::{bytes, count, count_in};

/// Arguments of `holodeck admin`.
#[derive(clap::Args)]
#[command(after_help = "\
Sends one command to the server and says how it went (exit status 1 if it was refused
or failed). Most commands need the admin token (FILE.token); pause and resume also take
the writer token, status any token.

Edit and restart (the paper's interactive scene changes):
  holodeck admin --connect 127.0.0.1:7777 --token-file room.hdk.token kill
  (edit scenes/room.toml; running samplers wait, and reload it when let in)
  holodeck admin --connect 127.0.0.1:7777 --token-file room.hdk.token adopt scenes/room.toml

Examples:
  holodeck admin --connect 127.0.0.1:7777 --token-file room.hdk.token status
  holodeck admin --connect 127.0.0.1:7777 --token-file room.hdk.writer.token pause
  holodeck admin --connect unix:/tmp/room.sock --token-file room.hdk.token adopt room.toml --keep-rays")]
pub struct Args {
    /// The server's address (host:port or unix:PATH).
    #[arg(long)]
    connect: String,
    #[command(flatten)]
    token: TokenArgs,
    #[command(subcommand)]
    command: Command,
}

/// The commands.
#[derive(clap::Subcommand)]
enum Command {
    /// Stop handing out work.
    Pause,
    /// Hand out work again.
    Resume,
    /// Disconnect every sampler and keep them out (they wait) until restart or adopt.
    Kill,
    /// Let samplers in again and start the batch fill afresh.
    Restart,
    /// Delete every ray in the file.
    Clobber,
    /// Flush the file and stop the server.
    Quit,
    /// Print the server's progress report.
    Status,
    /// Make the server's file the holodeck of an edited scene: its samplers of
    /// the old scene are disconnected, the old rays deleted (or kept, marked
    /// stale), and samplers of this scene let in.
    Adopt {
        /// Scene file, or builtin:NAME.
        scene: String,
        /// Keep the old scene's rays (`holodeck info` then says they are stale).
        #[arg(long)]
        keep_rays: bool,
        /// Triangles for builtin:landscape (K, M suffixes).
        #[arg(long, value_parser = count_in(1, MAX_TRIANGLES))]
        triangles: Option<u64>,
    },
}

/// The server's report, in one line.
fn describe(p: &Progress) -> String {
    format!(
        "{} rays ({} rays/s), {} of {} beams hold rays, file {}; {} samplers and {} displays connected{}",
        count(p.rays),
        count(p.rays_per_second.max(0.0).round() as u64),
        count(p.beams_filled),
        count(p.beams),
        bytes(p.file_bytes),
        p.samplers,
        p.displays,
        if p.paused { "; paused" } else { "" }
    )
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let token = a.token.token()?;
    let addr = a.token.address(&a.connect)?;
    let control = match a.command {
        Command::Pause => Control::Pause,
        Command::Resume => Control::Resume,
        Command::Kill => Control::KillSamplers,
        Command::Restart => Control::Restart,
        Command::Clobber => Control::Clobber,
        Command::Quit => Control::Quit,
        Command::Adopt {
            scene,
            keep_rays,
            triangles,
        } => {
            let loaded = holodeck::SceneInput::open(&scene, triangles, Some(1 << 20))?;
            Control::Adopt {
                scene: loaded.hash(),
                keep: keep_rays,
            }
        }
        Command::Status => {
            let (mut link, welcome) = client::open(&addr, client::hello(Role::Admin, &token, "", true))?;
            // Every connection gets a report as it comes.
            loop {
                match link.read().with_context(|| format!("reading from {}", a.connect))? {
                    Some(Frame::Message(Message::Progress(p))) => {
                        println!("{}: {} ({} access)", a.connect, describe(&p), welcome.access);
                        return Ok(ExitCode::SUCCESS);
                    }
                    Some(_) => {}
                    None => bail!("{} closed the connection before reporting", a.connect),
                }
            }
        }
    };
    match client::send_control(&addr, &token, control.clone()) {
        Ok(_) => {
            println!("{}: {control:?} done", a.connect);
            Ok(ExitCode::SUCCESS)
        }
        Err(e @ ClientError::Control { .. }) => {
            eprintln!("holodeck admin: {e}");
            Ok(ExitCode::FAILURE)
        }
        Err(e) => Err(e.into()),
    }
}
