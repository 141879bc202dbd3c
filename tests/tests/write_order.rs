//! Power loss, replayed: every write, sync and length change the engine
//! makes to a file while rays are appended, committed and the file closed is
//! recorded (`storage::faults::record`). From the file as it was before and
//! that record, every state a power cut could leave on disk is rebuilt: all
//! that a completed sync made durable, plus, of the writes since (which the
//! disk may persist in any order, or not at all), every prefix, every single
//! write alone, every set with one write left out, each write torn in half
//! after the ones before it, and all of them torn (as ALICE and CrashMonkey
//! explore), and the state before any of them with each commit slot copy
//! damaged in turn; no cut may tear more than one slot copy. Each state must open at a complete commit that
//! is no older than the last one whose commit returned before the cut, and
//! hold exactly that commit's rays, every one readable.

use std::collections::HashMap;
use std::path::Path;

use holodeck_file::settings::Settings;
use holodeck_file::storage::faults::{self, Event};
use holodeck_file::storage::format;
use holodeck_file::storage::{HoloFile, OpenOptions};
use holodeck_file::testing::{all_keys, metadata_map, pattern_rays};
use holodeck_protocol::{BeamKey, RayRecord, Section, SectionKind};

type Rays = HashMap<BeamKey, Vec<RayRecord>>;

/// `e` half done: a write cut after half its bytes (a sync is not a write).
fn half(e: &Event) -> Event {
    match e {
        Event::Write { offset, bytes } => Event::Write {
            offset: *offset,
            bytes: bytes[..bytes.len() / 2].to_vec(),
        },
        other => other.clone(),
    }
}

/// `image` with `events` applied in order.
fn apply(image: &mut Vec<u8>, events: &[&Event]) {
    for e in events {
        match e {
            Event::Write { offset, bytes } => {
                let (at, end) = (*offset as usize, *offset as usize + bytes.len());
                if image.len() < end {
                    image.resize(end, 0);
                }
                image[at..end].copy_from_slice(bytes);
            }
            Event::SetLen(len) => image.resize(*len as usize, 0),
            Event::Sync => {}
        }
    }
}

/// Every ray of the file at `path`, or why it cannot be read.
fn contents(path: &Path) -> Result<Rays, String> {
    let mut f = HoloFile::open(path, &OpenOptions::read_only()).map_err(|e| e.to_string())?;
    let keys = all_keys(&f);
    let mut rays = HashMap::new();
    let report = f
        .read_beams(&keys, |k, r| {
            if !r.is_empty() {
                rays.insert(k, r.to_vec());
            }
        })
        .map_err(|e| e.to_string())?;
    if !report.corrupt.is_empty() {
        return Err(format!("damaged beams {:?}", report.corrupt));
    }
    Ok(rays)
}

