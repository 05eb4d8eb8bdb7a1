//! CFD grid readers and resampling on the real grids of ../shared/data/cfd (skipped with a
//! message when ../shared is absent) and on small grids written here.
//!
//! The strongest check: replace a grid's data with a linear function of position and resample;
//! every interpolation umbra uses (barycentric, trilinear, isoparametric) reproduces linear
//! functions exactly, so any sample off by more than rounding means a wrong cell, wrong node
//! order or wrong weights — on the real meshes' own geometry.

use glam::DVec3;
use std::path::Path;
use test_support::shared_or_skip;
use volume::cfd_grid::{CfdGrid, Geometry, GridArray};

fn linear(p: DVec3) -> f64 {
    0.7 * p.x - 1.3 * p.y + 0.4 * p.z + 2.0
}

fn node_positions(g: &CfdGrid) -> Vec<DVec3> {
    match &g.geometry {
        Geometry::Rectilinear { x, y, z } => {
            let mut out = Vec::new();
            for &zz in z {
                for &yy in y {
                    for &xx in x {
                        out.push(DVec3::new(xx, yy, zz));
                    }
                }
            }
            out
        }
        Geometry::Structured { points, .. } | Geometry::Unstructured { points, .. } => {
            points.clone()
        }
    }
}

/// Puts `linear` on the nodes, resamples, and returns (max error, samples inside).
fn linear_error(mut g: CfdGrid, dims: [usize; 3]) -> (f64, usize) {
    let data = node_positions(&g)
        .iter()
        .map(|&p| linear(p) as f32)
        .collect();
    g.arrays.push(GridArray {
        name: "lin".into(),
        components: 1,
        on_cells: false,
        data,
    });
    let vol = g.resample("lin", dims).unwrap();
    let f = vol.select(None).unwrap();
    let mut worst: f64 = 0.0;
    let mut inside = 0;
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let v = f.data[i + dims[0] * (j + dims[1] * k)];
                if v.is_nan() {
                    continue;
                }
                inside += 1;
                let p = vol.index_to_world(DVec3::new(i as f64, j as f64, k as f64));
                worst = worst.max((v as f64 - linear(p)).abs());
            }
        }
    }
    (worst, inside)
}

fn load(dir: &Path, name: &str, q: Option<&str>) -> (CfdGrid, Vec<String>) {
    let qp = q.map(|q| dir.join("cfd").join(q));
    volume::load_grid(&dir.join("cfd").join(name), qp.as_deref()).unwrap()
}

#[test]
fn linear_fields_are_reproduced_on_every_real_grid() {
    let Some(dir) = shared_or_skip("linear_fields_are_reproduced_on_every_real_grid") else {
        return;
    };
    // f32 node data of magnitude ~40 carry ~4e-6 rounding; Newton stops at 1e-10.
    for (name, q, dims, min_inside) in [
        ("fire_ug.vtu", None, [40, 20, 20], 0.9),
        ("office.binary.vtk", None, [30, 30, 20], 0.99),
        ("kitchen.vtk", None, [30, 24, 12], 0.99),
        ("cth.vtr", None, [40, 20, 20], 0.99),
        ("combxyz.bin", Some("combq.bin"), [40, 30, 30], 0.3),
        ("bluntfinxyz.bin", Some("bluntfinq.bin"), [40, 20, 16], 0.5),
    ] {
        let (g, _) = load(&dir, name, q);
        let (err, inside) = linear_error(g, dims);
        let frac = inside as f64 / (dims[0] * dims[1] * dims[2]) as f64;
        assert!(err < 2e-4, "{name}: linear field off by {err}");
        assert!(frac >= min_inside, "{name}: only {frac} of samples inside");
    }
}

