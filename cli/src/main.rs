//! The `umbra` command line: one module per subcommand (`commands/`, `bench/`), each with its
//! arguments and a `run` that calls the libraries (`scene`, `occlusion`, `engine`, `volume`,
//! `tubes`) and prints.

mod bench;
mod commands;
mod output;
mod progress;

use clap::error::{ContextKind, ContextValue, ErrorKind};
use clap::{CommandFactory, Parser, Subcommand};
use commands::{
    convert, demo, info, iso, render, resample, scene, sweep, synth, trace, tracts, tubes, view,
};
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "umbra", version, about = "Volumes with tubes and lines, shaded with occlusion", long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Describe a volume file (format, grid, world frame, value range), or the GPU with --gpu.
    Info(info::Args),
    /// Signed distance and eight octant occlusion fields of an isosurface (fast sweeping).
    Sweep(sweep::Args),
    /// Render an isosurface on the CPU with swept or Monte Carlo ambient occlusion (reference).
    Iso(iso::Args),
    /// Trace streamlines (or, with --pathlines, pathlines through a time series) into .trk,
    /// .trx or .tck, with time and speed per point.
    Trace(trace::Args),
    /// B-spline stream tubes of a tractogram (.trk, .tck, optionally .gz, .trx, .vtk), written as
    /// PLY or OBJ.
    Tubes(tubes::Args),
    /// Tractogram tools: `umbra tracts select` (streamlines by include/exclude ROIs, length,
    /// attribute ranges, subsample) and `umbra tracts merge` (several into one).
    Tracts(tracts::Args),
    /// Write a synthetic scene as NRRD or NIfTI: validation (the sweeping paper's solids,
    /// [0,100]^3), three-solids (sphere, torus, box in [0,1]^3), phantom (3-D Shepp-Logan,
    /// uint16), abc, burgers, rotation (vector fields), double-gyre (a time-periodic flow, 5-D
    /// NIfTI), bundles (synthetic fibre bundles as .tck).
    Synth(synth::Args),
    /// Write a volume's field as NRRD (.nrrd) or NIfTI-1 (.nii, .nii.gz).
    Convert(convert::Args),
    /// Render a scene file (on the GPU, or the native CPU renderer): volume, tubes and lines by
    /// any method of the table to PNG (sRGB) or EXR (linear RGBA, --aov layers).
    Render(render::Args),
    /// Benchmarks, each timed and measured against a ground truth: accuracy (every method
    /// against the Monte Carlo reference, a Pareto chart), stability (scenes that make methods
    /// fail), lineao (LineAO and its anisotropic form against ray-traced AO), curves (cost
    /// against image size, slices, segments), sweep (occlusion sweeping against Monte Carlo
    /// AO), tubes (meshing cost against accuracy), ao (the tubes' reference AO for Mitsuba).
    Bench(bench::Args),
    /// Render a demo scene: `mni` (the MNI T1 template with HCP1065 tracts as tubes, combined
    /// method; the default), `cfd` (carotid flow with traced streamlines) or `lines` (all ten
    /// HCP1065 bundles as lines with LineAO over the template).
    Demo(demo::Args),
    /// Check a scene file (TOML) and print it resolved, with defaults and --set overrides, as
    /// JSON (`umbra render` and `umbra view` read the same files).
    Scene(scene::Args),
    /// Resample a CFD grid (.vtr, .vts, .vtu, legacy .vtk STRUCTURED_GRID/RECTILINEAR_GRID,
    /// PLOT3D) onto a regular grid; samples outside the mesh are NaN.
    Resample(resample::Args),
    /// Open a scene file in a window (the interactive viewer): orbit, pan, zoom, standard
    /// views, the method; a draft while you interact, the full image when the view rests.
    View(view::Args),
}

