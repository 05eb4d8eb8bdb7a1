//! `umbra info`: what a file holds (a volume, a tractogram or a CFD grid, told apart here), or
//! the GPU adapter with `--gpu`, as text or as one JSON object.

use crate::output::{out, out_json, out_json_pretty, out_raw};
use serde_json::{json, Value};
use std::path::PathBuf;
use volume::{FieldSelector, Volume, VolumeError};

#[derive(clap::Args)]
pub struct Args {
    /// Volume file (.nii, .nii.gz, .hdr, .nrrd, .nhdr, .vtk, .vti, .mhd, .mha, .slc), CFD grid
    /// (.vtr, .vts, .vtu, legacy .vtk grids, PLOT3D with --q) or tractogram (.trk, .tck,
    /// optionally .gz, .trx, .vtk polylines).
    file: Option<PathBuf>,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
    /// Field to describe: NAME, NAME:magnitude or NAME:x|y|z (default: the file's active array).
    #[arg(long, value_parser = super::field_selector)]
    field: Option<FieldSelector>,
    /// Describe the GPU adapter and run the GPU smoke check instead of reading a file
    /// (the adapter `--adapter` of `umbra render` would open: UMBRA_ADAPTER, else the best).
    #[arg(long)]
    gpu: bool,
    /// List every adapter with the index and PCI bus id `--adapter` takes.
    #[arg(long, conflicts_with = "gpu")]
    adapters: bool,
    /// PLOT3D solution (q) file, for a PLOT3D grid.
    #[arg(long)]
    q: Option<PathBuf>,
}

pub fn run(a: Args) -> Result<(), String> {
    if a.gpu {
        return gpu(a.json);
    }
    if a.adapters {
        let list = engine::gpu::adapters();
        if a.json {
            return out_json_pretty(&list);
        }
        if list.is_empty() {
            return Err("no GPU adapter found (on a machine without a GPU install Mesa's software Vulkan driver: apt-get install mesa-vulkan-drivers)".into());
        }
        for e in &list {
            let bus = if e.pci_bus_id.is_empty() {
                "-"
            } else {
                e.pci_bus_id.as_str()
            };
            out(format!(
                "{:>2}  {:<13} {:<8} {}  ({})",
                e.index, bus, e.backend, e.name, e.device_type
            ))?;
        }
        return Ok(());
    }
    let file = a
        .file
        .ok_or("umbra info: give a file, --gpu or --adapters")?;
    let name = file.display().to_string();
    let warn = |ws: &[String]| {
        ws.iter()
            .for_each(|w| eprintln!("umbra: warning: {name}: {w}"))
    };
    let print = |value: Value, text: String| {
        if a.json {
            out_json(&value)
        } else {
            out_raw(text)
        }
    };
    if tubes::is_tractogram(&file) {
        let s = tubes::load(&file).map_err(|e| e.to_string())?;
        warn(&s.warnings);
        return print(tractogram_json(&s), tractogram_text(&name, &s));
    }
    // CFD grids: by name, or PLOT3D (no signature) when --q is given or the file is no volume
    // but parses as a PLOT3D grid.
    let (grid, warnings) = if volume::is_grid(&file) || a.q.is_some() {
        volume::load_grid(&file, a.q.as_deref()).map_err(|e| e.to_string())?
    } else {
        let sel = a.field.as_ref();
        // A scalar field alone, in its stored type where it is 8/16-bit (a 1024^3 uint16 volume
        // is described in 2 GiB, not 10); vector fields and bad selections as before.
        match volume::load_scalar(&file, sel) {
            Ok(f) => {
                warn(&f.volume.warnings);
                let stats = f.samples.stats();
                let robust = (stats.min <= stats.max).then(|| {
                    scene::compile::robust_range(&f.samples, [stats.min, stats.max], |v| {
                        v.is_finite()
                    })
                });
                let j = volume_json_of(&f.volume, &f.name, 1, f.stored, stats, robust);
                let text = volume_text(&name, &f.volume, &j);
                return print(j, if a.json { String::new() } else { text });
            }
            Err(volume::VolumeError::Invalid(_)) => {}
            Err(e) if named_format(&file) => return Err(e.to_string()),
            Err(_) => {}
        }
        match volume::load(&file) {
            Ok(vol) => {
                warn(&vol.warnings);
                let j = volume_json(&vol, sel).map_err(|e| format!("{}: {e}", file.display()))?;
                let text = volume_text(&name, &vol, &j);
                return print(j, if a.json { String::new() } else { text });
            }
            Err(e) if named_format(&file) => return Err(e.to_string()),
            Err(e) => volume::plot3d::read(&file, None)
                .map_err(|p| format!("{e}; read as a PLOT3D grid: {p}"))?,
        }
    };
    // A grid describes all its arrays; a field it does not have is an error, not ignored.
    if let Some(sel) = &a.field {
        if !grid.names().contains(&sel.name) {
            return Err(format!(
                "{name}: field {}: no such array; the grid has: {}",
                sel.name,
                grid.names().join(", ")
            ));
        }
    }
    // Grid readers' warnings name their file themselves.
    warnings
        .iter()
        .for_each(|w| eprintln!("umbra: warning: {w}"));
    print(grid_json(&grid), grid_text(&name, &grid))
}

