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
    // LineAO's width code of the mesh's pixels (see `width_code` in VOut)
    width_code: f32,
    // a translucent mesh's opacity (the peel passes; opaque meshes: 1)
    opacity: f32,
    pad2: u32,
};

@group(0) @binding(0) var<uniform> G: Params;

struct VIn {
    @location(0) pos: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
};

// A vertex's outputs as the shaders use them; the stage interface packs them into fewer
// vec4 slots (VOutP): Mesa's llvmpipe (lavapipe) sets up and interpolates every slot of
// every triangle, 11 of them before.
struct VOut {
    clip: vec4<f32>,
    normal: vec3<f32>,
    color: vec3<f32>,
    rel: vec3<f32>,
    // Cylinder-profile lines: the side vector times the position across the width (-1..1),
    // and the half width in world units; zero for tubes and flat lines.
    bend: vec3<f32>,
    bulge: f32,
    // The width LineAO's r0 follows (the ND target's alpha): a width in pixels (> 0), minus a
    // world diameter (< 0: tubes, world-width lines), or 0 when unknown.
    width_code: f32,
    // Lines: the world radius they stand for in the volume's shadow (0: none); tubes: 0.
    proxy: f32,
    // Lines: the unit tangent (camera-relative world); tubes: zero.
    tangent: vec3<f32>,
    // Lines: the unit tangent on screen (pixels, view axes: x right, y up); tubes: zero.
    screen_t: vec2<f32>,
    // Haloed lines: the position across the strip, (-1 to 1, 0) (|across| below the core's
    // fraction is the line, beyond it the halo); points: the position in the disc's square
    // (x right, y up, -1 to 1; beyond a length of 1 is outside the disc); zero otherwise.
    across: vec2<f32>,
    // Haloed lines: the position along the segment in pixels from its first end (negative
    // or beyond `y` in the square caps), the segment's length on screen, and the core's half
    // width in pixels; interpolated in screen space. Points and tubes: never in a cap.
    seg: vec3<f32>,
};

// VOut packed for the interface between the stages: seven slots, the screen-linear `seg`
// on its own.
struct VOutP {
    @builtin(position) clip: vec4<f32>,
    @location(0) rel_bulge: vec4<f32>,
    @location(1) normal_width: vec4<f32>,
    @location(2) color_proxy: vec4<f32>,
    @location(3) tangent_across_x: vec4<f32>,
    @location(4) bend_across_y: vec4<f32>,
    @location(5) screen_t: vec2<f32>,
    @location(6) @interpolate(linear) seg: vec3<f32>,
};

fn pack(o: VOut) -> VOutP {
    var p: VOutP;
    p.clip = o.clip;
    p.rel_bulge = vec4<f32>(o.rel, o.bulge);
    p.normal_width = vec4<f32>(o.normal, o.width_code);
    p.color_proxy = vec4<f32>(o.color, o.proxy);
    p.tangent_across_x = vec4<f32>(o.tangent, o.across.x);
    p.bend_across_y = vec4<f32>(o.bend, o.across.y);
    p.screen_t = o.screen_t;
    p.seg = o.seg;
    return p;
}

// VOutP for haloed lines: every slot interpolated at each sample, so that a multisampled
// G-buffer runs the fragment shader per sample and the edge between a line's core and its rim
// is resolved sample by sample (decided once per pixel at its centre, a core edge that runs
// through pixel centres - a 3-pixel line on the pixel grid - came out as dashes of rim).
struct VOutPH {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(perspective, sample) rel_bulge: vec4<f32>,
    @location(1) @interpolate(perspective, sample) normal_width: vec4<f32>,
    @location(2) @interpolate(perspective, sample) color_proxy: vec4<f32>,
    @location(3) @interpolate(perspective, sample) tangent_across_x: vec4<f32>,
    @location(4) @interpolate(perspective, sample) bend_across_y: vec4<f32>,
    @location(5) @interpolate(perspective, sample) screen_t: vec2<f32>,
    @location(6) @interpolate(linear, sample) seg: vec3<f32>,
};

fn to_h(p: VOutP) -> VOutPH {
    return VOutPH(
        p.clip,
        p.rel_bulge,
        p.normal_width,
        p.color_proxy,
        p.tangent_across_x,
        p.bend_across_y,
        p.screen_t,
        p.seg,
    );
}

fn unpack_h(p: VOutPH) -> VOut {
    return unpack(VOutP(
        p.clip,
        p.rel_bulge,
        p.normal_width,
        p.color_proxy,
        p.tangent_across_x,
        p.bend_across_y,
        p.screen_t,
        p.seg,
    ));
}

fn unpack(p: VOutP) -> VOut {
    var o: VOut;
    o.clip = p.clip;
    o.rel = p.rel_bulge.xyz;
    o.bulge = p.rel_bulge.w;
    o.normal = p.normal_width.xyz;
    o.width_code = p.normal_width.w;
    o.color = p.color_proxy.xyz;
    o.proxy = p.color_proxy.w;
    o.tangent = p.tangent_across_x.xyz;
    o.bend = p.bend_across_y.xyz;
    o.across = vec2<f32>(p.tangent_across_x.w, p.bend_across_y.w);
    o.screen_t = p.screen_t;
    o.seg = p.seg;
    return o;
}

