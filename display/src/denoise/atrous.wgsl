// One pass of the variance-guided a-trous filter (atrous.rs is the
// reference: the same taps, weights and cut-offs, pixel for pixel).

struct Params {
    width: u32,
    height: u32,
    step: u32,
    sigma_normal: i32,
    sigma_luminance: f32,
    sigma_depth: f32,
    _pad0: f32,
    _pad1: f32,
};

@group(0) @binding(0) var<uniform> params: Params;
// rgb and variance of each pixel, read.
@group(0) @binding(1) var<storage, read> src: array<vec4<f32>>;
// rgb and variance of each pixel, written.
@group(0) @binding(2) var<storage, read_write> dst: array<vec4<f32>>;
// normal (xyz) and depth kind (w: 0 unknown, 1 finite, 2 sky).
@group(0) @binding(3) var<storage, read> normals: array<vec4<f32>>;
// depth and slope.
@group(0) @binding(4) var<storage, read> depths: array<vec2<f32>>;

const CUTOFF: f32 = 12.0;

fn kernel(i: i32) -> f32 {
    switch i {
        case 0, 4: { return 1.0 / 16.0; }
        case 1, 3: { return 1.0 / 4.0; }
        default: { return 3.0 / 8.0; }
    }
}

fn luminance(c: vec3<f32>) -> f32 {
    return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
}

// Depth dissimilarity, or a negative number where the tap is refused.
fn depth_term(p: u32, q: u32, dist: f32) -> f32 {
    let kp = normals[p].w;
    let kq = normals[q].w;
    if (kp < 0.5 || kq < 0.5) {
        return 0.0;
    }
    if (kp < 1.5 && kq < 1.5) {
        let a = depths[p];
        let b = depths[q];
        return abs(a.x - b.x) / (params.sigma_depth * (max(a.y, b.y) * dist + 2e-3 * max(a.x, b.x)) + 1e-6);
    }
    if (kp > 1.5 && kq > 1.5) {
        return 0.0;
    }
    return -1.0;
}

fn normal_weight(a: vec3<f32>, b: vec3<f32>) -> f32 {
    if (all(a == vec3<f32>(0.0)) || all(b == vec3<f32>(0.0))) {
        return 1.0;
    }
    let d = dot(a, b);
    if (d >= 1.0) {
        return 1.0;
    }
    var base = max(d, 0.0);
    var n = u32(max(params.sigma_normal, 0));
    var out = 1.0;
    loop {
        if (n == 0u) { break; }
        if ((n & 1u) == 1u) { out = out * base; }
        base = base * base;
        n = n >> 1u;
    }
    return out;
}

@compute @workgroup_size(8, 8)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let w = params.width;
    let h = params.height;
    if (id.x >= w || id.y >= h) {
        return;
    }
    let c = i32(id.x);
    let r = i32(id.y);
    let p = id.y * w + id.x;
    let step = i32(params.step);
    let a = src[p];
    let al = luminance(a.xyz);
    let asd = sqrt(max(a.w, 0.0));
    let an = normals[p].xyz;
    var sum_c = vec3<f32>(0.0);
    var sum_v = 0.0;
    var sum_w = 0.0;
    for (var j = 0; j < 5; j = j + 1) {
        let rr = r + (j - 2) * step;
        if (rr < 0 || rr >= i32(h)) {
            continue;
        }
        for (var i = 0; i < 5; i = i + 1) {
            let cc = c + (i - 2) * step;
            if (cc < 0 || cc >= i32(w)) {
                continue;
            }
            let q = u32(rr) * w + u32(cc);
            let k = kernel(i) * kernel(j);
            let b = src[q];
            var wt = k;
            if (q != p) {
                let bl = luminance(b.xyz);
                let bsd = sqrt(max(b.w, 0.0));
                let scale_l = params.sigma_luminance * min(asd, bsd) + 1e-6 + 1e-3 * min(al, bl);
                var e = abs(al - bl) / scale_l;
                if (e > CUTOFF) {
                    continue;
                }
                let dist = (abs(f32(i) - 2.0) + abs(f32(j) - 2.0)) * f32(step);
                let dt = depth_term(p, q, dist);
                if (dt < 0.0) {
                    continue;
                }
                e = e + dt;
                if (e > CUTOFF) {
                    continue;
                }
                wt = k * normal_weight(an, normals[q].xyz) * exp(-e);
            }
            sum_c = sum_c + b.xyz * wt;
            sum_v = sum_v + b.w * wt * wt;
            sum_w = sum_w + wt;
        }
    }
    dst[p] = vec4<f32>(sum_c / sum_w, sum_v / (sum_w * sum_w));
}
