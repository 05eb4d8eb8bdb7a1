// Smoke test of the GPU path: one compute dispatch and one render pass.
// engine/src/smoke.rs dispatches `square` and draws `vs_main`/`fs_main`, then reads both back.

@group(0) @binding(0) var<storage, read_write> values: array<u32>;

@compute @workgroup_size(64)
fn square(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i < arrayLength(&values)) {
        values[i] = i * i + 7u;
    }
}

struct VsOut {
    @builtin(position) pos: vec4<f32>,
};

// Two triangles covering the left half of the target: x in [-1, 0] NDC, full height.
@vertex
fn vs_main(@builtin(vertex_index) vi: u32) -> VsOut {
    var p = array<vec2<f32>, 6>(
        vec2<f32>(-1.0, -1.0), vec2<f32>(0.0, -1.0), vec2<f32>(0.0, 1.0),
        vec2<f32>(-1.0, -1.0), vec2<f32>(0.0, 1.0), vec2<f32>(-1.0, 1.0));
    var out: VsOut;
    out.pos = vec4<f32>(p[vi], 0.5, 1.0);
    return out;
}

@fragment
fn fs_main() -> @location(0) vec4<f32> {
    return vec4<f32>(1.0, 0.5, 0.25, 1.0);
}
