//! Radiance's calc language, for the patterns of Radiance scenes:
//! `colorfunc`, `brightfunc` and `texfunc` evaluate expressions of a
//! function file (`.cal`) at every hit; `brightdata` and `colordata` look
//! up a data file (an IES distribution written by `ies2rad`, say) at
//! coordinates the function file computes. A file is parsed once
//! ([`parse`]), the names a pattern reaches are resolved and compiled
//! ([`program`]), and the program is evaluated per hit with the ray's
//! variables ([`RayVars`]) in the pattern's own frame. The natives every
//! file may use are in [`builtin`]; data tables in [`data`].
//!
//! What differs from Radiance: every file has its own namespace and a
//! name it defines hides a native of the same name everywhere in it;
//! `:` constants are evaluated like `=` variables; the noise functions
//! have Radiance's kind (smooth gradient noise, fractal noise) but not its
//! lattice, so a noisy pattern has the same look, not the same texels.

pub mod builtin;
pub mod data;
pub mod parse;
pub mod program;

#[cfg(test)]
mod tests;

use serde::{Deserialize, Serialize};

/// Why a function or data file cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalcError {
    /// The text does not parse.
    #[error("{what}, line {line}: {message}")]
    Syntax {
        /// The file or argument.
        what: String,
        /// Where.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A name that nothing defines.
    #[error("{what}: {name:?} is not defined as {wanted}")]
    Undefined {
        /// The file.
        what: String,
        /// The name.
        name: String,
        /// What it was used as.
        wanted: String,
    },
    /// A data file that cannot be read.
    #[error("{what}: {message}")]
    Data {
        /// The file.
        what: String,
        /// What is wrong.
        message: String,
    },
}

/// A ray variable of Radiance's patterns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[repr(u8)]
pub enum Var {
    /// The ray's direction, in the pattern's frame.
    Dx,
    Dy,
    Dz,
    /// The surface normal (as the surface faces, not turned toward the ray).
    Nx,
    Ny,
    Nz,
    /// The hit point.
    Px,
    Py,
    Pz,
    /// The distance along the path from the eye, in pattern units.
    T,
    /// The length of this ray (a shadow ray's, from the lit point to the light).
    Ts,
    /// The cosine between the ray and the normal, −D·N.
    Rdot,
    /// The pattern's scale: 1 over the product of its `-s` factors.
    S,
    /// The world origin in the pattern's frame.
    Tx,
    Ty,
    Tz,
    /// The world axes x, y and z in the pattern's frame.
    Ix,
    Iy,
    Iz,
    Jx,
    Jy,
    Jz,
    Kx,
    Ky,
    Kz,
    /// Mesh coordinates (0: surfaces here have none).
    Lu,
    Lv,
}

impl Var {
    /// The variable named `name`.
    pub fn named(name: &str) -> Option<Var> {
        use Var::*;
        Some(match name {
            "Dx" => Dx,
            "Dy" => Dy,
            "Dz" => Dz,
            "Nx" => Nx,
            "Ny" => Ny,
            "Nz" => Nz,
            "Px" => Px,
            "Py" => Py,
            "Pz" => Pz,
            "T" => T,
            "Ts" => Ts,
            "Rdot" => Rdot,
            "S" => S,
            "Tx" => Tx,
            "Ty" => Ty,
            "Tz" => Tz,
            "Ix" => Ix,
            "Iy" => Iy,
            "Iz" => Iz,
            "Jx" => Jx,
            "Jy" => Jy,
            "Jz" => Jz,
            "Kx" => Kx,
            "Ky" => Ky,
            "Kz" => Kz,
            "Lu" => Lu,
            "Lv" => Lv,
            _ => return None,
        })
    }
}

/// The values of the ray variables for one evaluation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RayVars(pub [f64; 27]);

impl RayVars {
    /// The value of `v`.
    #[inline]
    pub fn get(&self, v: Var) -> f64 {
        self.0[v as usize]
    }
    /// Sets `v`.
    #[inline]
    pub fn set(&mut self, v: Var, value: f64) {
        self.0[v as usize] = value;
    }
}
