//! Errors of scene import, generation and description files.

use std::path::PathBuf;

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
    #[error("material {name:?}: {message}")]
    BadMaterial {
        /// Its name.
        name: String,
        /// What is wrong.
        message: String,
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
    #[error("{path}: unsupported geometry format (use .obj, .ply, .gltf or .glb)")]
    UnsupportedFormat {
        /// The file.
        path: PathBuf,
    },
}
