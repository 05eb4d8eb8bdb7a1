// LineAO (Eichelbaum, Hlawitschka and Scheuermann 2013, eq. 4-16) as three compute entries:
// `nd_level0` (the normal-depth map of the G-buffer, normalised, in view space), `nd_half`
// (one level of the pyramid from the one below) and `main` (the kernel, one viewport pixel per
// invocation). Rust side: engine/src/line_ao.rs; the model, its departures from the paper and
// the CPU twin this file follows function by function: occlusion/src/line_ao.rs.

// Keep in sync with `line_ao::LineAoParams`.
struct Params {
    // the view's basis in world space: right, up, back (towards the eye); xyz, 0
    right: vec4<f32>,
    up: vec4<f32>,
    back: vec4<f32>,
    // the camera's clipping range (the depth normalisation) and z(P)'s scale 0.5 P11 H
    near: f32,
    far: f32,
    zoom_scale: f32,
    // 1: perspective (z(P) = zoom_scale / z), 0: orthographic (z(P) = zoom_scale)
    perspective: u32,
    // the viewport, the ND map (viewport + 2 guard) and the band
    width: u32,
    height: u32,
    nd_width: u32,
    nd_height: u32,
    guard: u32,
    // s_r, s_h, and the layer of `terms` this pass writes
    levels: u32,
    samples: u32,
    layer: u32,
    r0_widths: f32,
    radius_step: f32,
    delta0: f32,
    light_intensity: f32,
    light_diffuse: f32,
    light_specular: f32,
    light_shininess: f32,
    seed: u32,
    // 1: delta(l) = 1 on every level; 0: eq. 11
    constant_falloff: u32,
    // 1: a sample is compared with P's tangent plane; 0: with P (eq. 8, the height field)
    plane: u32,
    // anisotropic LineAO (seed 002 eq. 10-12) and its alignment: 1 the paper's |t.x|, 0 the
    // doubled-angle tangent; I and A0 of eq. 11
    anisotropic: u32,
    paper_alignment: u32,
    intensity: f32,
    floor: f32,
    // 1: the levels' mean (OpenWalnut's 1 / s_r), 0: their sum (eq. 7)
    mean_levels: u32,
    pad2: u32,
    // level_angle(j) (occlusion::line_ao), 8 levels
    level_angle: array<vec4<f32>, 2>,
    // each level's first texel in `nd`, and its width and height
    level_offset: array<vec4<u32>, 2>,
    level_size: array<vec4<u32>, 4>,
};

// One halving: level `src` to level `src + 1`. Keep in sync with `line_ao::HalfParams`.
struct Half {
    src: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
};

@group(0) @binding(0) var<uniform> L: Params;
@group(0) @binding(1) var nd_depth: texture_2d<f32>;
@group(0) @binding(2) var nd_normal: texture_2d<f32>;
// The pyramid: per texel the view-space unit normal (xyz) and the normalised depth (w; 0 is
// background), level after level.
@group(0) @binding(3) var<storage, read_write> nd: array<vec4<f32>>;
@group(0) @binding(4) var<uniform> H: Half;
// The surface terms' layers; this pass writes layer L.layer (the visibility 1 - LineAO).
@group(0) @binding(5) var<storage, read_write> terms: array<f32>;
// The factor channels: V, g_depth, g_light, g_align, each width * height (1 = open).
@group(0) @binding(6) var<storage, read_write> factors: array<f32>;
// Per pyramid texel, the mean depth of its surfaces alone (0: none): P's own depth on a level.
@group(0) @binding(7) var<storage, read_write> cover: array<f32>;
// The lines' screen tangents (gbuffer.wgsl::fs_nd) and their pyramid, texel for texel as `nd`.
@group(0) @binding(8) var nd_tangent: texture_2d<f32>;
@group(0) @binding(9) var<storage, read_write> tangents: array<vec4<f32>>;

const TAU: f32 = 6.2831853;
const GOLDEN_ANGLE: f32 = 2.399963;
const MIN_POSITIVE: f32 = 1.17549435e-38;

fn level_offset(j: u32) -> u32 {
    return L.level_offset[j / 4u][j % 4u];
}

fn level_size(j: u32) -> vec2<u32> {
    let v = L.level_size[j / 2u];
    return select(v.xy, v.zw, j % 2u == 1u);
}

fn level_angle(j: u32) -> f32 {
    return L.level_angle[j / 4u][j % 4u];
}

