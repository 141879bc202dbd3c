//! Writing a command's output file: never over one of its inputs, and
//! whole or not at all (a temporary name, then a rename), so a full disk or
//! a killed command leaves no truncated file behind and fails the command.

use std::io::Write;
use std::path::Path;

use anyhow::{bail, Context, Result};

/// Whether `a` and `b` name the same file (the same device and inode).
fn same_file(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
        _ => false,
    }
}

/// Writes `bytes` to `path`, refusing when `path` is one of `inputs`.
pub fn write(path: &Path, bytes: &[u8], inputs: &[&Path]) -> Result<()> {
    if let Some(input) = inputs.iter().find(|i| same_file(path, i)) {
        bail!(
            "{} is the input {}: writing it would destroy it; give another output",
            path.display(),
            input.display()
        );
    }
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".{}.tmp", std::process::id()));
    let tmp = path.with_file_name(name);
    let written = (|| -> std::io::Result<()> {
        let _ = std::fs::remove_file(&tmp);
        let mut f = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(e).with_context(|| format!("writing {}", path.display()));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_input_is_never_overwritten_and_a_failed_write_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("room.hdk");
        std::fs::write(&input, "holodeck").unwrap();
        let err = write(&input, b"obj", &[&input]).unwrap_err();
        assert!(err.to_string().contains("would destroy it"), "{err}");
        // The same file by another name.
        let other = dir.path().join(".").join("room.hdk");
        assert!(write(&other, b"obj", &[&input]).is_err());
        assert_eq!(std::fs::read_to_string(&input).unwrap(), "holodeck");
        let out = dir.path().join("grid.obj");
        write(&out, b"v 0 0 0\n", &[&input]).unwrap();
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "v 0 0 0\n");
        // A folder that does not exist: an error naming the file, nothing left.
        let missing = dir.path().join("no/such/grid.obj");
        let err = write(&missing, b"x", &[]).unwrap_err();
        assert!(format!("{err:#}").contains("grid.obj"), "{err:#}");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 2, "no temporary file left: {names:?}");
    }
}
