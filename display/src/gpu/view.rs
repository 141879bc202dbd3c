//! The view projection on the GPU: the same arithmetic as
//! [`holodeck_protocol::ViewProjector::project`] for all four Radiance view
//! types, so a point drawn by a shader lands where the CPU drivers put it.

use glam::DVec3;
use holodeck_protocol::ViewType;

use crate::driver::Viewport;

/// The nearest distance drawn, in world units. Depth is reversed (1 at the
/// near plane, 0 at infinity), so far scenery keeps its precision and
/// escaped rays can be drawn at great distances.
pub const NEAR: f32 = 1e-3;

/// A view as the shaders take it (a uniform buffer): the eye relative to
/// an origin the vertex positions are also relative to (so that f32 keeps
/// millimeters in a large scene), the basis and the projection constants.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct ViewUniform {
    /// Eye minus origin; w: the view type (0 perspective, 1 angular,
    /// 2 hemispherical, 3 parallel).
    pub eye: [f32; 4],
    /// Unit right vector; w: the horizontal scale.
    pub right: [f32; 4],
    /// Unit up vector; w: the vertical scale.
    pub up: [f32; 4],
    /// Unit view direction; w: the horizontal shift.
    pub dir: [f32; 4],
    /// The vertical lift, the near distance, the frame's width and height
    /// in pixels (of the target drawn into).
    pub extra: [f32; 4],
}

impl ViewUniform {
    /// `viewport`'s view relative to `origin`, drawn into a target of
    /// `width` x `height` pixels.
    pub fn new(viewport: &Viewport, origin: DVec3, width: u32, height: u32) -> ViewUniform {
        let v = &viewport.view;
        let (right, up) = v.basis();
        let dir = v.direction.normalize();
        let (kind, sx, sy) = match v.kind {
            ViewType::Perspective => (
                0.0,
                (v.horizontal.to_radians() / 2.0).tan() * 2.0,
                (v.vertical.to_radians() / 2.0).tan() * 2.0,
            ),
            ViewType::Angular => (1.0, v.horizontal.to_radians(), v.vertical.to_radians()),
            ViewType::Hemispherical => (
                2.0,
                2.0 * (v.horizontal.to_radians() / 2.0).sin(),
                2.0 * (v.vertical.to_radians() / 2.0).sin(),
            ),
            ViewType::Parallel => (3.0, v.horizontal, v.vertical),
        };
        let eye = (v.position - origin).as_vec3();
        let f = |d: DVec3, w: f64| [d.x as f32, d.y as f32, d.z as f32, w as f32];
        ViewUniform {
            eye: [eye.x, eye.y, eye.z, kind],
            right: f(right, sx),
            up: f(up, sy),
            dir: f(dir, v.shift),
            extra: [v.lift as f32, NEAR, width as f32, height as f32],
        }
    }
}

/// WGSL for the projection: `project_point` gives image x, y (0..1, y up),
/// the depth as the CPU measures it, and 1 where the point shows (0 behind
/// a perspective eye or outside a fisheye); `clip_position` the clip-space
/// position, perspective-correct for perspective views and affine for the
/// others (whose triangles the drivers keep small).
pub const PROJECT_WGSL: &str = r#"
struct ViewU {
    eye: vec4<f32>,
    right: vec4<f32>,
    up: vec4<f32>,
    dir: vec4<f32>,
    extra: vec4<f32>,
};

fn view_kind(v: ViewU) -> u32 {
    return u32(v.eye.w + 0.5);
}

fn project_point(v: ViewU, p: vec3<f32>) -> vec4<f32> {
    let d = p - v.eye.xyz;
    let fx = dot(d, v.right.xyz);
    let fy = dot(d, v.up.xyz);
    let fz = dot(d, v.dir.xyz);
    let len = length(d);
    var dx = 0.0;
    var dy = 0.0;
    var depth = len;
    var ok = 1.0;
    switch view_kind(v) {
        case 0u: {
            if fz <= 0.0 { ok = 0.0; }
            let z = max(fz, 1e-30);
            dx = fx / z / v.right.w;
            dy = fy / z / v.up.w;
        }
        case 1u: {
            if len == 0.0 { ok = 0.0; }
            let r = acos(clamp(fz / max(len, 1e-30), -1.0, 1.0));
            let s = sqrt(fx * fx + fy * fy);
            if s > 0.0 {
                dx = fx / s * r / v.right.w;
                dy = fy / s * r / v.up.w;
            }
        }
        case 2u: {
            if len == 0.0 || fz < 0.0 { ok = 0.0; }
            dx = fx / max(len, 1e-30) / v.right.w;
            dy = fy / max(len, 1e-30) / v.up.w;
        }
        default: {
            dx = fx / v.right.w;
            dy = fy / v.up.w;
            depth = fz;
        }
    }
    return vec4<f32>(dx + 0.5 - v.dir.w, dy + 0.5 - v.extra.x, depth, ok);
}

fn clip_position(v: ViewU, p: vec3<f32>) -> vec4<f32> {
    let near = v.extra.y;
    if view_kind(v) == 0u {
        let d = p - v.eye.xyz;
        let fx = dot(d, v.right.xyz);
        let fy = dot(d, v.up.xyz);
        let fz = dot(d, v.dir.xyz);
        return vec4<f32>(
            2.0 * fx / v.right.w - (2.0 * v.dir.w) * fz,
            2.0 * fy / v.up.w - (2.0 * v.extra.x) * fz,
            near,
            fz,
        );
    }
    let q = project_point(v, p);
    if q.w == 0.0 || q.z < near {
        // Outside the drawable range: beyond the clip volume.
        return vec4<f32>(0.0, 0.0, -1.0, 1.0);
    }
    return vec4<f32>(q.x * 2.0 - 1.0, q.y * 2.0 - 1.0, near / q.z, 1.0);
}
"#;
