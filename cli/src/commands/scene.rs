//! `umbra scene`: a scene file checked and printed resolved (defaults, paths, `--set`
//! overrides) as JSON.

use crate::output::out_json_pretty;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Scene file.
    file: PathBuf,
    /// Override a key by its dotted path, e.g. --set render.width=640 (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    set: Vec<String>,
}

pub fn run(a: Args) -> Result<(), String> {
    out_json_pretty(&::scene::spec::load(&a.file, &a.set)?)
}
