// FXAA on the final image (Lottes' FXAA 3.11, the compact "PC console" variant) as a compute
// pass over a linear RGBA buffer. Rust side: engine/src/fxaa.rs.

// Keep in sync with `fxaa::FxaaParams`.
struct Params {
    width: u32,
    height: u32,
    pad: vec2<u32>,
};

@group(0) @binding(0) var<uniform> F: Params;
@group(0) @binding(1) var<storage, read> src: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> dst: array<vec4<f32>>;
// Per pixel: w = 1 keeps the pixel as it is (composite.wgsl: every sample on an unlit slice,
// whose colours are the colour map's and not an edge to smooth); w = 2 keeps it and its eight
// neighbours (a multisampled surface's pixel: its samples smoothed its edges, and FXAA beside
// it, whose corner fetches reach the diagonal pixels, would smear it outwards).
@group(0) @binding(3) var<storage, read> keep: array<vec4<f32>>;

fn kept(p: vec2<i32>) -> f32 {
    let q = clamp(p, vec2<i32>(0), vec2<i32>(i32(F.width) - 1, i32(F.height) - 1));
    return keep[u32(q.x) + F.width * u32(q.y)].w;
}

fn texel(p: vec2<i32>) -> vec4<f32> {
    let q = clamp(p, vec2<i32>(0), vec2<i32>(i32(F.width) - 1, i32(F.height) - 1));
    return src[u32(q.x) + F.width * u32(q.y)];
}

// Bilinear fetch at a continuous pixel position (texel centres at half-integers).
fn fetch(t: vec2<f32>) -> vec4<f32> {
    let s = t - vec2<f32>(0.5);
    let b = vec2<i32>(floor(s));
    let f = s - floor(s);
    let a = mix(texel(b), texel(b + vec2<i32>(1, 0)), f.x);
    let c = mix(texel(b + vec2<i32>(0, 1)), texel(b + vec2<i32>(1, 1)), f.x);
    return mix(a, c, f.y);
}

// Perceptual luma of linear colour (sqrt approximates the display encoding).
fn luma(c: vec4<f32>) -> f32 {
    return sqrt(max(dot(c.rgb, vec3<f32>(0.299, 0.587, 0.114)), 0.0));
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= F.width || id.y >= F.height) {
        return;
    }
    let p = vec2<i32>(id.xy);
    let centre = vec2<f32>(id.xy) + vec2<f32>(0.5);
    let m = texel(p);
    var beside = 0.0;
    for (var dy = -1; dy <= 1; dy = dy + 1) {
        for (var dx = -1; dx <= 1; dx = dx + 1) {
            beside = max(beside, kept(p + vec2<i32>(dx, dy)));
        }
    }
    if (keep[id.x + F.width * id.y].w > 0.5 || beside > 1.5) {
        dst[id.x + F.width * id.y] = m;
        return;
    }
    let l_m = luma(m);
    let l_nw = luma(fetch(centre + vec2<f32>(-0.5, -0.5)));
    let l_ne = luma(fetch(centre + vec2<f32>(0.5, -0.5)));
    let l_sw = luma(fetch(centre + vec2<f32>(-0.5, 0.5)));
    let l_se = luma(fetch(centre + vec2<f32>(0.5, 0.5)));
    let l_min = min(l_m, min(min(l_nw, l_ne), min(l_sw, l_se)));
    let l_max = max(l_m, max(max(l_nw, l_ne), max(l_sw, l_se)));
    let idx = id.x + F.width * id.y;
    // Low contrast: no edge (FXAA's edge threshold 1/8, minimum 1/32).
    if (l_max - l_min < max(1.0 / 32.0, l_max / 8.0)) {
        dst[idx] = m;
        return;
    }
    // Edge direction from the diagonal luma differences (pixel y down).
    var dir = vec2<f32>(-((l_nw + l_ne) - (l_sw + l_se)), (l_nw + l_sw) - (l_ne + l_se));
    let reduce = max((l_nw + l_ne + l_sw + l_se) * 0.25 * (1.0 / 8.0), 1.0 / 128.0);
    let rcp = 1.0 / (min(abs(dir.x), abs(dir.y)) + reduce);
    dir = clamp(dir * rcp, vec2<f32>(-8.0), vec2<f32>(8.0));
    let a = 0.5 * (fetch(centre + dir * (1.0 / 3.0 - 0.5)) + fetch(centre + dir * (2.0 / 3.0 - 0.5)));
    let b = a * 0.5 + 0.25 * (fetch(centre - dir * 0.5) + fetch(centre + dir * 0.5));
    let l_b = luma(b);
    // Colour and alpha (coverage) blended alike: an image composited over black stays
    // premultiplied (engine/src/fxaa.rs).
    if (l_b < l_min || l_b > l_max) {
        dst[idx] = a;
    } else {
        dst[idx] = b;
    }
}
