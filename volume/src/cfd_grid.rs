//! Curvilinear, rectilinear and unstructured CFD grids, located and resampled onto regular
//! grids (the [`Volume`] every other stage uses).
//!
//! # Interpolation
//! * Point data are interpolated with the cell's own shape functions: trilinear (isoparametric)
//!   in hexahedra, which covers curvilinear cells (the parametric coordinates of a point are
//!   found by Newton's method on the trilinear map from the cell's corners) and rectilinear
//!   cells (per-axis binary search, then trilinear), and barycentric in tetrahedra. Both
//!   reproduce fields that are linear in space exactly, whatever the cell's shape.
//! * Cell data are constant over their cell.
//! * Outside the mesh the result is NaN (no extrapolation); the renderer and the tracer treat
//!   NaN as "no data".
//!
//! # Location
//! Cells are binned by their bounding boxes into a uniform grid of buckets (about one cell per
//! bucket); a point is tested against the cells of its bucket. Every regular sample is located
//! independently, in parallel.

use crate::{Field, FieldPart, FieldSelector, Result, ScalarType, Space, Volume, VolumeError};
use glam::{DMat3, DMat4, DVec3, DVec4};
use rayon::prelude::*;

/// The shape of a grid.
#[derive(Clone, Debug)]
pub enum Geometry {
    /// Axis-aligned with per-axis coordinates (node positions).
    Rectilinear {
        x: Vec<f64>,
        y: Vec<f64>,
        z: Vec<f64>,
    },
    /// Curvilinear: `dims` nodes, positions x fastest.
    Structured {
        dims: [usize; 3],
        points: Vec<DVec3>,
    },
    /// Cells over a point list.
    Unstructured {
        points: Vec<DVec3>,
        cells: Vec<Cell>,
    },
}

/// A cell of an unstructured grid: a tetrahedron (4 ids) or a hexahedron (8 ids in VTK's
/// hexahedron order: bottom face counter-clockwise, then the top face).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cell {
    Tet([u32; 4]),
    Hex([u32; 8]),
}

/// A named array on points or cells.
#[derive(Clone, Debug)]
pub struct GridArray {
    pub name: String,
    pub components: usize,
    pub on_cells: bool,
    pub data: Vec<f32>,
}

/// A CFD grid with its arrays.
#[derive(Clone, Debug)]
pub struct CfdGrid {
    pub format: String,
    pub geometry: Geometry,
    pub arrays: Vec<GridArray>,
}

/// Corners of structured cell (i, j, k) in VTK hexahedron order; node indices are clamped to
/// the grid, so a flat axis (one node) gives a cell of repeated nodes.
fn structured_corners(dims: [usize; 3], i: usize, j: usize, k: usize) -> [usize; 8] {
    let id = |a: usize, b: usize, c: usize| {
        a.min(dims[0] - 1) + dims[0] * (b.min(dims[1] - 1) + dims[1] * c.min(dims[2] - 1))
    };
    [
        id(i, j, k),
        id(i + 1, j, k),
        id(i + 1, j + 1, k),
        id(i, j + 1, k),
        id(i, j, k + 1),
        id(i + 1, j, k + 1),
        id(i + 1, j + 1, k + 1),
        id(i, j + 1, k + 1),
    ]
}

/// Trilinear shape functions in VTK hexahedron order at parametric `(r, s, t)`.
fn hex_weights(p: DVec3) -> [f64; 8] {
    let (r, s, t) = (p.x, p.y, p.z);
    let (rm, sm, tm) = (1.0 - r, 1.0 - s, 1.0 - t);
    [
        rm * sm * tm,
        r * sm * tm,
        r * s * tm,
        rm * s * tm,
        rm * sm * t,
        r * sm * t,
        r * s * t,
        rm * s * t,
    ]
}

