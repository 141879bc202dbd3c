// Voronoi cones (holodeck paper, 2.4.4): each estimate is the apex of a
// cone drawn with depth testing in pixel space; all cones have one slope,
// so each pixel shows its nearest estimate. With scene geometry drawn
// first into a distance texture, estimates whose depth differs from it by
// more than the tolerance are dropped, and cones stop where the geometry's
// depth stops matching theirs (silhouettes stay sharp).

struct Cones {
    // Target width and height in pixels, depth scale, 1 when culling.
    size: vec4<f32>,
    // Relative depth tolerance; the rest unused.
    params: vec4<f32>,
};

@group(0) @binding(0) var<uniform> u: Cones;
@group(0) @binding(1) var distance: texture_2d<f32>;

struct Instance {
    // Apex in target pixels (x right, y down), depth (negative: escaped), radius.
    @location(0) apex: vec4<f32>,
    // Linear radiance, and the triangles in the fan.
    @location(1) color: vec4<f32>,
};

struct Out {
    @builtin(position) pos: vec4<f32>,
    @location(0) color: vec3<f32>,
    @location(1) @interpolate(flat) depth: f32,
};

// True where the scene's geometry says the estimate is not what shows.
fn mismatch(depth: f32, at: vec2<f32>) -> bool {
    if u.size.w < 0.5 {
        return false;
    }
    let dims = vec2<i32>(textureDimensions(distance));
    let p = clamp(vec2<i32>(floor(at)), vec2<i32>(0, 0), dims - vec2<i32>(1, 1));
    let g = textureLoad(distance, p, 0).r;
    if g < 0.0 {
        // No geometry there: nothing to judge by.
        return false;
    }
    if depth < 0.0 {
        // A ray that escaped where the geometry has a surface.
        return true;
    }
    return abs(depth - g) > u.params.x * g;
}

@vertex
fn vs(@builtin(vertex_index) vi: u32, inst: Instance) -> Out {
    let n = max(u32(inst.color.w + 0.5), 3u);
    let tri = vi / 3u;
    let corner = vi % 3u;
    var off = vec2<f32>(0.0, 0.0);
    var r = 0.0;
    if corner != 0u {
        let k = f32(tri + corner - 1u);
        let a = 6.28318530718 * k / f32(n);
        // The fan's polygon circumscribes the cone's circle.
        r = inst.apex.w / cos(3.14159265359 / f32(n));
        off = r * vec2<f32>(cos(a), sin(a));
    }
    let px = inst.apex.xy + off;
    var out: Out;
    out.pos = vec4<f32>(px.x / u.size.x * 2.0 - 1.0, 1.0 - px.y / u.size.y * 2.0, r / u.size.z, 1.0);
    if mismatch(inst.apex.z, inst.apex.xy) {
        // Every corner outside the clip volume: nothing drawn.
        out.pos = vec4<f32>(2.0, 2.0, 2.0, 1.0);
    }
    out.color = inst.color.rgb;
    out.depth = inst.apex.z;
    return out;
}

@fragment
fn fs(in: Out) -> @location(0) vec4<f32> {
    if mismatch(in.depth, in.pos.xy) {
        discard;
    }
    return vec4<f32>(in.color, 1.0);
}
