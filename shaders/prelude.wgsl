// The WGSL every pass shares (the one non-pass file of shaders/): the frame uniform, the
// head light, the pixel ray and trilinear interpolation. engine/src/prelude.rs prepends it to
// each pass's source and holds the Rust twins of its structs (keep in sync with them).

// The view of one frame (Rust: prelude::FrameUniform).
struct Frame {
    // clip -> world
    inv_view_proj: mat4x4<f32>,
    // eye position (xyz, 1)
    eye: vec4<f32>,
    // unit viewing direction (xyz, 0)
    forward: vec4<f32>,
    // width, height (pixels); unused, unused
    size: vec4<u32>,
};

// The head light's Phong parameters (Rust: prelude::LightUniform).
struct Light {
    ambient: f32,
    diffuse: f32,
    specular: f32,
    shininess: f32,
};

// A pixel's ray: origin on the near plane, unit direction, the direction's cosine with the
// viewing direction, and the origin's linear depth.
struct Ray {
    o: vec3<f32>,
    d: vec3<f32>,
    cosine: f32,
    o_depth: f32,
};

// The ray through pixel position px (pixels from the top-left corner; centres at +0.5).
fn pixel_ray(f: Frame, px: vec2<f32>) -> Ray {
    let ndc = vec2<f32>(
        2.0 * px.x / f32(f.size.x) - 1.0,
        1.0 - 2.0 * px.y / f32(f.size.y),
    );
    let a4 = f.inv_view_proj * vec4<f32>(ndc, 0.0, 1.0);
    let b4 = f.inv_view_proj * vec4<f32>(ndc, 1.0, 1.0);
    var r: Ray;
    r.o = a4.xyz / a4.w;
    r.d = normalize(b4.xyz / b4.w - r.o);
    r.cosine = dot(r.d, f.forward.xyz);
    r.o_depth = dot(r.o - f.eye.xyz, f.forward.xyz);
    return r;
}

// The offset of corner c (0..8, x fastest) of a grid cell.
fn cell_corner(c: u32) -> vec3<u32> {
    return vec3<u32>(c & 1u, (c >> 1u) & 1u, c >> 2u);
}

// Trilinear interpolation of a cell's corner values v[c] (corner c at cell_corner(c)) at
// fractions f: along x, then y, then z.
fn trilinear_mix(v: array<f32, 8>, f: vec3<f32>) -> f32 {
    let x00 = mix(v[0], v[1], f.x);
    let x10 = mix(v[2], v[3], f.x);
    let x01 = mix(v[4], v[5], f.x);
    let x11 = mix(v[6], v[7], f.x);
    return mix(mix(x00, x10, f.y), mix(x01, x11, f.y), f.z);
}