/// Parametric coordinates of `x` in the hexahedron with corners `c`, or `None` outside.
fn hex_locate(c: &[DVec3; 8], x: DVec3) -> Option<DVec3> {
    let mut p = DVec3::splat(0.5);
    for _ in 0..20 {
        let w = hex_weights(p);
        let f: DVec3 = (0..8).map(|a| c[a] * w[a]).sum::<DVec3>() - x;
        let (r, s, t) = (p.x, p.y, p.z);
        let (rm, sm, tm) = (1.0 - r, 1.0 - s, 1.0 - t);
        // Derivatives of the weights.
        let dr = [
            -sm * tm,
            sm * tm,
            s * tm,
            -s * tm,
            -sm * t,
            sm * t,
            s * t,
            -s * t,
        ];
        let ds = [
            -rm * tm,
            -r * tm,
            r * tm,
            rm * tm,
            -rm * t,
            -r * t,
            r * t,
            rm * t,
        ];
        let dt = [
            -rm * sm,
            -r * sm,
            -r * s,
            -rm * s,
            rm * sm,
            r * sm,
            r * s,
            rm * s,
        ];
        let j = DMat3::from_cols(
            (0..8).map(|a| c[a] * dr[a]).sum(),
            (0..8).map(|a| c[a] * ds[a]).sum(),
            (0..8).map(|a| c[a] * dt[a]).sum(),
        );
        let det = j.determinant();
        if det.abs() < 1e-300 {
            return None;
        }
        let dp = j.inverse() * f;
        p -= dp;
        if p.abs().max_element() > 10.0 {
            return None;
        }
        if dp.length() < 1e-10 {
            break;
        }
    }
    let eps = 1e-7;
    if !(p.min_element() >= -eps && p.max_element() <= 1.0 + eps) {
        return None;
    }
    let p = p.clamp(DVec3::ZERO, DVec3::ONE);
    // Newton may stall in strongly distorted cells: accept only a converged position.
    let w = hex_weights(p);
    let residual = ((0..8).map(|a| c[a] * w[a]).sum::<DVec3>() - x).length();
    let size = (c[6] - c[0]).length().max((c[7] - c[1]).length());
    (residual <= 1e-6 * size.max(1e-300)).then_some(p)
}

/// Barycentric coordinates of `x` in a tetrahedron, or `None` outside.
fn tet_locate(c: &[DVec3; 4], x: DVec3) -> Option<[f64; 4]> {
    let m = DMat3::from_cols(c[1] - c[0], c[2] - c[0], c[3] - c[0]);
    if m.determinant().abs() < 1e-300 {
        return None;
    }
    let l = m.inverse() * (x - c[0]);
    let w = [1.0 - l.x - l.y - l.z, l.x, l.y, l.z];
    let eps = 1e-9;
    w.iter().all(|&v| v >= -eps).then_some(w)
}

/// A located sample: the cell index and the weights of its nodes.
enum Hit {
    Nodes {
        cell: usize,
        nodes: Vec<(usize, f64)>,
    },
}

/// Buckets of cell indices over the grid's bounds.
struct Buckets {
    lo: DVec3,
    size: DVec3,
    n: [usize; 3],
    cells: Vec<Vec<u32>>,
}

impl Buckets {
    fn new(bounds: [DVec3; 2], boxes: &[[DVec3; 2]]) -> Self {
        let count = boxes.len().max(1) as f64;
        let ext = (bounds[1] - bounds[0]).max(DVec3::splat(1e-12));
        // About one cell per bucket, the same bucket size along each axis.
        let vol = ext.x * ext.y * ext.z;
        let h = (vol / count).cbrt().max(1e-12);
        let n = [0, 1, 2].map(|a| ((ext[a] / h).ceil() as usize).clamp(1, 512));
        let size = DVec3::new(
            ext.x / n[0] as f64,
            ext.y / n[1] as f64,
            ext.z / n[2] as f64,
        );
        let mut cells = vec![Vec::new(); n[0] * n[1] * n[2]];
        for (ci, b) in boxes.iter().enumerate() {
            let i0 = [0, 1, 2].map(|a| {
                (((b[0][a] - bounds[0][a]) / size[a]).floor().max(0.0) as usize).min(n[a] - 1)
            });
            let i1 = [0, 1, 2].map(|a| {
                (((b[1][a] - bounds[0][a]) / size[a]).floor().max(0.0) as usize).min(n[a] - 1)
            });
            for k in i0[2]..=i1[2] {
                for j in i0[1]..=i1[1] {
                    for i in i0[0]..=i1[0] {
                        cells[i + n[0] * (j + n[1] * k)].push(ci as u32);
                    }
                }
            }
        }
        Buckets {
            lo: bounds[0],
            size,
            n,
            cells,
        }
    }

