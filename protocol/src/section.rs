//! A holodeck section: a gridded parallelepiped that rays enter through one wall
//! cell and leave through another.
//!
//! Coordinates come in two frames: *world* (the scene's units) and *unit*
//! (section space, the parallelepiped mapped to [0,1]^3 along its three axes).
//! This module owns the section's shape and grid; beam indexing lives in
//! [`crate::beam`].

use glam::{DMat3, DVec3};
use serde::{Deserialize, Serialize};

use crate::depth::{DepthCode, DepthCoding};

mod bounds;
mod spec;
mod text;

pub use bounds::{
    SectionError, SectionField, MAX_AXIS_LENGTH, MAX_BEAMS_PER_SECTION, MAX_COORDINATE, MAX_GRID, MIN_AXIS_LENGTH,
    MIN_CELL_FRACTION, MIN_VOLUME_RATIO,
};
pub use spec::{SectionSpec, DEFAULT_BEAMS};
pub use text::SectionTextError;

/// Whether views look out of the section (interior) or into it (exterior).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum SectionKind {
    /// A region of free movement: geometry lies outside; rays are traced from the exit wall outward.
    Interior,
    /// An object viewed from outside: geometry lies inside; rays are traced from the entry wall inward.
    Exterior,
}

impl SectionKind {
    /// The lowercase name used in settings text.
    pub fn name(self) -> &'static str {
        match self {
            SectionKind::Interior => "interior",
            SectionKind::Exterior => "exterior",
        }
    }
}

/// One of the six walls: `2 * axis + side`, where side 0 lies at unit coordinate 0.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Wall(pub u8);

impl Wall {
    /// All six walls in index order.
    pub const ALL: [Wall; 6] = [Wall(0), Wall(1), Wall(2), Wall(3), Wall(4), Wall(5)];

    /// The axis (0, 1, 2) the wall is perpendicular to.
    pub fn axis(self) -> usize {
        usize::from(self.0 / 2)
    }
    /// 0 for the wall at unit coordinate 0 along its axis, 1 for the one at 1.
    pub fn side(self) -> u8 {
        self.0 % 2
    }
    /// The section axes that index the wall's cells, in (u, v) order.
    pub fn cell_axes(self) -> [usize; 2] {
        let a = self.axis();
        [(a + 1) % 3, (a + 2) % 3]
    }
}

/// A validated section with its derived beam-indexing tables.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "SectionSpec", into = "SectionSpec")]
pub struct Section {
    origin: DVec3,
    axes: [DVec3; 3],
    grid: [u16; 3],
    kind: SectionKind,
    to_unit: DMat3,
    /// (entry wall, exit wall, first beam index) for the 30 ordered wall pairs, in index order.
    pairs: [(Wall, Wall, u32); 30],
    beam_count: u32,
    diagonal: f64,
    depth_coding: DepthCoding,
    /// What depth codes are scaled by (see [`Section::depth_scale`]), kept
    /// because every encoded and decoded ray needs it.
    depth_scale: f64,
}

/// How near an eye new rays of its beams pass: `fraction` of the smallest
/// section diagonal of `sections` (the one rule displays' requests and
/// in-process fills share); `None` for 0 (anywhere in the beam) or where
/// that is not a finite, positive length.
pub fn eye_radius(sections: &[Section], fraction: f64) -> Option<f64> {
    let smallest = sections.iter().map(Section::diagonal).fold(f64::INFINITY, f64::min);
    let radius = fraction * smallest;
    (radius.is_finite() && radius > 0.0).then_some(radius)
}

/// The paper's beam count N = 2W²D² + 2W²H² + 2D²H² + 8W²DH + 8WD²H + 8WDH².
pub fn beam_count_for_grid(grid: [u16; 3]) -> u64 {
    let [w, d, h] = grid.map(u64::from);
    2 * w * w * d * d
        + 2 * w * w * h * h
        + 2 * d * d * h * h
        + 8 * w * w * d * h
        + 8 * w * d * d * h
        + 8 * w * d * h * h
}