// Mesh and line colours are 8-bit sRGB (as files and colour codes give them:
// `tubes::tube_mesh::map_color`); the G-buffer holds linear light. The sRGB EOTF exactly
// (`volume::colormap::srgb_to_linear`).
fn srgb_to_linear(c: vec3<f32>) -> vec3<f32> {
    return select(pow((c + vec3<f32>(0.055)) / 1.055, vec3<f32>(2.4)), c / 12.92, c <= vec3<f32>(0.04045));
}

@vertex
fn vs(v: VIn) -> VOutP {
    var o: VOut;
    let rel = v.pos + G.offset.xyz;
    o.clip = G.view_proj_rel * vec4<f32>(rel, 1.0);
    o.normal = v.normal;
    o.color = srgb_to_linear(v.color.rgb);
    o.rel = rel;
    o.bend = vec3<f32>(0.0);
    o.bulge = 0.0;
    o.width_code = G.width_code;
    o.proxy = 0.0;
    o.tangent = vec3<f32>(0.0);
    o.screen_t = vec2<f32>(0.0);
    o.across = vec2<f32>(0.0);
    o.seg = vec3<f32>(0.0, 1.0, 1.0);
    return pack(o);
}

// Line sets (Rust: gbuffer::GpuLines; the maths and its CPU twin: occlusion::illuminated_lines,
// after Zöckler et al. 1996 and Mallo et al. 2005): screen-facing strips built here from the points (vertex
// pulling, six vertices per segment, nothing duplicated on the CPU). Keep in sync with
// `gbuffer::LineParams`.
struct LineParams {
    // half the line's width: pixels, or world units when `world` is 1
    half_width: f32,
    world: u32,
    cylinder: u32,
    // the projection's P11: a world unit at linear depth w spans 0.5 P11 height / w pixels
    p11: f32,
    viewport: vec2<f32>,
    // 1: perspective (the eye is a point), 0: orthographic (the eye is a direction)
    perspective: u32,
    // the nearest clip-space w a strip's end may have (segments are cut there)
    min_w: f32,
    // the world radius the lines stand for in the volume's shadow (0: none)
    proxy_radius: f32,
    // 1: only each line's tapered trail [now - back, now + forward] is drawn, full width
    // within `start` of `now` and narrowing to `min_width` at the ends (tubes::lines::Trail)
    trail: u32,
    now: f32,
    back: f32,
    forward: f32,
    start: f32,
    min_width: f32,
    // 1: each segment entry is a point drawn as a disc of diameter `2 half_width` (Everts et
    // al. §3.5: a screen-aligned square, a circular mask, a cone-shaped halo displacement)
    points: u32,
    // Depth-dependent halos (Everts et al. 2009; Rust: tubes::lines::Halo): 0 none, 1 uniform
    // (no displacement), 2 depth; 1: outline style (dark rims that are part of the line),
    // 0: gap style (rims that hide what is behind them and are not a surface)
    halo: u32,
    halo_outline: u32,
    // the strip's width over the line's (w_strip / w_line)
    halo_width: f32,
    // d_max in linear view depth (world units: d_max times the camera's far - near)
    halo_depth: f32,
    // f of eq. 3: 0 linear, 1 sqrt, 2 square
    displacement: u32,
    // depth cueing: the core's width falls to (1 - depth_cue) of itself at the far plane
    depth_cue: f32,
    // the camera's clipping range (linear depth to the depth attachment's)
    near: f32,
    far: f32,
    // end tapers: the taper's extent in u (0: none); attribute filter (1: on), its threshold
    // and the attribute range over which cut ends narrow
    taper_t: f32,
    filter_on: u32,
    filter_min: f32,
    filter_taper: f32,
};

@group(1) @binding(0) var<uniform> LP: LineParams;
// Positions relative to the set's origin, xyz per point.
@group(1) @binding(1) var<storage, read> line_points: array<f32>;
// RGBA8 per point.
@group(1) @binding(2) var<storage, read> line_colors: array<u32>;
// The first point of each segment.
@group(1) @binding(3) var<storage, read> line_segments: array<u32>;
// A time per point (for trails).
@group(1) @binding(4) var<storage, read> line_times: array<f32>;
// Per point: the taper's u along its line, and the filter attribute.
@group(1) @binding(5) var<storage, read> line_aux: array<vec2<f32>>;

// tubes::lines::Trail::width_factor: 1 near the particle, min_width at the window's ends, 0
// outside it (NaN too).
fn trail_width(t: f32) -> f32 {
    var d = LP.now - t;
    var span = LP.back;
    if (t >= LP.now) {
        d = t - LP.now;
        span = LP.forward;
    }
    if (!(d <= span)) {
        return 0.0;
    }
    var u = 0.0;
    if (span > 0.0) {
        u = d / span;
    }
    if (u <= LP.start) {
        return 1.0;
    }
    return 1.0 + (LP.min_width - 1.0) * (u - LP.start) / (1.0 - LP.start);
}

