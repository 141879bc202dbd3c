//! The walkthrough's commands: typed as single keys (Radiance rholo's
//! letters, in the window and in the web page) or given as text lines (on
//! standard input for scripts and tests, or the web page's command box),
//! both parsed into one [`Command`].

use std::path::PathBuf;

use holodeck_protocol::wire::Control;

/// One command.
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// View options applied to the current view (`-vp 1 2 3 -vd 1 0 0`,
    /// or a Radiance `VIEW=`/`rvu` line).
    View(String),
    /// Back to the view before the last change.
    Last,
    /// Print the current view as a Radiance view line.
    Where,
    /// Frame the focus rectangle (or this one, in image coordinates: left,
    /// bottom, right, top, each 0..1) as the next view.
    Frame(Option<[f64; 4]>),
    /// Stop the samplers (server-wide; a writer's or admin's right).
    Pause,
    /// Let them go on.
    Resume,
    /// Draw again from what the display holds.
    Redraw,
    /// Forget what the display holds and have the server send it all again.
    Refresh,
    /// Disconnect every sampler (an admin's right).
    Kill,
    /// Let samplers in again and reschedule (an admin's right).
    Restart,
    /// Delete every ray in the holodeck (an admin's right).
    Clobber,
    /// Close this display.
    Quit,
    /// Keep the eye's height while moving (true) or not.
    HeadFixed(bool),
    /// Recompute the tone mapping from what is on screen now.
    Tone,
    /// Write what the window shows (without the status line) to a PNG.
    Save(PathBuf),
    /// Print `sync` once every earlier command is done (for scripts).
    Sync,
    /// Draw this many frames back to back and print their times.
    Bench(u32),
}

/// A text command that does not parse.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CommandError {
    /// Not a command.
    #[error("unknown command {0:?} (commands: view options, last, where, frame, pause, resume, redraw, refresh, kill, restart, clobber, quit, head fix|release, tone, save FILE, sync, bench N)")]
    Unknown(String),
    /// A command with wrong arguments.
    #[error("{command}: {why}")]
    Arguments {
        /// The command.
        command: String,
        /// What is wrong.
        why: String,
    },
}

/// Parses one line; `None` for a blank line or a `#` comment.
pub fn parse(line: &str) -> Result<Option<Command>, CommandError> {
    let line = line.split('#').next().unwrap_or("").trim();
    if line.is_empty() {
        return Ok(None);
    }
    let mut words = line.split_whitespace();
    let first = words.next().unwrap_or("");
    let rest: Vec<&str> = words.collect();
    let bad = |why: &str| CommandError::Arguments {
        command: first.to_string(),
        why: why.to_string(),
    };
    let none = |c: Command| {
        if rest.is_empty() {
            Ok(Some(c))
        } else {
            Err(bad("takes no arguments"))
        }
    };
    if first.starts_with('-') || first.eq_ignore_ascii_case("VIEW=") || first == "rvu" || first == "rview" {
        let at = if first.starts_with('-') { 0 } else { first.len() };
        return Ok(Some(Command::View(line[at..].trim().to_string())));
    }
    match first {
        "last" => none(Command::Last),
        "where" | "view" => none(Command::Where),
        "frame" => match rest.len() {
            0 => Ok(Some(Command::Frame(None))),
            4 => {
                let mut r = [0.0; 4];
                for (slot, w) in r.iter_mut().zip(&rest) {
                    *slot = w
                        .parse::<f64>()
                        .ok()
                        .filter(|v| (0.0..=1.0).contains(v))
                        .ok_or_else(|| bad("needs four numbers from 0 to 1: left bottom right top"))?;
                }
                Ok(Some(Command::Frame(Some(r))))
            }
            _ => Err(bad("needs no numbers or four: left bottom right top")),
        },
        "pause" => none(Command::Pause),
        "resume" => none(Command::Resume),
        "redraw" => none(Command::Redraw),
        "refresh" => none(Command::Refresh),
        "kill" => none(Command::Kill),
        "restart" => none(Command::Restart),
        "clobber" => none(Command::Clobber),
        "quit" | "exit" => none(Command::Quit),
        "head" | "height" => match rest.as_slice() {
            ["fix"] => Ok(Some(Command::HeadFixed(true))),
            ["release"] => Ok(Some(Command::HeadFixed(false))),
            _ => Err(bad("use `head fix` or `head release`")),
        },
        "tone" => none(Command::Tone),
        "save" => match rest.as_slice() {
            [path] => Ok(Some(Command::Save(PathBuf::from(path)))),
            _ => Err(bad("needs one file name")),
        },
        "sync" => none(Command::Sync),
        "bench" => match rest.as_slice() {
            [n] => n
                .parse::<u32>()
                .ok()
                .filter(|n| (1..=10_000).contains(n))
                .map(|n| Some(Command::Bench(n)))
                .ok_or_else(|| bad("needs a number of frames from 1 to 10000")),
            _ => Err(bad("needs a number of frames")),
        },
        _ => Err(CommandError::Unknown(first.to_string())),
    }
}

