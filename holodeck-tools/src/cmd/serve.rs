//! `holodeck serve`: the holodeck server on a TCP port.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{Context, Result};
use holodeck_cli::args::FINGERPRINT_LINE;
use holodeck_file::settings::{parse_duration, parse_size};
use holodeck_file::{HoloFile, OpenOptions};
use holodeck_protocol::wire::tls::Pin;
use holodeck_protocol::wire::MAX_PACKET_RAYS;
use holodeck_server::net::{serve, Fill, Listener, ServerConfig, Tls, Tokens, WebListener};
use holodeck_server::schedule::Share;
use rand::Rng;

/// Arguments of `holodeck serve`.
#[derive(clap::Args)]
#[command(after_help = "\
Serves FILE to samplers (which fill it) and displays (which read it) over TCP, and over a
Unix socket with --unix. Every peer presents one of three access tokens, each generated into
a file readable by the owner only unless given on the command line:
  FILE.token         admin (--token): everything, control commands included
  FILE.writer.token  writer (--writer-token): samplers, and pause/resume
  FILE.viewer.token  viewer (--viewer-token): displays that only read
A restarted server keeps the tokens already in those files (so running samplers and displays
get back in); --new-tokens writes new ones, locking out everyone who had the old.
TCP peers speak TLS: a self-signed certificate is made on first use (FILE.tls.crt, its key
FILE.tls.key readable by the owner only; or --tls-cert/--tls-key), and its fingerprint is
written into the token files, which pin it. Peers on other hosts must speak TLS unless
--plain-text-on-network (tokens and rays then cross the network in clear text).
Display requests are traced first;
otherwise samplers fill every beam by volume (or only what --views see; none with --no-fill).
Stops, flushing everything, on SIGINT/SIGTERM, an admin's quit, TIME, or a full DISKSPACE.

Examples:
  holodeck fill builtin:room room.hdk --rays 1K           # a file that knows its scene
  holodeck serve room.hdk --listen 0.0.0.0:7777
  holodeck sample builtin:room --connect server:7777 --token-file room.hdk.token
  holodeck serve room.hdk --unix /tmp/room.sock --views walk.vf --time 1h
  holodeck serve room.hdk --no-fill                       # display-only replay
  holodeck serve room.hdk --web 127.0.0.1:8080            # and a page: open the link it prints")]
pub struct Args {
    /// The holodeck file (it must record its scene: create it with `holodeck fill`).
    file: PathBuf,
    /// Address to listen on (port 0 picks a free one; the address is printed).
    #[arg(long, default_value = "127.0.0.1:7777")]
    listen: String,
    /// Also serve the web display here (HOST:PORT; port 0 picks a free one): a
    /// page anyone opens with a link, speaking the display protocol over a
    /// WebSocket on the same port, with the same tokens. HTTP and HTTPS (the
    /// server's certificate) on one port; from other hosts HTTPS only,
    /// unless --plain-text-on-network.
    #[arg(long, value_name = "ADDR")]
    web: Option<String>,
    /// Also listen on this Unix socket (peers connect to unix:PATH).
    #[arg(long)]
    unix: Option<PathBuf>,
    /// Admin access token; generated into FILE.token if omitted.
    #[arg(long)]
    token: Option<String>,
    /// Writer access token (samplers, pause, resume); generated into FILE.writer.token if omitted.
    #[arg(long)]
    writer_token: Option<String>,
    /// Viewer access token (read-only displays); generated into FILE.viewer.token if omitted.
    #[arg(long)]
    viewer_token: Option<String>,
    /// Generate new tokens even where the token files hold some (locks out every peer that had the old).
    #[arg(long)]
    new_tokens: bool,
    /// Rays per batch-fill packet.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_PACKET_RAYS)))]
    packet: u32,
    /// Most rays per packet traced for a display.
    #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_PACKET_RAYS)))]
    request_packet: u32,
    /// Each sampler's queue drains within this many milliseconds.
    #[arg(long, default_value_t = 250)]
    latency_ms: u64,
    /// Drop a sampler that returns nothing for this long while holding work (e.g. 30s).
    #[arg(long, default_value = "30s")]
    stall_timeout: String,
    /// Fill only the beams these views see (a file of Radiance views, one per line).
    #[arg(long, conflicts_with = "no_fill")]
    views: Option<PathBuf>,
    /// No batch fill: samplers trace only what displays request.
    #[arg(long)]
    no_fill: bool,
    /// Beam cache size (e.g. 256M); default: the file's CACHE setting.
    #[arg(long)]
    cache: Option<String>,
    /// Largest file size (e.g. 2G), a hard limit; default: the file's DISKSPACE setting (0: none).
    #[arg(long)]
    diskspace: Option<String>,
    /// Stop after this long (e.g. 2h); default: the file's TIME setting (0: no limit).
    #[arg(long)]
    time: Option<String>,
    /// Print progress this often (e.g. 1m); default: the file's REPORT setting (0: never).
    #[arg(long)]
    report: Option<String>,
    /// How display requests share the samplers: `fair` gives every display
    /// with unmet requests an equal share of the rays; `merged` serves all
    /// displays' beams in one neediest-first list (the paper's order, where
    /// a display asking for many rays starves the others).
    #[arg(long, value_enum, default_value_t = RequestShare::Fair)]
    request_share: RequestShare,
    /// Write on top of a file whose newest commit is damaged, keeping what can
    /// still be read and losing the rest for good (see `holodeck check`).
    #[arg(long)]
    accept_loss: bool,
    /// The server's certificate chain (PEM) for TLS, with --tls-key; default:
    /// the file's own, FILE.tls.crt, made self-signed on first use.
    #[arg(long, requires = "tls_key")]
    tls_cert: Option<PathBuf>,
    /// The private key (PEM) of --tls-cert.
    #[arg(long, requires = "tls_cert")]
    tls_key: Option<PathBuf>,
    /// Also take the plain protocol from other hosts: their tokens and rays
    /// cross the network in clear text, readable and forgeable on the path.
    /// Without it, peers elsewhere must speak TLS (the token files pin the
    /// certificate); this machine may always speak plain.
    #[arg(long)]
    plain_text_on_network: bool,
}

