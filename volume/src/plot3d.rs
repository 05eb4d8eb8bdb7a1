//! PLOT3D structured grids: an `xyz` grid file and an optional `q` solution file (NASA's
//! PLOT3D format as VTK's `vtkMultiBlockPLOT3DReader` reads it).
//!
//! Layout ("whole" format, one grid): dimensions `ni nj nk` (int32), then all x, all y, all z
//! (float32 or float64, i fastest), optionally an int32 IBLANK array; the q file repeats the
//! dimensions, then `fsmach alpha re time`, then density ρ, momentum (ρu, ρv, ρw) and total
//! energy per volume E, each a whole array. Files are written with or without Fortran record
//! markers (an int32 byte count before and after each record), in either byte order, with an
//! optional leading grid count (which must be 1).
//!
//! None of this is stored in the file, so the reader tries every combination and keeps the one
//! whose header is plausible and whose size matches the file exactly. Where none matches
//! exactly, the largest layout that fits is used and the trailing bytes are reported as a
//! warning (`bluntfinq.bin` of the VTK data carries 484 such bytes).
//!
//! Arrays from q: `density`, `momentum` (3 components), `energy`, and the derived
//! `velocity` = momentum/ρ and `pressure` = (γ−1)(E − ½ρ|u|²) with γ = 1.4 (VTK's default).
//! Where ρ is 0 or not finite, velocity and pressure are NaN.

use crate::cfd_grid::{CfdGrid, Geometry, GridArray};
use crate::io_util;
use crate::{Result, VolumeError};
use glam::DVec3;
use std::path::Path;

/// Ratio of specific heats for the derived pressure.
pub const GAMMA: f64 = 1.4;

#[derive(Clone, Copy, Debug, PartialEq)]
struct Layout {
    big_endian: bool,
    markers: bool,
    multi: bool,
    double: bool,
    iblank: bool,
    dims: [usize; 3],
    /// Bytes the layout accounts for.
    size: usize,
}

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
    big: bool,
}

impl Reader<'_> {
    fn i32(&mut self) -> Option<i64> {
        let b: [u8; 4] = self.bytes.get(self.pos..self.pos + 4)?.try_into().ok()?;
        self.pos += 4;
        Some(if self.big {
            i32::from_be_bytes(b)
        } else {
            i32::from_le_bytes(b)
        } as i64)
    }

    fn real(&mut self, double: bool) -> Option<f64> {
        if double {
            let b: [u8; 8] = self.bytes.get(self.pos..self.pos + 8)?.try_into().ok()?;
            self.pos += 8;
            Some(if self.big {
                f64::from_be_bytes(b)
            } else {
                f64::from_le_bytes(b)
            })
        } else {
            let b: [u8; 4] = self.bytes.get(self.pos..self.pos + 4)?.try_into().ok()?;
            self.pos += 4;
            Some(if self.big {
                f32::from_be_bytes(b)
            } else {
                f32::from_le_bytes(b)
            } as f64)
        }
    }

    /// Reads a record marker and checks it is `len` (when markers are on).
    fn marker(&mut self, markers: bool, len: usize) -> Option<()> {
        if markers {
            (self.i32()? == len as i64).then_some(())
        } else {
            Some(())
        }
    }
}

