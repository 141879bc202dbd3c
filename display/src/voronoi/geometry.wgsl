// The scene's (simplified) geometry drawn for its distances from the eye:
// what the Voronoi driver culls estimates and stops cones by.

@group(0) @binding(0) var<uniform> view: ViewU;

struct Out {
    @builtin(position) pos: vec4<f32>,
    @location(0) world: vec3<f32>,
};

@vertex
fn vs(@location(0) p: vec3<f32>) -> Out {
    var out: Out;
    out.pos = clip_position(view, p);
    out.world = p;
    return out;
}

@fragment
fn fs(in: Out) -> @location(0) vec4<f32> {
    return vec4<f32>(project_point(view, in.world).z, 0.0, 0.0, 1.0);
}
