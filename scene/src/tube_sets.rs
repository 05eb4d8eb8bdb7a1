//! `umbra tubes`: B-spline stream tubes of a tractogram, written as PLY or OBJ, with statistics
//! (see `tubes::bspline_fit` and `tubes::tube_mesh` for the methods).

use glam::{DMat4, DVec3};
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;
use tubes::bspline_fit::{FitMethod, FitOptions};
use tubes::tube_mesh::{
    build, ColorMode, FrameMethod, RadiusMode, TubeMesh, TubeOptions, TubeStats,
};

/// What `umbra tubes` is asked to do.
#[derive(Clone, Debug)]
pub struct TubesArgs {
    pub input: PathBuf,
    pub output: PathBuf,
    pub radius: f64,
    pub sides: usize,
    pub per_span: usize,
    pub tolerance: f64,
    pub chordal: Option<f64>,
    pub fit: FitMethod,
    pub frame: FrameMethod,
    pub radius_mode: RadiusMode,
    /// `direction`, `scalar:NAME`, `volume:PATH`, or `#rrggbb`.
    pub color: String,
    /// The colour map of `scalar:NAME` and `volume:PATH` (`None`: the built-in viridis-like
    /// ramp, `tubes::tube_mesh::colormap`).
    pub colormap: Option<volume::colormap::Colormap>,
    pub caps: bool,
    /// Row-major 4x4 applied to the points at load (e.g. the HCP1065 shift).
    pub transform: Option<[f64; 16]>,
}

impl TubesArgs {
    /// The mesher's defaults as `umbra tubes` has them (iterative fit, rotation-minimising
    /// frames, local radius, caps, one ring per span) for a radius, side count, fitting
    /// tolerance and colour source; no files.
    pub fn defaults(radius: f64, sides: usize, tolerance: f64, color: &str) -> TubesArgs {
        TubesArgs {
            input: PathBuf::new(),
            output: PathBuf::new(),
            radius,
            sides,
            per_span: 1,
            tolerance,
            chordal: None,
            fit: FitMethod::Iterative,
            frame: FrameMethod::Rmf,
            radius_mode: RadiusMode::Local,
            color: color.to_string(),
            colormap: None,
            caps: true,
            transform: None,
        }
    }
}

/// Seconds per stage (`compute`: fitting and meshing, no I/O).
pub use crate::fields::Seconds;

/// The statistics `--stats-json` writes.
#[derive(Clone, Debug, Serialize)]
pub struct TubesSummary {
    /// The mesher's statistics, as top-level keys.
    #[serde(flatten)]
    pub stats: TubeStats,
    pub vertices: usize,
    pub seconds: Seconds,
    pub warnings: Vec<String>,
}

fn parse_hex(s: &str) -> Result<[f32; 3], String> {
    let h = s.trim_start_matches('#');
    if h.len() != 6 || !h.is_ascii() {
        return Err(format!("colour {s}: expected #rrggbb"));
    }
    let c = |i: usize| {
        u8::from_str_radix(&h[i..i + 2], 16)
            .map(|v| v as f32 / 255.0)
            .map_err(|_| format!("colour {s}: not hexadecimal"))
    };
    Ok([c(0)?, c(2)?, c(4)?])
}

/// A row-major 4x4 (as `--transform` and a tube set's `transform` give it) as a matrix, or an
/// error naming `key` when it is not 16 finite numbers of an invertible matrix.
pub fn transform_matrix(m: &[f64; 16], key: &str) -> Result<DMat4, String> {
    let rows = DMat4::from_cols_array(m).transpose();
    if !m.iter().all(|v| v.is_finite() && v.abs() <= 1e15) || rows.determinant() == 0.0 {
        return Err(format!(
            "{key}: 16 finite numbers within 1e15 of an invertible row-major 4x4 matrix (a \
             flat list, row after row)"
        ));
    }
    // Points are moved as points (w = 1, not divided by a w): a projective bottom row would be
    // dropped unseen.
    if m[12..] != [0.0, 0.0, 0.0, 1.0] {
        return Err(format!(
            "{key}: the bottom row is {:?}; an affine transform's is 0, 0, 0, 1",
            &m[12..]
        ));
    }
    Ok(rows)
}

