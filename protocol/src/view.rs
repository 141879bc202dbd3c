//! Views in Radiance's notation (`-vtv -vp x y z -vd x y z -vu x y z -vh 60 -vv 45`):
//! how image coordinates map to rays, and world points back to the image.
//!
//! Image coordinates `(x, y)` run over [0, 1]², x to the right, y upward (row
//! 0 of a picture is y = 1). Pure arithmetic; shared by the reference renderer
//! and the displays.

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// Projection type (Radiance's -vt letter).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum ViewType {
    /// `-vtv`: perspective.
    Perspective,
    /// `-vta`: angular fisheye (equidistant).
    Angular,
    /// `-vth`: hemispherical fisheye (orthographic projection of the hemisphere).
    Hemispherical,
    /// `-vtl`: parallel; -vh and -vv are the image size in world units.
    Parallel,
}

/// A view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct View {
    /// Projection.
    pub kind: ViewType,
    /// Eye position.
    pub position: DVec3,
    /// Viewing direction (normalized).
    pub direction: DVec3,
    /// Up vector as given.
    pub up: DVec3,
    /// Horizontal field (degrees; world units for parallel views).
    pub horizontal: f64,
    /// Vertical field.
    pub vertical: f64,
    /// Horizontal shift of the image, in image widths.
    pub shift: f64,
    /// Vertical lift, in image heights.
    pub lift: f64,
    /// Fore clipping distance (`-vo`): nothing nearer the eye than this
    /// (a plane across the view direction; a sphere for fisheyes) is seen.
    #[serde(default)]
    pub fore: f64,
    /// Aft clipping distance (`-va`): nothing farther is seen (black, as
    /// in Radiance); 0 for none.
    #[serde(default)]
    pub aft: f64,
}

/// What is wrong with a view specification.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ViewError {
    /// An option this parser does not know.
    #[error("unknown view option {0:?} (known: -vtv -vta -vth -vtl -vp -vd -vu -vh -vv -vs -vl -vo -va)")]
    UnknownOption(String),
    /// An option without enough numbers after it.
    #[error("view option {option} needs {needs} number(s)")]
    MissingValue {
        /// The option.
        option: String,
        /// How many numbers it takes.
        needs: usize,
    },
    /// A value that is not a number.
    #[error("view option {option}: {value:?} is not a number")]
    NotANumber {
        /// The option.
        option: String,
        /// The text found.
        value: String,
    },
    /// A geometrically impossible view.
    #[error("impossible view: {0}")]
    Impossible(String),
}

impl Default for View {
    fn default() -> Self {
        View {
            kind: ViewType::Perspective,
            position: DVec3::ZERO,
            direction: DVec3::X,
            up: DVec3::Z,
            horizontal: 45.0,
            vertical: 45.0,
            shift: 0.0,
            lift: 0.0,
            fore: 0.0,
            aft: 0.0,
        }
    }
}

/// Words Radiance writes before a view's options (`rview -vtv …` from
/// rview's `view` command, `VIEW= -vtv …` in a picture's header), skipped
/// where they lead a view.
const PREFIXES: [&str; 7] = ["rview", "rpict", "rvu", "rholo", "rhpict", "VIEW=", "view="];

impl View {
    /// Parses options over the default view (looking along +x, z up, 45 x 45 degrees).
    pub fn parse(spec: &str) -> Result<View, ViewError> {
        View::default().with(spec)
    }

    /// Parses a file of views, one per line (a walkthrough path or a set of
    /// views). Each line starts from the view before it, so later lines may
    /// give only what changes; leading words that are not options (`rvu`,
    /// `rview`, `VIEW=`, as in Radiance view files) are skipped, as are blank
    /// lines and `#` comments. Errors carry the 1-based line number.
    pub fn parse_list(text: &str) -> Result<Vec<View>, (usize, ViewError)> {
        let mut views = Vec::new();
        let mut current = View::default();
        for (i, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("").trim();
            let options = match line.find(" -").map(|at| at + 1) {
                _ if line.starts_with('-') => line,
                Some(at) => &line[at..],
                None if line.is_empty() => continue,
                None => return Err((i + 1, ViewError::UnknownOption(line.to_string()))),
            };
            current = current.with(options).map_err(|e| (i + 1, e))?;
            views.push(current.clone());
        }
        Ok(views)
    }

