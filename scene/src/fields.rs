//! The swept fields of an isosurface (signed distance and the eight octant occlusion fields,
//! Singh et al.; see `volume::distance_sweep` and `volume::occlusion_sweep`): computed, written
//! as NRRD and read back - the library of `umbra sweep` and of scenes in isosurface mode.

use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;
use volume::distance_sweep::classify_and_initialise_owned;
use volume::distance_sweep::{DistanceField, DistanceMethod, DistanceOptions, InitMethod, Inside};
use volume::nrrd::{self, Array, ArrayData, WriteEncoding};
use volume::occlusion_sweep::{fields_from_band, OcclusionOptions, OctantFields};
use volume::{FieldSelector, ScalarType, Volume};

/// What `umbra sweep` is asked to do.
#[derive(Clone, Debug)]
pub struct SweepArgs {
    pub input: PathBuf,
    pub iso: f32,
    pub output: PathBuf,
    pub octants_out: Option<PathBuf>,
    pub inside: Inside,
    pub field: Option<FieldSelector>,
    pub sdf_only: bool,
    pub init: InitMethod,
    /// How the band's distances reach the rest of the grid.
    pub method: DistanceMethod,
    pub tolerance: f32,
    pub subsurface_alpha: Option<f32>,
}

/// Seconds per stage of a command (reading, computing without I/O, writing, in all).
#[derive(Clone, Debug, Serialize)]
pub struct Seconds {
    pub read: f64,
    pub compute: f64,
    pub write: f64,
    pub total: f64,
}

/// The summary `umbra sweep --json` prints.
#[derive(Clone, Debug, Serialize)]
pub struct SweepSummary {
    pub dims: [usize; 3],
    /// `closest-point` or `sweeping`.
    pub distance_method: &'static str,
    /// Rounds of eight distance sweeps (0 for closest points).
    pub iterations: usize,
    pub converged: bool,
    pub seconds: Seconds,
    pub peak_bytes: Option<u64>,
    pub band_voxels: usize,
    pub nan_voxels: usize,
    pub distance: PathBuf,
    pub octants: Option<PathBuf>,
    pub warnings: Vec<String>,
}

/// `<stem>.octants.nrrd` beside the distance file.
pub fn default_octants_path(distance: &Path) -> PathBuf {
    let name = distance
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let stem = name.strip_suffix(".nrrd").unwrap_or(&name);
    distance.with_file_name(format!("{stem}.octants.nrrd"))
}

/// Peak resident memory of this process (Linux `VmHWM`), in bytes.
pub fn peak_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Selects the scalar field and checks that the iso level cuts it.
pub fn scalar_field(
    vol: &Volume,
    field: Option<&FieldSelector>,
    iso: f32,
    inside: Inside,
    path: &Path,
) -> Result<Vec<f32>, String> {
    let f = vol
        .select(field)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    if f.components != 1 {
        return Err(format!(
            "{}: field '{}' has {} components; an isosurface needs a scalar (select {}:magnitude)",
            path.display(),
            f.name,
            f.components,
            f.name
        ));
    }
    if !iso.is_finite() {
        return Err(format!("iso level {iso}: must be a finite number"));
    }
    let st = f.stats();
    if st.min.is_nan() {
        return Err(format!(
            "{}: field '{}' has no finite samples",
            path.display(),
            f.name
        ));
    }
    let iso64 = iso as f64;
    let no_surface = match inside {
        Inside::Above => iso64 <= st.min || iso64 > st.max,
        Inside::Below => iso64 < st.min || iso64 >= st.max,
    };
    if no_surface {
        // At the range's minimum with `above` (maximum with `below`) the level is in the range
        // but every sample is inside: inside is at or above (at or below) the level.
        let place = if iso64 < st.min || iso64 > st.max {
            "outside it"
        } else {
            match inside {
                Inside::Above => "its minimum, and samples at or above the level are inside",
                Inside::Below => "its maximum, and samples at or below the level are inside",
            }
        };
        return Err(format!(
            "{}: field '{}' ranges over [{}, {}] and the iso level {iso} is {place}: every sample lies on one side, so there is no surface",
            path.display(),
            f.name,
            st.min,
            st.max
        ));
    }
    Ok(f.data)
}

/// Writes the distance as a 3-D float32 NRRD in the input's frame.
pub fn write_distance(
    path: &Path,
    vol: &Volume,
    df: &DistanceField,
    sweep: &SweepTag,
) -> Result<(), String> {
    nrrd::write_array_with(
        path,
        &Array {
            dims: vol.dims,
            affine: vol.affine,
            space: vol.space,
            components: 1,
            component_kind: "list",
            stored: ScalarType::F32,
            data: ArrayData::F32(&df.distance),
            content: "signed distance (world units, negative inside)",
        },
        WriteEncoding::Raw,
        &[(SWEEP_KEY, &sweep.id), (LEVEL_KEY, &sweep.level)],
    )
    .map_err(|e| e.to_string())
}

