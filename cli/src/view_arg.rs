//! A view given on the command line, as Radiance programs take it: options
//! (`-vtv -vp … -vo 1 -va 20`), optionally led by `rview`/`rpict`/`VIEW=`,
//! and `-vf FILE` reading the view from a file (a view file as rview's
//! `view` command writes, or a Radiance picture whose header has a `VIEW=`
//! line); options after `-vf` override the file's, as in Radiance.

use std::io::Read;
use std::path::Path;

use anyhow::{bail, Context, Result};
use holodeck_protocol::View;

/// The most of a view file (or a picture's header) read: views sit at the top.
const MOST: u64 = 1 << 20;

/// Parses a view given as `spec`.
pub fn parse(spec: &str) -> Result<View> {
    let mut view = View::default();
    let mut pending: Vec<&str> = Vec::new();
    let mut words = spec.split_whitespace();
    while let Some(word) = words.next() {
        if word != "-vf" {
            pending.push(word);
            continue;
        }
        let Some(file) = words.next() else {
            bail!("-vf needs a file name");
        };
        view = view.with(&pending.join(" "))?;
        pending.clear();
        view = from_file(view, Path::new(file)).with_context(|| format!("-vf {file}"))?;
    }
    Ok(view.with(&pending.join(" "))?)
}

/// `view` with the view lines of `path` applied in order.
fn from_file(mut view: View, path: &Path) -> Result<View> {
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .with_context(|| format!("opening {}", path.display()))?
        .take(MOST)
        .read_to_end(&mut bytes)
        .with_context(|| format!("reading {}", path.display()))?;
    // A picture's header ends at its first empty line; binary pixels follow.
    let text = String::from_utf8_lossy(&bytes);
    let mut found = false;
    for line in text.lines() {
        let line = line.trim();
        if line.is_empty() && found {
            break;
        }
        let viewish = line.starts_with("-v")
            || ["rview ", "rpict ", "rvu ", "rholo ", "rhpict ", "VIEW="]
                .iter()
                .any(|p| line.starts_with(p));
        if viewish {
            view = view.with(line)?;
            found = true;
        }
    }
    if !found {
        bail!("{} has no view line (rview …, VIEW= …, or -v options)", path.display());
    }
    Ok(view)
}

/// The views of a view file, one Radiance view per line (at least one).
pub fn read_views(path: &std::path::Path) -> Result<Vec<View>> {
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let views = View::parse_list(&text).map_err(|(line, e)| anyhow::anyhow!("{}:{line}: {e}", path.display()))?;
    if views.is_empty() {
        bail!("{} holds no views", path.display());
    }
    Ok(views)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn view_files_and_picture_headers_give_views_that_later_options_override() {
        let dir = tempfile::tempdir().unwrap();
        let vf = dir.path().join("v.vf");
        std::fs::write(
            &vf,
            "rview -vtv -vp 1 2 3 -vd 0 1 0 -vu 0 0 1 -vh 50 -vv 40 -vo 0 -va 0 -vs 0 -vl 0\n",
        )
        .unwrap();
        let v = parse(&format!("-vf {} -vh 70", vf.display())).unwrap();
        assert_eq!(
            (v.position.x, v.position.z, v.horizontal, v.vertical),
            (1.0, 3.0, 70.0, 40.0)
        );
        // A picture header: VIEW= lines, then a blank line and pixels.
        let pic = dir.path().join("p.hdr");
        let mut bytes = b"#?RADIANCE\nVIEW= -vtv -vp 5 5 1 -vd 1 0 0 -vu 0 0 1 -vh 30 -vv 20\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 1\n".to_vec();
        bytes.extend_from_slice(&[0xff, 0x00, 0x80, 0x7f]);
        std::fs::write(&pic, bytes).unwrap();
        let v = parse(&format!("-vf {}", pic.display())).unwrap();
        assert_eq!((v.position.x, v.horizontal), (5.0, 30.0));
        let err = parse(&format!("-vf {}", dir.path().join("missing").display())).unwrap_err();
        assert!(format!("{err:#}").contains("missing"), "{err:#}");
        std::fs::write(dir.path().join("empty"), "nothing here\n").unwrap();
        let err = parse(&format!("-vf {}", dir.path().join("empty").display())).unwrap_err();
        assert!(format!("{err:#}").contains("no view line"), "{err:#}");
        assert!(parse("-vf").is_err());
    }
}
