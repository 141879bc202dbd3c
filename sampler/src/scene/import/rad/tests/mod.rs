//! Radiance reader tests on small files written into a temporary directory:
//! helpers and the scene with every primitive here, the tests by concept beside.

use std::path::{Path, PathBuf};

use glam::{Mat4, Vec3};

use super::*;
use crate::scene::{Material, Scene};

mod commands;
mod errors;
mod functions;
mod materials;
mod pictures;
mod render;
mod sky;
mod surfaces;

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Reads `text` as the file `name` in `dir`.
fn read(dir: &Path, name: &str, text: &str) -> Result<(Scene, RadReport), SceneError> {
    let path = write(dir, name, text);
    let mut b = SceneBuilder::new();
    let report = read_rad(&mut b, &path, Mat4::IDENTITY, &ImportOptions::default())?;
    Ok((b.finish(), report))
}

/// The triangles whose material is named `name`.
fn triangles(s: &Scene, name: &str) -> Vec<[Vec3; 3]> {
    (0..s.triangles.len())
        .filter(|&t| s.material_names[s.triangles[t].material as usize] == name)
        .map(|t| s.vertices(t))
        .collect()
}

/// The material named `name`.
fn material<'a>(s: &'a Scene, name: &str) -> &'a Material {
    let k = s.material_names.iter().position(|n| n == name).unwrap_or_else(|| {
        panic!("no material {name:?} in {:?}", s.material_names);
    });
    &s.materials[k]
}

fn area(ts: &[[Vec3; 3]]) -> f64 {
    ts.iter()
        .map(|t| 0.5 * f64::from((t[1] - t[0]).cross(t[2] - t[0]).length()))
        .sum()
}

fn normal(t: &[Vec3; 3]) -> Vec3 {
    (t[1] - t[0]).cross(t[2] - t[0])
}

fn centroid(t: &[Vec3; 3]) -> Vec3 {
    (t[0] + t[1] + t[2]) / 3.0
}

fn close(a: f64, b: f64, tolerance: f64) -> bool {
    (a - b).abs() <= tolerance * b.abs()
}

/// The error of reading `text`, which must be a Radiance error.
fn rad_error(dir: &Path, name: &str, text: &str) -> RadError {
    match read(dir, name, text) {
        Err(SceneError::Rad(e)) => *e,
        Err(e) => panic!("not a Radiance error: {e}"),
        Ok(_) => panic!("{name} was read: {text}"),
    }
}

const EVERYTHING: &str = "\
# one material per surface, so each can be found by name
void plastic m_sphere 0 0 5 .5 .5 .5 0 0
void plastic m_bubble 0 0 5 .5 .5 .5 0 0
void plastic m_cone 0 0 5 .5 .5 .5 0 0
void plastic m_cup 0 0 5 .5 .5 .5 0 0
void plastic m_cylinder 0 0 5 .5 .5 .5 0 0
void plastic m_tube 0 0 5 .5 .5 .5 0 0
void plastic m_ring 0 0 5 .5 .5 .5 0 0
void plastic m_disk 0 0 5 .5 .5 .5 0 0
m_sphere sphere ball 0 0 4 1 2 3 2
m_bubble bubble dome 0 0 4 10 0 0 1.5
m_cone cone horn 0 0 8
    0 0 0   0 0 2
    1 0.5
m_cup cup funnel 0 0 8 5 5 0 5 5 1 0.5 0
m_cylinder cylinder pipe 0 0 7 0 10 0 0 10 3 0.5
m_tube tube sleeve 0 0 7 0 20 0 3 20 0 0.25
m_ring ring washer 0 0 8 0 0 -5 0 0 1 1 2
m_disk ring plate 0 0 8 0 0 -8 0 0 -1 1.5 0

# the materials, each on a small polygon
void plastic red 0 0 5 0.6 0.1 0.1 0.04 0.09
void metal gold 0 0 5 0.9 0.7 0.3 0.9 0.16
void trans shade 0 0 7 0.8 0.8 0.8 0.04 0.0 0.5 0.2
void glass pane 0 0 3 0.9 0.9 0.9
void glass thick 0 0 4 0.8 0.8 0.8 1.4
void dielectric water 0 0 5 0.9 0.95 1 1.33 0
void mirror silver 0 0 3 0.95 0.95 0.95
void light lamp 0 0 3 10 9 8
void glow neon 0 0 4 2 3 4 0
void illum window 1 pane 0 3 5 5 5
void illum ghost 0 0 3 1 1 1
void spotlight spot 0 0 7 100 100 100 30 0 0 -1
red polygon p1 0 0 9 0 0 30 1 0 30 0 1 30
gold polygon p2 0 0 9 0 0 31 1 0 31 0 1 31
shade polygon p3 0 0 9 0 0 32 1 0 32 0 1 32
pane polygon p4 0 0 9 0 0 33 1 0 33 0 1 33
thick polygon p5 0 0 9 0 0 34 1 0 34 0 1 34
water polygon p6 0 0 9 0 0 35 1 0 35 0 1 35
silver polygon p7 0 0 9 0 0 36 1 0 36 0 1 36
neon polygon p8 0 0 9 0 0 37 1 0 37 0 1 37
window polygon p9 0 0 9 0 0 38 1 0 38 0 1 38
ghost polygon p10 0 0 9 0 0 39 1 0 39 0 1 39
void polygon p11 0 0 9 0 0 40 1 0 40 0 1 40
spot polygon p12 0 0 9 0 0 41 1 0 41 0 1 41
# a square light, counter-clockwise seen from above: it faces +z
lamp polygon ceiling 0 0 12
    0 0 20  2 0 20  2 2 20  0 2 20

void light sunlight 0 0 3 1e5 1e5 1e5
sunlight source sun 0 0 4 0 1 1 0.53
";