    /// Applies options to this view and validates the result.
    pub fn with(mut self, spec: &str) -> Result<View, ViewError> {
        let mut words: Vec<&str> = spec.split_whitespace().collect();
        // `VIEW=-vtv` (no space) as some headers have it.
        if let Some(rest) = words
            .first()
            .and_then(|w| w.strip_prefix("VIEW="))
            .filter(|r| !r.is_empty())
        {
            words[0] = rest;
        }
        let mut i = words.iter().take_while(|w| PREFIXES.contains(w)).count();
        while i < words.len() {
            let opt = words[i];
            let nums = |n: usize| -> Result<Vec<f64>, ViewError> {
                let vals = words.get(i + 1..i + 1 + n).ok_or(ViewError::MissingValue {
                    option: opt.into(),
                    needs: n,
                })?;
                vals.iter()
                    .map(|v| {
                        v.parse().map_err(|_| ViewError::NotANumber {
                            option: opt.into(),
                            value: v.to_string(),
                        })
                    })
                    .collect()
            };
            let vec3 = |v: Vec<f64>| DVec3::new(v[0], v[1], v[2]);
            let used = match opt {
                "-vtv" | "-vta" | "-vth" | "-vtl" => {
                    self.kind = match opt {
                        "-vtv" => ViewType::Perspective,
                        "-vta" => ViewType::Angular,
                        "-vth" => ViewType::Hemispherical,
                        _ => ViewType::Parallel,
                    };
                    0
                }
                "-vp" => {
                    self.position = vec3(nums(3)?);
                    3
                }
                "-vd" => {
                    self.direction = vec3(nums(3)?);
                    3
                }
                "-vu" => {
                    self.up = vec3(nums(3)?);
                    3
                }
                "-vh" => {
                    self.horizontal = nums(1)?[0];
                    1
                }
                "-vv" => {
                    self.vertical = nums(1)?[0];
                    1
                }
                "-vs" => {
                    self.shift = nums(1)?[0];
                    1
                }
                "-vl" => {
                    self.lift = nums(1)?[0];
                    1
                }
                "-vo" => {
                    self.fore = nums(1)?[0];
                    1
                }
                "-va" => {
                    self.aft = nums(1)?[0];
                    1
                }
                other => return Err(ViewError::UnknownOption(other.to_string())),
            };
            i += 1 + used;
        }
        self.validate()
    }

    fn validate(mut self) -> Result<View, ViewError> {
        let finite = [self.position, self.direction, self.up].iter().all(|v| v.is_finite())
            && [self.horizontal, self.vertical, self.shift, self.lift]
                .iter()
                .all(|v| v.is_finite());
        if !(finite && self.fore.is_finite() && self.aft.is_finite()) {
            return Err(ViewError::Impossible("a value is not finite".into()));
        }
        if self.fore < 0.0 || self.aft < 0.0 {
            return Err(ViewError::Impossible(format!(
                "clipping distances -vo {} -va {} must not be negative",
                self.fore, self.aft
            )));
        }
        if self.aft > 0.0 && self.aft <= self.fore {
            return Err(ViewError::Impossible(format!(
                "aft clipping -va {} must lie beyond fore clipping -vo {}",
                self.aft, self.fore
            )));
        }
        // Scale by the largest component first: tiny and huge vectors normalize
        // without underflow or overflow.
        let unit = |v: DVec3| {
            let m = v.abs().max_element();
            if m > 0.0 {
                (v / m).normalize()
            } else {
                DVec3::ZERO
            }
        };
        self.direction = unit(self.direction);
        if self.direction == DVec3::ZERO {
            return Err(ViewError::Impossible("view direction -vd is zero".into()));
        }
        let up = unit(self.up);
        if up == DVec3::ZERO || up.cross(self.direction).length() < 1e-9 {
            return Err(ViewError::Impossible(
                "up vector -vu is zero or parallel to the view direction".into(),
            ));
        }
        self.up = up;
        let (lo, hi) = match self.kind {
            ViewType::Perspective => (0.0, 180.0),
            ViewType::Angular => (0.0, 360.0),
            ViewType::Hemispherical => (0.0, 180.0),
            ViewType::Parallel => (0.0, f64::INFINITY),
        };
        for (name, v) in [("-vh", self.horizontal), ("-vv", self.vertical)] {
            let ok = v > lo && (v < hi || (v == hi && self.kind != ViewType::Perspective));
            if !ok {
                return Err(ViewError::Impossible(format!("{name} {v} is outside ({lo}, {hi})")));
            }
        }
        Ok(self)
    }

