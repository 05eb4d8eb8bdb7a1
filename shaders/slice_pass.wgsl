// View-aligned slices through the volume and the tubes: Schott et al., Algorithms 1-4.
// Rust side and the maths it implements: engine/src/slice_pass.rs. Conventions:
// engine/src/camera.rs. Slice k is the plane at view depth z_k = z0 + (k + 0.5) d; it stands
// for the slab [z0 + k d, z0 + (k + 1) d].
//
// Two entry points share the per-sample code:
// * `light` does one step of the volumetric occlusion buffer (Alg. 3) on a grid of cells of
//   s x s pixels (the dispatch is the barrier the blur needs): a step is `light_step x
//   light_samples` slices deep (`occlusion::combined::light_view`; 1: the paper's slice),
//   sampled in `light_samples` parts (`occlusion::combined::light_samples`); O_k gathered from
//   the light leaving step k - 1 with the cone blur, the light leaving step k through the
//   volume and the tubes' thickness, O_k and the light reaching each further part stored in
//   the light volume (cells x stored slices, `light_samples` a step); the march reads each
//   step's front (`light_step_front`) and carries it along the pixel's own ray through the
//   step (`composite_eye`; occlusion::combined::light_in_slab); the surfaces' partial
//   occlusion reads `light_front`'s (eq. 1-3).
// * `march` walks every slice of a pixel in one invocation: the eye buffer (Alg. 2) with the
//   volume's colour modulated by the light volume when there is one, rays clipped to the
//   grid's box and to the surface, empty bricks skipped, early termination; then the partial
//   occlusion of the surface (Alg. 4, eq. 1-3 in the intended order) from the light volume.

// Phong shading of the volume with on-the-fly gradients: a pipeline constant, so that the
// other methods' march does not carry the gradient code (it halves lavapipe's speed even
// when a uniform flag skips it).
override PHONG: bool = false;

// The cone-following occlusion model (engine/src/slice_pass.rs): the light buffers carry, per
// cell, the light L and the shadow-weighted age of the shadow S D (S = 1 - L), and each step's
// blur radius grows with that age so that a shadow spreads as the cone does. Off: the paper's
// constant per-slice blur (the buffers then hold L only, at the same stride).
override CONE: bool = false;

// A 2-D transfer function (value x gradient magnitude): rows of 1-D points, interpolated in
// the gradient magnitude (ea_pass::Transfer). A constant, so 1-D functions skip the gradient.
override TF2D: bool = false;

// A projection instead of emission-absorption (Rust: method::VolumeShading::Projection): 0
// none, 1 the largest value along the ray (MIP), 2 the smallest (MinIP). CPU twin:
// occlusion::projection.
override PROJECTION: u32 = 0u;
// How the field's samples are stored (see `voxel`): 0 f32, 1 two 16-bit integers a word, 2
// four 8-bit integers. A pipeline constant, so a volume in f32 reads it as directly as ever (a
// run-time switch cost lavapipe 1.7x); how many bindings they span is written into the shader
// (`field_word`, below).
override PACKING: u32 = 0u;

// Keep in sync with `slice_pass::SliceParams`.
struct Params {
    frame: Frame,
    world_to_index: mat4x4<f32>,
    // grid samples per axis; transfer-function points (1-D)
    dims: vec3<u32>,
    n_tf: u32,
    // empty-space bricks per axis; a brick's edge in voxels
    bricks: vec3<u32>,
    brick: u32,
    // the slab's front depth, the slice spacing, tan(theta), the tubes' extinction per unit
    z0: f32,
    dz: f32,
    tan_theta: f32,
    geometry_extinction: f32,
    // clipping planes (normal, offset), keeping normal . p <= offset
    clip: array<vec4<f32>, 8>,
    n_clip: u32,
    n_slices: u32,
    // 1: the light volume (occlusion buffer) shades the volume
    occlusion: u32,
    // 1: the paper's endless shadow column behind surfaces
    column: u32,
    has_volume: u32,
    // blur taps per axis (n x n)
    blur_samples: u32,
    // 2-D transfer-function rows (0: 1-D)
    tf_rows: u32,
    // the layer of `terms` the partial occlusion goes to (NO_LAYER: none)
    partial_layer: u32,
    light: Light,
    // occlusion-buffer cells per axis; a cell's edge in pixels
    cells: vec2<u32>,
    cell: u32,
    // translucent layers peeled by the G-buffer (gbuffer.wgsl fs_peel)
    peel_layers: u32,
    // an overlay blended into the volume's colour (slice_pass::GpuBlend): world to its grid's
    // index, its grid, on/off, window, opacity, labels (1) and their count
    blend_to_index: mat4x4<f32>,
    blend_dims: vec3<u32>,
    blend_on: u32,
    blend_lo: f32,
    blend_hi: f32,
    blend_opacity: f32,
    blend_labels: u32,
    blend_count: u32,
    // 32-bit words in each of the field's parts (see `voxel`)
    part_len: u32,
    // how samples are packed: 0 f32, 1 two 16-bit integers a word, 2 four 8-bit integers
    packing: u32,
    // added to a packed integer to give the sample's value
    value_offset: f32,
    // eye slices per stored slice of the light volume (a power of two) and the stored slices
    // it holds (the march reads step fronts, `light_step_front`; the surfaces any slice's front,
    // `light_front`)
    light_step: u32,
    light_slices: u32,
    // stored slices per step of the `light` entry (its slabs light_step light_samples d
    // deep): volume samples at the middles of equal parts of its slab (a voxel apart)
    light_samples: u32,
    // the light's extinction factor: its mean path through a slab over the cone's directions,
    // -ln(cos theta) / (1 - cos theta) (`occlusion::combined::cone_path_factor`)
    light_path: f32,
    // eye slices between the march's reads of the light volume: a step (light_step
    // light_samples), or a stored slice (light_step) where tubes, lines or planes cast light
    // (their coverage is in the light's parts, not in the pixel's own samples)
    light_read: u32,
    light_pad0: u32,
    light_pad1: u32,
    light_pad2: u32,
};

const NO_LAYER: u32 = 0xffffffffu;
// Arriving light below which the light pass takes no samples: the cell passes its light on
// unattenuated (occlusion::combined::DARK, 1/1024; the CPU sweep alike).
const DARK: f32 = 0.0009765625;

// Per slice (a dynamic offset into a storage buffer): the index, whether the blur needs the
// tap loop (radius above one cell), the radius in cells, and otherwise the blur as a 3x3
// stencil (rows y = -1, 0, 1 in xyz of w[0..3]) - the n x n bilinear taps summed on the CPU,
// the same for every cell of the slice.
// Keep in sync with `slice_pass::SliceRow`.
struct Slice {
    k: u32,
    wide: u32,
    pad: vec2<u32>,
    rpx: vec4<f32>,
    w: array<vec4<f32>, 3>,
};