    fn at(&self, p: DVec3) -> &[u32] {
        let q = (p - self.lo) / self.size;
        if q.min_element() < -1e-9 {
            return &[];
        }
        let idx = [0, 1, 2].map(|a| (q[a].max(0.0) as usize).min(self.n[a] - 1));
        if (0..3).any(|a| q[a] > self.n[a] as f64 + 1e-9) {
            return &[];
        }
        &self.cells[idx[0] + self.n[0] * (idx[1] + self.n[1] * idx[2])]
    }
}

/// Point location for one grid.
pub struct Locator<'a> {
    grid: &'a CfdGrid,
    buckets: Option<Buckets>,
    /// Bounding box of each cell, slightly enlarged: a cheap test before Newton's method.
    boxes: Vec<[DVec3; 2]>,
}

fn grow(b: [DVec3; 2]) -> [DVec3; 2] {
    let e = (b[1] - b[0]).max_element() * 1e-7 + 1e-12;
    [b[0] - DVec3::splat(e), b[1] + DVec3::splat(e)]
}

fn in_box(b: &[DVec3; 2], x: DVec3) -> bool {
    x.cmpge(b[0]).all() && x.cmple(b[1]).all()
}

impl<'a> Locator<'a> {
    pub fn new(grid: &'a CfdGrid) -> Self {
        let (buckets, boxes) = match &grid.geometry {
            Geometry::Rectilinear { .. } => (None, Vec::new()),
            Geometry::Structured { dims, points } => {
                let nc = [
                    dims[0].saturating_sub(1),
                    dims[1].saturating_sub(1),
                    dims[2].saturating_sub(1),
                ];
                let mut boxes = Vec::with_capacity(nc[0] * nc[1] * nc[2]);
                for k in 0..nc[2] {
                    for j in 0..nc[1] {
                        for i in 0..nc[0] {
                            let c = structured_corners(*dims, i, j, k);
                            let (mut lo, mut hi) =
                                (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
                            for id in c {
                                lo = lo.min(points[id]);
                                hi = hi.max(points[id]);
                            }
                            boxes.push([lo, hi]);
                        }
                    }
                }
                (Some(Buckets::new(grid.bounds(), &boxes)), boxes)
            }
            Geometry::Unstructured { points, cells } => {
                let boxes: Vec<[DVec3; 2]> = cells
                    .iter()
                    .map(|c| {
                        let ids: &[u32] = match c {
                            Cell::Tet(i) => i,
                            Cell::Hex(i) => i,
                        };
                        let (mut lo, mut hi) =
                            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
                        for &id in ids {
                            lo = lo.min(points[id as usize]);
                            hi = hi.max(points[id as usize]);
                        }
                        [lo, hi]
                    })
                    .collect();
                (Some(Buckets::new(grid.bounds(), &boxes)), boxes)
            }
        };
        let boxes = boxes.into_iter().map(grow).collect();
        Locator {
            grid,
            buckets,
            boxes,
        }
    }

    fn locate(&self, x: DVec3) -> Option<Hit> {
        match &self.grid.geometry {
            Geometry::Rectilinear {
                x: xs,
                y: ys,
                z: zs,
            } => {
                let find = |c: &[f64], v: f64| -> Option<(usize, f64)> {
                    if c.len() < 2 {
                        return (c.len() == 1 && (v - c[0]).abs() < 1e-12).then_some((0, 0.0));
                    }
                    let (a, b) = (c[0].min(c[c.len() - 1]), c[0].max(c[c.len() - 1]));
                    if v < a || v > b {
                        return None;
                    }
                    let inc = c[c.len() - 1] >= c[0];
                    let i = if inc {
                        c.partition_point(|&q| q <= v)
                    } else {
                        c.partition_point(|&q| q >= v)
                    };
                    let i = i.clamp(1, c.len() - 1) - 1;
                    let f = (v - c[i]) / (c[i + 1] - c[i]);
                    Some((i, f.clamp(0.0, 1.0)))
                };
                let (i, fx) = find(xs, x.x)?;
                let (j, fy) = find(ys, x.y)?;
                let (k, fz) = find(zs, x.z)?;
                let d = [xs.len(), ys.len(), zs.len()];
                let nc = [
                    d[0].saturating_sub(1).max(1),
                    d[1].saturating_sub(1).max(1),
                    d[2].saturating_sub(1).max(1),
                ];
                let cell = i.min(nc[0] - 1) + nc[0] * (j.min(nc[1] - 1) + nc[1] * k.min(nc[2] - 1));
                let w = hex_weights(DVec3::new(fx, fy, fz));
                let corners = structured_corners(d, i, j, k);
                Some(Hit::Nodes {
                    cell,
                    nodes: corners.iter().copied().zip(w).collect(),
                })
            }
            Geometry::Structured { dims, points } => {
                let b = self.buckets.as_ref()?;
                let nc = [dims[0] - 1, dims[1] - 1];
                for &ci in b.at(x) {
                    let ci = ci as usize;
                    if !in_box(&self.boxes[ci], x) {
                        continue;
                    }
                    let (i, j, k) = (ci % nc[0], (ci / nc[0]) % nc[1], ci / (nc[0] * nc[1]));
                    let ids = structured_corners(*dims, i, j, k);
                    let c = ids.map(|id| points[id]);
                    if let Some(p) = hex_locate(&c, x) {
                        return Some(Hit::Nodes {
                            cell: ci,
                            nodes: ids.iter().copied().zip(hex_weights(p)).collect(),
                        });
                    }
                }
                None
            }
            Geometry::Unstructured { points, cells } => {
                let b = self.buckets.as_ref()?;
                for &ci in b.at(x) {
                    let ci = ci as usize;
                    if !in_box(&self.boxes[ci], x) {
                        continue;
                    }
                    match cells[ci] {
                        Cell::Tet(ids) => {
                            let c = ids.map(|id| points[id as usize]);
                            if let Some(w) = tet_locate(&c, x) {
                                return Some(Hit::Nodes {
                                    cell: ci,
                                    nodes: ids.iter().map(|&i| i as usize).zip(w).collect(),
                                });
                            }
                        }
                        Cell::Hex(ids) => {
                            let c = ids.map(|id| points[id as usize]);
                            if let Some(p) = hex_locate(&c, x) {
                                return Some(Hit::Nodes {
                                    cell: ci,
                                    nodes: ids
                                        .iter()
                                        .map(|&i| i as usize)
                                        .zip(hex_weights(p))
                                        .collect(),
                                });
                            }
                        }
                    }
                }
                None
            }
        }
    }
}

impl CfdGrid {
    /// Number of nodes.
    pub fn n_points(&self) -> usize {
        match &self.geometry {
            Geometry::Rectilinear { x, y, z } => x.len() * y.len() * z.len(),
            Geometry::Structured { points, .. } | Geometry::Unstructured { points, .. } => {
                points.len()
            }
        }
    }

