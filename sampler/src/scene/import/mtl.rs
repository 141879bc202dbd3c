//! MTL materials as the format defines them, mapped onto ours.
//!
//! `Ke` above zero makes an emitter. Otherwise the `illum` model decides:
//! 0–2 and 8 and 10 are opaque (plastic where `Ks` is above zero, else
//! diffuse), whatever `d` says (exporters write `d 0` meaning nothing);
//! 3 and 5 reflect (metal with `Ks` where `Kd` is black, else plastic);
//! 4, 6, 7 and 9 are glass (`Ni`, `Tf`). Without `illum`, `d` between 0 and
//! 1 is glass, as the files that omit it mean. `Ns` becomes roughness
//! sqrt(2 / (Ns + 2)).
//!
//! Maps: `map_Kd` multiplies the colour (sRGB), `map_d` cuts holes where
//! its alpha (or, for images without alpha, its red channel) is below one
//! half, `bump`/`map_Bump` (heights, `-bm` scale) and `norm` (tangent-space
//! normals) bend the shading normal, `map_Pr` scales roughness, `map_Ke`
//! (sRGB) times `Ke` glows on a surface that keeps its model. Options
//! `-s` and `-o` place the coordinates and `-clamp on` clamps them; the
//! rest are read past. What is dropped or approximated is noted per
//! material: `map_Ka`, `map_Ks`, `map_Ns`, `map_Pm`, `disp`,
//! `refl`, `illum` 0 (unlit) and 10 (shadow matte).

use std::path::Path;

use super::unit_color;
use crate::scene::builder::SceneBuilder;
use crate::scene::maps::{Channel, Coverage, MaterialMaps, Relief, TexRef, UvTransform};
use crate::scene::material::Material;
use crate::scene::texture::{Encoding, Wrap};

/// A map statement's file and the options that matter here.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct MapSpec {
    /// The image file, relative to the MTL's directory.
    pub path: String,
    /// `-s` scale and `-o` offset of the coordinates.
    pub transform: UvTransform,
    /// `-clamp on`.
    pub clamp: bool,
    /// `-bm` bump multiplier.
    pub bump: f32,
}

/// Parses the rest of a map statement: options, then the file name (which
/// may contain spaces). Backslashes, as Windows exporters write, become slashes.
pub(super) fn parse_map(text: &str) -> Option<MapSpec> {
    let tokens: Vec<&str> = text.split_whitespace().collect();
    let mut spec = MapSpec {
        path: String::new(),
        transform: UvTransform::default(),
        clamp: false,
        bump: 1.0,
    };
    let mut i = 0;
    let numbers = |i: &mut usize, most: usize| -> Vec<f32> {
        let mut out = Vec::new();
        while out.len() < most {
            match tokens.get(*i).and_then(|t| t.parse::<f32>().ok()) {
                Some(v) if v.is_finite() => {
                    out.push(v);
                    *i += 1;
                }
                _ => break,
            }
        }
        out
    };
    while i < tokens.len() && tokens[i].starts_with('-') && tokens[i].len() > 1 {
        let option = tokens[i];
        i += 1;
        match option {
            "-s" => {
                let v = numbers(&mut i, 3);
                if let [u, ref rest @ ..] = v[..] {
                    spec.transform.scale = [u, rest.first().copied().unwrap_or(u)];
                }
            }
            "-o" => {
                let v = numbers(&mut i, 3);
                if let [u, ref rest @ ..] = v[..] {
                    spec.transform.offset = [u, rest.first().copied().unwrap_or(0.0)];
                }
            }
            "-t" => {
                numbers(&mut i, 3);
            }
            "-bm" => {
                if let Some(&b) = numbers(&mut i, 1).first() {
                    spec.bump = b;
                }
            }
            "-mm" => {
                numbers(&mut i, 2);
            }
            "-boost" | "-texres" => {
                numbers(&mut i, 1);
            }
            "-clamp" => {
                spec.clamp = tokens.get(i).is_some_and(|t| t.eq_ignore_ascii_case("on"));
                i += 1;
            }
            // Options with one word: -blendu, -blendv, -cc, -imfchan, -type.
            _ => i += 1,
        }
    }
    let path = tokens.get(i..)?.join(" ").replace('\\', "/");
    if path.is_empty() {
        return None;
    }
    spec.path = path;
    Some(spec)
}