// occlusion::line_ao::normalised_depth
fn normalised_depth(z: f32) -> f32 {
    if (!(z > 0.0) || z > 3.0e38) {
        return 0.0;
    }
    return max((z - L.near) / (L.far - L.near), MIN_POSITIVE);
}

// Level 0: the G-buffer's normal-depth map, normalised, the normal in view space.
@compute @workgroup_size(8, 8, 1)
fn nd_level0(@builtin(global_invocation_id) id: vec3<u32>) {
    if (id.x >= L.nd_width || id.y >= L.nd_height) {
        return;
    }
    let p = vec2<i32>(id.xy);
    let d = normalised_depth(textureLoad(nd_depth, p, 0).r);
    var n = vec3<f32>(0.0, 0.0, 1.0);
    if (d > 0.0) {
        let w = textureLoad(nd_normal, p, 0).xyz;
        let v = vec3<f32>(dot(w, L.right.xyz), dot(w, L.up.xyz), dot(w, L.back.xyz));
        if (dot(v, v) > 1e-12) {
            n = normalize(v);
        }
    }
    nd[id.x + L.nd_width * id.y] = vec4<f32>(n, d);
    cover[id.x + L.nd_width * id.y] = d;
    var t = vec4<f32>(0.0);
    if (d > 0.0) {
        t = textureLoad(nd_tangent, p, 0);
    }
    tangents[id.x + L.nd_width * id.y] = t;
}

// occlusion::line_ao::NormalDepth::far_depth: background counts as far.
fn far_depth(t: vec4<f32>) -> f32 {
    return select(1.0, t.w, t.w > 0.0);
}

// occlusion::line_ao::NormalDepth::surface_depth: the surfaces' own depth, else far.
fn surface_depth(t: vec4<f32>, c: f32) -> f32 {
    return select(far_depth(t), c, c > 0.0);
}

// occlusion::line_ao::NormalDepth::half: the 2 x 2 mean, background as 1 (as far), the
// normals of the covered texels summed and renormalised; a block of background stays one.
@compute @workgroup_size(8, 8, 1)
fn nd_half(@builtin(global_invocation_id) id: vec3<u32>) {
    let src = H.src;
    let ss = level_size(src);
    let ds = level_size(src + 1u);
    if (id.x >= ds.x || id.y >= ds.y) {
        return;
    }
    var sum = 0.0;
    var count = 0.0;
    var covered = 0u;
    var n = vec3<f32>(0.0);
    var cov = 0.0;
    var tan = vec3<f32>(0.0);
    var lines = 0.0;
    for (var k = 0u; k < 4u; k = k + 1u) {
        let s = 2u * id.xy + vec2<u32>(k % 2u, k / 2u);
        if (s.x >= ss.x || s.y >= ss.y) {
            continue;
        }
        let i = level_offset(src) + s.x + ss.x * s.y;
        let t = nd[i];
        count = count + 1.0;
        sum = sum + far_depth(t);
        if (t.w > 0.0) {
            covered = covered + 1u;
            n = n + t.xyz;
            cov = cov + surface_depth(t, cover[i]);
            let tt = tangents[i];
            if (tt.w > 0.0) {
                tan = tan + tt.xyz;
                lines = lines + 1.0;
            }
        }
    }
    var out = vec4<f32>(0.0, 0.0, 1.0, 0.0);
    var out_cover = 0.0;
    if (covered > 0u) {
        var nn = vec3<f32>(0.0);
        if (dot(n, n) > 0.0) {
            nn = normalize(n);
        }
        out = vec4<f32>(nn, sum / count);
        out_cover = cov / f32(covered);
    }
    let o = level_offset(src + 1u) + id.x + ds.x * id.y;
    nd[o] = out;
    cover[o] = out_cover;
    var out_t = vec4<f32>(0.0);
    if (lines > 0.0) {
        out_t = vec4<f32>(tan / lines, 1.0);
    }
    tangents[o] = out_t;
}