/// Writes the octants as a 4-D uint8 NRRD whose first axis (kind `list`) holds the eight
/// octants in Table 1 order.
pub fn write_octants(
    path: &Path,
    vol: &Volume,
    oct: &OctantFields,
    sweep: &SweepTag,
) -> Result<(), String> {
    nrrd::write_array_with(
        path,
        &Array {
            dims: vol.dims,
            affine: vol.affine,
            space: vol.space,
            components: 8,
            component_kind: "list",
            stored: ScalarType::U8,
            // Interleaved while streaming: no 8-bytes-a-voxel copy.
            data: ArrayData::U8Planes(&oct.octants),
            content: "octant visibility x 255 (Table 1 order)",
        },
        WriteEncoding::Raw,
        &[
            (SWEEP_KEY, &sweep.id),
            (LEVEL_KEY, &sweep.level),
            (
                SUBSURFACE_KEY,
                &sweep.subsurface.map_or("none".into(), |a| format!("{a:?}")),
            ),
        ],
    )
    .map_err(|e| e.to_string())
}

/// The NRRD key of an octants file holding the subsurface opacity it was swept with (`none`,
/// or the opacity): the octants swept again for a cut keep it ([`iso_fields`]).
pub const SUBSURFACE_KEY: &str = "umbra_subsurface";

/// The subsurface opacity an octants file was swept with: `None` for `none`, for a file
/// without the key (other writers, umbra before 2026-12-07) and for a format without keys.
fn subsurface_of(octants: &Path) -> Result<Option<f32>, String> {
    let Ok(kv) = nrrd::key_values(octants) else {
        return Ok(None);
    };
    match kv.into_iter().find(|(k, _)| k == SUBSURFACE_KEY) {
        Some((_, v)) if v != "none" => v
            .parse::<f32>()
            .ok()
            .filter(|a| (0.0..=1.0).contains(a))
            .map(Some)
            .ok_or_else(|| {
                format!(
                    "{}: {SUBSURFACE_KEY} {v:?} is not an opacity from 0 to 1",
                    octants.display()
                )
            }),
        _ => Ok(None),
    }
}

/// The NRRD key whose value pairs a distance file with the octant fields of the same sweep:
/// one id per run of [`run`], written into both.
pub const SWEEP_KEY: &str = "umbra_sweep";

/// The NRRD key holding the level a sweep's fields belong to: `ISO above|below` (the iso
/// level as written, `f32` round trip, and which side is inside), checked when the fields are
/// used for a surface ([`iso_fields`]).
pub const LEVEL_KEY: &str = "umbra_iso";

/// What a sweep writes into both of its files' headers.
pub struct SweepTag {
    pub id: String,
    pub level: String,
    /// The subsurface opacity the octants were swept with ([`SUBSURFACE_KEY`]).
    pub subsurface: Option<f32>,
}

/// The [`LEVEL_KEY`] value of an iso level and side.
pub fn level_tag(iso: f32, inside: Inside) -> String {
    let side = match inside {
        Inside::Above => "above",
        Inside::Below => "below",
    };
    format!("{iso:?} {side}")
}

/// Refuses a distance field swept for another level or side than `iso`/`inside` (a file
/// without the key - another writer's, or umbra's before it - is taken as it is).
fn check_level(distance: &Path, iso: f32, inside: Inside) -> Result<(), String> {
    // Not a NRRD header (another format): nothing to check; reading it says the rest.
    let Ok(kv) = nrrd::key_values(distance) else {
        return Ok(());
    };
    let tag = kv.into_iter().find(|(k, _)| k == LEVEL_KEY).map(|(_, v)| v);
    let want = level_tag(iso, inside);
    match tag {
        Some(t) if t != want => Err(format!(
            "{}: these fields were swept for the level {t} ({LEVEL_KEY}), not {want}: sweep at \
             this level, or draw the level they were swept for",
            distance.display()
        )),
        _ => Ok(()),
    }
}

/// The id of one sweep: its input, iso level, clock and process, hashed.
fn sweep_id(args: &SweepArgs) -> String {
    let mut h = crate::hash::Fnv1a::default();
    h.eat(args.input.to_string_lossy().as_bytes());
    h.eat(&args.iso.to_le_bytes());
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos())
        .unwrap_or_default();
    h.eat(&now.to_le_bytes());
    h.eat(&std::process::id().to_le_bytes());
    format!("{:016x}", h.finish())
}

