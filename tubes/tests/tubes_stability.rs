//! Stream-tube stability: the adversarial curves of the stream-tube issue, each meshed with
//! rotation-minimizing frames. Required of every mesh: no NaN, no degenerate or inward-facing
//! triangle, a twist of at most 1 degree between rings, every ring at least half the area of
//! the ideal polygon at its radius.

use glam::{DVec3, Vec3};
use tubes::bspline_fit::{FitMethod, FitOptions};
use tubes::tube_mesh::{
    build, ColorMode, FrameMethod, RadiusMode, TubeMesh, TubeOptions, TubeStats,
};
use tubes::Streamlines;

fn opts(radius: f64) -> TubeOptions<'static> {
    TubeOptions {
        radius,
        sides: 8,
        per_span: 1, // the CLI default
        chordal: None,
        max_turn_deg: 15.0,
        frame: FrameMethod::Rmf,
        radius_mode: RadiusMode::Local,
        fit: FitOptions {
            epsilon: 0.02,
            method: FitMethod::Iterative,
            max_iterations: 100,
        },
        caps: true,
        color: ColorMode::Direction,
    }
}

fn lines(curves: &[Vec<DVec3>]) -> Streamlines {
    let mut s = Streamlines::new();
    for c in curves {
        s.push(&c.iter().map(|p| p.as_vec3()).collect::<Vec<Vec3>>());
    }
    s
}

/// Checks the mesh invariants at the tolerance of `opts` (0.02).
fn check(name: &str, mesh: &TubeMesh, st: &TubeStats, radius: f64) {
    let _ = radius;
    check_within(name, mesh, st, 0.02);
}

/// Checks the mesh invariants, the deviation within `tolerance`.
fn check_within(name: &str, mesh: &TubeMesh, st: &TubeStats, tolerance: f64) {
    assert!(
        mesh.positions
            .iter()
            .chain(&mesh.normals)
            .all(|v| v.is_finite()),
        "{name}: NaN in the mesh"
    );
    assert!(
        mesh.normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-3),
        "{name}: normals not unit"
    );
    for tri in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[tri[k] as usize].as_dvec3());
        let g = (b - a).cross(c - a);
        let n: DVec3 = tri
            .iter()
            .map(|&i| mesh.normals[i as usize].as_dvec3())
            .sum();
        // Degenerate: (nearly) collinear or coincident vertices, relative to the triangle's size.
        let e = (b - a).length().max((c - b).length()).max((a - c).length());
        assert!(
            e > 0.0 && g.length() > 1e-6 * e * e,
            "{name}: degenerate triangle {tri:?} (area {}, edge {e})",
            g.length() / 2.0
        );
        assert!(g.dot(n) > 0.0, "{name}: inward-facing triangle {tri:?}");
    }
    assert!(
        st.max_twist_deg <= 1.0,
        "{name}: twist {} degrees",
        st.max_twist_deg
    );
    assert!(
        st.min_section_ratio >= 0.5,
        "{name}: section ratio {}",
        st.min_section_ratio
    );
    assert!(
        st.max_deviation <= tolerance + 1e-9,
        "{name}: deviation {}",
        st.max_deviation
    );
}

/// Two straight legs of 10 mm meeting at a point where the line turns by `turn_deg`, points
/// `step` mm apart.
fn hairpin(turn_deg: f64, planar: bool, step: f64) -> Vec<DVec3> {
    let d1 = DVec3::X;
    let a = turn_deg.to_radians();
    let d2 = if planar {
        DVec3::new(a.cos(), a.sin(), 0.0)
    } else {
        DVec3::new(a.cos(), a.sin() * 0.6, a.sin() * 0.8)
    };
    let n = (10.0 / step).round() as usize;
    let mut pts: Vec<DVec3> = (0..=n).map(|i| -d1 * (10.0 - step * i as f64)).collect();
    pts.extend((1..=n).map(|i| d2 * (step * i as f64)));
    pts
}

