//! What the commands that trace accept as a scene: a scene file, a built-in
//! generator, or a built scene file (`.hds`) traced out of core through a
//! block cache of `--scene-memory` bytes.

use std::path::Path;
use std::sync::Arc;

use holodeck_protocol::Section;
use holodeck_sampler::ooc::{is_scene_file, OocScene};
use holodeck_sampler::scene::file::load_scene;
use holodeck_sampler::scene::gen::{generate, GenParams};
use holodeck_sampler::scene::hash::content_hash;
use holodeck_sampler::{Scene, TraceOptions, Tracer};

use crate::Error;

/// A view from inside the built-in room (`builtin:room`) toward its window:
/// the view the commands and benchmarks use when none is given.
pub const ROOM_VIEW: &str = "-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56";

/// Fetcher threads that load blocks of a scene file.
pub const FETCHERS: usize = 2;

/// A scene ready to become a tracer.
pub enum SceneInput {
    /// Triangles in memory.
    InCore(Box<Scene>),
    /// An open scene file.
    File(Arc<OocScene>),
}

impl SceneInput {
    /// Loads `spec`: a `.hds` file opens with a cache of `memory` bytes (all of
    /// its blocks if not given); anything else loads into memory.
    pub fn open(spec: &str, triangles: Option<u64>, memory: Option<u64>) -> Result<SceneInput, Error> {
        let path = Path::new(spec);
        if !spec.starts_with("builtin:") && is_scene_file(path) {
            let budget = memory.map(|m| usize::try_from(m).unwrap_or(usize::MAX));
            let ooc = OocScene::open(path, budget, FETCHERS).map_err(|source| Error::SceneFile {
                spec: spec.to_string(),
                source: Box::new(source),
            })?;
            tracing::info!(
                "{spec}: {} triangles in {} blocks ({} MB decompressed), cache {} MB",
                ooc.header().triangles,
                ooc.header().blocks,
                ooc.header().decompressed_bytes >> 20,
                ooc.cache().budget() >> 20
            );
            return Ok(SceneInput::File(Arc::new(ooc)));
        }
        Ok(SceneInput::InCore(Box::new(load(spec, triangles)?)))
    }

    /// The scene's content hash.
    pub fn hash(&self) -> String {
        match self {
            SceneInput::InCore(s) => content_hash(s),
            SceneInput::File(f) => f.header().content_hash.clone(),
        }
    }

    /// The sections the scene defines.
    pub fn sections(&self) -> &[Section] {
        match self {
            SceneInput::InCore(s) => &s.sections,
            SceneInput::File(f) => &f.header().sections,
        }
    }

    /// Triangles in the scene.
    pub fn triangles(&self) -> u64 {
        match self {
            SceneInput::InCore(s) => s.triangles.len() as u64,
            SceneInput::File(f) => f.header().triangles,
        }
    }

    /// The tracer (builds the kd-tree of an in-core scene). A scene file is
    /// assembled in memory when its cache budget holds every block, memory
    /// allows, and LOD is off; otherwise it is traced out of core.
    pub fn tracer(self, options: TraceOptions) -> Tracer {
        self.tracer_with(options, true)
    }

    /// [`SceneInput::tracer`], with the choice to assemble a scene file in
    /// memory when it fits (`in_core`) or always trace it out of core.
    pub fn tracer_with(self, options: TraceOptions, in_core: bool) -> Tracer {
        match self {
            SceneInput::InCore(s) => Tracer::new(*s, options),
            SceneInput::File(f) => {
                let lod = options.lod_primary > 0.0 || options.lod_secondary > 0.0;
                if in_core && !lod && f.fits_in_core() {
                    match Tracer::in_core_from_file(&f, options) {
                        Ok(t) => {
                            if let Some(r) = t.assembled() {
                                tracing::info!(
                                    "scene file assembled in memory: {} blocks, {} MB, {} nodes, {:.2} s",
                                    r.blocks,
                                    r.bytes >> 20,
                                    r.nodes,
                                    r.seconds
                                );
                            }
                            return t;
                        }
                        Err(e) => tracing::warn!("scene file not assembled in memory ({e}); tracing it out of core"),
                    }
                }
                Tracer::out_of_core(f, options)
            }
        }
    }
}

/// Loads a scene file or generates a built-in one.
pub fn load(spec: &str, triangles: Option<u64>) -> Result<Scene, Error> {
    if let Some(name) = spec.strip_prefix("builtin:") {
        let params = GenParams {
            triangles,
            ..GenParams::default()
        };
        return generate(name, &params).map_err(|source| Error::Generate {
            name: name.to_string(),
            source: Box::new(source),
        });
    }
    load_scene(Path::new(spec)).map_err(|source| Error::LoadScene {
        spec: spec.to_string(),
        source: Box::new(source),
    })
}
