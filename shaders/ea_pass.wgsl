// Emission-absorption through view-aligned slices (the `ea` baseline of `umbra render`).
// One invocation per pixel walks the slices front to back: slice k is the plane at distance
// z0 + (k + 0.5) dz from the eye along the viewing direction; the pixel's ray meets it at p,
// the field is sampled there trilinearly, mapped through the piecewise-linear transfer
// function, and composited with alpha = 1 - exp(-sigma * dz / cos) (extinction per world unit;
// dz / cos is the ray's length between two planes). The background is composited last.
// Samples without data (NaN in the volume) are uploaded as -3e38 and leave a gap.
// Conventions: engine/src/camera.rs. CPU twin: ea_pass::reference.

struct Params {
    inv_view_proj: mat4x4<f32>,
    world_to_index: mat4x4<f32>,
    eye: vec4<f32>,
    forward: vec4<f32>,
    background: vec4<f32>,
    dims: vec4<u32>,
    // z0, dz, unused, unused
    slicing: vec4<f32>,
    // n_slices, n_tf, width, height
    counts: vec4<u32>,
    // bricks per axis (x, y, z), brick edge in voxels
    bricks: vec4<u32>,
    // clipping planes (normal, offset), keeping normal . p <= offset; n_clip.x of them
    clip: array<vec4<f32>, 8>,
    n_clip: vec4<u32>,
};

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> field: array<f32>;
// Transfer function points: (value, r, g, b, extinction, 0, 0, 0) each.
@group(0) @binding(2) var<storage, read> tf: array<f32>;
@group(0) @binding(3) var<storage, read_write> image: array<vec4<f32>>;
// Empty-space skipping: 1 where the transfer function gives some extinction to a value the
// brick's voxels span, 0 where every sample in the brick is transparent (skipping those is
// exact: a sample with zero extinction adds nothing).
@group(0) @binding(4) var<storage, read> occupied: array<u32>;

fn voxel(i: vec3<u32>) -> f32 {
    return field[i.x + P.dims.x * (i.y + P.dims.y * i.z)];
}

// Trilinear sample at index-space position q; returns (value, inside).
fn sample(q: vec3<f32>) -> vec2<f32> {
    let hi = vec3<f32>(P.dims.xyz) - vec3<f32>(1.0);
    if (any(q < vec3<f32>(0.0)) || any(q > hi)) {
        return vec2<f32>(0.0, 0.0);
    }
    let b = min(vec3<u32>(floor(q)), max(P.dims.xyz, vec3<u32>(2u)) - vec3<u32>(2u));
    let f = q - vec3<f32>(b);
    let c000 = voxel(b);
    let c100 = voxel(b + vec3<u32>(1u, 0u, 0u));
    let c010 = voxel(b + vec3<u32>(0u, 1u, 0u));
    let c110 = voxel(b + vec3<u32>(1u, 1u, 0u));
    let c001 = voxel(b + vec3<u32>(0u, 0u, 1u));
    let c101 = voxel(b + vec3<u32>(1u, 0u, 1u));
    let c011 = voxel(b + vec3<u32>(0u, 1u, 1u));
    let c111 = voxel(b + vec3<u32>(1u, 1u, 1u));
    let x00 = mix(c000, c100, f.x);
    let x10 = mix(c010, c110, f.x);
    let x01 = mix(c001, c101, f.x);
    let x11 = mix(c011, c111, f.x);
    let v = mix(mix(x00, x10, f.y), mix(x01, x11, f.y), f.z);
    return vec2<f32>(v, 1.0);
}

