//! Radiance's function and data patterns as the path tracer applies them:
//! `colorfunc` and `brightfunc` multiply a surface's colour (a light's
//! radiance) by expressions of its function file, `texfunc` bends its
//! normal, and `brightdata`/`colordata` multiply by a data table looked up
//! at coordinates the file computes (an IES light's intensity over its
//! angles, as `ies2rad` writes it). Each is evaluated at every hit with the
//! ray's variables in the pattern's frame (its transform and the `!xform`
//! that placed its file). A pattern whose evaluation fails (a division by
//! zero, a runaway recursion) leaves that hit unchanged, as Radiance does.

use glam::{DMat4, DVec3, Vec3};
use serde::{Deserialize, Serialize};

use super::calc::data::Table;
use super::calc::program::{Callee, Eval, Program};
use super::calc::{RayVars, Var};

/// What a pattern computes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum PatternKind {
    /// `colorfunc`: red, green and blue multipliers.
    Color([u32; 3]),
    /// `brightfunc`: one multiplier.
    Bright(u32),
    /// `texfunc`: a perturbation of the normal, in the pattern's frame.
    Normal([u32; 3]),
    /// `brightdata`: `func(table(coordinates))`.
    BrightData {
        /// The function applied to the looked-up value.
        func: Callee,
        /// The table.
        table: Table,
        /// The coordinate expressions, one per dimension.
        coords: Vec<u32>,
    },
    /// `colordata`: a table per colour, each through its function.
    ColorData {
        /// The functions of red, green and blue, and whether each takes
        /// all three values (else its own).
        funcs: [(Callee, bool); 3],
        /// The tables.
        tables: Box<[Table; 3]>,
        /// The coordinate expressions, one per dimension.
        coords: Vec<u32>,
    },
}

/// One pattern, compiled.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pattern {
    /// Its Radiance name, for reports.
    pub name: String,
    /// What it computes.
    pub kind: PatternKind,
    /// The compiled expressions and what they reach.
    pub program: Program,
    /// Its real arguments (`A1`, `A2`, ...).
    pub args: Vec<f64>,
    /// World coordinates to the pattern's.
    pub to_pattern: DMat4,
    /// The pattern's coordinates to the world's (the inverse of `to_pattern`).
    pub to_world: DMat4,
    /// The factor by which `to_pattern` stretches lengths (the cube root
    /// of its determinant; Radiance's `S`).
    pub scale: f64,
}

/// Where a ray meets a patterned surface, in world coordinates.
#[derive(Clone, Copy, Debug)]
pub struct PatternHit {
    /// The hit point.
    pub point: Vec3,
    /// The surface normal as the surface faces (unit).
    pub normal: Vec3,
    /// The ray's direction (unit): for a light seen by a shadow ray, from
    /// the lit point toward the light.
    pub dir: Vec3,
    /// Distance along the path from its start.
    pub path: f32,
    /// This ray's length.
    pub length: f32,
}

/// What the patterns of a surface do at one hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Effect {
    /// Multiplies the colour or the emitted radiance.
    pub color: Vec3,
    /// Added to the normal before it is normalized (world frame).
    pub bend: Vec3,
}

impl Default for Effect {
    fn default() -> Effect {
        Effect {
            color: Vec3::ONE,
            bend: Vec3::ZERO,
        }
    }
}

impl Pattern {
    /// A pattern whose coordinates `to_pattern` maps world points into.
    pub fn new(name: String, kind: PatternKind, program: Program, args: Vec<f64>, to_pattern: DMat4) -> Pattern {
        let scale = glam::DMat3::from_mat4(to_pattern).determinant().abs().cbrt();
        Pattern {
            name,
            kind,
            program,
            args,
            to_pattern,
            to_world: to_pattern.inverse(),
            scale: if scale > 0.0 && scale.is_finite() { scale } else { 1.0 },
        }
    }