@group(0) @binding(0) var<uniform> P: Params;
@group(0) @binding(1) var<storage, read> field: array<u32>;
// Transfer function points: (value, r, g, b, extinction, 0, 0, 0) each.
@group(0) @binding(2) var<storage, read> tf: array<f32>;
@group(0) @binding(3) var<storage, read> occupied: array<u32>;
// Eye buffer: premultiplied colour and opacity of the volume in front of the surface.
@group(0) @binding(4) var<storage, read_write> eye_buf: array<vec4<f32>>;
// Per pixel two vec4: (unused, partial occlusion, sum w O, sum w), (depth where the eye
// buffer's opacity reached 0.5 or 0, unused x3).
@group(0) @binding(5) var<storage, read_write> state: array<vec4<f32>>;
// Linear depth of the tubes' nearest front and back faces (0: none).
@group(0) @binding(6) var front_depth: texture_2d<f32>;
@group(0) @binding(7) var back_depth: texture_2d<f32>;
// O per cell and step of the light (index cx + cells.x (cy + cells.y j)).
@group(0) @binding(8) var<storage, read_write> light_volume: array<f32>;
// Per cell: (nearest front depth of its pixels or 0, farthest back depth, 1 / cos of the
// cell's ray, unused).
@group(0) @binding(9) var<storage, read_write> cell_state: array<vec4<f32>>;
// The surface terms' layers (see composite.wgsl): `march` writes the partial occlusion.
@group(0) @binding(10) var<storage, read_write> terms: array<f32>;
// Translucent layers, nearest first (gbuffer::Peel): straight colour and opacity; normal and
// linear depth (w; 0: no layer).
@group(0) @binding(11) var peel_color: texture_2d_array<f32>;
@group(0) @binding(12) var peel_nd: texture_2d_array<f32>;
// The blended overlay's field (NaN as -3e38) and colours (256, or one per label).
@group(0) @binding(13) var<storage, read> blend_field: array<f32>;
@group(0) @binding(14) var<storage, read> blend_lut: array<vec4<f32>>;
@group(1) @binding(0) var<storage, read> S: Slice;
// Light leaving the previous slice towards the next (L_{k-1} = O_{k-1} (1 - alpha_{k-1})),
// and the same for this slice, per cell.
@group(1) @binding(1) var<storage, read> occ_in: array<f32>;
@group(1) @binding(2) var<storage, read_write> occ_out: array<f32>;

fn occ_texel(p: vec2<i32>) -> f32 {
    let q = clamp(p, vec2<i32>(0), vec2<i32>(P.cells) - vec2<i32>(1));
    return occ_in[2u * (u32(q.x) + P.cells.x * u32(q.y))];
}

// Both channels of a cell (light, shadow-weighted age).
fn occ_texel2(p: vec2<i32>) -> vec2<f32> {
    let q = clamp(p, vec2<i32>(0), vec2<i32>(P.cells) - vec2<i32>(1));
    let i = 2u * (u32(q.x) + P.cells.x * u32(q.y));
    return vec2<f32>(occ_in[i], occ_in[i + 1u]);
}

fn occ_bilinear2(t: vec2<f32>) -> vec2<f32> {
    let s = t - vec2<f32>(0.5);
    let b = vec2<i32>(floor(s));
    let f = s - floor(s);
    let a = mix(occ_texel2(b), occ_texel2(b + vec2<i32>(1, 0)), f.x);
    let c = mix(occ_texel2(b + vec2<i32>(0, 1)), occ_texel2(b + vec2<i32>(1, 1)), f.x);
    return mix(a, c, f.y);
}

// Bilinear read of the previous slice's light at a continuous cell position (centres at
// half-integers, clamped at the border).
fn occ_bilinear(t: vec2<f32>) -> f32 {
    let s = t - vec2<f32>(0.5);
    let b = vec2<i32>(floor(s));
    let f = s - floor(s);
    let a = mix(occ_texel(b), occ_texel(b + vec2<i32>(1, 0)), f.x);
    let c = mix(occ_texel(b + vec2<i32>(0, 1)), occ_texel(b + vec2<i32>(1, 1)), f.x);
    return mix(a, c, f.y);
}

// The light volume at a continuous pixel position, bilinear over cells, at fractional stored
// slice kf (linear between stored slices, the last one's beyond it). A stored slice holds the
// light reaching the front of its slab (occlusion::combined::light_view).
fn light_bilinear(px: vec2<f32>, kf: f32) -> f32 {
    let c = px / f32(P.cell) - vec2<f32>(0.5);
    let b = vec2<i32>(floor(c));
    let f = c - floor(c);
    let hi = vec2<i32>(P.cells) - vec2<i32>(1);
    var v: array<f32, 4>;
    for (var i = 0; i < 4; i = i + 1) {
        let q = clamp(b + vec2<i32>(i & 1, i >> 1u), vec2<i32>(0), hi);
        v[i] = light_step_at(u32(q.x) + P.cells.x * u32(q.y), kf);
    }
    return mix(mix(v[0], v[1], f.x), mix(v[2], v[3], f.x), f.y);
}

// The light reaching the front of the march's light read s (`light_read` eye slices each: a
// light step, or where tubes cast light a stored slice): stored slice
// s light_read / light_step (`LightVolume::front` in raycast/src/light.rs). The march carries
// it along the pixel's own ray to the next read (`composite_eye`;
// occlusion::combined::light_in_slab).
fn light_step_front(px: vec2<f32>, s: u32) -> f32 {
    return light_bilinear(px, f32(s * (P.light_read / P.light_step)));
}

// O_k of eye slice k, the light reaching the front of slab k: stored slice k / light_step.
// The surfaces' partial occlusion reads it (eq. 1-3).
fn light_front(px: vec2<f32>, k: u32) -> f32 {
    return light_bilinear(px, f32(k) / f32(P.light_step));
}

// The view depth where the clipping planes let ray r in (the largest entry over the planes it
// crosses front to back), or -1 when none does.
fn clip_entry(r: Ray) -> f32 {
    var a = -1.0;
    for (var c = 0u; c < P.n_clip; c = c + 1u) {
        let n = P.clip[c].xyz;
        let g1 = dot(n, r.d) / r.cosine;
        let g0 = dot(n, r.o) - P.clip[c].w - g1 * r.o_depth;
        if (g1 < -1e-12) {
            a = max(a, -g0 / g1);
        }
    }
    return a;
}

// Cell ci's light at fractional step kf: O interpolated between steps, 1 in front of step -1
// (O_{-1} = 1), the last step's beyond it (`LightVolume::cell_at` in raycast/src/light.rs).
fn light_step_at(ci: u32, kf: f32) -> f32 {
    let n = P.light_slices;
    let base = P.cells.x * P.cells.y;
    if (kf <= -1.0) {
        return 1.0;
    }
    if (kf < 0.0) {
        return mix(1.0, light_volume[ci], kf + 1.0);
    }
    let k0 = u32(floor(kf));
    let t = kf - floor(kf);
    let a = light_volume[ci + base * min(k0, n - 1u)];
    let b = light_volume[ci + base * min(k0 + 1u, n - 1u)];
    return mix(a, b, t);
}

