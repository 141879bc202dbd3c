//! Radiance modifiers: materials converted to ours, and the chains of names
//! that lead from a surface to its material. A name refers to its latest
//! definition at the time it is used, as in Radiance, so every modifier is
//! resolved the moment it is defined: what a surface using it shows, a
//! material, nothing (a chain that ends in `void`), or a type this reader
//! does not convert (an error only if a surface uses it).
//!
//! Conversions (colors clamped into [0, 1] except emitted radiance, which is
//! W/sr/m² in both and carried over unchanged):
//! * `plastic r g b spec rough`: plastic with albedo rgb and a coat whose
//!   normal-incidence reflectance is spec (ior (1+√spec)/(1−√spec), spec at
//!   most 0.9), roughness √rough (Radiance's rough is the rms facet slope,
//!   which is GGX's alpha); spec 0 gives a lambertian.
//! * `metal r g b spec rough`: metal of color rgb, roughness √rough; the
//!   diffuse part 1 − spec is dropped.
//! * `trans r g b spec rough trans tspec`: opaque plastic of albedo
//!   rgb·(1 − trans); transmitted light is dropped.
//! * `glass r g b [n]`: thin glass (a pane; rays are not bent), tint rgb,
//!   ior n (1.52 when not given).
//! * `dielectric r g b n hc`: solid glass, tint rgb, ior n; hc ignored.
//! * `mirror r g b`: mirror of color rgb (its alternate material is for
//!   Radiance's light calculation only and is ignored).
//! * `light`, `glow`, `spotlight`: emitters of radiance rgb (glow's radius
//!   and the spotlight's beam ignored).
//! * `illum`: its alternate material, or invisible without one.
//! * `plastic2`, `metal2`, `trans2`: as the isotropic ones, with the mean of
//!   the two roughnesses.
//! * `mist`: invisible. Patterns: the sky distributions of gensky
//!   (`brightfunc skybr skybright.cal`) and gendaylit (`brightfunc skybright
//!   perezlum.cal`) on `glow` sources shape the sky; `colorpict` pictures
//!   mapped by `picture.cal` colour the material; `colorfunc`, `brightfunc`,
//!   `texfunc`, `brightdata` and `colordata` are evaluated at every hit
//!   (see `functions.rs` and `crate::scene::pattern`), on lights too (an
//!   IES distribution from ies2rad). Other patterns and textures, and
//!   those whose files cannot be read, are ignored (noted, with why): the
//!   material keeps its base color. Mixtures: their foreground (background
//!   if `void`).
//! * Other materials (`BRTDfunc`, `BSDF`, `plasfunc`, `antimatter`, ...):
//!   refused where a surface uses them.

use std::collections::HashMap;

use super::error::{Location, RadError, RadErrorKind};
use super::functions::{is_function_pattern, FunctionFiles};
use super::parse::Primitive;
use super::report::{NoteKind, RadReport};
use crate::scene::material::Material;
use crate::scene::pattern::Pattern;
use crate::scene::sky_distribution::{CieSky, SkyDistribution};

/// Radiance's index of refraction for `glass` without one.
const GLASS_IOR: f64 = 1.52;

/// Pattern and texture types: they change a material's color or normal,
/// which is ignored here.
const PATTERNS: [&str; 14] = [
    "texfunc",
    "texdata",
    "brightfunc",
    "brightdata",
    "brighttext",
    "colorpict",
    "colorfunc",
    "colordata",
    "colortext",
    "spectrum",
    "specfile",
    "specfunc",
    "specdata",
    "specpict",
];

/// Mixture types: the first two strings name the materials mixed.
const MIXTURES: [&str; 4] = ["mixfunc", "mixdata", "mixtext", "mixpict"];

/// Radiance materials this reader does not convert.
const UNSUPPORTED: [&str; 15] = [
    "interface",
    "plasfunc",
    "metfunc",
    "transfunc",
    "BRTDfunc",
    "BSDF",
    "aBSDF",
    "WGMDfunc",
    "plasdata",
    "metdata",
    "transdata",
    "antimatter",
    "prism1",
    "prism2",
    "ashik2",
];

/// What a surface with a given modifier shows.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Resolved {
    /// The material in slot `.0` of [`Modifiers::slots`].
    Material(usize),
    /// Nothing: the surface is left out, and why.
    Invisible(NoteKind),
    /// A material type not converted.
    Unsupported {
        /// The material's name.
        name: String,
        /// Its type.
        kind: String,
        /// Where it is defined.
        at: Location,
    },
}

