// The sample mesh: vertices at the estimates' world points, Gouraud-shaded
// (the rasterizer interpolates the vertices' radiance), depth-tested so
// that it can be drawn from eyes other than the canonical one.

@group(0) @binding(0) var<uniform> view: ViewU;

struct Vertex {
    // World position relative to the canonical eye.
    @location(0) position: vec4<f32>,
    // Linear radiance.
    @location(1) color: vec4<f32>,
};

struct Out {
    @builtin(position) pos: vec4<f32>,
    @location(0) color: vec3<f32>,
};

@vertex
fn vs(v: Vertex) -> Out {
    var out: Out;
    out.pos = clip_position(view, v.position.xyz);
    out.color = v.color.rgb;
    return out;
}

@fragment
fn fs(in: Out) -> @location(0) vec4<f32> {
    return vec4<f32>(in.color, 1.0);
}