/// Grid from a cell length like Radiance's GRID: each axis length / `length`,
/// rounded up, clamped to 1..=[`MAX_GRID`].
pub fn grid_for_length(axes: [[f64; 3]; 3], length: f64) -> Result<[u16; 3], SectionError> {
    if !(length.is_finite() && length > 0.0) {
        return Err(SectionError::BadGridLength(length));
    }
    Ok(axes.map(|a| {
        let n = (DVec3::from(a).length() / length).ceil();
        n.clamp(1.0, f64::from(MAX_GRID)) as u16
    }))
}

/// The grid (from some cell length) whose beam count is closest to `target`,
/// measured by ratio. Useful to follow the paper's advice of 50k–500k beams.
pub fn grid_for_beam_count(axes: [[f64; 3]; 3], target: u64) -> Result<[u16; 3], SectionError> {
    // An axis too long or too short says so (its squared length may
    // overflow: measured scaled by its largest component).
    for (axis, a) in axes.iter().enumerate() {
        let v = finite(["axis 0", "axis 1", "axis 2"][axis], *a)?;
        let m = v.abs().max_element();
        let length = if m > 0.0 && m.is_finite() {
            m * (v / m).length()
        } else {
            m
        };
        if !(MIN_AXIS_LENGTH..=MAX_AXIS_LENGTH).contains(&length) {
            return Err(SectionError::AxisLength { axis, length });
        }
    }
    let longest = axes.iter().map(|a| DVec3::from(*a).length()).fold(0.0, f64::max);
    if !(longest.is_finite() && longest > 0.0) {
        return Err(SectionError::Degenerate(axes));
    }
    let target = target.max(1) as f64;
    // Beam count falls as the cell length grows: bisect on the log of the length.
    let (mut fine, mut coarse) = ((longest / f64::from(MAX_GRID)).ln() - 1.0, longest.ln() + 1.0);
    for _ in 0..80 {
        let mid = 0.5 * (fine + coarse);
        let count = beam_count_for_grid(grid_for_length(axes, mid.exp())?) as f64;
        if count > target {
            fine = mid;
        } else {
            coarse = mid;
        }
    }
    let candidates = [grid_for_length(axes, fine.exp())?, grid_for_length(axes, coarse.exp())?];
    let misfit = |g: &[u16; 3]| (beam_count_for_grid(*g) as f64 / target).ln().abs();
    let best = if misfit(&candidates[0]) < misfit(&candidates[1]) {
        candidates[0]
    } else {
        candidates[1]
    };
    Ok(best)
}

fn finite(what: &'static str, v: [f64; 3]) -> Result<DVec3, SectionError> {
    if v.iter().all(|c| c.is_finite()) {
        Ok(DVec3::from(v))
    } else {
        Err(SectionError::NonFinite { what, value: v })
    }
}

