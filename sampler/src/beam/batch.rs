//! Many beams' rays traced as one batch: what samplers do with the packets
//! a server hands them, and the batch fill with every core.
//!
//! Each beam's share is a [`BeamTask`] with its own random sequence, which
//! chooses the beam's rays and seeds their paths. A record therefore
//! depends on its task alone: tasks may be traced one by one or many
//! together, on any number of threads, with the paths each to its end or
//! a segment at a time in sorted order, and the records come out the same.
//! Batching only changes the speed: a batch of many beams gives ray
//! reordering ([`crate::Reorder`]) rays enough to sort.
//!
//! Never: a socket or a file; the server's and the worker's loops call this.

use glam::Vec3;
use holodeck_protocol::wire::SamplingMode;
use holodeck_protocol::{BeamIndex, BeamKey, RayRecord, Section, SectionError};
use rayon::prelude::*;

use super::{encode, proximity_rays, traced_ray, uniform_rays, BeamSample, FileRules};
use crate::shade::{batch_seed, FirstHits, Rng, SeededRay, Tracer};

/// One beam's share of a batch: `rays` rays of `beam`, chosen as `mode`
/// says with `rng`, which then seeds their paths.
#[derive(Clone, Debug)]
pub(crate) struct BeamTask<'a> {
    /// The beam's section.
    pub section: &'a Section,
    /// The beam.
    pub beam: BeamIndex,
    /// Rays to choose and trace.
    pub rays: usize,
    /// How to choose them.
    pub mode: SamplingMode,
    /// The task's random sequence.
    pub rng: Rng,
}

/// A task's rays as chosen: its section, the samples, where each traced
/// part starts, and the seed of their paths.
struct Chosen<'a> {
    section: &'a Section,
    samples: Vec<BeamSample>,
    starts: Vec<f64>,
    seed: u64,
}