    /// Prints the view as options that [`View::parse`] reads back exactly.
    pub fn to_spec(&self) -> String {
        let t = match self.kind {
            ViewType::Perspective => "v",
            ViewType::Angular => "a",
            ViewType::Hemispherical => "h",
            ViewType::Parallel => "l",
        };
        let v = |d: DVec3| format!("{} {} {}", d.x, d.y, d.z);
        format!(
            "-vt{t} -vp {} -vd {} -vu {} -vh {} -vv {} -vo {} -va {} -vs {} -vl {}",
            v(self.position),
            v(self.direction),
            v(self.up),
            self.horizontal,
            self.vertical,
            self.fore,
            self.aft,
            self.shift,
            self.lift
        )
    }

    /// The ray parameter at which a ray from [`View::ray`] (`origin`, unit
    /// `dir`) crosses the aft clipping plane; infinite without one.
    pub fn aft_limit(&self, origin: DVec3, dir: DVec3) -> f64 {
        if self.aft <= 0.0 {
            return f64::INFINITY;
        }
        match self.kind {
            ViewType::Perspective | ViewType::Parallel => {
                let along = dir.dot(self.direction);
                if along <= 0.0 {
                    return f64::INFINITY;
                }
                (self.aft - (origin - self.position).dot(self.direction)) / along
            }
            ViewType::Angular | ViewType::Hemispherical => self.aft - self.fore,
        }
    }

    /// Where a ray along unit `dir` from the eye starts: on the fore
    /// clipping plane (sphere for fisheyes), or at the eye without one.
    fn fore_origin(&self, origin: DVec3, dir: DVec3) -> DVec3 {
        if self.fore <= 0.0 {
            return origin;
        }
        match self.kind {
            ViewType::Perspective | ViewType::Parallel => {
                let along = dir.dot(self.direction).max(1e-12);
                origin + dir * (self.fore / along)
            }
            ViewType::Angular | ViewType::Hemispherical => origin + dir * self.fore,
        }
    }

    /// Unit right and up vectors of the image plane.
    pub fn basis(&self) -> (DVec3, DVec3) {
        let right = self.direction.cross(self.up).normalize();
        let up = right.cross(self.direction).normalize();
        (right, up)
    }

    /// The ray through image point (x, y): origin (on the fore clipping
    /// plane where there is one) and unit direction, or `None` outside a
    /// fisheye's circle.
    pub fn ray(&self, x: f64, y: f64) -> Option<(DVec3, DVec3)> {
        let (origin, dir) = self.eye_ray(x, y)?;
        Some((self.fore_origin(origin, dir), dir))
    }