impl Section {
    /// Builds a section, checking that it is finite, within the sane range of
    /// sizes and coordinates, spans a volume, and has a valid grid whose cells
    /// single precision resolves.
    pub fn new(
        origin: [f64; 3],
        axes: [[f64; 3]; 3],
        grid: [u16; 3],
        kind: SectionKind,
    ) -> Result<Section, SectionError> {
        let origin = finite("origin", origin)?;
        let axis_vecs = [
            finite("axis 0", axes[0])?,
            finite("axis 1", axes[1])?,
            finite("axis 2", axes[2])?,
        ];
        if origin.abs().max_element() > MAX_COORDINATE {
            return Err(SectionError::OriginOutOfRange {
                value: origin.to_array(),
            });
        }
        for (axis, a) in axis_vecs.iter().enumerate() {
            let length = a.length();
            if !(MIN_AXIS_LENGTH..=MAX_AXIS_LENGTH).contains(&length) {
                return Err(SectionError::AxisLength { axis, length });
            }
        }
        for (axis, &size) in grid.iter().enumerate() {
            if size == 0 || size > MAX_GRID {
                return Err(SectionError::GridOutOfRange {
                    axis,
                    size: u32::from(size),
                });
            }
        }
        let count = beam_count_for_grid(grid);
        if count > MAX_BEAMS_PER_SECTION {
            return Err(SectionError::TooManyBeams { grid, count });
        }
        let m = DMat3::from_cols(axis_vecs[0], axis_vecs[1], axis_vecs[2]);
        let scale = axis_vecs.iter().map(|a| a.length()).product::<f64>();
        let det = m.determinant();
        if !(scale > 0.0 && (det / scale).abs() >= MIN_VOLUME_RATIO) {
            return Err(SectionError::Degenerate(axes));
        }
        // The farthest corner from the scene's origin sets the coarsest
        // single-precision step any ray in the section meets.
        let far = origin.abs() + axis_vecs.iter().map(|a| a.abs()).sum::<DVec3>();
        let magnitude = far.max_element();
        for (axis, a) in axis_vecs.iter().enumerate() {
            let cell = a.length() / f64::from(grid[axis]);
            if cell < magnitude * MIN_CELL_FRACTION {
                return Err(SectionError::TooFine { axis, cell, magnitude });
            }
        }
        let cells = |w: Wall| {
            let [u, v] = w.cell_axes();
            u64::from(grid[u]) * u64::from(grid[v])
        };
        let mut pairs = [(Wall(0), Wall(0), 0u32); 30];
        let mut base = 0u64;
        let mut k = 0;
        for entry in Wall::ALL {
            for exit in Wall::ALL {
                if entry != exit {
                    pairs[k] = (entry, exit, base as u32);
                    base += cells(entry) * cells(exit);
                    k += 1;
                }
            }
        }
        debug_assert_eq!(base, count);
        let diagonal = (axis_vecs[0] + axis_vecs[1] + axis_vecs[2]).length();
        Ok(Section {
            origin,
            axes: axis_vecs,
            grid,
            kind,
            to_unit: m.inverse(),
            pairs,
            beam_count: count as u32,
            diagonal,
            depth_coding: DepthCoding::Holodeck,
            depth_scale: diagonal,
        })
    }

    /// The same section with its rays' depths in `coding` (Radiance's, for
    /// sections imported from Radiance holodecks).
    pub fn with_depth_coding(mut self, coding: DepthCoding) -> Section {
        self.depth_coding = coding;
        self.depth_scale = match coding {
            DepthCoding::Holodeck => self.diagonal,
            DepthCoding::Radiance => self.axes.iter().map(|a| a.length()).sum(),
        };
        self
    }

    /// How this section's depth codes map to distances.
    pub fn depth_coding(&self) -> DepthCoding {
        self.depth_coding
    }

    /// The length depth codes are scaled by: the main diagonal, or for
    /// Radiance's coding the sum of the axis lengths.
    pub fn depth_scale(&self) -> f64 {
        self.depth_scale
    }

    /// The depth code of a distance (world units from the entry wall).
    pub fn encode_depth(&self, distance: f64) -> DepthCode {
        self.depth_coding.encode(distance, self.depth_scale)
    }

    /// The distance from the entry wall of a depth code, `None` for a ray that escaped.
    pub fn decode_depth(&self, code: DepthCode) -> Option<f64> {
        self.depth_coding.decode(code, self.depth_scale)
    }

    /// Builds a section whose grid follows a cell length (Radiance's GRID).
    pub fn with_grid_length(
        origin: [f64; 3],
        axes: [[f64; 3]; 3],
        length: f64,
        kind: SectionKind,
    ) -> Result<Section, SectionError> {
        Section::new(origin, axes, grid_for_length(axes, length)?, kind)
    }

    /// The plain description, with its explicit grid (for settings text,
    /// scene files and the wire).
    pub fn spec(&self) -> SectionSpec {
        SectionSpec {
            kind: self.kind,
            origin: self.origin.to_array(),
            axes: self.axes.map(|a| a.to_array()),
            grid: Some(self.grid),
            beams: None,
            depth: (self.depth_coding != DepthCoding::Holodeck).then_some(self.depth_coding),
        }
    }

