//! Pictures from a holodeck file: the beams a view sees read from the
//! file, decoded on all cores and handed to a display driver, which draws
//! the frame; what `holodeck pict` and replay do, and Radiance's rhpict.

use std::cell::RefCell;
use std::collections::HashMap;
use std::time::{Duration, Instant};

use holodeck_display::denoise::{Denoised, Denoiser};
use holodeck_display::gaps;
use holodeck_display::geometry::Geometry;
use holodeck_display::request::{BeamRequest, RequestOptions};
use holodeck_display::tonemap::Histogram;
use holodeck_display::{make_driver, Driver, DriverSetup, DriverStats, EstimatorOptions, SampleDecoder, Viewport};
use holodeck_file::HoloFile;
use holodeck_protocol::{BeamKey, RayRecord};

use crate::Error;

/// Rays gathered before the driver takes them (a chunk ends with the beam
/// that reaches this). The store numbers new estimates in its batches'
/// order, and a frame samples its estimates by number to judge fireflies,
/// so the chunks are part of what makes a picture: changing them changes
/// pictures by rounding.
const CHUNK_RAYS: usize = 1 << 17;

/// Chunks handed to the driver together, so that it can merge one while it
/// projects the next (about 20 MB of records).
const GROUP_CHUNKS: usize = 16;

/// A display driver as chosen: its name, how pixels combine rays, the
/// geometry the Voronoi driver culls with, and the denoiser after it.
#[derive(Clone)]
pub struct DriverChoice {
    /// The driver's name.
    pub name: String,
    /// How pixels combine rays.
    pub options: EstimatorOptions,
    /// Simplified scene geometry, for the Voronoi driver.
    pub geometry: Option<std::sync::Arc<Geometry>>,
    /// What cleans its frames.
    pub denoise: Denoiser,
    /// Pixels that the view's beams leave without a ray (a sparse file)
    /// take the rays of the beams next to theirs, which pass near the eye;
    /// pixels with a ray are not changed. Off unless asked for, as in the
    /// window's replay (`WalkOptions::neighbours`), so that a picture and
    /// the window show the same.
    pub neighbours: bool,
    /// The scene, whose albedo guides the denoiser (OIDN takes an albedo
    /// beside the normals): each view's albedo traced from it, as
    /// [`crate::truth::scene_albedo`] does. None: the store's
    /// guide alone.
    pub scene: Option<std::sync::Arc<holodeck_sampler::Tracer>>,
}

impl std::fmt::Debug for DriverChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("DriverChoice")
            .field("name", &self.name)
            .field("options", &self.options)
            .field("geometry", &self.geometry.as_ref().map(|g| g.triangles.len()))
            .field("denoise", &self.denoise)
            .field("neighbours", &self.neighbours)
            .field("scene", &self.scene.is_some())
            .finish()
    }
}

impl DriverChoice {
    /// The driver `name` with `options` and no geometry.
    pub fn plain(name: &str, options: EstimatorOptions) -> DriverChoice {
        DriverChoice {
            name: name.to_string(),
            options,
            geometry: None,
            denoise: Denoiser::Off,
            neighbours: false,
            scene: None,
        }
    }

    /// Makes a fresh driver for `viewport`, its frames denoised as chosen.
    pub fn make(&self, viewport: Viewport) -> Result<Box<dyn Driver>, Error> {
        let driver = make_driver(
            &self.name,
            viewport,
            DriverSetup {
                options: self.options,
                geometry: self.geometry.as_deref(),
            },
        )?;
        Ok(match (self.denoise, &self.scene) {
            (Denoiser::Off, _) => driver,
            (d, None) => Box::new(Denoised::new(driver, d)),
            (d, Some(scene)) => {
                let scene = std::sync::Arc::clone(scene);
                let source = move |v: &Viewport| {
                    crate::truth::scene_albedo(&scene, &v.view, (v.width, v.height), 0x00a1_bed0)
                        .map_err(|e| tracing::warn!("the scene's albedo could not be traced: {e}"))
                        .ok()
                };
                Box::new(Denoised::new(driver, d).with_albedo(Box::new(source)))
            }
        })
    }
}

/// What [`recall`] read, and how long each stage took.
#[derive(Clone, Copy, Debug)]
pub struct Recalled {
    /// Beams the view selected.
    pub beams: usize,
    /// Samples read and handed to the driver.
    pub samples: u64,
    /// Reading, decoding and inserting.
    pub secs: Duration,
    /// Of which reading the file (the rest of `secs` is the driver's).
    pub read: Duration,
    /// Decoding records and projecting them onto pixels, on all cores.
    pub decode: Duration,
    /// Sorting the projected rays by pixel and merging them into the
    /// pixels' estimates.
    pub insert: Duration,
    /// Beams next to the view's read for pixels that had no ray (see
    /// [`DriverChoice::neighbours`]).
    pub neighbour_beams: usize,
    /// Pixels that had no ray from the view's beams and have one from
    /// their neighbours.
    pub filled: u64,
}

