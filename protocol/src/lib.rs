//! Holodeck protocol: the shared vocabulary of every holodeck process.
//!
//! This crate holds section geometry ([`Section`]), the bijection between beam
//! indices and pairs of wall cells ([`beam`]), and the 10-byte ray record
//! ([`RayRecord`]) with its RGBE color ([`Rgbe`]) and 16-bit depth code
//! ([`DepthCode`]). It is pure data and arithmetic: it must never touch files,
//! sockets or clocks, so that the storage engine, the samplers and the displays
//! all agree on the same bits. The one exception is [`wire::client`], the
//! blocking client socket every peer connects with.
//!
//! * `beam` — beam indices and the wall cells they join.
//! * `depth` — the 16-bit depth code.
//! * `picture` — linear HDR pictures and their size limits.
//! * `record` — the 10-byte ray record and its decoder.
//! * `rgbe` — Ward's shared-exponent colour.
//! * `section` — section geometry, its walls, grids and text form.
//! * `select` — which beams a view sees, and how much.
//! * `site` — the index of a holodeck exported as a static web site.
//! * `view` — Radiance views, parsed and written.
//! * `wire` — messages, framing, links and the blocking client.

pub mod beam;
pub mod depth;
pub mod picture;
pub mod record;
pub mod rgbe;
pub mod section;
pub mod select;
pub mod site;
pub mod view;
pub mod wire;

pub use beam::{BeamIndex, BeamKey, BeamRay, CellPair, LocatedRay, WallCell};
pub use depth::{DepthCode, DepthCoding};
pub use picture::{check_size as check_picture_size, Picture, PictureSizeError, MAX_PICTURE_PIXELS, MAX_PICTURE_SIDE};
pub use record::{BeamDecoder, DecodedRay, Hit, RayRecord, RAY_RECORD_BYTES};
pub use rgbe::Rgbe;
pub use section::{
    beam_count_for_grid, eye_radius, grid_for_beam_count, grid_for_length, Section, SectionError, SectionField,
    SectionKind, SectionSpec, SectionTextError, Wall, DEFAULT_BEAMS, MAX_AXIS_LENGTH, MAX_BEAMS_PER_SECTION,
    MAX_COORDINATE, MAX_GRID, MIN_AXIS_LENGTH, MIN_CELL_FRACTION, MIN_VOLUME_RATIO,
};
pub use select::ViewBeams;
pub use view::{Frustum, View, ViewError, ViewProjector, ViewRays, ViewType};
