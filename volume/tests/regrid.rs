//! `regrid::into_grid` against scipy: tests/fixtures/overlay/make_fixture.py wrote a rotated,
//! anisotropic overlay and label volume (NIfTI, read here with `volume::load`), a destination
//! grid that overlaps them partly, a transform from the destination's world into theirs, and
//! `scipy.ndimage.map_coordinates(order=1|0, mode='constant', cval=nan)` at the same fractional
//! source indices.
//!
//! Where the two may differ, and why:
//! * within 1e-6 voxels of the source's border (rounding in the matrix products decides there);
//! * for nearest, in the half voxel beyond each end (`q` in [-0.5, 0) or [n - 1, n - 0.5)):
//!   scipy's constant mode gives NaN outside [0, n - 1] even with order 0, `Interp::Nearest`
//!   gives the end voxel. There the value is checked against the source directly.

use glam::{DMat4, DVec3};
use serde_json::Value;
use std::path::PathBuf;
use test_support::fixtures;
use volume::regrid::{into_grid, Interp};

/// Distance in source voxels that counts as "on the border".
const BORDER: f64 = 1e-6;

fn dir() -> PathBuf {
    fixtures().join("overlay")
}

fn grid_json() -> Value {
    let text = std::fs::read_to_string(dir().join("grid.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// A 4 x 4 matrix written as a list of rows.
fn matrix(v: &Value) -> DMat4 {
    let rows: Vec<Vec<f64>> = serde_json::from_value(v.clone()).unwrap();
    assert_eq!(rows.len(), 4);
    let mut a = [[0.0; 4]; 4];
    for (r, row) in rows.iter().enumerate() {
        assert_eq!(row.len(), 4);
        a[r].copy_from_slice(row);
    }
    DMat4::from_cols_array_2d(&a).transpose()
}

fn dims(v: &Value) -> [usize; 3] {
    let d: Vec<usize> = serde_json::from_value(v.clone()).unwrap();
    [d[0], d[1], d[2]]
}

fn read_f32(name: &str) -> Vec<f32> {
    let bytes = std::fs::read(dir().join(name)).unwrap();
    assert_eq!(bytes.len() % 4, 0);
    bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
        .collect()
}

/// The fixture: the source volume's samples and grid, the destination grid, the transform.
struct Case {
    src: Vec<f32>,
    src_dims: [usize; 3],
    src_affine: DMat4,
    transform: DMat4,
    dst_dims: [usize; 3],
    dst_affine: DMat4,
}

impl Case {
    fn load(file: &str, stored: &str) -> Case {
        let g = grid_json();
        let vol = volume::load(&dir().join(file)).unwrap();
        let src_dims = dims(&g["source"]["dims"]);
        let src_affine = matrix(&g["source"]["affine"]);
        assert_eq!(vol.dims, src_dims);
        let (a, b) = (vol.affine.to_cols_array(), src_affine.to_cols_array());
        for (x, y) in a.iter().zip(b) {
            assert!((x - y).abs() <= 1e-12 * y.abs().max(1.0), "{a:?} vs {b:?}");
        }
        assert_eq!(vol.default().components, 1);
        assert_eq!(vol.default().stored.name(), stored);
        Case {
            src: vol.default().data.clone(),
            src_dims,
            src_affine: vol.affine,
            transform: matrix(&g["transform"]),
            dst_dims: dims(&g["destination"]["dims"]),
            dst_affine: matrix(&g["destination"]["affine"]),
        }
    }

    fn run(&self, interp: Interp) -> Vec<f32> {
        into_grid(
            &self.src,
            self.src_dims,
            self.src_affine,
            self.transform,
            self.dst_dims,
            self.dst_affine,
            interp,
        )
        .unwrap()
    }

    /// The fractional source index of every destination voxel, x fastest.
    fn q(&self) -> Vec<DVec3> {
        let m = self.src_affine.inverse() * self.transform * self.dst_affine;
        let [nx, ny, nz] = self.dst_dims;
        let mut out = Vec::with_capacity(nx * ny * nz);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    out.push(m.transform_point3(DVec3::new(i as f64, j as f64, k as f64)));
                }
            }
        }
        out
    }

    /// Signed distance of `q` inside the box [0, n - 1] of the source's voxel centres
    /// (negative outside).
    fn inside(&self, q: DVec3) -> f64 {
        (0..3)
            .map(|a| q[a].min((self.src_dims[a] - 1) as f64 - q[a]))
            .fold(f64::INFINITY, f64::min)
    }

    /// The source voxel nearest to `q` (which must be within half a voxel of the grid).
    fn nearest_voxel(&self, q: DVec3) -> f32 {
        let r = (q + 0.5).floor();
        let [nx, ny, _] = self.src_dims;
        self.src[r.x as usize + nx * (r.y as usize + ny * r.z as usize)]
    }
}

