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
enum Command {
    /// Describe a volume file (format, grid, world frame, value range), or the GPU with --gpu.
    Info {
        /// Volume file: .nii, .nii.gz, .hdr, .nrrd, .nhdr, .vtk, .vti, .mhd, .mha, .slc.
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
            let sel = parse_field(&field)?;
            let vol = volume::load(&file).map_err(|e| e.to_string())?;
            for w in &vol.warnings {
                eprintln!("umbra: warning: {}: {w}", file.display());
            }
            if json {
                let v = engine::info::volume_json(&vol, sel.as_ref()).map_err(|e| e.to_string())?;
                println!("{}", serde_json::to_string(&v).unwrap());
            } else {
                print!(
                    "{}",
                    engine::info::volume_text(&file.display().to_string(), &vol, sel.as_ref())
                        .map_err(|e| e.to_string())?
                );
            }
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