#[test]
fn hairpins_of_150_179_and_180_degrees() {
    for (planar, per_span) in [(true, 1), (false, 1), (true, 4), (false, 4)] {
        for turn in [150.0, 179.0, 180.0] {
            // Points 0.5 mm apart: the fit would need more rings than the line's 41 points
            // about the turn, so the line is split there into its two legs (each fitted or
            // meshed as its polyline, no more rings than points); points 0.02 mm apart: the
            // fit places fewer rings than the 1,001 points and is kept, its radius clamped
            // about the turn instead of folding.
            for step in [0.5, 0.02] {
                let s = lines(&[hairpin(turn, planar, step)]);
                let o = TubeOptions {
                    per_span,
                    ..opts(0.3)
                };
                let (mesh, st) = build(&s, &o);
                let name =
                    format!("hairpin {turn} planar={planar} per_span={per_span} step={step}");
                check(&name, &mesh, &st, 0.3);
                let points = s.line(0).len();
                assert!(
                    st.triangles <= (points - 1) * 2 * o.sides + 2 * 2 * 2 * o.sides,
                    "{name}: {} triangles, more than a ring per point",
                    st.triangles
                );
                if turn == 180.0 {
                    assert_eq!(st.splits, 1, "an exact reversal is split");
                    assert_eq!(st.streamlines_out, 2);
                } else if step == 0.5 {
                    assert_eq!(st.splits, 1, "{name}: split at the turn");
                    assert_eq!(st.streamlines_out, 2);
                } else {
                    // The tight turn clamps the radius locally instead of folding the tube; at
                    // 179 degrees the fitted apex is so sharp that the tube is cut there.
                    assert!(st.radius_clamps > 0, "{name}: no clamps {st:?}");
                    assert!(st.splits <= 1);
                    if turn == 150.0 {
                        assert_eq!(st.splits, 0);
                    }
                }
            }
        }
    }
}

#[test]
fn s_curves_helices_and_straight_lines() {
    let s_curve: Vec<DVec3> = (0..200)
        .map(|i| {
            let t = i as f64 * 0.06;
            DVec3::new(t, t.sin(), 0.0)
        })
        .collect();
    // A helix of radius 0.2 with a tube of radius 0.5: tighter than the tube.
    let helix: Vec<DVec3> = (0..300)
        .map(|i| {
            let t = i as f64 * 0.05;
            DVec3::new(0.2 * t.cos(), 0.2 * t.sin(), 0.05 * t)
        })
        .collect();
    let straight: Vec<DVec3> = (0..50)
        .map(|i| DVec3::new(1.0, 2.0, 3.0) + DVec3::new(0.3, 0.4, 0.5) * i as f64)
        .collect();
    for (name, c, r) in [
        ("s-curve", &s_curve, 0.2),
        ("tight helix", &helix, 0.5),
        ("collinear", &straight, 0.2),
    ] {
        let (mesh, st) = build(&lines(std::slice::from_ref(c)), &opts(r));
        check(name, &mesh, &st, r);
        if name == "tight helix" {
            assert!(st.radius_clamps > 0);
        }
        if name == "collinear" {
            assert!(
                st.control_points <= 6,
                "a line needs few control points: {}",
                st.control_points
            );
        }
    }
}

#[test]
fn degenerate_inputs() {
    let mut dup: Vec<DVec3> = Vec::new();
    for i in 0..30 {
        let p = DVec3::new(i as f64 * 0.2, (i as f64 * 0.3).sin(), 0.0);
        dup.push(p);
        dup.push(p);
        if i % 5 == 0 {
            dup.push(p);
        }
    }
    let one = vec![DVec3::new(1.0, 1.0, 1.0)];
    let two = vec![DVec3::ZERO, DVec3::new(0.0, 0.0, 2.0)];
    let mut nan = hairpin(90.0, true, 0.5);
    nan[5] = DVec3::NAN;
    nan[30] = DVec3::new(f64::NAN, 1.0, 2.0);
    let s = lines(&[dup, one, two, nan]);
    let (mesh, st) = build(&s, &opts(0.25));
    check("degenerate inputs", &mesh, &st, 0.25);
    assert_eq!(st.streamlines_in, 4);
    assert_eq!(
        st.skipped_streamlines, 1,
        "the one-point streamline has no tube"
    );
    assert_eq!(st.streamlines_out, 3);
    assert!(
        st.dropped_points >= 2 + 36,
        "NaN and repeated points are dropped: {}",
        st.dropped_points
    );
}

#[test]
fn far_from_the_origin() {
    let off = DVec3::splat(1e6);
    let c: Vec<DVec3> = hairpin(179.0, false, 0.5)
        .into_iter()
        .map(|p| p * 0.1 + off)
        .collect();
    let (mesh, st) = build(&lines(&[c]), &opts(0.03));
    check("offset 1e6", &mesh, &st, 0.03);
    assert!((mesh.origin - off).length() < 10.0);
}

