//! The holodeck's measurements: every benchmark (`holodeck bench`), the
//! charts drawn from their results and from the demo (`holodeck chart`),
//! and the demo's measured walk (`holodeck demo`: a fill, every driver and
//! the direct renders along a walk, against references). The `holodeck`
//! command parses their arguments and calls them; a Rust program may call
//! them too. What they measure is in the libraries (`holodeck`: fills,
//! pictures from a file, references).
//!
//! * `bench` — one module per benchmark, each reporting beside a baseline of the same run; `bench all`, `bench compare`.
//! * `chart` — charts of the demo's walk and the driver grid.
//! * `demo` — the demo's walk, its methods, sheets and report.

#[macro_use]
extern crate holodeck_cli;

pub mod bench;
pub mod chart;
pub mod demo;
