//! `umbra info`: what a file holds, as text or as one JSON object.

use serde_json::{json, Value};
use volume::{FieldSelector, Volume, VolumeError};

/// The JSON description of a volume (keys documented in the README: `format`, `dims`,
/// `components`, `type`, `spacing`, `affine`, `space`, `bounds`, `range`, `nonfinite`, `fields`,
/// plus `field`, the name of the field `range` and `nonfinite` describe).
pub fn volume_json(vol: &Volume, sel: Option<&FieldSelector>) -> Result<Value, VolumeError> {
    let field = vol.select(sel)?;
    let stats = field.stats();
    let a = vol.affine;
    let rows: Vec<Vec<f64>> = (0..4)
        .map(|r| (0..4).map(|c| a.col(c)[r]).collect())
        .collect();
    let [lo, hi] = vol.bounds();
    let num = |v: f64| if v.is_finite() { json!(v) } else { Value::Null };
    Ok(json!({
        "format": vol.format,
        "dims": vol.dims,
        "components": field.components,
        "type": field.stored.name(),
        "spacing": vol.spacing(),
        "affine": rows,
        "space": vol.space.name(),
        "bounds": [[lo.x, lo.y, lo.z], [hi.x, hi.y, hi.z]],
        "range": [num(stats.min), num(stats.max)],
        "nonfinite": stats.nonfinite,
        "fields": vol.field_names(),
        "field": field.name,
    }))
}

/// The same facts as lines of text for a person.
pub fn volume_text(
    path: &str,
    vol: &Volume,
    sel: Option<&FieldSelector>,
) -> Result<String, VolumeError> {
    let j = volume_json(vol, sel)?;
    let mut s = String::new();
    let f3 = |v: &Value| {
        v.as_array()
            .map(|a| {
                a.iter()
                    .map(|x| format!("{:.6}", x.as_f64().unwrap_or(f64::NAN)))
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
                    .map(|x| format!("{:>12.6}", x.as_f64().unwrap_or(f64::NAN)))
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
    s += &format!("non-finite: {} voxels\n", j["nonfinite"]);
    Ok(s)
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
            out += &format!(
                "bounds:      min ({:.3}, {:.3}, {:.3})  max ({:.3}, {:.3}, {:.3})\n",
                lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
            )
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