#[test]
fn frenet_frames_twist_where_rmf_does_not() {
    // A non-planar hairpin: the Frenet normal swings round the turn; RMF stays put.
    let c = hairpin(170.0, false, 0.5);
    let mut o = opts(0.2);
    let (_, rmf) = build(&lines(std::slice::from_ref(&c)), &o);
    o.frame = FrameMethod::Frenet;
    let (_, fr) = build(&lines(&[c]), &o);
    assert!(rmf.max_twist_deg <= 1.0);
    assert!(
        fr.max_twist_deg > 5.0 * rmf.max_twist_deg.max(0.1),
        "frenet {} vs rmf {}",
        fr.max_twist_deg,
        rmf.max_twist_deg
    );
}

/// Uniform noise in [-0.5, 0.5) from an xorshift64 stream seeded by `seed`.
fn noise(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }
}

/// The centres of the first `rings` rings of a mesh of one tube (caps come after the rings).
fn ring_centres(mesh: &TubeMesh, sides: usize, rings: usize) -> Vec<DVec3> {
    mesh.positions[..rings * sides]
        .chunks_exact(sides)
        .map(|v| mesh.origin + v.iter().map(|p| p.as_dvec3()).sum::<DVec3>() / sides as f64)
        .collect()
}

/// Every ring centre is an input point, in order, the first and the last on the line's ends,
/// and every input point lies within `tolerance` of the polyline through the centres.
fn assert_within_polyline(points: &[DVec3], centres: &[DVec3], tolerance: f64) {
    let on =
        |c: DVec3, from: usize| (from..points.len()).find(|&i| (points[i] - c).length() < 1e-4);
    let mut at = Vec::new();
    for (r, &c) in centres.iter().enumerate() {
        let from = at.last().map_or(0, |&i: &usize| i + 1);
        at.push(on(c, from).unwrap_or_else(|| panic!("ring {r} centred at {c}, on no point")));
    }
    assert_eq!(at.first(), Some(&0));
    assert_eq!(at.last(), Some(&(points.len() - 1)));
    for w in at.windows(2) {
        let (a, b) = (points[w[0]], points[w[1]]);
        let v = b - a;
        for (i, &x) in points.iter().enumerate().take(w[1]).skip(w[0] + 1) {
            let u = ((x - a).dot(v) / v.length_squared()).clamp(0.0, 1.0);
            let d = (x - a - v * u).length();
            assert!(d <= tolerance + 1e-9, "point {i} {d} from its segment");
        }
    }
}

#[test]
fn noisy_lines_are_meshed_as_their_polyline() {
    // A helix with noise of 5x the tolerance (the benchmark's noisy helices): the fit cannot
    // shorten it, so it is meshed as its polyline - a ring on each point the tolerance cannot
    // let go, at most vtkTubeFilter's ring per point - instead of a fit that follows the
    // noise with refined rings (2.4x the triangles, docs/benchmarks.md). The mesh keeps every
    // invariant but the twist (a polyline turns at every point; RMF carries the frame exactly,
    // the twist bound is for fitted curves), and smooth lines still go through the fit.
    let mut rnd = noise(12345u64);
    let n = 200;
    let noisy: Vec<DVec3> = (0..n)
        .map(|i| {
            let t = i as f64 * 0.16;
            DVec3::new(3.0 * t.cos(), 3.0 * t.sin(), 0.64 * t)
                + DVec3::new(rnd(), rnd(), rnd()) * 0.2
        })
        .collect();
    let o = opts(0.2);
    let (mesh, st) = build(&lines(std::slice::from_ref(&noisy)), &o);
    assert_eq!(st.polyline_pieces, 1);
    let caps = if o.caps { 2 * o.sides } else { 0 };
    let kept = st.control_points;
    assert_eq!(st.triangles, (kept - 1) * 2 * o.sides + caps);
    // Noise of 5x the tolerance lets few points go.
    assert!(kept <= n && kept >= n * 9 / 10, "{kept} of {n} points kept");
    assert!(st.max_deviation <= o.fit.epsilon, "{}", st.max_deviation);
    // The rings sit on input points, in order, the first and last on the line's ends, and
    // every input point lies within the tolerance of the axis through them.
    let centres = ring_centres(&mesh, o.sides, kept);
    assert_within_polyline(&noisy, &centres, o.fit.epsilon);
    assert!(mesh.positions.iter().all(|v| v.is_finite()));
    // Without the noise the same helix is fitted and reduced.
    let clean: Vec<DVec3> = (0..n)
        .map(|i| {
            let t = i as f64 * 0.16;
            DVec3::new(3.0 * t.cos(), 3.0 * t.sin(), 0.64 * t)
        })
        .collect();
    let (mesh, st) = build(&lines(std::slice::from_ref(&clean)), &o);
    assert_eq!(st.polyline_pieces, 0);
    assert!(st.control_points <= n / 2, "{}", st.control_points);
    check("clean helix", &mesh, &st, 0.2);
}