fn run(command: Command) -> Result<(), String> {
    match command {
        Command::Info(a) => info::run(a),
        Command::Sweep(a) => sweep::run(a),
        Command::Iso(a) => iso::run(a),
        Command::Trace(a) => trace::run(a),
        Command::Tubes(a) => tubes::run(a),
        Command::Tracts(a) => tracts::run(a),
        Command::Synth(a) => synth::run(a),
        Command::Convert(a) => convert::run(a),
        Command::Render(a) => render::run(a),
        Command::Bench(a) => bench::run(a),
        Command::Demo(a) => demo::run(a),
        Command::Scene(a) => scene::run(a),
        Command::Resample(a) => resample::run(a),
        Command::View(a) => view::run(a),
    }
}

/// Without a usable `XDG_RUNTIME_DIR` (a batch job, a container, `sudo`), Mesa's device-select
/// Vulkan layer tries to reach a Wayland display and prints "error: XDG_RUNTIME_DIR is invalid
/// or not set in the environment." twice to standard error, on success too. The layer only
/// orders the adapters (by `MESA_VK_DEVICE_SELECT` or the display's GPU), so it is turned off
/// then (`NODEVICE_SELECT=1`), unless the user asked it for a device.
fn quiet_device_select() {
    let runtime_ok =
        std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|d| std::path::Path::new(&d).is_dir());
    let asked = ["MESA_VK_DEVICE_SELECT", "NODEVICE_SELECT"]
        .iter()
        .any(|v| std::env::var_os(v).is_some());
    if !runtime_ok && !asked {
        // Before any thread starts: nothing else reads the environment yet.
        std::env::set_var("NODEVICE_SELECT", "1");
    }
}

/// A thread that waits for SIGINT or SIGTERM, then removes the temporary files being written
/// (`volume::remove_temps_being_written`) and ends the process as the signal would have (a
/// shell's loop sees the command interrupted, status 128 + the signal).
#[cfg(unix)]
fn remove_temps_on_signal() {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) else {
        return;
    };
    std::thread::spawn(move || {
        if let Some(sig) = signals.forever().next() {
            volume::remove_temps_being_written();
            // `umbra render --record`: what the run did before it was interrupted.
            commands::render::record_interrupted(sig);
            let _ = signal_hook::low_level::emulate_default_handler(sig);
            std::process::exit(128 + sig);
        }
    });
}

#[cfg(not(unix))]
fn remove_temps_on_signal() {}

/// The command line parsed, a negative number taken as an option's value wherever one is
/// given (`--radius -1` is a radius of -1, refused as out of range, not an unknown option
/// `-1`), in every command.
fn parse_cli() -> Result<Cli, clap::Error> {
    fn negatives(c: clap::Command) -> clap::Command {
        c.allow_negative_numbers(true).mut_subcommands(negatives)
    }
    let matches = negatives(Cli::command()).try_get_matches()?;
    <Cli as clap::FromArgMatches>::from_arg_matches(&matches)
}