// light_step_at for a cell whose ray enters the medium at stored slice `entry` (its cut; -1e30
// none): within the stored slice `entry` lies in, constant up to `entry` and geometric from there
// to the next (`LightVolume::cell_from` in raycast/src/light.rs): nothing before the cut absorbs.
fn light_step_from(ci: u32, kf: f32, entry: f32) -> f32 {
    if (kf < 0.0) {
        return light_step_at(ci, kf);
    }
    let n = P.light_slices;
    let base = P.cells.x * P.cells.y;
    let fl = floor(kf);
    let k0 = u32(fl);
    let s = max(entry, fl);
    var t = 0.0;
    if (s < kf) {
        t = (kf - s) / (fl + 1.0 - s);
    }
    let a = light_volume[ci + base * min(k0, n - 1u)];
    let b = light_volume[ci + base * min(k0 + 1u, n - 1u)];
    // Geometric from a cut within the stored slice, a (b / a)^t: exact for a medium uniform
    // between the two (`geometric` in raycast/src/light.rs, there by its own logarithm and
    // exponential); linear elsewhere, and within 1% of each other.
    let lo = min(a, b);
    if (t == 0.0 || !(lo > 1e-20) || !(s > fl) || !(max(a, b) - lo > 0.01 * max(a, b))) {
        return mix(a, b, t);
    }
    let hi = max(a, b);
    let u = select(1.0 - t, t, a >= b);
    return hi * exp(-u * log(hi / lo));
}

// Where a pixel behind a clipping plane reads its four cells: each cell at the same distance
// behind the plane as the pixel's sample (slice k + shift), not at the same depth. A cut face
// tilted to the slices meets a 2-pixel cell's rays in different slabs; read at equal depth, a
// cell whose cut is a slab nearer has absorbed a slab's worth more and the face shows a band
// per slice (`LightVolume::clip_shifts` in raycast/src/light.rs is the CPU twin).
struct CellShift {
    cells: array<u32, 4>,
    shift: vec4<f32>,
    // Where each cell's ray enters the medium at the cut, in eye slices (-1e30: no cut).
    start: vec4<f32>,
    f: vec2<f32>,
    // Where the pixel's ray enters the medium at the cut, in eye slices (-1e30: no cut).
    entry: f32,
};

fn cell_shifts(px: vec2<f32>, r: Ray) -> CellShift {
    var cs: CellShift;
    let c = px / f32(P.cell) - vec2<f32>(0.5);
    let b = vec2<i32>(floor(c));
    cs.f = c - floor(c);
    let hi = vec2<i32>(P.cells) - vec2<i32>(1);
    let a_px = clip_entry(r);
    cs.entry = select(-1e30, (a_px - P.z0) / P.dz, a_px >= 0.0);
    for (var i = 0; i < 4; i = i + 1) {
        let q = clamp(b + vec2<i32>(i & 1, i >> 1u), vec2<i32>(0), hi);
        cs.cells[i] = u32(q.x) + P.cells.x * u32(q.y);
        let a_c = clip_entry(pixel_ray(P.frame, (vec2<f32>(q) + vec2<f32>(0.5)) * f32(P.cell)));
        var sh = 0.0;
        var st = -1e30;
        if (a_px >= 0.0 && a_c >= 0.0) {
            sh = (a_c - a_px) / P.dz;
            st = (a_c - P.z0) / P.dz;
        }
        cs.shift[i] = sh;
        cs.start[i] = st;
    }
    return cs;
}

// Each cell with its shift (the same distance behind the planes as the pixel), between stored
// slices: on a ray's first read, where it enters the medium at the cut (its first sample in its
// cut's slice), at the cell's cut; a first read deeper at the front of the read its own slice
// k + shift lies in; later at the pixel's read's front plus the shift (the stored parts there
// hold the cell's own attenuation). Read at the pixel's front from the start, the cells would
// lie further in front of their cuts the further the pixel's lies behind its front: a line a
// step on a tilted cut face (`LightVolume::front` in raycast/src/light.rs).
fn light_shifted(cs: CellShift, k: u32, first: bool) -> f32 {
    let e = f32(P.light_read);
    let kf = f32(k / P.light_read * P.light_read);
    // The ray's first sample is its cut's slice: it enters the medium at the cut.
    let at_cut = first && f32(k) < cs.entry + 1.0;
    var v: array<f32, 4>;
    for (var i = 0; i < 4; i = i + 1) {
        var x = kf + cs.shift[i];
        if (at_cut) {
            x = max(f32(k) + cs.shift[i], cs.start[i]);
        } else if (first) {
            x = floor((f32(k) + cs.shift[i]) / e) * e;
        }
        v[i] = light_step_from(cs.cells[i], x / f32(P.light_step), cs.start[i] / f32(P.light_step));
    }
    return mix(mix(v[0], v[1], cs.f.x), mix(v[2], v[3], cs.f.x), cs.f.y);
}

// Behind clipping planes, where a ray reaches its next light read: the light it carries on and
// the factor each sample multiplies it by (besides its own attenuation), so that the carried
// light reaches the front read over the read's eye slices instead of jumping there,
// (front / carried)^(1 / light_read) within [1e-3, 1e3] by square roots (light_read is a power
// of two); a ray's first read, or a light carried below 1e-20, takes the front
// (`raycast::light::front_gain`, whose docs say why).
fn front_gain(carried: f32, front: f32, first: bool) -> vec2<f32> {
    if (first || !(carried > 1e-20)) {
        return vec2<f32>(front, 1.0);
    }
    var g = clamp(front / carried, 1e-3, 1e3);
    for (var n = P.light_read; n > 1u; n = n >> 1u) {
        g = sqrt(g);
    }
    return vec2<f32>(carried, g);
}

// A volume larger than one storage binding is split into parts of `part_len` words (in file
// order): `field` holds the first, `field1`, `field2`, ... (group 2) the rest, as many as the
// adapter binds (`slice_pass::volume_parts`). Their declarations and `field_word`, which picks
// the part of word w, are written by `slice_pass::field_parts_wgsl` in place of the next line.
// A word is an f32 sample, or two 16-bit or four 8-bit integers of an integer-valued volume
// (the value is the integer + `value_offset`): 2x or 4x less memory and bandwidth, the same
// values.
//@field-parts

fn voxel(i: vec3<u32>) -> f32 {
    let l = i.x + P.dims.x * (i.y + P.dims.y * i.z);
    if (PACKING == 0u) {
        return bitcast<f32>(field_word(l));
    }
    if (PACKING == 1u) {
        let w = field_word(l >> 1u);
        return f32((w >> ((l & 1u) * 16u)) & 0xFFFFu) + P.value_offset;
    }
    let w = field_word(l >> 2u);
    return f32((w >> ((l & 3u) * 8u)) & 0xFFu) + P.value_offset;
}