/// What kind of light a material is (for distant `source`s).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum LightKind {
    /// Not a light.
    None,
    /// `light`: a source for the sun.
    Light,
    /// `glow`: a source for the sky.
    Glow,
    /// `spotlight`.
    Spot,
}

/// One converted material definition.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Slot {
    /// Its Radiance name.
    pub name: String,
    /// Ours.
    pub material: Material,
    /// What kind of light it is.
    pub light: LightKind,
    /// Where it is defined.
    pub at: Location,
    /// The sky distribution that modifies it (a `glow` under gensky's or
    /// gendaylit's `skyfunc`).
    pub sky: Option<SkyDistribution>,
    /// The picture that colours it (a `colorpict` over `picture.cal`).
    pub picture: Option<Picture>,
    /// The function and data patterns that modify it, outermost last.
    pub patterns: Vec<Pattern>,
}

/// A `colorpict` pattern with `picture.cal`'s coordinates: the image
/// lies on the pattern's xy plane, lower left corner at the origin, its
/// smaller side 1 long.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Picture {
    /// The image file, as written (relative to the file that names it).
    pub file: String,
    /// The directory of the file that names it.
    pub dir: std::path::PathBuf,
    /// World (first file's frame) to the pattern's frame.
    pub inverse: glam::DMat4,
    /// How coordinates beyond the image read: `pic_u` clamps, `tile_u`
    /// repeats, `match_u` mirrors.
    pub wrap: crate::scene::texture::Wrap,
}

/// The modifiers defined so far.
#[derive(Default)]
pub(super) struct Modifiers {
    /// Each name's latest definition, resolved.
    names: HashMap<String, Resolved>,
    /// Sky brightness patterns by name (`brightfunc` over `skybright.cal`
    /// or `perezlum.cal`).
    skies: HashMap<String, SkyDistribution>,
    /// Picture patterns by name (`colorpict` over `picture.cal`).
    pictures: HashMap<String, Picture>,
    /// Function and data patterns by name, each with the chain of
    /// patterns that modify it.
    patterns: HashMap<String, Vec<Pattern>>,
    /// The function and data files read.
    files: FunctionFiles,
    /// Every material definition, in file order.
    pub slots: Vec<Slot>,
}

impl Modifiers {
    /// What a surface whose modifier is `name` shows.
    pub(super) fn lookup(&self, name: &str, at: &Location) -> Result<Resolved, RadError> {
        if name == "void" {
            return Ok(Resolved::Invisible(NoteKind::VoidSurface));
        }
        self.names.get(name).cloned().ok_or_else(|| {
            let name = name.to_string();
            RadError::new(at, RadErrorKind::UndefinedModifier { name })
        })
    }

    /// Defines `p` if it is a modifier (material, pattern, texture, mixture or
    /// alias) and returns true; false for anything else (surfaces, unknown types).
    /// `dir` is the directory of the file that defines it, `placed` the
    /// transform that places that file (its `!xform` commands): patterns
    /// move with the file, as `xform` moves them in Radiance.
    pub(super) fn define(
        &mut self,
        p: &Primitive,
        at: &Location,
        dir: &std::path::Path,
        placed: &glam::DMat4,
        report: &mut RadReport,
    ) -> Result<bool, RadError> {
        let kind = p.kind.as_str();
        let is_modifier = kind == "alias"
            || PATTERNS.contains(&kind)
            || MIXTURES.contains(&kind)
            || UNSUPPORTED.contains(&kind)
            || matches!(kind, "illum" | "mist")
            || convertible(kind);
        if !is_modifier {
            return Ok(false);
        }
        if p.name == "void" || p.name == "inherit" {
            let name = p.name.clone();
            return Err(RadError::new(at, RadErrorKind::ReservedName { name }));
        }
        let resolved = if kind == "alias" {
            let target = p.strings.first().map_or("", String::as_str);
            self.lookup(target, at)?
        } else if PATTERNS.contains(&kind) {
            self.define_pattern(p, at, dir, placed, report)?
        } else if MIXTURES.contains(&kind) {
            let [fore, back] = match &p.strings[..] {
                [fore, back, ..] => [fore, back],
                _ => return Err(count_error(p, at, "2 or more strings (foreground, background, ...)")),
            };
            report.note(NoteKind::MixtureForeground, at, || p.what());
            match self.lookup(fore, at)? {
                Resolved::Invisible(_) => self.lookup(back, at)?,
                other => other,
            }
        } else if UNSUPPORTED.contains(&kind) {
            Resolved::Unsupported {
                name: p.name.clone(),
                kind: p.kind.clone(),
                at: at.clone(),
            }
        } else if kind == "illum" {
            check_reals(p, at, &[3], "3 reals")?;
            match p.strings.first() {
                Some(alt) => {
                    report.note(NoteKind::IllumAlternate, at, || p.what());
                    match self.lookup(alt, at)? {
                        Resolved::Invisible(NoteKind::VoidSurface) => Resolved::Invisible(NoteKind::IllumInvisible),
                        other => other,
                    }
                }
                None => Resolved::Invisible(NoteKind::IllumInvisible),
            }
        } else if kind == "mist" {
            Resolved::Invisible(NoteKind::MistInvisible)
        } else {
            self.define_material(p, at, report)?
        };
        self.names.insert(p.name.clone(), resolved);
        Ok(true)
    }