// occlusion::line_ao::pcg_hash
fn pcg_hash(v: u32) -> u32 {
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// occlusion::line_ao::rotation_angle
fn rotation_angle(x: u32, y: u32, seed: u32) -> f32 {
    let h = pcg_hash(x + pcg_hash(y + pcg_hash(seed)));
    return TAU * (f32(h >> 8u) * (1.0 / 16777216.0));
}

// occlusion::line_ao::sample_offset
fn sample_offset(i: u32, n: u32, j: u32, rotation: f32) -> vec2<f32> {
    let r = sqrt((f32(i) + 0.5) / f32(max(n, 1u)));
    let a = f32(i) * GOLDEN_ANGLE + level_angle(j) + rotation;
    return vec2<f32>(r * cos(a), r * sin(a));
}

// occlusion::line_ao::hemisphere_direction
fn hemisphere_direction(o: vec2<f32>, n: vec3<f32>) -> vec3<f32> {
    let z = sqrt(max(1.0 - dot(o, o), 0.0));
    let w = vec3<f32>(o, z);
    return select(w, -w, dot(w, n) < 0.0);
}

// occlusion::line_ao::delta (eq. 11) or 1 under the constant falloff
fn delta(l: u32) -> f32 {
    if (L.constant_falloff != 0u) {
        return 1.0;
    }
    let t = 1.0 - f32(l) / f32(max(L.levels, 1u));
    return t * t;
}

// occlusion::line_ao::g_depth (eq. 12 with Δd, eq. 13)
fn g_depth(dd: f32, delta_l: f32) -> f32 {
    if (dd > delta_l) {
        return 0.0;
    }
    if (dd < L.delta0) {
        return 1.0;
    }
    return 1.0 - smoothstep(0.0, 1.0, (dd - L.delta0) / (delta_l - L.delta0));
}

// occlusion::line_ao::plane_rise: P's tangent plane's rise towards the eye at an offset of
// `o` pixels (view axes), in normalised depth, its slope along the ray `ray` (unit depth)
fn plane_rise(n: vec3<f32>, o: vec2<f32>, zoom: f32, ray: vec2<f32>) -> f32 {
    if (!(zoom > 0.0)) {
        return 0.0;
    }
    let a = n.z - n.x * ray.x - n.y * ray.y;
    return -(n.x * o.x + n.y * o.y) / (zoom * max(a, 0.1) * (L.far - L.near));
}

// occlusion::line_ao::pixel_ray: the ray at unit depth through `c` (ND-map pixels, y down) of
// a perspective camera with the focal length zoom_scale (the principal point the map's centre);
// zero for an orthographic camera
fn ao_pixel_ray(c: vec2<f32>) -> vec2<f32> {
    if (L.perspective == 0u || !(L.zoom_scale > 0.0)) {
        return vec2<f32>(0.0, 0.0);
    }
    let half = 0.5 * vec2<f32>(f32(L.nd_width), f32(L.nd_height));
    return vec2<f32>(c.x - half.x, half.y - c.y) / L.zoom_scale;
}

// occlusion::line_ao::alignment_difference and g_align (eq. 10-11)
fn g_align(p: vec4<f32>, q: vec4<f32>) -> f32 {
    if (L.anisotropic == 0u || p.w <= 0.0 || q.w <= 0.0) {
        return 1.0;
    }
    var x = abs(p.z - q.z);
    if (L.paper_alignment == 0u) {
        x = sqrt(max((1.0 - (p.x * q.x + p.y * q.y)) * 0.5, 0.0));
    }
    return max(L.floor, min(1.0, L.intensity * smoothstep(0.0, 1.0, x)));
}

// occlusion::line_ao::phong_brdf with the head light along +z (view space), eq. 14
fn phong_brdf(n: vec3<f32>, v: vec3<f32>) -> f32 {
    let light = vec3<f32>(0.0, 0.0, 1.0);
    let nl = dot(n, light);
    if (nl <= 0.0) {
        return 0.0;
    }
    let r = 2.0 * nl * n - light;
    return L.light_intensity
        * (L.light_diffuse * nl + L.light_specular * pow(max(dot(r, v), 0.0), L.light_shininess));
}

// The LineAO kernel at one viewport pixel: occlusion::line_ao::line_ao on the guard-banded
// pyramid, the rotation hashed from the viewport pixel.
@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let w = L.width;
    let h = L.height;
    if (id.x >= w || id.y >= h) {
        return;
    }
    let n_px = w * h;
    let out = id.x + w * id.y;
    let pb = id.xy + vec2<u32>(L.guard);
    let d0 = nd[pb.x + L.nd_width * pb.y];
    if (!(d0.w > 0.0)) {
        terms[L.layer * n_px + out] = 1.0;
        factors[out] = 1.0;
        factors[n_px + out] = 1.0;
        factors[2u * n_px + out] = 1.0;
        factors[3u * n_px + out] = 1.0;
        return;
    }
    let z = textureLoad(nd_depth, vec2<i32>(pb), 0).r;
    var zoom = L.zoom_scale;
    if (L.perspective != 0u) {
        zoom = select(0.0, L.zoom_scale / z, z > 0.0);
    }
    if (!(zoom > 0.0) || zoom > 3.0e38) {
        zoom = 0.0;
    }
    // r0 from the pixel's width code: pixels, a world diameter, or 2 pixels when unknown.
    let code = textureLoad(nd_normal, vec2<i32>(pb), 0).a;
    var width_px = 2.0;
    if (code > 0.0) {
        width_px = code;
    } else if (code < 0.0) {
        width_px = -code * zoom;
    }
    let r0 = L.r0_widths * width_px;
    let rotation = rotation_angle(id.x, id.y, L.seed);
    let centre = vec2<f32>(pb) + vec2<f32>(0.5);
    let size = vec2<f32>(f32(L.nd_width), f32(L.nd_height));
    var sum = 0.0;
    var v = 0.0;
    var gd = 0.0;
    var gl = 0.0;
    var ga = 0.0;
    var counted = 0u;
    for (var j = 0u; j < L.levels; j = j + 1u) {
        let off = level_offset(j);
        let ls = level_size(j);
        let pj = pb >> vec2<u32>(j);
        let ip = off + pj.x + ls.x * pj.y;
        let tp = nd[ip];
        let d_p = surface_depth(tp, cover[ip]);
        let n_p = tp.xyz;
        let n = (L.samples + j) / (j + 1u);
        let r = r0 + f32(j) * L.radius_step * zoom;
        let delta_l = delta(j);
        var valid = 0u;
        var ao = 0.0;
        var lv = 0.0;
        var lgd = 0.0;
        var lgl = 0.0;
        var lga = 0.0;
        let t_p = tangents[ip];
        for (var i = 0u; i < n; i = i + 1u) {
            let omega = hemisphere_direction(sample_offset(i, n, j, rotation), n_p);
            let q = centre + r * vec2<f32>(omega.x, -omega.y);
            if (!(q.x >= 0.0 && q.y >= 0.0 && q.x < size.x && q.y < size.y)) {
                continue;
            }
            valid = valid + 1u;
            let qj = vec2<u32>(q) >> vec2<u32>(j);
            let iq = off + qj.x + ls.x * qj.y;
            let tq = nd[iq];
            var dd = d_p - far_depth(tq);
            if (L.plane != 0u) {
                // Between the two texels' centres (level-0 pixels, view y up).
                let texels = vec2<f32>(f32(qj.x) - f32(pj.x), f32(pj.y) - f32(qj.y));
                // The slope along the ray through P's texel's centre (level-0 pixels).
                let ray = ao_pixel_ray((vec2<f32>(pj) + 0.5) * f32(1u << j));
                dd = dd - plane_rise(n_p, texels * f32(1u << j), zoom, ray);
            }
            // eq. 8, strict (occlusion::line_ao::occludes)
            let occ = select(0.0, 1.0, tq.w > 0.0 && dd > L.delta0);
            let g_d = g_depth(dd, delta_l);
            let g_l = 1.0 - clamp(phong_brdf(n_p, omega), 0.0, 1.0);
            let g_a = g_align(t_p, tangents[iq]);
            ao = ao + occ * g_d * g_l * g_a;
            lv = lv + occ;
            lgd = lgd + g_d;
            lgl = lgl + g_l;
            lga = lga + g_a;
        }
        if (valid > 0u) {
            let k = 1.0 / f32(valid);
            sum = sum + ao * k;
            v = v + lv * k;
            gd = gd + lgd * k;
            gl = gl + lgl * k;
            ga = ga + lga * k;
            counted = counted + 1u;
        }
    }
    var total = sum;
    if (L.mean_levels != 0u) {
        total = sum / f32(max(L.levels, 1u));
    }
    let line_ao = clamp(total, 0.0, 1.0);
    terms[L.layer * n_px + out] = 1.0 - line_ao;
    var fv = 0.0;
    var fgd = 1.0;
    var fgl = 1.0;
    var fga = 1.0;
    if (counted > 0u) {
        let k = 1.0 / f32(counted);
        fv = v * k;
        fgd = gd * k;
        fgl = gl * k;
        fga = ga * k;
    }
    factors[out] = 1.0 - fv;
    factors[n_px + out] = fgd;
    factors[2u * n_px + out] = fgl;
    factors[3u * n_px + out] = fga;
}