#[test]
fn linear_matches_scipy() {
    let case = Case::load("overlay.nii.gz", "float32");
    let got = case.run(Interp::Linear);
    let want = read_f32("expected_linear.f32");
    assert_eq!(got.len(), want.len());
    let (mut both, mut border) = (0, 0);
    for (n, (q, (g, w))) in case.q().into_iter().zip(got.iter().zip(&want)).enumerate() {
        match (g.is_finite(), w.is_finite()) {
            (true, true) => {
                both += 1;
                assert!(
                    (g - w).abs() <= 1e-5,
                    "voxel {n}: {g} vs scipy {w} (q = {q})"
                );
            }
            (false, false) => assert!(g.is_nan()),
            _ => {
                border += 1;
                let d = case.inside(q);
                assert!(
                    d.abs() < BORDER,
                    "voxel {n}: {g} vs scipy {w}, {d} voxels from the border (q = {q})"
                );
            }
        }
    }
    assert!(both > 300, "only {both} voxels compared");
    assert!(border < 5, "{border} voxels on the border");
}

#[test]
fn nearest_matches_scipy() {
    let case = Case::load("overlay.nii.gz", "float32");
    let got = case.run(Interp::Nearest);
    let want = read_f32("expected_nearest.f32");
    compare_nearest(&case, &got, &want);
}

#[test]
fn labels_stay_labels() {
    let case = Case::load("labels.nii.gz", "int16");
    let labels: Vec<f32> = serde_json::from_value::<Vec<i64>>(grid_json()["labels"].clone())
        .unwrap()
        .into_iter()
        .map(|l| l as f32)
        .collect();
    let mut present: Vec<f32> = case.src.clone();
    present.sort_by(f32::total_cmp);
    present.dedup();
    assert_eq!(present, labels, "the label volume's labels");

    let got = case.run(Interp::Nearest);
    let mut seen = Vec::new();
    for v in got.iter().filter(|v| v.is_finite()) {
        assert!(labels.contains(v), "{v} is not a label");
        if !seen.contains(v) {
            seen.push(*v);
        }
    }
    assert!(seen.len() >= 4, "only labels {seen:?} came out");
    compare_nearest(&case, &got, &read_f32("expected_labels_nearest.f32"));

    // Linear interpolation of labels makes values that are no label: what Nearest is for.
    let linear = case.run(Interp::Linear);
    assert!(linear.iter().any(|v| v.is_finite() && !labels.contains(v)));
}

fn compare_nearest(case: &Case, got: &[f32], want: &[f32]) {
    assert_eq!(got.len(), want.len());
    let (mut both, mut half_voxel) = (0, 0);
    for (n, (q, (g, w))) in case.q().into_iter().zip(got.iter().zip(want)).enumerate() {
        let d = case.inside(q);
        if w.is_finite() {
            both += 1;
            assert_eq!(
                g.to_bits(),
                w.to_bits(),
                "voxel {n}: {g} vs scipy {w} (q = {q})"
            );
        } else if g.is_finite() {
            // scipy's NaN beyond [0, n - 1]; into_grid's half voxel there.
            half_voxel += 1;
            assert!(
                (-0.5..BORDER).contains(&d),
                "voxel {n}: {g} where scipy has NaN, {d} voxels inside (q = {q})"
            );
            assert_eq!(g.to_bits(), case.nearest_voxel(q).to_bits(), "voxel {n}");
        } else if d >= 0.0 {
            // Both NaN inside the source: the voxel itself is NaN.
            assert!(
                case.nearest_voxel(q).is_nan(),
                "voxel {n}: NaN inside (q = {q})"
            );
        } else {
            let outside = (0..3).any(|a| q[a] < -0.5 || q[a] >= case.src_dims[a] as f64 - 0.5);
            assert!(
                outside || case.nearest_voxel(q).is_nan(),
                "voxel {n}: NaN within half a voxel of the source (q = {q})"
            );
        }
    }
    assert!(both > 300, "only {both} voxels compared");
    assert!(half_voxel > 0, "the half-voxel margin was not exercised");
}