#[test]
fn a_rough_line_is_split_at_a_sharp_turn() {
    // Noise above the tolerance and a 135-degree corner in the middle: meshed as two polylines
    // sharing the corner point (a ring per point would fold there), no more triangles than a
    // ring per input point, every mesh invariant kept but the fitted-curve twist bound.
    let mut rnd = noise(777u64);
    let a = 135f64.to_radians();
    let d2 = DVec3::new(a.cos(), a.sin(), 0.0);
    let mut pts: Vec<DVec3> = (0..=40)
        .map(|i| DVec3::X * (0.5 * i as f64 - 20.0) + DVec3::new(rnd(), rnd(), rnd()) * 0.2)
        .collect();
    pts[40] = DVec3::ZERO;
    pts.extend((1..=40).map(|i| d2 * (0.5 * i as f64) + DVec3::new(rnd(), rnd(), rnd()) * 0.2));
    let mut o = opts(0.2);
    o.caps = false;
    let (mesh, st) = build(&lines(std::slice::from_ref(&pts)), &o);
    assert!(st.splits >= 1, "splits {}", st.splits);
    assert!(
        st.polyline_pieces >= 2,
        "polyline pieces {}",
        st.polyline_pieces
    );
    assert!(
        st.triangles <= (pts.len() - 1) * 2 * o.sides,
        "{}",
        st.triangles
    );
    assert!(mesh.positions.iter().all(|v| v.is_finite()));
    for tri in mesh.indices.chunks_exact(3) {
        let [p, q, r] = [0, 1, 2].map(|k| mesh.positions[tri[k] as usize].as_dvec3());
        assert!(
            (q - p).cross(r - p).length() > 0.0,
            "degenerate triangle {tri:?}"
        );
    }
}

#[test]
fn a_line_rough_enough_to_turn_sharply_often_is_meshed_as_polylines_without_fits() {
    // 1 mm steps jittered by up to 0.75 mm: sharp turns every few points, so the line is
    // split into many short parts - each meshed as its polyline (a part of under eight points
    // was fitted on its own before: 60,000 of 189,000 parts on 20,000 such lines, 47% of the
    // meshing time, no fewer rings; docs/benchmarks.md). Within the tolerance, no more triangles than a ring per
    // point and the parts' caps.
    let mut rnd = noise(4242u64);
    let pts: Vec<DVec3> = (0..300)
        .map(|i| DVec3::X * i as f64 + DVec3::new(rnd(), rnd(), rnd()) * 1.5)
        .collect();
    let o = opts(0.2);
    let (mesh, st) = build(&lines(std::slice::from_ref(&pts)), &o);
    assert!(st.splits >= 20, "splits {}", st.splits);
    assert_eq!(st.polyline_pieces, st.splits + 1, "{st:?}");
    // (Not `check_within`: a polyline's rings fold where it turns by up to 100 degrees within
    // a ring spacing, `a_rough_line_narrows_where_it_turns_within_a_ring_spacing`.)
    assert!(mesh.positions.iter().all(|v| v.is_finite()));
    assert!(st.max_deviation <= o.fit.epsilon, "{}", st.max_deviation);
    let caps = 2 * o.sides * (st.splits + 1);
    assert!(
        st.triangles <= (pts.len() - 1 + st.splits) * 2 * o.sides + caps,
        "{}",
        st.triangles
    );
    // Every piece is closed by its caps, and its triangles agree in orientation: each edge
    // (by its ends' positions) is run once in each direction. (The pieces are written as one
    // run of rings a streamline, pieces starting where a ring says so; a cap on the wrong
    // ring, or quads across a piece's start, leave edges unmatched.)
    let key = |i: u32| mesh.positions[i as usize].to_array().map(f32::to_bits);
    let mut edges = std::collections::HashMap::new();
    for tri in mesh.indices.chunks_exact(3) {
        for k in 0..3 {
            *edges
                .entry((key(tri[k]), key(tri[(k + 1) % 3])))
                .or_insert(0) += 1;
        }
    }
    let open = edges
        .iter()
        .filter(|&(&(a, b), &n)| n != 1 || edges.get(&(b, a)) != Some(&1))
        .count();
    assert_eq!(open, 0, "{open} of {} edges unmatched", edges.len());
}

