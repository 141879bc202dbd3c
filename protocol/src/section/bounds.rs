//! The bounds every section keeps (sizes, coordinates, shape, grid, beam
//! count) and the errors that say which one a description breaks. Bounds are
//! checked where a section is built, [`super::Section::new`], so every way of
//! describing one (settings text, control files, scene files, the wire)
//! refuses the same sections.

/// Largest grid size along one axis: one byte per cell coordinate, as in the ray record's cells.
pub const MAX_GRID: u16 = 255;

/// Most beams one section may have. The paper advises 50k–500k; this bound keeps
/// the in-memory directory (16 bytes per beam) under 2 GiB.
pub const MAX_BEAMS_PER_SECTION: u64 = 1 << 27;

/// Shortest axis a section may have, in scene units: a millimeter in a scene
/// in meters. Shorter sections cannot hold a grid worth tracing.
pub const MIN_AXIS_LENGTH: f64 = 1e-3;

/// Longest axis a section may have, in scene units (10,000 km in meters).
pub const MAX_AXIS_LENGTH: f64 = 1e7;

/// Largest magnitude of an origin coordinate, in scene units: the scene's
/// sane range, the same as [`MAX_AXIS_LENGTH`].
pub const MAX_COORDINATE: f64 = 1e7;

/// Least volume of a section as a fraction of the box its axis lengths span
/// (1 for perpendicular axes): below this the axes are nearly coplanar and
/// cells become slivers.
pub const MIN_VOLUME_RATIO: f64 = 1e-3;

/// Least length of a grid cell as a fraction of the section's largest
/// coordinate. Samplers trace in single precision, whose steps near a
/// coordinate of magnitude m are at most m * 2^-23 apart; a ray record places
/// rays at 256 positions per cell along each axis, so a cell must span 256
/// such steps: 2^-15 of m.
pub const MIN_CELL_FRACTION: f64 = 1.0 / 32768.0;

/// Errors in defining a section or addressing its beams.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SectionError {
    /// A coordinate is NaN or infinite.
    #[error("section {what} is not finite: {value:?}")]
    NonFinite {
        /// Which vector ("origin", "axis 0", ...).
        what: &'static str,
        /// Its value.
        value: [f64; 3],
    },
    /// The three axes span no volume, or so little that they are nearly
    /// coplanar (see [`MIN_VOLUME_RATIO`]).
    #[error("section axes {0:?} are degenerate: they lie (nearly) in one plane, spanning less than {MIN_VOLUME_RATIO} of the volume of a box with their lengths")]
    Degenerate([[f64; 3]; 3]),
    /// An axis too short or too long to hold a grid.
    #[error("section axis {axis} is {length:?} long; every axis must be between {MIN_AXIS_LENGTH} and {MAX_AXIS_LENGTH} scene units")]
    AxisLength {
        /// Axis 0, 1 or 2.
        axis: usize,
        /// Its length.
        length: f64,
    },
    /// An origin beyond the scene's sane range.
    #[error("section origin {value:?} is outside the sane range: every coordinate must be within ±{MAX_COORDINATE} scene units")]
    OriginOutOfRange {
        /// The origin given.
        value: [f64; 3],
    },
    /// Cells too small for single-precision tracing that far from the
    /// scene's origin (see [`MIN_CELL_FRACTION`]).
    #[error("section cells along axis {axis} are {cell:?} long, too fine for single precision at coordinates up to {magnitude:?}: cells there must be at least {min:?} long; use a coarser grid or move the scene nearer its origin", min = magnitude * MIN_CELL_FRACTION)]
    TooFine {
        /// Axis 0, 1 or 2.
        axis: usize,
        /// Length of one cell along it.
        cell: f64,
        /// Largest coordinate of the section's corners.
        magnitude: f64,
    },
    /// A grid size is zero or above [`MAX_GRID`].
    #[error("section grid size {size} along axis {axis} is outside 1..={max}", max = MAX_GRID)]
    GridOutOfRange {
        /// Axis 0, 1 or 2.
        axis: usize,
        /// The size given.
        size: u32,
    },
    /// The grid gives more beams than [`MAX_BEAMS_PER_SECTION`].
    #[error("section grid {grid:?} gives {count} beams, more than the {max} a section may hold; use a coarser grid", max = MAX_BEAMS_PER_SECTION)]
    TooManyBeams {
        /// The grid.
        grid: [u16; 3],
        /// Its beam count.
        count: u64,
    },
    /// A beam index at or beyond the section's beam count.
    #[error("beam index {beam} is out of range: the section has {count} beams")]
    BeamOutOfRange {
        /// The index given.
        beam: u32,
        /// The section's beam count.
        count: u32,
    },
    /// A wall cell outside the wall's grid.
    #[error("cell {cell:?} is outside wall {wall}'s grid")]
    CellOutOfRange {
        /// The wall.
        wall: u8,
        /// The cell coordinates.
        cell: [u16; 2],
    },
    /// Entry and exit cells on the same wall do not make a beam.
    #[error("entry and exit cells are both on wall {0}: no ray crosses a wall twice")]
    SameWall(u8),
    /// A grid length (Radiance's GRID) that is not a positive finite number.
    #[error("grid length {0} must be a positive finite number")]
    BadGridLength(f64),
    /// A description gives both a grid and a target beam count.
    #[error("give a grid or a target beam count, not both")]
    GridAndBeams,
}

/// The part of a section description a [`SectionError`] is about, so that
/// callers can name it as their users wrote it (`x=` in a section line,
/// `axes[0]` in a TOML table).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SectionField {
    /// The corner.
    Origin,
    /// Edge vector 0, 1 or 2.
    Axis(usize),
    /// The cells per axis.
    Grid,
    /// The target beam count.
    Beams,
    /// The depth coding.
    Depth,
}

impl SectionField {
    /// The key in a TOML `[[section]]` table: `origin`, `axes[0]`..`axes[2]`, `grid`.
    pub fn toml_key(self) -> &'static str {
        match self {
            SectionField::Origin => "origin",
            SectionField::Axis(0) => "axes[0]",
            SectionField::Axis(1) => "axes[1]",
            SectionField::Axis(_) => "axes[2]",
            SectionField::Grid => "grid",
            SectionField::Beams => "beams",
            SectionField::Depth => "depth",
        }
    }

    /// The key in a section line (`interior origin=.. x=.. y=.. z=.. grid=..`).
    pub fn text_key(self) -> &'static str {
        match self {
            SectionField::Origin => "origin=",
            SectionField::Axis(0) => "x=",
            SectionField::Axis(1) => "y=",
            SectionField::Axis(_) => "z=",
            SectionField::Grid => "grid=",
            SectionField::Beams => "beams=",
            SectionField::Depth => "depth=",
        }
    }
}

impl SectionError {
    /// The field of the description the error is about, where it is about one.
    pub fn field(&self) -> Option<SectionField> {
        match self {
            SectionError::NonFinite { what: "origin", .. } | SectionError::OriginOutOfRange { .. } => {
                Some(SectionField::Origin)
            }
            SectionError::AxisLength { axis, .. } | SectionError::TooFine { axis, .. } => {
                Some(SectionField::Axis(*axis))
            }
            SectionError::NonFinite { what, .. } => what
                .strip_prefix("axis ")
                .and_then(|n| n.parse().ok())
                .map(SectionField::Axis),
            SectionError::GridOutOfRange { .. } | SectionError::TooManyBeams { .. } | SectionError::GridAndBeams => {
                Some(SectionField::Grid)
            }
            _ => None,
        }
    }
}