/// `umbra info --gpu`: the adapter and the smoke check.
fn gpu(json: bool) -> Result<(), String> {
    let g = engine::gpu::Gpu::new().map_err(|e| e.to_string())?;
    let report = g.report();
    let smoke = engine::smoke::run(&g, 8).map_err(|e| e.to_string())?;
    if json {
        return out_json_pretty(&json!({"adapter": report, "smoke": smoke}));
    }
    out(&report)?;
    if let Some(note) = &smoke.msaa_note {
        out(format!("note:               {note}"))?;
    }
    out(format!(
        "smoke check:        passed (compute {} values, render {}x{} at {}x MSAA)",
        smoke.compute_values_checked,
        smoke.render_size[0],
        smoke.render_size[1],
        smoke.sample_count
    ))
}

/// Whether the file's name says its format (a volume's, or VTK's `.vtk`, `.vtr`, `.vts`,
/// `.vtu`): then it is read by that reader or refused, never guessed at as a PLOT3D grid.
fn named_format(file: &std::path::Path) -> bool {
    let name = file.to_string_lossy().to_ascii_lowercase();
    volume::has_volume_extension(file)
        || [".vtk", ".vtr", ".vts", ".vtu", ".vtk.gz"]
            .iter()
            .any(|e| name.ends_with(e))
}

/// The JSON description of a volume (keys documented in the README: `format`, `dims`,
/// `components`, `type`, `spacing`, `affine`, `space`, `bounds`, `range`, `robust`,
/// `nonfinite`, `fields`, plus `field`, the name of the field `range` and `nonfinite` describe).
pub fn volume_json(vol: &Volume, sel: Option<&FieldSelector>) -> Result<Value, VolumeError> {
    let field = vol.select(sel)?;
    let stats = field.stats();
    // The robust range of a scalar field (what `volume.transfer.range = "robust"` spans); a
    // vector's components are not one distribution.
    let robust = (field.components == 1 && stats.min <= stats.max).then(|| {
        let q = volume::quantile::quantiles(
            || field.data.iter().copied().filter(|v| v.is_finite()),
            &scene::compile::ROBUST_FRACTIONS,
        );
        scene::compile::robust_from(&q, [stats.min, stats.max])
    });
    Ok(volume_json_of(
        vol,
        &field.name,
        field.components,
        field.stored,
        stats,
        robust,
    ))
}