    /// [`View::ray`] from the eye, before fore clipping.
    fn eye_ray(&self, x: f64, y: f64) -> Option<(DVec3, DVec3)> {
        let (right, up) = self.basis();
        let (dx, dy) = (x - 0.5 + self.shift, y - 0.5 + self.lift);
        match self.kind {
            ViewType::Perspective => {
                let h = (self.horizontal.to_radians() / 2.0).tan() * 2.0;
                let v = (self.vertical.to_radians() / 2.0).tan() * 2.0;
                Some((
                    self.position,
                    (self.direction + right * (dx * h) + up * (dy * v)).normalize(),
                ))
            }
            ViewType::Angular => {
                let (ax, ay) = (dx * self.horizontal.to_radians(), dy * self.vertical.to_radians());
                let r = (ax * ax + ay * ay).sqrt();
                if r > std::f64::consts::PI {
                    return None;
                }
                if r == 0.0 {
                    return Some((self.position, self.direction));
                }
                let d = self.direction * r.cos() + (right * ax + up * ay) * (r.sin() / r);
                Some((self.position, d.normalize()))
            }
            ViewType::Hemispherical => {
                let (hx, hy) = (
                    dx * 2.0 * (self.horizontal.to_radians() / 2.0).sin(),
                    dy * 2.0 * (self.vertical.to_radians() / 2.0).sin(),
                );
                let r2 = hx * hx + hy * hy;
                if r2 > 1.0 {
                    return None;
                }
                Some((
                    self.position,
                    (self.direction * (1.0 - r2).sqrt() + right * hx + up * hy).normalize(),
                ))
            }
            ViewType::Parallel => {
                let o = self.position + right * (dx * self.horizontal) + up * (dy * self.vertical);
                Some((o, self.direction))
            }
        }
    }

    /// A generator of this view's rays with the per-view trigonometry done
    /// once: for renderers that ask for millions of rays.
    pub fn rays(&self) -> ViewRays {
        let (right, up) = self.basis();
        let (h, v) = match self.kind {
            ViewType::Perspective => (
                (self.horizontal.to_radians() / 2.0).tan() * 2.0,
                (self.vertical.to_radians() / 2.0).tan() * 2.0,
            ),
            _ => (0.0, 0.0),
        };
        ViewRays {
            view: self.clone(),
            right,
            up,
            h,
            v,
        }
    }

    /// The directions a perspective view shows (see [`Frustum`]); `None` for
    /// the other view types, whose frames are not bounded by four planes.
    pub fn frustum(&self) -> Option<Frustum> {
        if self.kind != ViewType::Perspective {
            return None;
        }
        let corners = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)].map(|(x, y)| self.ray(x, y).map(|r| r.1));
        let [Some(a), Some(b), Some(c), Some(d)] = corners else {
            return None;
        };
        let center = self.ray(0.5, 0.5)?.1;
        let mut out = [[0.0f32; 3]; 4];
        for (i, (p, q)) in [(a, b), (b, c), (c, d), (d, a)].into_iter().enumerate() {
            let mut n = p.cross(q).normalize_or_zero();
            if n.dot(center) < 0.0 {
                n = -n;
            }
            out[i] = n.as_vec3().to_array();
        }
        Some(Frustum(out))
    }

    /// Where a world point appears: image (x, y) and its distance along the
    /// view (depth), or `None` if it is behind a perspective eye or outside a fisheye.
    pub fn project(&self, p: DVec3) -> Option<(f64, f64, f64)> {
        self.projector().project(p)
    }

    /// A projector of world points into this view with the per-view
    /// trigonometry done once: for displays that reproject millions of samples.
    pub fn projector(&self) -> ViewProjector {
        let (right, up) = self.basis();
        let (sx, sy) = match self.kind {
            ViewType::Perspective => (
                (self.horizontal.to_radians() / 2.0).tan() * 2.0,
                (self.vertical.to_radians() / 2.0).tan() * 2.0,
            ),
            ViewType::Angular => (self.horizontal.to_radians(), self.vertical.to_radians()),
            ViewType::Hemispherical => (
                2.0 * (self.horizontal.to_radians() / 2.0).sin(),
                2.0 * (self.vertical.to_radians() / 2.0).sin(),
            ),
            ViewType::Parallel => (self.horizontal, self.vertical),
        };
        ViewProjector {
            kind: self.kind,
            position: self.position,
            direction: self.direction,
            right,
            up,
            sx,
            sy,
            shift: self.shift,
            lift: self.lift,
            fore: self.fore,
            aft: if self.aft > 0.0 { self.aft } else { f64::INFINITY },
        }
    }
}

