//! `holodeck bench share`: two displays on one server, one greedy (a fisheye
//! asking for 20,000 rays in each of its hundreds of beams) and one modest (a
//! narrow view asking for a quarter of that in a twentieth of the beams),
//! with real sampler processes tracing the room. For each order of the
//! request list (`serve --request-share`), the time from the modest request
//! to the last ray it asked for, and each display's share of the rays traced
//! meanwhile; the baseline, in the same run, is the modest display with the
//! samplers to itself.

use std::collections::{HashMap, HashSet};
use std::path::Path;
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use holodeck_protocol::wire::{Frame, Message, Role};
use holodeck_protocol::{BeamKey, Section, View, ViewBeams};

use super::network::{me, quit, serve, Peer};
use holodeck_cli::human::count;

/// Arguments of `holodeck bench share`.
#[derive(clap::Args)]
#[command(after_help = "\
Two displays, one asking for far more than the other, share real sampler processes: each
display's share of the rays.

Example:
  holodeck bench share --samplers 2")]
pub struct Args {
    /// Sampler threads.
    #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u16).range(1..=256))]
    pub samplers: u16,
    #[command(flatten)]
    pub files: super::Files,
}

/// Runs `holodeck bench share`.
pub fn run_args(a: &Args) -> Result<std::process::ExitCode> {
    run(&a.files.dir, usize::from(a.samplers), a.files.keep)?;
    Ok(std::process::ExitCode::SUCCESS)
}

/// Rays the greedy display asks for in each of its beams.
const GREEDY_RAYS: u32 = 20_000;
/// Rays the modest display asks for in each of its beams.
const MODEST_RAYS: u32 = 5000;
/// How long the greedy display is served alone before the modest one asks.
const ALONE: Duration = Duration::from_secs(1);
/// The longest wait for the modest request.
const PATIENCE: Duration = Duration::from_secs(300);

/// The beams a view of the room sees, from a grid of view rays.
fn beams_seen(sections: &[Section], view: &str, columns: u32, rows: u32) -> Result<Vec<BeamKey>> {
    let view = View::parse(view).with_context(|| format!("view {view}"))?;
    Ok(ViewBeams::select(sections, &view, columns, rows, 1)
        .counts
        .into_iter()
        .map(|c| c.0)
        .collect())
}

/// A display's request: beams and the rays wanted in each.
type Request = Vec<(BeamKey, u32)>;

/// The two requests: greedy (a fisheye) and modest (a narrow view from
/// elsewhere, without the beams the fisheye sees).
fn requests(sections: &[Section]) -> Result<(Request, Request)> {
    let s = sections.first().context("the room has no section")?;
    let eye = |f: [f64; 3]| {
        let p = s.origin() + s.axes()[0] * f[0] + s.axes()[1] * f[1] + s.axes()[2] * f[2];
        format!("-vp {} {} {} -vu 0 0 1", p.x, p.y, p.z)
    };
    let wide = beams_seen(
        sections,
        &format!("-vta {} -vd 1 0 0 -vh 180 -vv 180", eye([0.2, 0.3, 0.5])),
        400,
        300,
    )?;
    let narrow = beams_seen(
        sections,
        &format!("-vtv {} -vd 0.2 1 0.4 -vh 40 -vv 30", eye([0.5, 0.5, 0.9])),
        80,
        60,
    )?;
    let greedy = wide.iter().map(|k| (*k, GREEDY_RAYS)).collect();
    let modest = narrow
        .into_iter()
        .filter(|k| !wide.contains(k))
        .map(|k| (k, MODEST_RAYS))
        .collect();
    Ok((greedy, modest))
}

/// Sends a request (replacing) without waiting; `resend`: every stored ray,
/// not only those this display was not sent yet.
fn send_request(peer: &mut Peer, beams: &[(BeamKey, u32)], resend: bool) -> Result<()> {
    peer.link.write(&Frame::Message(Message::BeamRequest {
        beams: beams.to_vec(),
        eye: None,
        replace: true,
        resend,
    }))?;
    peer.link.flush()?;
    Ok(())
}

/// Reads beam frames up to the next `Delivered`: rays per beam.
fn read_until_delivered(peer: &mut Peer) -> Result<HashMap<BeamKey, u64>> {
    let mut got: HashMap<BeamKey, u64> = HashMap::new();
    loop {
        match peer.link.read()? {
            Some(Frame::Beam { key, records }) => *got.entry(key).or_default() += records.len() as u64,
            Some(Frame::Message(Message::Delivered { .. })) => return Ok(got),
            other => bail!("expected beams, got {other:?}"),
        }
    }
}

/// What one order of the request list gave.
struct Outcome {
    /// From the modest request to its last ray (`None`: not within [`PATIENCE`]).
    met_after: Option<Duration>,
    /// Rays stored in the modest and the greedy display's beams from then on
    /// until the modest request was met.
    modest: u64,
    greedy: u64,
}

/// Ends a child process (a server or samplers) when dropped, so that a run
/// that fails leaves nothing behind.
struct Reap(Option<Child>);

impl Reap {
    fn take(&mut self) -> Result<Child> {
        self.0.take().context("the process was already taken")
    }
}

