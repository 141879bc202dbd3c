//! What a driver (and the sample store under it) has seen and done: the
//! count of every ray received, by what became of it.

/// What a driver has seen and done. Every ray received is counted once, as
/// `kept` (it started a pixel's estimate), `merged`, `replaced`, `discarded`,
/// `outside`, `rejected_nonfinite` or `passed_over`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DriverStats {
    /// Rays given to [`Driver::add`](crate::Driver::add).
    pub received: u64,
    /// Pixel estimates held for the current frame.
    pub kept: u64,
    /// Rays that joined the estimate of their pixel's surface.
    pub merged: u64,
    /// Rays that hit a surface in front of their pixel's estimate, which
    /// they replaced (the earlier rays saw something hidden from the eye).
    pub replaced: u64,
    /// Rays that hit behind their pixel's surface (past a silhouette, through
    /// a window): the multidepth rays of the paper's Figure 6, left out.
    pub discarded: u64,
    /// Rays rejected for NaN or infinite numbers.
    pub rejected_nonfinite: u64,
    /// Rays that reproject outside the frame (or behind the eye).
    pub outside: u64,
    /// Rays offered only to pixels without an estimate (a neighbouring
    /// beam's, drawing from a sparse file) that landed on a pixel with one.
    pub passed_over: u64,
    /// Estimates whose brightest ray was cut as a firefly in the last frame.
    pub fireflies: u64,
    /// Times the stored estimates were dropped after a large rotation.
    pub cache_drops: u64,
}

/// How long a sample store spent adding rays, by stage, since it was made
/// (see `store::insert`): what a profile of replay reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct InsertTimes {
    /// Projecting rays onto pixels (and decoding stored records with it),
    /// on every core.
    pub project: std::time::Duration,
    /// Sorting each batch into the index's order.
    pub sort: std::time::Duration,
    /// Finding each pixel's estimate and merging rays into it.
    pub merge: std::time::Duration,
}
