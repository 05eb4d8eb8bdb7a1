//! An object's registration transform (`transform`, a row-major 4 x 4 applied to its points) as
//! the viewer edits it: translation, rotation angles and scales when the matrix is a rotation
//! times a scale, and its twelve entries in any case (a sheared affine from a registration tool
//! keeps them exactly).
//!
//! Convention (stated once): `M = T(t) R S`, `R = Rz(z) Ry(y) Rx(x)` with the angles in degrees
//! (a point turns about x first, then y, then z, each about the world's axis), `S = diag(s)`,
//! scales positive except `s.x`, which carries a reflection. Angles are kept in x, y in
//! [-90, 90], z (the usual yaw-pitch-roll chart; at y = +-90 only x + z or x - z is defined and
//! x is taken as 0). Turning the object keeps one point fixed, the pivot (the camera's target):
//! the point of the object at the pivot stays there.

use eframe::egui;
use glam::{DMat3, DVec3};

/// The identity, row-major.
pub const IDENTITY: [f64; 16] = [
    1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
];

/// A transform as translation, rotation and scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    pub translation: [f64; 3],
    /// Degrees about x, y, z (see the module's convention).
    pub angles: [f64; 3],
    pub scale: [f64; 3],
}

/// The 3 x 3 linear part of row-major `m` (glam is column-major).
fn linear(m: &[f64; 16]) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(m[0], m[4], m[8]),
        DVec3::new(m[1], m[5], m[9]),
        DVec3::new(m[2], m[6], m[10]),
    )
}

fn with_linear(m: &[f64; 16], a: DMat3) -> [f64; 16] {
    let mut o = *m;
    for r in 0..3 {
        for c in 0..3 {
            o[r * 4 + c] = a.col(c)[r];
        }
    }
    o
}

/// `R = Rz Ry Rx` of the angles in degrees.
pub fn rotation(angles: [f64; 3]) -> DMat3 {
    let [x, y, z] = angles.map(f64::to_radians);
    DMat3::from_rotation_z(z) * DMat3::from_rotation_y(y) * DMat3::from_rotation_x(x)
}

/// The pose of `m`, or `None` when it is not `T R S` within 1e-5 (shear, a projective
/// row, a zero or non-finite scale): then only its entries are editable.
pub fn decompose(m: &[f64; 16]) -> Option<Pose> {
    if m.iter().any(|v| !v.is_finite()) || m[12..] != [0.0, 0.0, 0.0, 1.0] {
        return None;
    }
    let a = linear(m);
    let mut s = [a.x_axis.length(), a.y_axis.length(), a.z_axis.length()];
    if s.iter().any(|&v| v <= 1e-300) {
        return None;
    }
    let mut r = DMat3::from_cols(a.x_axis / s[0], a.y_axis / s[1], a.z_axis / s[2]);
    if r.determinant() < 0.0 {
        s[0] = -s[0];
        r = DMat3::from_cols(-r.x_axis, r.y_axis, r.z_axis);
    }
    // Orthonormal columns (no shear)? Within 1e-5: registration tools store f32 matrices or
    // print about six digits; an edit rebuilds the matrix exactly from the pose.
    let tol = 1e-5;
    if (r.transpose() * r - DMat3::IDENTITY)
        .to_cols_array()
        .iter()
        .any(|v| v.abs() > tol)
    {
        return None;
    }
    // R = Rz(c) Ry(b) Rx(a): r20 = -sin b, r21 = cos b sin a, r22 = cos b cos a,
    // r10 = sin c cos b, r00 = cos c cos b (r_rowcol).
    let r20 = r.x_axis.z;
    let (ax, by, cz) = if r20.abs() < 1.0 - 1e-12 {
        (
            r.y_axis.z.atan2(r.z_axis.z),
            (-r20).asin(),
            r.x_axis.y.atan2(r.x_axis.x),
        )
    } else {
        // Gimbal lock: x taken as 0, z from the first two rows of the second column.
        let b = if r20 < 0.0 {
            std::f64::consts::FRAC_PI_2
        } else {
            -std::f64::consts::FRAC_PI_2
        };
        (0.0, b, (-r.y_axis.x).atan2(r.y_axis.y))
    };
    Some(Pose {
        translation: [m[3], m[7], m[11]],
        // + 0.0: no -0 (atan2 of a -0 entry) shown in the fields.
        angles: [ax, by, cz].map(|a| a.to_degrees() + 0.0),
        scale: s,
    })
}

