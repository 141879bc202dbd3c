//! A walkthrough window on a live server, driven by commands on its
//! standard input: view lines move it, `where` prints the view, `last` goes
//! back, and `pause`/`resume` reach the server.

use holodeck_protocol::wire::Control;

use crate::common::screen::{view_of, Screen};
use crate::harness::{bin, carried_out, quit, rays_at_close, small_room, start_server};

#[test]
fn standard_input_commands_drive_a_window_on_a_server() {
    let dir = tempfile::tempdir().unwrap();
    let file = small_room(dir.path());
    let (server, addr) = start_server(file.to_str().unwrap(), "127.0.0.1:0", "secret");
    let screen = Screen::start();
    let window_of = |token: &str| {
        screen.open(bin().args([
            "view",
            "--connect",
            &addr,
            "--token",
            token,
            "-i",
            "-x",
            "160",
            "-y",
            "120",
        ]))
    };
    let (mut window, mut at) = window_of("secret");
    window.say("where");
    let first = window.wait_line("the first view", &mut at, view_of);

    // A view line changes what it gives and keeps the rest.
    window.say("-vp 1.2 2.5 1.4 -vh 60");
    window.say("where");
    let second = window.wait_line("the second view", &mut at, view_of);
    assert_eq!(second.position.to_array(), [1.2, 2.5, 1.4]);
    assert_eq!(second.horizontal, 60.0);
    assert_eq!((second.direction, second.up), (first.direction, first.up));

    // `last` goes back, and again to where it was.
    window.say("last");
    window.say("where");
    let back = window.wait_line("the view after last", &mut at, view_of);
    assert_eq!(back.position, first.position);
    assert_eq!(back.horizontal, first.horizontal);
    window.say("last");
    window.say("where");
    let again = window.wait_line("the view after last again", &mut at, view_of);
    assert_eq!(again.position, second.position);

    // A bad line is answered, and the window goes on.
    window.say("fly to the moon");
    window.wait_line("the answer to a bad command", &mut at, |l| {
        l.starts_with("error: unknown command").then_some(())
    });

    // Pause and resume are carried out by the server, which says so.
    let mut log = 0;
    window.say("pause");
    carried_out(&server, &mut log, Control::Pause);
    window.wait_line("the answer to pause", &mut at, |l| (l == "pause done").then_some(()));
    window.say("resume");
    carried_out(&server, &mut log, Control::Resume);
    window.wait_line("the answer to resume", &mut at, |l| (l == "resume done").then_some(()));

    // A window on a viewer's token may look but not clobber: the server
    // refuses, the window says so and goes on, and the rays stay.
    let viewer_token = std::fs::read_to_string(format!("{}.viewer.token", file.display())).unwrap();
    let (mut viewer, mut vat) = window_of(viewer_token.lines().next().unwrap().trim());
    for command in ["clobber", "kill", "pause"] {
        viewer.say(command);
        viewer.wait_line("the refusal", &mut vat, |l| {
            l.starts_with(&format!("{command} was refused")).then_some(())
        });
    }
    viewer.say("where");
    viewer.wait_line("a view: the window goes on", &mut vat, view_of);
    viewer.say("quit");
    assert!(viewer.wait().success(), "{}", viewer.text());

    // The server quitting ends the session: the window closes by itself,
    // says why, and exits as a session's end, not a failure.
    quit(&addr, "secret");
    assert!(window.wait().success(), "{}", window.text());
    assert!(
        window.text().contains("the server ended the session"),
        "{}",
        window.text()
    );
    assert!(rays_at_close(&server) > 0, "the viewer's clobber was refused");
}
