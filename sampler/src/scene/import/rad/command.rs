//! `!` command lines read without running anything: `xform` of files (its
//! transform options applied left to right, as `xform` does) and `genbox`,
//! each optionally piped through more `xform`s that only transform. Any other
//! command is refused: running programs named by a scene file is not this
//! reader's business.

use glam::{DMat4, DVec3};

use super::error::RadErrorKind;

/// Largest `-i` repeat count taken.
const MAX_REPEAT: u64 = 1 << 20;

/// What a command line produces, before its transform.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Producer {
    /// The primitives of these files (relative to the including file).
    Files(Vec<String>),
    /// A `genbox`: six polygons named `name.*` with modifier `material`, a box
    /// from the origin to `size`, facing out (in with `inward`).
    Genbox {
        /// The polygons' modifier.
        material: String,
        /// The box's name.
        name: String,
        /// Sizes along x, y, z.
        size: DVec3,
        /// `-i`: faces point into the box.
        inward: bool,
    },
}

/// A whole command line: what it produces and how that is placed.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Pipeline {
    /// The source of primitives.
    pub producer: Producer,
    /// The transform of every stage, in order (file frame to including frame).
    pub transform: DMat4,
    /// `-I`: surfaces are turned inside out.
    pub invert: bool,
    /// `-m`: the modifier every surface takes instead of its own.
    pub modifier: Option<String>,
}

/// Reads the command line `text` (without its `!`).
pub(super) fn parse_command(text: &str) -> Result<Pipeline, RadErrorKind> {
    let stages = split_words(text);
    let mut pipeline: Option<Pipeline> = None;
    for words in stages {
        let name = words
            .first()
            .map(|w| w.rsplit('/').next().unwrap_or(w).to_string())
            .unwrap_or_default();
        let stage = match (name.as_str(), &pipeline) {
            ("", _) => return Err(bad("!", "an empty command")),
            ("xform", _) => xform(&words[1..])?,
            ("genbox", None) => genbox(&words[1..])?,
            _ => return Err(RadErrorKind::UnsupportedCommand { command: name }),
        };
        pipeline = Some(match pipeline {
            None => stage,
            Some(before) => {
                if stage.producer != Producer::Files(Vec::new()) {
                    return Err(bad("xform", "after a pipe xform reads its input, not files"));
                }
                Pipeline {
                    producer: before.producer,
                    transform: stage.transform * before.transform,
                    invert: before.invert != stage.invert,
                    modifier: stage.modifier.or(before.modifier),
                }
            }
        });
    }
    let pipeline = pipeline.ok_or_else(|| bad("!", "an empty command"))?;
    if pipeline.producer == Producer::Files(Vec::new()) {
        return Err(bad("xform", "no file named: it would read its standard input"));
    }
    if !pipeline.transform.is_finite() {
        return Err(bad("xform", "the transform overflows"));
    }
    Ok(pipeline)
}

/// An `xform` stage: options, transform, files.
fn xform(args: &[String]) -> Result<Pipeline, RadErrorKind> {
    let mut k = 0;
    let mut invert = false;
    let mut modifier = None;
    // Options that come before the transform (as xform reads them).
    while let Some(a) = args.get(k) {
        match a.as_str() {
            "-m" | "-n" => {
                let value = args
                    .get(k + 1)
                    .ok_or_else(|| bad("xform", format!("{a} needs a value")))?;
                if a == "-m" && modifier.is_none() {
                    modifier = Some(value.clone());
                }
                // -n prefixes surface names, which the scene does not keep.
                k += 2;
            }
            "-c" | "-e" => k += 1,
            "-I" => {
                invert = !invert;
                k += 1;
            }
            _ => break,
        }
    }
    let mut total = DMat4::IDENTITY;
    let mut step = DMat4::IDENTITY;
    let mut repeat = 1u64;
    while let Some(a) = args.get(k).filter(|a| a.starts_with('-')) {
        let number = |at: usize| -> Result<f64, RadErrorKind> {
            let token = args
                .get(at)
                .ok_or_else(|| bad("xform", format!("{a} needs more values")))?;
            token
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad("xform", format!("{a}: {token:?} is not a number")))
        };
        let m = match a.as_str() {
            "-t" => {
                let t = DVec3::new(number(k + 1)?, number(k + 2)?, number(k + 3)?);
                k += 3;
                DMat4::from_translation(t)
            }
            "-rx" | "-ry" | "-rz" => {
                let angle = number(k + 1)?.to_radians();
                k += 1;
                match a.as_str() {
                    "-rx" => DMat4::from_rotation_x(angle),
                    "-ry" => DMat4::from_rotation_y(angle),
                    _ => DMat4::from_rotation_z(angle),
                }
            }
            "-s" => {
                let s = number(k + 1)?;
                if s == 0.0 {
                    return Err(bad("xform", "-s 0 collapses everything"));
                }
                k += 1;
                DMat4::from_scale(DVec3::splat(s))
            }
            "-mx" => DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0)),
            "-my" => DMat4::from_scale(DVec3::new(1.0, -1.0, 1.0)),
            "-mz" => DMat4::from_scale(DVec3::new(1.0, 1.0, -1.0)),
            "-i" => {
                let token = args.get(k + 1).ok_or_else(|| bad("xform", "-i needs a count"))?;
                let n = token
                    .parse::<u64>()
                    .ok()
                    .filter(|n| *n <= MAX_REPEAT)
                    .ok_or_else(|| bad("xform", format!("-i {token:?} is not a count up to {MAX_REPEAT}")))?;
                total = power(step, repeat) * total;
                step = DMat4::IDENTITY;
                repeat = n;
                k += 2;
                continue;
            }
            other => return Err(bad("xform", format!("option {other} is not supported"))),
        };
        // Left to right: each option acts on the result of the ones before.
        step = m * step;
        k += 1;
    }
    total = power(step, repeat) * total;
    Ok(Pipeline {
        producer: Producer::Files(args[k..].to_vec()),
        transform: total,
        invert,
        modifier,
    })
}