fn line_point(i: u32) -> vec3<f32> {
    return vec3<f32>(line_points[3u * i], line_points[3u * i + 1u], line_points[3u * i + 2u]);
}

// Segments an instance of a line draw holds (engine::gbuffer::SEGMENTS_PER_INSTANCE).
const SEGMENTS_PER_INSTANCE: u32 = 32u;

@vertex
fn vs_line(@builtin(vertex_index) index: u32, @builtin(instance_index) instance: u32) -> VOutP {
    return line_vertex(index, instance);
}

// Haloed lines: the same vertices, interpolated per sample (VOutPH).
@vertex
fn vs_line_h(@builtin(vertex_index) index: u32, @builtin(instance_index) instance: u32) -> VOutPH {
    return to_h(line_vertex(index, instance));
}

fn line_vertex(index: u32, instance: u32) -> VOutP {
    // Six vertices per segment; SEGMENTS_PER_INSTANCE segments an instance (a draw's first
    // and last few segments may come as instance 0, their vertex index counting from 0).
    let vi = index % 6u;
    let i = line_segments[instance * SEGMENTS_PER_INSTANCE + index / 6u];
    let pts = LP.points != 0u;
    // A point is a segment of length zero (its square is built on screen axes below).
    let j = select(i + 1u, i, pts);
    var a = line_point(i) + G.offset.xyz;
    var b = line_point(j) + G.offset.xyz;
    // Trails, attribute filters and end tapers: the part of the segment that is drawn
    // (parameters s0..s1 along it) and its ends' width factors.
    var s0 = 0.0;
    var s1 = 1.0;
    var outside = false;
    var ta = 0.0;
    var tb = 0.0;
    if (LP.trail != 0u) {
        ta = line_times[i];
        tb = line_times[j];
        let lo = LP.now - LP.back;
        let hi = LP.now + LP.forward;
        if (!(max(ta, tb) >= lo && min(ta, tb) <= hi)) {
            // Wholly outside the window (or a NaN time): not drawn.
            outside = true;
        } else if (tb != ta) {
            let e0 = (lo - ta) / (tb - ta);
            let e1 = (hi - ta) / (tb - ta);
            s0 = max(s0, clamp(min(e0, e1), 0.0, 1.0));
            s1 = min(s1, clamp(max(e0, e1), 0.0, 1.0));
        }
    }
    var xa = vec2<f32>(0.0);
    var xb = vec2<f32>(0.0);
    if (LP.filter_on != 0u || LP.taper_t > 0.0) {
        xa = line_aux[i];
        xb = line_aux[j];
    }
    if (LP.filter_on != 0u) {
        // Seed 004 §3.6: only where the attribute reaches filter_min.
        if (!(max(xa.y, xb.y) >= LP.filter_min)) {
            outside = true;
        } else if (xa.y < LP.filter_min) {
            s0 = max(s0, (LP.filter_min - xa.y) / (xb.y - xa.y));
        } else if (xb.y < LP.filter_min) {
            s1 = min(s1, (LP.filter_min - xa.y) / (xb.y - xa.y));
        }
    }
    if (s0 > s1) {
        outside = true;
    }
    let a0 = a;
    a = mix(a0, b, s0);
    b = mix(a0, b, s1);
    var taper = vec2<f32>(1.0);
    if (LP.trail != 0u) {
        taper = vec2<f32>(trail_width(mix(ta, tb, s0)), trail_width(mix(ta, tb, s1)));
        // Rounding at the window's edge must not drop the end that lies on it.
        taper = max(taper, vec2<f32>(min(LP.min_width, 1.0) * 0.999));
    }
    if (LP.filter_on != 0u && LP.filter_taper > 0.0) {
        // The cut ends narrow to a point over filter_taper of the attribute.
        let fa = mix(xa.y, xb.y, s0);
        let fb = mix(xa.y, xb.y, s1);
        taper = taper * clamp((vec2<f32>(fa, fb) - LP.filter_min) / LP.filter_taper, vec2<f32>(0.0), vec2<f32>(1.0));
    }
    if (LP.taper_t > 0.0) {
        // Seed 004 §3.4: the line's ends narrow to a point (u from the CPU, non-linear so
        // that the taper spans the first and last vertices whatever the line's length).
        let ua = mix(xa.x, xb.x, s0);
        let ub = mix(xa.x, xb.x, s1);
        let u = vec2<f32>(ua, ub);
        taper = taper * clamp(min(u, vec2<f32>(1.0) - u) / LP.taper_t, vec2<f32>(0.0), vec2<f32>(1.0));
    }
    // Cut the segment where it crosses behind the eye (w below min_w), so that a strip is never
    // widened from a point behind the camera; a segment wholly behind is dropped.
    // The ends in clip space, projected once: a cut end is the same mix of the clip-space
    // ends as of the points (the projection is linear in homogeneous coordinates).
    var ca = G.view_proj_rel * vec4<f32>(a, 1.0);
    var cb = G.view_proj_rel * vec4<f32>(b, 1.0);
    let wa = ca.w;
    let wb = cb.w;
    var behind = outside;
    if (wa < LP.min_w && wb < LP.min_w) {
        behind = true;
    } else if (wa < LP.min_w) {
        let k = (LP.min_w - wa) / (wb - wa);
        a = mix(a, b, k);
        ca = mix(ca, cb, k);
    } else if (wb < LP.min_w) {
        let k = (LP.min_w - wb) / (wa - wb);
        b = mix(b, a, k);
        cb = mix(cb, ca, k);
    }
    // The corner: which end (0: a, 1: b) and which side of the strip, two triangles.
    let ends = array<u32, 6>(0u, 1u, 0u, 0u, 1u, 1u);
    let sides = array<f32, 6>(-1.0, -1.0, 1.0, 1.0, -1.0, 1.0);
    let end = ends[vi];
    let side = sides[vi];
    let p = select(a, b, end == 1u);
    var c = select(ca, cb, end == 1u);
    // The tangent; a segment between equal points takes any direction (no NaN).
    let ab = b - a;
    var t = vec3<f32>(1.0, 0.0, 0.0);
    if (dot(ab, ab) > 1e-24) {
        t = normalize(ab);
    }
    // The tangent on screen at this end (the derivative of the projection along t, in pixels;
    // defined wherever the end is in front of the eye, whatever the other end does).
    let tc = G.view_proj_rel * vec4<f32>(t, 0.0);
    var d = (tc.xy * c.w - c.xy * tc.w) * LP.viewport;
    if (dot(d, d) < 1e-24) {
        // Along the view ray: the strip faces the viewer in any direction.
        d = vec2<f32>(1.0, 0.0);
    }
    d = normalize(d);
    if (pts) {
        // Points: a square on the screen's axes (x along `d`, y along `n`).
        d = vec2<f32>(1.0, 0.0);
    }
    let n = vec2<f32>(-d.y, d.x);
    let px_per_world = 0.5 * LP.p11 * LP.viewport.y / max(c.w, 1e-6);
    var hw = LP.half_width;
    if (LP.world != 0u) {
        hw = LP.half_width * px_per_world;
    }
    hw = hw * select(taper.x, taper.y, end == 1u);
    if (LP.halo != 0u) {
        // The strip: the line in its centre, the halo around it.
        hw = hw * LP.halo_width;
    }
    // At least one pixel wide.
    hw = max(hw, 0.5);
    // Square caps: each end reaches half a width beyond its point, so consecutive segments
    // overlap at their joint (watertight at any angle).
    let along = select(-1.0, 1.0, end == 1u);
    var cap = hw;
    let seg_len = length((cb.xy / max(cb.w, 1e-6) - ca.xy / max(ca.w, 1e-6)) * 0.5 * LP.viewport);
    if (LP.trail != 0u || LP.taper_t > 0.0 || (LP.filter_on != 0u && LP.filter_taper > 0.0)) {
        // A tapered line (trail, end taper, filtered cut): a cap no longer than half the
        // segment on screen, so that a wider point's cap does not cover its narrower
        // neighbours (the taper would lag by half a width); dense lines bend little between
        // points, so their joints stay closed.
        cap = min(hw, 0.5 * seg_len + 0.5);
    }
    let off = n * (side * hw) + d * (along * cap);
    c = vec4<f32>(c.xy + off * 2.0 / LP.viewport * c.w, c.z, c.w);
    if (behind) {
        // Outside every clip volume: the triangle is dropped.
        c = vec4<f32>(0.0, 0.0, -1.0, 1.0);
    }
    var o: VOut;
    o.clip = c;
    o.rel = p;
    o.color = srgb_to_linear(unpack4x8unorm(line_colors[select(i, j, end == 1u)]).rgb);
    // The view-facing normal (T x C) x T of illuminated lines, C towards the eye (a point
    // under perspective, a direction under orthographic projection).
    var to_eye = -G.forward.xyz;
    if (LP.perspective != 0u) {
        to_eye = -normalize(p);
    }
    let s = cross(t, to_eye);
    var normal = to_eye;
    if (dot(s, s) > 1e-12) {
        normal = normalize(cross(s, t));
    }
    o.normal = normal;
    o.bend = vec3<f32>(0.0);
    o.bulge = 0.0;
    o.width_code = select(2.0 * LP.half_width, -2.0 * LP.half_width, LP.world != 0u);
    o.proxy = LP.proxy_radius;
    o.tangent = t;
    o.screen_t = d;
    o.across = vec2<f32>(select(0.0, side, LP.halo != 0u), 0.0);
    // Along the segment: -cap at the first end's corners, length + cap at the second's.
    o.seg = vec3<f32>(select(-cap, seg_len + cap, end == 1u), seg_len, hw / LP.halo_width);
    if (pts) {
        // A point has no tangent; it faces the viewer, a sphere's impostor unless haloed (the
        // paper's discs are flat): the normal bends towards the square's corner, the depth
        // bulges by the radius. Screen up in world is row 1 of the projection times the view
        // (P11 u), screen right is forward x up (camera.rs).
        o.tangent = vec3<f32>(0.0);
        o.screen_t = vec2<f32>(0.0);
        o.across = vec2<f32>(along, side);
        o.seg = vec3<f32>(0.0, 1.0, 1.0);
        o.normal = -G.forward.xyz;
        if (LP.halo == 0u) {
            let m = G.view_proj_rel;
            let up = normalize(vec3<f32>(m[0].y, m[1].y, m[2].y));
            let right = normalize(cross(G.forward.xyz, up));
            o.bend = right * along + up * side;
            o.bulge = hw / px_per_world;
        }
        return pack(o);
    }
    // Haloed lines keep the flat profile.
    if (LP.cylinder != 0u && LP.halo == 0u && dot(s, s) > 1e-12) {
        // The side vector on screen: +side is offset along perp(d) = (-d.y, d.x), which is
        // to_eye x t (t x to_eye points the other way).
        o.bend = -normalize(s) * side;
        o.bulge = hw / px_per_world;
    }
    return pack(o);
}

