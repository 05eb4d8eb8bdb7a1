//! `umbra tracts select`: streamlines kept by include/exclude ROIs (spheres, boxes, masks),
//! length and attribute ranges and a seeded subsample (`tubes::select`, built by
//! `scene::tube_sets::selection` from the same keys a scene's `select` has), written in the
//! format of the output's extension with their attributes. `umbra tracts merge`: several
//! tractograms into one (`tubes::Streamlines::append`).

use crate::output::out_json;
use scene::spec::SelectSpec;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand)]
enum Command {
    /// Keep the streamlines that every include ROI holds a point of and no exclude ROI
    /// does, within the length and attribute ranges; world coordinates (RAS+ mm, as `umbra
    /// info` reports them).
    Select(Box<SelectArgs>),
    /// Merge tractograms into one (e.g. an atlas's bundles into a whole-brain set), each
    /// optionally moved by --transform first.
    Merge(MergeArgs),
}

#[derive(clap::Args)]
struct MergeArgs {
    /// Input tractograms (.trk, .tck, .vtk, .trx, optionally .gz), in order.
    #[arg(required = true, num_args = 1..)]
    inputs: Vec<PathBuf>,
    /// Output tractogram (.trk, .tck, .trx, optionally .gz for .trk/.tck).
    #[arg(short, long)]
    output: PathBuf,
    /// Row-major 4x4 transform applied to every input's points, as 16 comma-separated numbers.
    #[arg(long, allow_hyphen_values = true, value_parser = numbers::<16>)]
    transform: Option<[f64; 16]>,
}

#[derive(clap::Args)]
struct SelectArgs {
    /// Input tractogram (.trk, .tck, .vtk, .trx, optionally .gz).
    input: PathBuf,
    /// Output tractogram (.trk, .tck, .trx, optionally .gz for .trk/.tck).
    #[arg(short, long)]
    output: PathBuf,
    /// A sphere X,Y,Z,R each kept streamline has a point in (repeatable).
    #[arg(long, value_name = "X,Y,Z,R", allow_hyphen_values = true, value_parser = numbers::<4>)]
    include_sphere: Vec<[f64; 4]>,
    /// A sphere no point of a kept streamline is in (repeatable).
    #[arg(long, value_name = "X,Y,Z,R", allow_hyphen_values = true, value_parser = numbers::<4>)]
    exclude_sphere: Vec<[f64; 4]>,
    /// A box of two opposite corners X0,Y0,Z0,X1,Y1,Z1 (repeatable).
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", allow_hyphen_values = true, value_parser = numbers::<6>)]
    include_box: Vec<[f64; 6]>,
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", allow_hyphen_values = true, value_parser = numbers::<6>)]
    exclude_box: Vec<[f64; 6]>,
    /// A mask volume: its nonzero voxels, or those equal to LABEL (repeatable).
    #[arg(long, value_name = "FILE[:LABEL]")]
    include_mask: Vec<String>,
    #[arg(long, value_name = "FILE[:LABEL]")]
    exclude_mask: Vec<String>,
    /// Shortest arc length kept (world units, inclusive).
    #[arg(long, value_name = "L")]
    min_length: Option<f64>,
    /// Longest arc length kept (world units, inclusive).
    #[arg(long, value_name = "L")]
    max_length: Option<f64>,
    /// A per-streamline attribute (or a per-point one's mean over the streamline) to keep
    /// within --min/--max.
    #[arg(long, value_name = "NAME")]
    attribute: Option<String>,
    /// Smallest attribute value kept (with --attribute).
    #[arg(
        long,
        value_name = "V",
        allow_hyphen_values = true,
        requires = "attribute"
    )]
    min: Option<f64>,
    /// Largest attribute value kept (with --attribute).
    #[arg(
        long,
        value_name = "V",
        allow_hyphen_values = true,
        requires = "attribute"
    )]
    max: Option<f64>,
    /// Keep N of the streamlines that pass, chosen at random (the same for the same --seed).
    #[arg(long, value_name = "N")]
    subsample: Option<usize>,
    /// The seed of --subsample.
    #[arg(long, default_value_t = 0, value_name = "S")]
    seed: u64,
    /// Row-major 4x4 transform applied to the points before the selection, as 16
    /// comma-separated numbers (as `umbra tubes --transform` and a scene's `transform`); the
    /// output holds the transformed points.
    #[arg(long, allow_hyphen_values = true, value_parser = numbers::<16>)]
    transform: Option<[f64; 16]>,
    /// Print the summary as one JSON object on standard output.
    #[arg(long)]
    json: bool,
}

/// N comma-separated finite numbers.
fn numbers<const N: usize>(s: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| {
            x.trim()
                .parse::<f64>()
                .map_err(|_| format!("'{}' is not a number", x.trim()))
        })
        .collect::<Result<_, _>>()?;
    let a: [f64; N] = v.try_into().map_err(|v: Vec<f64>| {
        format!("expected {N} comma-separated numbers, found {}", v.len())
    })?;
    if a.iter().any(|x| !x.is_finite()) {
        return Err("the numbers must be finite".into());
    }
    Ok(a)
}

pub fn run(a: Args) -> Result<(), String> {
    match a.command {
        Command::Select(s) => select(*s),
        Command::Merge(m) => merge(m),
    }
}