impl Drop for Reap {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// One run: server, samplers, the greedy display (unless `!with_greedy`)
/// alone for [`ALONE`], then the modest one until its request is met.
fn run_once(dir: &Path, share: &str, with_greedy: bool, samplers: usize, keep: bool) -> Result<Outcome> {
    let file = dir.join(format!("share-{share}.hdk"));
    let _ = std::fs::remove_file(&file);
    let o = me()?
        .args(["fill", "builtin:room"])
        .arg(&file)
        .args(["--rays", "1K", "--bounces", "0"])
        .output()?;
    if !o.status.success() {
        bail!("holodeck fill failed: {}", String::from_utf8_lossy(&o.stderr));
    }
    let sections = holodeck::load("builtin:room", None)?.sections;
    let (greedy_want, modest_want) = requests(&sections)?;
    let (server, addr) = serve(&file, &["--no-fill", "--request-share", share])?;
    let mut server = Reap(Some(server));
    let mut sampler = Reap(Some(
        me()?
            .args(["sample", "builtin:room", "--connect", &addr, "--token", "bench"])
            .args(["-j", &samplers.to_string(), "--retry-for", "0s", "-q"])
            .stdout(Stdio::null())
            .spawn()?,
    ));

    // The greedy display reads what it is sent, and asks first.
    let mut greedy = Peer::connect(&addr, Role::Display, "")?;
    if with_greedy {
        send_request(&mut greedy, &greedy_want, true)?;
    }
    let reader = std::thread::spawn(move || while let Ok(Some(_)) = greedy.link.read() {});
    // A probe reads what is stored in both displays' beams (asking for
    // none): streamed rays reach a display late, the file's count does not.
    let mut probe = Peer::connect(&addr, Role::Display, "")?;
    let everything: Vec<(BeamKey, u32)> = greedy_want.iter().chain(&modest_want).map(|w| (w.0, 0)).collect();
    std::thread::sleep(ALONE);
    send_request(&mut probe, &everything, true)?;
    read_until_delivered(&mut probe)?;

    let mut modest = Peer::connect(&addr, Role::Display, "")?;
    let modest_keys: HashSet<BeamKey> = modest_want.iter().map(|w| w.0).collect();
    // Rays stored in the modest and in the greedy display's beams since the
    // probe's last look: streamed to it since, and the rest with this look.
    let mut look = || -> Result<(u64, u64)> {
        send_request(&mut probe, &everything, false)?;
        let stored = read_until_delivered(&mut probe)?;
        Ok(stored.iter().fold((0, 0), |(m, g), (k, n)| {
            if modest_keys.contains(k) {
                (m + n, g)
            } else {
                (m, g + n)
            }
        }))
    };
    let start = Instant::now();
    send_request(&mut modest, &modest_want, true)?;
    let mut have: HashMap<BeamKey, u64> = HashMap::new();
    let mut short = modest_want.len();
    let mut admitted = false;
    modest.link.stream().set_read_timeout(Some(PATIENCE))?;
    while short > 0 && start.elapsed() < PATIENCE {
        match modest.link.read() {
            Ok(Some(Frame::Beam { key, records })) => {
                let n = have.entry(key).or_default();
                let was = *n;
                *n += records.len() as u64;
                let want = modest_want.iter().find(|w| w.0 == key).map_or(0, |w| u64::from(w.1));
                if was < want && *n >= want {
                    short -= 1;
                }
            }
            // Its stored rays are read and the request is in the list: the
            // shares are counted from here.
            Ok(Some(Frame::Message(Message::Delivered { .. }))) if !admitted => {
                look()?;
                admitted = true;
            }
            Ok(Some(Frame::Message(Message::Delivered { .. }))) => {}
            Ok(Some(other)) => bail!("the modest display got {other:?}"),
            Ok(None) => bail!("the server closed the modest display's connection"),
            Err(_) => break,
        }
    }
    let met_after = (short == 0).then(|| start.elapsed());
    if !admitted {
        bail!("the modest request was never answered");
    }
    let (modest_rays, greedy_rays) = look()?;
    quit(&addr, server.take()?)?;
    let _ = sampler.take()?.wait();
    let _ = reader.join();
    if !keep {
        let _ = std::fs::remove_file(&file);
        let _ = std::fs::remove_file(dir.join(format!("share-{share}.hdk.token")));
    }
    Ok(Outcome {
        met_after,
        modest: modest_rays,
        greedy: greedy_rays,
    })
}

/// Runs the benchmark with `samplers` tracing threads.
pub fn run(dir: &Path, samplers: usize, keep: bool) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    let sections = holodeck::load("builtin:room", None)?.sections;
    let (greedy, modest) = requests(&sections)?;
    println!(
        "greedy display: {} beams x {} rays ({} rays); modest display: {} beams x {} rays ({} rays); \
         {samplers} sampler thread(s)\n",
        greedy.len(),
        GREEDY_RAYS,
        count(greedy.len() as u64 * u64::from(GREEDY_RAYS)),
        modest.len(),
        MODEST_RAYS,
        count(modest.len() as u64 * u64::from(MODEST_RAYS)),
    );
    println!(
        "| order | modest request met after | from its `Delivered` on: modest display's share of \
         the rays stored | greedy display's share |"
    );
    println!("|---|---|---|---|");
    for (share, with_greedy, what) in [
        ("fair", false, "the modest display alone"),
        ("merged", true, "merged (one neediest-first list)"),
        ("fair", true, "fair share"),
    ] {
        eprintln!("{what}...");
        let o = run_once(dir, share, with_greedy, samplers, keep)?;
        let all = (o.modest + o.greedy).max(1) as f64;
        let met = match o.met_after {
            Some(t) => format!("{:.2} s", t.as_secs_f64()),
            None => format!("not within {} s", PATIENCE.as_secs()),
        };
        println!(
            "| {what} | {met} | {:.1}% ({} rays) | {:.1}% ({} rays) |",
            100.0 * o.modest as f64 / all,
            count(o.modest),
            100.0 * o.greedy as f64 / all,
            count(o.greedy),
        );
    }
    Ok(())
}