/// Chooses a task's rays and the seed of their paths.
fn choose(mut task: BeamTask<'_>) -> Result<Chosen<'_>, SectionError> {
    let samples = match task.mode {
        SamplingMode::Uniform => uniform_rays(task.section, task.beam, task.rays, &mut task.rng)?,
        SamplingMode::NearEye { eye, radius, frustum } => {
            proximity_rays(
                task.section,
                task.beam,
                task.rays,
                glam::DVec3::from(eye),
                radius,
                frustum.as_ref(),
                &mut task.rng,
            )?
            .0
        }
    };
    let seed = batch_seed(&mut task.rng);
    Ok(Chosen {
        section: task.section,
        starts: Vec::with_capacity(samples.len()),
        samples,
        seed,
    })
}

/// Traces the tasks' rays as one batch under a file's `rules` (first hits
/// as [`FirstHits::Measured`] finds them; paths as the tracer's options
/// order them): each task's records, or why its beam could not be sampled.
/// Samples only unreadable scene-file blocks could have traced are left out.
pub(crate) fn trace_tasks(
    tracer: &Tracer,
    rules: FileRules,
    tasks: Vec<BeamTask<'_>>,
) -> Vec<Result<Vec<RayRecord>, SectionError>> {
    // A beam's rays run between one pair of cells; whether that is coherent
    // enough for packets to pay, the times tell.
    trace_chosen(
        tracer,
        rules,
        tasks.into_iter().map(choose).collect(),
        FirstHits::Measured,
    )
}

/// Traces beam samples into records, finding their first hits as `first`
/// says (in core; out of core every ray walks alone), each sample's paths
/// drawing from its own streams of one seed taken from `rng`: the records
/// do not depend on `first`. Samples only unreadable scene-file blocks
/// could have traced are left out.
pub fn trace_samples(
    tracer: &Tracer,
    section: &Section,
    rules: FileRules,
    samples: &[BeamSample],
    first: FirstHits,
    rng: &mut Rng,
) -> Vec<RayRecord> {
    let chosen = Chosen {
        section,
        starts: Vec::with_capacity(samples.len()),
        samples: samples.to_vec(),
        seed: batch_seed(rng),
    };
    trace_chosen(tracer, rules, vec![Ok(chosen)], first)
        .pop()
        .and_then(Result::ok)
        .unwrap_or_default()
}

/// Traces chosen rays as one batch: sample `i` of a task draws its
/// estimates from streams `i * samples ..` of the task's seed.
fn trace_chosen(
    tracer: &Tracer,
    rules: FileRules,
    mut chosen: Vec<Result<Chosen<'_>, SectionError>>,
    first: FirstHits,
) -> Vec<Result<Vec<RayRecord>, SectionError>> {
    let n = u64::from(tracer.options.samples.max(1));
    let mut rays: Vec<SeededRay> = Vec::new();
    for c in chosen.iter_mut().flatten() {
        for (i, s) in c.samples.iter().enumerate() {
            let (start, origin, dir): (f64, Vec3, Vec3) = traced_ray(c.section, rules, s);
            c.starts.push(start);
            rays.push(SeededRay {
                origin,
                dir,
                seed: c.seed,
                stream: i as u64 * n,
            });
        }
    }
    let mut traced = tracer.trace_seeded(&rays, rules.vdistance, first).into_iter();
    chosen
        .into_iter()
        .map(|c| {
            let c = c?;
            Ok(c.samples
                .iter()
                .zip(&c.starts)
                .zip(traced.by_ref())
                .filter_map(|((s, &start), sample)| Some(encode(c.section, s, start, &sample?)))
                .collect())
        })
        .collect()
}

/// Rays traced as one task: beams asked for many rays are cut into pieces
/// of this size, so that every core stays busy when a few beams get most of
/// the rays (a display's requests go where its pixels need them).
pub(crate) const TASK_RAYS: u32 = 256;

/// Traces a batch of (beam, rays) with all cores of the current rayon pool,
/// choosing each beam's rays as `mode` says, one random sequence per piece
/// of at most [`TASK_RAYS`] rays (stream `t` of `seed` for the `t`-th).
/// Where the tracer reorders batches of the size each core would get, each
/// core traces its share of the pieces as one batch; otherwise each piece
/// is traced alone. Either way the records are the same. Beams come back in
/// the batch's order, each with all its rays; a beam its section lacks
/// gets none.
pub fn trace_batch(
    tracer: &Tracer,
    sections: &[Section],
    rules: FileRules,
    batch: &[(BeamKey, u32)],
    mode: &(dyn Fn(BeamKey) -> SamplingMode + Sync),
    seed: u64,
) -> Vec<(BeamKey, Vec<RayRecord>)> {
    let mut pieces = Vec::with_capacity(batch.len());
    for (i, &(key, n)) in batch.iter().enumerate() {
        let mut left = n;
        while left > 0 {
            let take = left.min(TASK_RAYS);
            pieces.push((i, key, take));
            left -= take;
        }
    }
    let total: u64 = batch.iter().map(|&(_, n)| u64::from(n)).sum();
    let threads = rayon::current_num_threads().max(1);
    let per_thread = (total as usize).div_ceil(threads) * tracer.options.samples.max(1) as usize;
    let group = if tracer.may_reorder(per_thread) {
        pieces.len().div_ceil(threads).max(1)
    } else {
        1
    };
    let traced: Vec<(usize, Vec<RayRecord>)> = pieces
        .par_chunks(group)
        .enumerate()
        .flat_map_iter(|(g, chunk)| {
            // A beam its section lacks gets no task (and no rays).
            let (at, tasks): (Vec<usize>, Vec<BeamTask>) = chunk
                .iter()
                .enumerate()
                .filter_map(|(j, &(i, key, n))| {
                    let task = BeamTask {
                        section: sections.get(key.section as usize)?,
                        beam: key.beam,
                        rays: n as usize,
                        mode: mode(key),
                        rng: Rng::new(seed, (g * group + j) as u64),
                    };
                    Some((i, task))
                })
                .unzip();
            let records = trace_tasks(tracer, rules, tasks);
            at.into_iter()
                .zip(records)
                .map(|(i, r)| (i, r.unwrap_or_default()))
                .collect::<Vec<_>>()
        })
        .collect();
    let mut out: Vec<(BeamKey, Vec<RayRecord>)> = batch.iter().map(|&(k, _)| (k, Vec::new())).collect();
    for (i, records) in traced {
        out[i].1.extend(records);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{generate, GenParams};
    use crate::{Reorder, TraceOptions};

    /// A batch of the room's beams: every 53rd beam of each section, with a
    /// few rays each, one beam with many (cut into pieces).
    fn room_batch(sections: &[Section]) -> Vec<(BeamKey, u32)> {
        let mut batch = Vec::new();
        for (i, s) in sections.iter().enumerate() {
            for beam in (0..s.beam_count()).step_by(53) {
                batch.push((BeamKey::new(i as u32, beam), 1 + beam % 7));
            }
        }
        batch[3].1 = 3 * TASK_RAYS + 5;
        batch
    }

    /// The records of a batch are the same traced piece by piece, or in
    /// groups with the paths sorted, on one thread or two.
    #[test]
    fn grouping_and_sorting_change_no_record() {
        let room = generate("room", &GenParams::default()).unwrap();
        let sections = room.sections.clone();
        let mut tracer = Tracer::new(
            room,
            TraceOptions {
                samples: 2,
                ..TraceOptions::default()
            },
        );
        let batch = room_batch(&sections);
        let mode = |_| SamplingMode::Uniform;
        let mut want = None;
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            for reorder in [Reorder::Off, Reorder::HitPoint, Reorder::Origin] {
                tracer.options.reorder = reorder;
                let got = pool.install(|| trace_batch(&tracer, &sections, FileRules::default(), &batch, &mode, 11));
                for ((k, records), &(key, n)) in got.iter().zip(&batch) {
                    assert_eq!((*k, records.len()), (key, n as usize));
                }
                match &want {
                    None => want = Some(got),
                    Some(w) => assert!(*w == got, "{threads} threads, {reorder:?}"),
                }
            }
        }
    }

    /// Tasks traced together give each the records it gets alone; a beam
    /// its section lacks is an error for that task only.
    #[test]
    fn tasks_traced_together_or_alone_agree() {
        let room = generate("room", &GenParams::default()).unwrap();
        let section = room.sections[0].clone();
        let tracer = Tracer::new(room, TraceOptions::default());
        let rules = FileRules::default();
        let task = |beam, rays, stream| BeamTask {
            section: &section,
            beam,
            rays,
            mode: SamplingMode::Uniform,
            rng: Rng::new(5, stream),
        };
        let beams = [0, 77, section.beam_count(), 1234];
        let together = trace_tasks(
            &tracer,
            rules,
            beams.iter().enumerate().map(|(i, &b)| task(b, 9, i as u64)).collect(),
        );
        assert!(together[2].is_err());
        for (i, &b) in beams.iter().enumerate() {
            let alone = trace_tasks(&tracer, rules, vec![task(b, 9, i as u64)]);
            match (&together[i], &alone[0]) {
                (Ok(t), Ok(a)) => assert_eq!((t, t.len()), (a, 9)),
                (Err(_), Err(_)) => assert_eq!(i, 2),
                _ => panic!("task {i}: together and alone disagree"),
            }
        }
    }
}