    /// Defines pattern `p`: a sky's distribution, a picture, or a function
    /// or data pattern (chained onto its modifier's), noted where ignored.
    /// Over a material, what it resolves to is that material pictured or
    /// patterned.
    fn define_pattern(
        &mut self,
        p: &Primitive,
        at: &Location,
        dir: &std::path::Path,
        placed: &glam::DMat4,
        report: &mut RadReport,
    ) -> Result<Resolved, RadError> {
        self.skies.remove(&p.name);
        self.pictures.remove(&p.name);
        self.patterns.remove(&p.name);
        if let Some(sky) = sky_pattern(p, at)? {
            self.skies.insert(p.name.clone(), sky);
        } else if let Some(picture) = picture_pattern(p, at, dir, placed)? {
            self.pictures.insert(p.name.clone(), picture);
        } else if is_function_pattern(&p.kind) {
            match self.files.pattern(p, dir, placed) {
                Ok(pattern) => {
                    let mut chain = self.patterns.get(&p.modifier).cloned().unwrap_or_default();
                    chain.push(pattern);
                    self.patterns.insert(p.name.clone(), chain);
                }
                Err(why) => {
                    tracing::warn!("{at}: {}: {why}; the pattern is ignored", p.what());
                    report.note(NoteKind::PatternIgnored, at, || format!("{}: {why}", p.what()));
                }
            }
        } else {
            report.note(NoteKind::PatternIgnored, at, || p.what());
        }
        let pattern = self.patterns.get(&p.name).and_then(|c| c.last());
        let resolved = match (self.lookup(&p.modifier, at)?, self.pictures.get(&p.name), pattern) {
            // A picture over a material (surface -> pattern -> material):
            // surfaces that name the pattern show the material pictured.
            (Resolved::Material(slot), Some(picture), _) => {
                let mut pictured = self.slots[slot].clone();
                pictured.picture = Some(picture.clone());
                self.slots.push(pictured);
                Resolved::Material(self.slots.len() - 1)
            }
            // The same for a function or data pattern.
            (Resolved::Material(slot), None, Some(pattern)) => {
                let mut patterned = self.slots[slot].clone();
                patterned.patterns.push(pattern.clone());
                self.slots.push(patterned);
                Resolved::Material(self.slots.len() - 1)
            }
            (resolved, ..) => resolved,
        };
        Ok(resolved)
    }

    /// Defines material `p` (converted, checked), with the sky, picture and
    /// patterns its modifier names.
    fn define_material(&mut self, p: &Primitive, at: &Location, report: &mut RadReport) -> Result<Resolved, RadError> {
        let (material, light) = convert(p, at, report)?;
        material.validate().map_err(|e| {
            let (what, message) = (p.what(), e.to_string());
            RadError::new(at, RadErrorKind::BadArguments { what, message })
        })?;
        let sky = match light {
            LightKind::Glow => self.skies.get(&p.modifier).cloned(),
            _ => None,
        };
        let picture = self.pictures.get(&p.modifier).cloned();
        let patterns = match light {
            // A sky's pattern shapes the sky; the glow itself is the sky.
            LightKind::Glow if sky.is_some() => Vec::new(),
            _ => self.patterns.get(&p.modifier).cloned().unwrap_or_default(),
        };
        self.slots.push(Slot {
            name: p.name.clone(),
            material,
            light,
            at: at.clone(),
            sky,
            picture,
            patterns,
        });
        Ok(Resolved::Material(self.slots.len() - 1))
    }
}