/// The output's format before the work (what `tubes::save` writes).
fn check_format(output: &std::path::Path) -> Result<(), String> {
    let name = output.to_string_lossy().to_ascii_lowercase();
    let stem = name.strip_suffix(".gz").unwrap_or(&name);
    if !(stem.ends_with(".trk") || stem.ends_with(".tck") || name.ends_with(".trx")) {
        return Err(format!(
            "{}: the output must be .trk, .tck (optionally .gz) or .trx",
            output.display()
        ));
    }
    Ok(())
}

fn merge(a: MergeArgs) -> Result<(), String> {
    check_format(&a.output)?;
    let matrix = a
        .transform
        .map(|m| scene::tube_sets::transform_matrix(&m, "--transform"))
        .transpose()?;
    volume::check_output(&a.output)?;
    let inputs: Vec<Option<&std::path::Path>> =
        a.inputs.iter().map(|p| Some(p.as_path())).collect();
    volume::check_not_input(&inputs, &[Some(a.output.as_path())])?;
    let mut all = tubes::Streamlines::new();
    let mut dropped: Vec<String> = vec![];
    for p in &a.inputs {
        let mut s = tubes::load(p).map_err(|e| e.to_string())?;
        for w in &s.warnings {
            eprintln!("umbra: warning: {}: {w}", p.display());
        }
        if let Some(m) = &matrix {
            s.transform(m);
        }
        for d in all.append(&s) {
            if !dropped.contains(&d) {
                dropped.push(d);
            }
        }
    }
    all.warnings.clear();
    tubes::save(&a.output, &all).map_err(|e| e.to_string())?;
    if !dropped.is_empty() {
        eprintln!(
            "umbra: note: attributes not in every input were left out: {}",
            dropped.join(", ")
        );
    }
    if let Some(note) = super::tck_drops_note(&a.output, &all) {
        eprintln!("umbra: note: {note}");
    }
    eprintln!(
        "merged {} tractograms: {} streamlines, {} points; wrote {}",
        a.inputs.len(),
        all.len(),
        all.points.len(),
        a.output.display()
    );
    Ok(())
}

fn select(a: SelectArgs) -> Result<(), String> {
    let spec = SelectSpec {
        include_spheres: a.include_sphere,
        exclude_spheres: a.exclude_sphere,
        include_boxes: a.include_box,
        exclude_boxes: a.exclude_box,
        include_masks: a.include_mask,
        exclude_masks: a.exclude_mask,
        min_length: a.min_length,
        max_length: a.max_length,
        attribute: a.attribute,
        attribute_min: a.min,
        attribute_max: a.max,
        subsample: a.subsample,
        seed: a.seed,
    };
    // A key of the selection as the flag that gives it.
    let flag = |k: &str| match k {
        "" => "umbra tracts select".to_string(),
        "attribute" => "--attribute".to_string(),
        "include_boxes" => "--include-box".to_string(),
        "exclude_boxes" => "--exclude-box".to_string(),
        // include_spheres -> --include-sphere, include_masks -> --include-mask, ...
        k => format!("--{}", k.trim_end_matches('s').replace('_', "-")),
    };
    let sel = scene::tube_sets::selection(&spec, &flag, true)?;
    check_format(&a.output)?;
    volume::check_output(&a.output)?;
    volume::check_not_input(&[Some(a.input.as_path())], &[Some(a.output.as_path())])?;
    let matrix = a
        .transform
        .map(|m| scene::tube_sets::transform_matrix(&m, "--transform"))
        .transpose()?;
    let mut s = tubes::load(&a.input).map_err(|e| e.to_string())?;
    for w in &s.warnings {
        eprintln!("umbra: warning: {}: {w}", a.input.display());
    }
    if let Some(m) = &matrix {
        s.transform(m);
        // The input's grid no longer describes the moved points (a .trk or .trx header would
        // place them by it).
        s.reference = None;
    }
    let (out, sum) = sel
        .apply(&s)
        .map_err(|e| format!("{}: {e}", a.input.display()))?;
    tubes::save(&a.output, &out).map_err(|e| e.to_string())?;
    if let Some(note) = super::tck_drops_note(&a.output, &out) {
        eprintln!("umbra: note: {note}");
    }
    if a.json {
        out_json(&sum)?;
    }
    eprintln!(
        "kept {} of {} streamlines ({} missed an include ROI, {} touched an exclude ROI, {} outside the length range, {} outside the attribute range, {} left out by the subsample); wrote {}",
        sum.kept,
        sum.total,
        sum.by_include,
        sum.by_exclude,
        sum.by_length,
        sum.by_attribute,
        sum.by_subsample,
        a.output.display()
    );
    if sum.kept == 0 && sum.total > 0 {
        // Where the points are: ROIs in another frame (an atlas bundle outside MNI space, a
        // mask in the other frame) miss them all.
        let span = s
            .bounds()
            .map(|[lo, hi]| {
                format!(
                    " (its points span ({:.1}, {:.1}, {:.1}) to ({:.1}, {:.1}, {:.1}){}; ROIs \
                     and masks are in the same world coordinates - a tractogram in another \
                     frame needs --transform)",
                    lo.x,
                    lo.y,
                    lo.z,
                    hi.x,
                    hi.y,
                    hi.z,
                    if matrix.is_some() {
                        " after --transform"
                    } else {
                        ""
                    }
                )
            })
            .unwrap_or_default();
        eprintln!("umbra: warning: the selection kept no streamline{span}; the output holds none");
    }
    Ok(())
}
