//! The web display in a real browser (see [`crate::browser`]): a page that
//! joins a live server with a link draws what `holodeck pict` draws from the
//! same file, moves by the native window's rule, is refused what its token
//! does not allow, keeps its picture across a server restart, and cannot
//! harm the server with bad WebSocket messages.

use std::path::Path;

use holodeck_display::compare::relative_rmse;
use holodeck_display::image_io::read_picture;
use holodeck_protocol::View;
use serde_json::json;

use crate::browser::Browser;
use crate::common::holodeck;
use crate::common::process::Proc;
use crate::harness::*;

/// The view the tests fill and look at: into the built-in room, toward its window.
const VIEW: &str = "-vtv -vp 3 2 1.4 -vd 1 0.3 -0.1 -vu 0 0 1 -vh 60 -vv 45";

/// A room file filled with `rays` rays for [`VIEW`] (one bounce).
fn room_for_view(dir: &Path, rays: &str) -> std::path::PathBuf {
    let file = dir.join("room.hdk");
    let views = dir.join("view.vf");
    std::fs::write(&views, format!("{VIEW}\n")).unwrap();
    let o = holodeck(&[
        "fill",
        "builtin:room",
        file.to_str().unwrap(),
        "--rays",
        rays,
        "--bounces",
        "1",
        "--views",
        views.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", crate::common::text(&o));
    file
}

/// A server of `file` (no fill: what is stored is all there is) with the
/// web display on `web`; returns it and the page's address.
fn web_server(file: &Path, web: &str) -> (Proc, String) {
    let (server, _) = start_server_with(
        file.to_str().unwrap(),
        "127.0.0.1:0",
        "admin-token",
        &["--no-fill", "--web", web, "--viewer-token", "viewer-token"],
    );
    let page = server.wait_line("the web display's address", &mut 0, |l| {
        Some(l.strip_prefix("web display on ")?.split_once(' ')?.0.to_string())
    });
    (server, page)
}

/// `holodeck pict` of `view` (the page's `where`) from a copy of `file` (a
/// server holds the file itself), as the page draws it: 160 x 120, one view
/// ray per 8 pixels selecting the beams, no denoiser; `extra` flags beside.
fn pict(file: &Path, view: &serde_json::Value, extra: &[&str]) -> holodeck_protocol::Picture {
    let copy = file.with_extension("copy.hdk");
    std::fs::copy(file, &copy).unwrap();
    let out = file.with_extension("pict.hdr");
    let mut args = vec![
        "pict",
        copy.to_str().unwrap(),
        "--view",
        view.as_str().unwrap(),
        "-x",
        "160",
        "-y",
        "120",
        "--stride",
        "8",
        "--denoise",
        "off",
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = holodeck(&args);
    assert!(o.status.success(), "{}", crate::common::text(&o));
    read_picture(&out).unwrap()
}

/// How closely the page's picture `a` agrees with `pict`'s `b`: every
/// measure of the yardstick, printed; the light kept in the darkest
/// quarter, middle half and brightest quarter within `light` of 1, FLIP
/// under `flip`, SSIM over `ssim`, relative RMSE under `rmse`.
fn assert_agrees(
    what: &str,
    a: &holodeck_protocol::Picture,
    b: &holodeck_protocol::Picture,
    rmse: f64,
    flip: f64,
    ssim: f64,
    light: f64,
) {
    let tone = holodeck_display::tonemap::ToneMap::from_picture(b, holodeck_display::tonemap::ToneMode::Camera);
    let m = holodeck_display::compare::metrics(a, b, &tone, None).unwrap();
    eprintln!(
        "{what}: relative RMSE {:.4}, FLIP {:.4}, SSIM {:.4}, light kept dark {:.4} middle {:.4} bright {:.4}",
        m.relative_rmse, m.flip, m.ssim, m.light.dark, m.light.middle, m.light.bright
    );
    assert!(m.relative_rmse < rmse, "{what}: relative RMSE {}", m.relative_rmse);
    assert!(m.flip < flip, "{what}: FLIP {}", m.flip);
    assert!(m.ssim > ssim, "{what}: SSIM {}", m.ssim);
    for (region, kept) in [
        ("dark", m.light.dark),
        ("middle", m.light.middle),
        ("bright", m.light.bright),
    ] {
        assert!(
            (kept - 1.0).abs() < light,
            "{what}: the {region} part keeps {kept} of the light"
        );
    }
}

/// A link's fragment value: spaces as %20 (views have no other character
/// a fragment's parameters would take otherwise).
fn fragment(s: &str) -> String {
    s.replace('%', "%25")
        .replace(' ', "%20")
        .replace('&', "%26")
        .replace('+', "%2B")
}

/// The page's link: `token`, [`VIEW`], 160 x 120, no denoiser, and one
/// request per view (a still view's refinement would select more beams,
/// with more rays than `pict` reads).
fn link(page: &str, token: &str) -> String {
    format!(
        "{page}#token={token}&view={}&width=160&height=120&denoise=off&max-density=1",
        fragment(VIEW)
    )
}

/// Waits until the page is welcomed and has every stored ray of its view.
const DELIVERED: &str = "window.holodeck && holodeck.open() && holodeck.transfers() === 0 && holodeck.samples() > 0";

#[test]
fn a_page_draws_what_pict_draws_moves_as_the_window_does_and_may_not_kill() {
    let Some(mut browser) = Browser::start() else { return };
    let dir = tempfile::tempdir().unwrap();
    let file = room_for_view(dir.path(), "150K");
    eprintln!("the browser's WebGL2: {}", browser.ask(json!({"op": "backend"})));

    // The picture: every stored ray of the view, as pict draws it (from a
    // copy of the file: the server holds the file itself), for the view
    // the page shows (the window's, fitted to the frame's aspect).
    let (mut server, page) = web_server(&file, "127.0.0.1:0");
    browser.open(&link(&page, "viewer-token"));
    browser.wait(DELIVERED);
    let shown = browser.picture();
    let reference = pict(&file, &browser.eval("holodeck.where()"), &[]);
    let error = relative_rmse(&shown, &reference).unwrap();
    let light = |p: &holodeck_protocol::Picture| p.pixels.iter().map(|c| f64::from(c.x + c.y + c.z)).sum::<f64>();
    let kept = light(&shown) / light(&reference);
    eprintln!("the page's picture against pict's: relative RMSE {error:.4}, light {kept:.4}");
    assert!(
        error < 0.01,
        "the page's picture differs from pict's: relative RMSE {error}"
    );
    assert!((kept - 1.0).abs() < 0.01, "the page keeps {kept} of pict's light");
    assert_agrees("the page (quadtree)", &shown, &reference, 0.01, 0.02, 0.98, 0.01);

    // The canvas shows it: its pixels, read back, follow the picture's light.
    let rgba: Vec<f64> = browser
        .eval("holodeck.pixels()")
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let grey: Vec<f64> = rgba.chunks_exact(4).map(|p| (p[0] + p[1] + p[2]) / 3.0).collect();
    let lum: Vec<f64> = shown
        .pixels
        .iter()
        .map(|c| f64::from(c.x + c.y + c.z).powf(1.0 / 2.2))
        .collect();
    let r = correlation(&grey, &lum);
    eprintln!("canvas against picture: correlation {r:.3}");
    assert!(r > 0.9, "the canvas does not show the picture (correlation {r})");

    // A drag with the left button moves the eye toward the point under
    // the cursor, keeping the view direction (the window's rule).
    let before = view_of(&browser.eval("holodeck.where()"));
    browser.ask(json!({"op": "mouse", "action": "down", "x": 80, "y": 60, "button": "left"}));
    browser.ask(json!({"op": "hold", "ms": 400}));
    browser.ask(json!({"op": "mouse", "action": "up", "x": 80, "y": 60, "button": "left"}));
    browser.wait(DELIVERED);
    let after = view_of(&browser.eval("holodeck.where()"));
    let moved = after.position - before.position;
    let along = moved.normalize().dot(before.direction.normalize());
    eprintln!(
        "the drag moved the eye {:.3} m, {:.2} degrees off the view direction",
        moved.length(),
        along.clamp(-1.0, 1.0).acos().to_degrees()
    );
    assert!(moved.length() > 0.01, "the eye did not move: {before:?} -> {after:?}");
    assert!(along > 0.999, "the eye moved off the line to the point: {moved:?}");
    assert!((after.direction.normalize() - before.direction.normalize()).length() < 1e-9);
    // `last` goes back.
    browser.ask(json!({"op": "type", "selector": "#line", "text": "last", "enter": true}));
    let back = view_of(&browser.wait("holodeck.where().includes('-vp 3 2 1.4') && holodeck.where()"));
    assert!((back.position - before.position).length() < 1e-9);

    // Fingers: one moves toward the point, two back away (the window's
    // left and right buttons).
    let touch = |fingers: &[(u32, u32)]| {
        let points: Vec<String> = fingers.iter().map(|(x, y)| format!("[{x}, {y}]")).collect();
        format!(
            "(async () => {{ const c = document.getElementById('view'); const r = c.getBoundingClientRect();              const ev = (type, [x, y], id) => new PointerEvent(type, {{ pointerId: id, pointerType: 'touch', bubbles: true,              clientX: r.left + (x + 0.5) * r.width / c.width, clientY: r.top + (y + 0.5) * r.height / c.height }});              const pts = [{}]; pts.forEach((p, i) => c.dispatchEvent(ev('pointerdown', p, 11 + i)));              await new Promise((d) => setTimeout(d, 300)); pts.forEach((p, i) => c.dispatchEvent(ev('pointerup', p, 11 + i)));              return true; }})()",
            points.join(", ")
        )
    };
    browser.eval(&touch(&[(80, 60)]));
    browser.wait(DELIVERED);
    let forward = view_of(&browser.eval("holodeck.where()"));
    let ahead = (forward.position - before.position).dot(before.direction.normalize());
    assert!(ahead > 0.01, "one finger did not move the eye forward: {ahead}");
    browser.eval(&touch(&[(70, 60), (90, 60)]));
    browser.wait(DELIVERED);
    let back = view_of(&browser.eval("holodeck.where()"));
    let behind = (back.position - forward.position).dot(before.direction.normalize());
    eprintln!("one finger moved the eye {ahead:.3} m forward, two fingers {behind:.3} m");
    assert!(behind < -0.01, "two fingers did not move the eye back: {behind}");
    // A pinch (two fingers spreading) turns toward their middle, the eye kept.
    let pinch = "(async () => { const c = document.getElementById('view'); const r = c.getBoundingClientRect(); \
        const ev = (type, x, y, id) => new PointerEvent(type, { pointerId: id, pointerType: 'touch', bubbles: true, \
        clientX: r.left + (x + 0.5) * r.width / c.width, clientY: r.top + (y + 0.5) * r.height / c.height }); \
        c.dispatchEvent(ev('pointerdown', 120, 30, 21)); c.dispatchEvent(ev('pointerdown', 140, 30, 22)); \
        c.dispatchEvent(ev('pointermove', 110, 30, 21)); c.dispatchEvent(ev('pointermove', 150, 30, 22)); \
        await new Promise((d) => setTimeout(d, 300)); \
        c.dispatchEvent(ev('pointerup', 110, 30, 21)); c.dispatchEvent(ev('pointerup', 150, 30, 22)); return true; })()";
    browser.eval(pinch);
    browser.wait(DELIVERED);
    let turned = view_of(&browser.eval("holodeck.where()"));
    let angle = turned
        .direction
        .normalize()
        .dot(back.direction.normalize())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    eprintln!("a pinch turned the view {angle:.2} degrees");
    assert!(angle > 0.5, "a pinch did not turn the view");
    assert!(
        (turned.position - back.position).length() < 1e-9,
        "a pinch moved the eye"
    );
    // The pinch's middle is up and to the right: the view turned that way.
    assert!(turned.direction.z > back.direction.z, "{turned:?}");
    browser.ask(json!({"op": "type", "selector": "#line", "text": "last", "enter": true}));
    browser.wait(DELIVERED);

    // The window's keys: `v` says where the view is.
    browser.ask(json!({"op": "key", "key": "v"}));
    let said = browser.wait("holodeck.log.find((l) => l.startsWith('VIEW='))");
    assert_eq!(view_of(&said).position, back.position);
    // The save button offers the picture as a PNG of the frame's size.
    let png = dir.path().join("saved.png");
    let name = browser.ask(json!({"op": "download", "selector": "#save", "path": png.to_str().unwrap()}));
    assert_eq!(name, json!("holodeck.png"));
    let saved = image::open(&png).unwrap();
    assert_eq!((saved.width(), saved.height()), (160, 120));

    // A viewer may look, never change anything: the server refuses its kill.
    browser.ask(json!({"op": "type", "selector": "#line", "text": "kill", "enter": true}));
    let refusal = browser.wait("holodeck.log.find((l) => l.startsWith('kill was refused'))");
    assert!(refusal.as_str().unwrap().contains("viewer"), "{refusal}");

    // A wrong token is refused with a reason, and the page asks for one.
    browser.open("about:blank");
    browser.open(&link(&page, "not-a-token"));
    let why = browser.wait("holodeck.log.find((l) => l.includes('refused'))");
    assert!(why.as_str().unwrap().contains("wrong access token"), "{why}");
    assert_eq!(browser.eval("document.getElementById('join').hidden"), json!(false));

    // Bad WebSocket messages end that socket, and nothing else.
    let ws = page.replacen("http://", "ws://", 1) + "ws";
    let closed = browser.eval(&format!(
        "new Promise((done) => {{ const s = new WebSocket('{ws}'); s.binaryType = 'arraybuffer'; \
         s.onopen = () => s.send(new Uint8Array(2 << 20)); s.onclose = (e) => done(e.code); }})"
    ));
    eprintln!("an oversized message closed its socket with code {closed}");
    let refused = browser.eval(&format!(
        "new Promise((done) => {{ const s = new WebSocket('{ws}'); s.binaryType = 'arraybuffer'; let got = 0; \
         s.onopen = () => s.send(new Uint8Array([255, 255, 255, 127, 0, 1, 2, 3])); \
         s.onmessage = (e) => {{ got += e.data.byteLength; }}; s.onclose = () => done(got); }})"
    ));
    assert!(refused.as_u64().unwrap() > 0, "a malformed frame got no refusal");
    let text = browser.eval(&format!(
        "new Promise((done) => {{ const s = new WebSocket('{ws}'); s.onopen = () => s.send('hello'); s.onclose = () => done('closed'); }})"
    ));
    assert_eq!(text, json!("closed"));
    assert!(server.try_wait().is_none(), "the server died");
    browser.open("about:blank");
    browser.open(&link(&page, "viewer-token"));
    browser.wait(DELIVERED);
    let again = browser.picture();
    assert!(relative_rmse(&again, &reference).unwrap() < 0.05);
}

#[test]
fn a_page_keeps_its_picture_while_the_server_restarts_and_then_reconnects() {
    let Some(mut browser) = Browser::start() else { return };
    let dir = tempfile::tempdir().unwrap();
    let file = room_for_view(dir.path(), "60K");
    let (mut server, page) = web_server(&file, "127.0.0.1:0");
    browser.open(&link(&page, "viewer-token"));
    browser.wait(DELIVERED);
    let first = browser.picture();
    let pixels = browser.eval("holodeck.pixels()");

    server.signal(libc::SIGTERM);
    assert!(server.wait().success());
    browser.wait("holodeck.status().startsWith('connection lost')");
    // While the server is gone the page still shows its picture.
    assert_eq!(browser.eval("holodeck.pixels()"), pixels);

    let port = page.trim_end_matches('/').rsplit(':').next().unwrap().to_string();
    let (_server, again) = web_server(&file, &format!("127.0.0.1:{port}"));
    assert_eq!(again, page);
    browser.wait(&format!("holodeck.connects() === 2 && {DELIVERED}"));
    let second = browser.picture();
    let error = relative_rmse(&second, &first).unwrap();
    assert!(
        error < 0.05,
        "after reconnecting the picture differs: relative RMSE {error}"
    );
}

/// The view of a `VIEW= …` line.
fn view_of(line: &serde_json::Value) -> View {
    View::parse(line.as_str().unwrap()).unwrap()
}

/// Pearson's correlation of two equally long series.
fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        ab += (x - ma) * (y - mb);
        aa += (x - ma) * (x - ma);
        bb += (y - mb) * (y - mb);
    }
    ab / (aa * bb).sqrt().max(1e-300)
}

#[test]
fn a_page_joins_a_live_run_and_its_picture_fills_in_as_samplers_trace() {
    let Some(mut browser) = Browser::start() else { return };
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("live.hdk");
    let run = Proc::start(bin().current_dir(dir.path()).args([
        "run",
        "builtin:room",
        file.to_str().unwrap(),
        "-n",
        "2",
        "--time",
        "300s",
        "--bounces",
        "1",
        "--web",
        "127.0.0.1:0",
    ]));
    let viewer = run.wait_line("the page's link", &mut 0, |l| {
        Some(l.split_once("a viewer's link: ")?.1.trim_end_matches(')').to_string())
    });
    // The link as printed, with the page's own frame size and view.
    browser.open(&format!("{viewer}&view={}&width=160&height=120", fragment(VIEW)));
    let first = browser.wait("window.holodeck && holodeck.open() && holodeck.samples() > 0 && holodeck.samples()");
    let first = first.as_f64().unwrap();
    let status = browser.wait("holodeck.status().includes('samplers') && holodeck.status()");
    eprintln!("the page's status line: {status}");
    // While the view stays, the samplers trace for it and the picture fills in.
    let later = browser.wait(&format!(
        "holodeck.samples() > 4 * {first} + 5000 && holodeck.samples()"
    ));
    let shown = browser.picture();
    let lit = shown.pixels.iter().filter(|p| p.max_element() > 0.0).count();
    eprintln!(
        "samples {first} then {later}; {lit} of {} pixels lit",
        shown.pixels.len()
    );
    assert!(lit * 10 > shown.pixels.len() * 9, "only {lit} pixels have light");
}

#[test]
fn a_static_export_replays_the_file_in_a_page_with_no_server() {
    let Some(mut browser) = Browser::start() else { return };
    let dir = tempfile::tempdir().unwrap();
    let file = room_for_view(dir.path(), "150K");
    let site = dir.path().join("site");
    let o = holodeck(&[
        "export",
        "web",
        file.to_str().unwrap(),
        "-o",
        site.to_str().unwrap(),
        "--chunk",
        "256K",
    ]);
    assert!(o.status.success(), "{}", crate::common::text(&o));
    for f in [
        "index.html",
        "app.js",
        "holodeck_web.js",
        "holodeck_web_bg.wasm",
        "holodeck.idx",
        "beams-0000.bin",
    ] {
        assert!(site.join(f).is_file(), "the site has no {f}");
    }
    // A folder that holds files is never written over.
    let again = holodeck(&["export", "web", file.to_str().unwrap(), "-o", site.to_str().unwrap()]);
    assert!(!again.status.success());
    let said = crate::common::text(&again);
    assert!(said.contains("is not an empty folder"), "{said}");
    // No process serves it: the browser reads the folder as a static host would.
    browser.ask(json!({"op": "site", "dir": site.to_str().unwrap(), "origin": "http://site.test"}));
    browser.open(&format!(
        "http://site.test/#view={}&width=160&height=120&denoise=off",
        fragment(VIEW)
    ));
    browser.wait(DELIVERED);
    assert_eq!(browser.eval("holodeck.replay()"), json!(true));
    assert!(
        browser.eval("holodeck.ranged()").as_u64().unwrap() > 0,
        "no byte range was asked for"
    );
    let shown = browser.picture();
    let reference = pict(&file, &browser.eval("holodeck.where()"), &[]);
    assert_agrees("the replayed page", &shown, &reference, 0.02, 0.02, 0.98, 0.01);
    let error = relative_rmse(&shown, &reference).unwrap();
    eprintln!(
        "the replayed page against pict: relative RMSE {error:.4}; served {}",
        browser.ask(json!({"op": "served"}))
    );
    assert!(
        error < 0.02,
        "the replayed picture differs from pict's: relative RMSE {error}"
    );
    // A command that needs a server says so.
    browser.ask(json!({"op": "type", "selector": "#line", "text": "pause", "enter": true}));
    browser.wait("holodeck.log.find((l) => l.includes('pause needs a server'))");
    // Moving fetches the new view's beams.
    let before = browser.eval("holodeck.samples()").as_f64().unwrap();
    browser.ask(json!({"op": "type", "selector": "#line", "text": "-vd 1 -0.3 -0.1", "enter": true}));
    let after = browser.wait(&format!(
        "holodeck.transfers() === 0 && holodeck.samples() > {before} && holodeck.samples()"
    ));
    eprintln!("turning fetched {} more samples", after.as_f64().unwrap() - before);
}

#[test]
fn a_sparse_static_export_fills_its_gaps_from_neighbouring_beams_as_pict_does() {
    let Some(mut browser) = Browser::start() else { return };
    let dir = tempfile::tempdir().unwrap();
    // A fill by volume: a few rays in every beam, sparse for any one view.
    let file = dir.path().join("sparse.hdk");
    let o = holodeck(&["fill", "builtin:room", file.to_str().unwrap(), "--rays", "200K", "-q"]);
    assert!(o.status.success(), "{}", crate::common::text(&o));
    let site = dir.path().join("site");
    let o = holodeck(&["export", "web", file.to_str().unwrap(), "-o", site.to_str().unwrap()]);
    assert!(o.status.success(), "{}", crate::common::text(&o));
    browser.ask(json!({"op": "site", "dir": site.to_str().unwrap(), "origin": "http://site.test"}));
    browser.open(&format!(
        "http://site.test/#view={}&width=160&height=120&denoise=off&neighbours=1",
        fragment(VIEW)
    ));
    browser.wait(DELIVERED);
    let status = browser.wait("holodeck.status().includes('px from neighbouring beams') && holodeck.status()");
    let filled: u64 = status
        .as_str()
        .and_then(|s| {
            s.split("  ")
                .find_map(|p| p.strip_suffix(" px from neighbouring beams"))
        })
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no count of filled pixels in {status}"));
    let shown = browser.picture();
    let at = browser.eval("holodeck.where()");
    let filled_pict = pict(&file, &at, &["--neighbour-beams"]);
    let plain_pict = pict(&file, &at, &[]);
    assert_agrees(
        "the sparse page with neighbours",
        &shown,
        &filled_pict,
        0.02,
        0.02,
        0.98,
        0.01,
    );
    let apart = relative_rmse(&shown, &plain_pict).unwrap();
    eprintln!("{filled} pixels filled; the page against pict without neighbours: relative RMSE {apart:.4}");
    assert!(filled > 1000, "{filled} pixels filled");
    assert!(apart > 0.05, "the neighbours changed nothing: {apart}");
}

/// The server's resident memory, kB (`VmRSS` of /proc/PID/status).
fn resident_kb(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap_or_else(|| panic!("no VmRSS in {status}"))
}

#[test]
fn pages_left_open_cost_the_server_no_growing_memory_and_a_missing_token_is_asked_for() {
    let Some(mut browser) = Browser::start() else { return };
    let dir = tempfile::tempdir().unwrap();
    let file = room_for_view(dir.path(), "60K");
    let (server, page) = web_server(&file, "127.0.0.1:0");
    // Without a token the page asks for one, and joins with it.
    browser.open(&format!(
        "{page}#view={}&width=160&height=120&max-density=1",
        fragment(VIEW)
    ));
    assert_eq!(
        browser.wait("window.holodeck && !document.getElementById('join').hidden"),
        json!(true)
    );
    browser.ask(json!({"op": "type", "selector": "#token", "text": "viewer-token", "enter": true}));
    browser.wait(DELIVERED);
    // The page's greeting and request, sent again by twelve idle sockets
    // that read every report the server sends them.
    let pages = 12;
    browser.eval(&format!(
        "(() => {{ window.idle = []; const sent = holodeck.sentLog(); for (let i = 0; i < {pages}; i++) {{ \
         const s = new WebSocket(`ws://${{location.host}}/ws`); s.binaryType = 'arraybuffer'; const w = {{ messages: 0 }}; \
         s.onopen = () => sent.forEach((m) => s.send(m)); s.onmessage = () => {{ w.messages += 1; }}; window.idle.push(w); }} \
         return true; }})()"
    ));
    let reports = |browser: &mut Browser| {
        browser
            .eval("Math.min(...window.idle.map((w) => w.messages))")
            .as_u64()
            .unwrap()
    };
    browser.wait("window.idle.every((w) => w.messages >= 5)");
    let (before, at) = (resident_kb(server.id()), reports(&mut browser));
    // A report a second: fifteen more to every page.
    browser.wait(&format!("window.idle.every((w) => w.messages >= {})", at + 15));
    let after = resident_kb(server.id());
    eprintln!("the server with {pages} idle pages: {before} kB, then {after} kB after fifteen more reports each");
    assert!(
        after <= before + 1024,
        "the server grew from {before} kB to {after} kB with idle pages"
    );
}

/// This machine's first address that is not loopback, if it has one.
fn network_address() -> Option<std::net::IpAddr> {
    // The address a datagram socket would leave by (nothing is sent).
    let s = std::net::UdpSocket::bind("0.0.0.0:0").ok()?;
    s.connect("198.51.100.1:9").ok()?;
    let ip = s.local_addr().ok()?.ip();
    (!ip.is_loopback() && !ip.is_unspecified()).then_some(ip)
}

#[test]
fn the_web_port_speaks_https_and_takes_pages_from_other_hosts_only_over_it() {
    let Some(mut browser) = Browser::start() else { return };
    let dir = tempfile::tempdir().unwrap();
    let file = room_for_view(dir.path(), "60K");
    let Some(ip) = network_address() else {
        eprintln!("this machine has no address but loopback: the web port is tested on loopback only");
        let (_server, page) = web_server(&file, "127.0.0.1:0");
        browser.open(&link(&page.replacen("http://", "https://", 1), "viewer-token"));
        browser.wait(DELIVERED);
        return;
    };
    let (server, page) = web_server(&file, "0.0.0.0:0");
    let fingerprint = server.wait_line("the certificate's fingerprint", &mut 0, |l| {
        l.contains("the web display speaks HTTPS").then(|| l.to_string())
    });
    assert!(page.starts_with("https://"), "{page}");
    let port = page.trim_end_matches('/').rsplit(':').next().unwrap().to_string();
    // Over TLS from another host's address (this one's, not loopback): served.
    browser.open(&link(&format!("https://{ip}:{port}/"), "viewer-token"));
    browser.wait(DELIVERED);
    assert!(browser.eval("location.protocol").as_str() == Some("https:"));
    // Plain HTTP from another host: the page loads, its display is refused.
    browser.open("about:blank");
    browser.open(&link(&format!("http://{ip}:{port}/"), "viewer-token"));
    let why = browser.wait("window.holodeck && holodeck.log.find((l) => l.includes('refused'))");
    assert!(why.as_str().unwrap().contains("over TLS only"), "{why}");
    eprintln!("{fingerprint}\nplain HTTP from {ip}: {why}");
}

#[test]
fn a_page_draws_with_the_gpu_mesh_driver_on_webgl2_as_pict_does_natively() {
    let Some(mut browser) = Browser::start() else { return };
    let dir = tempfile::tempdir().unwrap();
    let file = room_for_view(dir.path(), "150K");
    let (_server, page) = web_server(&file, "127.0.0.1:0");
    browser.open(&format!("{}&driver=mesh", link(&page, "viewer-token")));
    browser.wait(DELIVERED);
    let driver = browser.eval("holodeck.driver()");
    eprintln!("the page's driver: {driver}");
    let driver = driver.as_str().unwrap();
    assert!(driver.starts_with("mesh on") && driver.contains("WebGL"), "{driver}");
    let shown = browser.picture();
    let reference = pict(&file, &browser.eval("holodeck.where()"), &["--driver", "mesh"]);
    assert_agrees(
        "the page's mesh (WebGL2, against Vulkan)",
        &shown,
        &reference,
        0.05,
        0.05,
        0.95,
        0.02,
    );
    let error = relative_rmse(&shown, &reference).unwrap();
    eprintln!("the page's mesh (WebGL2) against pict's mesh (Vulkan): relative RMSE {error:.4}");
    assert!(
        error < 0.05,
        "the page's mesh picture differs from pict's: relative RMSE {error}"
    );
    // The Voronoi cones too (no scene geometry in the page to cull them by).
    browser.open("about:blank");
    browser.open(&format!("{}&driver=voronoi", link(&page, "viewer-token")));
    browser.wait(DELIVERED);
    assert!(browser
        .eval("holodeck.driver()")
        .as_str()
        .unwrap()
        .starts_with("voronoi on"));
    let cones = browser.picture();
    let reference = pict(&file, &browser.eval("holodeck.where()"), &["--driver", "voronoi"]);
    assert_agrees(
        "the page's voronoi (WebGL2, against Vulkan)",
        &cones,
        &reference,
        0.05,
        0.05,
        0.95,
        0.02,
    );
    let error = relative_rmse(&cones, &reference).unwrap();
    eprintln!("the page's voronoi (WebGL2) against pict's voronoi (Vulkan): relative RMSE {error:.4}");
    assert!(
        error < 0.05,
        "the page's voronoi picture differs from pict's: relative RMSE {error}"
    );
}

#[test]
fn a_browser_without_webgl_draws_a_gpu_drivers_view_with_the_quadtree() {
    let Some(mut browser) = Browser::start_with(&["--disable-gpu", "--disable-software-rasterizer"]) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let file = room_for_view(dir.path(), "60K");
    let (_server, page) = web_server(&file, "127.0.0.1:0");
    browser.open(&format!("{}&driver=mesh", link(&page, "viewer-token")));
    browser.wait(DELIVERED);
    assert_eq!(browser.ask(json!({"op": "backend"})), json!("no WebGL2"));
    assert_eq!(browser.eval("holodeck.driver()"), json!("quadtree on the CPU"));
    let said = browser.wait("holodeck.log.find((l) => l.includes('cannot run here'))");
    assert!(
        said.as_str().unwrap().starts_with("the mesh driver cannot run here"),
        "{said}"
    );
    let reference = pict(&file, &browser.eval("holodeck.where()"), &[]);
    let error = relative_rmse(&browser.picture(), &reference).unwrap();
    assert!(
        error < 0.01,
        "the stand-in quadtree differs from pict's: relative RMSE {error}"
    );
}