    /// Number of cells.
    pub fn n_cells(&self) -> usize {
        let c = |n: usize| n.saturating_sub(1).max(1);
        match &self.geometry {
            Geometry::Rectilinear { x, y, z } => c(x.len()) * c(y.len()) * c(z.len()),
            Geometry::Structured { dims, .. } => c(dims[0]) * c(dims[1]) * c(dims[2]),
            Geometry::Unstructured { cells, .. } => cells.len(),
        }
    }

    /// Checks what the locator and the interpolation rely on: finite node positions,
    /// increasing rectilinear coordinates, node counts that match the dimensions, cell ids in
    /// range and array lengths that match their entities. Errors name `path` and the field.
    /// NaN or infinite array values are allowed: they resample to NaN ("no data").
    pub fn validate(&self, path: &std::path::Path) -> Result<()> {
        let bad = |field: &str, msg: String| Err(VolumeError::format(path, field, msg));
        match &self.geometry {
            Geometry::Rectilinear { x, y, z } => {
                for (name, c) in [
                    ("x coordinates", x),
                    ("y coordinates", y),
                    ("z coordinates", z),
                ] {
                    if c.is_empty() {
                        return bad(name, "empty".into());
                    }
                    if let Some(i) = c.iter().position(|v| !v.is_finite()) {
                        return bad(name, format!("value {i} is {}", c[i]));
                    }
                    if let Some(i) = c.windows(2).position(|w| w[1] <= w[0]) {
                        return bad(
                            name,
                            format!("not increasing at {}: {} then {}", i + 1, c[i], c[i + 1]),
                        );
                    }
                }
            }
            Geometry::Structured { dims, points } => {
                let n = dims.iter().try_fold(1usize, |a, &d| a.checked_mul(d));
                if dims.contains(&0) || n != Some(points.len()) {
                    return bad(
                        "points",
                        format!("{} points for dimensions {dims:?}", points.len()),
                    );
                }
            }
            Geometry::Unstructured { points, cells } => {
                for (ci, c) in cells.iter().enumerate() {
                    let ids: &[u32] = match c {
                        Cell::Tet(i) => i,
                        Cell::Hex(i) => i,
                    };
                    if let Some(&id) = ids.iter().find(|&&id| id as usize >= points.len()) {
                        return bad(
                            "connectivity",
                            format!("cell {ci} uses point {id}; there are {}", points.len()),
                        );
                    }
                }
            }
        }
        if let Geometry::Structured { points, .. } | Geometry::Unstructured { points, .. } =
            &self.geometry
        {
            if let Some(i) = points.iter().position(|p| !p.is_finite()) {
                let p = points[i];
                return bad(
                    "points",
                    format!(
                        "point {i} is ({}, {}, {}): coordinates must be finite",
                        p.x, p.y, p.z
                    ),
                );
            }
        }
        for a in &self.arrays {
            let n = if a.on_cells {
                self.n_cells()
            } else {
                self.n_points()
            };
            if a.components == 0 || a.data.len() != n * a.components {
                return bad(
                    &a.name,
                    format!(
                        "{} values, {n} {} x {} components need {}",
                        a.data.len(),
                        if a.on_cells { "cells" } else { "points" },
                        a.components,
                        n * a.components
                    ),
                );
            }
        }
        Ok(())
    }