/// The header under one guess of the layout; `None` when it is implausible.
fn try_layout(
    bytes: &[u8],
    big_endian: bool,
    markers: bool,
    multi: bool,
    double: bool,
    iblank: bool,
    q: bool,
) -> Option<Layout> {
    let mut r = Reader {
        bytes,
        pos: 0,
        big: big_endian,
    };
    if multi {
        r.marker(markers, 4)?;
        if r.i32()? != 1 {
            return None;
        }
        r.marker(markers, 4)?;
    }
    r.marker(markers, 12)?;
    let mut dims = [0usize; 3];
    for d in &mut dims {
        let v = r.i32()?;
        if !(1..=65_536).contains(&v) {
            return None;
        }
        *d = v as usize;
    }
    r.marker(markers, 12)?;
    let n = dims[0].checked_mul(dims[1])?.checked_mul(dims[2])?;
    if n as u64 > io_util::MAX_SAMPLES {
        return None;
    }
    let real = if double { 8 } else { 4 };
    let mut size = r.pos;
    if q {
        // fsmach, alpha, re, time.
        let rec = 4 * real;
        size += rec + if markers { 8 } else { 0 };
        if markers {
            let mut m = Reader {
                bytes,
                pos: r.pos,
                big: big_endian,
            };
            m.marker(true, rec)?;
        }
    }
    let data = n * real * if q { 5 } else { 3 } + if iblank { n * 4 } else { 0 };
    if markers {
        let mut m = Reader {
            bytes,
            pos: size,
            big: big_endian,
        };
        m.marker(true, data)?;
    }
    size += data + if markers { 8 } else { 0 };
    Some(Layout {
        big_endian,
        markers,
        multi,
        double,
        iblank,
        dims,
        size,
    })
}

/// Finds the layout of a PLOT3D file: an exact size match, else the largest that fits.
fn detect(path: &Path, bytes: &[u8], q: bool) -> Result<(Layout, Option<String>)> {
    let mut exact = Vec::new();
    let mut fits = Vec::new();
    for big in [true, false] {
        for markers in [false, true] {
            for multi in [false, true] {
                for double in [false, true] {
                    for iblank in [false, true] {
                        if q && iblank {
                            continue;
                        }
                        if let Some(l) = try_layout(bytes, big, markers, multi, double, iblank, q) {
                            if l.size == bytes.len() {
                                exact.push(l);
                            } else if l.size < bytes.len() {
                                fits.push(l);
                            }
                        }
                    }
                }
            }
        }
    }
    if let Some(l) = exact.first() {
        return Ok((*l, None));
    }
    // Prefer the layout that explains the most bytes.
    fits.sort_by_key(|l| std::cmp::Reverse(l.size));
    match fits.first() {
        Some(l) => Ok((
            *l,
            Some(format!(
                "{}: {} trailing bytes after the PLOT3D data were ignored",
                path.display(),
                bytes.len() - l.size
            )),
        )),
        None => Err(VolumeError::format(
            path,
            "header",
            format!(
                "no PLOT3D {} layout (byte order, record markers, precision{}) explains this {}-byte file",
                if q { "solution" } else { "grid" },
                if q { "" } else { ", IBLANK" },
                bytes.len()
            ),
        )),
    }
}

/// Reads the data arrays after the header of a detected layout.
fn read_arrays(bytes: &[u8], l: &Layout, q: bool, count: usize) -> Vec<Vec<f64>> {
    let n = l.dims.iter().product::<usize>();
    let mut pos = if l.multi {
        4 + if l.markers { 8 } else { 0 }
    } else {
        0
    };
    pos += 12 + if l.markers { 8 } else { 0 };
    let real = if l.double { 8 } else { 4 };
    if q {
        pos += 4 * real + if l.markers { 8 } else { 0 };
    }
    if l.markers {
        pos += 4;
    }
    let mut r = Reader {
        bytes,
        pos,
        big: l.big_endian,
    };
    (0..count)
        .map(|_| {
            (0..n)
                .map(|_| r.real(l.double).unwrap_or(f64::NAN))
                .collect()
        })
        .collect()
}