/// Converts MTL material `m` of the library in `dir` (read from `file`),
/// loading its textures into `b` and noting what is dropped.
pub(super) fn convert(b: &mut SceneBuilder, m: &tobj::Material, dir: &Path, file: &str) -> (Material, MaterialMaps) {
    let name = m.name.as_str();
    // `map_Ke` with `Ke`: the surface glows through the texture and keeps
    // the model its `illum` gives (an emitter would reflect nothing).
    let glows = m.unknown_param.contains_key("map_Ke") && m.emissive.is_some_and(|ke| ke.iter().any(|&v| v > 0.0));
    let material = if glows {
        let plain = tobj::Material {
            emissive: None,
            ..m.clone()
        };
        model(b, &plain, file)
    } else {
        model(b, m, file)
    };
    let mut maps = MaterialMaps {
        alpha: 1.0,
        ..MaterialMaps::default()
    };
    let load = |b: &mut SceneBuilder, key: &str, text: &str, encoding: Encoding| -> Option<(TexRef, MapSpec)> {
        let Some(spec) = parse_map(text) else {
            b.note(file, Some(name), format!("{key} names no file; dropped"));
            return None;
        };
        let path = dir.join(&spec.path);
        match b.textures().load(&path, encoding) {
            Ok(texture) => {
                let wrap = if spec.clamp { Wrap::Clamp } else { Wrap::Repeat };
                let tex = TexRef {
                    texture,
                    wrap: [wrap; 2],
                    transform: spec.transform,
                };
                Some((tex, spec))
            }
            Err(e) => {
                tracing::warn!("{file}: material {name:?}: {key}: {e}; the map is dropped");
                b.note(file, Some(name), format!("{key}: {e}; dropped"));
                None
            }
        }
    };
    if let Some(text) = &m.diffuse_texture {
        maps.base_color = load(b, "map_Kd", text, Encoding::Srgb).map(|t| t.0);
    }
    let own_alpha = maps.base_color.filter(|t| {
        m.dissolve_texture.is_some()
            && m.dissolve_texture == m.diffuse_texture
            && b.textures().get(t.texture).is_some_and(|t| t.has_alpha)
    });
    if let Some(tex) = own_alpha {
        // map_d names the colour image itself: its alpha (stored linear) is the coverage.
        maps.coverage = Some((Some((tex, Channel::Alpha)), Coverage::Mask { cutoff: 0.5 }));
    } else if let Some(text) = &m.dissolve_texture {
        if let Some((tex, _)) = load(b, "map_d", text, Encoding::Linear) {
            let channel = match b.textures().get(tex.texture) {
                Some(t) if t.has_alpha => Channel::Alpha,
                _ => Channel::Red,
            };
            maps.coverage = Some((Some((tex, channel)), Coverage::Mask { cutoff: 0.5 }));
        }
    }
    if let Some(text) = &m.normal_texture {
        if let Some((tex, spec)) = load(b, "bump", text, Encoding::Linear) {
            maps.relief = Some((tex, Relief::Height { scale: spec.bump }));
        }
    }
    if let Some(text) = m.unknown_param.get("norm") {
        if let Some((tex, _)) = load(b, "norm", text, Encoding::Linear) {
            maps.relief = Some((tex, Relief::Normal { scale: 1.0 }));
        }
    }
    if let Some(text) = m.unknown_param.get("map_Pr") {
        if matches!(material, Material::Plastic { .. } | Material::Metal { .. }) {
            maps.roughness = load(b, "map_Pr", text, Encoding::Linear).map(|t| t.0);
        } else {
            b.note(file, Some(name), "map_Pr on a diffuse or glass model; dropped");
        }
    }
    let dropped = [
        ("map_Ka", m.ambient_texture.is_some()),
        ("map_Ks", m.specular_texture.is_some()),
        ("map_Ns", m.shininess_texture.is_some()),
    ];
    for (key, present) in dropped {
        if present {
            b.note(file, Some(name), format!("{key} is not used; dropped"));
        }
    }
    if let Some(text) = m.unknown_param.get("map_Ke") {
        if glows {
            maps.emissive = load(b, "map_Ke", text, Encoding::Srgb).map(|t| t.0);
            maps.emission = m
                .emissive
                .unwrap_or([0.0; 3])
                .map(|v| if v.is_finite() { v.max(0.0) } else { 0.0 });
        } else {
            b.note(
                file,
                Some(name),
                "map_Ke without Ke above 0 glows with nothing; dropped",
            );
        }
    }
    for key in ["map_Pm", "disp", "refl", "map_refl", "decal", "map_aat"] {
        if m.unknown_param.contains_key(key) {
            b.note(file, Some(name), format!("{key} is not used; dropped"));
        }
    }
    if matches!(material, Material::Emitter { .. }) && !maps.is_empty() {
        b.note(file, Some(name), "an emitter's maps are not used; it glows with Ke");
        maps = MaterialMaps::default();
    }
    (material, maps)
}