/// Runs `umbra tubes`.
pub fn run(a: &TubesArgs) -> Result<TubesSummary, String> {
    let t0 = Instant::now();
    // Settings first, before anything is read (the mesher's check, on the same values).
    TubeOptions {
        radius: a.radius,
        sides: a.sides,
        per_span: a.per_span,
        chordal: a.chordal,
        ..TubeOptions::defaults(a.radius, a.sides, a.tolerance)
    }
    .check()?;
    volume::check_output(&a.output)?;
    let mut s = tubes::load(&a.input).map_err(|e| e.to_string())?;
    let nonfinite = s.nonfinite_points();
    if let Some(m) = a.transform {
        s.transform(&transform_matrix(&m, "transform")?);
    }
    let t_read = t0.elapsed().as_secs_f64();
    // Vertices are single precision relative to the mesh's origin: a radius below what that
    // resolves across the tractogram's extent flattens the tubes.
    let extent = s
        .bounds()
        .map_or(0.0, |[lo, hi]| (hi - lo).as_dvec3().max_element());
    let flat = a.radius < 1e-6 * extent;
    let t1 = Instant::now();
    let ply = a
        .output
        .to_string_lossy()
        .to_ascii_lowercase()
        .ends_with(".ply");
    let mut warnings = std::mem::take(&mut s.warnings);
    let (st, vertices, t_compute, t_write) = if ply {
        // Meshed and written part by part: the peak is the points, the rings and one part.
        let (st, vertices, t_write) = tubes_to_ply(s, a)?;
        (st, vertices, t1.elapsed().as_secs_f64() - t_write, t_write)
    } else {
        // An OBJ is built whole: refused first when it would not fit.
        if let (Some(need), Some((budget, what))) = (mesh_memory_estimate(&s, a)?, memory_budget())
        {
            if need > budget {
                return Err(format!(
                    "{}: meshing its {} streamlines as tubes would need about {:.1} GB (from a \
                     mesh of {ESTIMATE_SAMPLE} of them chosen at random: its vertices, \
                     triangles and rings scaled by points), more than the {:.1} GB {what}; \
                     write a PLY (meshed part by part), draw them as lines ([[lines]] in a \
                     scene), select or subsample them (umbra tracts select), or raise the \
                     tolerance",
                    a.input.display(),
                    s.len(),
                    need as f64 / 1e9,
                    budget as f64 / 1e9
                ));
            }
        }
        let (mesh, st) = build_mesh_owned(s, a)?;
        let t_compute = t1.elapsed().as_secs_f64();
        let t2 = Instant::now();
        tubes::mesh_io::write(&a.output, &mesh).map_err(|e| e.to_string())?;
        (
            st,
            mesh.positions.len(),
            t_compute,
            t2.elapsed().as_secs_f64(),
        )
    };
    push_mesh_warnings(&mut warnings, &st, a.tolerance, nonfinite);
    if flat {
        warnings.push(format!(
            "the radius {} is below what single-precision vertices resolve across the \
             tractogram's extent of {extent:e}: the tubes come out flattened",
            a.radius
        ));
    }
    Ok(TubesSummary {
        stats: st,
        vertices,
        seconds: Seconds {
            read: t_read,
            compute: t_compute,
            write: t_write,
            total: t0.elapsed().as_secs_f64(),
        },
        warnings,
    })
}