/// [`volume_json`] of the grid `vol` and the described field's name, components, stored type
/// and statistics.
pub fn volume_json_of(
    vol: &Volume,
    name: &str,
    components: usize,
    stored: volume::ScalarType,
    stats: volume::FieldStats,
    robust: Option<[f64; 2]>,
) -> Value {
    let a = vol.affine;
    let rows: Vec<Vec<f64>> = (0..4)
        .map(|r| (0..4).map(|c| a.col(c)[r]).collect())
        .collect();
    let [lo, hi] = vol.bounds();
    let num = |v: f64| if v.is_finite() { json!(v) } else { Value::Null };
    json!({
        "format": vol.format,
        "dims": vol.dims,
        "components": components,
        "type": stored.name(),
        "spacing": vol.spacing(),
        "affine": rows,
        "space": vol.space.name(),
        "bounds": [[lo.x, lo.y, lo.z], [hi.x, hi.y, hi.z]],
        "range": [num(stats.min), num(stats.max)],
        "robust": robust.map(|[a, b]| json!([a, b])).unwrap_or(Value::Null),
        "nonfinite": stats.nonfinite,
        "fields": vol.field_names(),
        "field": name,
    })
}

/// The same facts as lines of text for a person.
pub fn volume_text(path: &str, vol: &Volume, j: &Value) -> String {
    let mut s = String::new();
    let f3 = |v: &Value| {
        v.as_array()
            .map(|a| {
                a.iter()
                    .map(|x| decimals(x.as_f64().unwrap_or(f64::NAN), 6))
                    .collect::<Vec<_>>()
                    .join(", ")
            })
            .unwrap_or_default()
    };
    s += &format!("file:       {path}\n");
    s += &format!("format:     {}\n", j["format"].as_str().unwrap_or(""));
    s += &format!(
        "dims:       {} x {} x {}\n",
        vol.dims[0], vol.dims[1], vol.dims[2]
    );
    s += &format!(
        "field:      {} ({} component{}, stored as {})\n",
        j["field"].as_str().unwrap_or(""),
        j["components"],
        if j["components"] == 1 { "" } else { "s" },
        j["type"].as_str().unwrap_or("")
    );
    s += &format!("fields:     {}\n", vol.field_names().join(", "));
    s += &format!("spacing:    {}\n", f3(&j["spacing"]));
    s += &format!(
        "space:      {}\n",
        if vol.space == volume::Space::Ras {
            "RAS+ (mm)"
        } else {
            "file's own frame"
        }
    );
    s += "affine:     (index -> world)\n";
    for r in j["affine"].as_array().into_iter().flatten() {
        s += &format!(
            "            [{}]\n",
            r.as_array()
                .map(|a| a
                    .iter()
                    .map(|x| format!("{:>12}", decimals(x.as_f64().unwrap_or(f64::NAN), 6)))
                    .collect::<Vec<_>>()
                    .join(" "))
                .unwrap_or_default()
        );
    }
    s += &format!(
        "bounds:     min ({})  max ({})\n",
        f3(&j["bounds"][0]),
        f3(&j["bounds"][1])
    );
    s += &format!("range:      {} .. {}\n", j["range"][0], j["range"][1]);
    if !j["robust"].is_null() {
        // Equal to the range, it may be the fallback where the percentiles coincide (a mask
        // with under 2% of one value has both at the other).
        let why = match j["robust"] == j["range"] {
            true => "2nd to 98th percentiles, or the full range where those coincide",
            false => "2nd to 98th percentiles",
        };
        s += &format!(
            "robust:     {} .. {} ({why})\n",
            j["robust"][0], j["robust"][1]
        );
    }
    s += &format!("non-finite: {} voxels\n", j["nonfinite"]);
    s
}

/// `x` with `places` decimals, or in exponent form with as many where that would show fewer
/// than two significant digits (spacings of 1e-7 read "0.000000").
fn decimals(x: f64, places: usize) -> String {
    if x != 0.0 && x.abs() < 10f64.powi(1 - places as i32) {
        format!("{x:.places$e}")
    } else {
        format!("{x:.places$}")
    }
}

