// Isosurface ray marching with swept occlusion (Singh, Yuksel and House, section 3): sphere
// tracing with the distance field of `umbra sweep`, the eight octant visibilities and the
// analytic G_s(N) for the ambient term. The GPU twin of occlusion/src/isosurface.rs (`umbra
// iso`); Rust side: engine/src/iso_pass.rs.

// Keep in sync with `iso_pass::IsoParams`.
struct Params {
    frame: Frame,
    world_to_index: mat4x4<f32>,
    // world normal from an index-space gradient: A^-T (upper 3x3)
    normal_to_world: mat4x4<f32>,
    // world normal to the octants' index frame: R^T (upper 3x3)
    normal_to_index: mat4x4<f32>,
    dims: vec3<u32>,
    // geometry term: 0 cosine, 1 constant, 2 absolute
    geometry: u32,
    // smallest spacing, lookup offset c (in h_min), gamma, normalisation
    h_min: f32,
    offset: f32,
    gamma: f32,
    norm: f32,
    // octant weights, four to a row
    weights: array<vec4<f32>, 2>,
    // sweep directions sigma_s (xyz)
    sweeps: array<vec4<f32>, 8>,
    // surface colour (rgb, 1)
    color: vec4<f32>,
    light: Light,
    n_clip: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
    // clipping planes (normal, offset), keeping normal . p <= offset
    clip: array<vec4<f32>, 8>,
};

@group(0) @binding(0) var<uniform> P: Params;
// Classified samples: inside where g >= 0 (NaN uploaded as -1).
@group(0) @binding(1) var<storage, read> gfield: array<f32>;
@group(0) @binding(2) var<storage, read> sdf: array<f32>;
// Octant visibilities as bytes, four per word: voxel i's octants 0-3 in word 2i, 4-7 in 2i + 1.
@group(0) @binding(3) var<storage, read> octants: array<u32>;
// Per pixel: shaded colour (rgb) and linear depth (0: no hit).
@group(0) @binding(4) var<storage, read_write> iso_out: array<vec4<f32>>;
// Per pixel: the ambient term (-1: no hit).
@group(0) @binding(5) var<storage, read_write> iso_ambient: array<f32>;

fn idx(i: vec3<u32>) -> u32 {
    return i.x + P.dims.x * (i.y + P.dims.y * i.z);
}

fn hi() -> vec3<f32> {
    return vec3<f32>(P.dims) - vec3<f32>(1.0);
}

// The classified field with the space beyond the grid outside (a virtual sample mirrors the
// border sample's magnitude with negative sign; IsoSurface::g_at).
fn g_sample(c: vec3<f32>) -> f32 {
    let inside = all(c >= vec3<f32>(0.0)) && all(c <= hi());
    let v = gfield[idx(vec3<u32>(clamp(c, vec3<f32>(0.0), hi())))];
    return select(-max(abs(v), 1e-6), v, inside);
}

fn g_at(p: vec3<f32>) -> f32 {
    let b = floor(p);
    var v: array<f32, 8>;
    for (var c = 0u; c < 8u; c = c + 1u) {
        v[c] = g_sample(b + vec3<f32>(cell_corner(c)));
    }
    return trilinear_mix(v, p - b);
}

// Trilinear distance (world units), positions clamped to the grid.
fn sdf_at(q: vec3<f32>) -> f32 {
    let p = clamp(q, vec3<f32>(0.0), hi());
    let b = min(vec3<u32>(floor(p)), max(P.dims, vec3<u32>(2u)) - vec3<u32>(2u));
    let o = vec3<u32>(min(vec3<u32>(1u), P.dims - vec3<u32>(1u)));
    var v: array<f32, 8>;
    for (var c = 0u; c < 8u; c = c + 1u) {
        v[c] = sdf[idx(b + cell_corner(c) * o)];
    }
    return trilinear_mix(v, p - vec3<f32>(b));
}

fn octant(i: u32, s: u32) -> f32 {
    let word = octants[2u * i + s / 4u];
    return f32((word >> (8u * (s % 4u))) & 255u) / 255.0;
}

