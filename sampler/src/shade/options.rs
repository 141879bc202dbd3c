//! The estimator's settings: how many bounces and estimates, whether
//! lights are sampled, the level of detail out of core, and the order in
//! which the rays of a batch are found and traced.

use std::str::FromStr;
use std::sync::OnceLock;

/// Settings of the estimator.
#[derive(Clone, Copy, Debug)]
pub struct TraceOptions {
    /// Largest number of bounces after the first hit.
    pub max_bounces: u32,
    /// Bounce after which Russian roulette may end paths.
    pub roulette_after: u32,
    /// Report virtual distances through flat mirrors and thin glass.
    pub vdistance: bool,
    /// Independent estimates averaged per ray (a holodeck ray's radiance is
    /// their mean; its distance is the first estimate's).
    pub samples: u32,
    /// Sample lights and the sun directly (next-event estimation with MIS).
    /// Off, paths find light only by BSDF sampling: a baseline for comparisons.
    pub light_sampling: bool,
    /// Out-of-core scenes: a voxel stands in for its subtree on the first
    /// segment of a path when its radius is below this share of its distance
    /// (pixels of error times the pixel's angle; 0: never).
    pub lod_primary: f32,
    /// The same for every later segment and shadow ray (from a solid angle).
    pub lod_secondary: f32,
    /// The order in which the paths of a batch are traced (in core): each
    /// to its end, or a segment at a time with each segment's rays sorted.
    /// The samples are the same either way.
    pub reorder: Reorder,
}

impl Default for TraceOptions {
    fn default() -> Self {
        TraceOptions {
            max_bounces: 8,
            roulette_after: 3,
            vdistance: false,
            light_sampling: true,
            samples: 1,
            lod_primary: 0.0,
            lod_secondary: 0.0,
            reorder: Reorder::Auto,
        }
    }
}

/// How [`Tracer::trace_rays`](super::Tracer::trace_rays) finds the first hits of its rays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FirstHits {
    /// In packets of [`PACKET`](crate::accel::PACKET) consecutive rays (coherent rays, such as one
    /// beam's, share their walk and their leaf tests).
    #[default]
    Packets,
    /// One ray at a time.
    Single,
    /// Whichever of the two has cost less per ray on this tracer's batches
    /// so far, timed as they run, with one batch in `PROBE_EVERY` given
    /// to the other (see `measured.rs`). Beam rays share an origin cell,
    /// not a point, so whether packets pay depends on the grid and the scene.
    Measured,
}

/// The way of finding first hits a `TwoWays` index stands for (see `measured.rs`).
pub(super) fn way_of(i: usize) -> FirstHits {
    if i == 0 {
        FirstHits::Packets
    } else {
        FirstHits::Single
    }
}

/// How a tracer orders the rays of a batch of paths ([`Tracer::trace_rays`](super::Tracer::trace_rays)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Reorder {
    /// Sorted where that pays, as timed while the batches run: on an
    /// in-core scene whose structure and mesh are larger than the
    /// last-level cache, batches of at least [`AUTO_MIN_PATHS`] paths are
    /// traced both ways (sorted by origin, which measured faster than by
    /// hit point for whole paths, and each to its end), then the faster
    /// way, with the other tried now and then. Otherwise each path is
    /// traced to its end.
    #[default]
    Auto,
    /// Each path traced to its end, in the batch's order (for comparison).
    Off,
    /// Always a segment at a time, sorted by estimated hit point (the
    /// first occupied cell of a coarse grid along each ray).
    HitPoint,
    /// Always a segment at a time, sorted by ray origin.
    Origin,
}

impl std::fmt::Display for Reorder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Reorder::Auto => "auto",
            Reorder::Off => "off",
            Reorder::HitPoint => "hit-point",
            Reorder::Origin => "origin",
        })
    }
}

impl FromStr for Reorder {
    type Err = String;
    fn from_str(s: &str) -> Result<Reorder, String> {
        match s {
            "auto" => Ok(Reorder::Auto),
            "off" => Ok(Reorder::Off),
            "hit-point" => Ok(Reorder::HitPoint),
            "origin" => Ok(Reorder::Origin),
            _ => Err(format!(
                "unknown ray order {s:?}: expected auto, off, hit-point or origin"
            )),
        }
    }
}

/// Paths a batch needs before [`Reorder::Auto`] tries sorting it: below
/// this the sort does not pay for itself even on large scenes (`holodeck
/// bench tracer`: bounce rays sorted in batches of 32,768 ran no faster than
/// as given on the 10M landscape; whole paths gained only in batches of a
/// million).
pub const AUTO_MIN_PATHS: usize = 1 << 18;

/// Bytes of the largest CPU cache, read once from Linux's sysfs (8 MiB
/// where it cannot be read).
pub fn last_level_cache_bytes() -> usize {
    static BYTES: OnceLock<usize> = OnceLock::new();
    *BYTES.get_or_init(|| {
        let read = |i: u32| -> Option<usize> {
            let text = std::fs::read_to_string(format!("/sys/devices/system/cpu/cpu0/cache/index{i}/size")).ok()?;
            let text = text.trim();
            let (digits, unit) = text.split_at(text.find(|c: char| !c.is_ascii_digit()).unwrap_or(text.len()));
            let n: usize = digits.parse().ok()?;
            Some(match unit {
                "K" => n << 10,
                "M" => n << 20,
                "G" => n << 30,
                _ => n,
            })
        };
        (0..8).filter_map(read).max().unwrap_or(8 << 20)
    })
}
