//! The demo's stages, for any program that wants to walk and measure as
//! `holodeck demo` does: the walk through the built-in room and out across the
//! scenery beyond its window ([`walk::path`]), and the ways a view is drawn and scored ([`methods`]:
//! every display driver, raw and denoised, and a direct render given the
//! same time, raw and cleaned by Open Image Denoise). The fill is
//! [`crate::fill()`], the references [`crate::truth`]; `holodeck-bench`
//! runs the stages in order and writes the sheets, charts and report.
//!
//! * `methods` — the ways of drawing a view, their shots and columns.
//! * `walk` — the walk's views.

pub mod methods;
pub mod walk;
