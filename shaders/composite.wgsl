// Final compositing and shading (Schott et al., Algorithm 6, eq. 7-10) as a compute pass.
// Rust side: engine/src/composite.rs, which prepends the prelude and the G-buffer's colour and
// normal bindings (4, 5; single or multisampled), `g_col`, `g_nrm` and `SAMPLES`.

// Keep in sync with `composite::CompositeParams`.
struct Params {
    frame: Frame,
    // linear RGB (xyz, 1)
    background: vec4<f32>,
    light: Light,
    // surface terms: the layers of `terms` folded
    n_terms: u32,
    // 0: min (eq. 7), 1: product (eq. 8)
    product: u32,
    // 1: LineAO's paper shading, combined c + specular (Eichelbaum et al. §3.3)
    paper_shading: u32,
    // a term layer that reads 1 (0xffffffff: none): the partial term where no light volume
    // is swept and nothing wrote it
    open_layer: u32,
    // the colour of halo samples (gbuffer.wgsl: alpha 0.5): the background (xyz, 0: a gap,
    // no coverage), or the illustrative method's halo colour (xyz, 1)
    halo: vec4<f32>,
    // the illustrative method's line colour (xyz) and w = 1 when the method is illustrative
    line: vec4<f32>,
};

@group(0) @binding(0) var<uniform> C: Params;
@group(0) @binding(1) var<storage, read> eye_buf: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> state: array<vec4<f32>>;
// The surface terms' layers (layer t of pixel i at t * width * height + i), written by the
// passes of the method's terms; composite leaves in each the value it used (1 where no tube
// surface is nearest), which is that term's AOV.
@group(0) @binding(3) var<storage, read_write> terms: array<f32>;
@group(0) @binding(6) var front_depth: texture_2d<f32>;
// Linear RGBA: colour, and alpha = coverage (1 where a surface is, else the volume's opacity).
@group(0) @binding(7) var<storage, read_write> image: array<vec4<f32>>;
// AOVs per pixel: (volumetric, combined, linear depth, what FXAA does there: 1 leaves the
// pixel as it is - every sample an unlit slice's -, 2 leaves it and its four neighbours -
// a surface's sample in a multisampled G-buffer, whose edges the samples have smoothed: FXAA
// over them took a quarter of a lone 2-pixel line's ink, and beside them smeared it out).
@group(0) @binding(8) var<storage, read_write> aov: array<vec4<f32>>;
// The isosurface (iso_pass): shaded colour and linear depth (0: none), and its ambient term.
@group(0) @binding(9) var<storage, read> iso_out: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read> iso_ambient: array<f32>;

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let w = C.frame.size.x;
    let h = C.frame.size.y;
    if (id.x >= w || id.y >= h) {
        return;
    }
    let idx = id.x + w * id.y;
    let e = eye_buf[idx];
    let s0 = state[2u * idx];
    let s1 = state[2u * idx + 1u];
    let z = textureLoad(front_depth, vec2<i32>(id.xy), 0).r;
    let volumetric = select(1.0, s0.z / s0.w, s0.w > 1e-6);
    let n = w * h;
    var combined = 1.0;
    var under = C.background.rgb;
    var coverage = e.a;
    let iso = iso_out[idx];
    if (iso.w > 0.0 && (z <= 0.0 || iso.w < z)) {
        // The isosurface is the nearest surface: shaded by its swept ambient term.
        combined = iso_ambient[idx];
        under = iso.rgb;
        coverage = 1.0;
        image[idx] = vec4<f32>(under * (1.0 - e.a) + e.rgb, coverage);
        for (var t = 0u; t < C.n_terms; t = t + 1u) {
            terms[t * n + idx] = 1.0;
        }
        aov[idx] = vec4<f32>(volumetric, combined, iso.w, 0.0);
        return;
    }
    // The surface, shaded per sample (each with its own normal) and averaged; samples no
    // surface covers show the background. The occlusion terms are per pixel.
    for (var t = 0u; t < C.n_terms; t = t + 1u) {
        var v = 1.0;
        if (z > 0.0 && t != C.open_layer) {
            v = terms[t * n + idx];
            // eq. 7 (min) or eq. 8 (product), over every term of the method
            combined = select(min(combined, v), combined * v, C.product == 1u);
        }
        terms[t * n + idx] = v;
    }
    // The head light: from the eye along the pixel's ray.
    let to_eye = -pixel_ray(C.frame, vec2<f32>(id.xy) + vec2<f32>(0.5)).d;
    var sum = vec3<f32>(0.0);
    var covered = 0.0;
    var on_slice = 0;
    for (var s = 0; s < SAMPLES; s = s + 1) {
        let c = g_col(vec2<i32>(id.xy), s);
        if (c.a <= 0.0) {
            sum = sum + C.background.rgb;
            continue;
        }
        if (c.a < 0.75) {
            // A halo (Everts et al.): its colour, unlit and not occluded; coverage only where
            // it is ink (the illustrative halo), not where a gap shows the background.
            sum = sum + C.halo.rgb;
            covered = covered + C.halo.w;
            continue;
        }
        if (C.line.w > 0.5) {
            // The illustrative method: unshaded cores.
            sum = sum + C.line.rgb;
            covered = covered + 1.0;
            continue;
        }
        if (c.a > 0.95 && c.a < 0.985) {
            // An unlit slice (gbuffer.wgsl: alpha 0.97): its colour, occluded, no head light.
            sum = sum + combined * c.rgb;
            covered = covered + 1.0;
            on_slice = on_slice + 1;
            continue;
        }
        let n = g_nrm(vec2<i32>(id.xy), s).xyz;
        let nl = max(dot(n, to_eye), 0.0);
        // Head light: the reflection of the light about n makes angle 2 acos(n.l) with the
        // view direction; cos of it is 2 (n.l)^2 - 1.
        let rv = max(2.0 * nl * nl - 1.0, 0.0);
        // An outline rim (gbuffer.wgsl: alpha 0.9) is black ink: no highlight on it.
        let spec = select(C.light.specular * pow(rv, C.light.shininess), 0.0, c.a < 0.95);
        // eq. 9, or LineAO's paper shading (the AO in place of ambient and diffuse)
        var lit = C.light.ambient + C.light.diffuse * nl;
        if (C.paper_shading != 0u) {
            lit = 1.0;
        }
        sum = sum + combined * c.rgb * lit + vec3<f32>(spec);
        covered = covered + 1.0;
    }
    if (covered > 0.0) {
        under = sum / f32(SAMPLES);
        let f = covered / f32(SAMPLES);
        coverage = f + (1.0 - f) * e.a;
    }
    // eq. 10, with the background last when no surface is there.
    image[idx] = vec4<f32>(under * (1.0 - e.a) + e.rgb, coverage);
    var depth = z;
    if (s1.x > 0.0 && (z <= 0.0 || s1.x < z)) {
        depth = s1.x;
    }
    var fxaa = select(0.0, 1.0, on_slice == SAMPLES);
    if (SAMPLES > 1 && covered > 0.0) {
        fxaa = 2.0;
    }
    aov[idx] = vec4<f32>(volumetric, combined, depth, fxaa);
}
