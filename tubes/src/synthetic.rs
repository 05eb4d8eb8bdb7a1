//! Synthetic fibre bundles: whole-brain-sized tractograms of any size, made one streamline at a
//! time (so that 10^6 streamlines can be written without holding them), for the scale tests
//! and benchmarks (`umbra synth bundles`).
//!
//! Streamline `i` belongs to bundle `i mod bundles`. A bundle is a cubic Bezier curve
//! `C(t), t in [0, 1]`: its ends are drawn (from the seed and the bundle's number) in a
//! brain-sized box, `[-70, 70] x [-90, 90] x [-60, 60]` mm, at least 60 mm apart; its inner
//! control points lie at a third and two thirds of the chord, pushed off it perpendicularly by
//! up to a quarter of its length (no cusps, no loops). A streamline follows its bundle's curve
//! at an offset `r (cos a, sin a)` in the plane normal to the chord (`r = radius sqrt(u)`,
//! uniform over the disc), turning slowly along the line (`a + 0.8 t`: bundles are twisted),
//! over a sub-interval `[t0, t1]` with `t0` in `[0, 0.1]` and `t1` in `[0.9, 1]`, sampled at
//! `points` values of `t` evenly spaced. Everything depends only on `(seed, i)`: any
//! streamline can be made alone, in any order.

use glam::DVec3;

/// What a synthetic tractogram looks like.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bundles {
    /// Streamlines in all.
    pub count: usize,
    /// Points a streamline (at least 2).
    pub points: usize,
    /// Bundles the streamlines are dealt to (at least 1).
    pub bundles: usize,
    /// Radius of a bundle's cross-section, mm.
    pub radius: f64,
    pub seed: u64,
}

impl Default for Bundles {
    fn default() -> Self {
        Bundles {
            count: 10_000,
            points: 100,
            bundles: 24,
            radius: 6.0,
            seed: 1,
        }
    }
}

/// SplitMix64's output function: a well-mixed 64-bit hash of `x`.
fn mix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// The `k`-th uniform number in `[0, 1)` of stream `key`.
fn uniform(key: u64, k: u64) -> f64 {
    (mix(key ^ mix(k)) >> 11) as f64 / (1u64 << 53) as f64
}

impl Bundles {
    /// Checks the description: a clear message naming the value when it is unusable.
    pub fn validate(&self) -> Result<(), String> {
        if self.points < 2 {
            return Err(format!(
                "points {}: a streamline needs at least 2",
                self.points
            ));
        }
        if self.bundles == 0 {
            return Err("bundles 0: at least one bundle".into());
        }
        if !(self.radius.is_finite() && self.radius >= 0.0) {
            return Err(format!("radius {}: not a finite length >= 0", self.radius));
        }
        Ok(())
    }

    /// Total points of the tractogram.
    pub fn total_points(&self) -> u64 {
        self.count as u64 * self.points as u64
    }

    /// The four control points of bundle `b`: the ends at least 60 mm apart in the box, the
    /// inner two at a third and two thirds of the chord, pushed off it perpendicularly by up
    /// to a quarter of its length. The curve's derivative along the chord is then the chord
    /// itself, never zero: no cusp, no loop.
    #[cfg(test)]
    fn controls(&self, b: usize) -> [DVec3; 4] {
        self.axis(b).0
    }

    /// The control points and two unit vectors normal to the chord (the cross-section frame).
    fn axis(&self, b: usize) -> ([DVec3; 4], DVec3, DVec3) {
        let key = mix(self.seed ^ 0xB0D1E5) ^ mix(b as u64);
        let half = DVec3::new(70.0, 90.0, 60.0);
        let point = |k: u64| {
            let u = |j| uniform(key, 3 * k + j) * 2.0 - 1.0;
            DVec3::new(u(0), u(1), u(2)) * half
        };
        let p0 = point(0);
        let p3 = (1..64)
            .map(point)
            .find(|p| p.distance(p0) >= 60.0)
            .unwrap_or(-p0);
        let chord = p3 - p0;
        let along = chord.normalize();
        let e1 = along.any_orthonormal_vector();
        let e2 = along.cross(e1);
        let bulge = |k: u64| {
            let (a, r) = (
                uniform(key, 400 + k) * std::f64::consts::TAU,
                uniform(key, 500 + k),
            );
            (e1 * a.cos() + e2 * a.sin()) * (0.25 * chord.length() * r)
        };
        let c = [
            p0,
            p0 + chord / 3.0 + bulge(0),
            p0 + chord * (2.0 / 3.0) + bulge(1),
            p3,
        ];
        (c, e1, e2)
    }