/// The JSON description of a tractogram: `format`, `streamlines`, `points`, `bounds` (world,
/// `null` when empty), `attributes` (`{"point": {name: components}, "streamline": {...}}`).
pub fn tractogram_json(s: &tubes::Streamlines) -> Value {
    let bounds = s
        .bounds()
        .map(|[lo, hi]| json!([[lo.x, lo.y, lo.z], [hi.x, hi.y, hi.z]]))
        .unwrap_or(Value::Null);
    let attrs = |a: &[tubes::Attribute]| -> Value {
        a.iter()
            .map(|a| (a.name.clone(), json!(a.components)))
            .collect::<serde_json::Map<_, _>>()
            .into()
    };
    json!({
        "format": s.format,
        "streamlines": s.len(),
        "points": s.points.len(),
        "bounds": bounds,
        "attributes": {"point": attrs(&s.point_attributes), "streamline": attrs(&s.line_attributes)},
    })
}

/// The same as text.
pub fn tractogram_text(path: &str, s: &tubes::Streamlines) -> String {
    let mut out = format!(
        "file:        {path}\nformat:      {}\nstreamlines: {}\npoints:      {}\n",
        s.format,
        s.len(),
        s.points.len()
    );
    match s.bounds() {
        Some([lo, hi]) => {
            let f = |v: glam::Vec3| v.to_array().map(|x| decimals(x as f64, 3)).join(", ");
            out += &format!("bounds:      min ({})  max ({})\n", f(lo), f(hi))
        }
        None => out += "bounds:      (empty)\n",
    }
    let list = |a: &[tubes::Attribute]| {
        if a.is_empty() {
            "none".to_string()
        } else {
            a.iter()
                .map(|a| format!("{} ({})", a.name, a.components))
                .collect::<Vec<_>>()
                .join(", ")
        }
    };
    out += &format!(
        "per point:   {}\nper line:    {}\n",
        list(&s.point_attributes),
        list(&s.line_attributes)
    );
    if let Some(r) = &s.reference {
        out += &format!(
            "reference:   {:?} voxels of {:?} mm, order {}\n",
            r.dims,
            r.voxel_sizes,
            String::from_utf8_lossy(&r.voxel_order)
        );
    }
    out
}

/// The JSON description of a CFD grid: `format`, `geometry` (`rectilinear`, `structured`,
/// `unstructured`), `dims` (node counts per axis, structured kinds only), `points`, `cells`,
/// `bounds`, `arrays` (`[{name, components, on: "points"|"cells", range, nonfinite}]`; `range`
/// over finite values, per component for scalars and of the magnitude for vectors).
pub fn grid_json(g: &volume::cfd_grid::CfdGrid) -> Value {
    use volume::cfd_grid::Geometry;
    let [lo, hi] = g.bounds();
    let (geometry, dims) = match &g.geometry {
        Geometry::Rectilinear { x, y, z } => ("rectilinear", json!([x.len(), y.len(), z.len()])),
        Geometry::Structured { dims, .. } => ("structured", json!(dims)),
        Geometry::Unstructured { .. } => ("unstructured", Value::Null),
    };
    let num = |v: f64| if v.is_finite() { json!(v) } else { Value::Null };
    let arrays: Vec<Value> = g
        .arrays
        .iter()
        .map(|a| {
            let c = a.components.max(1);
            let (mut min, mut max, mut bad) = (f64::INFINITY, f64::NEG_INFINITY, 0usize);
            for t in a.data.chunks(c) {
                let v = if c == 1 {
                    t[0] as f64
                } else {
                    t.iter()
                        .map(|&x| (x as f64) * (x as f64))
                        .sum::<f64>()
                        .sqrt()
                };
                if v.is_finite() {
                    min = min.min(v);
                    max = max.max(v);
                } else {
                    bad += 1;
                }
            }
            json!({
                "name": a.name,
                "components": a.components,
                "on": if a.on_cells { "cells" } else { "points" },
                "range": [num(min), num(max)],
                "nonfinite": bad,
            })
        })
        .collect();
    json!({
        "format": g.format,
        "geometry": geometry,
        "dims": dims,
        "points": g.n_points(),
        "cells": g.n_cells(),
        "bounds": [[lo.x, lo.y, lo.z], [hi.x, hi.y, hi.z]],
        "arrays": arrays,
    })
}