/// Reads a PLOT3D grid file and, if given, its q file.
pub fn read(xyz: &Path, q: Option<&Path>) -> Result<(CfdGrid, Vec<String>)> {
    let bytes = io_util::read_file(xyz)?;
    let grid = detect(xyz, &bytes, false);
    // No grid layout explains the whole file, a solution's does: the q file given as the
    // grid (the classic mix-up), whose momentum would be read as coordinates.
    if matches!(grid, Err(_) | Ok((_, Some(_)))) {
        if let Ok((ql, None)) = detect(xyz, &bytes, true) {
            let [a, b, c] = ql.dims;
            return Err(VolumeError::format(
                xyz,
                "header",
                format!(
                    "the file is laid out as a PLOT3D solution (q) file ({a} x {b} x {c} points, 4 \
                     reference values and 5 variables), not as a grid: give the grid (xyz) \
                     file as the input and this one with --q"
                ),
            ));
        }
    }
    let (layout, warn) = grid?;
    let mut warnings: Vec<String> = warn.into_iter().collect();
    let c = read_arrays(&bytes, &layout, false, 3);
    let n = c[0].len();
    let points: Vec<DVec3> = (0..n)
        .map(|i| DVec3::new(c[0][i], c[1][i], c[2][i]))
        .collect();
    let mut arrays = Vec::new();
    if let Some(qp) = q {
        let qb = io_util::read_file(qp)?;
        let (ql, warn) = detect(qp, &qb, true)?;
        warnings.extend(warn);
        if ql.dims != layout.dims {
            return Err(VolumeError::format(
                qp,
                "dimensions",
                format!(
                    "{:?} in the q file, {:?} in the grid {}",
                    ql.dims,
                    layout.dims,
                    xyz.display()
                ),
            ));
        }
        let v = read_arrays(&qb, &ql, true, 5);
        let (rho, mx, my, mz, e) = (&v[0], &v[1], &v[2], &v[3], &v[4]);
        let mut momentum = Vec::with_capacity(3 * n);
        let mut velocity = Vec::with_capacity(3 * n);
        let mut pressure = Vec::with_capacity(n);
        for i in 0..n {
            let m = DVec3::new(mx[i], my[i], mz[i]);
            momentum.extend([m.x as f32, m.y as f32, m.z as f32]);
            let (u, p) = if rho[i].is_finite() && rho[i] != 0.0 {
                let u = m / rho[i];
                (
                    u,
                    (GAMMA - 1.0) * (e[i] - 0.5 * rho[i] * u.length_squared()),
                )
            } else {
                (DVec3::NAN, f64::NAN)
            };
            velocity.extend([u.x as f32, u.y as f32, u.z as f32]);
            pressure.push(p as f32);
        }
        let scalar = |name: &str, d: &[f64]| GridArray {
            name: name.into(),
            components: 1,
            on_cells: false,
            data: d.iter().map(|&x| x as f32).collect(),
        };
        let vector = |name: &str, data: Vec<f32>| GridArray {
            name: name.into(),
            components: 3,
            on_cells: false,
            data,
        };
        arrays = vec![
            scalar("density", rho),
            vector("momentum", momentum),
            scalar("energy", e),
            vector("velocity", velocity),
            scalar(
                "pressure",
                &pressure.iter().map(|&p| p as f64).collect::<Vec<_>>(),
            ),
        ];
    }
    let grid = CfdGrid {
        format: "plot3d".into(),
        geometry: Geometry::Structured {
            dims: layout.dims,
            points,
        },
        arrays,
    };
    grid.validate(xyz)?;
    Ok((grid, warnings))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(out: &mut Vec<u8>, markers: bool, big: bool, body: &[u8]) {
        let m = |v: i32| {
            if big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        };
        if markers {
            out.extend(m(body.len() as i32));
        }
        out.extend(body);
        if markers {
            out.extend(m(body.len() as i32));
        }
    }

    /// Writes a 3x2x2 grid with x = i, y = 2j, z = 3k, and a q file with ρ = 2, ρu = (2i, 0, 4).
    fn files(markers: bool, big: bool, double: bool) -> (Vec<u8>, Vec<u8>) {
        let dims = [3i32, 2, 2];
        let i32b = |v: i32| {
            if big {
                v.to_be_bytes()
            } else {
                v.to_le_bytes()
            }
        };
        let real = |v: f64| -> Vec<u8> {
            match (double, big) {
                (true, true) => v.to_be_bytes().to_vec(),
                (true, false) => v.to_le_bytes().to_vec(),
                (false, true) => (v as f32).to_be_bytes().to_vec(),
                (false, false) => (v as f32).to_le_bytes().to_vec(),
            }
        };
        let head: Vec<u8> = dims.iter().flat_map(|&d| i32b(d)).collect();
        let idx = || (0..12).map(|n| (n % 3, (n / 3) % 2, n / 6));
        let mut xyz = Vec::new();
        record(&mut xyz, markers, big, &head);
        let mut body = Vec::new();
        for f in [
            |i: i32, _j: i32, _k: i32| i as f64,
            |_i, j, _k| 2.0 * j as f64,
            |_i, _j, k| 3.0 * k as f64,
        ] {
            for (i, j, k) in idx() {
                body.extend(real(f(i, j, k)));
            }
        }
        record(&mut xyz, markers, big, &body);
        let mut q = Vec::new();
        record(&mut q, markers, big, &head);
        let params: Vec<u8> = [0.5, 0.0, 1e6, 0.0].iter().flat_map(|&v| real(v)).collect();
        record(&mut q, markers, big, &params);
        let mut body = Vec::new();
        for c in 0..5 {
            for (i, _j, _k) in idx() {
                let v = match c {
                    0 => 2.0,
                    1 => 2.0 * i as f64,
                    2 => 0.0,
                    3 => 4.0,
                    _ => 10.0,
                };
                body.extend(real(v));
            }
        }
        record(&mut q, markers, big, &body);
        (xyz, q)
    }

    #[test]
    fn every_layout_is_detected_and_derived_fields_are_right() {
        let dir = tempfile::tempdir().unwrap();
        for markers in [false, true] {
            for big in [false, true] {
                for double in [false, true] {
                    let (x, q) = files(markers, big, double);
                    let (xp, qp) = (dir.path().join("g.xyz"), dir.path().join("g.q"));
                    std::fs::write(&xp, &x).unwrap();
                    std::fs::write(&qp, &q).unwrap();
                    let (g, warn) = read(&xp, Some(&qp)).unwrap();
                    assert!(warn.is_empty(), "{warn:?}");
                    let Geometry::Structured { dims, points } = &g.geometry else {
                        panic!()
                    };
                    assert_eq!(*dims, [3, 2, 2]);
                    assert_eq!(points[11], DVec3::new(2.0, 2.0, 3.0));
                    let vel = g.arrays.iter().find(|a| a.name == "velocity").unwrap();
                    // Point (2, 1, 1) = index 11: u = (2*2/2, 0, 4/2).
                    assert_eq!(&vel.data[33..36], &[2.0, 0.0, 2.0]);
                    let p = g.arrays.iter().find(|a| a.name == "pressure").unwrap();
                    let expect = 0.4 * (10.0 - 0.5 * 2.0 * (4.0 + 4.0));
                    assert!((p.data[11] as f64 - expect).abs() < 1e-5);
                }
            }
        }
    }

    #[test]
    fn trailing_bytes_warn_and_garbage_errors() {
        let dir = tempfile::tempdir().unwrap();
        let (mut x, _) = files(false, true, false);
        x.extend([0u8; 20]);
        let xp = dir.path().join("t.xyz");
        std::fs::write(&xp, &x).unwrap();
        let (_, warn) = read(&xp, None).unwrap();
        assert!(warn[0].contains("20 trailing bytes"), "{warn:?}");
        std::fs::write(&xp, b"not a grid at all").unwrap();
        let e = read(&xp, None).unwrap_err().to_string();
        assert!(e.contains("t.xyz") && e.contains("layout"), "{e}");
        // Dimensions of another grid in the q file.
        let (x, _) = files(false, true, false);
        let (_, mut q) = files(false, true, false);
        q[3] = 4; // ni = 4
        std::fs::write(&xp, &x).unwrap();
        let qp = dir.path().join("t.q");
        std::fs::write(&qp, &q).unwrap();
        assert!(read(&xp, Some(&qp)).is_err());
        // The q file given as the grid: refused, saying so (it was read as a grid with
        // IBLANK and trailing bytes, its momentum as coordinates).
        for markers in [false, true] {
            let (_, q) = files(markers, false, false);
            std::fs::write(&qp, &q).unwrap();
            let e = read(&qp, None).unwrap_err().to_string();
            assert!(
                e.contains("t.q")
                    && e.contains("solution (q) file")
                    && e.contains("--q")
                    && !e.contains("  "),
                "{e}"
            );
        }
    }
}