    /// World bounding box of the nodes.
    pub fn bounds(&self) -> [DVec3; 2] {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        let mut add = |p: DVec3| {
            lo = lo.min(p);
            hi = hi.max(p);
        };
        match &self.geometry {
            Geometry::Rectilinear { x, y, z } => {
                for (a, c) in [x, y, z].into_iter().enumerate() {
                    for &v in c {
                        lo[a] = lo[a].min(v);
                        hi[a] = hi[a].max(v);
                    }
                }
            }
            Geometry::Structured { points, .. } | Geometry::Unstructured { points, .. } => {
                points.iter().copied().for_each(&mut add)
            }
        }
        [lo, hi]
    }

    pub fn names(&self) -> Vec<String> {
        self.arrays.iter().map(|a| a.name.clone()).collect()
    }

    /// The arrays a selector names: `NAME`, `NAME:magnitude`, or `A,B,C` (three scalars
    /// assembled into a vector). Returns the arrays and how to combine them.
    fn pick(&self, sel: &str) -> Result<(Vec<&GridArray>, FieldPart)> {
        let find = |n: &str| {
            self.arrays.iter().find(|a| a.name == n).ok_or_else(|| {
                VolumeError::Invalid(format!(
                    "field {n}: no such array; the grid has: {}",
                    self.names().join(", ")
                ))
            })
        };
        let parts: Vec<&str> = sel.split(',').map(str::trim).collect();
        if parts.len() == 3 {
            let arrays: Vec<&GridArray> = parts.iter().map(|n| find(n)).collect::<Result<_>>()?;
            if arrays
                .iter()
                .any(|a| a.components != 1 || a.on_cells != arrays[0].on_cells)
            {
                return Err(VolumeError::Invalid(format!(
                    "field {sel}: three scalar arrays on the same entities are needed"
                )));
            }
            return Ok((arrays, FieldPart::Whole));
        }
        let s: FieldSelector = sel.parse()?;
        let a = find(&s.name)?;
        if s.part != FieldPart::Whole && a.components != 3 {
            return Err(VolumeError::Invalid(format!(
                "field {sel}: '{}' has {} components",
                a.name, a.components
            )));
        }
        Ok((vec![a], s.part))
    }

    /// Resamples an array (`NAME`, `NAME:magnitude`, `NAME:x|y|z` or `A,B,C`) onto `dims` samples spanning the grid's
    /// bounding box; samples outside the mesh are NaN.
    pub fn resample(&self, sel: &str, dims: [usize; 3]) -> Result<Volume> {
        self.resample_counted(sel, dims).map(|(v, _)| v)
    }

