//! The holodeck as a library: what the `holodeck` command does, for Rust
//! programs. Load a scene from any supported input ([`SceneInput`]: scene
//! files, models, Radiance scenes, `builtin:` generators, out-of-core `.hds`
//! files), fill a holodeck file with its rays in this process ([`fill()`]),
//! draw pictures from a file with any display driver ([`recall()`]), and
//! measure them against converged references ([`truth::Truth`]).
//! `examples/fill_and_draw.rs` does all three in a page.
//!
//! * `demo` — the demo's stages: its walk, and the ways a view is drawn and scored.
//! * `fill` — a batch fill in one process: the schedule picks beams, the cores trace them, the file keeps the rays.
//! * `prepare` — a scene and its file made ready to fill: created, adopted or refused.
//! * `recall` — pictures from a file: the beams a view sees, read, decoded and handed to a driver.
//! * `replay` — a file replayed into the walkthrough window (feature `window`).
//! * `scene_input` — what the commands that trace accept as a scene.
//! * `site` — a file as a static web site's data, for the web display's replay.
//! * `truth` — converged reference pictures in two halves that state their own noise, and direct renders.

pub mod demo;
pub mod fill;
pub mod prepare;
pub mod recall;
#[cfg(feature = "window")]
pub mod replay;
pub mod scene_input;
pub mod site;
pub mod truth;

pub use fill::{fill, FillOptions, FillReport, ViewFill};
pub use prepare::{prepare, PrepareOptions, Prepared};
pub use recall::{recall, DriverChoice, Recalled};
pub use scene_input::{load, SceneInput, ROOM_VIEW};

/// Why a library call failed.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An out-of-core scene file could not be opened.
    #[error("opening scene file {spec}")]
    SceneFile {
        /// The file as given.
        spec: String,
        /// Why.
        #[source]
        source: Box<holodeck_sampler::ooc::OocError>,
    },
    /// A built-in scene could not be generated.
    #[error("generating builtin:{name}")]
    Generate {
        /// The generator's name.
        name: String,
        /// Why.
        #[source]
        source: Box<holodeck_sampler::SceneError>,
    },
    /// A scene could not be loaded.
    #[error("loading scene {spec}")]
    LoadScene {
        /// The scene as given.
        spec: String,
        /// Why.
        #[source]
        source: Box<holodeck_sampler::SceneError>,
    },
    /// A new file needs sections, and the scene defines none.
    #[error("scene {spec} defines no holodeck section; add [[section]] tables to it")]
    NoSections {
        /// The scene as given.
        spec: String,
    },
    /// The file holds rays of another scene.
    #[error("{} holds rays of another scene ({held}); this scene is {scene}. Use a new file.", path.display())]
    OtherScene {
        /// The file.
        path: std::path::PathBuf,
        /// The scene it records.
        held: String,
        /// This scene.
        scene: String,
    },
    /// The holodeck file refused or failed.
    #[error(transparent)]
    Storage(#[from] holodeck_file::StorageError),
    /// The file's sections cannot be scheduled.
    #[error(transparent)]
    Sections(#[from] holodeck_protocol::SectionError),
    /// No driver could be made for the view.
    #[error(transparent)]
    Driver(#[from] holodeck_display::DriverError),
    /// A reference or direct render failed.
    #[error(transparent)]
    Render(#[from] holodeck_sampler::render::RenderError),
    /// A picture cannot be measured against its reference.
    #[error(transparent)]
    Compare(#[from] holodeck_display::compare::CompareError),
    /// A denoiser failed (or is not in this build).
    #[error(transparent)]
    Denoise(#[from] holodeck_display::denoise::DenoiseError),
    /// A picture size is impossible.
    #[error(transparent)]
    PictureSize(#[from] holodeck_protocol::PictureSizeError),
}