#[test]
fn real_grids_have_their_documented_shapes_and_arrays() {
    let Some(dir) = shared_or_skip("real_grids_have_their_documented_shapes_and_arrays") else {
        return;
    };
    let (cth, _) = load(&dir, "cth.vtr", None);
    assert_eq!(
        (cth.n_points(), cth.n_cells()),
        (129 * 65 * 65, 128 * 64 * 64)
    );
    assert!(cth.arrays.iter().all(|a| a.on_cells));
    let (fire, _) = load(&dir, "fire_ug.vtu", None);
    assert_eq!(fire.n_points(), 12_323);
    let uvw = fire.arrays.iter().find(|a| a.name == "uvw").unwrap();
    assert_eq!(uvw.components, 3);
    let (office, _) = load(&dir, "office.binary.vtk", None);
    assert!(matches!(
        office.geometry,
        Geometry::Structured {
            dims: [21, 20, 20],
            ..
        }
    ));
    let (kitchen, _) = load(&dir, "kitchen.vtk", None);
    assert!(matches!(
        kitchen.geometry,
        Geometry::Structured {
            dims: [28, 24, 17],
            ..
        }
    ));
    let hpor = kitchen.arrays.iter().find(|a| a.name == "hpor").unwrap();
    assert!(hpor.data.iter().all(|&v| v == 0.0 || v == 1.0));
    assert!(hpor.data.contains(&1.0));
    let (comb, warn) = load(&dir, "combxyz.bin", Some("combq.bin"));
    assert!(warn.is_empty());
    assert!(matches!(
        comb.geometry,
        Geometry::Structured {
            dims: [57, 33, 25],
            ..
        }
    ));
    let get = |n: &str| &comb.arrays.iter().find(|a| a.name == n).unwrap().data;
    let (rho, m, u) = (get("density"), get("momentum"), get("velocity"));
    for i in (0..rho.len()).step_by(97) {
        for c in 0..3 {
            let back = u[3 * i + c] * rho[i];
            assert!((back - m[3 * i + c]).abs() <= 1e-5 * m[3 * i + c].abs().max(1.0));
        }
    }
    let (_, warn) = load(&dir, "bluntfinxyz.bin", Some("bluntfinq.bin"));
    assert!(warn[0].contains("484 trailing bytes"), "{warn:?}");
}

#[test]
fn cell_data_resamples_to_exact_cell_values_and_vectors_assemble() {
    let Some(dir) = shared_or_skip("cell_data_resamples_to_exact_cell_values_and_vectors_assemble")
    else {
        return;
    };
    let (cth, _) = load(&dir, "cth.vtr", None);
    let dims = [50, 26, 26];
    let vol = cth
        .resample("X Velocity,Y Velocity,Z Velocity", dims)
        .unwrap();
    let f = vol.select(None).unwrap();
    assert_eq!(f.components, 3);
    let col = |n: &str| &cth.arrays.iter().find(|a| a.name == n).unwrap().data;
    let mut triples = std::collections::HashSet::new();
    let (x, y, z) = (col("X Velocity"), col("Y Velocity"), col("Z Velocity"));
    for i in 0..x.len() {
        triples.insert([x[i].to_bits(), y[i].to_bits(), z[i].to_bits()]);
    }
    // Piecewise-constant cell data: every sample is some cell's own (vx, vy, vz).
    for s in f.data.chunks(3) {
        assert!(triples.contains(&[s[0].to_bits(), s[1].to_bits(), s[2].to_bits()]));
    }
    // uvw and u,v,w of the fire grid give the same vectors.
    let (fire, _) = load(&dir, "fire_ug.vtu", None);
    let a = fire.resample("uvw", [30, 12, 12]).unwrap();
    let b = fire.resample("u,v,w", [30, 12, 12]).unwrap();
    let (fa, fb) = (a.select(None).unwrap(), b.select(None).unwrap());
    let max = fa
        .data
        .iter()
        .zip(&fb.data)
        .filter(|(p, q)| !p.is_nan() || !q.is_nan())
        .map(|(p, q)| (p - q).abs())
        .fold(0.0f32, f32::max);
    assert!(max < 1e-4, "uvw vs u,v,w differ by {max}");
}

fn vtu(types: &[(u8, &[u32])], points: &[[f32; 3]], cell_values: &[f32]) -> String {
    let pts: Vec<String> = points
        .iter()
        .map(|p| format!("{} {} {}", p[0], p[1], p[2]))
        .collect();
    let mut conn = Vec::new();
    let mut offs = Vec::new();
    for (_, ids) in types {
        conn.extend(ids.iter().map(|i| i.to_string()));
        offs.push(conn.len().to_string());
    }
    let tys: Vec<String> = types.iter().map(|(t, _)| t.to_string()).collect();
    let cv: Vec<String> = cell_values.iter().map(|v| v.to_string()).collect();
    format!(
        r#"<?xml version="1.0"?>
<VTKFile type="UnstructuredGrid" version="0.1" byte_order="LittleEndian">
  <UnstructuredGrid>
    <Piece NumberOfPoints="{}" NumberOfCells="{}">
      <CellData><DataArray type="Float32" Name="id" format="ascii">{}</DataArray></CellData>
      <Points><DataArray type="Float32" NumberOfComponents="3" format="ascii">{}</DataArray></Points>
      <Cells>
        <DataArray type="Int32" Name="connectivity" format="ascii">{}</DataArray>
        <DataArray type="Int32" Name="offsets" format="ascii">{}</DataArray>
        <DataArray type="UInt8" Name="types" format="ascii">{}</DataArray>
      </Cells>
    </Piece>
  </UnstructuredGrid>
</VTKFile>
"#,
        points.len(),
        types.len(),
        cv.join(" "),
        pts.join(" "),
        conn.join(" "),
        offs.join(" "),
        tys.join(" ")
    )
}

