//! Errors of scene import, generation and description files.

use std::path::PathBuf;

use crate::scene::material::{MaterialError, SkyError};
use glam::Vec3;
use holodeck_protocol::SectionError;

/// What went wrong building a scene, naming the file or mesh involved.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// A file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A file could not be parsed.
    #[error("{path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// What is wrong, and where in the file if known.
        message: String,
    },
    /// A mesh is inconsistent (indices out of range and the like).
    #[error("{what}: {message}")]
    Invalid {
        /// The mesh or file.
        what: String,
        /// What is wrong.
        message: String,
    },
    /// A material has impossible parameters.
    #[error("material {name:?}: {source}")]
    BadMaterial {
        /// Its name.
        name: String,
        /// What is wrong.
        source: MaterialError,
    },
    /// A material name added again with other parameters.
    #[error("material {0:?}: defined twice with different parameters")]
    MaterialRedefined(String),
    /// The sky has impossible parameters.
    #[error("{what}: {source}")]
    BadSky {
        /// Where the sky was written.
        what: String,
        /// Which key is wrong.
        source: SkyError,
    },
    /// A geometry entry's transform is impossible.
    #[error("{what}: {source}")]
    Transform {
        /// The geometry entry.
        what: String,
        /// Which key is wrong.
        source: TransformError,
    },
    /// A section table does not describe a valid section.
    #[error("{what}: {key}{source}", key = crate::scene::section::toml_key_prefix(source))]
    Section {
        /// The table (file and index) or the generated scene.
        what: String,
        /// Why.
        source: SectionError,
    },
    /// A scene could not be written as a scene file.
    #[error("{path}: {source}")]
    Export {
        /// The scene file.
        path: PathBuf,
        /// Why.
        source: ExportError,
    },
    /// A material name that is not defined.
    #[error("{what}: unknown material {name:?}; defined materials are: {known}")]
    UnknownMaterial {
        /// Where it was used.
        what: String,
        /// The name.
        name: String,
        /// The names that exist, comma-separated.
        known: String,
    },
    /// Faces that name no material, imported without a default material.
    #[error("{path}: {what} has no material; give the geometry a default `material`")]
    MissingMaterial {
        /// The file.
        path: PathBuf,
        /// Which faces (object, primitive or face index).
        what: String,
    },
    /// A file format this build cannot read.
    #[error("{path}: unsupported geometry format (use .obj, .ply, .gltf, .glb or .rad)")]
    UnsupportedFormat {
        /// The file.
        path: PathBuf,
    },
    /// A Radiance scene file that cannot be read (the error names its file and line).
    #[error(transparent)]
    Rad(Box<crate::scene::import::rad::error::RadError>),
}

/// Why a scene cannot be written as scene file text.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A table has a value TOML cannot hold (a NaN, say).
    #[error("{table} cannot be written as TOML: {source}")]
    Toml {
        /// Which table.
        table: &'static str,
        /// Why.
        source: toml::ser::Error,
    },
}

/// Why a `[[geometry]]` entry's transform is refused, naming the key.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum TransformError {
    /// `scale` with a zero, NaN or infinite factor.
    #[error("scale {0} must be finite and non-zero")]
    Scale(Vec3),
    /// `rotate` with a NaN or infinite angle.
    #[error("rotate {0} must be finite")]
    Rotate(Vec3),
    /// `translate` with a NaN or infinite offset.
    #[error("translate {0} must be finite")]
    Translate(Vec3),
    /// A `matrix` that is not a finite, invertible affine transform.
    #[error("matrix {0}")]
    Matrix(&'static str),
}
