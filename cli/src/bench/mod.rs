//! `umbra bench`: the benchmarks, one module each (`accuracy`, `stability`, `sweep`, `tubes`,
//! `ao`, `lineao`, `curves`), with the image metrics (`metrics`) and the charts (`chart`) they share.

mod accuracy;
mod ao;
mod chart;
mod curves;
mod lineao;
mod metrics;
mod stability;
mod sweep;
mod tubes;

use clap::Subcommand;

#[derive(clap::Args)]
pub struct Args {
    #[command(subcommand)]
    what: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Hemisphere ambient occlusion of a scene's tubes (Monte Carlo, the reference for the
    /// cross-check with Mitsuba 3 in bench/mitsuba_ao.py): <out>/ao.exr, tubes.ply, camera.json.
    Ao(ao::Args),
    /// Stream tubes' cost against accuracy: control points, triangles, largest deviation and
    /// meshing time per fitting tolerance: <out>/tubes.csv and a chart.
    Tubes(tubes::Args),
    /// Occlusion sweeping against Monte Carlo AO on the validation scene over grid sizes:
    /// <out>/sweep.csv and a chart.
    Sweep(sweep::Args),
    /// Scenes built to make the methods fail (a sheet thinner than the slices, grazing views,
    /// very few slices, cone angles near 0 and 80 degrees, zooming, turning in small steps,
    /// sparse and dense tube bundles, a bundle cut by the image border, isosurfaces for
    /// occlusion sweeping), each against its reference: <out>/stability.csv with verdicts,
    /// <out>/flicker.csv.
    Stability(stability::Args),
    /// Every method at every combination of the swept settings, timed and compared with the
    /// Monte Carlo reference of the same light model (cached): <out>/results.csv,
    /// <out>/pareto.svg and .png. Images are 128 x 128 unless --set says otherwise.
    Accuracy(accuracy::Args),
    /// LineAO against ray-traced ambient occlusion of the same lines as tubes (orthographic
    /// views), beside Schott's vicinity and a CPU SSAO: isolated lines, a dense bundle, the
    /// s_h sweep, the falloff, zoom, screen borders, real tracts. <out>/results.csv,
    /// pareto.svg/.png, samples.svg/.png, zoom.csv, border.csv, images/; with --cases aniso
    /// (a default) anisotropic LineAO: aniso_roll.csv, aniso_summary.csv, aniso_flicker.csv,
    /// aniso_roll.svg.
    Lineao(lineao::Args),
    /// The renderer's cost curves in one process: frame time against image size (--sizes),
    /// slice count (--slices) and line segments (--segments, fractions of each set) for each
    /// method (--methods) and device (--devices gpu,cpu): <out>/curves.csv and
    /// curve_size|slices|segments.svg/.png.
    Curves(curves::Args),
}

pub fn run(a: Args) -> Result<(), String> {
    match a.what {
        Command::Ao(a) => ao::run(a),
        Command::Tubes(a) => tubes::run(a),
        Command::Sweep(a) => sweep::run(a),
        Command::Stability(a) => stability::run(a),
        Command::Accuracy(a) => accuracy::run(a),
        Command::Lineao(a) => lineao::run(a),
        Command::Curves(a) => curves::run(a),
    }
}