/// The command a key stands for (rholo's letters), if any: `key` is the
/// key's name as the web's `KeyboardEvent.key` gives it ("Enter",
/// "Escape", or the character typed, "K" with shift), `ctrl` whether the
/// control key is held.
pub fn key(key: &str, ctrl: bool) -> Option<Command> {
    match key {
        "Enter" => Some(Command::Resume),
        "Escape" => Some(Command::Quit),
        c if ctrl => match c.to_ascii_lowercase().as_str() {
            "r" => Some(Command::Redraw),
            "l" => Some(Command::Refresh),
            _ => None,
        },
        "l" => Some(Command::Last),
        "v" => Some(Command::Where),
        "f" => Some(Command::Frame(None)),
        "p" => Some(Command::Pause),
        "K" => Some(Command::Kill),
        "R" => Some(Command::Restart),
        "C" => Some(Command::Clobber),
        "q" => Some(Command::Quit),
        "h" => Some(Command::HeadFixed(true)),
        "H" => Some(Command::HeadFixed(false)),
        "t" => Some(Command::Tone),
        _ => None,
    }
}

/// A control command as the walkthrough's commands name it ("kill" for
/// [`Control::KillSamplers`]).
pub fn command_name(c: &Control) -> &'static str {
    match c {
        Control::Pause => "pause",
        Control::Resume => "resume",
        Control::KillSamplers => "kill",
        Control::Restart => "restart",
        Control::Clobber => "clobber",
        Control::Quit => "quit",
        Control::Adopt { .. } => "adopt",
    }
}

/// The keys, for `--help` and the window's title.
pub const KEYS: &str = "\
left button: forward toward the point under the cursor; right: back away; middle: turn toward the cursor;
shift+left/right: orbit left/right around the point; shift+middle: orbit over it; ctrl+shift drag: focus rectangle;
l last view, v print view, f frame focus, p pause, Enter resume, ctrl+R redraw, ctrl+L refresh from server,
K kill samplers, R restart, C clobber, h/H fix/release head height, t re-tone-map, q quit";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_parse_into_commands_and_bad_ones_say_why() {
        assert_eq!(parse("  # nothing").unwrap(), None);
        assert_eq!(parse("").unwrap(), None);
        assert_eq!(
            parse("-vp 1 2 3 -vd 1 0 0").unwrap(),
            Some(Command::View("-vp 1 2 3 -vd 1 0 0".into()))
        );
        assert_eq!(
            parse("VIEW= -vtv -vp 0 0 1").unwrap(),
            Some(Command::View("-vtv -vp 0 0 1".into()))
        );
        assert_eq!(parse("where").unwrap(), Some(Command::Where));
        assert_eq!(parse("last").unwrap(), Some(Command::Last));
        assert_eq!(parse("pause").unwrap(), Some(Command::Pause));
        assert_eq!(
            parse("frame 0.1 0.2 0.3 0.4").unwrap(),
            Some(Command::Frame(Some([0.1, 0.2, 0.3, 0.4])))
        );
        assert_eq!(parse("head fix").unwrap(), Some(Command::HeadFixed(true)));
        assert_eq!(parse("save a.png").unwrap(), Some(Command::Save("a.png".into())));
        assert_eq!(parse("clobber # all of it").unwrap(), Some(Command::Clobber));
        assert!(matches!(parse("fly"), Err(CommandError::Unknown(w)) if w == "fly"));
        let e = parse("frame 0.1 2 0.3 0.4").unwrap_err();
        assert!(e.to_string().contains("from 0 to 1"), "{e}");
        assert!(parse("quit now").is_err());
        assert!(parse("save").is_err());
        assert_eq!(parse("bench 20").unwrap(), Some(Command::Bench(20)));
        assert!(parse("bench 0").is_err());
    }

    #[test]
    fn keys_are_rholos_letters() {
        assert_eq!(key("K", false), Some(Command::Kill));
        assert_eq!(key("q", false), Some(Command::Quit));
        assert_eq!(key("Enter", false), Some(Command::Resume));
        assert_eq!(key("r", true), Some(Command::Redraw));
        assert_eq!(key("R", true), Some(Command::Redraw));
        assert_eq!(key("x", false), None);
        assert_eq!(key("Shift", false), None);
    }
}
