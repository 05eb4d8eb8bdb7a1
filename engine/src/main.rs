//! The `umbra` command line: parses arguments and calls the engine library.

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;
use volume::FieldSelector;

#[derive(Parser)]
#[command(name = "umbra", version, about = "Volumes with tubes and lines, shaded with occlusion", long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Hemisphere ambient occlusion of a scene's tubes (Monte Carlo, the reference for the
    /// cross-check with Mitsuba 3 in bench/mitsuba_ao.py): <out>/ao.exr, tubes.ply, camera.json.
    Ao {
        scene: PathBuf,
        #[arg(long, default_value_t = 1024)]
        spp: u32,
        /// Only tubes this near occlude (world units; default: any distance).
        #[arg(long)]
        max_distance: Option<f64>,
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Stream tubes' cost against accuracy: control points, triangles, largest deviation and
    /// meshing time per fitting tolerance: <out>/tubes.csv and a chart.
    Tubes {
        /// Tractogram.
        input: PathBuf,
        #[arg(long, default_value = "0.005,0.01,0.02,0.05,0.1,0.2")]
        tolerances: String,
        #[arg(long, default_value_t = 0.5)]
        radius: f64,
        /// Meshing runs per tolerance (the median is reported).
        #[arg(long, default_value_t = 3)]
        runs: usize,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Occlusion sweeping against Monte Carlo AO on the validation scene over grid sizes:
    /// <out>/sweep.csv and a chart.
    Sweep {
        #[arg(long, default_value = "32,64,128")]
        sizes: String,
        /// Flat-face offsets c (comma-separated).
        #[arg(long, default_value = "1.5")]
        offsets: String,
        /// Geometry terms: cosine (AO, against cosine-weighted rays), constant (scalar AO,
        /// against uniform-sphere visibility).
        #[arg(long, default_value = "cosine")]
        geometry: String,
        /// Monte Carlo rays per pixel of the reference.
        #[arg(long, default_value_t = 256)]
        spp: usize,
        /// Image size (square).
        #[arg(long, default_value_t = 128)]
        size: usize,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Scenes built to make the volume methods fail (a sheet thinner than the slices, grazing
    /// views, very few slices, cone angles near 0 and 80 degrees, zooming, turning in small
    /// steps), each against the Monte Carlo reference: <out>/stability.csv with verdicts.
    Stability {
        /// Monte Carlo paths per pixel of the references.
        #[arg(long, default_value_t = 256)]
        reference_spp: u32,
        #[arg(long, default_value_t = 1)]
        frames: u32,
        #[arg(short, long)]
        output: PathBuf,
    },
    /// Every method at every combination of the swept settings, timed and compared with the
    /// Monte Carlo reference of the same light model (cached): <out>/results.csv,
    /// <out>/pareto.svg and .png. Images are 128 x 128 unless --set says otherwise.
    Accuracy {
        /// Scene file (without tubes: the reference does not model them yet).
        scene: PathBuf,
        /// KEY=V1,V2,... (repeatable): slices, cone (degrees), a render.* key by name, or a
        /// dotted scene key.
        #[arg(long = "sweep", value_name = "KEY=VALUES")]
        sweeps: Vec<String>,
        /// Methods, comma-separated.
        #[arg(long, default_value = "combined,dos,vicinity,ea")]
        methods: String,
        /// Monte Carlo paths per pixel of the reference.
        #[arg(long, default_value_t = 256)]
        reference_spp: u32,
        /// Frames timed per configuration (the median is its time).
        #[arg(long, default_value_t = 3)]
        frames: u32,
        /// Override a scene key by its dotted path (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Output folder.
        #[arg(short, long)]
        output: PathBuf,
    },
}

#[derive(Subcommand)]
enum Command {
    /// Describe a volume file (format, grid, world frame, value range), or the GPU with --gpu.
    Info {
        /// Volume file (.nii, .nii.gz, .hdr, .nrrd, .nhdr, .vtk, .vti, .mhd, .mha, .slc) or
        /// tractogram (.trk, .tck, optionally .gz).
        file: Option<PathBuf>,
        /// Print one JSON object instead of text.
        #[arg(long)]
        json: bool,
        /// Field to describe: NAME, NAME:magnitude or NAME:x|y|z (default: the file's active array).
        #[arg(long)]
        field: Option<String>,
        /// Describe the GPU adapter and run the GPU smoke check instead of reading a file.
        #[arg(long)]
        gpu: bool,
        /// PLOT3D solution (q) file, for a PLOT3D grid.
        #[arg(long)]
        q: Option<PathBuf>,
    },
    /// Signed distance and eight octant occlusion fields of an isosurface (fast sweeping).
    Sweep {
        /// Input volume (any format `umbra info` reads).
        input: PathBuf,
        /// Iso level.
        #[arg(long, allow_hyphen_values = true)]
        iso: f32,
        /// Output distance field: 3-D float32 NRRD, world units, negative inside.
        #[arg(short, long)]
        output: PathBuf,
        /// Output octant fields: 4-D uint8 NRRD, first axis the 8 octants in Table 1 order
        /// (default: <stem>.octants.nrrd beside the distance file).
        #[arg(long)]
        octants_out: Option<PathBuf>,
        /// Which side is inside (negative distance): values above (>=) or below (<=) the level.
        #[arg(long, value_enum, default_value = "above")]
        inside: InsideArg,
        /// Field to use: NAME or NAME:magnitude.
        #[arg(long)]
        field: Option<String>,
        /// Write only the distance field.
        #[arg(long)]
        sdf_only: bool,
        /// Initial distances next to the surface: gradient (default), plane, or edge (the paper).
        #[arg(long, default_value = "gradient")]
        init: String,
        /// Convergence tolerance of the distance sweeps, in voxels.
        #[arg(long, default_value_t = 1e-3)]
        tolerance: f32,
        /// Subsurface variant: per-voxel opacity alpha in [0, 1] for the octant sweeps.
        #[arg(long)]
        subsurface: Option<f32>,
        /// Print the summary as one JSON object on standard output.
        #[arg(long)]
        json: bool,
    },
    /// Render an isosurface on the CPU with swept or Monte Carlo ambient occlusion (reference).
    Iso {
        /// Input volume.
        input: PathBuf,
        /// Iso level.
        #[arg(long, allow_hyphen_values = true)]
        iso: f32,
        /// Distance field from `umbra sweep` (octants beside it); computed when absent.
        #[arg(long)]
        fields: Option<PathBuf>,
        /// Octant fields, when not at <stem>.octants.nrrd beside --fields.
        #[arg(long)]
        octants: Option<PathBuf>,
        /// Output PNG (8-bit sRGB).
        #[arg(short, long)]
        output: PathBuf,
        #[arg(long, default_value_t = 512)]
        width: usize,
        #[arg(long, default_value_t = 512)]
        height: usize,
        /// Degrees; 0 looks along +y, 90 along +x.
        #[arg(long, default_value_t = 30.0, allow_hyphen_values = true)]
        azimuth: f64,
        /// Degrees; 90 looks down from +z.
        #[arg(long, default_value_t = 30.0, allow_hyphen_values = true)]
        elevation: f64,
        /// Camera distance in multiples of the bounding-sphere radius.
        #[arg(long, default_value_t = 3.0)]
        distance: f64,
        /// Shade with Monte Carlo ambient occlusion from N rays per pixel instead.
        #[arg(long)]
        reference_ao: Option<usize>,
        /// With --reference-ao: uniform-sphere visibility (the reference for --geometry none).
        #[arg(long)]
        uniform: bool,
        /// No occlusion at all (local illumination).
        #[arg(long)]
        local: bool,
        /// Geometry term: cosine (eq. 4-5), none (scalar AO) or abs (subsurface, |N.w|).
        #[arg(long, default_value = "cosine")]
        geometry: String,
        /// Octants that light the scene: uniform, overcast, or octant:1..8.
        #[arg(long, default_value = "uniform")]
        sky: String,
        /// Gamma applied to the ambient term (A^(1/gamma)).
        #[arg(long, default_value_t = 1.0)]
        gamma: f64,
        /// Flat-face correction: look the octants up at P + c h N.
        #[arg(long, default_value_t = volume::occlusion_shading::DEFAULT_OFFSET)]
        offset: f64,
        /// Subsurface opacity for the octant sweeps computed in memory.
        #[arg(long)]
        subsurface: Option<f32>,
        /// Add a Phong head light.
        #[arg(long)]
        phong: bool,
        #[arg(long, value_enum, default_value = "above")]
        inside: InsideArg,
        #[arg(long)]
        field: Option<String>,
        /// Print statistics as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Trace streamlines through a vector field (3-component volume) into .tck or .trk.
    Trace {
        /// Vector field: any volume with a 3-component array (NIfTI V1, VTK vectors, ...).
        input: PathBuf,
        /// Output tractogram (.tck or .trk).
        #[arg(short, long)]
        output: PathBuf,
        /// The vector array, by name.
        #[arg(long)]
        field: Option<String>,
        /// Seeds: grid:N, random:N, plane:x=VALUE:N (also y, z), or a CSV file of x,y,z.
        #[arg(long, default_value = "grid:10")]
        seeds: String,
        /// Step in world units (default: half the smallest voxel spacing).
        #[arg(long)]
        step: Option<f64>,
        /// Integrator: rk4, rk45 (adaptive) or euler.
        #[arg(long, default_value = "rk4")]
        integrator: String,
        /// RK45 local error bound (world units).
        #[arg(long, default_value_t = 1e-3)]
        tolerance: f64,
        /// Longest streamline (world units; default: twice the grid's diagonal).
        #[arg(long)]
        max_length: Option<f64>,
        /// Stop where the field's magnitude falls below this.
        #[arg(long, default_value_t = 1e-6)]
        min_speed: f64,
        /// Stop where this scalar volume (e.g. FA) falls below --threshold.
        #[arg(long)]
        mask: Option<PathBuf>,
        #[arg(long, default_value_t = 0.2)]
        threshold: f64,
        /// Stop where the direction turns by more than this many degrees in one step.
        #[arg(long, default_value_t = 60.0)]
        max_angle: f64,
        /// The field is an eigenvector field (no sign): orient it along the direction of travel.
        #[arg(long)]
        eigen: bool,
        /// Trace forward only (default: both ways from each seed).
        #[arg(long)]
        one_way: bool,
    },
    /// B-spline stream tubes of a tractogram (.trk, .tck), written as PLY or OBJ.
    Tubes {
        /// Input tractogram.
        input: PathBuf,
        /// Output mesh: .ply (binary) or .obj.
        #[arg(short, long)]
        output: PathBuf,
        /// Tube radius (world units).
        #[arg(long, default_value_t = 0.5)]
        radius: f64,
        /// Sides of a ring.
        #[arg(long, default_value_t = 8)]
        sides: usize,
        /// Rings per B-spline span before adaptive refinement (spans are bisected until the
        /// tangent turns by at most 15 degrees between rings).
        #[arg(long, default_value_t = 1)]
        per_span: usize,
        /// Largest distance of an input point to the fitted curve (world units).
        #[arg(long, default_value_t = 0.05)]
        tolerance: f64,
        /// Error-bounded tessellation: sides and ring spacing from this chordal tolerance.
        #[arg(long)]
        chordal: Option<f64>,
        /// Curve fit: iterative (the paper's), least-squares, or none.
        #[arg(long, default_value = "iterative")]
        fit: String,
        /// Frames: rmf (rotation minimizing) or frenet (with flip correction).
        #[arg(long, default_value = "rmf")]
        frame: String,
        /// Radius limit: local (per ring, below 1/curvature) or global (the paper's 1/kappa_max).
        #[arg(long, default_value = "local")]
        radius_mode: String,
        /// Colour: direction, scalar:NAME, volume:PATH, or #rrggbb.
        #[arg(long, default_value = "direction")]
        color: String,
        /// Close the tube ends.
        #[arg(long)]
        caps: bool,
        /// Row-major 4x4 transform applied to the points, as 16 comma-separated numbers.
        #[arg(long, allow_hyphen_values = true)]
        transform: Option<String>,
        /// Write the statistics as JSON to this file.
        #[arg(long)]
        stats_json: Option<PathBuf>,
    },
    /// Write a synthetic scene as NRRD: validation (the sweeping paper's solids, [0,100]^3),
    /// three-solids (sphere, torus, box in [0,1]^3), abc, burgers, rotation (vector fields).
    Synth {
        scene: String,
        #[arg(short, long)]
        output: PathBuf,
        /// Samples per axis.
        #[arg(long, default_value_t = 100)]
        n: usize,
    },
    /// Write a volume's field as NRRD (.nrrd) or NIfTI-1 (.nii, .nii.gz).
    Convert {
        /// Input volume.
        input: PathBuf,
        /// Output file; the format follows the extension.
        #[arg(short, long)]
        output: PathBuf,
        /// Field to write: NAME, NAME:magnitude or NAME:x|y|z.
        #[arg(long)]
        field: Option<String>,
        /// Gzip-encode NRRD output.
        #[arg(long)]
        gzip: bool,
    },
    /// Render a scene file on the GPU: volume and tubes with combined occlusion (or the
    /// dos, vicinity, ea, phong baselines) to PNG (sRGB) or EXR (linear RGBA, --aov layers).
    Render {
        /// Scene file (see `umbra scene` and the README).
        scene: PathBuf,
        /// Output image: .png (8-bit sRGB) or .exr (linear float RGBA).
        #[arg(short, long)]
        output: PathBuf,
        /// Image width (render.width).
        #[arg(long)]
        width: Option<u32>,
        /// Image height (render.height).
        #[arg(long)]
        height: Option<u32>,
        /// combined, dos, vicinity, ea or phong (render.method).
        #[arg(long)]
        method: Option<String>,
        /// Render each image this many times, every pass re-run (total_ms is the median);
        /// more than 1 also times each pass.
        #[arg(long, default_value_t = 1)]
        frames: u32,
        /// Write the timings (total_ms, passes, each frame's) as JSON to this file; also times
        /// each pass.
        #[arg(long)]
        timings_json: Option<PathBuf>,
        /// Render a turntable of N frames: frame k at camera.azimuth + k 360/N (a look-at
        /// camera turns its eye about the target around up). The output name's run of #
        /// becomes k, zero-padded.
        #[arg(long, value_name = "N", conflicts_with = "camera_path")]
        orbit: Option<u32>,
        /// Render the keyframed cameras of this TOML file (see the README, "Turntables and
        /// camera paths"); the output name needs a run of # as with --orbit.
        #[arg(long, value_name = "FILE")]
        camera_path: Option<PathBuf>,
        /// Add the AOV channels to the EXR: volumetric, partial, vicinity and combined
        /// occlusion, linear depth (Z).
        #[arg(long)]
        aov: bool,
        /// Override a scene key by its dotted path (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
    /// Benchmarks: `umbra bench accuracy` (every method against the Monte Carlo ground truth,
    /// error against time, results.csv and a Pareto chart).
    Bench {
        #[command(subcommand)]
        what: BenchCommand,
    },
    /// Render a bundled demo scene by the combined method: `mni` (the MNI T1 template with
    /// HCP1065 tracts; the default) or `cfd` (carotid flow with traced streamlines).
    Demo {
        /// mni or cfd.
        #[arg(default_value = "mni")]
        which: String,
        /// Output image (.png or .exr).
        #[arg(short, long, default_value = "demo.png")]
        output: PathBuf,
        #[arg(long)]
        width: Option<u32>,
        #[arg(long)]
        height: Option<u32>,
        /// combined, dos, vicinity, ea or phong.
        #[arg(long)]
        method: Option<String>,
        /// Frames timed; total_ms is their median.
        #[arg(long, default_value_t = 1)]
        frames: u32,
        /// Override a scene key by its dotted path (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
    },
    /// Check a scene file (TOML) and print it resolved, with defaults and --set overrides, as
    /// JSON (the renderer of issue 5 reads the same files).
    Scene {
        /// Scene file.
        file: PathBuf,
        /// Override a key by its dotted path, e.g. --set render.width=640 (repeatable).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
    },
    /// Resample a CFD grid (.vtr, .vts, .vtu, legacy .vtk STRUCTURED_GRID/RECTILINEAR_GRID,
    /// PLOT3D) onto a regular grid; samples outside the mesh are NaN.
    Resample {
        /// Grid file; any name other than .vtr/.vts/.vtu/.vtk is read as a PLOT3D grid.
        input: PathBuf,
        /// PLOT3D solution (q) file: gives density, momentum, energy, velocity, pressure.
        #[arg(long)]
        q: Option<PathBuf>,
        /// Array: NAME, NAME:magnitude, NAME:x|y|z, or three scalars A,B,C assembled into a
        /// vector (e.g. "X Velocity,Y Velocity,Z Velocity").
        #[arg(long)]
        field: String,
        /// Output dimensions NX,NY,NZ (default: --size on the longest side, equal spacing).
        #[arg(long, value_parser = parse_dims)]
        dims: Option<[usize; 3]>,
        /// Samples along the longest side when --dims is not given.
        #[arg(long, default_value_t = 128)]
        size: usize,
        /// Output volume (.nrrd, .nii, .nii.gz).
        #[arg(short, long)]
        output: PathBuf,
        /// Gzip-encode NRRD output.
        #[arg(long)]
        gzip: bool,
        /// Print the report as JSON.
        #[arg(long)]
        json: bool,
    },
}

/// Prints `umbra info`'s answer: the JSON object, or the text for a person.
fn print_info(
    json: bool,
    value: serde_json::Value,
    text: impl FnOnce() -> Result<String, String>,
) -> Result<(), String> {
    if json {
        println!(
            "{}",
            serde_json::to_string(&value).map_err(|e| e.to_string())?
        );
    } else {
        print!("{}", text()?);
    }
    Ok(())
}

fn parse_dims(s: &str) -> Result<[usize; 3], String> {
    let v: Vec<usize> = s
        .split(',')
        .map(|t| t.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("'{s}' is not NX,NY,NZ"))?;
    match v.as_slice() {
        &[x, y, z] if x > 0 && y > 0 && z > 0 => Ok([x, y, z]),
        _ => Err(format!("'{s}' is not three positive integers NX,NY,NZ")),
    }
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
enum InsideArg {
    Above,
    Below,
}

impl From<InsideArg> for volume::distance_sweep::Inside {
    fn from(a: InsideArg) -> Self {
        match a {
            InsideArg::Above => volume::distance_sweep::Inside::Above,
            InsideArg::Below => volume::distance_sweep::Inside::Below,
        }
    }
}

fn parse_field(s: &Option<String>) -> Result<Option<FieldSelector>, String> {
    s.as_deref()
        .map(|s| s.parse::<FieldSelector>().map_err(|e| e.to_string()))
        .transpose()
}

fn run(cli: Cli) -> Result<(), String> {
    match cli.command {
        Command::Info {
            file,
            json,
            field,
            gpu,
            q,
        } => {
            if gpu {
                let g = engine::gpu::Gpu::new().map_err(|e| e.to_string())?;
                let report = g.report();
                let smoke = engine::smoke::run(&g, 8).map_err(|e| e.to_string())?;
                if json {
                    let v = serde_json::json!({"adapter": report, "smoke": smoke});
                    println!("{}", serde_json::to_string_pretty(&v).unwrap());
                } else {
                    println!("{report}");
                    if let Some(note) = &smoke.msaa_note {
                        println!("note:               {note}");
                    }
                    println!(
                        "smoke check:        passed (compute {} values, render {}x{} at {}x MSAA)",
                        smoke.compute_values_checked,
                        smoke.render_size[0],
                        smoke.render_size[1],
                        smoke.sample_count
                    );
                }
                return Ok(());
            }
            let file = file.ok_or("umbra info: give a file, or --gpu")?;
            let name = file.display().to_string();
            let warn = |ws: &[String]| {
                ws.iter()
                    .for_each(|w| eprintln!("umbra: warning: {name}: {w}"))
            };
            if tubes::is_tractogram(&file) {
                let s = tubes::load(&file).map_err(|e| e.to_string())?;
                warn(&s.warnings);
                return print_info(json, engine::info::tractogram_json(&s), || {
                    Ok(engine::info::tractogram_text(&name, &s))
                });
            }
            // CFD grids: by name, or PLOT3D (no signature) when --q is given or the file is no
            // volume but parses as a PLOT3D grid.
            let (grid, warnings) = if volume::is_grid(&file) || q.is_some() {
                volume::load_grid(&file, q.as_deref()).map_err(|e| e.to_string())?
            } else {
                match volume::load(&file) {
                    Ok(vol) => {
                        warn(&vol.warnings);
                        let sel = parse_field(&field)?;
                        let j = engine::info::volume_json(&vol, sel.as_ref())
                            .map_err(|e| e.to_string())?;
                        return print_info(json, j, || {
                            engine::info::volume_text(&name, &vol, sel.as_ref())
                                .map_err(|e| e.to_string())
                        });
                    }
                    Err(e) => volume::plot3d::read(&file, None).map_err(|_| e.to_string())?,
                }
            };
            // Grid readers' warnings name their file themselves.
            warnings
                .iter()
                .for_each(|w| eprintln!("umbra: warning: {w}"));
            print_info(json, engine::info::grid_json(&grid), || {
                Ok(engine::info::grid_text(&name, &grid))
            })
        }
        Command::Sweep {
            input,
            iso,
            output,
            octants_out,
            inside,
            field,
            sdf_only,
            init,
            tolerance,
            subsurface,
            json,
        } => {
            use std::io::IsTerminal;
            let args = engine::sweep_cmd::SweepArgs {
                input,
                iso,
                output,
                octants_out,
                inside: inside.into(),
                field: parse_field(&field)?,
                sdf_only,
                init: init.parse()?,
                tolerance,
                subsurface_alpha: subsurface,
                progress: !json && std::io::stderr().is_terminal(),
            };
            let s = engine::sweep_cmd::run(&args)?;
            for w in &s.warnings {
                eprintln!("umbra: warning: {}: {w}", args.input.display());
            }
            if json {
                println!("{}", serde_json::to_string(&s).unwrap());
            } else {
                println!("grid:        {} x {} x {}", s.dims[0], s.dims[1], s.dims[2]);
                println!(
                    "iterations:  {} rounds of 8 sweeps ({})",
                    s.iterations,
                    if s.converged {
                        "converged"
                    } else {
                        "not converged"
                    }
                );
                println!(
                    "band:        {} voxels initialised next to the surface",
                    s.band_voxels
                );
                println!(
                    "seconds:     read {:.3}, compute {:.3}, write {:.3}, total {:.3}",
                    s.seconds.read, s.seconds.compute, s.seconds.write, s.seconds.total
                );
                if let Some(p) = s.peak_bytes {
                    println!("peak memory: {:.1} MiB", p as f64 / (1024.0 * 1024.0));
                }
                println!("distance:    {}", s.distance.display());
                if let Some(o) = &s.octants {
                    println!("octants:     {}", o.display());
                }
            }
            Ok(())
        }
        Command::Iso {
            input,
            iso,
            fields,
            octants,
            output,
            width,
            height,
            azimuth,
            elevation,
            distance,
            reference_ao,
            uniform,
            local,
            geometry,
            sky,
            gamma,
            offset,
            subsurface,
            phong,
            inside,
            field,
            json,
        } => {
            use volume::occlusion_shading::{AmbientOptions, GeometryTerm};
            let geometry: GeometryTerm = geometry
                .parse()
                .map_err(|e| format!("--geometry {geometry}: {e}"))?;
            if !(gamma.is_finite() && gamma > 0.0) {
                return Err(format!("--gamma {gamma}: must be a positive number"));
            }
            if width == 0 || height == 0 || width * height > 1 << 26 {
                return Err(format!("--width {width} --height {height}: the image must have between 1 and 2^26 pixels"));
            }
            let args = engine::iso_cmd::IsoArgs {
                input,
                iso,
                inside: inside.into(),
                field: parse_field(&field)?,
                fields,
                octants,
                output: output.clone(),
                camera: engine::iso_reference::OrbitCamera {
                    width,
                    height,
                    azimuth_deg: azimuth,
                    elevation_deg: elevation,
                    distance,
                },
                reference_ao,
                uniform,
                local,
                ambient: AmbientOptions {
                    geometry,
                    sky: sky.parse()?,
                    gamma,
                    offset,
                },
                subsurface_alpha: subsurface,
                phong,
            };
            let (_, stats) = engine::iso_cmd::render_cli(&args)?;
            if json {
                println!("{}", serde_json::to_string(&stats).unwrap());
            } else {
                eprintln!(
                    "wrote {} ({} surface pixels, mean ambient {:.3}, {:.2} s)",
                    output.display(),
                    stats.hit_pixels,
                    stats.mean_ambient,
                    stats.seconds
                );
            }
            Ok(())
        }
        Command::Trace {
            input,
            output,
            field,
            seeds,
            step,
            integrator,
            tolerance,
            max_length,
            min_speed,
            mask,
            threshold,
            max_angle,
            eigen,
            one_way,
        } => {
            use tubes::trace::Integrator;
            let integrator = match integrator.as_str() {
                "rk4" => Integrator::Rk4,
                "rk45" => Integrator::Rk45,
                "euler" => Integrator::Euler,
                o => return Err(format!("--integrator {o}: use rk4, rk45 or euler")),
            };
            let args = engine::trace_cmd::TraceArgs {
                input,
                output: output.clone(),
                field,
                seeds,
                step,
                integrator,
                tolerance,
                max_length,
                min_speed,
                mask,
                threshold,
                max_angle,
                eigen,
                one_way,
            };
            let (n, p) = engine::trace_cmd::run(&args)?;
            eprintln!("wrote {}: {n} streamlines, {p} points", output.display());
            Ok(())
        }
        Command::Tubes {
            input,
            output,
            radius,
            sides,
            per_span,
            tolerance,
            chordal,
            fit,
            frame,
            radius_mode,
            color,
            caps,
            transform,
            stats_json,
        } => {
            use tubes::bspline_fit::FitMethod;
            use tubes::tube_mesh::{FrameMethod, RadiusMode};
            let fit = match fit.as_str() {
                "iterative" => FitMethod::Iterative,
                "least-squares" => FitMethod::LeastSquares,
                "none" => FitMethod::None,
                o => return Err(format!("--fit {o}: use iterative, least-squares or none")),
            };
            let frame = match frame.as_str() {
                "rmf" => FrameMethod::Rmf,
                "frenet" => FrameMethod::Frenet,
                o => return Err(format!("--frame {o}: use rmf or frenet")),
            };
            let radius_mode = match radius_mode.as_str() {
                "local" => RadiusMode::Local,
                "global" => RadiusMode::Global,
                o => return Err(format!("--radius-mode {o}: use local or global")),
            };
            let transform = match transform {
                None => None,
                Some(t) => {
                    let v: Vec<f64> = t
                        .split(',')
                        .map(|x| x.trim().parse::<f64>())
                        .collect::<Result<_, _>>()
                        .map_err(|_| format!("--transform {t}: 16 comma-separated numbers"))?;
                    Some(
                        <[f64; 16]>::try_from(v)
                            .map_err(|_| format!("--transform {t}: 16 comma-separated numbers"))?,
                    )
                }
            };
            let args = engine::tubes_cmd::TubesArgs {
                input,
                output: output.clone(),
                radius,
                sides,
                per_span,
                tolerance,
                chordal,
                fit,
                frame,
                radius_mode,
                color,
                caps,
                transform,
            };
            let s = engine::tubes_cmd::run(&args)?;
            for w in &s.warnings {
                eprintln!("umbra: warning: {}: {w}", args.input.display());
            }
            let json = serde_json::to_string_pretty(&s).unwrap();
            if let Some(p) = stats_json {
                volume::write_atomic(&p, json.as_bytes()).map_err(|e| e.to_string())?;
            }
            eprintln!(
                "wrote {}: {} tubes, {} triangles, {} control points for {} points, max deviation {:.4}, {:.2} s",
                output.display(), s.stats.streamlines_out, s.stats.triangles, s.stats.control_points, s.stats.points_in, s.stats.max_deviation, s.seconds.total
            );
            Ok(())
        }
        Command::Synth { scene, output, n } => {
            let vol = engine::synth::scene(&scene, n)?;
            volume::nrrd::write(
                &output,
                &vol,
                &vol.fields[0],
                volume::nrrd::WriteEncoding::Raw,
            )
            .map_err(|e| e.to_string())?;
            eprintln!("wrote {} ({n}^3 {scene})", output.display());
            Ok(())
        }
        Command::Convert {
            input,
            output,
            field,
            gzip,
        } => {
            let sel = parse_field(&field)?;
            engine::convert::convert(&input, &output, sel.as_ref(), gzip)
                .map_err(|e| e.to_string())?;
            eprintln!("wrote {}", output.display());
            Ok(())
        }
        Command::Render {
            scene,
            output,
            width,
            height,
            method,
            frames,
            timings_json,
            orbit,
            camera_path,
            aov,
            set,
            json,
        } => {
            let overrides = size_method_overrides(width, height, method, set);
            let cameras = match (orbit, camera_path) {
                (Some(n), _) => engine::render_cmd::Cameras::Orbit(n),
                (None, Some(p)) => engine::render_cmd::Cameras::Path(p),
                (None, None) => engine::render_cmd::Cameras::Single,
            };
            let sequence = cameras != engine::render_cmd::Cameras::Single;
            let terminal = std::io::IsTerminal::is_terminal(&std::io::stderr());
            let bar = indicatif::ProgressBar::hidden();
            let r = engine::render_cmd::run(
                &engine::render_cmd::RenderArgs {
                    scene,
                    output: output.clone(),
                    overrides,
                    frames,
                    aov,
                    pass_timings: timings_json.is_some() || frames > 1,
                    cameras,
                },
                &mut |f, n| {
                    if !sequence {
                        return;
                    }
                    if terminal {
                        if bar.is_hidden() {
                            bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
                            bar.set_length(n as u64);
                        }
                        bar.set_message(f.path.display().to_string());
                        bar.inc(1);
                    } else {
                        eprintln!(
                            "frame {}/{n} {} {:.1} ms",
                            f.index + 1,
                            f.path.display(),
                            f.total_ms
                        );
                    }
                },
            )?;
            bar.finish_and_clear();
            for n in &r.notes {
                eprintln!("note: {n}");
            }
            if let Some(t) = timings_json {
                let j = serde_json::json!({
                    "total_ms": r.total_ms,
                    "passes": r.passes,
                    "frames_ms": r.frames_ms,
                    "method": r.method,
                    "width": r.width,
                    "height": r.height,
                    "slices": r.slices,
                    "triangles": r.triangles,
                    "adapter": r.adapter,
                    "setup_seconds": r.setup_seconds,
                    "seconds": r.seconds,
                    "sequence": r.sequence.iter().map(|f| serde_json::json!({
                        "index": f.index,
                        "path": f.path,
                        "total_ms": f.total_ms,
                        "frames_ms": f.frames_ms,
                        "passes": f.passes,
                        "slices": f.slices,
                    })).collect::<Vec<_>>(),
                });
                let text = serde_json::to_string_pretty(&j).map_err(|e| e.to_string())?;
                volume::write_atomic(&t, text.as_bytes()).map_err(|e| e.to_string())?;
            }
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&r).map_err(|e| e.to_string())?
                );
            } else {
                println!("{}", summary(&r));
            }
            if r.sequence.is_empty() {
                eprintln!("wrote {}", output.display());
            } else {
                eprintln!(
                    "wrote {} frames ({} ... {})",
                    r.sequence.len(),
                    r.sequence[0].path.display(),
                    r.sequence[r.sequence.len() - 1].path.display()
                );
            }
            Ok(())
        }
        Command::Bench {
            what:
                BenchCommand::Accuracy {
                    scene,
                    sweeps,
                    methods,
                    reference_spp,
                    frames,
                    set,
                    output,
                },
        } => {
            let mut overrides = vec![
                "render.width=128".to_string(),
                "render.height=128".to_string(),
            ];
            overrides.extend(set);
            let sweeps = sweeps
                .iter()
                .map(|s| engine::bench_cmd::parse_sweep(s))
                .collect::<Result<Vec<_>, _>>()?;
            let bar = indicatif::ProgressBar::new_spinner();
            bar.enable_steady_tick(std::time::Duration::from_millis(200));
            let report = engine::bench_cmd::accuracy(
                &engine::bench_cmd::AccuracyArgs {
                    scene,
                    overrides,
                    sweeps,
                    methods: methods.split(',').map(|m| m.trim().to_string()).collect(),
                    spp: reference_spp,
                    frames,
                    out: output.clone(),
                },
                &|m| bar.set_message(m.to_string()),
            )?;
            bar.finish_and_clear();
            for r in &report.rows {
                println!(
                    "{:9} {:>16} {:9.1} ms  rmse {:.5}  psnr {:6.2}  ssim {:.4}",
                    r.method,
                    r.values.join(" "),
                    r.ms,
                    r.rmse,
                    r.psnr,
                    r.ssim
                );
            }
            eprintln!(
                "references: {} traced, {} from the cache",
                report.references_traced, report.references_cached
            );
            eprintln!(
                "wrote {0}/results.csv, {0}/pareto.svg, {0}/pareto.png",
                output.display()
            );
            Ok(())
        }
        Command::Bench {
            what:
                BenchCommand::Ao {
                    scene,
                    spp,
                    max_distance,
                    set,
                    output,
                },
        } => {
            let mean = engine::bench_cmd::ao(&scene, &set, spp, max_distance, &output)?;
            println!("mean ambient occlusion (open fraction) {mean:.5}");
            eprintln!(
                "wrote {0}/ao.exr, {0}/tubes.ply, {0}/camera.json",
                output.display()
            );
            Ok(())
        }
        Command::Bench {
            what:
                BenchCommand::Tubes {
                    input,
                    tolerances,
                    radius,
                    runs,
                    output,
                },
        } => {
            let t: Vec<f64> = parse_list("--tolerances", &tolerances)?;
            for r in engine::bench_cmd::tubes(&input, &t, radius, runs, &output)? {
                println!(
                    "tolerance {:8}  control points {:9}  triangles {:10}  max deviation {:.5}  {:.1} ms",
                    r.tolerance, r.control_points, r.triangles, r.max_deviation, r.ms
                );
            }
            eprintln!(
                "wrote {0}/tubes.csv, {0}/tubes.svg, {0}/tubes.png",
                output.display()
            );
            Ok(())
        }
        Command::Bench {
            what:
                BenchCommand::Sweep {
                    sizes,
                    offsets,
                    geometry,
                    spp,
                    size,
                    output,
                },
        } => {
            let offs: Vec<f64> = parse_list("--offsets", &offsets)?;
            let geoms: Vec<volume::occlusion_shading::GeometryTerm> =
                parse_list("--geometry", &geometry)?;
            let n: Vec<usize> = parse_list("--sizes", &sizes)?;
            for r in engine::bench_cmd::sweep(&n, &offs, &geoms, spp, size, &output)? {
                println!(
                    "n {:4}  {:8} offset {:4}  sweep {:9.1} ms  rmse {:.5}  (reference stderr {:.5})",
                    r.n, r.geometry, r.offset, r.ms, r.rmse, r.reference_stderr
                );
            }
            eprintln!(
                "wrote {0}/sweep.csv, {0}/sweep.svg, {0}/sweep.png",
                output.display()
            );
            Ok(())
        }
        Command::Bench {
            what:
                BenchCommand::Stability {
                    reference_spp,
                    frames,
                    output,
                },
        } => {
            let bar = indicatif::ProgressBar::new_spinner();
            bar.enable_steady_tick(std::time::Duration::from_millis(200));
            let rows = engine::bench_cmd::stability(&output, reference_spp, frames, &|m| {
                bar.set_message(m.to_string())
            })?;
            bar.finish_and_clear();
            for (case, _, r) in &rows {
                println!(
                    "{case:14} {:5} {:>10}  rmse {:.4}  {}",
                    r.method,
                    r.values.join(" "),
                    r.rmse,
                    engine::bench_cmd::verdict(r.rmse)
                );
            }
            eprintln!("wrote {}/stability.csv", output.display());
            Ok(())
        }
        Command::Demo {
            which,
            output,
            width,
            height,
            method,
            frames,
            set,
        } => {
            let overrides = size_method_overrides(width, height, method, set);
            let r = engine::demo::run(&which, &output, &overrides, frames)?;
            for n in &r.notes {
                eprintln!("note: {n}");
            }
            println!("{}", summary(&r));
            eprintln!("wrote {}", output.display());
            Ok(())
        }
        Command::Scene { file, set } => {
            let scene = engine::scene::load(&file, &set)?;
            println!(
                "{}",
                serde_json::to_string_pretty(&scene).map_err(|e| e.to_string())?
            );
            Ok(())
        }
        Command::Resample {
            input,
            q,
            field,
            dims,
            size,
            output,
            gzip,
            json,
        } => {
            let r = engine::resample_cmd::resample(
                &input,
                q.as_deref(),
                &field,
                dims,
                size,
                &output,
                gzip,
                !json && std::io::IsTerminal::is_terminal(&std::io::stderr()),
            )
            .map_err(|e| e.to_string())?;
            for w in &r.warnings {
                eprintln!("warning: {w}");
            }
            if json {
                println!(
                    "{}",
                    serde_json::to_string_pretty(&r).map_err(|e| e.to_string())?
                );
            } else {
                println!(
                    "{} grid: {} points, {} cells; arrays: {}",
                    r.format,
                    r.points,
                    r.cells,
                    r.arrays.join(", ")
                );
                println!(
                    "resampled '{}' to {}x{}x{} over [{:.4}, {:.4}, {:.4}]..[{:.4}, {:.4}, {:.4}]; {:.1}% of samples inside the mesh",
                    r.field,
                    r.dims[0],
                    r.dims[1],
                    r.dims[2],
                    r.bounds[0][0],
                    r.bounds[0][1],
                    r.bounds[0][2],
                    r.bounds[1][0],
                    r.bounds[1][1],
                    r.bounds[1][2],
                    100.0 * r.inside
                );
            }
            eprintln!("wrote {}", output.display());
            Ok(())
        }
    }
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("umbra: error: {e}");
            ExitCode::from(1)
        }
    }
}

/// `--width`, `--height`, `--method` as scene overrides, before the `--set` ones.
fn size_method_overrides(
    width: Option<u32>,
    height: Option<u32>,
    method: Option<String>,
    set: Vec<String>,
) -> Vec<String> {
    let mut o = vec![];
    if let Some(w) = width {
        o.push(format!("render.width={w}"));
    }
    if let Some(h) = height {
        o.push(format!("render.height={h}"));
    }
    if let Some(m) = method {
        o.push(format!("render.method=\"{m}\""));
    }
    o.extend(set);
    o
}

/// One line about a render.
fn summary(r: &engine::render_cmd::RenderReport) -> String {
    format!(
        "{}: {} x {}, {} slices {:.4} apart, {} triangles, on {}: {:.1} ms per frame ({}), {:.2} s in all",
        r.method,
        r.width,
        r.height,
        r.slices,
        r.slice_distance,
        r.triangles,
        r.adapter,
        r.total_ms,
        r.passes
            .iter()
            .map(|(k, v)| format!("{k} {v:.1}"))
            .collect::<Vec<_>>()
            .join(", "),
        r.seconds
    )
}

/// A comma-separated list of values, or an error naming the flag and the value.
fn parse_list<T: std::str::FromStr>(flag: &str, s: &str) -> Result<Vec<T>, String> {
    s.split(',')
        .map(|x| {
            x.trim()
                .parse::<T>()
                .map_err(|_| format!("{flag}: '{}' is not valid here", x.trim()))
        })
        .collect()
}
