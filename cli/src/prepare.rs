//! Opening a scene's holodeck file for the commands that fill one (`fill`,
//! `run`, the demo and the benchmarks): the library's `prepare`, with what
//! it found said to the user.

use std::path::Path;

use anyhow::Result;
use holodeck::{PrepareOptions, SceneInput};
use holodeck_file::HoloFile;
use holodeck_protocol::{Section, SectionKind};
use holodeck_sampler::scene::section_fit::{cut, Cut};
use holodeck_sampler::Scene;

use crate::human::count;
use crate::note;

/// Loads a scene and opens its holodeck file for writing (see
/// `holodeck::prepare`): says when a file that recorded no scene is
/// continued with this one, and warns of sections that cut the scene.
pub fn prepare(
    scene_spec: &str,
    path: &Path,
    triangles: Option<u64>,
    scene_memory: Option<u64>,
    accept_loss: bool,
    vdistance: bool,
) -> Result<(SceneInput, HoloFile)> {
    let options = PrepareOptions {
        triangles,
        scene_memory,
        accept_loss,
        vdistance,
    };
    let p = holodeck::prepare(scene_spec, path, &options)?;
    if let Some(rays) = p.adopted {
        note!(
            "{} recorded no scene (an imported Radiance holodeck?): it now records {scene_spec} ({}), \
             and its {} rays are taken as traced in it",
            path.display(),
            p.scene.hash(),
            count(rays)
        );
    }
    for line in cut_lines(&p.cuts, &p.file.settings().sections) {
        tracing::warn!("{}: {line}", path.display());
    }
    Ok((p.scene, p.file))
}

/// One line per section of `sections` that cuts geometry of `scene`: how
/// many triangles, and where.
pub fn section_cuts(scene: &Scene, sections: &[Section]) -> Vec<String> {
    let cuts: Vec<(usize, Cut)> = (sections.iter().enumerate())
        .filter_map(|(k, sec)| cut(scene, sec).map(|c| (k, c)))
        .collect();
    cut_lines(&cuts, sections)
}

/// The lines that say where sections cut geometry.
fn cut_lines(cuts: &[(usize, Cut)], sections: &[Section]) -> Vec<String> {
    cuts.iter()
        .map(|(k, c)| {
            let (lo, hi) = c.bounds;
            let what = match sections.get(*k).map(Section::kind) {
                Some(SectionKind::Exterior) => "cross the walls of exterior",
                _ => "reach into interior",
            };
            format!(
                "{} triangles {what} section {k}, between x {:.3} .. {:.3}, y {:.3} .. {:.3}, z {:.3} .. {:.3} m: \
                 they draw as black wedges; `holodeck scene section` proposes a section that fits",
                count(c.triangles),
                lo.x,
                hi.x,
                lo.y,
                hi.y,
                lo.z,
                hi.z
            )
        })
        .collect()
}