/// The sweep id a file written by [`write_distance`] or [`write_octants`] carries (`None`
/// for files without one: other writers, or umbra before ids).
pub fn sweep_id_of(path: &Path) -> Result<Option<String>, String> {
    Ok(nrrd::key_values(path)
        .map_err(|e| e.to_string())?
        .into_iter()
        .find(|(k, _)| k == SWEEP_KEY)
        .map(|(_, v)| v))
}

/// Refuses octant fields that another sweep wrote than the distance field's: a distance
/// with an id needs octants with the same one (`umbra sweep --sdf-only` leaves older octants
/// beside a new distance).
fn check_pair(distance: &Path, octants: &Path) -> Result<(), String> {
    let Some(d) = sweep_id_of(distance)? else {
        return Ok(());
    };
    match sweep_id_of(octants)? {
        Some(o) if o == d => Ok(()),
        o => Err(format!(
            "{}: these octant fields come from another umbra sweep than the distance field {} \
             ({SWEEP_KEY} {} against {d}; a sweep with --sdf-only writes no octants): sweep \
             again without --sdf-only, or name the matching octants",
            octants.display(),
            distance.display(),
            o.as_deref().unwrap_or("missing"),
        )),
    }
}

/// Reads octant fields written by [`write_octants`].
pub fn read_octants(path: &Path, dims: [usize; 3]) -> Result<OctantFields, String> {
    let v = volume::load(path).map_err(|e| e.to_string())?;
    if v.dims != dims {
        return Err(format!(
            "{}: octant grid {:?} does not match the volume's {:?}",
            path.display(),
            v.dims,
            dims
        ));
    }
    if v.fields.len() != 8 || v.fields.iter().any(|f| f.components != 1) {
        return Err(format!(
            "{}: expected 8 octant fields (a 4-D NRRD with a list axis of 8), found {}",
            path.display(),
            v.fields.len()
        ));
    }
    let octants: [Vec<u8>; 8] = std::array::from_fn(|s| {
        v.fields[s]
            .data
            .iter()
            .map(|&x| x.clamp(0.0, 255.0) as u8)
            .collect()
    });
    Ok(OctantFields { dims, octants })
}

/// Runs `umbra sweep`; `stage` hears the name of each stage as it starts.
pub fn run(args: &SweepArgs, stage: &dyn Fn(&str)) -> Result<SweepSummary, String> {
    let t0 = Instant::now();
    // Settings and every output path before any work (a bad octants path left the distance
    // file written).
    let dopts = DistanceOptions {
        iso: args.iso,
        inside: args.inside,
        init: args.init,
        method: args.method,
        tolerance: args.tolerance,
        ..Default::default()
    };
    dopts.check()?;
    let oopts = OcclusionOptions {
        subsurface_alpha: args.subsurface_alpha,
    };
    oopts.check()?;
    let octants_path = (!args.sdf_only).then(|| {
        args.octants_out
            .clone()
            .unwrap_or_else(|| default_octants_path(&args.output))
    });
    for p in std::iter::once(&args.output).chain(octants_path.as_ref()) {
        if !p.to_string_lossy().to_ascii_lowercase().ends_with(".nrrd") {
            return Err(format!(
                "{}: umbra sweep writes NRRD files; name the output .nrrd",
                p.display()
            ));
        }
    }
    volume::check_outputs(&[Some(args.output.as_path()), octants_path.as_deref()])?;
    volume::check_not_input(
        &[Some(args.input.as_path())],
        &[Some(args.output.as_path()), octants_path.as_deref()],
    )?;
    let id = sweep_id(args);
    stage("reading");
    let mut vol = volume::load(&args.input).map_err(|e| e.to_string())?;
    let values = scalar_field(
        &vol,
        args.field.as_ref(),
        args.iso,
        args.inside,
        &args.input,
    )?;
    // Only the grid's frame is needed from here on: the volume's own copy of the samples goes,
    // and the selected samples go after the classification (peak memory, docs/benchmarks.md).
    vol.fields = Vec::new();
    let mut warnings: Vec<String> = vol.warnings.clone();
    let t_read = t0.elapsed().as_secs_f64();
    stage("sweeping distance and octants");
    let sp = vol.spacing();
    let spacing = [sp[0] as f32, sp[1] as f32, sp[2] as f32];
    let t1 = Instant::now();
    let init = classify_and_initialise_owned(values, vol.dims, spacing, &dopts);
    let (df, oct) = fields_from_band(init, &dopts, &oopts, !args.sdf_only);
    let t_compute = t1.elapsed().as_secs_f64();
    if df.nan_count > 0 {
        warnings.push(format!(
            "{} NaN samples were treated as outside the surface",
            df.nan_count
        ));
    }
    if !df.converged {
        warnings.push(format!(
            "the distance sweeps did not converge in {} rounds",
            df.iterations
        ));
    }
    stage("writing");
    let t2 = Instant::now();
    let tag = SweepTag {
        id,
        level: level_tag(args.iso, args.inside),
        subsurface: args.subsurface_alpha,
    };
    let oct_path = match (&oct, args.sdf_only) {
        (Some(o), false) => {
            // Both files or neither (a failure leaves an earlier run's pair as it was).
            let p = octants_path.clone().unwrap_or_default();
            volume::write_pair(
                &args.output,
                |staged| write_distance(staged, &vol, &df, &tag),
                || write_octants(&p, &vol, o, &tag),
            )?;
            Some(p)
        }
        _ => {
            write_distance(&args.output, &vol, &df, &tag)?;
            None
        }
    };
    let t_write = t2.elapsed().as_secs_f64();
    Ok(SweepSummary {
        dims: vol.dims,
        distance_method: match args.method {
            DistanceMethod::ClosestPoint => "closest-point",
            DistanceMethod::Sweeping => "sweeping",
        },
        iterations: df.iterations,
        converged: df.converged,
        seconds: Seconds {
            read: t_read,
            compute: t_compute,
            write: t_write,
            total: t0.elapsed().as_secs_f64(),
        },
        peak_bytes: peak_bytes(),
        band_voxels: df.band,
        nan_voxels: df.nan_count,
        distance: args.output.clone(),
        octants: oct_path,
        warnings,
    })
}

