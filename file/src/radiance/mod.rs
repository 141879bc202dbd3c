//! Radiance holodecks (`rholo`'s `.hdk` files): reading them into holodeck
//! files and writing holodeck files back out in Radiance's layout, so that
//! people can move between the two without retracing a ray.
//!
//! Radiance writes raw C structs in the writer's byte order: a text header of
//! `rholo` variables, a 4-byte magic number that also gives the size of a
//! directory entry, then a chain of sections, each a pointer to the next, the
//! section's grid (origin, three axis vectors, three cell counts) and one
//! (ray count, file offset) entry per beam. Beams are runs of the same 10-byte
//! records this program stores; only Radiance's beam numbering and depth
//! scale differ, so rays carry over byte for byte (see [`layout`] and
//! [`numbering`]).

pub mod error;
pub mod export;
pub mod header;
pub mod import;
pub mod layout;
pub mod numbering;
pub mod source;

pub use error::RadianceError;
pub use export::{export, ExportReport};
pub use import::{import, ImportOptions, ImportReport, RadianceFile};
pub use layout::{ByteOrder, Layout};
