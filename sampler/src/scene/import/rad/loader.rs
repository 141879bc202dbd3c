//! Reading a Radiance file and what its `!` lines include into one triangle
//! list: modifiers are defined in reading order across files (as Radiance
//! reads one stream), surfaces are tessellated and placed by the transforms
//! of the commands that included them, distant sources are kept for the sky.
//! Nothing here touches the scene being built; that happens once all is read.

use std::path::{Path, PathBuf};

use glam::{DMat4, Vec3};

use super::command::{parse_command, Producer};
use super::error::{Location, RadError, RadErrorKind};
use super::materials::{count_error, Modifiers, Resolved};
use super::parse::{Parser, Primitive, Statement};
use super::report::{NoteKind, RadReport};
use super::shapes::{self, ShapeError, ShapeMesh, ShapeNote, SurfaceKind};
use super::sky::Source;
use crate::scene::builder::MAX_TRIANGLES;
use crate::scene::import::MAX_FILE_BYTES;

/// Deepest nesting of included files.
pub(super) const MAX_DEPTH: usize = 64;
/// Most files included in all (a guard against a file that includes another
/// many times over, each including more).
pub(super) const MAX_INCLUDES: usize = 10_000;

/// How the file being read is placed: the transform from its frame to the
/// first file's, and what its including commands changed.
#[derive(Clone, Debug)]
struct Frame {
    transform: DMat4,
    /// `xform -I` an odd number of times.
    invert: bool,
    /// Whether triangles turn around: a mirroring transform, or `invert`.
    flip: bool,
    /// `xform -m`: the modifier of every surface (the outermost one wins).
    modifier: Option<String>,
}

impl Frame {
    fn new(transform: DMat4, invert: bool, modifier: Option<String>) -> Frame {
        // A mirror reverses vertex order; xform turns the faces back so that
        // they keep facing the way they did.
        let flip = (transform.determinant() < 0.0) != invert;
        Frame {
            transform,
            invert,
            flip,
            modifier,
        }
    }
}

/// Everything read so far.
pub(super) struct Loader {
    /// Modifiers and the converted materials.
    pub modifiers: Modifiers,
    /// What was approximated.
    pub report: RadReport,
    /// Vertices in the first file's frame.
    pub positions: Vec<Vec3>,
    /// Triangles, front counter-clockwise.
    pub triangles: Vec<[u32; 3]>,
    /// The material slot of each triangle.
    pub slots: Vec<usize>,
    /// Picture coordinates (the pattern's x and y) of each vertex, once a
    /// surface under a `colorpict` is added (zero for the others).
    pub uvs: Vec<glam::Vec2>,
    /// Distant sources.
    pub sources: Vec<Source>,
    /// The files being read, outermost first, as found on disk.
    stack: Vec<PathBuf>,
    /// Files included so far.
    includes: usize,
    /// What ear clipping may still spend ([`shapes::EAR_CLIP_BUDGET`]).
    ear_budget: u64,
}

impl Default for Loader {
    fn default() -> Loader {
        Loader {
            modifiers: Modifiers::default(),
            report: RadReport::default(),
            positions: Vec::new(),
            triangles: Vec::new(),
            slots: Vec::new(),
            uvs: Vec::new(),
            sources: Vec::new(),
            stack: Vec::new(),
            includes: 0,
            ear_budget: shapes::EAR_CLIP_BUDGET,
        }
    }
}