// Trilinear sample at index-space position q (inside the grid).
fn trilinear(q: vec3<f32>) -> f32 {
    let b = min(vec3<u32>(floor(q)), max(P.dims, vec3<u32>(2u)) - vec3<u32>(2u));
    var v: array<f32, 8>;
    for (var c = 0u; c < 8u; c = c + 1u) {
        v[c] = voxel(b + cell_corner(c));
    }
    return trilinear_mix(v, q - vec3<f32>(b));
}

// Colour (rgb) and extinction (a) at value v of the 1-D function in points [first, end).
fn transfer_row(v: f32, first: u32, end: u32) -> vec4<f32> {
    if (end <= first) {
        return vec4<f32>(0.0);
    }
    let f = 8u * first;
    if (v <= tf[f]) {
        return vec4<f32>(tf[f + 1u], tf[f + 2u], tf[f + 3u], tf[f + 4u]);
    }
    for (var i = first + 1u; i < end; i = i + 1u) {
        let x1 = tf[8u * i];
        if (v <= x1) {
            let j = 8u * (i - 1u);
            let x0 = tf[j];
            let a = vec4<f32>(tf[j + 1u], tf[j + 2u], tf[j + 3u], tf[j + 4u]);
            let b = vec4<f32>(tf[8u * i + 1u], tf[8u * i + 2u], tf[8u * i + 3u], tf[8u * i + 4u]);
            return mix(a, b, select(0.0, (v - x0) / (x1 - x0), x1 > x0));
        }
    }
    let l = 8u * (end - 1u);
    return vec4<f32>(tf[l + 1u], tf[l + 2u], tf[l + 3u], tf[l + 4u]);
}

// Colour (rgb) and extinction (a) at value v and gradient magnitude g. The rows of a 2-D
// function follow the points in `tf`: (gradient, first point, end point, 0) each.
fn transfer(v: f32, g: f32) -> vec4<f32> {
    let n = P.n_tf;
    let nr = P.tf_rows;
    if (!TF2D || nr == 0u) {
        return transfer_row(v, 0u, n);
    }
    let base = 8u * n;
    if (g <= tf[base]) {
        return transfer_row(v, u32(tf[base + 1u]), u32(tf[base + 2u]));
    }
    for (var j = 1u; j < nr; j = j + 1u) {
        let r = base + 4u * j;
        if (g <= tf[r]) {
            let q = r - 4u;
            let t = select(0.0, (g - tf[q]) / (tf[r] - tf[q]), tf[r] > tf[q]);
            let a = transfer_row(v, u32(tf[q + 1u]), u32(tf[q + 2u]));
            let b = transfer_row(v, u32(tf[r + 1u]), u32(tf[r + 2u]));
            return mix(a, b, t);
        }
    }
    let l = base + 4u * (nr - 1u);
    return transfer_row(v, u32(tf[l + 1u]), u32(tf[l + 2u]));
}

// The slices a ray meets inside the grid's box (first, one past the last), in front of the
// surface at depth `front` when there is one (> 0). In index space the box is
// [0, dims - 1]^3 and the ray's position is affine in its parameter s.
fn box_slices(r: Ray, front: f32) -> vec2<u32> {
    let qo = (P.world_to_index * vec4<f32>(r.o, 1.0)).xyz;
    let qd = (P.world_to_index * vec4<f32>(r.d, 0.0)).xyz;
    let hi = vec3<f32>(P.dims) - vec3<f32>(1.0);
    let inv = 1.0 / select(qd, vec3<f32>(1e-30), abs(qd) < vec3<f32>(1e-30));
    let t0 = (vec3<f32>(0.0) - qo) * inv;
    let t1 = (hi - qo) * inv;
    let s_in = max(max(min(t0.x, t1.x), min(t0.y, t1.y)), min(t0.z, t1.z));
    let s_out = min(min(max(t0.x, t1.x), max(t0.y, t1.y)), max(t0.z, t1.z));
    if (s_out < s_in || P.has_volume == 0u) {
        return vec2<u32>(0u);
    }
    let k_in = (s_in * r.cosine + r.o_depth - P.z0) / P.dz - 0.5;
    var k_out = (s_out * r.cosine + r.o_depth - P.z0) / P.dz - 0.5;
    if (front > 0.0) {
        k_out = min(k_out, (front - P.z0) / P.dz);
    }
    let n = f32(P.n_slices);
    return vec2<u32>(u32(clamp(floor(k_in), 0.0, n)), u32(clamp(ceil(k_out) + 1.0, 0.0, n)));
}


// The ray through a continuous pixel position (y down), as Camera::ray.

// The part of slice k's slab [z0 + k d, z0 + (k + 1) d] (view depths) the ray keeps: in front
// of the surface at depth `front` (when > 0) and on the kept side of every clipping plane
// (n . p <= offset; along the ray n . p is affine in depth). Empty when y <= x. Clipping the
// slab rather than dropping samples keeps cut faces free of slice steps.
fn slab_interval(r: Ray, k: u32, front: f32) -> vec2<f32> {
    return depth_interval(r, P.z0 + f32(k) * P.dz, P.dz, front);
}

// The part of the slab [a, a + depth] the ray keeps (see `slab_interval`).
fn depth_interval(r: Ray, a0: f32, depth: f32, front: f32) -> vec2<f32> {
    var a = a0;
    var b = a + depth;
    if (front > 0.0) {
        b = min(b, front);
    }
    for (var c = 0u; c < P.n_clip; c = c + 1u) {
        let n = P.clip[c].xyz;
        let g1 = dot(n, r.d) / r.cosine;
        let g0 = dot(n, r.o) - P.clip[c].w - g1 * r.o_depth;
        if (abs(g1) < 1e-12) {
            if (g0 > 0.0) {
                b = a;
            }
        } else if (g1 > 0.0) {
            b = min(b, -g0 / g1);
        } else {
            a = max(a, -g0 / g1);
        }
    }
    return vec2<f32>(a, b);
}