/// The warnings of a mesh's statistics (`nonfinite`: the input's points with a NaN or infinite
/// coordinate, of the points dropped).
fn push_mesh_warnings(
    warnings: &mut Vec<String>,
    st: &TubeStats,
    tolerance: f64,
    nonfinite: usize,
) {
    if st.triangles == 0 {
        warnings.push(
            "no tube was made: no streamline has two distinct points (the mesh is empty)".into(),
        );
    }
    if st.max_deviation > tolerance * (1.0 + 1e-9) {
        warnings.push(format!(
            "the largest deviation, {:.4}, exceeds the tolerance {tolerance}: only the \
             iterative fit refines until the tolerance holds",
            st.max_deviation
        ));
    }
    // Told apart: a clean tractogram's repeated points are no NaN to look for.
    let repeated = st.dropped_points.saturating_sub(nonfinite);
    match (nonfinite.min(st.dropped_points), repeated) {
        (0, 0) => {}
        (0, r) => warnings.push(format!(
            "{r} repeated points (each equal to the point before it) were dropped"
        )),
        (n, 0) => warnings.push(format!(
            "{n} non-finite (NaN or infinite) points were dropped"
        )),
        (n, r) => warnings.push(format!(
            "{n} non-finite (NaN or infinite) points and {r} repeated points (each equal to the \
             point before it) were dropped"
        )),
    }
    if st.skipped_streamlines > 0 {
        warnings.push(format!(
            "{} streamlines with fewer than two distinct points have no tube",
            st.skipped_streamlines
        ));
    }
}

/// Tractograms of fewer streamlines are meshed without an estimate.
const ESTIMATE_ABOVE: usize = 20_000;

/// Streamlines the estimate meshes, chosen at random.
const ESTIMATE_SAMPLE: usize = 1000;

/// The peak memory meshing `s` would take (bytes), extrapolated by points from a mesh of
/// 1000 of its streamlines chosen at random; `None` for tractograms of at most 20,000
/// streamlines (cheap enough to mesh whatever they need).
pub fn mesh_memory_estimate(s: &tubes::Streamlines, a: &TubesArgs) -> Result<Option<u64>, String> {
    if s.len() <= ESTIMATE_ABOVE {
        return Ok(None);
    }
    let all: Vec<usize> = (0..s.len()).collect();
    let keep = tubes::select::subsample(&all, ESTIMATE_SAMPLE, 1);
    let sample = tubes::select::subset(s, &keep);
    if sample.points.is_empty() {
        return Ok(None);
    }
    let (mesh, st) = build_mesh(&sample, a)?;
    let scale = s.points.len() as f64 / sample.points.len() as f64;
    let vertices = mesh.positions.len() as f64;
    // Every tube's rings are held until the mesh is written (a ring's vertices without caps).
    let sides = match a.chordal {
        Some(tol) => tubes::tube_mesh::sides_for(a.radius, tol),
        None => a.sides.max(3),
    };
    let rings = vertices / sides as f64;
    let bytes = VERTEX_BYTES as f64 * vertices
        + INDEX_BYTES as f64 * st.triangles as f64
        + tubes::tube_mesh::RING_BYTES as f64 * rings;
    Ok(Some(
        (bytes * scale * ESTIMATE_MARGIN) as u64 + 12 * s.points.len() as u64 + 8 * s.len() as u64,
    ))
}

/// A mesh vertex's bytes (position, normal, 8-bit colour) and a triangle's (three u32
/// indices).
const VERTEX_BYTES: u64 = 27;
const INDEX_BYTES: u64 = 12;

/// The estimate's margin over the mesh, its rings and the points: the allocator's and the
/// block lists' share (`bench/random_walks_tck.py`: 10^6 random walks of 3 points to an OBJ,
/// 31.8 M triangles: 1.18 GB at the peak, `/usr/bin/time -v`; the mesh and rings 1.12 + 0.08
/// GB).
const ESTIMATE_MARGIN: f64 = 1.1;

/// The memory this process may still take, and what limits it: the smaller of its
/// address-space limit (`Max address space` of /proc/self/limits, as `prlimit --as` sets it,
/// less what it maps already) and the memory available (`MemAvailable` of /proc/meminfo);
/// `None` where neither is known.
pub fn memory_budget() -> Option<(u64, &'static str)> {
    let field = |text: &str, key: &str| -> Option<u64> {
        let line = text.lines().find(|l| l.starts_with(key))?;
        line[key.len()..].split_whitespace().next()?.parse().ok()
    };
    let available = std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|t| field(&t, "MemAvailable:"))
        .map(|kb| (kb * 1024, "of memory available"));
    let limit = std::fs::read_to_string("/proc/self/limits")
        .ok()
        .and_then(|t| field(&t, "Max address space"))
        .map(|bytes| {
            let mapped = std::fs::read_to_string("/proc/self/status")
                .ok()
                .and_then(|t| field(&t, "VmSize:"))
                .map_or(0, |kb| kb * 1024);
            (
                bytes.saturating_sub(mapped),
                "left under the address-space limit",
            )
        });
    match (available, limit) {
        (Some(a), Some(l)) => Some(if l.0 < a.0 { l } else { a }),
        (a, l) => a.or(l),
    }
}

