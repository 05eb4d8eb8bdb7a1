// The tubes' G-buffer (Schott et al., section 3.2.1): colour, world normal and linear view
// depth of the nearest surface (`fs_front`), and the linear depth of the nearest back-facing
// surface (`fs_back`), which bounds a tube's inside for the geometry-into-volume occlusion.
// Rust side: engine/src/gbuffer.rs. Positions are relative to the mesh origin; `offset`
// (origin - eye) makes them camera-relative, so large world coordinates keep f32 precision.

// Keep in sync with `gbuffer::GBufferParams`.
struct Params {
    // projection * view * translate(eye): camera-relative position to clip space
    view_proj_rel: mat4x4<f32>,
    // the mesh's origin - eye (xyz, 0)
    offset: vec4<f32>,
    forward: vec4<f32>,
    eye: vec4<f32>,
    // clipping planes (normal, offset), keeping normal . p <= offset
    clip: array<vec4<f32>, 8>,
    n_clip: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
};

@group(0) @binding(0) var<uniform> G: Params;

struct VIn {
    @location(0) pos: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
};

struct VOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) color: vec3<f32>,
    @location(2) rel: vec3<f32>,
};

@vertex
fn vs(v: VIn) -> VOut {
    var o: VOut;
    let rel = v.pos + G.offset.xyz;
    o.clip = G.view_proj_rel * vec4<f32>(rel, 1.0);
    o.normal = v.normal;
    o.color = v.color.rgb;
    o.rel = rel;
    return o;
}

fn clipped(rel: vec3<f32>) -> bool {
    let p = rel + G.eye.xyz;
    for (var c = 0u; c < G.n_clip; c = c + 1u) {
        if (dot(G.clip[c].xyz, p) > G.clip[c].w) {
            return true;
        }
    }
    return false;
}

struct FrontOut {
    @location(0) color: vec4<f32>,
    @location(1) normal: vec4<f32>,
    @location(2) depth: vec4<f32>,
};

@fragment
fn fs_front(v: VOut) -> FrontOut {
    return front_values(v);
}

fn front_values(v: VOut) -> FrontOut {
    if (clipped(v.rel)) {
        discard;
    }
    var o: FrontOut;
    o.color = vec4<f32>(v.color, 1.0);
    var n = normalize(v.normal);
    // Two-sided: the normal faces the viewer (cut-open tubes show their inside).
    if (dot(n, v.rel) > 0.0) {
        n = -n;
    }
    o.normal = vec4<f32>(n, 1.0);
    o.depth = vec4<f32>(dot(v.rel, G.forward.xyz), 0.0, 0.0, 1.0);
    return o;
}

// Multisampled G-buffer: colour and normal per sample (for per-sample shading).
struct SurfaceOut {
    @location(0) color: vec4<f32>,
    @location(1) normal: vec4<f32>,
};

@fragment
fn fs_surface(v: VOut) -> SurfaceOut {
    let f = front_values(v);
    var o: SurfaceOut;
    o.color = f.color;
    o.normal = f.normal;
    return o;
}

// The nearest surface's linear depth alone (single sample, beside a multisampled G-buffer).
@fragment
fn fs_depth(v: VOut) -> @location(0) vec4<f32> {
    if (clipped(v.rel)) {
        discard;
    }
    return vec4<f32>(dot(v.rel, G.forward.xyz), 0.0, 0.0, 1.0);
}

@fragment
fn fs_back(v: VOut) -> @location(0) vec4<f32> {
    // Back faces by their normal (the mesh's winding is not relied on).
    if (clipped(v.rel) || dot(v.normal, v.rel) < 0.0) {
        discard;
    }
    return vec4<f32>(dot(v.rel, G.forward.xyz), 0.0, 0.0, 1.0);
}