/// The reflectance model of `m`, as its `illum`, `Ke`, `Kd`, `Ks`, `Ns`,
/// `d`, `Ni` and `Tf` say.
fn model(b: &mut SceneBuilder, m: &tobj::Material, file: &str) -> Material {
    let name = Some(m.name.as_str());
    let kd = m.diffuse.map(unit_color);
    let ks = m.specular.map(unit_color).unwrap_or([0.0; 3]);
    let ke = m
        .emissive
        .unwrap_or([0.0; 3])
        .map(|v| if v.is_finite() { v.max(0.0) } else { 0.0 });
    let roughness = match m.shininess {
        Some(ns) if ns.is_finite() && ns >= 0.0 => (2.0 / (ns + 2.0)).sqrt().clamp(0.0, 1.0),
        _ => 1.0,
    };
    let max = |c: [f32; 3]| c[0].max(c[1]).max(c[2]);
    if max(ke) > 0.0 {
        return Material::Emitter { radiance: ke };
    }
    let dissolve = m.dissolve.filter(|d| d.is_finite()).unwrap_or(1.0);
    let glass = || {
        let ior = m.optical_density.filter(|n| n.is_finite() && *n >= 1.0).unwrap_or(1.5);
        let color = m
            .unknown_param
            .get("Tf")
            .and_then(|tf| parse_rgb(tf))
            .map(unit_color)
            .unwrap_or([1.0; 3]);
        Material::Glass {
            ior,
            color,
            thin: false,
        }
    };
    let illum = m.illumination_model;
    match illum {
        Some(4 | 6 | 7 | 9) => return glass(),
        None if dissolve > 0.0 && dissolve < 1.0 => return glass(),
        None if dissolve <= 0.0 => {
            b.note(
                file,
                name,
                "d 0 without illum read as opaque (exporters write it meaning nothing)",
            );
        }
        Some(k) if dissolve < 1.0 => {
            b.note(
                file,
                name,
                format!("d {dissolve} ignored: illum {k} is an opaque model"),
            );
        }
        _ => {}
    }
    match illum {
        Some(0) => b.note(file, name, "illum 0 (colour without lighting) shaded as diffuse"),
        Some(10) => b.note(file, name, "illum 10 (shadow matte) shaded as diffuse"),
        Some(k) if k > 10 => b.note(file, name, format!("illum {k} is not an MTL model; read as 2")),
        _ => {}
    }
    let reflective = matches!(illum, Some(3 | 5 | 8));
    if reflective && kd.is_none_or(|c| max(c) < 0.01) {
        let color = if max(ks) > 0.0 { ks } else { [0.9; 3] };
        return Material::Metal { color, roughness };
    }
    let albedo = kd.unwrap_or([0.8; 3]);
    if max(ks) > 0.0 && !matches!(illum, Some(0 | 1)) {
        return Material::Plastic {
            albedo,
            roughness,
            ior: 1.5,
        };
    }
    Material::lambertian(albedo)
}

/// Three numbers, or one repeated (as MTL allows for `Tf`).
fn parse_rgb(s: &str) -> Option<[f32; 3]> {
    let v: Vec<f32> = s.split_whitespace().map(str::parse).collect::<Result<_, _>>().ok()?;
    match v[..] {
        [g] => Some([g; 3]),
        [r, g, b] => Some([r, g, b]),
        _ => None,
    }
}