#[test]
fn voxels_wedges_and_pyramids_are_split_and_bad_cells_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    // A unit voxel (x 0..1), a wedge (x 1..2) and a pyramid (x 2..3) side by side.
    let mut pts = Vec::new();
    for k in 0..2 {
        for j in 0..2 {
            for i in 0..4 {
                pts.push([i as f32, j as f32, k as f32]);
            }
        }
    }
    let id = |i: u32, j: u32, k: u32| i + 4 * (j + 2 * k);
    let voxel = [
        id(0, 0, 0),
        id(1, 0, 0),
        id(0, 1, 0),
        id(1, 1, 0),
        id(0, 0, 1),
        id(1, 0, 1),
        id(0, 1, 1),
        id(1, 1, 1),
    ];
    // Wedge: triangle (1,0,0) (2,0,0) (1,1,0) extruded in z.
    let wedge = [
        id(1, 0, 0),
        id(2, 0, 0),
        id(1, 1, 0),
        id(1, 0, 1),
        id(2, 0, 1),
        id(1, 1, 1),
    ];
    // Pyramid: base square x 2..3, z 0..1 at y = 0, apex (3,1,1).
    let pyramid = [
        id(2, 0, 0),
        id(3, 0, 0),
        id(3, 0, 1),
        id(2, 0, 1),
        id(3, 1, 1),
    ];
    let text = vtu(
        &[(11, &voxel), (13, &wedge), (14, &pyramid)],
        &pts,
        &[10.0, 20.0, 30.0],
    );
    let p = dir.path().join("mixed.vtu");
    std::fs::write(&p, text).unwrap();
    let (g, _) = volume::load_grid(&p, None).unwrap();
    // 1 hex + 3 tets + 2 tets; cell data repeated onto the pieces.
    assert_eq!(g.n_cells(), 6);
    assert_eq!(g.arrays[0].data, vec![10.0, 20.0, 20.0, 20.0, 30.0, 30.0]);
    let (err, inside) = linear_error(g.clone(), [13, 5, 5]);
    assert!(err < 1e-5, "linear field off by {err}");
    assert!(inside > 100);
    // Sample (0.5, 0.5, 0.5) of the voxel: cell value 10; inside the wedge: 20.
    let v = g.resample("id", [7, 3, 3]).unwrap();
    let f = v.select(None).unwrap();
    let at = |i: usize, j: usize, k: usize| f.data[i + 7 * (j + 3 * k)];
    assert_eq!(at(1, 1, 1), 10.0);
    assert_eq!(at(3, 0, 1), 20.0); // x = 1.5, y = 0, z = 0.5: wedge face
    assert!(at(5, 2, 0).is_nan()); // x = 2.5, y = 1, z = 0: above the pyramid's base, outside

    // A triangle (type 5) is refused with its type named.
    std::fs::write(&p, vtu(&[(5, &[0, 1, 2])], &pts, &[1.0])).unwrap();
    let e = volume::load_grid(&p, None).unwrap_err().to_string();
    assert!(e.contains("mixed.vtu") && e.contains("VTK type 5"), "{e}");
    // A connectivity id past the points.
    std::fs::write(&p, vtu(&[(10, &[0, 1, 2, 99])], &pts, &[1.0])).unwrap();
    let e = volume::load_grid(&p, None).unwrap_err().to_string();
    assert!(e.contains("connectivity") && e.contains("99"), "{e}");
    // NaN coordinates.
    let mut bad = pts.clone();
    bad[0][1] = f32::NAN;
    std::fs::write(&p, vtu(&[(10, &[0, 1, 4, 15])], &bad, &[1.0])).unwrap();
    let e = volume::load_grid(&p, None).unwrap_err().to_string();
    assert!(
        e.contains("points") && e.contains("NaN") && e.contains("must be finite"),
        "{e}"
    );
    assert!(!e.contains("DVec3"), "{e}");
}

