//! Fault injection on the server's storage path: while real samplers trace
//! into it and a display reads from it, the file's writes or syncs start
//! failing (EIO, as a dying disk's would) at chosen points. The server must
//! say so, keep serving what it has to the display (read-only), stop once the
//! display leaves, and exit with an error; the file must still hold every ray
//! of its last durable commit (as the server's own log of its flushes says)
//! and check clean.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use holodeck_display::client::DisplaySession;
use holodeck_display::request::BeamRequest;
use holodeck_file::settings::Settings;
use holodeck_file::storage::faults::{self, Op};
use holodeck_file::storage::{self, HoloFile, OpenOptions};
use holodeck_file::testing::pattern_rays;
use holodeck_protocol::{BeamKey, ViewBeams};
use holodeck_sampler::scene::gen::{generate, GenParams};
use holodeck_sampler::scene::hash::content_hash;
use holodeck_sampler::worker::run_worker;
use holodeck_sampler::{TraceOptions, Tracer};
use holodeck_server::net::{serve, Listener, ServerConfig};

const TOKEN: &str = "fault-test-token";

/// The log lines of this test process (the server runs in it).
static LOG: std::sync::Mutex<String> = std::sync::Mutex::new(String::new());

/// A writer into [`LOG`].
struct Capture;

impl std::io::Write for Capture {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        LOG.lock().unwrap().push_str(&String::from_utf8_lossy(buf));
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// Keeps the server's debug log in [`LOG`] (once per process).
fn capture_log() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        tracing_subscriber::fmt()
            .with_max_level(tracing::Level::DEBUG)
            .with_ansi(false)
            .with_writer(|| Capture)
            .init();
    });
}

/// The most rays the server's log says a commit made durable.
fn durable_in_log() -> u64 {
    LOG.lock()
        .unwrap()
        .lines()
        .filter_map(|l| l.split(" rays durable").next()?.rsplit(' ').next()?.parse().ok())
        .max()
        .unwrap_or(0)
}
/// One generous deadline for everything awaited.
const DEADLINE: Duration = Duration::from_secs(120);

/// Waits for `what` to hold, failing the test with a message after [`DEADLINE`].
fn wait_for(what: &str, mut ready: impl FnMut() -> bool) {
    let start = Instant::now();
    while !ready() {
        assert!(start.elapsed() < DEADLINE, "gave up waiting for {what}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Beams filled before the server starts: (key, rays), all durable.
fn prefill(path: &Path) -> HashMap<BeamKey, u64> {
    let mut f = HoloFile::open(path, &OpenOptions::default()).unwrap();
    let beams = f.sections()[0].beam_count();
    let mut filled = HashMap::new();
    for i in 0..150u32 {
        let key = BeamKey::new(0, (i * 811) % beams);
        f.append(key, &pattern_rays(key, 0, 7)).unwrap();
        filled.insert(key, 7);
    }
    f.close().unwrap();
    filled
}

/// Rays the display gets for the prefilled beams; each must be the pattern.
fn read_back(display: &mut DisplaySession, filled: &HashMap<BeamKey, u64>) -> u64 {
    let req = BeamRequest {
        beams: filled.keys().map(|&k| (k, 7)).collect(),
        eye: None,
        seen: ViewBeams::default(),
    };
    let mut got = 0u64;
    display
        .request(&req, true, &mut |samples| got += samples.len() as u64)
        .unwrap();
    got
}

fn scenario(tracer: &Arc<Tracer>, settings: &Settings, hash: &str, op: Op, after: u64) {
    let what = format!("{op:?} failing after {after}");
    capture_log();
    LOG.lock().unwrap().clear();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("faulty.hdk");
    HoloFile::create(&path, settings).unwrap();
    let filled = prefill(&path);
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let listener = runtime.block_on(Listener::tcp("127.0.0.1:0")).unwrap();
    let addr = listener.address();
    let file = HoloFile::open(&path, &OpenOptions::default()).unwrap();
    faults::arm(&path, op, after);
    let server =
        std::thread::spawn(move || runtime.block_on(serve(vec![listener], file, ServerConfig::new(TOKEN.into()))));
    let samplers: Vec<_> = (0..2)
        .map(|seed| {
            let (tracer, addr, hash) = (Arc::clone(tracer), addr.clone(), hash.to_string());
            std::thread::spawn(move || run_worker(&addr, &tracer, &hash, TOKEN, seed))
        })
        .collect();
    let mut display = DisplaySession::connect(&addr, TOKEN, true).unwrap();
    // The display reads what is stored, before the failure and after it.
    assert!(read_back(&mut display, &filled) >= 150 * 7, "{what}");
    wait_for(&format!("the injected failure ({what})"), faults::tripped);
    // Samplers may have added rays to these beams: at least the prefill comes back.
    assert!(
        read_back(&mut display, &filled) >= 150 * 7,
        "{what}: reads go on after a write failed"
    );
    assert!(
        !server.is_finished(),
        "{what}: the server stopped with a display connected"
    );
    drop(display);
    wait_for(&format!("the server to stop ({what})"), || server.is_finished());
    let result = server.join().unwrap();
    let e = result.expect_err("a server whose file failed must exit with an error");
    assert!(e.to_string().contains("earlier write or sync failed"), "{what}: {e}");
    for s in samplers {
        let _ = s.join().unwrap();
    }
    faults::disarm();
    // Every ray of the last durable commit is there, and the file checks clean.
    let report = storage::check(&path, |_, _| {}).unwrap();
    assert!(report.is_clean(), "{what}: {report:?}");
    let mut f = HoloFile::open(&path, &OpenOptions::read_only()).unwrap();
    let keys: Vec<BeamKey> = filled.keys().copied().collect();
    let mut seen = 0;
    f.read_beams(&keys, |k, got| {
        assert!(got.len() as u64 >= filled[&k], "{what}: {k:?} lost rays");
        assert_eq!(&got[..7], pattern_rays(k, 0, 7).as_slice(), "{what}: {k:?}");
        seen += 1;
    })
    .unwrap();
    assert_eq!(seen, filled.len());
    assert!(report.rays_ok >= 150 * 7);
    // The last commit the server made durable is all there.
    let durable = durable_in_log();
    println!(
        "{what}: the log says {durable} rays were made durable; the file holds {}",
        report.rays_ok
    );
    assert!(
        report.rays_ok >= durable,
        "{what}: {} rays, {durable} durable",
        report.rays_ok
    );
}

#[test]
fn failing_writes_and_syncs_lose_nothing_durable_and_stop_the_server() {
    let scene = generate("room", &GenParams::default()).unwrap();
    let hash = content_hash(&scene);
    let settings = Settings {
        sections: scene.sections.clone(),
        scene: Some(hash.clone()),
        ..Settings::default()
    };
    let options = TraceOptions {
        max_bounces: 1,
        ..TraceOptions::default()
    };
    let tracer = Arc::new(Tracer::new(scene, options));
    for (op, after) in [(Op::Write, 0), (Op::Write, 25), (Op::Sync, 0), (Op::Sync, 2)] {
        scenario(&tracer, &settings, &hash, op, after);
    }
}