// Colour (rgb) and extinction (a) at value v.
fn transfer(v: f32) -> vec4<f32> {
    let n = P.counts.y;
    if (n == 0u) {
        return vec4<f32>(0.0);
    }
    let first = vec4<f32>(tf[1], tf[2], tf[3], tf[4]);
    if (v <= tf[0]) {
        return first;
    }
    for (var i = 1u; i < n; i = i + 1u) {
        let x1 = tf[8u * i];
        if (v <= x1) {
            let x0 = tf[8u * (i - 1u)];
            let a = vec4<f32>(tf[8u * (i - 1u) + 1u], tf[8u * (i - 1u) + 2u], tf[8u * (i - 1u) + 3u], tf[8u * (i - 1u) + 4u]);
            let b = vec4<f32>(tf[8u * i + 1u], tf[8u * i + 2u], tf[8u * i + 3u], tf[8u * i + 4u]);
            let t = select(0.0, (v - x0) / (x1 - x0), x1 > x0);
            return mix(a, b, t);
        }
    }
    let l = 8u * (n - 1u);
    return vec4<f32>(tf[l + 1u], tf[l + 2u], tf[l + 3u], tf[l + 4u]);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let w = P.counts.z;
    let h = P.counts.w;
    if (id.x >= w || id.y >= h) {
        return;
    }
    // The ray through the pixel centre (y down), as Camera::ray.
    let ndc = vec2<f32>(
        2.0 * (f32(id.x) + 0.5) / f32(w) - 1.0,
        1.0 - 2.0 * (f32(id.y) + 0.5) / f32(h),
    );
    let a4 = P.inv_view_proj * vec4<f32>(ndc, 0.0, 1.0);
    let b4 = P.inv_view_proj * vec4<f32>(ndc, 1.0, 1.0);
    let o = a4.xyz / a4.w;
    let d = normalize(b4.xyz / b4.w - o);
    let f = P.forward.xyz;
    let cosine = dot(d, f);
    let o_depth = dot(o - P.eye.xyz, f);
    let seg = P.slicing.y / cosine;
    // Clip the slice range to where the ray is inside the grid's box (in index space the box
    // is [0, dims - 1]^3; the ray's index-space position is affine in s).
    let qo = (P.world_to_index * vec4<f32>(o, 1.0)).xyz;
    let qd = (P.world_to_index * vec4<f32>(d, 0.0)).xyz;
    let hi = vec3<f32>(P.dims.xyz) - vec3<f32>(1.0);
    let inv = 1.0 / select(qd, vec3<f32>(1e-30), abs(qd) < vec3<f32>(1e-30));
    let t0 = (vec3<f32>(0.0) - qo) * inv;
    let t1 = (hi - qo) * inv;
    let s_in = max(max(min(t0.x, t1.x), min(t0.y, t1.y)), min(t0.z, t1.z));
    let s_out = min(min(max(t0.x, t1.x), max(t0.y, t1.y)), max(t0.z, t1.z));
    // Slice k is at ray parameter (z0 + (k + 0.5) dz - o_depth) / cosine.
    let k_in = (s_in * cosine + o_depth - P.slicing.x) / P.slicing.y - 0.5;
    let k_out = (s_out * cosine + o_depth - P.slicing.x) / P.slicing.y - 0.5;
    let k_first = u32(clamp(floor(k_in), 0.0, f32(P.counts.x)));
    let k_last = u32(clamp(ceil(k_out) + 1.0, 0.0, f32(P.counts.x)));
    var colour = vec3<f32>(0.0);
    var alpha = 0.0;
    for (var k = k_first; k < k_last; k = k + 1u) {
        let depth = P.slicing.x + (f32(k) + 0.5) * P.slicing.y;
        let s = (depth - o_depth) / cosine;
        if (s < 0.0) {
            continue;
        }
        let p = o + d * s;
        var clipped = false;
        for (var c = 0u; c < P.n_clip.x; c = c + 1u) {
            if (dot(P.clip[c].xyz, p) > P.clip[c].w) {
                clipped = true;
            }
        }
        if (clipped) {
            continue;
        }
        let q = (P.world_to_index * vec4<f32>(p, 1.0)).xyz;
        if (any(q < vec3<f32>(0.0)) || any(q > vec3<f32>(P.dims.xyz) - vec3<f32>(1.0))) {
            continue;
        }
        let br = min(vec3<u32>(q) / P.bricks.w, P.bricks.xyz - vec3<u32>(1u));
        if (occupied[br.x + P.bricks.x * (br.y + P.bricks.y * br.z)] == 0u) {
            continue;
        }
        let v = sample(q);
        // Outside the grid, or next to a sample without data (NaN, uploaded as -3e38).
        if (v.y == 0.0 || v.x < -1e30) {
            continue;
        }
        let c = transfer(v.x);
        let a = 1.0 - exp(-max(c.w, 0.0) * seg);
        colour = colour + (1.0 - alpha) * a * c.xyz;
        alpha = alpha + (1.0 - alpha) * a;
        if (alpha > 0.999) {
            break;
        }
    }
    let out = colour + (1.0 - alpha) * P.background.xyz;
    image[id.x + w * id.y] = vec4<f32>(out, alpha);
}
