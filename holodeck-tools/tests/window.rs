//! The walkthrough window on a virtual X screen (Xvfb) and software Vulkan:
//! real X input events (xdotool) move the view as the holodeck paper's input
//! model says, and the window's pixels (read back with xwd) match a headless
//! picture of the same view.

mod common;

use std::process::Command;

use common::screen::{view_of, Screen};
use glam::DVec3;
use holodeck_display::compare::relative_rmse_masked;
use holodeck_display::image_io::read_picture;
use holodeck_protocol::{Picture, View};

/// Window size: small, so that software rendering stays quick.
const W: u32 = 320;
const H: u32 = 240;

/// Rows of the status line at the bottom of the window (left out of
/// picture comparisons): at this width it wraps onto up to four lines.
const STATUS_ROWS: usize = 4 * holodeck_display::window::overlay::STATUS_HEIGHT as usize;

/// The end of a motion: its steps and the point it moved about (none when
/// the button was let go before a step).
fn moved(line: &str) -> Option<(u32, Option<DVec3>)> {
    let rest = line.strip_prefix("moved: ")?;
    let words: Vec<&str> = rest.split_whitespace().collect();
    let steps = words.first()?.parse().ok()?;
    let p = (|| {
        Some(DVec3::new(
            words.get(3)?.parse().ok()?,
            words.get(4)?.parse().ok()?,
            words.get(5)?.parse().ok()?,
        ))
    })();
    Some((steps, p))
}

/// The built-in room filled with `rays` rays of one bounce.
fn room(dir: &std::path::Path, rays: &str) -> std::path::PathBuf {
    let file = dir.join("room.hdk");
    common::fill_room(&file, rays, "1");
    file
}

/// The relative RMSE of what a window `shown` against `holodeck pict` of
/// `view` from `file` with `driver` (the status line left out).
fn headless_error(file: &std::path::Path, view: &View, driver: &str, shown: &Picture) -> f64 {
    let reference = file.with_extension(format!("{driver}.png"));
    let (w, h, spec) = (W.to_string(), H.to_string(), view.to_spec());
    let f = file.to_str().unwrap();
    let mut args = vec![
        "pict", f, "--view", &spec, "--stride", "2", "-x", &w, "-y", &h, "--driver", driver,
    ];
    if driver == "voronoi" {
        args.extend(["--geometry", "builtin:room"]);
    }
    args.extend(["-o", reference.to_str().unwrap()]);
    let o = common::holodeck(&args);
    assert!(o.status.success(), "{}", common::text(&o));
    let reference = read_picture(&reference).unwrap();
    let mask: Vec<bool> = (0..shown.pixels.len())
        .map(|i| i / (W as usize) < H as usize - STATUS_ROWS)
        .collect();
    relative_rmse_masked(shown, &reference, &mask).unwrap()
}