// A volume sample at view depth `depth` along the ray: colour (rgb) and extinction (a); zero
// extinction outside the grid, in an empty brick, next to a NaN voxel, or behind the eye.
// `grad` receives the world-space gradient when the Phong volume asks for it.
fn volume_sample(r: Ray, depth: f32, grad: ptr<function, vec3<f32>>) -> vec4<f32> {
    if (P.has_volume == 0u) {
        return vec4<f32>(0.0);
    }
    let s = (depth - r.o_depth) / r.cosine;
    if (s < 0.0) {
        return vec4<f32>(0.0);
    }
    let p = r.o + r.d * s;
    let q = (P.world_to_index * vec4<f32>(p, 1.0)).xyz;
    let hi = vec3<f32>(P.dims) - vec3<f32>(1.0);
    if (any(q < vec3<f32>(0.0)) || any(q > hi)) {
        return vec4<f32>(0.0);
    }
    let br = min(vec3<u32>(q) / P.brick, P.bricks - vec3<u32>(1u));
    if (occupied[br.x + P.bricks.x * (br.y + P.bricks.y * br.z)] == 0u) {
        return vec4<f32>(0.0);
    }
    let v = trilinear(q);
    if (v < -1e30) {
        return vec4<f32>(0.0);
    }
    if (PHONG || TF2D) {
        // Central differences in index space (one-sided at the border), to world space by
        // the transpose of the index-from-world Jacobian.
        let e = vec3<f32>(1.0, 0.0, 0.0);
        let gx = trilinear(min(q + e.xyz, hi)) - trilinear(max(q - e.xyz, vec3<f32>(0.0)));
        let gy = trilinear(min(q + e.yxz, hi)) - trilinear(max(q - e.yxz, vec3<f32>(0.0)));
        let gz = trilinear(min(q + e.zyx, hi)) - trilinear(max(q - e.zyx, vec3<f32>(0.0)));
        let gq = 0.5 * vec3<f32>(gx, gy, gz);
        let m = P.world_to_index;
        *grad = vec3<f32>(
            dot(m[0].xyz, gq),
            dot(m[1].xyz, gq),
            dot(m[2].xyz, gq),
        );
    }
    return transfer(v, length(*grad));
}

// Empty space ahead: the slabs after the one whose sample lies at view depth `m` whose samples
// lie in the same empty brick (0 where `m`'s does not), for the march to step past - their
// samples are transparent. A later slab's sample may sit anywhere in its slab (clipping
// planes, layers), so within a slab of where the first's step puts it: slabs up to the one
// before the brick's edge minus that slab are certain. As `raycast`'s `Ray::past_block` on
// the CPU (bricks, not the cube of empty blocks around them).
fn empty_slabs(r: Ray, m: f32) -> u32 {
    let s = (m - r.o_depth) / r.cosine;
    let q = (P.world_to_index * vec4<f32>(r.o + r.d * s, 1.0)).xyz;
    let hi = vec3<f32>(P.dims) - vec3<f32>(1.0);
    // (NaN fails both bounds.)
    if (s < 0.0 || !(all(q >= vec3<f32>(0.0)) && all(q <= hi))) {
        return 0u;
    }
    let last = P.bricks - vec3<u32>(1u);
    let br = min(vec3<u32>(q) / P.brick, last);
    if (occupied[br.x + P.bricks.x * (br.y + P.bricks.y * br.z)] != 0u) {
        return 0u;
    }
    // The index-space step from a slab's sample to the next's, unclipped.
    let dq = (P.world_to_index * vec4<f32>(r.d, 0.0)).xyz * (P.dz / r.cosine);
    let lo = vec3<f32>(br * P.brick);
    // The last brick reaches the grid's end (samples past it are outside: transparent).
    let up = select(vec3<f32>((br + vec3<u32>(1u)) * P.brick), vec3<f32>(3.0e38), br == last);
    var n = 3.0e38;
    for (var a = 0u; a < 3u; a = a + 1u) {
        if (dq[a] > 1e-12) {
            n = min(n, (up[a] - q[a]) / dq[a]);
        } else if (dq[a] < -1e-12) {
            n = min(n, (q[a] - lo[a]) / -dq[a]);
        }
    }
    return u32(clamp(floor(n) - 2.0, 0.0, f32(P.n_slices)));
}

// Colour of a volume sample under the head light: unshaded emission, or Phong with the
// gradient as normal (two-sided; flat regions keep their emission).
fn shade_volume(c: vec3<f32>, grad: vec3<f32>, view_dir: vec3<f32>) -> vec3<f32> {
    if (!PHONG) {
        return c;
    }
    let g = length(grad);
    if (g < 1e-12) {
        return c;
    }
    let n = grad / g;
    let nl = abs(dot(n, view_dir));
    let spec = P.light.specular * pow(nl, P.light.shininess);
    return c * (P.light.ambient + P.light.diffuse * nl) + vec3<f32>(spec);
}

// Adds a sample to the eye buffer value `e` (Alg. 2) over the depth interval `iv` of its slab
// (clipped at the surface and the clipping planes). Accumulates the volumetric AOV
// (opacity-weighted occlusion) in `acc` and the depth where the volume becomes half opaque in
// `half`.
fn composite_eye(
    e: ptr<function, vec4<f32>>, acc: ptr<function, vec2<f32>>, half: ptr<function, f32>,
    r: Ray, iv: vec2<f32>, c: vec4<f32>, grad: vec3<f32>, lit: bool, lrun: ptr<function, f32>,
    lgain: f32,
) {
    let len = iv.y - iv.x;
    if (len <= 0.0 || c.a <= 0.0) {
        return;
    }
    let tau = c.a * len / r.cosine;
    let et = exp(-tau);
    let a = 1.0 - et;
    let w = (1.0 - (*e).a) * a;
    // Lit: the light along the ray's own path through its light step, weighted by the eye's
    // attenuation within the slab (occlusion::combined::light_in_slab): `lrun` is the light
    // reaching the slab's front along the ray, then the light leaving it.
    var lw = w;
    if (lit) {
        let ef = exp(-P.light_path * tau);
        lw = (1.0 - (*e).a) * (*lrun * ((1.0 - et * ef) / (1.0 + P.light_path)));
        *lrun = *lrun * (ef * lgain);
    }
    let rgb = shade_volume(c.rgb, grad, -r.d);
    let before = (*e).a;
    *e = vec4<f32>((*e).rgb + lw * rgb, (*e).a + w);
    *acc = *acc + vec2<f32>(lw, w);
    if ((*e).a >= 0.5 && before < 0.5) {
        *half = 0.5 * (iv.x + iv.y);
    }
}

// Concentric map of [-1, 1]^2 onto the unit disk (Shirley and Chiu).
fn concentric(a: vec2<f32>) -> vec2<f32> {
    if (a.x == 0.0 && a.y == 0.0) {
        return vec2<f32>(0.0);
    }
    let q = 0.78539816;
    if (abs(a.x) > abs(a.y)) {
        let t = q * a.y / a.x;
        return a.x * vec2<f32>(cos(t), sin(t));
    }
    let t = 1.57079633 - q * a.x / a.y;
    return a.y * vec2<f32>(cos(t), sin(t));
}