impl Loader {
    /// Reads `bytes`, the content of the file `path` that the import names.
    pub(super) fn read_root(&mut self, bytes: &[u8], path: &Path) -> Result<(), RadError> {
        self.stack
            .push(std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf()));
        let result = self.read_bytes(bytes, path, &Frame::new(DMat4::IDENTITY, false, None));
        self.stack.pop();
        result
    }

    /// Reads the file `path` that the command at `from` includes.
    fn read_include(&mut self, path: &Path, frame: &Frame, from: &Location) -> Result<(), RadError> {
        let io = |source: std::io::Error| {
            let file = path.to_path_buf();
            RadError::new(from, RadErrorKind::Include { file, source })
        };
        let refused = |message: String| {
            let file = path.to_path_buf();
            RadError::new(from, RadErrorKind::IncludeRefused { file, message })
        };
        let meta = std::fs::metadata(path).map_err(io)?;
        if !meta.is_file() {
            return Err(refused("not a regular file".to_string()));
        }
        if meta.len() > MAX_FILE_BYTES {
            return Err(refused(format!(
                "{} bytes is more than the {MAX_FILE_BYTES} read",
                meta.len()
            )));
        }
        let real = std::fs::canonicalize(path).map_err(io)?;
        if self.stack.contains(&real) {
            let chain = self
                .stack
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(" -> ");
            let file = path.to_path_buf();
            return Err(RadError::new(from, RadErrorKind::IncludeCycle { file, chain }));
        }
        if self.stack.len() >= MAX_DEPTH {
            return Err(RadError::new(from, RadErrorKind::TooDeep { max: MAX_DEPTH }));
        }
        self.includes += 1;
        if self.includes > MAX_INCLUDES {
            return Err(RadError::new(from, RadErrorKind::TooManyIncludes { max: MAX_INCLUDES }));
        }
        let bytes = std::fs::read(path).map_err(io)?;
        self.stack.push(real);
        let result = self.read_bytes(&bytes, path, frame);
        self.stack.pop();
        result
    }

    /// Reads every statement of one file.
    fn read_bytes(&mut self, bytes: &[u8], path: &Path, frame: &Frame) -> Result<(), RadError> {
        let mut parser = Parser::new(bytes, path);
        while let Some(statement) = parser.next_statement()? {
            match statement {
                Statement::Command { text, line } => self.command(&text, &parser.at(line), path, frame)?,
                Statement::Primitive(p) => self.primitive(&p, &parser.at(p.line), frame)?,
            }
        }
        Ok(())
    }

    /// A `!` line of the file `path`.
    fn command(&mut self, text: &str, at: &Location, path: &Path, frame: &Frame) -> Result<(), RadError> {
        let pipeline = parse_command(text).map_err(|kind| RadError::new(at, kind))?;
        let inner = Frame::new(
            frame.transform * pipeline.transform,
            frame.invert != pipeline.invert,
            frame.modifier.clone().or(pipeline.modifier),
        );
        match pipeline.producer {
            Producer::Files(files) => {
                let dir = path.parent().unwrap_or(Path::new(""));
                for file in files {
                    self.read_include(&dir.join(file), &inner, at)?;
                }
            }
            Producer::Genbox {
                material,
                name,
                size,
                inward,
            } => {
                let modifier = inner.modifier.clone().unwrap_or(material);
                let what = format!("genbox {name:?}");
                let resolved = self.modifiers.lookup(&modifier, at)?;
                if let Some(slot) = self.shown(resolved, &what, at)? {
                    self.add(shapes::genbox(size, inward), None, slot, &what, at, &inner)?;
                }
            }
        }
        Ok(())
    }

    /// A primitive: a modifier is defined, a surface added, a source kept.
    fn primitive(&mut self, p: &Primitive, at: &Location, frame: &Frame) -> Result<(), RadError> {
        let dir = self
            .stack
            .last()
            .and_then(|f| f.parent())
            .map(Path::to_path_buf)
            .unwrap_or_default();
        if self.modifiers.define(p, at, &dir, &frame.transform, &mut self.report)? {
            return Ok(());
        }
        let modifier = frame.modifier.as_deref().unwrap_or(&p.modifier);
        if p.kind == "source" {
            if p.reals.len() != 4 {
                return Err(count_error(p, at, "4 reals: direction and angular diameter"));
            }
            let r = &p.reals;
            let direction = frame.transform.transform_vector3(glam::DVec3::new(r[0], r[1], r[2]));
            let resolved = self.modifiers.lookup(modifier, at)?;
            if let Some(slot) = self.shown(resolved, &p.what(), at)? {
                self.sources.push(Source {
                    direction,
                    angle: r[3],
                    slot,
                    at: at.clone(),
                    what: p.what(),
                });
            }
            return Ok(());
        }
        if matches!(p.kind.as_str(), "instance" | "mesh") {
            let kind = RadErrorKind::UnsupportedSurface {
                kind: p.kind.clone(),
                name: p.name.clone(),
                why: "it refers to a compiled octree or mesh file; include the scene it was made from instead",
            };
            return Err(RadError::new(at, kind));
        }
        let Some(kind) = SurfaceKind::parse(&p.kind) else {
            let kind = p.kind.clone();
            return Err(RadError::new(at, RadErrorKind::UnknownType { kind }));
        };
        let resolved = self.modifiers.lookup(modifier, at)?;
        let what = p.what();
        let Some(slot) = self.shown(resolved, &what, at)? else {
            return Ok(());
        };
        let shape = shapes::tessellate(kind, &p.reals, &mut self.ear_budget).map_err(|e| match e {
            ShapeError::Count(expected) => count_error(p, at, expected),
            ShapeError::Bad(message) => {
                let what = p.what();
                RadError::new(at, RadErrorKind::BadArguments { what, message })
            }
        })?;
        self.add(shape.mesh, shape.note, slot, &what, at, frame)
    }

    /// The material slot a surface `what` showing `resolved` takes; `None`
    /// (reported) for surfaces left out.
    fn shown(&mut self, resolved: Resolved, what: &str, at: &Location) -> Result<Option<usize>, RadError> {
        match resolved {
            Resolved::Material(slot) => Ok(Some(slot)),
            Resolved::Invisible(kind) => {
                self.report.note(kind, at, || what.to_string());
                Ok(None)
            }
            Resolved::Unsupported {
                name,
                kind,
                at: defined_at,
            } => {
                let kind = RadErrorKind::UnsupportedMaterial {
                    what: what.to_string(),
                    material: name,
                    kind,
                    defined_at,
                };
                Err(RadError::new(at, kind))
            }
        }
    }

    /// Adds the triangles of the surface `what` (material `slot`), placed by `frame`.
    fn add(
        &mut self,
        mesh: ShapeMesh,
        note: Option<ShapeNote>,
        slot: usize,
        what: &str,
        at: &Location,
        frame: &Frame,
    ) -> Result<(), RadError> {
        match note {
            Some(ShapeNote::NegativeRadius) => self.report.note(NoteKind::NegativeRadius, at, || what.to_string()),
            Some(ShapeNote::ZeroArea) => self.report.note(NoteKind::ZeroArea, at, || what.to_string()),
            Some(ShapeNote::Fanned) => self.report.note(NoteKind::Fanned, at, || what.to_string()),
            None => {}
        }
        if self.triangles.len().saturating_add(mesh.triangles.len()) > MAX_TRIANGLES
            || self.positions.len().saturating_add(mesh.positions.len()) > u32::MAX as usize
        {
            let (what, message) = (what.to_string(), format!("more than {MAX_TRIANGLES} triangles in all"));
            return Err(RadError::new(at, RadErrorKind::BadArguments { what, message }));
        }
        let base = self.positions.len() as u32;
        self.positions.extend(
            mesh.positions
                .iter()
                .map(|p| frame.transform.transform_point3(*p).as_vec3()),
        );
        if let Some(picture) = &self.modifiers.slots[slot].picture {
            // picture.cal's pic_u and pic_v: the point's x and y in the pattern's frame.
            self.uvs.resize(base as usize, glam::Vec2::ZERO);
            self.uvs.extend(mesh.positions.iter().map(|p| {
                let q = picture.inverse.transform_point3(frame.transform.transform_point3(*p));
                glam::Vec2::new(q.x as f32, q.y as f32)
            }));
        } else if !self.uvs.is_empty() {
            self.uvs.resize(self.positions.len(), glam::Vec2::ZERO);
        }
        self.triangles.extend(mesh.triangles.iter().map(|t| {
            let t = t.map(|i| i + base);
            if frame.flip {
                [t[0], t[2], t[1]]
            } else {
                t
            }
        }));
        self.slots.resize(self.triangles.len(), slot);
        Ok(())
    }
}