fn main() -> ExitCode {
    quiet_device_select();
    // A command never writes over a file it has read, whatever the names say (README,
    // "Command line").
    volume::guard_inputs();
    let cli = match parse_cli() {
        Ok(cli) => cli,
        Err(e) => {
            let _ = e.print();
            // A bad value of a flag (an unknown --fit, a --dims that is not NX,NY,NZ) is wrong
            // input like the errors the commands find (exit 1); help and version exit 0, and a
            // malformed command line clap's usual 2.
            // An option given without its value (`--orbit` at the end) is a malformed command
            // line: clap reports it as an invalid, empty value.
            let missing = e.kind() == ErrorKind::InvalidValue
                && matches!(
                    e.get(ContextKind::InvalidValue),
                    Some(ContextValue::String(v)) if v.is_empty()
                );
            let code = match e.kind() {
                ErrorKind::InvalidValue | ErrorKind::ValueValidation if !missing => 1,
                _ => e.exit_code(),
            };
            if code != 0 {
                // `umbra render --record FILE` leaves its record on any failure.
                let text = e.render().to_string();
                let first = text.lines().next().unwrap_or_default();
                let why = first.strip_prefix("error: ").unwrap_or(first);
                let args: Vec<_> = std::env::args_os().collect();
                if let Err(w) = render::record_unparsed(&args, why) {
                    eprintln!("umbra: error: the record could not be written: {w}");
                }
            }
            return ExitCode::from(code as u8);
        }
    };
    // Options that conflict by their values are a command line that does not parse (exit 2,
    // as clap's own conflicts; README, "Command line").
    if let Command::Sweep(a) = &cli.command {
        if let Some(c) = sweep::conflict(a) {
            // With the sweep's own usage line, as clap's errors of its options have.
            let mut cmd = Cli::command();
            cmd.build();
            let sweep = cmd.find_subcommand_mut("sweep").expect("the sweep command");
            let _ = sweep.error(ErrorKind::ArgumentConflict, c).print();
            return ExitCode::from(2);
        }
    }
    // Interrupted (SIGINT, SIGTERM), a command removes the temporary files it is writing
    // before it exits (status 128 + the signal): its outputs are as they were. The viewer
    // ends on those signals itself.
    if !matches!(cli.command, Command::View(_)) {
        remove_temps_on_signal();
    }
    match run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // A last guard on length: an error that quotes a huge value (a 5 MB string in a
            // scene) prints each line cut to 1000 characters.
            let mut lines: Vec<String> = e.lines().map(|l| volume::clip_text(l, 1000)).collect();
            let args: Vec<String> = std::env::args().collect();
            lines.extend(set_hint(&e, &args));
            eprintln!("umbra: error: {}", lines.join("\n"));
            ExitCode::from(1)
        }
    }
}

/// The scene keys a command line overrides, in the order they apply: the shorthand flags
/// (`--width`, `--height`, `--method`, `--title`, `--orientation`, `--scale-bar`,
/// `--colorbar`), then each `--set KEY=VALUE` - as (key, value, the option as typed).
fn overrides_of(args: &[String]) -> Vec<(String, String, String)> {
    const FLAGS: [(&str, &str); 7] = [
        ("--width", "render.width"),
        ("--height", "render.height"),
        ("--method", "render.method"),
        ("--title", "annotate.title"),
        ("--orientation", "annotate.orientation"),
        ("--scale-bar", "annotate.scale_bar"),
        ("--colorbar", "annotate.colorbar"),
    ];
    let (mut flags, mut sets) = (vec![], vec![]);
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let (name, inline) = match a.split_once('=') {
            Some((n, v)) if n.starts_with("--") => (n, Some(v.to_string())),
            _ => (a.as_str(), None),
        };
        if name == "--set" {
            let kv = inline.or_else(|| it.next().cloned()).unwrap_or_default();
            if let Some((k, v)) = kv.split_once('=') {
                sets.push((k.trim().to_string(), v.to_string(), format!("--set {kv}")));
            }
        } else if let Some((flag, key)) = FLAGS.iter().find(|(f, _)| *f == name) {
            let value = match (*flag, inline) {
                ("--orientation", _) => String::new(),
                (_, Some(v)) => v,
                (_, None) => it.next().cloned().unwrap_or_default(),
            };
            let typed = match *flag {
                "--orientation" => flag.to_string(),
                _ => format!("{flag} {value}"),
            };
            flags.push((key.to_string(), value, typed));
        }
    }
    flags.extend(sets);
    flags
}