@compute @workgroup_size(8, 8, 1)
fn light(@builtin(global_invocation_id) id: vec3<u32>) {
    let cw = P.cells.x;
    let ch = P.cells.y;
    if (id.x >= cw || id.y >= ch) {
        return;
    }
    let ci = id.x + cw * id.y;
    // Step k of the light: a slab light_step light_samples eye slices deep.
    let k = S.k;
    let n = max(P.light_samples, 1u);
    let d = P.dz * f32(P.light_step * n);
    let s = P.cell;
    let centre = (vec2<f32>(id.xy) + vec2<f32>(0.5)) * f32(s);
    let r = pixel_ray(P.frame, centre);
    // Per-cell constants at the first slice: the depth range of the tubes over its pixels.
    var cs: vec4<f32>;
    if (k == 0u) {
        var lo = 3e38;
        var hi = 0.0;
        for (var j = 0u; j < s; j = j + 1u) {
            for (var i = 0u; i < s; i = i + 1u) {
                let p = vec2<i32>(min(id.xy * s + vec2<u32>(i, j), vec2<u32>(P.frame.size.x, P.frame.size.y) - vec2<u32>(1u)));
                let f = textureLoad(front_depth, p, 0).r;
                if (f > 0.0) {
                    lo = min(lo, f);
                    hi = max(hi, max(textureLoad(back_depth, p, 0).r, f));
                }
            }
        }
        // The light's path per unit of slab depth: along the ray (1 / cosine), times the cone's
        // mean slant (light_path), for the volume's and the tubes' extinction alike.
        cs = vec4<f32>(select(0.0, lo, hi > 0.0), hi, P.light_path / r.cosine, 0.0);
        cell_state[ci] = cs;
    } else {
        cs = cell_state[ci];
    }
    // O_k: the light reaching slice k, gathered from the light leaving slice k - 1 over the
    // disk the cone of half-angle theta cuts from it: radius d tan(theta) in world units at
    // depth z_{k-1}, in cells 0.5 (P00 w, P11 h) r / (z s) (camera::texture_radius).
    var occl = 1.0;
    // Shadow-weighted mean age of the shadow arriving here (cone model).
    var age = 0.0;
    if (CONE && k > 0u) {
        // The step that makes the shadow of an occluder at distance D reach the variance of
        // the cone's disk at D + d: r^2 = tan^2(theta) ((D + d)^2 - D^2), i.e. the paper's
        // radius d tan(theta) times sqrt(1 + 2 D / d); taps grow with the radius in cells.
        let own = occ_texel2(vec2<i32>(id.xy));
        let d0 = own.y / max(1.0 - own.x, 1e-6);
        let rc = S.rpx.xy * sqrt(1.0 + 2.0 * max(d0, 0.0) / d);
        var sum = vec2<f32>(0.0);
        if (max(rc.x, rc.y) <= 2.0) {
            // The 3x3 stencil with the disk's variance (slice_pass::blur_stencil).
            let v = rc * rc * 0.25;
            let kx = vec3<f32>(0.5 * v.x, 1.0 - v.x, 0.5 * v.x);
            let ky = vec3<f32>(0.5 * v.y, 1.0 - v.y, 0.5 * v.y);
            for (var j = 0; j < 3; j = j + 1) {
                for (var i = 0; i < 3; i = i + 1) {
                    sum = sum + kx[i] * ky[j] * occ_texel2(vec2<i32>(id.xy) + vec2<i32>(i - 1, j - 1));
                }
            }
        } else {
            let n = clamp(u32(ceil(max(rc.x, rc.y))), P.blur_samples, 9u);
            let c = vec2<f32>(id.xy) + vec2<f32>(0.5);
            for (var i = 0u; i < n; i = i + 1u) {
                for (var j = 0u; j < n; j = j + 1u) {
                    var g = vec2<f32>(0.0);
                    if (n > 1u) {
                        g = (vec2<f32>(f32(i), f32(j)) + vec2<f32>(0.5)) / f32(n) * 2.0 - vec2<f32>(1.0);
                    }
                    sum = sum + occ_bilinear2(c + concentric(g) * rc);
                }
            }
            sum = sum / f32(n * n);
        }
        occl = sum.x;
        age = sum.y / max(1.0 - occl, 1e-6);
    } else if (k > 0u) {
        let p = vec2<i32>(id.xy);
        if (S.wide == 0u) {
            var sum = 0.0;
            for (var j = 0; j < 3; j = j + 1) {
                let row = S.w[j];
                sum = sum + row.x * occ_texel(p + vec2<i32>(-1, j - 1))
                    + row.y * occ_texel(p + vec2<i32>(0, j - 1))
                    + row.z * occ_texel(p + vec2<i32>(1, j - 1));
            }
            occl = sum;
        } else {
            let c = vec2<f32>(id.xy) + vec2<f32>(0.5);
            let n = P.blur_samples;
            var sum = 0.0;
            for (var i = 0u; i < n; i = i + 1u) {
                for (var j = 0u; j < n; j = j + 1u) {
                    var g = vec2<f32>(0.0);
                    if (n > 1u) {
                        g = (vec2<f32>(f32(i), f32(j)) + vec2<f32>(0.5)) / f32(n) * 2.0 - vec2<f32>(1.0);
                    }
                    sum = sum + occ_bilinear(c + concentric(g) * S.rpx.xy);
                }
            }
            occl = sum / f32(n * n);
        }
    }
    light_volume[ci + cw * ch * k * n] = occl;
    // The light leaving slice k: through the volume's extinction at the cell's ray, and
    // through the tubes where the slice lies inside them (between front and back faces; with
    // flag 4 everywhere behind a front face, the paper's rule), as the mean transmittance of
    // the cell's pixels. Over the whole slab: occlusion does not stop at the surface. The slab
    // is taken in n equal parts (one: the whole slab), each sampled at its middle and clipped
    // on its own, as the CPU renderer's `EaVolume::optical_depth` takes them, the tubes'
    // coverage tested at each part's middle; the light reaching part i is stored at slice
    // k n + i (`raycast::light::store_parts`).
    var grad = vec3<f32>(0.0);
    let column = P.column != 0u;
    let part = d / f32(n);
    let seg = part * cs.z;
    // Light below DARK passes on unattenuated: no samples, no tubes.
    let lit = occl >= DARK;
    var t = 1.0;
    for (var i = 0u; i < n; i = i + 1u) {
        if (i > 0u) {
            light_volume[ci + cw * ch * (k * n + i)] = occl * t;
        }
        if (!lit) {
            continue;
        }
        let iv = depth_interval(r, P.z0 + (f32(k) + f32(i) / f32(n)) * d, part, 0.0);
        if (iv.y > iv.x) {
            let c = volume_sample(r, 0.5 * (iv.x + iv.y), &grad);
            t = t * exp(-max(c.a, 0.0) * (iv.y - iv.x) * cs.z);
        }
        let z_i = P.z0 + (f32(k) + (f32(i) + 0.5) / f32(n)) * d;
        if (cs.x > 0.0 && z_i >= cs.x && (column || z_i <= cs.y)) {
            var inside = 0.0;
            for (var y = 0u; y < s; y = y + 1u) {
                for (var x = 0u; x < s; x = x + 1u) {
                    let p = vec2<i32>(min(id.xy * s + vec2<u32>(x, y), vec2<u32>(P.frame.size.x, P.frame.size.y) - vec2<u32>(1u)));
                    let f = textureLoad(front_depth, p, 0).r;
                    if (f > 0.0 && z_i >= f && (column || z_i <= textureLoad(back_depth, p, 0).r)) {
                        inside = inside + 1.0;
                    }
                }
            }
            let cov = inside / f32(s * s);
            t = t * (1.0 - cov * (1.0 - exp(-P.geometry_extinction * seg)));
        }
    }
    let leave = occl * t;
    occ_out[2u * ci] = leave;
    if (CONE) {
        // The arriving shadow (1 - O) ages by d; the shadow made here is new.
        occ_out[2u * ci + 1u] = (1.0 - occl) * (age + d);
    }
}