/// The distance field and (when `need_octants`) the eight octant visibilities of an
/// isosurface: read from `fields` (the octants from `octants` or beside it) when given, else
/// swept in memory. The octants describe the solid cut by the clipping planes `cut` (each
/// keeping `normal . p <= offset`; `volume::occlusion_sweep::open_cut`): swept in memory with
/// the cut, or, read from files, swept again from the distance field where a plane reaches the
/// grid (with the subsurface opacity the octants file records, [`SUBSURFACE_KEY`]).
#[allow(clippy::too_many_arguments)]
pub fn iso_fields(
    vol: &volume::Volume,
    values: &[f32],
    iso: f32,
    inside: Inside,
    fields: Option<&std::path::Path>,
    octants: Option<&std::path::Path>,
    need_octants: bool,
    subsurface_alpha: Option<f32>,
    cut: &[([f64; 3], f64)],
) -> Result<(Vec<f32>, Option<volume::occlusion_sweep::OctantFields>), String> {
    match fields {
        Some(p) => {
            check_level(p, iso, inside)?;
            let d = volume::load(p).map_err(|e| e.to_string())?;
            if d.dims != vol.dims || d.fields[0].components != 1 {
                return Err(format!(
                    "{}: distance grid {:?} does not match the volume's {:?}",
                    p.display(),
                    d.dims,
                    vol.dims
                ));
            }
            let oct = if need_octants {
                let op = octants
                    .map(|o| o.to_path_buf())
                    .unwrap_or_else(|| default_octants_path(p));
                check_pair(p, &op)?;
                let alpha = subsurface_of(&op)?;
                let distance = &d.fields[0].data;
                let mut tau = volume::occlusion_sweep::transmittance_from_distance(
                    distance,
                    vol.spacing(),
                    alpha,
                );
                if volume::occlusion_sweep::open_cut(&mut tau, vol.dims, &vol.affine, cut) {
                    Some(volume::occlusion_sweep::sweep_octants(&tau, vol.dims))
                } else {
                    Some(read_octants(&op, vol.dims)?)
                }
            } else {
                None
            };
            Ok((d.fields[0].data.clone(), oct))
        }
        None => {
            let sp = vol.spacing();
            let dopts = DistanceOptions {
                iso,
                inside,
                ..Default::default()
            };
            dopts.check()?;
            OcclusionOptions { subsurface_alpha }.check()?;
            let spacing = [sp[0] as f32, sp[1] as f32, sp[2] as f32];
            let init =
                volume::distance_sweep::classify_and_initialise(values, vol.dims, spacing, &dopts);
            let (df, oct) = volume::occlusion_sweep::fields_from_band_cut(
                init,
                &dopts,
                &OcclusionOptions { subsurface_alpha },
                need_octants,
                (!cut.is_empty()).then_some((&vol.affine, cut)),
            );
            Ok((df.distance, oct))
        }
    }
}