    /// [`CfdGrid::resample`], with how many samples fell inside the mesh (whatever the array's
    /// values there: a NaN in the data is NaN inside the mesh).
    pub fn resample_counted(&self, sel: &str, dims: [usize; 3]) -> Result<(Volume, usize)> {
        if dims.iter().any(|&d| !(1..=2048).contains(&d)) || dims[0] * dims[1] * dims[2] > 1 << 28 {
            return Err(VolumeError::Invalid(format!(
                "grid size {dims:?}: each 1 to 2048, at most 2^28 samples"
            )));
        }
        let (arrays, part) = self.pick(sel)?;
        let out_comps = if arrays.len() == 3 {
            3
        } else if part == FieldPart::Whole {
            arrays[0].components
        } else {
            1
        };
        if out_comps != 1 && out_comps != 3 {
            return Err(VolumeError::Invalid(format!(
                "field {sel}: {out_comps} components; select one with NAME:x or NAME:magnitude"
            )));
        }
        let [lo, hi] = self.bounds();
        let step = |a: usize| {
            if dims[a] > 1 && hi[a] > lo[a] {
                (hi[a] - lo[a]) / (dims[a] - 1) as f64
            } else {
                1.0
            }
        };
        let affine = DMat4::from_cols(
            DVec4::new(step(0), 0.0, 0.0, 0.0),
            DVec4::new(0.0, step(1), 0.0, 0.0),
            DVec4::new(0.0, 0.0, step(2), 0.0),
            DVec4::from((lo, 1.0)),
        );
        let loc = Locator::new(self);
        let n = dims[0] * dims[1] * dims[2];
        let sample = |hit: &Hit| -> [f32; 3] {
            let Hit::Nodes { cell, nodes } = hit;
            let value = |a: &GridArray, c: usize| -> f64 {
                if a.on_cells {
                    a.data[cell * a.components + c] as f64
                } else {
                    nodes
                        .iter()
                        .map(|&(id, w)| w * a.data[id * a.components + c] as f64)
                        .sum()
                }
            };
            if arrays.len() == 3 {
                [
                    value(arrays[0], 0) as f32,
                    value(arrays[1], 0) as f32,
                    value(arrays[2], 0) as f32,
                ]
            } else {
                let a = arrays[0];
                match part {
                    FieldPart::Whole if a.components == 3 => {
                        [value(a, 0) as f32, value(a, 1) as f32, value(a, 2) as f32]
                    }
                    FieldPart::Whole => [value(a, 0) as f32, 0.0, 0.0],
                    FieldPart::Magnitude => [
                        DVec3::new(value(a, 0), value(a, 1), value(a, 2)).length() as f32,
                        0.0,
                        0.0,
                    ],
                    FieldPart::Component(c) => [value(a, c) as f32, 0.0, 0.0],
                }
            }
        };
        let inside = std::sync::atomic::AtomicUsize::new(0);
        let data: Vec<f32> = (0..n)
            .into_par_iter()
            .flat_map_iter(|id| {
                let (i, j, k) = (
                    id % dims[0],
                    (id / dims[0]) % dims[1],
                    id / (dims[0] * dims[1]),
                );
                let x = (affine * DVec4::new(i as f64, j as f64, k as f64, 1.0)).truncate();
                let v = match loc.locate(x) {
                    Some(hit) => {
                        inside.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        sample(&hit)
                    }
                    None => [f32::NAN; 3],
                };
                v.into_iter().take(out_comps)
            })
            .collect();
        let name = if arrays.len() == 3 {
            sel.replace(',', "_")
        } else {
            sel.to_string()
        };
        let mut v = Volume::new(
            dims,
            affine,
            Space::File,
            Field {
                name,
                components: out_comps,
                stored: ScalarType::F32,
                data,
            },
        )?;
        v.format = format!("{} resampled", self.format);
        Ok((v, inside.into_inner()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn warped(n: [usize; 3]) -> Vec<DVec3> {
        let mut pts = Vec::new();
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    let (x, y, z) = (i as f64, j as f64, k as f64);
                    // A smooth, non-affine warp: cells are curved hexahedra.
                    pts.push(DVec3::new(
                        x + 0.25 * (0.7 * y).sin(),
                        y + 0.2 * (0.5 * z + 0.3 * x).cos(),
                        z * 1.5 + 0.1 * x * y / n[0] as f64,
                    ));
                }
            }
        }
        pts
    }