// The projected value of the ray: the largest (PROJECTION 1) or smallest (2) trilinear
// sample at the middles of the slabs' intervals kept by the clipping planes, over the whole
// ray inside the grid (surfaces do not stop it); NaN gaps are skipped. Through the transfer
// function: premultiplied colour and opacity (its extinction, clamped to [0, 1]); nothing
// where no sample was taken. Empty bricks (every value they span transparent: below the
// window's low end, or above it for a reversed window - the transfer function's first point
// then has extinction) change nothing when the transparent side is away from the extreme (a
// MIP's value is then either taken elsewhere or transparent anyway), so they are skipped;
// when it is towards the extreme, a sample there makes the whole ray transparent, so the ray
// ends. The CPU twin takes every sample; the results are the same.
fn projection(r: Ray) -> vec4<f32> {
    let kr = box_slices(r, 0.0);
    let hi = vec3<f32>(P.dims) - vec3<f32>(1.0);
    // Transparent below the window (its first point has no extinction) or above it.
    let clear_below = tf[4] <= 0.0;
    let ends = (PROJECTION == 1u) != clear_below;
    var found = false;
    var m = 0.0;
    for (var k = kr.x; k < kr.y; k = k + 1u) {
        let iv = slab_interval(r, k, 0.0);
        if (iv.y <= iv.x) {
            continue;
        }
        let s = (0.5 * (iv.x + iv.y) - r.o_depth) / r.cosine;
        if (s < 0.0) {
            continue;
        }
        let q = (P.world_to_index * vec4<f32>(r.o + r.d * s, 1.0)).xyz;
        if (any(q < vec3<f32>(0.0)) || any(q > hi)) {
            continue;
        }
        let br = min(vec3<u32>(q) / P.brick, P.bricks - vec3<u32>(1u));
        let empty = occupied[br.x + P.bricks.x * (br.y + P.bricks.y * br.z)] == 0u;
        if (empty && !ends) {
            // Past the empty brick (`empty_slabs`).
            k = k + empty_slabs(r, 0.5 * (iv.x + iv.y));
            continue;
        }
        let v = trilinear(q);
        if (v < -1e30) {
            continue;
        }
        if (empty) {
            return vec4<f32>(0.0);
        }
        if (!found || (PROJECTION == 1u && v > m) || (PROJECTION == 2u && v < m)) {
            m = v;
            found = true;
        }
    }
    if (!found) {
        return vec4<f32>(0.0);
    }
    let c = transfer(m, 0.0);
    let a = clamp(c.a, 0.0, 1.0);
    return vec4<f32>(c.rgb * a, a);
}

fn blend_voxel(i: vec3<u32>) -> f32 {
    return blend_field[i.x + P.blend_dims.x * (i.y + P.blend_dims.y * i.z)];
}

// The blended overlay's colour and coverage at world point p: the slices' mapping of an
// overlay (engine::planes::layer_color; gbuffer.wgsl plane_layer_color).
fn blend_color(p: vec3<f32>) -> vec4<f32> {
    let hi = vec3<f32>(P.blend_dims) - vec3<f32>(1.0);
    let c = clamp((P.blend_to_index * vec4<f32>(p, 1.0)).xyz, vec3<f32>(0.0), hi);
    if (P.blend_labels != 0u) {
        let v = blend_voxel(vec3<u32>(floor(c + vec3<f32>(0.5))));
        if (!(v >= 0.0 && v < f32(P.blend_count))) {
            return vec4<f32>(0.0);
        }
        return blend_lut[min(u32(floor(v + 0.5)), P.blend_count - 1u)];
    }
    let b = min(vec3<u32>(floor(c)), max(P.blend_dims, vec3<u32>(2u)) - vec3<u32>(2u));
    let top = P.blend_dims - vec3<u32>(1u);
    var vs: array<f32, 8>;
    for (var k = 0u; k < 8u; k = k + 1u) {
        vs[k] = blend_voxel(min(b + cell_corner(k), top));
    }
    let v = trilinear_mix(vs, c - vec3<f32>(b));
    let t = (v - P.blend_lo) / (P.blend_hi - P.blend_lo);
    if (v < -1e30 || !(t > 0.0)) {
        return vec4<f32>(0.0);
    }
    let x = min(t, 1.0) * 255.0;
    let i = min(u32(floor(x)), 254u);
    return vec4<f32>(mix(blend_lut[i], blend_lut[i + 1u], x - f32(i)).rgb, 1.0);
}

// A volume sample's colour with the blended overlay mixed in at depth `depth` along the ray.
fn blended(c: vec4<f32>, r: Ray, depth: f32) -> vec4<f32> {
    if (P.blend_on == 0u) {
        return c;
    }
    let b = blend_color(r.o + r.d * ((depth - r.o_depth) / r.cosine));
    return vec4<f32>(mix(c.rgb, b.rgb, b.a * P.blend_opacity), c.a);
}

// The depth of translucent layer l at pixel p (0: none; the march stops at the first none, as
// a pass after an empty layer may peel the nearest fragment again).
fn layer_depth(p: vec2<i32>, l: u32) -> f32 {
    if (l >= P.peel_layers) {
        return 0.0;
    }
    return textureLoad(peel_nd, p, i32(l), 0).w;
}

// Composites translucent layer l over the eye buffer value `e` (front to back): its colour lit
// by the head light as composite lights surfaces (no occlusion terms; an unlit slice, zero
// normal, unshaded), weighted by its
// opacity; `half` gets its depth when it takes the opacity past 0.5.
fn composite_layer(e: ptr<function, vec4<f32>>, half: ptr<function, f32>, p: vec2<i32>, l: u32, r: Ray) {
    let c = textureLoad(peel_color, p, i32(l), 0);
    let nd = textureLoad(peel_nd, p, i32(l), 0);
    let nl = max(dot(nd.xyz, -r.d), 0.0);
    let rv = max(2.0 * nl * nl - 1.0, 0.0);
    let spec = P.light.specular * pow(rv, P.light.shininess);
    var lit = c.rgb * (P.light.ambient + P.light.diffuse * nl) + vec3<f32>(spec);
    if (all(nd.xyz == vec3<f32>(0.0))) {
        // an unlit slice (gbuffer.wgsl `fs_peel_p`): its colour as mapped
        lit = c.rgb;
    }
    let w = (1.0 - (*e).a) * c.a;
    let before = (*e).a;
    *e = vec4<f32>((*e).rgb + w * lit, (*e).a + w);
    if ((*e).a >= 0.5 && before < 0.5) {
        *half = nd.w;
    }
}