#[test]
fn left_drag_walks_toward_the_point_under_the_cursor_and_the_window_shows_the_headless_picture() {
    let dir = tempfile::tempdir().unwrap();
    let file = room(dir.path(), "60K");
    let f = file.to_str().unwrap();
    let screen = Screen::start();
    let (w, h) = (W.to_string(), H.to_string());
    let (mut window, mut at) = screen.open(
        Command::new(env!("CARGO_BIN_EXE_holodeck"))
            .args(["pict", f, "--window", "-i", "--stride", "2", "-x", &w, "-y", &h]),
    );
    window.say("where");
    let start = window.wait_line("the first view", &mut at, view_of);
    let id = screen.window("^holodeck: ");

    // Hold the left button over the middle of the window until the eye has
    // moved (a loaded machine may take a while to draw a step; what the
    // motion did is read back from the window, whatever the number of steps).
    screen.tool("xdotool", &["mousemove", "--window", &id, "160", "120"]);
    screen.tool("xdotool", &["mousedown", "1"]);
    common::process::wait_for("a step of the motion", common::process::DEADLINE, || {
        window.say("where");
        let now = window.wait_line("the view while moving", &mut at, view_of);
        (now.position != start.position).then_some(())
    });
    screen.tool("xdotool", &["mouseup", "1"]);
    let (steps, target) = window.wait_line("the end of the motion", &mut at, moved);
    let target = target.expect("a motion of at least one step has a point");
    window.say("where");
    let end = window.wait_line("the view after the motion", &mut at, view_of);

    // Each step left 90% of the distance to the point, along the line to it:
    // the direction is unchanged and the point stays under the cursor.
    assert!(steps >= 1, "the eye moved without a step");
    let (d0, d1) = (target - start.position, target - end.position);
    let left = d1.length() / d0.length();
    assert!(
        (left - 0.9f64.powi(steps as i32)).abs() < 1e-9,
        "{steps} steps left {left} of the distance"
    );
    assert!(
        d0.normalize().dot(d1.normalize()) > 1.0 - 1e-12,
        "the eye left the line to the point"
    );
    assert!(end.direction.distance(start.direction) < 1e-12);
    let (x, y, _) = start.project(target).expect("the point is in view");
    let (col, row) = (x * f64::from(W), (1.0 - y) * f64::from(H));
    assert!(
        (col - 160.5).abs() <= 5.0 && (row - 120.5).abs() <= 5.0,
        "the point is at pixel ({col}, {row}), not under the cursor"
    );

    // Everything again from the file, tone mapped from what is on screen:
    // then the window shows what `holodeck pict` draws for the same view.
    window.say("refresh");
    window.say("tone");
    window.say("sync");
    window.wait_line("the redrawn frame", &mut at, |l| (l == "sync").then_some(()));
    let shown = screen.capture(&id);
    assert_eq!((shown.width, shown.height), (W as usize, H as usize));
    let error = headless_error(&file, &end, "quadtree", &shown);
    assert!(
        error < 0.02,
        "the window differs from the headless picture: relative RMSE {error}"
    );
    // And it is a picture, not a blank window. How much of it the file's
    // 60K rays light depends on where the motion ended (from 42% to 96% of
    // the pixels in runs of 1 to 136 steps), so the bound only tells a
    // picture from a blank.
    let lit = shown.pixels.iter().filter(|p| p.max_element() > 0.05).count();
    assert!(
        lit > shown.pixels.len() / 5,
        "only {lit} pixels lit after {steps} steps"
    );

    // A ctrl+shift drag marks a focus rectangle; the `f` key frames it: the
    // rectangle's center becomes the view's center, and the field narrows.
    // Keys go where the input focus is (there is no window manager to give it).
    screen.tool("xdotool", &["windowfocus", "--sync", &id]);
    screen.tool("xdotool", &["mousemove", "--window", &id, "200", "60"]);
    screen.tool("xdotool", &["keydown", "ctrl+shift", "mousedown", "1"]);
    screen.tool("xdotool", &["mousemove", "--window", &id, "280", "140"]);
    screen.tool("xdotool", &["mouseup", "1", "keyup", "ctrl+shift"]);
    screen.tool("xdotool", &["key", "f"]);
    // `v` prints the view, as `where` does.
    screen.tool("xdotool", &["key", "v"]);
    let framed = window.wait_line("the framed view", &mut at, view_of);
    let center = (
        (200.5 + 280.5) / 2.0 / f64::from(W),
        1.0 - (60.5 + 140.5) / 2.0 / f64::from(H),
    );
    let (_, toward) = end.ray(center.0, center.1).unwrap();
    assert!(
        framed.direction.distance(toward) < 1e-9,
        "framed {:?}, the rectangle's center is along {toward:?}",
        framed.direction
    );
    assert!(framed.horizontal < end.horizontal / 2.0, "{}", framed.horizontal);
    assert_eq!(framed.position, end.position);

    window.say("quit");
    assert!(window.wait().success(), "{}", window.text());
}

#[test]
fn every_driver_draws_into_the_window_what_it_draws_headless() {
    let dir = tempfile::tempdir().unwrap();
    let file = room(dir.path(), "30K");
    let f = file.to_str().unwrap();
    let screen = Screen::start();
    let (w, h) = (W.to_string(), H.to_string());
    for driver in ["splat", "voronoi", "mesh"] {
        let mut args = vec![
            "pict", f, "--window", "-i", "--stride", "2", "-x", &w, "-y", &h, "--driver", driver,
        ];
        if driver == "voronoi" {
            args.extend(["--geometry", "builtin:room"]);
        }
        let (mut window, mut at) = screen.open(Command::new(env!("CARGO_BIN_EXE_holodeck")).args(&args));
        window.say("where");
        let view = window.wait_line("the view", &mut at, view_of);
        window.say("tone");
        window.say("sync");
        window.wait_line("the frame", &mut at, |l| (l == "sync").then_some(()));
        let id = screen.window(&format!("^holodeck: .*\\({driver}\\)"));
        let shown = screen.capture(&id);
        let error = headless_error(&file, &view, driver, &shown);
        assert!(
            error < 0.02,
            "{driver}: the window differs from the headless picture: relative RMSE {error}"
        );
        window.say("quit");
        assert!(window.wait().success(), "{driver}: {}", window.text());
    }
}