    /// The ray variables at `hit` in this pattern's frame.
    pub fn vars(&self, hit: &PatternHit) -> RayVars {
        let m = &self.to_pattern;
        let s = self.scale;
        let unit = |v: Vec3| m.transform_vector3(v.as_dvec3()) / s;
        let (d, n) = (unit(hit.dir), unit(hit.normal));
        let p = m.transform_point3(hit.point.as_dvec3());
        let origin = m.transform_point3(DVec3::ZERO);
        let [i, j, k] = [DVec3::X, DVec3::Y, DVec3::Z].map(|a| m.transform_vector3(a) / s);
        let mut v = RayVars::default();
        let set3 = |v: &mut RayVars, vars: [Var; 3], x: DVec3| {
            for (var, c) in vars.into_iter().zip(x.to_array()) {
                v.set(var, c);
            }
        };
        set3(&mut v, [Var::Dx, Var::Dy, Var::Dz], d);
        set3(&mut v, [Var::Nx, Var::Ny, Var::Nz], n);
        set3(&mut v, [Var::Px, Var::Py, Var::Pz], p);
        set3(&mut v, [Var::Tx, Var::Ty, Var::Tz], origin);
        set3(&mut v, [Var::Ix, Var::Iy, Var::Iz], i);
        set3(&mut v, [Var::Jx, Var::Jy, Var::Jz], j);
        set3(&mut v, [Var::Kx, Var::Ky, Var::Kz], k);
        v.set(Var::T, f64::from(hit.path) * s);
        v.set(Var::Ts, f64::from(hit.length) * s);
        v.set(Var::Rdot, f64::from(-hit.dir.dot(hit.normal)).clamp(-1.0, 1.0));
        v.set(Var::S, s);
        v
    }

    /// Adds this pattern's effect at `hit` to `effect`; a failed
    /// evaluation adds nothing.
    pub fn apply(&self, hit: &PatternHit, effect: &mut Effect) {
        let vars = self.vars(hit);
        let mut e = Eval::new(&self.program, &vars, &self.args);
        let result: Result<(), super::calc::program::Fault> = (|| {
            match &self.kind {
                PatternKind::Color(rgb) => {
                    let c = [e.value(rgb[0])?, e.value(rgb[1])?, e.value(rgb[2])?];
                    effect.color *= DVec3::from_array(c).as_vec3();
                }
                PatternKind::Bright(b) => effect.color *= e.value(*b)? as f32,
                PatternKind::Normal(xyz) => {
                    let pert = DVec3::new(e.value(xyz[0])?, e.value(xyz[1])?, e.value(xyz[2])?);
                    // Back to the world by the forward transform, without its scale.
                    let w = self.to_world.transform_vector3(pert) * self.scale;
                    if w.is_finite() {
                        effect.bend += w.as_vec3();
                    }
                }
                PatternKind::BrightData { func, table, coords } => {
                    let at = coords.iter().map(|&c| e.value(c)).collect::<Result<Vec<_>, _>>()?;
                    let v = e.call_with(*func, &[table.value(&at)])?;
                    effect.color *= v as f32;
                }
                PatternKind::ColorData { funcs, tables, coords } => {
                    let at = coords.iter().map(|&c| e.value(c)).collect::<Result<Vec<_>, _>>()?;
                    let raw = [0, 1, 2].map(|k| tables[k].value(&at));
                    let mut c = [0.0; 3];
                    for (k, (f, all)) in funcs.iter().enumerate() {
                        c[k] = if *all {
                            e.call_with(*f, &raw)?
                        } else {
                            e.call_with(*f, &[raw[k]])?
                        };
                    }
                    effect.color *= DVec3::from_array(c).as_vec3();
                }
            }
            Ok(())
        })();
        if result.is_err() {
            tracing::trace!("pattern {:?}: evaluation failed; the hit is left as it is", self.name);
        }
    }
}

/// The combined effect of `patterns` at `hit`.
pub fn effect_of(patterns: &[Pattern], hit: &PatternHit) -> Effect {
    let mut e = Effect::default();
    for p in patterns {
        p.apply(hit, &mut e);
    }
    if !e.color.is_finite() {
        e.color = Vec3::ONE;
    }
    e
}