@compute @workgroup_size(8, 8, 1)
fn march(@builtin(global_invocation_id) id: vec3<u32>) {
    let w = P.frame.size.x;
    let h = P.frame.size.y;
    if (id.x >= w || id.y >= h) {
        return;
    }
    let idx = id.x + w * id.y;
    let px = vec2<f32>(id.xy) + vec2<f32>(0.5);
    let r = pixel_ray(P.frame, px);
    let front = textureLoad(front_depth, vec2<i32>(id.xy), 0).r;
    if (PROJECTION != 0u) {
        // The translucent layers, then behind the surfaces the projection, where none is.
        var e = vec4<f32>(0.0);
        var h = 0.0;
        for (var l = 0u; layer_depth(vec2<i32>(id.xy), l) > 0.0; l = l + 1u) {
            composite_layer(&e, &h, vec2<i32>(id.xy), l, r);
        }
        if (front <= 0.0 && P.has_volume != 0u) {
            let m = projection(r);
            e = vec4<f32>(e.rgb + (1.0 - e.a) * m.rgb, e.a + (1.0 - e.a) * m.a);
        }
        eye_buf[idx] = e;
        state[2u * idx] = vec4<f32>(1.0, 1.0, 0.0, 0.0);
        state[2u * idx + 1u] = vec4<f32>(0.0);
        return;
    }
    let lit = P.occlusion != 0u;
    var e = vec4<f32>(0.0);
    var acc = vec2<f32>(0.0);
    var half = 0.0;
    // Without a volume no slab has a sample to take: only the layers (below) are composited.
    let kr = select(box_slices(r, front), vec2<u32>(0u), P.has_volume == 0u);
    let shifted = lit && P.n_clip > 0u;
    var cs: CellShift;
    if (shifted) {
        cs = cell_shifts(px, r);
    }
    // The light step last read (none yet) and the light reaching the next sample along the ray.
    var lstep = 0xffffffffu;
    var lrun = 1.0;
    // Behind clipping planes, the factor each sample brings the light towards the last front
    // read (front_gain).
    var lgain = 1.0;
    // Translucent layers are composited where the ray reaches their depth: a slab they lie in
    // is split there, each part sampled at its middle as clipping planes split slabs.
    let pid = vec2<i32>(id.xy);
    var next = 0u;
    var zl = layer_depth(pid, 0u);
    for (var k = kr.x; k < kr.y; k = k + 1u) {
        let iv = slab_interval(r, k, front);
        if (iv.y <= iv.x) {
            continue;
        }
        // The light step's front, read when a sample absorbs in a step not read yet (most
        // slabs of a ray take none).
        let ls = k / P.light_read;
        var a = iv.x;
        // Whether the slab took nothing (no absorbing sample, no layer).
        var clear = true;
        loop {
            // The part of the slab up to the next layer in it, or to its end.
            let in_slab = zl > 0.0 && zl <= iv.y;
            let b = select(iv.y, zl, in_slab);
            if (b > a) {
                var grad = vec3<f32>(0.0);
                let c = volume_sample(r, 0.5 * (a + b), &grad);
                if (c.a > 0.0) {
                    clear = false;
                    let cb = blended(c, r, 0.5 * (a + b));
                    if (lit && ls != lstep) {
                        if (shifted) {
                            let fr = light_shifted(cs, k, lstep == 0xffffffffu);
                            let g = front_gain(lrun, fr, lstep == 0xffffffffu);
                            lrun = g.x;
                            lgain = g.y;
                        } else {
                            lrun = light_step_front(px, ls);
                        }
                        lstep = ls;
                    }
                    composite_eye(&e, &acc, &half, r, vec2<f32>(a, b), cb, grad, lit, &lrun, lgain);
                }
            }
            if (!in_slab) {
                break;
            }
            clear = false;
            composite_layer(&e, &half, pid, next, r);
            a = max(a, zl);
            next = next + 1u;
            zl = layer_depth(pid, next);
        }
        // Early ray termination at occlusion::emission_absorption::OPAQUE (1 - 1/128): the rest
        // of the ray is taken as the mean of what it showed so far (colour over opacity,
        // opacity 1; `emission_absorption::end_opaque`), not as the background behind it.
        if (e.a > 0.9921875) {
            e = vec4<f32>(e.rgb / e.a, 1.0);
            break;
        }
        if (clear) {
            // Past the empty brick. (A layer in the slabs stepped over is composited at the
            // start of the next slab taken, before its samples: nothing lay between.)
            k = k + empty_slabs(r, 0.5 * (iv.x + iv.y));
        }
    }
    // Layers behind the volume (or with none), in front of the opaque surface.
    for (; zl > 0.0; zl = layer_depth(pid, next)) {
        composite_layer(&e, &half, pid, next, r);
        next = next + 1u;
    }
    eye_buf[idx] = e;
    // Partial occlusion (eq. 1-3): a surface at z between z_{k-1} and z_k receives
    // lerp(O_{k-1}, O_k, (z - z_{k-1}) / d) (O_{-1} = 1; beyond the last slice O of the last).
    // (Half a slab in front of the surface, as the paper has it: read at the surface's own
    // depth, the light past the slab the surface lies in is the light the tube itself
    // attenuated where that slab's middle is inside it - a tube would shadow its own top.)
    // The light volume's cells mix the pixels of s x s blocks: looked up at the nearest
    // surface depth of the cells around the pixel, a tube does not shadow itself; occluders
    // nearer than that within the cell are the vicinity term's.
    var partial = 1.0;
    if (lit && front > 0.0) {
        let c = px / f32(P.cell) - vec2<f32>(0.5);
        let b = vec2<i32>(floor(c));
        var z = front;
        for (var i = 0; i < 4; i = i + 1) {
            let q = clamp(b + vec2<i32>(i & 1, i >> 1u), vec2<i32>(0), vec2<i32>(P.cells) - vec2<i32>(1));
            let m = cell_state[u32(q.x) + P.cells.x * u32(q.y)].x;
            if (m > 0.0) {
                z = min(z, m);
            }
        }
        let kf = (z - P.z0) / P.dz - 0.5;
        if (kf >= 0.0) {
            let k1 = u32(floor(kf)) + 1u;
            let ratio = min(kf - floor(kf), 1.0);
            let o0 = light_front(px, k1 - 1u);
            var o1 = o0;
            if (k1 < P.n_slices) {
                o1 = light_front(px, k1);
            }
            partial = mix(o0, o1, ratio);
        } else {
            // In front of slice 0: between O_{-1} = 1 and O_0.
            partial = mix(1.0, light_front(px, 0u), clamp(kf + 1.0, 0.0, 1.0));
        }
    }
    state[2u * idx] = vec4<f32>(1.0, partial, acc.x, acc.y);
    state[2u * idx + 1u] = vec4<f32>(half, 0.0, 0.0, 0.0);
    if (P.partial_layer != NO_LAYER) {
        terms[P.partial_layer * P.frame.size.x * P.frame.size.y + idx] = partial;
    }
}