    /// World position of the corner at unit coordinates (0,0,0).
    pub fn origin(&self) -> DVec3 {
        self.origin
    }
    /// The three edge vectors, world units.
    pub fn axes(&self) -> [DVec3; 3] {
        self.axes
    }
    /// Cells along each axis.
    pub fn grid(&self) -> [u16; 3] {
        self.grid
    }
    /// Interior or exterior.
    pub fn kind(&self) -> SectionKind {
        self.kind
    }
    /// Number of beams (ordered pairs of cells on different walls).
    pub fn beam_count(&self) -> u32 {
        self.beam_count
    }
    /// Length of the main diagonal, world units; the scale of the depth code.
    pub fn diagonal(&self) -> f64 {
        self.diagonal
    }
    /// World volume of the parallelepiped.
    pub fn volume(&self) -> f64 {
        self.axes[0].dot(self.axes[1].cross(self.axes[2])).abs()
    }
    /// Number of cells on one wall.
    pub fn wall_cells(&self, wall: Wall) -> u32 {
        let [u, v] = wall.cell_axes();
        u32::from(self.grid[u]) * u32::from(self.grid[v])
    }
    /// The 30 ordered (entry wall, exit wall, first beam index) triples in index order.
    pub(crate) fn wall_pairs(&self) -> &[(Wall, Wall, u32); 30] {
        &self.pairs
    }

    /// Maps a unit-frame point to world coordinates.
    pub fn unit_to_world(&self, unit: DVec3) -> DVec3 {
        self.origin + self.axes[0] * unit.x + self.axes[1] * unit.y + self.axes[2] * unit.z
    }
    /// Maps a world point to the unit frame.
    pub fn world_to_unit(&self, world: DVec3) -> DVec3 {
        self.to_unit * (world - self.origin)
    }
    /// Maps a world direction (or difference of points) to the unit frame.
    pub fn world_dir_to_unit(&self, dir: DVec3) -> DVec3 {
        self.to_unit * dir
    }
    /// World line segments drawing the section's box and its wall grids, each
    /// line once: for viewing the holodeck layout in any mesh viewer.
    pub fn grid_lines(&self) -> Vec<[DVec3; 2]> {
        let mut lines = Vec::new();
        // For each axis a, lines parallel to a at every grid coordinate on the walls
        // perpendicular to the other two axes: (b, c) on the boundary of the wall grid.
        for a in 0..3 {
            let (b, c) = ((a + 1) % 3, (a + 2) % 3);
            let (gb, gc) = (self.grid[b], self.grid[c]);
            for i in 0..=gb {
                for j in 0..=gc {
                    let on_b_wall = i == 0 || i == gb;
                    let on_c_wall = j == 0 || j == gc;
                    if !(on_b_wall || on_c_wall) {
                        continue;
                    }
                    let mut p = DVec3::ZERO;
                    p[b] = f64::from(i) / f64::from(gb);
                    p[c] = f64::from(j) / f64::from(gc);
                    let mut q = p;
                    q[a] = 1.0;
                    lines.push([self.unit_to_world(p), self.unit_to_world(q)]);
                }
            }
        }
        lines
    }

    /// True when a world point lies inside the section (boundary included).
    pub fn contains(&self, world: DVec3) -> bool {
        let u = self.world_to_unit(world);
        (0.0..=1.0).contains(&u.x) && (0.0..=1.0).contains(&u.y) && (0.0..=1.0).contains(&u.z)
    }
}

impl TryFrom<SectionSpec> for Section {
    type Error = SectionError;
    fn try_from(s: SectionSpec) -> Result<Self, Self::Error> {
        s.resolve(None, None)
    }
}