/// A line for an error about a scene key whose value (or a table above it) came from the
/// command line rather than the scene file the error names: "scene key slices[0].position"
/// (or a message that begins with the key, "volume.iso.value: ...") and `--set
/// slices.0.position=999` (keys compared with `[N]` read as `.N`). Of several overrides of
/// the key the last, which applied last, is named.
fn set_hint(err: &str, args: &[String]) -> Option<String> {
    // A manifest line's error already says which override gave the value.
    if err.contains(::scene::spec::BLAME_PREFIX) {
        return None;
    }
    let overrides = overrides_of(args);
    ::scene::spec::blamed_override(err, &overrides)
        .map(|typed| format!("{}{typed}, not from the file)", ::scene::spec::BLAME_PREFIX))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(a: &[&str]) -> Vec<String> {
        a.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn an_error_about_a_key_given_by_set_says_so() {
        let a = args(&[
            "umbra",
            "render",
            "s.toml",
            "--set",
            "slices.0.position=999",
            "--set=render.width=0",
        ]);
        let e = "s.toml: scene key slices[0].position: the plane at 999 does not cut the volume";
        assert_eq!(
            set_hint(e, &a).as_deref(),
            Some("(the value comes from --set slices.0.position=999, not from the file)")
        );
        let e = "s.toml: scene key render.width: 0 pixels is not within 1..16384";
        assert!(set_hint(e, &a).unwrap().contains("--set render.width=0"));
        // A table set whole covers its keys; other keys and prefixes that are not a table's
        // (render.widths) are not the option's.
        let t = args(&[
            "umbra",
            "render",
            "s.toml",
            "--set",
            "lines.0.halo={width=-1}",
        ]);
        assert!(set_hint("scene key lines[0].halo.width: -1 is negative", &t).is_some());
        assert!(set_hint("scene key lines[1].halo.width: bad", &t).is_none());
        assert!(set_hint("scene key render.widths: bad", &a).is_none());
        assert!(set_hint("scene key render.height: bad", &a).is_none());
        assert!(set_hint("no key here", &a).is_none());
        assert!(set_hint(e, &args(&["umbra", "render", "s.toml"])).is_none());
    }

    #[test]
    fn the_last_override_of_a_key_and_the_shorthand_flags_are_named() {
        // Two overrides of one key: the later applied, and is named.
        let a = args(&[
            "umbra",
            "render",
            "s.toml",
            "--set",
            "camera.fov_y=30",
            "--set",
            "camera.fov_y=200",
        ]);
        let e = "s.toml: scene key camera.fov_y: 200 is not in (0, 180)";
        assert!(set_hint(e, &a).unwrap().contains("camera.fov_y=200"));
        // A list set whole, then one entry's key: the entry's.
        let a = args(&[
            "umbra",
            "render",
            "s.toml",
            "--set",
            "volume.transfer.points=[{value=0.0}]",
            "--set",
            "volume.transfer.points.1.extinction=-1",
        ]);
        let e = "scene key volume.transfer.points[1].extinction: -1 is negative";
        assert!(set_hint(e, &a).unwrap().contains("points.1.extinction=-1"));
        // A message that begins with the key.
        let a = args(&[
            "umbra",
            "render",
            "s.toml",
            "--set",
            "volume.iso.value=99999.0",
        ]);
        let e = "s.toml: volume.iso.value: 99999 is outside the field's range";
        assert!(set_hint(e, &a).is_some());
        // A key inside a word (a file's name) is not one.
        let a = args(&["umbra", "render", "s.toml", "--set", "render.width=1"]);
        assert!(set_hint("see my.render.width: nothing", &a).is_none());
        // Shorthand flags, with their values as typed; --set after them wins.
        let a = args(&["umbra", "render", "s.toml", "--width", "20000", "--title=x"]);
        let e = "s.toml: scene key render.width: 20000 pixels is not within 1..16384";
        assert_eq!(
            set_hint(e, &a).as_deref(),
            Some("(the value comes from --width 20000, not from the file)")
        );
        assert!(set_hint("scene key annotate.title: bad", &a)
            .unwrap()
            .contains("--title x"));
        let a = args(&[
            "umbra",
            "render",
            "s.toml",
            "--width",
            "20",
            "--set",
            "render.width=0",
        ]);
        assert!(set_hint(e, &a).unwrap().contains("--set render.width=0"));
    }
}