/// The directions a perspective view shows: four planes through the eye,
/// each given by its inward unit normal (a direction `d` is in the frame when
/// `n · d >= 0` for all four). Samplers restrict rays traced near an eye to
/// them, so that a display's rays land in its frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Frustum(pub [[f32; 3]; 4]);

impl Frustum {
    /// True when direction `d` (any length) is in the frame, or within
    /// `slack` (a sine) of it.
    pub fn contains(&self, d: DVec3, slack: f64) -> bool {
        let d = d.normalize_or_zero();
        self.0
            .iter()
            .all(|n| DVec3::new(f64::from(n[0]), f64::from(n[1]), f64::from(n[2])).dot(d) >= -slack)
    }

    /// True when every number is finite.
    pub fn is_finite(&self) -> bool {
        self.0.iter().flatten().all(|v| v.is_finite())
    }
}

/// Projection into a view with its constants precomputed (see [`View::projector`]).
#[derive(Clone, Debug)]
pub struct ViewProjector {
    /// The projection.
    pub kind: ViewType,
    /// The eye.
    pub position: DVec3,
    /// The view direction, as given (depths along it are not normalized).
    pub direction: DVec3,
    /// Unit vector to the right of the view.
    pub right: DVec3,
    /// Unit vector up in the view.
    pub up: DVec3,
    /// Horizontal scale: the tangent factor, the field in radians, the
    /// hemisphere's sine factor or the parallel width, by view type.
    pub sx: f64,
    /// Vertical scale, as `sx`.
    pub sy: f64,
    /// The view's horizontal shift (`-vs`), in frame widths.
    pub shift: f64,
    /// The view's vertical lift (`-vl`), in frame heights.
    pub lift: f64,
    /// Clipping range: along the view direction (perspective, parallel) or
    /// from the eye (fisheyes).
    pub fore: f64,
    /// The far end of the clipping range (infinity: none).
    pub aft: f64,
}

impl ViewProjector {
    /// The same as [`View::project`].
    #[inline]
    pub fn project(&self, p: DVec3) -> Option<(f64, f64, f64)> {
        let d = p - self.position;
        let (fx, fy, fz) = (d.dot(self.right), d.dot(self.up), d.dot(self.direction));
        let (dx, dy, depth) = match self.kind {
            ViewType::Perspective => {
                if fz <= 0.0 || fz < self.fore || fz > self.aft {
                    return None;
                }
                (fx / fz / self.sx, fy / fz / self.sy, d.length())
            }
            ViewType::Angular => {
                let len = d.length();
                if len == 0.0 || len < self.fore || len > self.aft {
                    return None;
                }
                let r = (fz / len).clamp(-1.0, 1.0).acos();
                let s = (fx * fx + fy * fy).sqrt();
                let (ux, uy) = if s > 0.0 { (fx / s, fy / s) } else { (0.0, 0.0) };
                (ux * r / self.sx, uy * r / self.sy, len)
            }
            ViewType::Hemispherical => {
                let len = d.length();
                if len == 0.0 || fz < 0.0 || len < self.fore || len > self.aft {
                    return None;
                }
                (fx / len / self.sx, fy / len / self.sy, len)
            }
            ViewType::Parallel => {
                if fz < self.fore || fz > self.aft {
                    return None;
                }
                (fx / self.sx, fy / self.sy, fz)
            }
        };
        Some((dx + 0.5 - self.shift, dy + 0.5 - self.lift, depth))
    }
}

/// Rays of a view with its constants precomputed (see [`View::rays`]).
#[derive(Clone, Debug)]
pub struct ViewRays {
    view: View,
    right: DVec3,
    up: DVec3,
    h: f64,
    v: f64,
}