/// A token as a link's fragment carries it (tokens are URL-safe already;
/// anything else is percent-encoded).
fn token_link(token: &str) -> String {
    token
        .bytes()
        .map(|b| match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' | b'~' => (b as char).to_string(),
            other => format!("%{other:02X}"),
        })
        .collect()
}

/// Values of `--request-share`.
#[derive(Clone, Copy, clap::ValueEnum)]
enum RequestShare {
    /// An equal share of the rays for every display that waits.
    Fair,
    /// One neediest-first list over every display's beams.
    Merged,
}

/// Where the token of one access level goes: `FILE.token` (admin),
/// `FILE.writer.token`, `FILE.viewer.token`.
pub(crate) fn token_path(file: &Path, level: &str) -> PathBuf {
    let mut name = file.file_name().unwrap_or_default().to_os_string();
    if level != "admin" {
        name.push(format!(".{level}"));
    }
    name.push(".token");
    file.with_file_name(name)
}

/// The given token; else the one its file already holds (a restarted
/// server keeps its peers), unless `fresh`; else a new random one written
/// to its file.
fn token_for(given: Option<String>, file: &Path, level: &str, fresh: bool) -> Result<String> {
    if let Some(t) = given {
        if t.trim().is_empty() {
            anyhow::bail!("the {level} token must not be empty");
        }
        return Ok(t);
    }
    let path = token_path(file, level);
    if !fresh {
        if let Some(t) = kept_token(&path) {
            if !holodeck_cli::quiet() {
                eprintln!("{level} access token kept from {}", path.display());
            }
            return Ok(t);
        }
    }
    let t: String = (0..32)
        .map(|_| format!("{:x}", rand::thread_rng().gen_range(0..16u8)))
        .collect();
    write_token(&path, &t, None)?;
    if !holodeck_cli::quiet() {
        eprintln!("{level} access token written to {}", path.display());
    }
    Ok(t)
}

/// The token a token file holds, where it is one this program wrote: a
/// regular file (not a link), readable by its owner only, holding 32 hex digits.
fn kept_token(path: &Path) -> Option<String> {
    use std::os::unix::fs::PermissionsExt;
    let meta = std::fs::symlink_metadata(path).ok()?;
    if !meta.file_type().is_file() || meta.permissions().mode() & 0o077 != 0 || meta.len() > 256 {
        return None;
    }
    let text = std::fs::read_to_string(path).ok()?;
    let t = text.lines().next()?.trim();
    (t.len() == 32 && t.chars().all(|c| c.is_ascii_hexdigit())).then(|| t.to_string())
}