    #[test]
    fn linear_fields_are_reproduced_on_curvilinear_and_tetrahedral_grids() {
        let lin = |p: DVec3| DVec3::new(2.0 * p.x - p.y + 0.5 * p.z + 1.0, p.y, -p.z);
        let n = [9, 8, 7];
        let pts = warped(n);
        let data: Vec<f32> = pts
            .iter()
            .flat_map(|&p| {
                let v = lin(p);
                [v.x as f32, v.y as f32, v.z as f32]
            })
            .collect();
        let g = CfdGrid {
            format: "test".into(),
            geometry: Geometry::Structured {
                dims: n,
                points: pts.clone(),
            },
            arrays: vec![GridArray {
                name: "v".into(),
                components: 3,
                on_cells: false,
                data: data.clone(),
            }],
        };
        let vol = g.resample("v", [20, 18, 16]).unwrap();
        let (mut inside, mut worst) = (0, 0.0f64);
        for (id, v) in vol.fields[0].data.chunks_exact(3).enumerate() {
            if v[0].is_nan() {
                continue;
            }
            let (i, j, k) = (id % 20, (id / 20) % 18, id / 360);
            let x = vol.index_to_world(DVec3::new(i as f64, j as f64, k as f64));
            let want = lin(x);
            worst = worst.max((DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) - want).length());
            inside += 1;
        }
        assert!(inside > 2000, "{inside} samples inside");
        assert!(worst < 1e-4, "largest error {worst}");
        // The same points as tetrahedra (each structured cell split into 6 tets).
        let mut cells = Vec::new();
        for k in 0..n[2] - 1 {
            for j in 0..n[1] - 1 {
                for i in 0..n[0] - 1 {
                    let c = structured_corners(n, i, j, k).map(|v| v as u32);
                    for t in [
                        [0, 1, 3, 4],
                        [1, 2, 3, 6],
                        [1, 4, 5, 6],
                        [3, 4, 6, 7],
                        [1, 3, 4, 6],
                    ] {
                        cells.push(Cell::Tet(t.map(|q| c[q])));
                    }
                }
            }
        }
        let u = CfdGrid {
            format: "test".into(),
            geometry: Geometry::Unstructured { points: pts, cells },
            arrays: vec![GridArray {
                name: "v".into(),
                components: 3,
                on_cells: false,
                data,
            }],
        };
        let vu = u.resample("v:x", [12, 12, 12]).unwrap();
        let mut found = 0;
        for (id, &v) in vu.fields[0].data.iter().enumerate() {
            if v.is_nan() {
                continue;
            }
            let (i, j, k) = (id % 12, (id / 12) % 12, id / 144);
            let x = vu.index_to_world(DVec3::new(i as f64, j as f64, k as f64));
            assert!(
                (v as f64 - lin(x).x).abs() < 1e-4,
                "tet sample {v} vs {}",
                lin(x).x
            );
            found += 1;
        }
        assert!(found > 300);
    }

    #[test]
    fn rectilinear_grids_with_cell_data_and_assembled_vectors() {
        let g = CfdGrid {
            format: "test".into(),
            geometry: Geometry::Rectilinear {
                x: vec![0.0, 1.0, 3.0],
                y: vec![0.0, 2.0],
                z: vec![-1.0, 0.0, 1.0],
            },
            arrays: vec![
                GridArray {
                    name: "p".into(),
                    components: 1,
                    on_cells: true,
                    data: vec![1.0, 2.0, 3.0, 4.0],
                },
                GridArray {
                    name: "u".into(),
                    components: 1,
                    on_cells: false,
                    data: (0..18).map(|i| i as f32).collect(),
                },
                GridArray {
                    name: "v".into(),
                    components: 1,
                    on_cells: false,
                    data: vec![1.0; 18],
                },
                GridArray {
                    name: "w".into(),
                    components: 1,
                    on_cells: false,
                    data: vec![2.0; 18],
                },
            ],
        };
        let p = g.resample("p", [7, 3, 5]).unwrap();
        // x in [0, 1) is cell 0 (z < 0) or cell 2 (z > 0); x in (1, 3] cells 1 and 3.
        assert_eq!(p.fields[0].data[p.index(0, 0, 0)], 1.0);
        assert_eq!(p.fields[0].data[p.index(6, 0, 0)], 2.0);
        assert_eq!(p.fields[0].data[p.index(6, 0, 4)], 4.0);
        let uvw = g.resample("u,v,w", [4, 2, 3]).unwrap();
        assert_eq!(uvw.fields[0].components, 3);
        let s = &uvw.fields[0].data;
        // Sample (1, 0, 0) sits on node x = 1, y = 0, z = -1, where u = 1.
        assert_eq!(&s[3..6], &[1.0, 1.0, 2.0]);
        assert!(g.resample("nope", [2, 2, 2]).is_err());
        assert!(g.resample("u", [0, 2, 2]).is_err());
    }
}
