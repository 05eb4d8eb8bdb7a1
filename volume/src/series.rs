//! Time series of volumes on one grid: time-varying (unsteady) fields.
//!
//! Frame `k` of a [`VolumeSeries`] holds the field at time `t0 + k dt` (in the file's time
//! unit: NIfTI's `xyzt_units`, which umbra writes as seconds; nothing is rescaled). Between two
//! frames the field is interpolated linearly in time ([`VolumeSeries::bracket`]). Outside the
//! frames:
//! * a **periodic** series of `T` frames has period `T dt`: frame `T` would equal frame 0 and
//!   is not stored, so the time between the last frame and `t0 + T dt` interpolates from the
//!   last frame back to frame 0, and every time wraps into `[t0, t0 + T dt)`;
//! * any other series is **clamped**: the field is frame 0 before `t0` and the last frame after
//!   `t0 + (T - 1) dt`.
//!
//! A steady volume is a series of one frame ([`VolumeSeries::steady`]), the same at every time.
//! NIfTI files hold a series as a 5-D image (`nifti::read_series`, `nifti::write_series`); every
//! other format reads as a steady series ([`crate::load_series`]).

use crate::{Result, Volume, VolumeError};

/// Frames of one grid at equally spaced times.
#[derive(Clone, Debug, PartialEq)]
pub struct VolumeSeries {
    /// At least one; every frame has the grid, affine, space and field layout of frame 0.
    pub frames: Vec<Volume>,
    /// Time of frame 0.
    pub t0: f64,
    /// Time between frames (positive and finite when there are two frames or more).
    pub dt: f64,
    /// The series repeats with period `frames.len() * dt` (else it is clamped at its ends).
    pub periodic: bool,
    /// What the reader accepted but a user should know.
    pub warnings: Vec<String>,
}

/// Where a time falls between frames: the field there is `(1 - w) frame[k0] + w frame[k1]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bracket {
    pub k0: usize,
    pub k1: usize,
    /// In `[0, 1]`.
    pub w: f64,
}

impl VolumeSeries {
    /// A steady field: one frame at time 0, the same at every time.
    pub fn steady(v: Volume) -> Self {
        VolumeSeries {
            warnings: v.warnings.clone(),
            frames: vec![v],
            t0: 0.0,
            dt: 1.0,
            periodic: false,
        }
    }

    /// A series from its frames; checks the invariants ([`VolumeSeries::validate`]).
    pub fn new(frames: Vec<Volume>, t0: f64, dt: f64, periodic: bool) -> Result<Self> {
        let s = VolumeSeries {
            frames,
            t0,
            dt,
            periodic,
            warnings: vec![],
        };
        s.validate()?;
        Ok(s)
    }

