// Vicinity occlusion (Schott et al., Algorithm 5, eq. 4-6) as a compute pass: the tubes'
// occlusion of each other from their linear depths. Rust side and the corrections to the
// paper: engine/src/vicinity.rs.

// Keep in sync with `vicinity::VicinityParams`.
struct Params {
    // the projection's P00 and P11
    p00: f32,
    p11: f32,
    // 1: perspective, 0: orthographic
    perspective: u32,
    // the radius r = l_vicinity tan(theta), world units
    radius: f32,
    // the depth bias and the reach l_vicinity, world units
    bias: f32,
    range: f32,
    samples: u32,
    // the layer of `terms` this pass writes
    layer: u32,
    width: u32,
    height: u32,
    pad: vec2<u32>,
};

@group(0) @binding(0) var<uniform> V: Params;
@group(0) @binding(1) var front_depth: texture_2d<f32>;
// Poisson-disk offsets in the unit disk (xy), N of them.
@group(0) @binding(2) var<storage, read> disk: array<vec2<f32>>;
// The surface terms' layers; this pass writes layer V.layer.
@group(0) @binding(3) var<storage, read_write> terms: array<f32>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let w = V.width;
    let h = V.height;
    if (id.x >= w || id.y >= h) {
        return;
    }
    let out = V.layer * w * h + id.x + w * id.y;
    let z = textureLoad(front_depth, vec2<i32>(id.xy), 0).r;
    if (z <= 0.0) {
        terms[out] = 1.0;
        return;
    }
    // Texture-space radius R_t = 0.5 (P00, P11) r / |z| (eq. 4-5 corrected), in pixels here.
    var rt = 0.5 * vec2<f32>(V.p00, V.p11) * V.radius;
    if (V.perspective != 0u) {
        rt = rt / z;
    }
    let rpx = rt * vec2<f32>(f32(w), f32(h));
    let centre = vec2<f32>(id.xy) + vec2<f32>(0.5);
    let n = V.samples;
    var hits = 0.0;
    var valid = 0.0;
    for (var i = 0u; i < n; i = i + 1u) {
        // eq. 6: t_i = f_t + p_i (texture y runs down; the disk is symmetric)
        let t = centre + disk[i] * rpx;
        if (t.x < 0.0 || t.y < 0.0 || t.x >= f32(w) || t.y >= f32(h)) {
            // Off screen: unknown, left out of the ratio rather than counted as open.
            continue;
        }
        valid = valid + 1.0;
        let zs = textureLoad(front_depth, vec2<i32>(t), 0).r;
        // A neighbour occludes when it is closer to the eye than the biased surface depth
        // (Algorithm 5 adds the bias the other way) and within the cone's reach l_vicinity.
        if (zs > 0.0 && zs < z - V.bias && z - zs <= V.range) {
            hits = hits + 1.0;
        }
    }
    terms[out] = select(1.0, 1.0 - hits / valid, valid > 0.0);
}