/// The sky distribution of a `brightfunc` over gensky's `skybright.cal`
/// (functions `skybr`, and the older `skybright`) or gendaylit's
/// `perezlum.cal` (`skybright`); `None` for any other pattern.
fn sky_pattern(p: &Primitive, at: &Location) -> Result<Option<SkyDistribution>, RadError> {
    if p.kind != "brightfunc" {
        return Ok(None);
    }
    let [function, file, ..] = &p.strings[..] else {
        return Ok(None);
    };
    let file = file.rsplit(['/', '\\']).next().unwrap_or(file);
    let r: Vec<f32> = p.reals.iter().map(|&v| v as f32).collect();
    let sky = match (file, function.as_str()) {
        ("skybright.cal", "skybr" | "skybright") => {
            if r.len() != 7 {
                return Err(count_error(
                    p,
                    at,
                    "7 reals: type zenith-brightness ground-brightness normalization sun-x sun-y sun-z",
                ));
            }
            let kind = if function == "skybright" {
                // The older function: a positive first argument is cloudy.
                if r[0] > 0.0 {
                    CieSky::Overcast
                } else {
                    CieSky::Clear
                }
            } else {
                match r[0].round() as i64 {
                    1 => CieSky::Clear,
                    2 => CieSky::Overcast,
                    3 => CieSky::Uniform,
                    4 => CieSky::Intermediate,
                    other => {
                        let (what, message) = (p.what(), format!("sky type {other} is not 1 to 4"));
                        return Err(RadError::new(at, RadErrorKind::BadArguments { what, message }));
                    }
                }
            };
            SkyDistribution::Cie {
                kind,
                zenith: r[1],
                ground: r[2],
                normalization: r[3],
                toward_sun: [r[4], r[5], r[6]],
            }
        }
        ("perezlum.cal", "skybright") => {
            if r.len() != 10 {
                return Err(count_error(
                    p,
                    at,
                    "10 reals: normalization ground-brightness a b c d e sun-x sun-y sun-z",
                ));
            }
            SkyDistribution::Perez {
                normalization: r[0],
                ground: r[1],
                coefficients: [r[2], r[3], r[4], r[5], r[6]],
                toward_sun: [r[7], r[8], r[9]],
            }
        }
        _ => return Ok(None),
    };
    sky.validate().map_err(|message| {
        let what = p.what();
        RadError::new(at, RadErrorKind::BadArguments { what, message })
    })?;
    Ok(Some(sky))
}

/// The picture of a `colorpict` that maps its image with `picture.cal`
/// (`red green blue` colour functions, `pic_u pic_v`, `tile_u tile_v` or
/// `match_u match_v` coordinates, then an optional transform, applied
/// within the file's own placement `placed`); `None` for any other pattern.
fn picture_pattern(
    p: &Primitive,
    at: &Location,
    dir: &std::path::Path,
    placed: &glam::DMat4,
) -> Result<Option<Picture>, RadError> {
    use crate::scene::texture::Wrap;
    if p.kind != "colorpict" || p.strings.len() < 7 {
        return Ok(None);
    }
    let s = &p.strings;
    let cal = s[4].rsplit(['/', '\\']).next().unwrap_or(&s[4]);
    if s[0..3] != ["red", "green", "blue"] || cal != "picture.cal" {
        return Ok(None);
    }
    let wrap = match (s[5].as_str(), s[6].as_str()) {
        ("pic_u", "pic_v") => Wrap::Clamp,
        ("tile_u", "tile_v") => Wrap::Repeat,
        ("match_u", "match_v") => Wrap::Mirror,
        _ => return Ok(None),
    };
    let transform = super::command::transform_args(&s[7..]).map_err(|kind| RadError::new(at, kind))?;
    Ok(Some(Picture {
        file: s[3].clone(),
        dir: dir.to_path_buf(),
        inverse: (*placed * transform).inverse(),
        wrap,
    }))
}

/// Whether `kind` is a material [`convert`] handles.
fn convertible(kind: &str) -> bool {
    matches!(
        kind,
        "plastic"
            | "metal"
            | "trans"
            | "plastic2"
            | "metal2"
            | "trans2"
            | "glass"
            | "dielectric"
            | "mirror"
            | "light"
            | "glow"
            | "spotlight"
    )
}