#[test]
fn truncated_and_mismatched_legacy_grids_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("g.vtk");
    let good = "# vtk DataFile Version 3.0\nt\nASCII\nDATASET STRUCTURED_GRID\nDIMENSIONS 2 2 1\nPOINTS 4 float\n0 0 0 1 0 0 0 1 0 1 1 0\nPOINT_DATA 4\nSCALARS s float\nLOOKUP_TABLE default\n1 2 3 4\n";
    std::fs::write(&p, good).unwrap();
    let (g, _) = volume::load_grid(&p, None).unwrap();
    assert_eq!(g.n_points(), 4);
    std::fs::write(&p, good.replace("POINTS 4", "POINTS 5")).unwrap();
    let e = volume::load_grid(&p, None).unwrap_err().to_string();
    assert!(e.contains("g.vtk") && e.contains("POINTS"), "{e}");
    std::fs::write(&p, &good[..good.len() - 4]).unwrap();
    let e = volume::load_grid(&p, None).unwrap_err().to_string();
    assert!(e.contains("g.vtk") && e.contains("SCALARS s"), "{e}");
    // Reading a grid as a volume says what to do.
    std::fs::write(&p, good).unwrap();
    let e = volume::load(&p).unwrap_err().to_string();
    assert!(e.contains("umbra resample"), "{e}");
    // Decreasing rectilinear coordinates.
    let r = "# vtk DataFile Version 3.0\nt\nASCII\nDATASET RECTILINEAR_GRID\nDIMENSIONS 2 2 2\nX_COORDINATES 2 float\n1 0\nY_COORDINATES 2 float\n0 1\nZ_COORDINATES 2 float\n0 1\nPOINT_DATA 8\nSCALARS s float\n1 2 3 4 5 6 7 8\n";
    std::fs::write(&p, r).unwrap();
    let e = volume::load_grid(&p, None).unwrap_err().to_string();
    assert!(
        e.contains("x coordinates") && e.contains("not increasing"),
        "{e}"
    );
}

#[test]
fn legacy_unstructured_grids_in_both_layouts_match_the_xml_grid() {
    let dir = test_support::fixtures().join("grids");
    let load = |n: &str| volume::load_grid(&dir.join(n), None).unwrap().0;
    let xml = load("fire_part.vtu");
    let dims = [24, 8, 4];
    let reference = xml.resample("uvw", dims).unwrap();
    let rf = reference.select(None).unwrap();
    // Cells of mixed types: the XML file's own counts.
    assert_eq!((xml.n_points(), xml.n_cells()), (712, 300));
    for name in ["fire_part_42_ascii.vtk", "fire_part_51_binary.vtk"] {
        let g = load(name);
        assert_eq!(
            (g.n_points(), g.n_cells()),
            (xml.n_points(), xml.n_cells()),
            "{name}"
        );
        let v = g.resample("uvw", dims).unwrap();
        let f = v.select(None).unwrap();
        for (a, b) in f.data.iter().zip(&rf.data) {
            assert_eq!(a.is_nan(), b.is_nan(), "{name}: inside/outside differ");
            if !a.is_nan() {
                // The ASCII file carries 6 significant digits.
                assert!(
                    (a - b).abs() <= 1e-4 * (1.0 + b.abs()),
                    "{name}: {a} vs {b}"
                );
            }
        }
        let (err, inside) = linear_error(g.clone(), dims);
        assert!(
            err < 1e-4 && inside > 100,
            "{name}: linear field off by {err}"
        );
        // Cell data stay with their cells.
        let c = g.resample("cell_id", dims).unwrap();
        let cx = xml.resample("cell_id", dims).unwrap();
        let (c, cx) = (c.select(None).unwrap(), cx.select(None).unwrap());
        let same = c
            .data
            .iter()
            .zip(&cx.data)
            .filter(|(a, b)| a == b || (a.is_nan() && b.is_nan()))
            .count();
        assert!(
            same as f64 >= 0.99 * c.data.len() as f64,
            "{name}: {same} of {}",
            c.data.len()
        );
    }
    // A CELLS list that runs past its declared size.
    let text = std::fs::read_to_string(dir.join("fire_part_42_ascii.vtk")).unwrap();
    let bad = text.replacen("CELLS 300 2700", "CELLS 300 2000", 1);
    assert!(bad != text, "fixture layout changed");
    let t = tempfile::tempdir().unwrap();
    let p = t.path().join("bad.vtk");
    std::fs::write(&p, bad).unwrap();
    let e = volume::load_grid(&p, None).unwrap_err().to_string();
    assert!(e.contains("bad.vtk") && e.contains("CELL"), "{e}");
}