    /// Checks that there is a frame, that every frame is a valid volume on frame 0's grid with
    /// frame 0's fields (names and components), and that the times are finite and increasing.
    pub fn validate(&self) -> Result<()> {
        let Some(first) = self.frames.first() else {
            return Err(VolumeError::Invalid("time series has no frames".into()));
        };
        if !self.t0.is_finite() {
            return Err(VolumeError::Invalid(format!(
                "time series: the first time {} is not finite",
                self.t0
            )));
        }
        if self.frames.len() > 1 && !(self.dt.is_finite() && self.dt > 0.0) {
            return Err(VolumeError::Invalid(format!(
                "time series: the time step {} is not positive",
                self.dt
            )));
        }
        for (k, f) in self.frames.iter().enumerate() {
            f.validate()
                .map_err(|e| VolumeError::Invalid(format!("time series frame {k}: {e}")))?;
            if f.dims != first.dims || f.affine != first.affine || f.space != first.space {
                return Err(VolumeError::Invalid(format!(
                    "time series frame {k}: its grid differs from frame 0's"
                )));
            }
            let layout = |v: &Volume| -> Vec<(String, usize)> {
                v.fields
                    .iter()
                    .map(|f| (f.name.clone(), f.components))
                    .collect()
            };
            if layout(f) != layout(first) {
                return Err(VolumeError::Invalid(format!(
                    "time series frame {k}: its fields differ from frame 0's"
                )));
            }
        }
        Ok(())
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Never true for a valid series; here for clippy's sake.
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// One frame: the field does not change in time.
    pub fn is_steady(&self) -> bool {
        self.frames.len() <= 1
    }

    /// The time frame `k` holds.
    pub fn time(&self, k: usize) -> f64 {
        self.t0 + k as f64 * self.dt
    }

    /// The time the series covers: its period `T dt` when periodic, else `(T - 1) dt` (0 for
    /// a steady field).
    pub fn span(&self) -> f64 {
        let t = self.frames.len();
        if t <= 1 {
            0.0
        } else if self.periodic {
            t as f64 * self.dt
        } else {
            (t - 1) as f64 * self.dt
        }
    }

    /// The two frames around time `t` and the weight of the second (see the module doc for
    /// times outside the frames). A non-finite `t` gives frame 0.
    pub fn bracket(&self, t: f64) -> Bracket {
        let n = self.frames.len();
        let first = Bracket {
            k0: 0,
            k1: 0,
            w: 0.0,
        };
        if n <= 1 || !t.is_finite() {
            return first;
        }
        let u = (t - self.t0) / self.dt;
        if self.periodic {
            let u = u.rem_euclid(n as f64);
            let k0 = (u.floor() as usize).min(n - 1);
            let w = (u - k0 as f64).clamp(0.0, 1.0);
            Bracket {
                k0,
                k1: (k0 + 1) % n,
                w,
            }
        } else {
            let u = u.clamp(0.0, (n - 1) as f64);
            let k0 = (u.floor() as usize).min(n - 2);
            Bracket {
                k0,
                k1: k0 + 1,
                w: (u - k0 as f64).clamp(0.0, 1.0),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synthetic::{cube_affine, sample_scalar};

    fn series(n: usize, periodic: bool) -> VolumeSeries {
        let dims = [2, 2, 2];
        let frames = (0..n)
            .map(|k| sample_scalar(dims, cube_affine(dims, 0.0, 1.0), "f", |_| k as f64))
            .collect();
        VolumeSeries::new(frames, 1.0, 0.5, periodic).unwrap()
    }

    #[test]
    fn clamped_series_bracket_inside_and_hold_their_ends() {
        let s = series(4, false);
        assert_eq!(s.span(), 1.5);
        let b = |t| {
            let b = s.bracket(t);
            (b.k0, b.k1, b.w)
        };
        assert_eq!(b(1.0), (0, 1, 0.0));
        assert_eq!(b(1.25), (0, 1, 0.5));
        assert_eq!(b(2.0), (2, 3, 0.0));
        assert_eq!(b(2.5), (2, 3, 1.0));
        assert_eq!(b(9.0), (2, 3, 1.0));
        assert_eq!(b(-9.0), (0, 1, 0.0));
        assert_eq!(b(f64::NAN), (0, 0, 0.0));
    }

    #[test]
    fn periodic_series_wrap_from_the_last_frame_to_the_first() {
        let s = series(4, true);
        assert_eq!(s.span(), 2.0);
        let b = |t| {
            let b = s.bracket(t);
            (b.k0, b.k1, b.w)
        };
        assert_eq!(b(1.0), (0, 1, 0.0));
        assert_eq!(b(2.75), (3, 0, 0.5));
        assert_eq!(b(3.0), (0, 1, 0.0));
        assert_eq!(b(0.25), (2, 3, 0.5));
        assert_eq!(b(1.0 + 2.0 * 1000.0 + 0.25), (0, 1, 0.5));
    }

    #[test]
    fn steady_series_and_bad_series() {
        let s = series(1, false);
        assert!(s.is_steady());
        assert_eq!(s.span(), 0.0);
        assert_eq!(s.bracket(123.0).k0, 0);
        assert!(VolumeSeries::new(vec![], 0.0, 1.0, false).is_err());
        let f = series(2, false).frames;
        let e = VolumeSeries::new(f.clone(), 0.0, 0.0, false).unwrap_err();
        assert!(e.to_string().contains("time step"), "{e}");
        let mut g = f.clone();
        g[1].affine.w_axis.x = 3.0;
        let e = VolumeSeries::new(g, 0.0, 1.0, false).unwrap_err();
        assert!(e.to_string().contains("frame 1"), "{e}");
        let mut g = f;
        g[1].fields[0].name = "other".into();
        assert!(VolumeSeries::new(g, 0.0, 1.0, false).is_err());
    }
}