/// Calls `f` with the colour mode of the colour source `color` for the streamlines `s`
/// (`direction`, `scalar:NAME`, `volume:PATH` - the volume loaded and sampled at the points -
/// or `#rrggbb`); errors say what is wrong with the source.
pub fn with_color_mode<R>(
    s: &tubes::Streamlines,
    color: &str,
    f: impl FnOnce(&ColorMode) -> R,
) -> Result<R, String> {
    with_color_map(s, color, None, f)
}

/// [`with_color_mode`] with the colour map of `scalar:NAME` and `volume:PATH` colours (`None`:
/// the built-in ramp).
pub fn with_color_map<R>(
    s: &tubes::Streamlines,
    color: &str,
    map: Option<volume::colormap::Colormap>,
    f: impl FnOnce(&ColorMode) -> R,
) -> Result<R, String> {
    let names: Vec<&str> = s.point_attributes.iter().map(|a| a.name.as_str()).collect();
    with_color_map_of(&names, color, map, f)
}

/// [`with_color_map`] for streamlines whose per-point attributes are `names` (so that `f` may
/// take the streamlines themselves).
pub fn with_color_map_of<R>(
    names: &[&str],
    color: &str,
    map: Option<volume::colormap::Colormap>,
    f: impl FnOnce(&ColorMode) -> R,
) -> Result<R, String> {
    let vol_field;
    let sampler;
    let mode = if color == "direction" {
        ColorMode::Direction
    } else if color.starts_with('#') {
        ColorMode::Constant(parse_hex(color)?)
    } else if let Some(name) = color.strip_prefix("scalar:") {
        if !names.contains(&name) {
            let have = names;
            return Err(format!(
                "colour scalar:{name}: the tractogram has no per-point '{name}' (it has: {})",
                if have.is_empty() {
                    "none".to_string()
                } else {
                    have.join(", ")
                }
            ));
        }
        ColorMode::Scalar(name.to_string(), map)
    } else if let Some(path) = color.strip_prefix("volume:") {
        if path.is_empty() {
            return Err("colour volume:PATH: the path is empty".into());
        }
        let v = volume::load(std::path::Path::new(path))
            .map_err(|e| format!("colour volume:{path}: {e}"))?;
        let fl = v.select(None).map_err(|e| e.to_string())?;
        if fl.components != 1 {
            return Err(format!(
                "colour volume:{path}: needs a scalar volume; its field '{}' has {} components \
                 (colour by a scalar map such as FA, or by one component of it: NAME:x, :y, :z or \
                 :magnitude written as its own volume)",
                fl.name, fl.components
            ));
        }
        let st = fl.stats();
        vol_field = (v, fl);
        let inv = vol_field.0.affine.inverse();
        sampler = move |p: DVec3| -> f64 {
            let (v, f) = &vol_field;
            let q = inv.transform_point3(p).round();
            let [nx, ny, nz] = v.dims;
            if q.min_element() < 0.0 || q.x >= nx as f64 || q.y >= ny as f64 || q.z >= nz as f64 {
                return f64::NAN;
            }
            f.data[v.index(q.x as usize, q.y as usize, q.z as usize)] as f64
        };
        ColorMode::Field(&sampler, [st.min, st.max], map)
    } else {
        return Err(format!(
            "colour {color}: use direction, scalar:NAME, volume:PATH or #rrggbb"
        ));
    };
    Ok(f(&mode))
}

