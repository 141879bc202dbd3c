//! A scene and its holodeck file, ready to fill: the file created from the
//! scene's sections where it does not exist, a file made for another scene
//! refused, a file that records no scene (an imported Radiance holodeck, or
//! one made without a scene) adopted, and the sections that cut the scene's
//! geometry found.

use std::path::Path;

use holodeck_file::{HoloFile, OpenOptions, Settings, StorageError};
use holodeck_sampler::scene::section_fit::{cut, Cut};

use crate::{Error, SceneInput};

/// How [`prepare`] loads the scene and opens the file.
#[derive(Clone, Copy, Debug, Default)]
pub struct PrepareOptions {
    /// Triangles of a generated scene (its default where `None`).
    pub triangles: Option<u64>,
    /// For a `.hds` scene file: decompressed blocks kept in memory (all where `None`).
    pub scene_memory: Option<u64>,
    /// Write on top of a file whose newest commit is damaged, losing what
    /// cannot be read.
    pub accept_loss: bool,
    /// For a new file: record virtual distances through windows and mirrors.
    pub vdistance: bool,
}

/// What [`prepare`] made ready.
pub struct Prepared {
    /// The scene.
    pub scene: SceneInput,
    /// Its file, open for writing.
    pub file: HoloFile,
    /// Where the file recorded no scene and now records this one: the rays
    /// it held, now taken as traced in this scene.
    pub adopted: Option<u64>,
    /// The sections (by index) that cut the scene's geometry (in-core
    /// scenes only): those triangles draw as black wedges.
    pub cuts: Vec<(usize, Cut)>,
}

/// Loads the scene `scene_spec` and opens its holodeck file `path` for
/// writing, creating it from the scene's sections if it does not exist. Of
/// two processes creating the same file at once, one creates it and the
/// other opens it (or is told it is in use).
pub fn prepare(scene_spec: &str, path: &Path, o: &PrepareOptions) -> Result<Prepared, Error> {
    let scene = SceneInput::open(scene_spec, o.triangles, o.scene_memory)?;
    let hash = scene.hash();
    if !path.exists() {
        if scene.sections().is_empty() {
            return Err(Error::NoSections {
                spec: scene_spec.to_string(),
            });
        }
        let settings = Settings {
            sections: scene.sections().to_vec(),
            scene: Some(hash.clone()),
            vdistance: o.vdistance,
            ..Settings::default()
        };
        match HoloFile::create(path, &settings) {
            // Another process created it first: open what it made.
            Ok(()) | Err(StorageError::Exists { .. }) => {}
            Err(e) => return Err(e.into()),
        }
    }
    let options = OpenOptions {
        accept_loss: o.accept_loss,
        ..OpenOptions::default()
    };
    let mut file = HoloFile::open(path, &options)?;
    let mut adopted = None;
    if file.settings().scene.is_none() {
        file.set_scene(&hash, false)?;
        adopted = Some(file.summary().rays()).filter(|&r| r > 0);
    }
    let cuts = match &scene {
        SceneInput::InCore(s) => (file.settings().sections.iter().enumerate())
            .filter_map(|(k, sec)| cut(s, sec).map(|c| (k, c)))
            .collect(),
        SceneInput::File(_) => Vec::new(),
    };
    if let Some(h) = &file.settings().scene {
        if *h != hash {
            return Err(Error::OtherScene {
                path: path.to_path_buf(),
                held: h.clone(),
                scene: hash,
            });
        }
    }
    Ok(Prepared {
        scene,
        file,
        adopted,
        cuts,
    })
}