impl From<Section> for SectionSpec {
    fn from(s: Section) -> Self {
        s.spec()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const BOX: [[f64; 3]; 3] = [[10.0, 0.0, 0.0], [0.0, 6.0, 0.0], [0.0, 0.0, 3.0]];

    #[test]
    fn the_eye_radius_is_a_fraction_of_the_smallest_diagonal() {
        let big = Section::new([0.0; 3], BOX, [2, 2, 2], SectionKind::Interior).unwrap();
        let half = BOX.map(|a| a.map(|c| c / 2.0));
        let small = Section::new([0.0; 3], half, [2, 2, 2], SectionKind::Interior).unwrap();
        let d = (100.0f64 + 36.0 + 9.0).sqrt() / 2.0;
        let r = eye_radius(&[big.clone(), small], 0.01).unwrap();
        assert!((r - 0.01 * d).abs() < 1e-12, "{r}");
        assert_eq!(
            eye_radius(std::slice::from_ref(&big), 0.0),
            None,
            "0: anywhere in the beam"
        );
        assert_eq!(eye_radius(&[], 0.01), None, "no sections");
        assert_eq!(eye_radius(&[big], f64::NAN), None);
    }

    #[test]
    fn beam_count_matches_the_formula_by_brute_force() {
        for grid in [[1, 1, 1], [2, 3, 4], [7, 1, 5], [12, 9, 4]] {
            let walls = Wall::ALL.map(|w| {
                let [u, v] = w.cell_axes();
                u64::from(grid[u]) * u64::from(grid[v])
            });
            let total: u64 = walls.iter().sum();
            let same_wall: u64 = walls.iter().map(|c| c * c).sum();
            assert_eq!(beam_count_for_grid(grid), total * total - same_wall, "{grid:?}");
            let s = Section::new([0.0; 3], BOX, grid, SectionKind::Interior).unwrap();
            assert_eq!(u64::from(s.beam_count()), beam_count_for_grid(grid));
        }
        assert_eq!(beam_count_for_grid([1, 1, 1]), 30);
    }

    #[test]
    fn grid_from_length_rounds_up_and_clamps() {
        assert_eq!(grid_for_length(BOX, 1.0).unwrap(), [10, 6, 3]);
        assert_eq!(grid_for_length(BOX, 0.9).unwrap(), [12, 7, 4]);
        assert_eq!(grid_for_length(BOX, 100.0).unwrap(), [1, 1, 1]);
        assert_eq!(grid_for_length(BOX, 1e-6).unwrap(), [255, 255, 255]);
        assert!(grid_for_length(BOX, 0.0).is_err());
        assert!(grid_for_length(BOX, f64::NAN).is_err());
    }

    #[test]
    fn grid_for_target_beam_count_lands_near_target() {
        for target in [1_000u64, 50_000, 154_728, 500_000] {
            let g = grid_for_beam_count(BOX, target).unwrap();
            let n = beam_count_for_grid(g) as f64;
            let ratio = n / target as f64;
            assert!((0.5..2.0).contains(&ratio), "target {target}: grid {g:?} gives {n}");
        }
    }

    #[test]
    fn invalid_sections_are_refused_with_reasons() {
        let k = SectionKind::Interior;
        assert!(matches!(
            Section::new([f64::NAN, 0.0, 0.0], BOX, [1, 1, 1], k),
            Err(SectionError::NonFinite { what: "origin", .. })
        ));
        let flat = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
        assert!(matches!(
            Section::new([0.0; 3], flat, [1, 1, 1], k),
            Err(SectionError::Degenerate(_))
        ));
        assert!(matches!(
            Section::new([0.0; 3], BOX, [0, 1, 1], k),
            Err(SectionError::GridOutOfRange { axis: 0, size: 0 })
        ));
        assert!(matches!(
            Section::new([0.0; 3], BOX, [256, 1, 1], k),
            Err(SectionError::GridOutOfRange { axis: 0, size: 256 })
        ));
        let err = Section::new([0.0; 3], BOX, [255, 255, 255], k).unwrap_err();
        assert!(err.to_string().contains("coarser grid"), "{err}");
    }

    #[test]
    fn sections_must_be_of_sane_size_range_and_shape() {
        let k = SectionKind::Interior;
        let scaled = |s: f64| BOX.map(|a| a.map(|c| c * s));
        // 10 x 6 x 3 scaled to the bounds: the 3 and the 10 reach them.
        assert!(Section::new([0.0; 3], scaled(MIN_AXIS_LENGTH / 3.0), [4, 4, 4], k).is_ok());
        assert!(Section::new([0.0; 3], scaled(MAX_AXIS_LENGTH / 10.0), [4, 4, 4], k).is_ok());
        let tiny = [[1e-30, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert_eq!(
            Section::new([0.0; 3], tiny, [1, 1, 1], k),
            Err(SectionError::AxisLength { axis: 0, length: 1e-30 })
        );
        let huge = Section::new([0.0; 3], scaled(1e30), [1, 1, 1], k).unwrap_err();
        assert!(matches!(huge, SectionError::AxisLength { axis: 0, .. }), "{huge:?}");
        // So long that its square overflows: still too long, not degenerate.
        let axes = [[1e155, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let e = grid_for_beam_count(axes, 1000).unwrap_err();
        assert!(
            matches!(e, SectionError::AxisLength { axis: 0, length } if length == 1e155),
            "{e:?}"
        );
        assert_eq!(huge.field(), Some(SectionField::Axis(0)));
        let far = Section::new([0.0, -2e7, 0.0], BOX, [1, 1, 1], k).unwrap_err();
        assert_eq!(
            far,
            SectionError::OriginOutOfRange {
                value: [0.0, -2e7, 0.0]
            }
        );
        assert_eq!(far.field(), Some(SectionField::Origin));
        // Nearly coplanar: the third axis rises 0.04 degrees out of the plane of the others.
        let sliver = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.001]];
        assert!(matches!(
            Section::new([0.0; 3], sliver, [1, 1, 1], k),
            Err(SectionError::Degenerate(_))
        ));
        let steep = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.01]];
        assert!(Section::new([0.0; 3], steep, [1, 1, 1], k).is_ok());
    }

    #[test]
    fn cells_must_span_256_single_precision_steps() {
        let k = SectionKind::Interior;
        let unit = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        // At 5e6 a cell must be at least 5e6 / 32768 = 152.6 long: one cell
        // of 1 unit is far too fine, far from it ...
        let e = Section::new([5e6, 0.0, 0.0], unit, [2, 1, 1], k).unwrap_err();
        let SectionError::TooFine {
            axis: 0,
            cell,
            magnitude,
        } = e
        else {
            panic!("{e:?}")
        };
        assert_eq!((cell, magnitude), (0.5, 5e6 + 1.0));
        assert!(e.to_string().contains("single precision"), "{e}");
        // ... while near the origin 255 cells across a millimeter are fine.
        let mm = unit.map(|a| a.map(|c| c * 1e-3));
        assert!(Section::new([0.0; 3], mm, [255, 255, 255], k)
            .is_err_and(|e| matches!(e, SectionError::TooManyBeams { .. })));
        assert!(Section::new([0.0; 3], mm, [32, 32, 32], k).is_ok());
        let wide = [[1000.0, 0.0, 0.0], [0.0, 1000.0, 0.0], [0.0, 0.0, 1000.0]];
        assert!(Section::new([5e6, 0.0, 0.0], wide, [4, 4, 4], k).is_ok());
    }

    #[test]
    fn grid_lines_cover_every_wall_line_once() {
        let s = Section::new([0.0; 3], BOX, [2, 3, 1], SectionKind::Interior).unwrap();
        let lines = s.grid_lines();
        // Lines along axis a: the boundary points of the other two axes' grid,
        // (gb+1)(gc+1) - (gb-1)(gc-1): 8 along x (3 by 1), 6 along y (1 by 2), 10 along z (2 by 3).
        assert_eq!(lines.len(), 8 + 6 + 10);
        let mut keys: Vec<String> = lines.iter().map(|l| format!("{:?}", l)).collect();
        keys.sort();
        keys.dedup();
        assert_eq!(keys.len(), lines.len(), "no line drawn twice");
        assert!(lines.iter().all(|[p, q]| s.contains(*p) && s.contains(*q)));
    }

    #[test]
    fn unit_frame_round_trips_on_sheared_sections() {
        let axes = [[3.0, 0.5, 0.0], [0.2, 2.0, 0.1], [0.0, -0.3, 1.5]];
        let s = Section::new([1.0, -2.0, 0.5], axes, [4, 4, 2], SectionKind::Exterior).unwrap();
        let p = DVec3::new(0.25, 0.5, 0.75);
        let back = s.world_to_unit(s.unit_to_world(p));
        assert!((back - p).length() < 1e-12);
        assert!(s.contains(s.unit_to_world(p)));
        assert!(!s.contains(s.unit_to_world(DVec3::new(1.01, 0.5, 0.5))));
    }
}
