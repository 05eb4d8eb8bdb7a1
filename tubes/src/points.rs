//! Point clouds for `[[points]]` (Everts et al. 2009 §3.5): read as one [`Streamlines`] whose
//! single "line" holds every point, so colour sources (`scalar:NAME`, `volume:PATH`) and
//! transforms work as for tractograms.
//!
//! * `.ply`: the `vertex` element's `x y z` (ASCII or binary; faces and other properties are
//!   ignored).
//! * `.csv` / `.txt`: one point a row, fields separated by commas, semicolons, tabs or spaces.
//!   A first row that is not all numbers is a header: the columns named `x`, `y`, `z` (any
//!   case) are the position, every other column a per-point scalar of its name. Without a
//!   header the first three columns are x, y, z and the others `column4`, `column5`, ...
//!   Empty rows and rows starting with `#` are skipped.
//! * a tractogram (`.trk`, `.tck`, `.vtk`, `.trx`, see [`crate::load`]): its points, with its
//!   per-point attributes.

use crate::{Attribute, Result, Streamlines, TubesError};
use glam::Vec3;
use std::path::Path;

/// At most this many points (the GPU indexes them with 32 bits).
pub const MAX_POINTS: usize = 1 << 30;

/// Reads a point cloud (see the module doc for the formats).
pub fn read(path: &Path) -> Result<Streamlines> {
    let name = path.to_string_lossy().to_ascii_lowercase();
    let mut s = if name.ends_with(".ply") {
        let m = crate::mesh_io::read(path)?;
        let points = m
            .positions
            .iter()
            .map(|p| (m.origin + p.as_dvec3()).as_vec3())
            .collect();
        one_line(points, vec![])
    } else if name.ends_with(".csv") || name.ends_with(".txt") {
        let text =
            volume::read_text(path, volume::MAX_FILE_BYTES).map_err(|e| TubesError::io(path, e))?;
        read_csv(path, &text)?
    } else {
        let t = crate::load(path)?;
        let mut s = one_line(t.points, t.point_attributes);
        s.warnings = t.warnings;
        s.format = t.format;
        s
    };
    if s.points.len() > MAX_POINTS {
        return Err(TubesError::format(
            path,
            "points",
            format!("{} points: at most {MAX_POINTS}", s.points.len()),
        ));
    }
    if let Some(k) = s.points.iter().position(|p| !p.is_finite()) {
        return Err(TubesError::format(
            path,
            format!("point {k}"),
            format!("the position {:?} is not finite", s.points[k]),
        ));
    }
    if s.format.is_empty() {
        s.format = name.rsplit('.').next().unwrap_or("").to_string();
    }
    Ok(s)
}

fn one_line(points: Vec<Vec3>, point_attributes: Vec<Attribute>) -> Streamlines {
    Streamlines {
        offsets: vec![0, points.len()],
        points,
        point_attributes,
        ..Streamlines::new()
    }
}