/// Writes the token (and the line pinning the server's certificate, when
/// there is one) readable by the owner only, to a temporary name first so
/// that a failed write leaves no empty or partial token file behind. The
/// temporary file is created new (`O_CREAT|O_EXCL|O_NOFOLLOW`): whatever
/// lies at its name (a stale file, or a link planted to catch the token) is
/// removed first, never written through.
fn write_token(path: &Path, token: &str, pin: Option<Pin>) -> Result<()> {
    use std::os::unix::fs::OpenOptionsExt;
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".{}.tmp", std::process::id()));
    let tmp = path.with_file_name(name);
    let written = (|| -> std::io::Result<()> {
        let create = || {
            std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .custom_flags(libc::O_NOFOLLOW)
                .mode(0o600)
                .open(&tmp)
        };
        let mut f = match create() {
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {
                // Unlinks a link itself, not what it points at.
                std::fs::remove_file(&tmp)?;
                create()?
            }
            other => other?,
        };
        writeln!(f, "{token}")?;
        if let Some(pin) = pin {
            writeln!(f, "{FINGERPRINT_LINE}{pin}")?;
        }
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(e).with_context(|| format!("writing the access token to {}", path.display()));
    }
    Ok(())
}

/// The certificate the server presents: the user's, or the file's own
/// (made self-signed for this machine's names and the listening address on
/// first use); its fingerprint is said.
fn server_tls(a: &Args) -> Result<Tls> {
    let tls = match (&a.tls_cert, &a.tls_key) {
        (Some(cert), Some(key)) => Tls::load(cert, key)?,
        _ => {
            let mut names = vec!["localhost".to_string(), "127.0.0.1".to_string(), "::1".to_string()];
            if let Ok(host) = std::fs::read_to_string("/proc/sys/kernel/hostname") {
                names.push(host.trim().to_string());
            }
            for addr in std::iter::once(&a.listen).chain(&a.web) {
                let host = addr.rsplit_once(':').map_or(addr.as_str(), |(h, _)| h);
                let host = host.trim_start_matches('[').trim_end_matches(']');
                if !matches!(host, "" | "0.0.0.0" | "::") {
                    names.push(host.to_string());
                }
            }
            names.retain(|n| !n.is_empty());
            names.dedup();
            let (tls, made) = Tls::own(&a.file, &names)?;
            let (cert, _) = holodeck_server::net::tls::own_paths(&a.file);
            if made {
                note!(
                    "made a self-signed TLS certificate {} (its key beside it, readable by you alone)",
                    cert.display()
                );
            }
            tls
        }
    };
    note!("TLS certificate fingerprint (SHA-256): {}", tls.fingerprint);
    Ok(tls)
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let cache_bytes = match &a.cache {
        Some(c) => Some(parse_size(c).context("--cache")?),
        None => None,
    };
    let mut file = HoloFile::open(
        &a.file,
        &OpenOptions {
            cache_bytes,
            accept_loss: a.accept_loss,
            ..OpenOptions::default()
        },
    )?;
    let tls = server_tls(&a)?;
    // Tokens are written once the file is open: a file that cannot be served keeps its old tokens.
    let tokens = Tokens {
        admin: token_for(a.token, &a.file, "admin", a.new_tokens)?,
        writer: Some(token_for(a.writer_token, &a.file, "writer", a.new_tokens)?),
        viewer: Some(token_for(a.viewer_token, &a.file, "viewer", a.new_tokens)?),
    };
    if tokens.writer.as_ref() == Some(&tokens.admin)
        || tokens.viewer.as_ref() == Some(&tokens.admin)
        || tokens.viewer == tokens.writer
    {
        anyhow::bail!("the admin, writer and viewer tokens must differ from one another");
    }
    // The token files pin the certificate: a peer given one speaks TLS.
    for (level, token) in [
        ("admin", Some(&tokens.admin)),
        ("writer", tokens.writer.as_ref()),
        ("viewer", tokens.viewer.as_ref()),
    ] {
        let path = token_path(&a.file, level);
        let generated = kept_token(&path).is_some_and(|t| Some(&t) == token);
        if let (true, Some(token)) = (generated, token) {
            write_token(&path, token, Some(tls.fingerprint))?;
        }
    }
    if let Some(d) = &a.diskspace {
        let bytes = parse_size(d).context("--diskspace")?;
        file.set_size_limit((bytes > 0).then_some(bytes));
    }
    let setting = |flag: &Option<String>, from_file: Duration, name: &str| -> Result<Option<Duration>> {
        let d = match flag {
            Some(t) => parse_duration(t, 1.0).with_context(|| format!("--{name}"))?,
            None => from_file,
        };
        Ok((!d.is_zero()).then_some(d))
    };
    let time = setting(&a.time, file.settings().time, "time")?;
    let report = setting(&a.report, file.settings().report, "report")?;
    let fill = match (&a.views, a.no_fill) {
        (_, true) => Fill::Off,
        (Some(path), false) => {
            let views = holodeck_cli::view_arg::read_views(path)?;
            let seen = holodeck::ViewFill::new(file.sections(), &views, 0.0).seen;
            eprintln!("filling only what the views see: {} beam requests", seen.len());
            Fill::Views(seen)
        }
        (None, false) => Fill::All,
    };
    let viewer_link_token = tokens.viewer.clone().unwrap_or_default();
    let web_tls = tls.clone();
    let config = ServerConfig {
        packet: a.packet,
        request_packet: a.request_packet,
        latency: Duration::from_millis(a.latency_ms.max(1)),
        fill,
        time,
        report,
        stall: parse_duration(&a.stall_timeout, 1.0).context("--stall-timeout")?,
        tokens,
        share: match a.request_share {
            RequestShare::Fair => Share::Fair,
            RequestShare::Merged => Share::Merged,
        },
        tls: Some(tls),
        plain_from_network: a.plain_text_on_network,
        ..ServerConfig::new(String::new())
    };
    let runtime = tokio::runtime::Builder::new_multi_thread().enable_all().build()?;
    runtime.block_on(async {
        let mut listeners = vec![Listener::tcp(&a.listen)
            .await
            .with_context(|| format!("listening on {}", a.listen))?];
        if let Some(path) = &a.unix {
            listeners.push(Listener::unix(path).with_context(|| format!("listening on {}", path.display()))?);
        }
        for l in &listeners {
            println!("listening on {}", l.address());
        }
        if let Some(addr) = &a.web {
            let web = Listener::Web(
                WebListener::bind(addr, crate::web::assets()?, Some(web_tls.clone()))
                    .await
                    .with_context(|| format!("serving the web display on {addr}"))?,
            );
            // Beyond this machine the link is HTTPS: plain HTTP from another
            // host is refused (unless --plain-text-on-network), as the
            // protocol's plain peers are.
            let mut page = web.address();
            if !web.local_only() {
                page = page.replacen("http://", "https://", 1);
                println!(
                    "the web display speaks HTTPS with the certificate whose SHA-256 fingerprint is {} \
                     (browsers warn of a self-signed one: compare the fingerprint)",
                    web_tls.fingerprint
                );
            }
            let viewer = token_link(&viewer_link_token);
            println!("web display on {page} (a viewer's link: {page}#token={viewer})");
            listeners.push(web);
        }
        std::io::stdout().flush()?;
        serve(listeners, file, config)
            .await
            .with_context(|| format!("serving {}", a.file.display()))
    })?;
    // Whoever started us may be gone (its end of our output with it): that is no failure.
    let _ = writeln!(std::io::stdout(), "{}: flushed and closed", a.file.display());
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn token_files_are_never_written_through_a_link_and_survive_restarts() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("room.hdk");
        // A link planted at the temporary name, pointing at a file someone can read.
        let bait = dir.path().join("bait");
        std::fs::write(&bait, "unchanged").unwrap();
        let path = token_path(&file, "admin");
        let mut tmp = path.file_name().unwrap().to_os_string();
        tmp.push(format!(".{}.tmp", std::process::id()));
        std::os::unix::fs::symlink(&bait, path.with_file_name(tmp)).unwrap();
        let first = token_for(None, &file, "admin", false).unwrap();
        assert_eq!(
            std::fs::read_to_string(&bait).unwrap(),
            "unchanged",
            "nothing written through the link"
        );
        let meta = std::fs::symlink_metadata(&path).unwrap();
        assert!(meta.file_type().is_file(), "the token file is a file, not a link");
        assert_eq!(meta.permissions().mode() & 0o777, 0o600);
        // A restart keeps it; --new-tokens replaces it.
        assert_eq!(token_for(None, &file, "admin", false).unwrap(), first);
        let fresh = token_for(None, &file, "admin", true).unwrap();
        assert_ne!(fresh, first);
        assert_eq!(token_for(None, &file, "admin", false).unwrap(), fresh);
        // A token file others may read, or a link, is not trusted: a new token replaces it.
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o644)).unwrap();
        assert_ne!(token_for(None, &file, "admin", false).unwrap(), fresh);
    }
}
