//! What reading a Radiance file approximated or left out: one entry per kind
//! of approximation, with a count and the first place it happened, so a large
//! model gives a short report. Logged once per kind; never an error.

use super::error::Location;

/// A kind of approximation or omission.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum NoteKind {
    /// A pattern or texture (`brightfunc`, `colorpict`, `texfunc`, ...) was
    /// ignored: the materials it modifies keep their base color.
    PatternIgnored,
    /// A mixture (`mixfunc`, ...) was shown as its foreground material (its
    /// background where the foreground is `void`).
    MixtureForeground,
    /// An `illum` was shown as its alternate material.
    IllumAlternate,
    /// An `illum` without an alternate material is invisible, and its
    /// surfaces were left out.
    IllumInvisible,
    /// Surfaces whose modifier chain holds no material (`void`) are invisible
    /// in Radiance and were left out.
    VoidSurface,
    /// `mist` boundaries are invisible; their surfaces were left out.
    MistInvisible,
    /// A `trans` (or `trans2`) material was shown as opaque plastic: its
    /// transmitted light is dropped.
    TransOpaque,
    /// A `dielectric`'s transmission per unit length was taken as the tint of
    /// its surfaces, and its Hartmann constant (dispersion) ignored.
    DielectricTint,
    /// A `metal` with a specular fraction below 1 lost its diffuse part.
    MetalDiffuse,
    /// A `glow`'s maximum radius of influence was ignored: it lights the
    /// whole scene.
    GlowRadius,
    /// A `spotlight` emits into the whole hemisphere: its beam is ignored.
    SpotlightBeam,
    /// An anisotropic material (`plastic2`, `metal2`, `trans2`) was made
    /// isotropic with the mean of its two roughnesses.
    Anisotropic,
    /// A reflectance or transmittance outside [0, 1] was clamped into it.
    ColorClamped,
    /// A negative emitted radiance was set to zero.
    NegativeLight,
    /// A negative radius turned a surface inside out (as in Radiance).
    NegativeRadius,
    /// A polygon of zero area was left out.
    ZeroArea,
    /// A polygon too twisted or too large to ear-clip was fanned from its
    /// first vertex.
    Fanned,
    /// A `glow` source covering a hemisphere became the sky's color there
    /// (uniform: its patterns are ignored).
    GlowSky,
    /// Glow sources under different sky distributions: the first shapes the whole sky.
    SkyDistributions,
}

impl NoteKind {
    /// One line saying what was done.
    pub fn summary(self) -> &'static str {
        match self {
            NoteKind::PatternIgnored => "patterns and textures not read are ignored; materials keep their base color",
            NoteKind::MixtureForeground => "mixtures are shown as their foreground material",
            NoteKind::IllumAlternate => "illum is shown as its alternate material",
            NoteKind::IllumInvisible => "illum without an alternate material is invisible; its surfaces are left out",
            NoteKind::VoidSurface => "surfaces without a material (void) are invisible and left out",
            NoteKind::MistInvisible => "mist boundaries are invisible and left out",
            NoteKind::TransOpaque => "trans is shown as opaque plastic; transmitted light is dropped",
            NoteKind::DielectricTint => {
                "dielectric transmission per unit length is used as a surface tint; dispersion is ignored"
            }
            NoteKind::MetalDiffuse => "metal's diffuse part (1 - specularity) is dropped",
            NoteKind::GlowRadius => "glow's maximum radius is ignored; it lights the whole scene",
            NoteKind::SpotlightBeam => "spotlight's beam is ignored; it emits into the whole hemisphere",
            NoteKind::Anisotropic => "anisotropic materials use the mean of their two roughnesses",
            NoteKind::ColorClamped => "reflectances outside [0, 1] are clamped",
            NoteKind::NegativeLight => "negative emitted radiance is set to zero",
            NoteKind::NegativeRadius => "a negative radius turns the surface inside out",
            NoteKind::ZeroArea => "polygons of zero area are left out",
            NoteKind::Fanned => "polygons that could not be ear-clipped are fanned from their first vertex",
            NoteKind::GlowSky => "glow sources without a sky distribution become a uniform sky color",
            NoteKind::SkyDistributions => {
                "glow sources under different sky distributions: the first shapes the whole sky"
            }
        }
    }
}

/// Every occurrence of one kind of approximation.
#[derive(Clone, Debug, PartialEq)]
pub struct RadNote {
    /// What was approximated.
    pub kind: NoteKind,
    /// How many times.
    pub count: u64,
    /// Where it first happened.
    pub first: Location,
    /// What it was the first time (the primitive's type and identifier).
    pub detail: String,
}

/// What reading a Radiance file (with everything it includes) approximated.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RadReport {
    /// One entry per kind, in the order first met.
    pub notes: Vec<RadNote>,
}

impl RadReport {
    /// Counts one occurrence of `kind` at `at`; `detail` is kept for the first.
    pub(super) fn note(&mut self, kind: NoteKind, at: &Location, detail: impl FnOnce() -> String) {
        match self.notes.iter_mut().find(|n| n.kind == kind) {
            Some(n) => n.count += 1,
            None => self.notes.push(RadNote {
                kind,
                count: 1,
                first: at.clone(),
                detail: detail(),
            }),
        }
    }

    /// How many times `kind` happened.
    pub fn count(&self, kind: NoteKind) -> u64 {
        self.notes.iter().find(|n| n.kind == kind).map_or(0, |n| n.count)
    }

    /// Adds one import note per kind to the scene `b` builds, naming the
    /// file `path` (loading a scene says them once: a summary line, each
    /// with `-v`).
    pub fn note_into(&self, b: &mut crate::scene::SceneBuilder, path: &std::path::Path) {
        for n in &self.notes {
            let what = format!("{}: {} ({}; {} in all)", n.first, n.kind.summary(), n.detail, n.count);
            b.note(&path.display().to_string(), None, what);
        }
    }
}