    /// Streamline `i` (of `0..count`), its points appended to `out` (cleared first).
    pub fn line(&self, i: usize, out: &mut Vec<glam::Vec3>) {
        out.clear();
        let ([p0, p1, p2, p3], e1, e2) = self.axis(i % self.bundles);
        let key = mix(self.seed) ^ mix(i as u64 ^ 0x5EED_0000_0000);
        let r = self.radius * uniform(key, 0).sqrt();
        let a0 = uniform(key, 1) * std::f64::consts::TAU;
        let t0 = 0.1 * uniform(key, 2);
        let t1 = 1.0 - 0.1 * uniform(key, 3);
        let n = self.points;
        for k in 0..n {
            let t = t0 + (t1 - t0) * k as f64 / (n - 1) as f64;
            let s = 1.0 - t;
            let c = p0 * (s * s * s)
                + p1 * (3.0 * s * s * t)
                + p2 * (3.0 * s * t * t)
                + p3 * (t * t * t);
            // The offset lies in the plane normal to the chord (a frame fixed per bundle, so
            // the offset turns smoothly).
            let a = a0 + 0.8 * t;
            out.push((c + (e1 * a.cos() + e2 * a.sin()) * r).as_vec3());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_are_deterministic_smooth_and_inside_their_hulls() {
        let b = Bundles {
            count: 200,
            ..Default::default()
        };
        let (mut x, mut y) = (vec![], vec![]);
        for i in 0..b.count {
            b.line(i, &mut x);
            b.line(i, &mut y);
            assert_eq!(x, y, "line {i} is not reproducible");
            assert_eq!(x.len(), 100);
            // A Bezier curve stays in its control points' hull; the offset adds `radius`.
            let c = b.controls(i % b.bundles);
            let lo = c.iter().fold(DVec3::INFINITY, |a, p| a.min(*p)) - b.radius - 1e-3;
            let hi = c.iter().fold(DVec3::NEG_INFINITY, |a, p| a.max(*p)) + b.radius + 1e-3;
            for p in &x {
                let p = p.as_dvec3();
                assert!(p.cmpge(lo).all() && p.cmple(hi).all(), "line {i}: {p}");
            }
            // Smooth: consecutive steps turn by less than 30 degrees.
            for w in x.windows(3) {
                let (u, v) = (w[1] - w[0], w[2] - w[1]);
                let cos = u.dot(v) / (u.length() * v.length()).max(1e-12);
                assert!(
                    cos > 0.866,
                    "line {i} turns by {} degrees",
                    cos.acos().to_degrees()
                );
            }
        }
    }

    #[test]
    fn every_point_lies_within_the_radius_of_its_bundle_s_curve() {
        let b = Bundles {
            count: 48,
            ..Default::default()
        };
        let mut x = vec![];
        let mut widest = 0.0f64;
        for i in 0..b.count {
            let [p0, p1, p2, p3] = b.controls(i % b.bundles);
            let curve: Vec<DVec3> = (0..=4000)
                .map(|k| {
                    let t = k as f64 / 4000.0;
                    let s = 1.0 - t;
                    p0 * (s * s * s)
                        + p1 * (3.0 * s * s * t)
                        + p2 * (3.0 * s * t * t)
                        + p3 * (t * t * t)
                })
                .collect();
            b.line(i, &mut x);
            for p in &x {
                let d = curve
                    .iter()
                    .map(|c| c.distance(p.as_dvec3()))
                    .fold(f64::INFINITY, f64::min);
                // The curve sampled every < 0.25 mm: at most 0.13 mm of sampling error.
                assert!(
                    d <= b.radius + 0.15,
                    "line {i}: {d} mm from its bundle's axis"
                );
                widest = widest.max(d);
            }
        }
        // The cross-section is filled, not collapsed onto the axis.
        assert!(widest > 0.8 * b.radius, "{widest}");
    }

    #[test]
    fn bad_descriptions_are_refused() {
        let b = Bundles::default();
        assert!(Bundles { points: 1, ..b }
            .validate()
            .unwrap_err()
            .contains("points 1"));
        assert!(Bundles { bundles: 0, ..b }.validate().is_err());
        assert!(Bundles {
            radius: f64::NAN,
            ..b
        }
        .validate()
        .is_err());
        assert!(b.validate().is_ok());
    }
}