#[test]
fn every_state_a_power_cut_can_leave_opens_at_a_durable_commit_with_all_its_rays() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("room.hdk");
    let section = Section::new(
        [0.0; 3],
        [[4.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 2.5]],
        [4, 3, 2],
        SectionKind::Interior,
    )
    .unwrap();
    let settings = Settings {
        sections: vec![section],
        ..Settings::default()
    };
    HoloFile::create(&path, &settings).unwrap();
    let before = std::fs::read(&path).unwrap();

    // Three commits (appends to new and to grown beams), then a close.
    faults::record(&path);
    let mut f = HoloFile::open(
        &path,
        &OpenOptions {
            flush_interval: None,
            ..OpenOptions::default()
        },
    )
    .unwrap();
    let beams = f.sections()[0].beam_count();
    let mut state: Rays = HashMap::new();
    // The rays of each commit, and the recorded events when it returned.
    let mut commits: Vec<(Rays, usize)> = vec![(HashMap::new(), 0)];
    for round in 0..3u64 {
        for i in 0..40u32 {
            let key = BeamKey::new(0, (i * 37 + round as u32 * 11) % beams);
            let rays = pattern_rays(key, round * 100 + u64::from(i), 1 + u64::from(i % 4));
            f.append(key, &rays).unwrap();
            state.entry(key).or_default().extend(rays);
        }
        f.flush().unwrap();
        commits.push((state.clone(), faults::recorded_len()));
    }
    f.close().unwrap();
    let events = faults::recorded();
    assert!(
        events.iter().filter(|e| **e == Event::Sync).count() >= 9,
        "three commits sync thrice each"
    );
    // The file as closed holds the last commit.
    assert_eq!(contents(&path).unwrap(), commits[3].0);
    // The commit slots (fixed places): each copy must be durable when its
    // commit returns, so a cut plus one damaged slot copy costs nothing.
    let slots: Vec<(usize, usize)> = metadata_map(&path)
        .iter()
        .filter(|m| m.what.starts_with("slot"))
        .map(|m| (m.extent.offset as usize, m.extent.len as usize))
        .collect();
    assert_eq!(slots.len(), 4, "two sides, two copies each");

    // Epochs: the events between syncs; a cut in epoch k leaves every event
    // before it on disk and any subset of its own writes.
    let mut start = 0;
    let mut states = 0u64;
    let crash = dir.path().join("crash.hdk");
    for (end, _) in events.iter().enumerate().filter(|(_, e)| **e == Event::Sync) {
        let durable: Vec<&Event> = events[..start].iter().collect();
        let epoch: Vec<&Event> = events[start..end].iter().collect();
        // Commits whose flush returned before the cut (at the end of this
        // epoch, before its sync completes) must have been made durable.
        let floor = commits.iter().rposition(|(_, at)| *at <= end).unwrap_or(0);
        let whole = |events: &[&Event]| -> Vec<Event> { events.iter().map(|e| (*e).clone()).collect() };
        let mut variants: Vec<Vec<Event>> = (0..=epoch.len()).map(|k| whole(&epoch[..k])).collect();
        for j in 0..epoch.len() {
            variants.push(vec![epoch[j].clone()]);
            let mut without = whole(&epoch[..j]);
            without.extend(whole(&epoch[j + 1..]));
            variants.push(without);
            // Torn: the writes before it whole, it half written.
            let mut torn = whole(&epoch[..j]);
            torn.push(half(epoch[j]));
            variants.push(torn);
        }
        // Every write of the epoch torn at once.
        variants.push(epoch.iter().map(|e| half(e)).collect());
        // The cut before any of the epoch's writes, with each slot copy damaged in turn.
        let damaged = slots.iter().map(|&(at, len)| {
            let mut image = before.clone();
            apply(&mut image, &durable);
            if image.len() >= at + len {
                image[at..at + len].fill(0);
            }
            (image, 0, true)
        });
        let images = variants.iter().map(|variant| {
            let mut image = before.clone();
            apply(&mut image, &durable);
            apply(&mut image, &variant.iter().collect::<Vec<_>>());
            (image, variant.len(), false)
        });
        for (image, variant, damage) in images.chain(damaged) {
            // STORAGE.md: "a crash can tear at most one slot copy".
            let torn = slots
                .iter()
                .filter(|&&(at, len)| {
                    image.len() >= at + len && format::decode_slot(&image[at..at + len], at as u64).is_err()
                })
                .count();
            assert!(
                damage || torn <= 1,
                "a cut in the epoch ending at event {end} tore {torn} slot copies"
            );
            std::fs::write(&crash, &image).unwrap();
            let got = contents(&crash).unwrap_or_else(|e| {
                panic!("a cut in the epoch ending at event {end} ({variant} of its writes) leaves a file that cannot be read: {e}")
            });
            let at = commits.iter().position(|(rays, _)| *rays == got);
            assert!(
                at.is_some_and(|c| c >= floor),
                "a cut in the epoch ending at event {end}: the file holds {:?} (commits {floor}.. were durable)",
                at.map_or_else(|| "rays of no commit".to_string(), |c| format!("commit {c}"))
            );
            states += 1;
        }
        start = end + 1;
    }
    println!("{} events, {states} crash states replayed", events.len());
    assert!(states > 50, "{states} states");
}