/// A straight line has no curvature to limit its radius: its tube is the same ring for ring at
/// any radius up to the 1e15 allowed (rings closer than 1e-4 radius were skipped as a
/// near-reversal's apex: from a radius of 1e5 on a line of 49 mm, and at 1e6 all but one,
/// "no tube could be built").
#[test]
fn a_straight_line_takes_any_radius() {
    let pts: Vec<DVec3> = (0..50).map(|i| DVec3::X * i as f64).collect();
    let count = |radius: f64| {
        let (mesh, st) = build(&lines(std::slice::from_ref(&pts)), &opts(radius));
        assert!(
            mesh.positions.iter().all(|v| v.is_finite()),
            "radius {radius}"
        );
        st.triangles
    };
    let small = count(0.2);
    assert!(small > 0);
    for radius in [1e4, 1e5, 1e6, 1e12] {
        assert_eq!(count(radius), small, "radius {radius}");
    }
}

#[test]
fn meshing_owned_streamlines_gives_the_same_mesh() {
    // `build_owned` frees the points between the rings and the mesh (umbra tubes' lower peak):
    // the mesh, vertex for vertex, and the statistics are those of `build`, on smooth, noisy
    // and degenerate lines together.
    let mut rnd = noise(4242u64);
    let helix = |r: f64, eps: f64, rnd: &mut dyn FnMut() -> f64| -> Vec<DVec3> {
        (0..150)
            .map(|i| {
                let t = i as f64 * 0.16;
                DVec3::new(r * t.cos(), r * t.sin(), 0.64 * t)
                    + DVec3::new(rnd(), rnd(), rnd()) * eps
            })
            .collect()
    };
    let curves = vec![
        helix(3.0, 0.0, &mut rnd),
        helix(2.0, 0.2, &mut rnd),
        vec![DVec3::ONE; 3],
        hairpin(179.0, false, 0.5),
    ];
    let o = opts(0.2);
    let (a, sa) = build(&lines(&curves), &o);
    let (b, sb) = tubes::tube_mesh::build_owned(lines(&curves), &o);
    assert!(a.triangles() > 1000);
    assert_eq!(sa, sb);
    assert_eq!(a.origin, b.origin);
    assert_eq!(a.positions, b.positions);
    assert_eq!(a.normals, b.normals);
    assert_eq!(a.colors, b.colors);
    assert_eq!(a.indices, b.indices);
}

#[test]
fn many_streamlines_mesh_as_each_alone_across_batches_and_blocks() {
    // 65,539 short curved streamlines: more than one batch (4,096) and one block (65,536) of
    // the mesher. The mesh of all of them is each one's own mesh, in order: the same world
    // positions (f32 about another origin: within 1e-4), normals and colours, its indices
    // shifted by the vertices before it; the statistics add up.
    let n = 65_536 + 3;
    let curve = |i: usize| -> Vec<DVec3> {
        let c = DVec3::new((i % 256) as f64, (i / 256) as f64, 0.0) * 3.0;
        let b = 0.2 + 0.3 * ((i * 7919) % 13) as f64 / 13.0;
        (0..4)
            .map(|k| c + DVec3::new(k as f64 * 0.5, b * (k * k) as f64 * 0.1, 0.0))
            .collect()
    };
    let curves: Vec<Vec<DVec3>> = (0..n).map(curve).collect();
    let o = opts(0.1);
    let (all, st) = tubes::tube_mesh::build_owned(lines(&curves), &o);
    assert_eq!(st.streamlines_in, n);
    let (mut v0, mut i0, mut triangles) = (0usize, 0usize, 0usize);
    // Every 97th streamline and those at the batch and block edges, compared in full.
    let check: Vec<usize> = (0..n)
        .filter(|&i| i % 97 == 0 || [4095, 4096, 65_535, 65_536, n - 1].contains(&i))
        .collect();
    for (i, c) in curves.iter().enumerate() {
        let (one, s1) = build(&lines(std::slice::from_ref(c)), &o);
        let (nv, ni) = (one.positions.len(), one.indices.len());
        assert!(nv > 0, "streamline {i} has no tube");
        if check.binary_search(&i).is_ok() {
            for k in 0..nv {
                let a = all.origin + all.positions[v0 + k].as_dvec3();
                let b = one.origin + one.positions[k].as_dvec3();
                assert!(
                    (a - b).length() < 1e-4,
                    "streamline {i} vertex {k}: {a} {b}"
                );
                assert!((all.normals[v0 + k] - one.normals[k]).length() < 1e-5);
                assert_eq!(all.colors[v0 + k], one.colors[k]);
            }
            for k in 0..ni {
                assert_eq!(all.indices[i0 + k] as usize, one.indices[k] as usize + v0);
            }
        }
        v0 += nv;
        i0 += ni;
        triangles += s1.triangles;
    }
    assert_eq!((v0, i0), (all.positions.len(), all.indices.len()));
    assert_eq!(triangles, st.triangles);
}