// Outside the clipping planes, or outside a point's disc.
fn clipped(v: VOut) -> bool {
    if (dot(v.across, v.across) > 1.0) {
        return true;
    }
    let p = v.rel + G.eye.xyz;
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
fn fs_front(packed: VOutP) -> FrontOut {
    let v = unpack(packed);
    return front_values(v);
}

fn front_values(v: VOut) -> FrontOut {
    if (clipped(v)) {
        discard;
    }
    var o: FrontOut;
    o.color = vec4<f32>(v.color, 1.0);
    // A cylinder-profile line bends its normal across the width and bulges towards the eye.
    let u2 = min(dot(v.bend, v.bend), 1.0);
    let cap = sqrt(1.0 - u2);
    var n = normalize(v.normal * cap + v.bend);
    // Two-sided: the normal faces the viewer (cut-open tubes show their inside).
    if (dot(n, v.rel) > 0.0) {
        n = -n;
    }
    o.normal = vec4<f32>(n, 1.0);
    o.depth = vec4<f32>(surface_depth(v), 0.0, 0.0, 1.0);
    return o;
}

// The linear depth of the surface at this fragment (a cylinder line's bulge taken off).
fn surface_depth(v: VOut) -> f32 {
    let u2 = min(dot(v.bend, v.bend), 1.0);
    return dot(v.rel, G.forward.xyz) - v.bulge * sqrt(1.0 - u2);
}

// Multisampled G-buffer: colour and normal per sample (for per-sample shading).
struct SurfaceOut {
    @location(0) color: vec4<f32>,
    @location(1) normal: vec4<f32>,
};

@fragment
fn fs_surface(packed: VOutP) -> SurfaceOut {
    let v = unpack(packed);
    let f = front_values(v);
    var o: SurfaceOut;
    o.color = f.color;
    o.normal = f.normal;
    return o;
}

// Slices of volumes (`[[slices]]`; Rust: engine/src/planes.rs, CPU twin: planes::plane_color):
// planar polygons drawn as meshes whose colour each fragment samples from the layers' grid at
// its own world position - the slice's volume, then the overlays blended over it in order.
// Keep in sync with `planes::PlaneLayerParams`.
struct PlaneLayer {
    // the window: t = (v - lo) / (hi - lo) runs the colour map from its low end (t = 0) to its
    // high end (t = 1); lo > hi turns it round (negative statistics)
    lo: f32,
    hi: f32,
    opacity: f32,
    // 0: scalar (trilinear) through the 256 colours at `lut`; 1: labels (the nearest voxel),
    // label l's colour at lut + l (alpha 0: hidden), `count` entries
    labels: u32,
    lut: u32,
    count: u32,
    // 1: the slice's own volume (opaque; t clamped to [0, 1], NaN at the low end); 0: an
    // overlay (transparent where t <= 0 or NaN, clamped above)
    base: u32,
    pad: u32,
};

// Keep in sync with `planes::PlaneParams`.
struct PlaneParams {
    // camera-relative position (VOut.rel) to the layers' voxel index
    rel_to_index: mat4x4<f32>,
    // the grid's samples per axis (xyz) and the number of layers (w, 1 to 4)
    dims: vec4<u32>,
    // x: 1 when the slice is lit by the head light, 0 when it shows its colours unshaded
    shading: vec4<u32>,
    layers: array<PlaneLayer, 4>,
};

@group(2) @binding(0) var<uniform> PP: PlaneParams;
@group(2) @binding(1) var<storage, read> plane_lut: array<vec4<f32>>;
@group(2) @binding(2) var<storage, read> plane_f0: array<f32>;
@group(2) @binding(3) var<storage, read> plane_f1: array<f32>;
@group(2) @binding(4) var<storage, read> plane_f2: array<f32>;
@group(2) @binding(5) var<storage, read> plane_f3: array<f32>;

fn plane_voxel(l: u32, i: vec3<u32>) -> f32 {
    let n = i.x + PP.dims.x * (i.y + PP.dims.y * i.z);
    switch l {
        case 0u: { return plane_f0[n]; }
        case 1u: { return plane_f1[n]; }
        case 2u: { return plane_f2[n]; }
        default: { return plane_f3[n]; }
    }
}

// Layer l at index-space q (clamped into the grid): trilinear, or the nearest voxel
// (floor(q + 0.5)) for labels. NaN corners make NaN.
fn plane_sample(l: u32, q: vec3<f32>, nearest: bool) -> f32 {
    let hi = vec3<f32>(PP.dims.xyz) - vec3<f32>(1.0);
    let c = clamp(q, vec3<f32>(0.0), hi);
    if (nearest) {
        return plane_voxel(l, vec3<u32>(floor(c + vec3<f32>(0.5))));
    }
    let b = min(vec3<u32>(floor(c)), max(PP.dims.xyz, vec3<u32>(2u)) - vec3<u32>(2u));
    let top = PP.dims.xyz - vec3<u32>(1u);
    var v: array<f32, 8>;
    for (var k = 0u; k < 8u; k = k + 1u) {
        v[k] = plane_voxel(l, min(b + cell_corner(k), top));
    }
    return trilinear_mix(v, c - vec3<f32>(b));
}

// A layer's colour (rgb) and coverage (a) at value v.
fn plane_layer_color(y: PlaneLayer, v: f32) -> vec4<f32> {
    if (y.labels != 0u) {
        // Gaps and labels outside the table are not shown.
        if (!(v >= 0.0 && v < f32(y.count))) {
            return vec4<f32>(0.0);
        }
        return plane_lut[y.lut + min(u32(floor(v + 0.5)), y.count - 1u)];
    }
    // Gaps (NaN voxels, as -3e38: engine::planes) show the low end under the slice's volume
    // and nothing of an overlay.
    let gap = v < -1e30;
    var t = (v - y.lo) / (y.hi - y.lo);
    if (y.base != 0u) {
        t = select(clamp(t, 0.0, 1.0), 0.0, gap);
    } else if (gap || !(t > 0.0)) {
        return vec4<f32>(0.0);
    }
    let x = min(t, 1.0) * 255.0;
    let i = min(u32(floor(x)), 254u);
    let c = mix(plane_lut[y.lut + i], plane_lut[y.lut + i + 1u], x - f32(i));
    return vec4<f32>(c.rgb, 1.0);
}

// The slice's colour at a fragment: its volume (opaque; a hidden or missing label shows
// black), then each overlay over it by its coverage times its opacity.
fn plane_color(rel: vec3<f32>) -> vec3<f32> {
    let q = (PP.rel_to_index * vec4<f32>(rel, 1.0)).xyz;
    var c = vec3<f32>(0.0);
    for (var l = 0u; l < min(PP.dims.w, 4u); l = l + 1u) {
        let y = PP.layers[l];
        let s = plane_layer_color(y, plane_sample(l, q, y.labels != 0u));
        if (y.base != 0u) {
            c = s.rgb * s.a;
        } else {
            c = mix(c, s.rgb, s.a * y.opacity);
        }
    }
    return c;
}

// A slice's colour in the G-buffer: alpha 1 when it is lit like the other surfaces, else
// UNLIT_ALPHA (composite shows its colour times the occlusion terms alone).
fn plane_gcolor(rel: vec3<f32>) -> vec4<f32> {
    return vec4<f32>(plane_color(rel), select(UNLIT_ALPHA, 1.0, PP.shading.x != 0u));
}

@fragment
fn fs_front_p(packed: VOutP) -> FrontOut {
    let v = unpack(packed);
    var f = front_values(v);
    f.color = plane_gcolor(v.rel);
    return f;
}

@fragment
fn fs_surface_p(packed: VOutP) -> SurfaceOut {
    let v = unpack(packed);
    let f = front_values(v);
    var o: SurfaceOut;
    o.color = plane_gcolor(v.rel);
    o.normal = f.normal;
    return o;
}

// The nearest surface's linear depth alone (single sample, beside a multisampled G-buffer).
@fragment
fn fs_depth(packed: VOutP) -> @location(0) vec4<f32> {
    let v = unpack(packed);
    if (clipped(v)) {
        discard;
    }
    return vec4<f32>(surface_depth(v), 0.0, 0.0, 1.0);
}

// LineAO's normal-depth map (single sample, drawn with the guard band): the nearest
// surface's linear depth, and its world normal facing the viewer with the width code in alpha.
struct NdOut {
    @location(0) depth: vec4<f32>,
    @location(1) normal: vec4<f32>,
    // Lines' screen tangent for anisotropic LineAO (occlusion::line_ao::tangent_texel):
    // (cos 2θ, sin 2θ, |t.x|, 1); zero for tubes.
    @location(2) tangent: vec4<f32>,
};

// A line's normal here is its strip's (the surface whose depth this map holds): the
// direction perpendicular to the tangent that faces along the viewing direction, bent across
// the width for the cylinder profile. It differs from the lit normal, which faces the eye
// point, by a pixel's angle off the view axis under perspective; LineAO's tangent plane needs
// the one that agrees with the depth.
@fragment
fn fs_nd(packed: VOutP) -> NdOut {
    let v = unpack(packed);
    return nd_values(v);
}

fn nd_values(v: VOut) -> NdOut {
    let f = front_values(v);
    var n = f.normal.xyz;
    let t = v.tangent;
    if (dot(t, t) > 0.25) {
        let c = -G.forward.xyz;
        let g = c - dot(c, t) * t;
        if (dot(g, g) > 1e-12) {
            let u2 = min(dot(v.bend, v.bend), 1.0);
            n = normalize(normalize(g) * sqrt(1.0 - u2) + v.bend);
        }
    }
    var o: NdOut;
    o.depth = f.depth;
    o.normal = vec4<f32>(n, v.width_code);
    o.tangent = vec4<f32>(0.0);
    if (dot(v.screen_t, v.screen_t) > 1e-12) {
        let st = normalize(v.screen_t);
        o.tangent = vec4<f32>(st.x * st.x - st.y * st.y, 2.0 * st.x * st.y, abs(st.x), 1.0);
    }
    return o;
}

@fragment
fn fs_back(packed: VOutP) -> @location(0) vec4<f32> {
    let v = unpack(packed);
    return back_value(v);
}

fn back_value(v: VOut) -> vec4<f32> {
    if (clipped(v)) {
        discard;
    }
    if (v.proxy > 0.0) {
        // A line standing for a tube of radius `proxy`: its far side, a diameter behind.
        return vec4<f32>(surface_depth(v) + 2.0 * v.proxy, 0.0, 0.0, 1.0);
    }
    // Back faces by their normal (the mesh's winding is not relied on).
    if (dot(v.normal, v.rel) < 0.0) {
        discard;
    }
    return vec4<f32>(dot(v.rel, G.forward.xyz), 0.0, 0.0, 1.0);
}

// Depth-dependent halos (Everts et al. 2009, §3.3 eq. 2-3; the halo width against the depth gap,
// Appendix A corrected: occlusion::halos). A haloed line's fragment is its core where
// |across| is below the core's fraction of the strip, 1 / halo_width (narrowed by depth
// cueing), else its rim, pushed back by halo_depth f(|across|) in linear depth and written to
// the depth attachment through frag_depth.
struct Halo {
    rim: bool,
    // the linear depth the fragment is drawn at
    depth: f32,
    // the depth attachment's value
    frag: f32,
};

fn displacement(x: f32) -> f32 {
    if (LP.displacement == 1u) {
        return sqrt(x);
    }
    if (LP.displacement == 2u) {
        return x * x;
    }
    return x;
}

// The depth attachment's value of a linear view depth (camera.rs conventions: 0 at near, 1 at
// far).
fn attachment_depth(z: f32) -> f32 {
    if (LP.perspective != 0u) {
        return LP.far / (LP.near - LP.far) * (LP.near - z) / max(z, 1e-12);
    }
    return (LP.near - z) / (LP.near - LP.far);
}

fn halo_at(v: VOut) -> Halo {
    var h: Halo;
    let z = surface_depth(v);
    // The distance from the line's centre (points: from the disc's, a cone).
    let a = length(v.across);
    var core = 1.0 / LP.halo_width;
    if (LP.depth_cue > 0.0) {
        let t = clamp((z - LP.near) / (LP.far - LP.near), 0.0, 1.0);
        core = core * (1.0 - LP.depth_cue * t);
    }
    // A sample exactly on the core's edge (a line of odd width on the pixel grid) is core:
    // decided by rounding, the overlapping strips of a line's neighbouring segments would each
    // draw it their own way (Rust: occlusion::halos::EDGE_TOLERANCE, the same factor).
    h.rim = a > core * (1.0 + 1e-3);
    // The square caps hold the core only, reaching half the core's width beyond the point:
    // the joints stay closed while no rim lies beyond a segment's end, where it would hide
    // the next segment of a line that bends away in depth (and a line's tip carries no halo,
    // as the paper's strips).
    let beyond = max(-v.seg.x, v.seg.x - v.seg.y);
    if (beyond > 0.0 && (h.rim || beyond > v.seg.z)) {
        discard;
    }
    h.depth = z;
    if (h.rim && LP.halo == 2u) {
        h.depth = z + LP.halo_depth * displacement(min(a, 1.0));
    }
    h.frag = clamp(attachment_depth(h.depth), 0.0, 1.0);
    return h;
}

// The colour of a halo sample in the G-buffer: alpha 0.5 marks it (composite paints it with
// the halo colour, the background unless the method is illustrative); an outline rim is black
// and a surface, alpha 0.9 marking it unlit (composite adds no specular highlight to it).
// An unlit slice (`[[slices]] lit = false`): alpha 0.97.
const HALO_ALPHA: f32 = 0.5;
const OUTLINE_ALPHA: f32 = 0.9;
const UNLIT_ALPHA: f32 = 0.97;

struct FrontOutH {
    @location(0) color: vec4<f32>,
    @location(1) normal: vec4<f32>,
    @location(2) depth: vec4<f32>,
    @builtin(frag_depth) frag: f32,
};

fn rim_color(f: FrontOut) -> vec4<f32> {
    if (LP.halo_outline != 0u) {
        return vec4<f32>(0.0, 0.0, 0.0, OUTLINE_ALPHA);
    }
    return vec4<f32>(0.0, 0.0, 0.0, HALO_ALPHA);
}

@fragment
fn fs_front_h(packed: VOutPH) -> FrontOutH {
    let v = unpack_h(packed);
    return front_h_values(v);
}

fn front_h_values(v: VOut) -> FrontOutH {
    let f = front_values(v);
    let h = halo_at(v);
    var o: FrontOutH;
    o.color = f.color;
    o.normal = f.normal;
    o.depth = vec4<f32>(h.depth, 0.0, 0.0, 1.0);
    o.frag = h.frag;
    if (h.rim) {
        o.color = rim_color(f);
        if (LP.halo_outline == 0u) {
            o.depth = vec4<f32>(0.0);
        }
    }
    return o;
}

struct SurfaceOutH {
    @location(0) color: vec4<f32>,
    @location(1) normal: vec4<f32>,
    @builtin(frag_depth) frag: f32,
};

@fragment
fn fs_surface_h(packed: VOutPH) -> SurfaceOutH {
    let v = unpack_h(packed);
    let f = front_h_values(v);
    var o: SurfaceOutH;
    o.color = f.color;
    o.normal = f.normal;
    o.frag = f.frag;
    return o;
}

struct DepthOutH {
    @location(0) depth: vec4<f32>,
    @builtin(frag_depth) frag: f32,
};

@fragment
fn fs_depth_h(packed: VOutPH) -> DepthOutH {
    let v = unpack_h(packed);
    let f = front_h_values(v);
    var o: DepthOutH;
    o.depth = f.depth;
    o.frag = f.frag;
    return o;
}

struct NdOutH {
    @location(0) depth: vec4<f32>,
    @location(1) normal: vec4<f32>,
    @location(2) tangent: vec4<f32>,
    @builtin(frag_depth) frag: f32,
};

@fragment
fn fs_nd_h(packed: VOutPH) -> NdOutH {
    let v = unpack_h(packed);
    let n = nd_values(v);
    let f = front_h_values(v);
    var o: NdOutH;
    o.depth = f.depth;
    o.normal = n.normal;
    o.tangent = n.tangent;
    if (f.depth.x <= 0.0) {
        o.tangent = vec4<f32>(0.0);
    }
    o.frag = f.frag;
    return o;
}

struct BackOutH {
    @location(0) depth: vec4<f32>,
    @builtin(frag_depth) frag: f32,
};

@fragment
fn fs_back_h(packed: VOutPH) -> BackOutH {
    let v = unpack_h(packed);
    let h = halo_at(v);
    if (h.rim && LP.halo_outline == 0u) {
        // A gap is no surface: nothing is inside it.
        discard;
    }
    var o: BackOutH;
    o.depth = back_value(v);
    o.frag = h.frag;
    return o;
}

// Translucent meshes and slices (Rust: gbuffer::Peel): depth peeling, one layer per pass, the
// nearest first. A layer keeps, per pixel, the nearest translucent fragment behind the previous
// layer's (strictly) and in front of the opaque surfaces; the march pass composites the layers
// into the volume in depth order. Group 3: the previous layer's normal and depth (w; 0 where
// none: the first pass reads a target that is never written) and the opaque front depth.
@group(3) @binding(0) var peel_prev: texture_2d<f32>;
@group(3) @binding(1) var peel_front: texture_2d<f32>;

struct PeelOut {
    // straight colour, and the mesh's opacity
    @location(0) color: vec4<f32>,
    // world normal facing the viewer, and the linear view depth
    @location(1) nd: vec4<f32>,
};

fn peel_values(v: VOut, color: vec3<f32>) -> PeelOut {
    let f = front_values(v);
    let px = vec2<i32>(floor(v.clip.xy));
    let z = f.depth.x;
    let front = textureLoad(peel_front, px, 0).r;
    if (front > 0.0 && z >= front) {
        discard;
    }
    if (z <= textureLoad(peel_prev, px, 0).w) {
        discard;
    }
    var o: PeelOut;
    o.color = vec4<f32>(color, G.opacity);
    o.nd = vec4<f32>(f.normal.xyz, z);
    return o;
}

@fragment
fn fs_peel(packed: VOutP) -> PeelOut {
    let v = unpack(packed);
    return peel_values(v, v.color);
}

// A translucent slice; unlit (`PP.shading.x` 0), its normal is written as zero, which the
// march (`slice_pass.wgsl` `composite_layer`) takes for its colour unshaded.
@fragment
fn fs_peel_p(packed: VOutP) -> PeelOut {
    let v = unpack(packed);
    var o = peel_values(v, plane_color(v.rel));
    if (PP.shading.x == 0u) {
        o.nd = vec4<f32>(0.0, 0.0, 0.0, o.nd.w);
    }
    return o;
}