/// Reads the CSV text of `path` (see the module doc).
pub fn read_csv(path: &Path, text: &str) -> Result<Streamlines> {
    let split = |line: &str| -> Vec<String> {
        line.split([',', ';', '\t', ' '])
            .map(|f| f.trim().trim_matches('"').to_string())
            .filter(|f| !f.is_empty())
            .collect()
    };
    let mut rows = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    let Some((first_no, first)) = rows.next() else {
        return Err(TubesError::format(path, "rows", "the file has no points"));
    };
    let head = split(first);
    let numeric = head.iter().all(|f| f.parse::<f64>().is_ok());
    let names: Vec<String> = if numeric {
        (0..head.len())
            .map(|k| match k {
                0 => "x".into(),
                1 => "y".into(),
                2 => "z".into(),
                _ => format!("column{}", k + 1),
            })
            .collect()
    } else {
        head.clone()
    };
    let find = |axis: &str| {
        names
            .iter()
            .position(|n| n.eq_ignore_ascii_case(axis))
            .ok_or_else(|| {
                TubesError::format(
                    path,
                    "header",
                    format!("no column '{axis}' (columns: {})", names.join(", ")),
                )
            })
    };
    let xyz = [find("x")?, find("y")?, find("z")?];
    let extra: Vec<usize> = (0..names.len()).filter(|k| !xyz.contains(k)).collect();
    let mut points = vec![];
    let mut values: Vec<Vec<f32>> = vec![vec![]; extra.len()];
    let mut push = |no: usize, fields: &[String]| -> Result<()> {
        if fields.len() != names.len() {
            return Err(TubesError::format(
                path,
                format!("line {}", no + 1),
                format!(
                    "{} fields where the first row has {}",
                    fields.len(),
                    names.len()
                ),
            ));
        }
        let num = |k: usize| -> Result<f64> {
            fields[k].parse::<f64>().map_err(|_| {
                TubesError::format(
                    path,
                    format!("line {} column '{}'", no + 1, names[k]),
                    format!("'{}' is not a number", fields[k]),
                )
            })
        };
        let p = Vec3::new(
            num(xyz[0])? as f32,
            num(xyz[1])? as f32,
            num(xyz[2])? as f32,
        );
        if !p.is_finite() {
            return Err(TubesError::format(
                path,
                format!("line {}", no + 1),
                format!("the position {p:?} is not finite"),
            ));
        }
        if points.len() >= MAX_POINTS {
            return Err(TubesError::format(
                path,
                "rows",
                format!("more than {MAX_POINTS} points"),
            ));
        }
        points.push(p);
        for (v, &k) in values.iter_mut().zip(&extra) {
            v.push(num(k)? as f32);
        }
        Ok(())
    };
    if numeric {
        push(first_no, &head)?;
    }
    for (no, line) in rows {
        push(no, &split(line))?;
    }
    let attributes = extra
        .iter()
        .zip(values)
        .map(|(&k, values)| Attribute {
            name: names[k].clone(),
            components: 1,
            values,
        })
        .collect();
    let mut s = one_line(points, attributes);
    s.format = "csv".into();
    Ok(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_with_and_without_a_header() {
        let p = Path::new("cloud.csv");
        let s = read_csv(p, "# a cloud\nid, Z, x, y\n1, 3, 1, 2\n\n2, 6, 4, 5\n").unwrap();
        assert_eq!(
            s.points,
            vec![Vec3::new(1.0, 2.0, 3.0), Vec3::new(4.0, 5.0, 6.0)]
        );
        assert_eq!(s.offsets, vec![0, 2]);
        assert_eq!(s.point_attributes.len(), 1);
        assert_eq!(s.point_attributes[0].name, "id");
        assert_eq!(s.point_attributes[0].values, vec![1.0, 2.0]);
        let s = read_csv(p, "1 2 3 9\n4\t5\t6\t8\n").unwrap();
        assert_eq!(s.points.len(), 2);
        assert_eq!(s.point_attributes[0].name, "column4");
        assert_eq!(s.point_attributes[0].values, vec![9.0, 8.0]);
    }

    #[test]
    fn bad_csv_names_the_line_and_column() {
        let p = Path::new("cloud.csv");
        let e = read_csv(p, "x,y,z\n1,2,3\n1,two,3\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("cloud.csv") && e.contains("line 3") && e.contains("'y'"),
            "{e}"
        );
        let e = read_csv(p, "x,y,z\n1,2\n").unwrap_err().to_string();
        assert!(e.contains("line 2") && e.contains("2 fields"), "{e}");
        let e = read_csv(p, "a,b,c\n1,2,3\n").unwrap_err().to_string();
        assert!(e.contains("no column 'x'"), "{e}");
        let e = read_csv(p, "x,y,z\n1,nan,3\n").unwrap_err().to_string();
        assert!(e.contains("not finite"), "{e}");
        assert!(read_csv(p, "# nothing\n").is_err());
    }

    #[test]
    fn ply_vertices_and_tractogram_points_are_read() {
        let dir = std::env::temp_dir().join(format!("umbra-points-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let ply = dir.join("c.ply");
        std::fs::write(
            &ply,
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float intensity\nend_header\n0 0 0 1\n1 0 0 2\n10 20 30 3\n",
        )
        .unwrap();
        let s = read(&ply).unwrap();
        assert_eq!(s.points.len(), 3);
        assert!((s.points[2] - Vec3::new(10.0, 20.0, 30.0)).length() < 1e-4);
        let mut t = Streamlines::new();
        t.push(&[Vec3::ZERO, Vec3::X]);
        t.push(&[Vec3::Y]);
        let tck = dir.join("t.tck");
        crate::save(&tck, &t).unwrap();
        let s = read(&tck).unwrap();
        assert_eq!(s.points.len(), 3);
        assert_eq!(s.len(), 1);
        std::fs::remove_dir_all(&dir).ok();
    }
}
