//! Surveying a file in format version 1 (see [`format::v1`]): its newest
//! commit whose root and directories verify, with the same report of damage
//! as for the current format. Such a file is read, never written: a writable
//! open refuses it and `holodeck optimize` converts it.

use std::fs::File;
use std::path::Path;

use super::error::{CommitDamage, Result, StorageError};
use super::format::{self, v1, BeamEntry, Extent, FormatError};
use super::found::{read_part, Survey};
use crate::settings::Settings;

/// A format-1 commit read in full: its directories and every extent it uses.
struct Commit {
    dirs: Vec<Vec<BeamEntry>>,
    used: Vec<Extent>,
}

fn load(
    file: &File,
    path: &Path,
    slot: &v1::Slot,
    settings: &Settings,
    data_start: u64,
    file_len: u64,
) -> Result<std::result::Result<(Commit, u64), FormatError>> {
    let root = match read_part(file, path, slot.root.offset, slot.root.len, file_len, "root")? {
        Ok(b) if crc32c::crc32c(&b) == slot.root_crc => b,
        Ok(b) => {
            return Ok(Err(FormatError::Checksum {
                what: format!("root of commit {}", slot.generation),
                start: slot.root.offset,
                end: slot.root.end(),
                stored: slot.root_crc,
                computed: crc32c::crc32c(&b),
            }))
        }
        Err(e) => return Ok(Err(e)),
    };
    let refs = match v1::decode_root(&root, slot.root.offset, slot.generation, settings.sections.len()) {
        Ok(r) => r,
        Err(e) => return Ok(Err(e)),
    };
    let mut commit = Commit {
        dirs: Vec::new(),
        used: vec![slot.root],
    };
    let mut claimed = 0;
    for (s, (r, section)) in refs.iter().zip(&settings.sections).enumerate() {
        claimed += r.rays;
        let what = format!("directory of section {s}");
        let dir = read_part(file, path, r.block.offset, r.block.len, file_len, &what)?
            .and_then(|b| v1::decode_directory(&b, r.block.offset, s as u32, section.beam_count(), data_start));
        let dir = match dir {
            Ok(d) => d,
            Err(e) => return Ok(Err(e)),
        };
        if let Some((b, e)) = dir.iter().enumerate().find(|(_, e)| e.extent().end() > file_len) {
            return Ok(Err(FormatError::Truncated {
                what: format!("beam {b} of section {s}"),
                start: e.offset,
                end: e.extent().end(),
                have: file_len.saturating_sub(e.offset),
            }));
        }
        commit.used.push(r.block);
        commit.used.extend(dir.iter().map(|e| e.extent()));
        commit.dirs.push(dir);
    }
    Ok(Ok((commit, claimed)))
}

/// Surveys a format-1 file whose settings text is `text_len` bytes.
pub(crate) fn survey_v1(file: &File, path: &Path, file_len: u64, text_len: u32) -> Result<Survey> {
    let text = read_part(
        file,
        path,
        v1::TEXT_OFFSET,
        u64::from(text_len) + 4,
        file_len,
        "settings text",
    )?
    .and_then(|b| format::decode_text(&b, v1::TEXT_OFFSET))
    .map_err(|source| StorageError::Format {
        path: path.to_path_buf(),
        source,
    })?;
    let settings = Settings::from_text(&text).map_err(|source| StorageError::Settings {
        path: path.to_path_buf(),
        source,
    })?;
    let data_start = v1::data_start(text_len);
    let mut slots = Vec::new();
    let mut problems = Vec::new();
    for (side, &at) in v1::SLOT_OFFSETS.iter().enumerate() {
        match read_part(file, path, at, 64, file_len, "commit slot")?.and_then(|b| v1::decode_slot(&b, at)) {
            Ok(Some(s)) => slots.push((side, s)),
            Ok(None) => {}
            Err(e) => problems.push(e.to_string()),
        }
    }
    slots.sort_by_key(|(_, s)| std::cmp::Reverse(s.generation));
    let newest = slots.first().map(|(_, s)| s.generation).unwrap_or(0);
    let mut newest_rays = None;
    for (side, slot) in &slots {
        match load(file, path, slot, &settings, data_start, file_len)? {
            Ok((commit, claimed)) => {
                let readable = commit.dirs.iter().flatten().map(|e| u64::from(e.count)).sum();
                if slot.generation == newest {
                    newest_rays = Some(claimed);
                }
                // A format-1 file cannot tell a torn commit from damage: any
                // newer commit passed over is reported as damage.
                let damage = (slot.generation != newest).then(|| CommitDamage {
                    generation: newest,
                    problems: problems.clone(),
                    claimed_rays: newest_rays,
                    readable_rays: readable,
                    fallback: Some(slot.generation),
                });
                return Ok(Survey {
                    settings,
                    text_len,
                    version: 1,
                    data_start,
                    file_len,
                    repaired: Vec::new(),
                    torn: Vec::new(),
                    bad_header: [false; 2],
                    damage,
                    generation: slot.generation,
                    side: *side,
                    dirs: commit.dirs,
                    clean: None,
                    metadata: commit.used,
                    weak_chunks: Vec::new(),
                    uneven_slots: [false; 2],
                    legacy: Some(1),
                });
            }
            Err(e) => problems.push(format!("commit {}: {e}", slot.generation)),
        }
    }
    if slots.is_empty() {
        problems.push("neither commit slot holds a commit".into());
    }
    Err(StorageError::NoValidCommit {
        path: path.to_path_buf(),
        problems: problems.join("\n"),
    })
}