#[test]
fn a_rough_line_narrows_where_it_turns_within_a_ring_spacing() {
    // A noisy circle of radius 1 mm, a point every 0.1 mm, meshed as its polyline (no fit, so
    // no fitted curvature) with a 1.5 mm tube, which would fold on the inside of the circle:
    // the discrete curvature between rings (turn over spacing, about 1/mm) must narrow every
    // ring to at most 0.9 spacing / turn towards either neighbour. Checked on the mesh: each
    // ring's radius, centre and plane from its vertices. (The arccosine is skipped only for
    // turns that cannot narrow a ring; skipping it everywhere fails here.)
    let mut rnd = noise(4242u64);
    let pts: Vec<DVec3> = (0..60)
        .map(|i| {
            let a = 0.1 * i as f64;
            DVec3::new(a.cos(), a.sin(), 0.0) + DVec3::new(rnd(), rnd(), rnd()) * 0.04
        })
        .collect();
    // Noise of +-0.02 mm is rough at a tolerance of 0.005 mm.
    let mut o = opts(1.5);
    o.fit.epsilon = 0.005;
    o.caps = false;
    let (mesh, st) = build(&lines(std::slice::from_ref(&pts)), &o);
    assert_eq!(st.polyline_pieces, 1, "meshed as its polyline");
    let rings = mesh.positions.len() / o.sides;
    assert_eq!(rings, st.control_points);
    assert!(
        rings <= pts.len() && rings >= pts.len() * 3 / 4,
        "{rings} rings for {} points",
        pts.len()
    );
    assert!(
        st.radius_clamps > rings / 2,
        "{} of {rings} rings narrowed",
        st.radius_clamps,
    );
    // Centre, radius and axis of each ring (vertices 0 and 2 of an octagon are 90 degrees
    // apart: radius r and radius b).
    let rings: Vec<(DVec3, f64, DVec3)> = mesh
        .positions
        .chunks_exact(o.sides)
        .map(|v| {
            let v: Vec<DVec3> = v.iter().map(|p| p.as_dvec3()).collect();
            let c = v.iter().sum::<DVec3>() / o.sides as f64;
            let axis = (v[0] - c).cross(v[2] - c).normalize();
            (c, (v[0] - c).length(), axis)
        })
        .collect();
    for (i, w) in rings.windows(2).enumerate() {
        let ((c0, r0, t0), (c1, r1, t1)) = (w[0], w[1]);
        let turn = t0.dot(t1).clamp(-1.0, 1.0).acos();
        let limit = 0.9 * (c1 - c0).length() / turn.max(1e-12);
        assert!(
            r0.max(r1) <= limit * 1.01 + 1e-5,
            "rings {i}, {}: radii {r0}, {r1} above 0.9 spacing / turn = {limit}",
            i + 1
        );
    }
}

#[test]
fn a_short_line_whose_fit_misses_the_tolerance_is_meshed_as_its_polyline() {
    // Three points of HCP1065 (TrackVis' 1/16 mm steps; a part of a line split at its sharp
    // turns): the cubic through them misses the 0.02 mm tolerance by a third (0.027 mm), so
    // the part is meshed as its polyline, deviation 0.
    let pts = vec![
        DVec3::new(-54.15625, -68.875, 119.5),
        DVec3::new(-53.90625, -69.0, 119.9375),
        DVec3::new(-53.90625, -69.03125, 119.9375),
    ];
    let o = opts(0.2);
    let (_, st) = build(&lines(std::slice::from_ref(&pts)), &o);
    assert!(
        st.max_deviation <= o.fit.epsilon,
        "deviation {}",
        st.max_deviation
    );
    assert!(st.triangles <= 2 * 2 * o.sides + 2 * 2 * o.sides);
}