// The eight visibilities at index position p, trilinear, with the open-sky rule beyond the
// grid (occlusion_shading::sample_octants).
fn sample_octants(p: vec3<f32>) -> array<f32, 8> {
    var v: array<f32, 8>;
    for (var s = 0u; s < 8u; s = s + 1u) {
        v[s] = 0.0;
    }
    let b = floor(p);
    let f = p - b;
    for (var c = 0u; c < 8u; c = c + 1u) {
        let o = vec3<f32>(f32(c & 1u), f32((c >> 1u) & 1u), f32(c >> 2u));
        let wv = mix(vec3<f32>(1.0) - f, f, o);
        let w = wv.x * wv.y * wv.z;
        if (w == 0.0) {
            continue;
        }
        let q = b + o;
        let side = select(vec3<f32>(0.0), vec3<f32>(-1.0), q < vec3<f32>(0.0))
            + select(vec3<f32>(0.0), vec3<f32>(1.0), q > hi());
        let i = idx(vec3<u32>(clamp(q, vec3<f32>(0.0), hi())));
        let outside = any(side != vec3<f32>(0.0));
        for (var s = 0u; s < 8u; s = s + 1u) {
            let sky = -P.sweeps[s].xyz;
            let agree = (side == vec3<f32>(0.0)) | (sky == side);
            let open = outside && all(agree);
            v[s] = v[s] + w * select(octant(i, s), 1.0, open);
        }
    }
    return v;
}

// The integral of max(n . w, 0) over the spherical triangle with unit vertices a, b, c
// (occlusion_shading::projected_solid_angle): clip against n . w >= 0, then sum the arcs.
fn projected_solid_angle(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, n: vec3<f32>) -> f32 {
    var verts = array<vec3<f32>, 3>(a, b, c);
    var poly: array<vec3<f32>, 6>;
    var m = 0u;
    for (var i = 0u; i < 3u; i = i + 1u) {
        let p = verts[i];
        let q = verts[(i + 1u) % 3u];
        let dp = dot(n, p);
        let dq = dot(n, q);
        if (dp >= 0.0) {
            poly[m] = p;
            m = m + 1u;
        }
        if ((dp >= 0.0) != (dq >= 0.0)) {
            poly[m] = normalize(p + (q - p) * (dp / (dp - dq)));
            m = m + 1u;
        }
    }
    if (m < 3u) {
        return 0.0;
    }
    var sum = 0.0;
    for (var i = 0u; i < m; i = i + 1u) {
        let p = poly[i];
        let q = poly[(i + 1u) % m];
        let cr = cross(p, q);
        let len = length(cr);
        if (len < 1e-12) {
            continue;
        }
        sum = sum + acos(clamp(dot(p, q), -1.0, 1.0)) * dot(n, cr / len);
    }
    return abs(0.5 * sum);
}

fn geometry_term(s: u32, n: vec3<f32>) -> f32 {
    let d = P.sweeps[s].xyz;
    return projected_solid_angle(
        vec3<f32>(-d.x, 0.0, 0.0),
        vec3<f32>(0.0, -d.y, 0.0),
        vec3<f32>(0.0, 0.0, -d.z),
        n,
    );
}

// A(P, N) of occlusion_shading::AmbientModel::ambient.
fn ambient(v: array<f32, 8>, n_world: vec3<f32>) -> f32 {
    let n = normalize((P.normal_to_index * vec4<f32>(n_world, 0.0)).xyz);
    var raw = 0.0;
    for (var s = 0u; s < 8u; s = s + 1u) {
        let w = P.weights[s / 4u][s % 4u];
        if (w <= 0.0) {
            continue;
        }
        var g = 1.0;
        if (P.geometry == 0u) {
            g = geometry_term(s, n);
        } else if (P.geometry == 2u) {
            g = geometry_term(s, n) + geometry_term(s, -n);
        }
        raw = raw + w * v[s] * g;
    }
    let a = clamp(raw / P.norm, 0.0, 1.0);
    return select(pow(a, 1.0 / P.gamma), a, P.gamma == 1.0);
}