/// The tube mesh of `s` with the options of `a` (its paths are not used): the colour source
/// resolved ([`with_color_mode`]), then `tubes::tube_mesh::build`.
pub fn build_mesh(s: &tubes::Streamlines, a: &TubesArgs) -> Result<(TubeMesh, TubeStats), String> {
    let names: Vec<String> = s.point_attributes.iter().map(|x| x.name.clone()).collect();
    mesh_with(&names, a, |opts| build(s, opts))
}

/// [`build_mesh`] taking the streamlines: their points are freed before the mesh is allocated
/// (`tubes::tube_mesh::build_owned`), which lowers the peak memory of `umbra tubes`.
pub fn build_mesh_owned(
    s: tubes::Streamlines,
    a: &TubesArgs,
) -> Result<(TubeMesh, TubeStats), String> {
    let names: Vec<String> = s.point_attributes.iter().map(|x| x.name.clone()).collect();
    mesh_with(&names, a, |opts| tubes::tube_mesh::build_owned(s, opts))
}

/// The options of `a` for streamlines with per-point attributes `names`, given to `mesh`, and
/// the check of what it made.
fn mesh_with(
    names: &[String],
    a: &TubesArgs,
    mesh: impl FnOnce(&TubeOptions) -> (TubeMesh, TubeStats),
) -> Result<(TubeMesh, TubeStats), String> {
    with_options(names, a, |opts| {
        let (mesh, st) = mesh(opts);
        not_empty(mesh.indices.len(), &st, a.radius)?;
        Ok((mesh, st))
    })
}

/// `f` given the mesher's options of `a` for streamlines with per-point attributes `names`.
fn with_options<R>(
    names: &[String],
    a: &TubesArgs,
    f: impl FnOnce(&TubeOptions) -> Result<R, String>,
) -> Result<R, String> {
    let names: Vec<&str> = names.iter().map(String::as_str).collect();
    with_color_map_of(&names, &a.color, a.colormap, |color| {
        let opts = TubeOptions {
            radius: a.radius,
            sides: a.sides,
            per_span: a.per_span,
            chordal: a.chordal,
            max_turn_deg: 15.0,
            frame: a.frame,
            radius_mode: a.radius_mode,
            fit: FitOptions {
                epsilon: a.tolerance,
                method: a.fit,
                max_iterations: 100,
            },
            caps: a.caps,
            color: color.clone(),
        };
        opts.check()?;
        f(&opts)
    })?
}

/// A non-empty input that gives no triangle (`indices` 0): the radius is beyond what the
/// lines' curvature allows everywhere (the mesher cuts a tube where even 1/1000 of the radius
/// would fold), or every line is degenerate; said rather than an empty mesh written.
fn not_empty(indices: usize, st: &TubeStats, radius: f64) -> Result<(), String> {
    if indices == 0 && st.streamlines_in > 0 && st.skipped_streamlines < st.streamlines_in {
        return Err(format!(
            "radius {radius}: no tube could be built (the tubes would fold on themselves at \
             every ring of the {} streamlines); use a radius below the lines' radius of \
             curvature",
            st.streamlines_in
        ));
    }
    Ok(())
}

/// A PLY stream that refuses an empty mesh before writing anything ([`not_empty`]).
struct CheckedPly<'a> {
    ply: &'a mut tubes::mesh_io::PlyStream,
    radius: f64,
}

impl tubes::tube_mesh::MeshSink for CheckedPly<'_> {
    fn begin(
        &mut self,
        origin: glam::DVec3,
        vertices: usize,
        indices: usize,
        stats: &TubeStats,
    ) -> tubes::Result<()> {
        not_empty(indices, stats, self.radius).map_err(tubes::TubesError::Invalid)?;
        self.ply.begin(origin, vertices, indices, stats)
    }

    fn part(&mut self, part: &tubes::tube_mesh::MeshPart<'_>) -> tubes::Result<()> {
        self.ply.part(part)
    }
}