/// A fresh driver for `viewport` holding every stored ray of the beams the
/// view sees (and, where that leaves pixels without a ray, of the beams
/// next to theirs: [`DriverChoice::neighbours`]), ready to draw.
pub fn recall(
    file: &mut HoloFile,
    viewport: Viewport,
    driver: &DriverChoice,
    stride: u32,
    seed: u64,
) -> Result<(Box<dyn holodeck_display::Driver>, Recalled), Error> {
    let sections = file.sections().to_vec();
    let keys = view_keys(&sections, &viewport, stride, seed);
    let decoder = SampleDecoder::new(sections.clone());
    let mut d = driver.make(viewport.clone())?;
    let start = Instant::now();
    let before = d.insert_times();
    let (mut samples, mut adding) = feed(file, &keys, &decoder, d.as_mut(), false)?;
    let (mut neighbour_beams, mut filled) = (0, 0);
    if driver.neighbours {
        let empty = d.empty_pixels();
        let gaps = gaps::count(&empty);
        if gaps > 0 {
            let near = gaps::neighbour_beams(&sections, &viewport, &empty, &keys);
            neighbour_beams = near.len();
            let (n, t) = feed(file, &near, &decoder, d.as_mut(), true)?;
            samples += n;
            adding += t;
            filled = gaps - gaps::count(&d.empty_pixels());
        }
    }
    let secs = start.elapsed();
    let times = d.insert_times();
    Ok((
        d,
        Recalled {
            beams: keys.len(),
            samples,
            secs,
            read: secs.saturating_sub(adding),
            decode: times.project.saturating_sub(before.project),
            insert: (times.sort + times.merge).saturating_sub(before.sort + before.merge),
            neighbour_beams,
            filled,
        },
    ))
}

/// The beams `viewport` sees, found by one view ray per `stride` pixels
/// across and down (placed by `seed`), sorted.
fn view_keys(sections: &[holodeck_protocol::Section], viewport: &Viewport, stride: u32, seed: u64) -> Vec<BeamKey> {
    let options = RequestOptions {
        stride,
        ..RequestOptions::default()
    };
    let request = BeamRequest::for_viewport(sections, viewport, &options, seed);
    let mut keys: Vec<BeamKey> = request.beams.iter().map(|b| b.0).collect();
    keys.sort_unstable();
    keys
}

/// Reads the beams `keys` (sorted) and hands their rays to `d` (only to
/// its pixels without an estimate with `where_empty`); returns the rays
/// read and the time the driver took.
fn feed(
    file: &mut HoloFile,
    keys: &[BeamKey],
    decoder: &SampleDecoder,
    d: &mut dyn Driver,
    where_empty: bool,
) -> Result<(u64, Duration), Error> {
    let mut adding = Duration::ZERO;
    let samples = read_in_chunks(
        file,
        keys,
        |_, _| 0,
        |chunks| {
            let at = Instant::now();
            if where_empty {
                d.add_beams_where_empty(decoder, chunks);
            } else {
                d.add_beams(decoder, chunks);
            }
            adding += at.elapsed();
        },
    )?;
    Ok((samples, adding))
}

/// Reads the beams `keys` (sorted), each past the records `skip` says (it
/// is given the beam and its length), and hands their records to `take` in
/// chunks of about [`CHUNK_RAYS`], [`GROUP_CHUNKS`] chunks at a time, so
/// that a driver merges one batch while it projects the next; returns the
/// records handed over. The chunks are part of what makes a picture (see
/// [`CHUNK_RAYS`]): `pict` and the window's replay cut them alike.
pub(crate) fn read_in_chunks(
    file: &mut HoloFile,
    keys: &[BeamKey],
    mut skip: impl FnMut(BeamKey, usize) -> usize,
    mut take: impl FnMut(&[&[(BeamKey, &[RayRecord])]]),
) -> Result<u64, holodeck_file::StorageError> {
    let mut samples = 0u64;
    let mut records: Vec<RayRecord> = Vec::with_capacity(CHUNK_RAYS * (GROUP_CHUNKS + 1));
    let mut beams: Vec<(BeamKey, std::ops::Range<usize>)> = Vec::new();
    let mut ends: Vec<usize> = Vec::new();
    let mut flush =
        |records: &mut Vec<RayRecord>, beams: &mut Vec<(BeamKey, std::ops::Range<usize>)>, ends: &mut Vec<usize>| {
            let slices: Vec<(BeamKey, &[RayRecord])> = beams.iter().map(|(k, r)| (*k, &records[r.clone()])).collect();
            let mut chunks: Vec<&[(BeamKey, &[RayRecord])]> = Vec::with_capacity(ends.len() + 1);
            let mut from = 0;
            for &end in ends.iter().chain(std::iter::once(&slices.len())) {
                if end > from {
                    chunks.push(&slices[from..end]);
                }
                from = end;
            }
            if !chunks.is_empty() {
                take(&chunks);
            }
            samples += records.len() as u64;
            records.clear();
            beams.clear();
            ends.clear();
        };
    let mut chunk_start = 0;
    file.read_beams(keys, |k, rays| {
        let from = skip(k, rays.len()).min(rays.len());
        if from == rays.len() {
            return;
        }
        let at = records.len();
        records.extend_from_slice(&rays[from..]);
        beams.push((k, at..records.len()));
        if records.len() - chunk_start >= CHUNK_RAYS {
            ends.push(beams.len());
            chunk_start = records.len();
            if ends.len() == GROUP_CHUNKS {
                flush(&mut records, &mut beams, &mut ends);
                chunk_start = 0;
            }
        }
    })?;
    flush(&mut records, &mut beams, &mut ends);
    Ok(samples)
}