#[test]
fn a_rough_polyline_keeps_the_points_the_tolerance_needs() {
    // A line sampled every 0.1 along a gentle arc, with one kink (a point moved by 5
    // tolerances: too rough for the fit, so meshed as its polyline): the arc needs few rings, every input point stays within the tolerance of the axis, the reported
    // deviation is the largest of those distances, and the mesh has fewer triangles than a
    // ring per point. Coloured by a per-point attribute, every point keeps its ring (its
    // value is drawn there).
    let mut pts: Vec<DVec3> = (0..150)
        .map(|i| {
            let s = 0.1 * i as f64;
            DVec3::new(s, 0.3 * (s / 3.0).sin(), 0.0)
        })
        .collect();
    // Moved by 5 tolerances: a fourth difference of 30 tolerances, a turn of 90 degrees.
    pts[75].y += 5.0 * 0.02;
    let o = opts(0.2);
    let (mesh, st) = build(&lines(std::slice::from_ref(&pts)), &o);
    assert_eq!(st.polyline_pieces, 1, "meshed as its polyline");
    assert!(
        st.control_points < pts.len() / 3,
        "{} rings for {} points",
        st.control_points,
        pts.len()
    );
    assert!(st.max_deviation > 0.0 && st.max_deviation <= o.fit.epsilon);
    let centres = ring_centres(&mesh, o.sides, st.control_points);
    assert_within_polyline(&pts, &centres, o.fit.epsilon);
    let caps = if o.caps { 2 * o.sides } else { 0 };
    assert_eq!(st.triangles, (st.control_points - 1) * 2 * o.sides + caps);
    check("rough polyline", &mesh, &st, 0.2);
    // A per-point attribute: a ring on every point.
    let mut s = lines(std::slice::from_ref(&pts));
    s.point_attributes.push(tubes::Attribute {
        name: "fa".into(),
        components: 1,
        values: (0..pts.len())
            .map(|i| i as f32 / pts.len() as f32)
            .collect(),
    });
    let mut o = opts(0.2);
    o.color = ColorMode::Scalar("fa".into(), None);
    let (_, st) = build(&s, &o);
    assert_eq!(st.polyline_pieces, 1);
    assert_eq!(st.control_points, pts.len());
    assert_eq!(st.max_deviation, 0.0);
}