/// Our material for the Radiance material `p`, and what light it is.
fn convert(p: &Primitive, at: &Location, report: &mut RadReport) -> Result<(Material, LightKind), RadError> {
    let r = &p.reals;
    let kind = p.kind.as_str();
    let expected: (&[usize], &'static str) = match kind {
        "plastic" | "metal" => (&[5], "5 reals: red green blue specularity roughness"),
        "plastic2" | "metal2" => (&[6], "6 reals: red green blue specularity u-roughness v-roughness"),
        "trans" => (
            &[7],
            "7 reals: red green blue specularity roughness transmissivity transmitted-specular",
        ),
        "trans2" => (
            &[8],
            "8 reals: red green blue specularity u-roughness v-roughness transmissivity transmitted-specular",
        ),
        "glass" => (&[3, 4], "3 or 4 reals: red green blue [index of refraction]"),
        "dielectric" => (&[5], "5 reals: red green blue index-of-refraction Hartmann-constant"),
        "mirror" | "light" => (&[3], "3 reals: red green blue"),
        "glow" => (&[4], "4 reals: red green blue maximum-radius"),
        _ => (&[7], "7 reals: red green blue angle x y z"),
    };
    check_reals(p, at, expected.0, expected.1)?;
    let rgb = [r[0], r[1], r[2]];
    let color = |c: [f64; 3], report: &mut RadReport| {
        if c.iter().any(|v| !(0.0..=1.0).contains(v)) {
            report.note(NoteKind::ColorClamped, at, || p.what());
        }
        c.map(|v| v.clamp(0.0, 1.0) as f32)
    };
    let roughness = |rough: f64| rough.clamp(0.0, 1.0).sqrt() as f32;
    let material = match kind {
        "plastic" | "plastic2" | "trans" | "trans2" => {
            let anisotropic = kind.ends_with('2');
            let rough = if anisotropic {
                report.note(NoteKind::Anisotropic, at, || p.what());
                0.5 * (r[4].abs() + r[5].abs())
            } else {
                r[4]
            };
            let mut albedo = rgb;
            if kind.starts_with("trans") {
                report.note(NoteKind::TransOpaque, at, || p.what());
                let trans = r[if anisotropic { 6 } else { 5 }].clamp(0.0, 1.0);
                albedo = rgb.map(|c| c * (1.0 - trans));
            }
            plastic(color(albedo, report), r[3], roughness(rough))
        }
        "metal" | "metal2" => {
            let rough = if kind == "metal2" {
                report.note(NoteKind::Anisotropic, at, || p.what());
                0.5 * (r[4].abs() + r[5].abs())
            } else {
                r[4]
            };
            if r[3] < 1.0 {
                report.note(NoteKind::MetalDiffuse, at, || p.what());
            }
            Material::Metal {
                color: color(rgb, report),
                roughness: roughness(rough),
            }
        }
        "glass" => Material::Glass {
            ior: r.get(3).copied().unwrap_or(GLASS_IOR) as f32,
            color: color(rgb, report),
            thin: true,
        },
        "dielectric" => {
            report.note(NoteKind::DielectricTint, at, || p.what());
            Material::Glass {
                ior: r[3] as f32,
                color: color(rgb, report),
                thin: false,
            }
        }
        "mirror" => Material::Mirror {
            color: color(rgb, report),
        },
        _ => {
            match kind {
                "glow" => report.note(NoteKind::GlowRadius, at, || p.what()),
                "spotlight" => report.note(NoteKind::SpotlightBeam, at, || p.what()),
                _ => {}
            }
            if rgb.iter().any(|&v| v < 0.0) {
                report.note(NoteKind::NegativeLight, at, || p.what());
            }
            Material::Emitter {
                radiance: rgb.map(|v| v.max(0.0) as f32),
            }
        }
    };
    let light = match kind {
        "light" => LightKind::Light,
        "glow" => LightKind::Glow,
        "spotlight" => LightKind::Spot,
        _ => LightKind::None,
    };
    Ok((material, light))
}

/// Radiance plastic: a lambertian without specularity, else a coat whose
/// normal-incidence Fresnel reflectance is the specularity.
fn plastic(albedo: [f32; 3], spec: f64, roughness: f32) -> Material {
    let spec = spec.clamp(0.0, 0.9);
    if spec == 0.0 {
        return Material::lambertian(albedo);
    }
    let s = spec.sqrt();
    Material::Plastic {
        albedo,
        roughness,
        ior: ((1.0 + s) / (1.0 - s)) as f32,
    }
}

/// Refuses `p` unless it has one of the `counts` of reals.
fn check_reals(p: &Primitive, at: &Location, counts: &[usize], expected: &'static str) -> Result<(), RadError> {
    if counts.contains(&p.reals.len()) {
        Ok(())
    } else {
        Err(count_error(p, at, expected))
    }
}

/// The error for `p` with arguments other than `expected`.
pub(super) fn count_error(p: &Primitive, at: &Location, expected: &'static str) -> RadError {
    let got = format!(
        "{} strings, {} integers and {} reals",
        p.strings.len(),
        p.ints.len(),
        p.reals.len()
    );
    let what = p.what();
    RadError::new(at, RadErrorKind::ArgumentCount { what, expected, got })
}