/// Reads the records of the beams `keys` (sorted) that `sent` (records
/// per beam handed over so far) has not seen, hands them to `take` in the
/// chunks [`read_in_chunks`] cuts, and counts them into `sent` once handed
/// over; returns the records handed over. A beam sent in full is not read
/// again (its length is in the file's directory, in memory). The window's
/// replay and [`follow`] share it.
pub fn read_unsent(
    file: &mut HoloFile,
    keys: &[BeamKey],
    sent: &mut HashMap<BeamKey, u64>,
    mut take: impl FnMut(&[&[(BeamKey, &[RayRecord])]]),
) -> Result<u64, holodeck_file::StorageError> {
    let fresh: Vec<BeamKey> = keys
        .iter()
        .copied()
        .filter(|&k| {
            file.beam_len(k)
                .map_or(true, |n| n > sent.get(&k).copied().unwrap_or(0))
        })
        .collect();
    let counts = RefCell::new(std::mem::take(sent));
    let read = read_in_chunks(
        file,
        &fresh,
        |k, _| counts.borrow().get(&k).copied().unwrap_or(0) as usize,
        |chunks| {
            take(chunks);
            let mut counts = counts.borrow_mut();
            for &(k, records) in chunks.iter().copied().flatten() {
                *counts.entry(k).or_default() += records.len() as u64;
            }
        },
    );
    *sent = counts.into_inner();
    read
}

/// What [`follow`] did for one view.
#[derive(Clone, Copy, Debug, Default)]
pub struct Followed {
    /// Beams the view selected.
    pub beams: usize,
    /// Samples read and handed over (those of beams not given before).
    pub samples: u64,
    /// Moving the driver's estimates to the new view.
    pub reproject: Duration,
    /// Reading, decoding and inserting the new samples.
    pub recall: Duration,
}

/// Moves `driver` to `viewport` (its estimates reprojected, as a window
/// does when the user moves) and hands it the stored rays of the view's
/// beams it has not been given yet (`given`: records per beam so far), as
/// the window's replay does once the view settles: a walk through a file
/// in one driver, each view costing what is new in it. A turn that makes
/// the driver drop its estimates (more than the paper's 20 degrees) makes
/// every beam of the view new again, as the window asks for them again.
pub fn follow(
    file: &mut HoloFile,
    driver: &mut dyn Driver,
    viewport: Viewport,
    given: &mut HashMap<BeamKey, u64>,
    stride: u32,
    seed: u64,
) -> Result<Followed, Error> {
    let sections = file.sections().to_vec();
    let keys = view_keys(&sections, &viewport, stride, seed);
    let start = Instant::now();
    let drops = driver.stats().cache_drops;
    driver.set_view(viewport);
    if driver.stats().cache_drops > drops {
        given.clear();
    }
    let reproject = start.elapsed();
    let decoder = SampleDecoder::new(sections);
    let start = Instant::now();
    let samples = read_unsent(file, &keys, given, |chunks| driver.add_beams(&decoder, chunks))?;
    Ok(Followed {
        beams: keys.len(),
        samples,
        reproject,
        recall: start.elapsed(),
    })
}

/// What drawing one frame took.
pub struct FrameStats {
    /// Beams the view selected.
    pub beams: usize,
    /// Samples read and handed to the driver.
    pub samples: u64,
    /// Reading, decoding and inserting.
    pub recall: Duration,
    /// The stages of the recall.
    pub stages: Recalled,
    /// Drawing the frame (and denoising it).
    pub render: Duration,
    /// The driver's counters.
    pub driver: DriverStats,
    /// Heap bytes the driver held after drawing (its estimates, index and
    /// scratch).
    pub heap: usize,
}

/// Draws `view` from `file` with a fresh driver; returns the frame, the
/// histogram of the samples, and the statistics.
pub fn draw(
    file: &mut HoloFile,
    viewport: Viewport,
    driver: &DriverChoice,
    stride: u32,
    seed: u64,
) -> Result<(holodeck_protocol::Picture, Histogram, FrameStats), Error> {
    let (mut d, recalled) = recall(file, viewport, driver, stride, seed)?;
    let start = Instant::now();
    let picture = d.render();
    let render = start.elapsed();
    // Tone mapping follows what is on screen (as rhpict's does).
    let hist = Histogram::from_picture(&picture);
    Ok((
        picture,
        hist,
        FrameStats {
            beams: recalled.beams,
            samples: recalled.samples,
            recall: recalled.secs,
            stages: recalled,
            render,
            driver: d.stats(),
            heap: d.heap_bytes(),
        },
    ))
}