/// `umbra tubes` to a PLY file: meshed and written part by part
/// ([`tubes::tube_mesh::build_streamed`]); the statistics, the vertex count and the seconds
/// spent writing.
fn tubes_to_ply(s: tubes::Streamlines, a: &TubesArgs) -> Result<(TubeStats, usize, f64), String> {
    let names: Vec<String> = s.point_attributes.iter().map(|x| x.name.clone()).collect();
    let mut ply = tubes::mesh_io::PlyStream::create(&a.output).map_err(|e| e.to_string())?;
    let (st, vertices) = with_options(&names, a, |opts| {
        let mut sink = CheckedPly {
            ply: &mut ply,
            radius: a.radius,
        };
        tubes::tube_mesh::build_streamed(s, opts, &mut sink).map_err(|e| e.to_string())
    })?;
    let seconds = ply.finish().map_err(|e| e.to_string())?;
    Ok((st, vertices, seconds))
}

/// A value per point of `s` from `source`: `scalar:NAME` (a per-point attribute) or
/// `volume:PATH` (a scalar volume sampled at the nearest voxel; NaN outside it).
pub fn point_values(s: &tubes::Streamlines, source: &str) -> Result<Vec<f32>, String> {
    if let Some(name) = source.strip_prefix("scalar:") {
        let a = s
            .point_attributes
            .iter()
            .find(|a| a.name == name)
            .ok_or_else(|| {
                let have: Vec<&str> = s.point_attributes.iter().map(|x| x.name.as_str()).collect();
                format!(
                    "{source}: the tractogram has no per-point '{name}' (it has: {})",
                    if have.is_empty() {
                        "none".to_string()
                    } else {
                        have.join(", ")
                    }
                )
            })?;
        return Ok(a
            .values
            .iter()
            .step_by(a.components.max(1))
            .copied()
            .collect());
    }
    let Some(path) = source.strip_prefix("volume:") else {
        return Err(format!("{source}: use scalar:NAME or volume:PATH"));
    };
    let v = volume::load(std::path::Path::new(path)).map_err(|e| e.to_string())?;
    let f = v.select(None).map_err(|e| e.to_string())?;
    if f.components != 1 {
        return Err(format!(
            "{source}: needs a scalar volume; its field '{}' has {} components (colour by a \
             scalar map such as FA)",
            f.name, f.components
        ));
    }
    let inv = v.affine.inverse();
    let [nx, ny, nz] = v.dims;
    Ok(s.points
        .iter()
        .map(|p| {
            let q = inv.transform_point3(p.as_dvec3()).round();
            if q.min_element() < 0.0 || q.x >= nx as f64 || q.y >= ny as f64 || q.z >= nz as f64 {
                f32::NAN
            } else {
                f.data[v.index(q.x as usize, q.y as usize, q.z as usize)]
            }
        })
        .collect())
}

/// The selection a `select` spec asks; `label` names a key of it in errors (a scene gives
/// `scene key tubes[0].select.include_spheres`, the command line its flag). The masks are read
/// from their files when `read_masks`, else left out (to check the values alone).
pub fn selection(
    sel: &crate::spec::SelectSpec,
    label: &dyn Fn(&str) -> String,
    read_masks: bool,
) -> Result<tubes::select::Selection, String> {
    use tubes::select::{AttributeRange, Mask, Roi, Selection};
    let at = |k: &str, why: String| format!("{}: {why}", label(k));
    let spheres = |k: &str, v: &[[f64; 4]]| -> Result<Vec<Roi>, String> {
        v.iter()
            .map(|s| Roi::sphere(*s).map_err(|e| at(k, e)))
            .collect()
    };
    let boxes = |k: &str, v: &[[f64; 6]]| -> Result<Vec<Roi>, String> {
        v.iter()
            .map(|b| Roi::cuboid(*b).map_err(|e| at(k, e)))
            .collect()
    };
    let masks = |k: &str, v: &[String]| -> Result<Vec<Roi>, String> {
        if !read_masks {
            return Ok(vec![]);
        }
        v.iter()
            .map(|m| Mask::load(m).map(Roi::Mask).map_err(|e| at(k, e)))
            .collect()
    };
    let mut include = spheres("include_spheres", &sel.include_spheres)?;
    include.extend(boxes("include_boxes", &sel.include_boxes)?);
    include.extend(masks("include_masks", &sel.include_masks)?);
    let mut exclude = spheres("exclude_spheres", &sel.exclude_spheres)?;
    exclude.extend(boxes("exclude_boxes", &sel.exclude_boxes)?);
    exclude.extend(masks("exclude_masks", &sel.exclude_masks)?);
    let attribute = match (&sel.attribute, sel.attribute_min, sel.attribute_max) {
        (Some(name), min, max) => Some(AttributeRange {
            name: name.clone(),
            min: min.unwrap_or(f64::NEG_INFINITY),
            max: max.unwrap_or(f64::INFINITY),
        }),
        (None, None, None) => None,
        (None, _, _) => {
            return Err(at(
                "attribute",
                "a minimum or maximum needs the attribute's name".into(),
            ))
        }
    };
    let out = Selection {
        include,
        exclude,
        min_length: sel.min_length,
        max_length: sel.max_length,
        attribute,
        subsample: sel.subsample.map(|n| (n, sel.seed)),
    };
    out.check().map_err(|e| format!("{}: {e}", label("")))?;
    Ok(out)
}