/// The same as text.
pub fn grid_text(path: &str, g: &volume::cfd_grid::CfdGrid) -> String {
    let j = grid_json(g);
    let b = &j["bounds"];
    let mut out = format!(
        "file:       {path}\nformat:     {} ({} grid)\n",
        j["format"].as_str().unwrap_or(""),
        j["geometry"].as_str().unwrap_or("")
    );
    if let Some(d) = j["dims"].as_array() {
        let d: Vec<String> = d.iter().map(|v| v.to_string()).collect();
        out += &format!("dims:       {}\n", d.join(" x "));
    }
    out += &format!(
        "points:     {}\ncells:      {}\nbounds:     min ({}, {}, {})  max ({}, {}, {})\n",
        j["points"], j["cells"], b[0][0], b[0][1], b[0][2], b[1][0], b[1][1], b[1][2]
    );
    out += "arrays:\n";
    for a in j["arrays"].as_array().into_iter().flatten() {
        let what = if a["components"] == 1 {
            "range".to_string()
        } else {
            format!("{} components, magnitude", a["components"])
        };
        out += &format!(
            "  {:<28} on {:<6} {what} {} .. {}{}\n",
            a["name"].as_str().unwrap_or(""),
            a["on"].as_str().unwrap_or(""),
            a["range"][0],
            a["range"][1],
            match a["nonfinite"].as_u64() {
                Some(0) | None => String::new(),
                Some(n) => format!(" ({n} non-finite)"),
            }
        );
    }
    if j["arrays"].as_array().is_none_or(|a| a.is_empty()) {
        out += "  (none)\n";
    }
    out += "resample onto a regular grid with `umbra resample FILE --field NAME -o out.nrrd`\n";
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn small_numbers_keep_their_digits() {
        use super::decimals;
        assert_eq!(decimals(1e-7, 6), "1.000000e-7");
        assert_eq!(decimals(-2.5e-6, 6), "-2.500000e-6");
        assert_eq!(decimals(0.5, 6), "0.500000");
        assert_eq!(decimals(0.0, 3), "0.000");
        assert_eq!(decimals(0.005, 3), "5.000e-3");
        assert_eq!(decimals(0.05, 3), "0.050");
        assert_eq!(decimals(181.0, 3), "181.000");
    }

    fn volume(data: Vec<f32>) -> volume::Volume {
        let field = volume::Field {
            name: "v".into(),
            components: 1,
            stored: volume::ScalarType::F32,
            data,
        };
        volume::Volume::new(
            [10, 10, 10],
            glam::DMat4::IDENTITY,
            volume::Space::Ras,
            field,
        )
        .unwrap()
    }

    #[test]
    fn the_robust_line_says_where_it_may_be_the_full_range() {
        // A mask with one voxel in a hundred set: both percentiles 0, the full range shown.
        let mask = volume((0..1000).map(|i| (i % 100 == 0) as u8 as f32).collect());
        let j = super::volume_json(&mask, None).unwrap();
        let t = super::volume_text("m.nii", &mask, &j);
        assert!(
            t.contains("(2nd to 98th percentiles, or the full range where those coincide)"),
            "{t}"
        );
        let ramp = volume((0..1000).map(|i| i as f32).collect());
        let j = super::volume_json(&ramp, None).unwrap();
        let t = super::volume_text("r.nii", &ramp, &j);
        assert!(t.contains("(2nd to 98th percentiles)\n"), "{t}");
    }
}