impl ViewRays {
    /// The same ray as [`View::ray`].
    #[inline]
    pub fn ray(&self, x: f64, y: f64) -> Option<(DVec3, DVec3)> {
        if self.view.kind != ViewType::Perspective {
            return self.view.ray(x, y);
        }
        let (dx, dy) = (x - 0.5 + self.view.shift, y - 0.5 + self.view.lift);
        let d = (self.view.direction + self.right * (dx * self.h) + self.up * (dy * self.v)).normalize();
        Some((self.view.fore_origin(self.view.position, d), d))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn parses_radiance_options_and_round_trips() {
        let v = View::parse("-vtv -vp 1 2 1.5 -vd 0 1 0 -vu 0 0 1 -vh 60 -vv 40").unwrap();
        assert_eq!(v.position, DVec3::new(1.0, 2.0, 1.5));
        assert_eq!(v.direction, DVec3::Y);
        assert_eq!(View::parse(&v.to_spec()).unwrap(), v);
        let (o, d) = v.ray(0.5, 0.5).unwrap();
        assert_eq!(o, v.position);
        assert!((d - DVec3::Y).length() < 1e-12);
        // Right edge is 30 degrees to the right (+x when looking along +y with z up).
        let fast = v.rays();
        for (x, y) in [(0.0, 0.0), (0.3, 0.9), (1.0, 0.5)] {
            assert_eq!(fast.ray(x, y), v.ray(x, y), "precomputed rays are the same rays");
        }
        let (_, d) = v.ray(1.0, 0.5).unwrap();
        assert!((d.x - 30f64.to_radians().sin()).abs() < 1e-12 && d.x > 0.0);
    }

    #[test]
    fn radiance_view_lines_are_read_as_rview_and_pictures_write_them() {
        let line = "rview -vtv -vp 2.5 1 1.6 -vd 0 1 0 -vu 0 0 1 -vh 60 -vv 45 -vo 1.5 -va 9 -vs 0.1 -vl -0.05";
        let v = View::parse(line).unwrap();
        assert_eq!((v.fore, v.aft, v.shift, v.lift), (1.5, 9.0, 0.1, -0.05));
        for header in [
            "VIEW= -vtv -vp 2.5 1 1.6 -vd 0 1 0 -vu 0 0 1 -vh 60 -vv 45 -vo 1.5 -va 9 -vs 0.1 -vl -0.05",
            "VIEW=-vtv -vp 2.5 1 1.6 -vd 0 1 0 -vu 0 0 1 -vh 60 -vv 45 -vo 1.5 -va 9 -vs 0.1 -vl -0.05",
            "rpict -vtv -vp 2.5 1 1.6 -vd 0 1 0 -vu 0 0 1 -vh 60 -vv 45 -vo 1.5 -va 9 -vs 0.1 -vl -0.05",
        ] {
            assert_eq!(View::parse(header).unwrap(), v, "{header}");
        }
        assert_eq!(View::parse(&v.to_spec()).unwrap(), v);
        // Rays start on the fore plane, 1.5 along the view direction.
        let (o, d) = v.ray(0.9, 0.2).unwrap();
        assert!(((o - v.position).dot(v.direction) - 1.5).abs() < 1e-12);
        assert!(
            ((o - v.position).normalize() - d).length() < 1e-12,
            "on the ray from the eye"
        );
        assert_eq!(v.rays().ray(0.9, 0.2), Some((o, d)));
        // The aft plane 9 along the view direction.
        let t = v.aft_limit(o, d);
        assert!(((o + d * t - v.position).dot(v.direction) - 9.0).abs() < 1e-9);
        // Points outside the clipping range are not projected.
        let p = |along: f64| v.position + v.direction * along;
        assert!(v.project(p(1.0)).is_none(), "nearer than -vo");
        assert!(v.project(p(5.0)).is_some());
        assert!(v.project(p(9.5)).is_none(), "beyond -va");
        assert!(View::parse("-vo 2 -va 1").unwrap_err().to_string().contains("beyond"));
        assert!(View::parse("-vo -1").is_err());
        assert_eq!(
            View::parse("-vp 0 0 0").unwrap().aft_limit(DVec3::ZERO, DVec3::X),
            f64::INFINITY
        );
    }

    #[test]
    fn refuses_bad_views_with_reasons() {
        assert!(matches!(View::parse("-vq 1"), Err(ViewError::UnknownOption(_))));
        assert!(matches!(
            View::parse("-vp 1 2"),
            Err(ViewError::MissingValue { needs: 3, .. })
        ));
        assert!(matches!(View::parse("-vh wide"), Err(ViewError::NotANumber { .. })));
        assert!(View::parse("-vd 0 0 0").unwrap_err().to_string().contains("zero"));
        assert!(View::parse("-vd 0 0 1 -vu 0 0 2")
            .unwrap_err()
            .to_string()
            .contains("parallel"));
        assert!(View::parse("-vtv -vh 180").is_err());
        assert!(View::parse("-vta -vh 360 -vv 360").is_ok());
    }

    #[test]
    fn extreme_magnitudes_normalize_cleanly() {
        let v = View::parse("-vd 1e-170 0 0 -vu 0 0 1e200").unwrap();
        assert_eq!((v.direction, v.up), (DVec3::X, DVec3::Z));
        let v = View::parse("-vd 1.6e-162 0 0").unwrap();
        assert!((v.direction.length() - 1.0).abs() < 1e-15);
        assert!(View::parse("-vd 1e160 0 0 -vu 0 0 1").is_ok());
    }

    proptest! {
        #[test]
        fn project_inverts_ray(
            kind in 0usize..4, x in 0.05f64..0.95, y in 0.05f64..0.95, dist in 0.5f64..50.0,
            h in 20.0f64..150.0, v in 20.0f64..150.0, yaw in -3.0f64..3.0, pitch in -1.2f64..1.2,
        ) {
            let kind = [ViewType::Perspective, ViewType::Angular, ViewType::Hemispherical, ViewType::Parallel][kind];
            let dir = DVec3::new(yaw.cos() * pitch.cos(), yaw.sin() * pitch.cos(), pitch.sin());
            let view = View { kind, position: DVec3::new(1.0, -2.0, 0.5), direction: dir, horizontal: h, vertical: v, ..View::default() }
                .validate().unwrap();
            if let Some((o, d)) = view.ray(x, y) {
                let (px, py, depth) = view.project(o + d * dist).unwrap();
                prop_assert!((px - x).abs() < 1e-9 && (py - y).abs() < 1e-9, "{kind:?}: ({x},{y}) -> ({px},{py})");
                if kind != ViewType::Parallel {
                    prop_assert!((depth - dist).abs() < 1e-9);
                }
            }
        }
    }

    #[test]
    fn a_frustum_holds_the_frame_and_nothing_else() {
        let v = View::parse("-vtv -vp 1 2 1.5 -vd 1 0.2 -0.1 -vu 0 0 1 -vh 75 -vv 56 -vs 0.1").unwrap();
        let f = v.frustum().unwrap();
        for (x, y) in [(0.01, 0.01), (0.5, 0.5), (0.99, 0.3), (0.2, 0.99)] {
            assert!(f.contains(v.ray(x, y).unwrap().1, 0.0), "({x}, {y})");
        }
        for (x, y) in [(-0.05, 0.5), (1.05, 0.5), (0.5, -0.05), (0.5, 1.05)] {
            let (_, d) = v.rays().ray(x, y).unwrap();
            assert!(!f.contains(d, 0.0), "({x}, {y})");
        }
        assert!(!f.contains(-v.direction, 0.0));
        assert!(View::parse("-vta -vh 180 -vv 180").unwrap().frustum().is_none());
    }

    #[test]
    fn view_files_list_one_view_per_line_each_from_the_last() {
        let text = "# a path\nrvu -vtv -vp 1 2 3 -vd 0 1 0 -vh 60 -vv 40\n\nVIEW= -vp 1 3 3\n-vd 1 0 0\n";
        let views = View::parse_list(text).unwrap();
        assert_eq!(views.len(), 3);
        assert_eq!(views[1].position, DVec3::new(1.0, 3.0, 3.0));
        assert_eq!(views[1].horizontal, 60.0, "later lines keep what they do not change");
        assert_eq!(views[2].direction, DVec3::X);
        let err = View::parse_list("-vp 0 0 0\n-vp 1 x 2\n").unwrap_err();
        assert_eq!(err.0, 2);
        assert!(View::parse_list("hello\n").is_err());
    }
}