/// The row-major matrix of a pose.
pub fn compose(p: &Pose) -> [f64; 16] {
    let a = rotation(p.angles) * DMat3::from_diagonal(DVec3::from(p.scale));
    let mut m = with_linear(&IDENTITY, a);
    m[3] = p.translation[0];
    m[7] = p.translation[1];
    m[11] = p.translation[2];
    m
}

/// `new` with its translation changed so that the object's point that `old` put at `pivot` is
/// there under `new` too (the object turns or scales about the pivot). `None` when `old`'s
/// linear part cannot be inverted.
pub fn about_pivot(old: &[f64; 16], new: &[f64; 16], pivot: [f64; 3]) -> Option<[f64; 16]> {
    let a_old = linear(old);
    if a_old.determinant().abs() < 1e-300 {
        return None;
    }
    let p = DVec3::from(pivot);
    let q = a_old.inverse() * (p - DVec3::new(old[3], old[7], old[11]));
    let t = p - linear(new) * q;
    let mut m = *new;
    m[3] = t.x;
    m[7] = t.y;
    m[11] = t.z;
    Some(m)
}

/// The transform editor of one object: translation always; angles and scales when the matrix
/// is a pose (turning about `pivot`); the twelve entries behind "matrix". The identity is
/// written when the object had none and a field moves. True when it changed.
pub fn editor(ui: &mut egui::Ui, key: &str, t: &mut Option<[f64; 16]>, pivot: [f64; 3]) -> bool {
    let mut m = t.unwrap_or(IDENTITY);
    let before = m;
    ui.horizontal(|ui| {
        let l = ui.label(format!("  {key} translate"));
        for i in [3, 7, 11] {
            ui.add(egui::DragValue::new(&mut m[i]).speed(0.5))
                .labelled_by(l.id);
        }
    });
    match decompose(&m) {
        Some(pose) => {
            let mut p = pose;
            ui.horizontal(|ui| {
                let l = ui.label(format!("  {key} rotate °"));
                for a in &mut p.angles {
                    ui.add(egui::DragValue::new(a).speed(1.0).range(-360.0..=360.0))
                        .labelled_by(l.id);
                }
            });
            ui.horizontal(|ui| {
                let l = ui.label(format!("  {key} scale"));
                for (i, s) in p.scale.iter_mut().enumerate() {
                    // A reflection is the x scale's sign; y and z stay positive.
                    let v = if i == 0 {
                        egui::DragValue::new(s).speed(0.01)
                    } else {
                        egui::DragValue::new(s).speed(0.01).range(1e-6..=1e12)
                    };
                    ui.add(v).labelled_by(l.id);
                }
            });
            if (p.angles != pose.angles || p.scale != pose.scale)
                && p.scale.iter().all(|s| s.is_finite() && s.abs() > 1e-6)
            {
                let new = compose(&p);
                m = about_pivot(&m, &new, pivot).unwrap_or(new);
            }
        }
        None => {
            ui.label(
                egui::RichText::new(format!("  {key}: sheared or projective; edit its entries"))
                    .small(),
            );
        }
    }
    egui::CollapsingHeader::new(format!("  {key} matrix"))
        .default_open(false)
        .show(ui, |ui| {
            egui::Grid::new(format!("{key} matrix grid")).show(ui, |ui| {
                for r in 0..3 {
                    for c in 0..4 {
                        ui.add(egui::DragValue::new(&mut m[r * 4 + c]).speed(0.01));
                    }
                    ui.end_row();
                }
            });
        });
    if m != before && m.iter().all(|v| v.is_finite()) {
        *t = Some(m);
        true
    } else {
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn apply(m: &[f64; 16], p: [f64; 3]) -> [f64; 3] {
        let v = linear(m) * DVec3::from(p) + DVec3::new(m[3], m[7], m[11]);
        v.to_array()
    }

    fn close(a: &[f64], b: &[f64], tol: f64) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tol)
    }

    #[test]
    fn poses_round_trip_through_their_matrices() {
        for (angles, scale) in [
            ([0.0, 0.0, 0.0], [1.0, 1.0, 1.0]),
            ([30.0, -20.0, 75.0], [1.0, 2.0, 0.5]),
            ([-170.0, 89.0, 10.0], [3.0, 3.0, 3.0]),
            ([45.0, 0.0, -120.0], [-1.0, 1.0, 1.0]),
        ] {
            let p = Pose {
                translation: [78.0, 76.0, -50.0],
                angles,
                scale,
            };
            let m = compose(&p);
            let q = decompose(&m).expect("a pose");
            assert!(
                close(&q.angles, &angles, 1e-9),
                "{angles:?} -> {:?}",
                q.angles
            );
            assert!(close(&q.scale, &scale, 1e-12), "{scale:?} -> {:?}", q.scale);
            assert_eq!(q.translation, p.translation);
            assert!(close(&compose(&q), &m, 1e-12));
        }
    }

    #[test]
    fn the_convention_turns_about_x_then_y_then_z() {
        // 90 degrees about z takes x to y; about x first (90), y goes to z.
        let m = compose(&Pose {
            translation: [0.0; 3],
            angles: [0.0, 0.0, 90.0],
            scale: [1.0; 3],
        });
        assert!(close(&apply(&m, [1.0, 0.0, 0.0]), &[0.0, 1.0, 0.0], 1e-12));
        let m = compose(&Pose {
            translation: [0.0; 3],
            angles: [90.0, 0.0, 90.0],
            scale: [1.0; 3],
        });
        // y -> z by x, then z stays under z.
        assert!(close(&apply(&m, [0.0, 1.0, 0.0]), &[0.0, 0.0, 1.0], 1e-12));
    }

    #[test]
    fn an_identity_with_negative_zeros_has_angles_of_plus_zero() {
        let mut m = IDENTITY;
        m[6] = -0.0;
        m[4] = -0.0;
        let q = decompose(&m).unwrap();
        assert!(
            q.angles.iter().all(|a| *a == 0.0 && a.is_sign_positive()),
            "{:?}",
            q.angles
        );
    }

    #[test]
    fn gimbal_lock_keeps_the_matrix() {
        let p = Pose {
            translation: [1.0, 2.0, 3.0],
            angles: [25.0, 90.0, 40.0],
            scale: [1.0; 3],
        };
        let m = compose(&p);
        let q = decompose(&m).unwrap();
        assert_eq!(q.angles[0], 0.0);
        assert!(close(&compose(&q), &m, 1e-9));
    }

    #[test]
    fn a_rotation_stored_in_f32_is_a_pose() {
        let m = compose(&Pose {
            translation: [1.5, -2.0, 30.0],
            angles: [12.0, -33.0, 71.0],
            scale: [1.0; 3],
        });
        let f32ed = m.map(|v| v as f32 as f64);
        let q = decompose(&f32ed).expect("a pose within f32 rounding");
        assert!(close(&q.angles, &[12.0, -33.0, 71.0], 1e-4));
        // Six printed digits too.
        let printed = m.map(|v| format!("{v:.6}").parse::<f64>().unwrap());
        assert!(decompose(&printed).is_some());
    }

    #[test]
    fn sheared_and_projective_matrices_are_not_poses() {
        let mut shear = IDENTITY;
        shear[1] = 0.3;
        assert!(decompose(&shear).is_none());
        let mut proj = IDENTITY;
        proj[12] = 0.1;
        assert!(decompose(&proj).is_none());
        let mut flat = IDENTITY;
        flat[10] = 0.0;
        assert!(decompose(&flat).is_none());
        let mut nan = IDENTITY;
        nan[3] = f64::NAN;
        assert!(decompose(&nan).is_none());
    }

    #[test]
    fn turning_about_the_pivot_keeps_the_pivots_point() {
        let old = compose(&Pose {
            translation: [78.0, 76.0, -50.0],
            angles: [0.0, 0.0, 0.0],
            scale: [1.0; 3],
        });
        let pivot = [10.0, -5.0, 20.0];
        let q = [-68.0, -81.0, 70.0]; // old maps q to the pivot
        assert!(close(&apply(&old, q), &pivot, 1e-12));
        let new = compose(&Pose {
            translation: [78.0, 76.0, -50.0],
            angles: [15.0, -30.0, 60.0],
            scale: [1.5, 1.5, 1.5],
        });
        let m = about_pivot(&old, &new, pivot).unwrap();
        assert!(close(&apply(&m, q), &pivot, 1e-9), "{:?}", apply(&m, q));
        // The linear part is the new one.
        assert!(close(&m[..3], &new[..3], 0.0) && close(&m[8..11], &new[8..11], 0.0));
        let mut singular = IDENTITY;
        singular[0] = 0.0;
        assert!(about_pivot(&singular, &new, pivot).is_none());
    }
}