/// `s` reduced to what the selection `sel` keeps (nothing done without one), and a note with
/// the counts; `key` names the set (`tubes[0]`).
pub fn apply_selection(
    s: tubes::Streamlines,
    sel: Option<&crate::spec::SelectSpec>,
    key: &str,
) -> Result<(tubes::Streamlines, Option<String>), String> {
    let Some(sel) = sel else {
        return Ok((s, None));
    };
    let selection = selection(sel, &|k| scene_key(&format!("{key}.select"), k), true)?;
    let (out, sum) = selection
        .apply(&s)
        .map_err(|e| format!("{key}.select: {e}"))?;
    let note = format!(
        "{key}: select kept {} of {} streamlines",
        sum.kept, sum.total
    );
    Ok((out, Some(note)))
}

/// `scene key tubes[0].select.include_spheres` (or `... tubes[0].select` for `k` empty).
pub fn scene_key(key: &str, k: &str) -> String {
    if k.is_empty() {
        format!("scene key {key}")
    } else {
        format!("scene key {key}.{k}")
    }
}

/// The colour bar of a set coloured by `color`: `scalar:NAME` (the attribute's finite range, as
/// the tubes and lines map it) or `volume:PATH` (the field's range), the tubes' colour map over
/// it; `None` for other colourings, and for a set with no streamline (a selection that kept
/// none: nothing in the image is coloured, though a volume's range would make a bar).
pub fn color_bar(
    s: &tubes::Streamlines,
    color: &str,
    map: Option<volume::colormap::Colormap>,
) -> Result<Option<crate::annotate::ColorBar>, String> {
    if s.is_empty() {
        return Ok(None);
    }
    let label = color
        .strip_prefix("scalar:")
        .map(str::to_string)
        .or_else(|| {
            color.strip_prefix("volume:").map(|p| {
                let n = std::path::Path::new(p)
                    .file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default();
                n.split('.').next().unwrap_or("").to_string()
            })
        });
    let Some(label) = label else {
        return Ok(None);
    };
    let range = with_color_mode(s, color, |mode| match mode {
        ColorMode::Scalar(name, _) => {
            s.point_attributes
                .iter()
                .find(|a| &a.name == name)
                .map(|a| {
                    a.values
                        .iter()
                        .step_by(a.components)
                        .filter(|v| v.is_finite())
                        .fold([f64::INFINITY, f64::NEG_INFINITY], |[l, h], &x| {
                            [l.min(x as f64), h.max(x as f64)]
                        })
                })
        }
        ColorMode::Field(_, r, _) => Some(*r),
        _ => None,
    })?;
    Ok(range
        .filter(|r| r[0] <= r[1])
        .map(|range| crate::annotate::ColorBar {
            label,
            map: map.map_or("viridis", |m| m.name()).into(),
            range,
            colors: (0..64)
                // Drawn into the linear image: decoded as the renderer decodes the tubes'.
                .map(|k| {
                    tubes::tube_mesh::map_color(map, (k as f64 + 0.5) / 64.0)
                        .map(|c| volume::colormap::srgb_to_linear(c as f64) as f32)
                })
                .collect(),
        }))
}
