//! A virtual X screen for window tests: Xvfb, real input events from
//! xdotool and the window's pixels read back with xwd (all three from apt:
//! xvfb, xdotool, x11-apps; `.ci/run` installs them).

use std::process::Command;

use holodeck_protocol::Picture;

use super::process::Proc;

/// A running Xvfb and its display name (`:N`); it ends with the guard.
pub struct Screen {
    _xvfb: Proc,
    /// The DISPLAY to give windows.
    pub display: String,
}

impl Screen {
    /// Starts Xvfb on a free display number.
    pub fn start() -> Screen {
        let found = Command::new("Xvfb").arg("-help").output();
        assert!(
            found.is_ok(),
            "window tests need Xvfb, xdotool and xwd: apt-get install xvfb xdotool x11-apps"
        );
        // -displayfd: Xvfb picks a free number and prints it when it is ready.
        let xvfb = Proc::start(Command::new("Xvfb").args([
            "-displayfd",
            "1",
            "-screen",
            "0",
            "800x600x24",
            "-nolisten",
            "tcp",
        ]));
        let n: u32 = xvfb.wait_line("Xvfb's display number", &mut 0, |l| l.trim().parse().ok());
        Screen {
            _xvfb: xvfb,
            display: format!(":{n}"),
        }
    }

    /// Starts a window command (`holodeck view -i`, `holodeck pict
    /// --window -i`) on this screen and waits until it is ready; returns it
    /// and where its output goes on from.
    pub fn open(&self, command: &mut Command) -> (Proc, usize) {
        let window = Proc::start(command.env("DISPLAY", &self.display).env("NO_COLOR", "1"));
        let mut at = 0;
        window.wait_line("the window", &mut at, |l| l.starts_with("ready:").then_some(()));
        (window, at)
    }

    /// Runs an X tool on this screen; its standard output.
    pub fn tool(&self, program: &str, args: &[&str]) -> Vec<u8> {
        let o = super::process::run(Command::new(program).args(args).env("DISPLAY", &self.display));
        assert!(
            o.status.success(),
            "{program} {args:?}: {}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        o.stdout
    }

    /// The id of the first window whose name matches `pattern`, waiting for it.
    pub fn window(&self, pattern: &str) -> String {
        let out = self.tool("xdotool", &["search", "--sync", "--name", pattern]);
        String::from_utf8_lossy(&out)
            .lines()
            .next()
            .unwrap_or_else(|| panic!("no window named {pattern:?}"))
            .trim()
            .to_string()
    }

    /// What window `id` shows, as a linear picture (decoded from sRGB).
    pub fn capture(&self, id: &str) -> Picture {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("window.xwd");
        self.tool("xwd", &["-silent", "-id", id, "-out", path.to_str().unwrap()]);
        parse_xwd(&std::fs::read(&path).unwrap())
    }
}

/// Decodes an XWD dump (ZPixmap, 24 or 32 bits per pixel, true color).
pub fn parse_xwd(b: &[u8]) -> Picture {
    let field = |i: usize| u32::from_be_bytes(b[i * 4..i * 4 + 4].try_into().unwrap());
    let (header, format, width, height) = (field(0) as usize, field(2), field(4), field(5));
    let (lsb_first, bpp, line) = (field(7) == 0, field(11), field(12) as usize);
    let masks = [field(14), field(15), field(16)];
    let colors = field(19) as usize;
    assert_eq!(format, 2, "only ZPixmap dumps");
    assert!(bpp == 32 || bpp == 24, "{bpp} bits per pixel");
    let data = &b[header + colors * 12..];
    let mut p = Picture {
        width: width as usize,
        height: height as usize,
        pixels: vec![glam::Vec3::ZERO; width as usize * height as usize],
    };
    for y in 0..height as usize {
        for x in 0..width as usize {
            let at = y * line + x * (bpp as usize / 8);
            let mut raw = [0u8; 4];
            raw[..bpp as usize / 8].copy_from_slice(&data[at..at + bpp as usize / 8]);
            let v = if lsb_first {
                u32::from_le_bytes(raw)
            } else {
                u32::from_be_bytes(raw) >> (32 - bpp)
            };
            let channel = |m: u32| {
                let byte = (v & m) >> m.trailing_zeros();
                holodeck_display::tonemap::decode_srgb(byte as u8)
            };
            p.pixels[y * width as usize + x] = glam::Vec3::new(channel(masks[0]), channel(masks[1]), channel(masks[2]));
        }
    }
    p
}

/// The view in a line the window prints for `where` (or the `v` key).
pub fn view_of(line: &str) -> Option<holodeck_protocol::View> {
    line.strip_prefix("VIEW= ")
        .map(|v| holodeck_protocol::View::parse(v).expect("the window prints views it can read back"))
}