/// Trackers' kinks: a smooth arc whose last segment doubles back (a hook), and a straight run
/// with a hair-length side step. Where the kink's segment is no longer than the tolerance its
/// point is dropped (`kinks`, within `max_deviation`): the hooked arc is fitted as a line
/// without a sharp turn, and the side step leaves one tube, not three pieces (the middle one
/// a side step long: a crack and a sliver at the joint, found by a new user on HCP1065's
/// TR_S_R at tolerance 0.2). A hook longer than the tolerance but shorter than the tube's scale
/// (twice its radius) splits the line there instead of keeping a fit with more rings than its
/// two parts need as polylines (HCP1065 at tolerance 0.2 cost more triangles than at 0.1 on
/// nine of its ten bundles before, docs/benchmarks.md); a hairpin whose legs are longer than
/// that keeps its fit (`hairpins_of_150_179_and_180_degrees`).
#[test]
fn trackers_kinks_are_dropped_within_the_tolerance_or_split_off() {
    // A gentle arc (radius 40 mm, 0.5 mm steps over 30 mm), then a hook of length h turning
    // back by `turn` degrees.
    let arc = |h: f64, turn: f64| {
        let mut p: Vec<DVec3> = (0..=60)
            .map(|i| {
                let a = i as f64 * 0.5 / 40.0;
                DVec3::new(40.0 * a.sin(), 40.0 * (1.0 - a.cos()), 0.0)
            })
            .collect();
        let n = p.len();
        let d = (p[n - 1] - p[n - 2]).normalize();
        let side = DVec3::Z.cross(d);
        let back = d * turn.to_radians().cos() + side * turn.to_radians().sin();
        p.push(p[n - 1] + back.normalize() * h);
        p
    };
    let o = TubeOptions {
        fit: FitOptions {
            epsilon: 0.2,
            ..opts(0.5).fit
        },
        ..opts(0.5)
    };
    // No hook: the reference.
    let plain = {
        let mut p = arc(0.1, 150.0);
        p.pop();
        lines(&[p])
    };
    let (_, st0) = build(&plain, &o);
    assert_eq!((st0.kinks, st0.splits), (0, 0), "{st0:?}");
    // A hook of 0.1 mm: its turn point dropped, the line ending at the hook's tip.
    let (mesh, st) = build(&lines(&[arc(0.1, 150.0)]), &o);
    check_within("hook 0.1", &mesh, &st, 0.2);
    assert_eq!((st.kinks, st.splits), (1, 0), "{st:?}");
    // A straight run 0.5 mm apart with a side step of 0.028 mm at x = 10, back and across
    // (turns of 135 degrees at both of its ends).
    let mut run: Vec<DVec3> = (0..=20).map(|i| DVec3::X * (i as f64 * 0.5)).collect();
    run.push(DVec3::new(9.98, 0.02, 0.0));
    run.extend((21..=40).map(|i| DVec3::new(i as f64 * 0.5, 0.03, 0.0)));
    let (mesh, st) = build(&lines(&[run.clone()]), &o);
    check_within("side step", &mesh, &st, 0.2);
    assert!(st.kinks >= 1, "{st:?}");
    assert_eq!((st.splits, st.streamlines_out), (0, 1), "{st:?}");
    // At a tolerance below the step it stays: split there, no piece shorter than a segment.
    let tight = TubeOptions {
        fit: FitOptions {
            epsilon: 0.02,
            ..opts(0.5).fit
        },
        ..opts(0.5)
    };
    let (_, st) = build(&lines(&[run]), &tight);
    assert_eq!(st.kinks, 0, "{st:?}");
    // A hook of 0.6 mm turning back by 170 degrees runs back inside the tube (its tip 0.14 mm
    // from the segment before the turn): longer than the tolerance, but its tip goes.
    let (mesh, st) = build(&lines(&[arc(0.6, 170.0)]), &o);
    check_within("hook 0.6 at 170", &mesh, &st, 0.2);
    assert_eq!((st.kinks, st.splits), (1, 0), "{st:?}");
    // A hook of 0.3 mm turning by 110 degrees (above the tolerance, its tip 0.28 mm off the
    // line, below the scale): kept, the line split there, no more triangles than the fit of
    // the arc alone and a two-point stub.
    let (mesh, st) = build(&lines(&[arc(0.3, 110.0)]), &o);
    check_within("hook 0.3 at 110", &mesh, &st, 0.2);
    assert_eq!(
        (st.kinks, st.splits, st.streamlines_out),
        (0, 1, 2),
        "{st:?}"
    );
    assert!(
        st.triangles <= st0.triangles + 2 * o.sides + 2 * 2 * 2 * o.sides,
        "{} triangles against {} without the hook",
        st.triangles,
        st0.triangles
    );
    // At least two points stay: a line of a segment and its hook is not trimmed away.
    let tiny = lines(&[vec![
        DVec3::ZERO,
        DVec3::X,
        DVec3::X + DVec3::new(-0.05, 0.03, 0.0),
    ]]);
    let (_, st) = build(&tiny, &o);
    assert_eq!((st.streamlines_out, st.kinks), (1, 1), "{st:?}");
}

/// A NaN attribute value colours its own point's ring with the map's lowest colour, and no
/// other: the rings beside it take their own values (interpolated with the NaN they had taken
/// the lowest colour a ring spacing either side).
#[test]
fn a_nan_scalar_colours_only_its_own_ring() {
    // A zigzag rough enough to be meshed as its polyline, a ring on every point.
    let pts: Vec<Vec3> = (0..40)
        .map(|i| Vec3::new(i as f32, if i % 2 == 0 { 0.3 } else { -0.3 }, 0.0))
        .collect();
    let mut s = Streamlines::new();
    s.push(&pts);
    let mut values: Vec<f32> = (0..40).map(|i| 0.25 + 0.5 * i as f32 / 39.0).collect();
    values[0] = 0.0;
    values[39] = 1.0;
    values[20] = f32::NAN;
    s.point_attributes.push(tubes::Attribute {
        name: "fa".into(),
        components: 1,
        values,
    });
    let o = TubeOptions {
        caps: false,
        color: ColorMode::Scalar("fa".into(), None),
        ..opts(0.1)
    };
    let (mesh, st) = build(&s, &o);
    assert_eq!(st.polyline_pieces, 1, "{st:?}");
    assert_eq!(mesh.positions.len(), 40 * o.sides, "a ring a point");
    let lowest = mesh.colors[0];
    let rings_lowest: Vec<usize> = (1..40)
        .filter(|&r| mesh.colors[r * o.sides] == lowest)
        .collect();
    assert_eq!(rings_lowest, vec![20], "rings in the lowest colour");
}