@compute @workgroup_size(8, 8, 1)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let w = P.frame.size.x;
    let h = P.frame.size.y;
    if (id.x >= w || id.y >= h) {
        return;
    }
    let pix = id.x + w * id.y;
    iso_out[pix] = vec4<f32>(0.0);
    iso_ambient[pix] = -1.0;
    let ray = pixel_ray(P.frame, vec2<f32>(id.xy) + vec2<f32>(0.5));
    let o = ray.o;
    let d = ray.d;
    let oi = (P.world_to_index * vec4<f32>(o, 1.0)).xyz;
    let di = (P.world_to_index * vec4<f32>(d, 0.0)).xyz;
    // Slab test against the grid box grown by one voxel, in index space.
    var t0 = 0.0;
    var t1 = 3e38;
    for (var a = 0; a < 3; a = a + 1) {
        let lo = -1.0;
        let top = f32(P.dims[a]);
        if (abs(di[a]) < 1e-30) {
            if (oi[a] < lo || oi[a] > top) {
                return;
            }
            continue;
        }
        var ta = (lo - oi[a]) / di[a];
        var tb = (top - oi[a]) / di[a];
        if (ta > tb) {
            let x = ta;
            ta = tb;
            tb = x;
        }
        t0 = max(t0, ta);
        t1 = min(t1, tb);
    }
    // Clipping planes: the kept half-spaces bound the ray; a ray that enters one inside the
    // solid meets the cut face there.
    var cut = -1;
    for (var c = 0u; c < P.n_clip; c = c + 1u) {
        let g0 = dot(P.clip[c].xyz, o) - P.clip[c].w;
        let g1 = dot(P.clip[c].xyz, d);
        if (abs(g1) < 1e-30) {
            if (g0 > 0.0) {
                return;
            }
        } else if (g1 > 0.0) {
            t1 = min(t1, -g0 / g1);
        } else if (-g0 / g1 > t0) {
            t0 = -g0 / g1;
            cut = i32(c);
        }
    }
    if (t0 > t1) {
        return;
    }
    let h_min = P.h_min;
    var t = t0;
    var hit = -1.0;
    if (g_at(oi + di * t) >= 0.0) {
        hit = t;
    } else {
        let min_step = 0.3 * h_min;
        for (var it = 0u; it < 100000u && t < t1; it = it + 1u) {
            let dist = sdf_at(oi + di * t);
            let prev = t;
            t = min(t + max(dist - h_min, min_step), t1);
            if (g_at(oi + di * t) >= 0.0) {
                var lo = prev;
                var up = t;
                for (var k = 0; k < 20; k = k + 1) {
                    let mid = 0.5 * (lo + up);
                    if (g_at(oi + di * mid) >= 0.0) {
                        up = mid;
                    } else {
                        lo = mid;
                    }
                }
                hit = up;
                break;
            }
        }
    }
    if (hit < 0.0) {
        return;
    }
    let p = o + d * hit;
    let q = (P.world_to_index * vec4<f32>(p, 1.0)).xyz;
    let e = 0.5;
    let grad = vec3<f32>(
        sdf_at(q + vec3<f32>(e, 0.0, 0.0)) - sdf_at(q - vec3<f32>(e, 0.0, 0.0)),
        sdf_at(q + vec3<f32>(0.0, e, 0.0)) - sdf_at(q - vec3<f32>(0.0, e, 0.0)),
        sdf_at(q + vec3<f32>(0.0, 0.0, e)) - sdf_at(q - vec3<f32>(0.0, 0.0, e)),
    );
    // On the closure beyond the grid the face's own normal (IsoSurface::normal).
    let side = select(vec3<f32>(0.0), vec3<f32>(-1.0), q < vec3<f32>(0.0))
        + select(vec3<f32>(0.0), vec3<f32>(1.0), q > hi());
    var gw = (P.normal_to_world * vec4<f32>(grad, 0.0)).xyz;
    if (any(side != vec3<f32>(0.0))) {
        gw = (P.normal_to_world * vec4<f32>(side, 0.0)).xyz;
    }
    if (cut >= 0 && hit == t0) {
        // The cut face: its normal points into the removed half-space.
        gw = P.clip[cut].xyz;
    }
    var n = -d;
    if (length(gw) > 1e-20) {
        n = normalize(gw);
    }
    if (dot(n, d) > 0.0) {
        n = -n;
    }
    let look = p + n * (P.offset * h_min);
    var am = ambient(sample_octants((P.world_to_index * vec4<f32>(look, 1.0)).xyz), n);
    if (cut >= 0 && hit == t0) {
        // A cut face faces the removed, empty half-space: its hemisphere is open, shaded
        // unoccluded (the fields, swept for the cut solid, would read octants that straddle
        // the plane as partly shut).
        am = 1.0;
    }
    // Shaded as the tubes are (eq. 9): A colour (ambient + diffuse (n.l)) + specular.
    let nl = max(dot(n, -d), 0.0);
    let rv = max(2.0 * nl * nl - 1.0, 0.0);
    let rgb = am * P.color.rgb * (P.light.ambient + P.light.diffuse * nl) + vec3<f32>(P.light.specular * pow(rv, P.light.shininess));
    iso_out[pix] = vec4<f32>(rgb, dot(p - P.frame.eye.xyz, P.frame.forward.xyz));
    iso_ambient[pix] = am;
}