/// The transform that xform-style options (`-t`, `-rx`, `-ry`, `-rz`,
/// `-s`, `-mx`, `-my`, `-mz`, `-i`) give, as a pattern's arguments end with them.
pub(super) fn transform_args(args: &[String]) -> Result<DMat4, RadErrorKind> {
    let pipeline = xform(args)?;
    match pipeline.producer {
        Producer::Files(rest) if rest.is_empty() && !pipeline.invert && pipeline.modifier.is_none() => {
            Ok(pipeline.transform)
        }
        _ => Err(bad(
            "transform",
            "only -t, -rx, -ry, -rz, -s, -mx, -my, -mz and -i may follow",
        )),
    }
}

/// `m` applied `n` times, by squaring.
fn power(mut m: DMat4, mut n: u64) -> DMat4 {
    let mut out = DMat4::IDENTITY;
    while n > 0 {
        if n & 1 == 1 {
            out = m * out;
        }
        m = m * m;
        n >>= 1;
    }
    out
}

/// A `genbox` stage: `material name xsize ysize zsize [-i]`.
fn genbox(args: &[String]) -> Result<Pipeline, RadErrorKind> {
    if args.len() < 5 {
        return Err(bad("genbox", "takes: material name x-size y-size z-size [-i]"));
    }
    let mut size = [0.0; 3];
    for (k, s) in size.iter_mut().enumerate() {
        let token = &args[2 + k];
        *s = token
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite() && *v > 0.0)
            .ok_or_else(|| bad("genbox", format!("size {token:?} is not a positive number")))?;
    }
    let mut inward = false;
    for a in &args[5..] {
        match a.as_str() {
            "-i" => inward = !inward,
            other => return Err(bad("genbox", format!("option {other} is not supported (only -i)"))),
        }
    }
    Ok(Pipeline {
        producer: Producer::Genbox {
            material: args[0].clone(),
            name: args[1].clone(),
            size: DVec3::from(size),
            inward,
        },
        transform: DMat4::IDENTITY,
        invert: false,
        modifier: None,
    })
}

/// The error for a command line `command` cannot take.
fn bad(command: &str, message: impl Into<String>) -> RadErrorKind {
    RadErrorKind::BadCommand {
        command: command.to_string(),
        message: message.into(),
    }
}

/// The words of each stage of a pipeline: white space separates words,
/// quotes group them, `|` outside quotes separates stages.
fn split_words(text: &str) -> Vec<Vec<String>> {
    let mut stages = vec![Vec::new()];
    let mut word: Option<String> = None;
    let mut quote = None;
    for c in text.chars() {
        match quote {
            Some(q) if c == q => quote = None,
            Some(_) => word.get_or_insert_with(String::new).push(c),
            None if c == '"' || c == '\'' => {
                quote = Some(c);
                word.get_or_insert_with(String::new);
            }
            None if c.is_whitespace() || c == '|' => {
                if let Some(w) = word.take() {
                    if let Some(s) = stages.last_mut() {
                        s.push(w);
                    }
                }
                if c == '|' {
                    stages.push(Vec::new());
                }
            }
            None => word.get_or_insert_with(String::new).push(c),
        }
    }
    if let Some(w) = word {
        if let Some(s) = stages.last_mut() {
            s.push(w);
        }
    }
    stages
}
