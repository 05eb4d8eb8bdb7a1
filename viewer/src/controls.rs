//! The viewer's camera: an orbit about a target (the scene's `camera.azimuth`, `elevation`,
//! `distance` and `target`, with the convention of `occlusion::camera`: azimuth 0 looks along
//! +y, azimuth 90 along +x, elevation 90 looks down from +z), changed by mouse and keys and
//! written back into the scene that the renderer draws, so that what the viewer shows is the
//! scene `umbra render` draws.

use glam::DVec3;
use scene::spec::{CameraSpec, ProjectionKind};

/// Degrees of orbit per logical pixel dragged.
pub const DEGREES_PER_PIXEL: f64 = 0.4;
/// Degrees per arrow-key press.
pub const KEY_STEP: f64 = 5.0;
/// The closest orbit distance, in bounding-sphere radii (as `Camera::orbit`).
pub const MIN_DISTANCE: f64 = 1.01;
/// Elevation is kept inside [-LIMIT, LIMIT] degrees, so that the up vector stays defined: the
/// README's top view (89.9) is drawn as `umbra render` draws it (89.5 held a scene's 89.9
/// at 89.5 in the view, its screenshot and the saved scene).
pub const ELEVATION_LIMIT: f64 = 89.9;

/// The orbit: angles in degrees, distance in bounding-sphere radii, the target in world units,
/// the projection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    pub azimuth: f64,
    pub elevation: f64,
    pub distance: f64,
    pub target: DVec3,
    pub orthographic: bool,
    /// The orthographic view's height in world units (`camera.height`): what zooming changes
    /// in an orthographic view, where the eye's distance changes nothing on screen.
    pub ortho_height: f64,
}

/// A standard view of RAS data (x to the Right, y Anterior, z Superior): from the left, right,
/// front, back, top or bottom.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StandardView {
    Left,
    Right,
    Anterior,
    Posterior,
    Superior,
    Inferior,
}

impl StandardView {
    /// Azimuth and elevation that look at the target from this side: from the left the eye is
    /// at -x and looks along +x (azimuth 90), from the front at +y looking along -y (180).
    pub fn angles(self) -> (f64, f64) {
        match self {
            StandardView::Left => (90.0, 0.0),
            StandardView::Right => (-90.0, 0.0),
            StandardView::Anterior => (180.0, 0.0),
            StandardView::Posterior => (0.0, 0.0),
            StandardView::Superior => (0.0, ELEVATION_LIMIT),
            StandardView::Inferior => (0.0, -ELEVATION_LIMIT),
        }
    }
}

impl Orbit {
    /// The orbit of a scene's camera in a scene of `bounds`: its angles and distance, or, for
    /// a camera given by `eye`, the orbit that puts the eye there.
    pub fn of(c: &CameraSpec, bounds: [DVec3; 2]) -> Orbit {
        let centre = (bounds[0] + bounds[1]) * 0.5;
        let radius = ((bounds[1] - bounds[0]).length() * 0.5).max(1e-9);
        let target = c.target.map_or(centre, DVec3::from);
        let mut o = Orbit {
            azimuth: c.azimuth,
            elevation: c.elevation,
            distance: c.distance,
            target,
            orthographic: c.projection == ProjectionKind::Orthographic,
            // The scene's, else the height `scene::compile::camera` fits to the scene.
            ortho_height: c.height.unwrap_or(2.1 * radius),
        };
        if let Some(eye) = c.eye {
            let v = target - DVec3::from(eye);
            let len = v.length();
            if len > 1e-12 {
                let f = v / len;
                o.elevation = (-f.z).clamp(-1.0, 1.0).asin().to_degrees();
                o.azimuth = f.x.atan2(f.y).to_degrees();
                o.distance = len / radius;
            }
        }
        o.clamped()
    }

    /// The direction the camera looks along (unit).
    pub fn forward(&self) -> DVec3 {
        let (a, e) = (self.azimuth.to_radians(), self.elevation.to_radians());
        DVec3::new(a.sin() * e.cos(), a.cos() * e.cos(), -e.sin())
    }

    fn clamped(mut self) -> Orbit {
        self.azimuth = (self.azimuth + 180.0).rem_euclid(360.0) - 180.0;
        self.elevation = self.elevation.clamp(-ELEVATION_LIMIT, ELEVATION_LIMIT);
        self.distance = self.distance.clamp(MIN_DISTANCE, 1e4);
        self
    }

    /// A drag by `(dx, dy)` logical pixels: right turns the scene right (the eye left),
    /// down tilts it towards the viewer (the eye up).
    pub fn drag(self, dx: f64, dy: f64) -> Orbit {
        Orbit {
            azimuth: self.azimuth - dx * DEGREES_PER_PIXEL,
            elevation: self.elevation + dy * DEGREES_PER_PIXEL,
            ..self
        }
        .clamped()
    }

    /// Zoom by `steps` (positive: closer): the distance is divided by `1.1^steps`, or in an
    /// orthographic view its height (within 1e-9 to 1e15 world units).
    pub fn zoom(self, steps: f64) -> Orbit {
        let k = 1.1f64.powf(steps);
        match self.orthographic {
            true => Orbit {
                ortho_height: (self.ortho_height / k).clamp(1e-9, 1e15),
                ..self
            },
            false => Orbit {
                distance: self.distance / k,
                ..self
            }
            .clamped(),
        }
    }

    /// Pan by `(dx, dy)` in world units along the view's right and up axes.
    pub fn pan(self, dx: f64, dy: f64) -> Orbit {
        let (right, up) = self.axes();
        Orbit {
            target: self.target - right * dx + up * dy,
            ..self
        }
    }

    /// Looks from a standard side, keeping distance and target.
    pub fn standard(self, v: StandardView) -> Orbit {
        let (azimuth, elevation) = v.angles();
        Orbit {
            azimuth,
            elevation,
            ..self
        }
        .clamped()
    }

    /// The orbit that keeps the eye where it is and turns about `point` (a picked point):
    /// the new target, the distance to it (at least [`MIN_DISTANCE`] radii).
    pub fn pivot(self, eye: DVec3, point: DVec3, bounds: [DVec3; 2]) -> Orbit {
        let c = CameraSpec {
            eye: Some(eye.to_array()),
            target: Some(point.to_array()),
            projection: if self.orthographic {
                ProjectionKind::Orthographic
            } else {
                ProjectionKind::Perspective
            },
            ..CameraSpec::default()
        };
        Orbit {
            ortho_height: self.ortho_height,
            ..Orbit::of(&c, bounds)
        }
    }

    /// The view's right and up axes (unit; as [`Orbit::pan`] moves along them).
    fn axes(&self) -> (DVec3, DVec3) {
        let f = self.forward();
        let right = f.cross(DVec3::Z).try_normalize().unwrap_or(DVec3::X);
        (right, right.cross(f))
    }

    /// How much a drag of `(dx, dy)` logical points (x right, y down) changes the `offset` of
    /// a clipping plane `normal . x <= offset` (`clip[]` of a scene, in world units): the
    /// plane follows the pointer along its normal, the drag taken as a move on the view plane
    /// (`per_point` world units a point, right and up as the view's) and, upwards, as a push
    /// away from the eye, so that a plane facing the camera moves too (up: further).
    pub fn clip_drag(&self, normal: DVec3, dx: f64, dy: f64, per_point: f64) -> f64 {
        let (right, up) = self.axes();
        normal.dot(right * dx - up * dy - self.forward() * dy) * per_point
    }

    /// A clipping plane `normal . x <= offset` tilted by a drag of `(dx, dy)` logical points:
    /// its normal turned [`DEGREES_PER_PIXEL`] a point about the view's up axis (across) and
    /// right axis (down), the plane turned about `pivot` (it keeps its distance from it: a
    /// plane through the pivot turns in place; a drag in steps ends where one drag of their
    /// sum does); the normal keeps its length. Returns the new normal and offset.
    pub fn clip_tilt(
        &self,
        normal: DVec3,
        offset: f64,
        dx: f64,
        dy: f64,
        pivot: DVec3,
    ) -> (DVec3, f64) {
        let len = normal.length();
        if len == 0.0 {
            return (normal, offset);
        }
        let (right, up) = self.axes();
        let turn = glam::DQuat::from_axis_angle(up, (dx * DEGREES_PER_PIXEL).to_radians())
            * glam::DQuat::from_axis_angle(right, (dy * DEGREES_PER_PIXEL).to_radians());
        let turned = turn * normal;
        (turned, offset + (turned - normal).dot(pivot))
    }

    /// Writes the orbit into a scene's camera (an orbit camera: `eye` cleared, `up` +z; the
    /// height only where orthographic).
    pub fn apply(&self, c: &mut CameraSpec) {
        c.eye = None;
        c.up = [0.0, 0.0, 1.0];
        c.azimuth = self.azimuth;
        c.elevation = self.elevation;
        c.distance = self.distance;
        c.target = Some(self.target.to_array());
        c.projection = if self.orthographic {
            c.height = Some(self.ortho_height);
            ProjectionKind::Orthographic
        } else {
            // A perspective camera has no height (the scene file's, for an orthographic one,
            // would draw a note that it changes nothing; the orbit keeps its own).
            c.height = None;
            ProjectionKind::Perspective
        };
    }
}

/// Where the plane `normal . x = offset` cuts the box `bounds`: the points where it crosses
/// the box's twelve edges, in order around the plane (a polygon of three to six corners), or
/// nothing where it misses the box or `normal` is zero. The viewer outlines the clipping plane
/// being dragged with it.
pub fn plane_outline(normal: DVec3, offset: f64, bounds: [DVec3; 2]) -> Vec<DVec3> {
    let Some(n) = normal.try_normalize() else {
        return vec![];
    };
    let corner = |i: usize| {
        DVec3::new(
            if i & 1 == 0 { bounds[0].x } else { bounds[1].x },
            if i & 2 == 0 { bounds[0].y } else { bounds[1].y },
            if i & 4 == 0 { bounds[0].z } else { bounds[1].z },
        )
    };
    let mut pts: Vec<DVec3> = vec![];
    for a in 0..8 {
        for bit in [1, 2, 4] {
            if a & bit != 0 {
                continue;
            }
            let (pa, pb) = (corner(a), corner(a | bit));
            let (da, db) = (normal.dot(pa) - offset, normal.dot(pb) - offset);
            if (da < 0.0) != (db < 0.0) {
                let p = pa + (pb - pa) * (da / (da - db));
                // A plane through a corner crosses its three edges there: once.
                let scale = (bounds[1] - bounds[0]).length().max(1e-12);
                if pts.iter().all(|q| (*q - p).length() > 1e-9 * scale) {
                    pts.push(p);
                }
            }
        }
    }
    if pts.len() < 3 {
        return vec![];
    }
    let c = pts.iter().sum::<DVec3>() / pts.len() as f64;
    let u = n.any_orthonormal_vector();
    let v = n.cross(u);
    let angle = |p: &DVec3| (*p - c).dot(v).atan2((*p - c).dot(u));
    pts.sort_by(|p, q| angle(p).total_cmp(&angle(q)));
    pts
}

/// A camera path file (`umbra render --camera-path`, `scene::camera_path`) through the
/// orbits `keys`, a key a second, Catmull-Rom, 30 frames a second, for a scene whose camera
/// targets `target`: orbit keys (azimuth, elevation, distance) when every key has that
/// target, else look-at keys (eye, target, up) about the scene of `bounds`, with the view's
/// `height` where a key is orthographic (its zoom). Azimuths are unwrapped so that each step
/// turns the short way.
pub fn camera_path(keys: &[Orbit], bounds: [DVec3; 2], target: DVec3) -> Result<String, String> {
    if keys.len() < 2 {
        return Err(format!(
            "a camera path needs two keys or more ({})",
            keys.len()
        ));
    }
    let radius = ((bounds[1] - bounds[0]).length() * 0.5).max(1e-9);
    let same_target = keys.iter().all(|k| (k.target - target).length() < 1e-9);
    let mut out = String::from("fps = 30\ninterpolation = \"catmull-rom\"\n");
    let mut az = keys[0].azimuth;
    for (i, k) in keys.iter().enumerate() {
        if i > 0 {
            // The nearest equivalent of this azimuth to the previous key's.
            az += (k.azimuth - az + 180.0).rem_euclid(360.0) - 180.0;
        }
        out += &format!("\n[[key]]\ntime = {}.0\n", i);
        if same_target {
            out += &format!(
                "azimuth = {az:?}\nelevation = {:?}\ndistance = {:?}\n",
                k.elevation, k.distance
            );
        } else {
            let eye = k.target - k.forward() * k.distance * radius;
            let f = |v: DVec3| format!("[{:?}, {:?}, {:?}]", v.x, v.y, v.z);
            out += &format!(
                "eye = {}\ntarget = {}\nup = [0.0, 0.0, 1.0]\n",
                f(eye),
                f(k.target)
            );
        }
        if k.orthographic {
            out += &format!("height = {:?}\n", k.ortho_height);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bounds() -> [DVec3; 2] {
        [DVec3::new(-10.0, -20.0, 0.0), DVec3::new(30.0, 20.0, 40.0)]
    }

    #[test]
    fn an_eye_camera_becomes_the_orbit_that_puts_the_eye_there() {
        let b = bounds();
        let radius = (b[1] - b[0]).length() * 0.5;
        let centre = (b[0] + b[1]) * 0.5;
        for (az, el, dist) in [(30.0, 20.0, 2.5), (-120.0, -40.0, 4.0), (179.0, 80.0, 1.5)] {
            let o = Orbit {
                azimuth: az,
                elevation: el,
                distance: dist,
                target: centre,
                orthographic: false,
                ortho_height: 2.1 * radius,
            };
            let eye = centre - o.forward() * dist * radius;
            let c = CameraSpec {
                eye: Some(eye.to_array()),
                ..CameraSpec::default()
            };
            let back = Orbit::of(&c, b);
            assert!((back.azimuth - az).abs() < 1e-9, "{az}: {}", back.azimuth);
            assert!((back.elevation - el).abs() < 1e-9);
            assert!((back.distance - dist).abs() < 1e-9);
        }
    }

    #[test]
    fn the_forward_direction_follows_the_camera_convention() {
        let o = Orbit::of(&CameraSpec::default(), bounds());
        let at = |az: f64, el: f64| Orbit {
            azimuth: az,
            elevation: el,
            ..o
        };
        assert!((at(0.0, 0.0).forward() - DVec3::Y).length() < 1e-12);
        assert!((at(90.0, 0.0).forward() - DVec3::X).length() < 1e-12);
        assert!((at(0.0, 90.0).forward() + DVec3::Z).length() < 1e-12);
        // The standard views look from their side: the left view's eye is at -x.
        let l = o.standard(StandardView::Left);
        assert!((l.forward() - DVec3::X).length() < 1e-12);
        let a = o.standard(StandardView::Anterior);
        assert!((a.forward() + DVec3::Y).length() < 1e-12);
        assert!(o.standard(StandardView::Superior).forward().z < -0.99);
        assert!(o.standard(StandardView::Inferior).forward().z > 0.99);
    }

    #[test]
    fn a_dragged_clip_plane_follows_the_pointer_along_its_normal() {
        let o = Orbit::of(&CameraSpec::default(), bounds());
        let (right, up) = o.axes();
        let f = o.forward();
        assert!(right.dot(f).abs() < 1e-12 && up.dot(f).abs() < 1e-12 && up.z > 0.0);
        // A plane whose normal is the view's right moves right with a drag to the right, by
        // the drag's length in world units, and not with a drag up or down.
        assert!((o.clip_drag(right, 30.0, 0.0, 0.5) - 15.0).abs() < 1e-9);
        assert!(o.clip_drag(right, 0.0, 40.0, 0.5).abs() < 1e-9);
        // Facing up: a drag up (negative y) raises it; facing away from the eye: a drag up
        // pushes it further.
        assert!((o.clip_drag(up, 0.0, -20.0, 0.5) - 10.0).abs() < 1e-9);
        assert!((o.clip_drag(f, 0.0, -20.0, 0.5) - 10.0).abs() < 1e-9);
        assert!((o.clip_drag(-f, 0.0, -20.0, 0.5) + 10.0).abs() < 1e-9);
        // An unnormalised normal keeps `normal . x <= offset` moving by the same distance.
        assert!((o.clip_drag(right * 2.0, 30.0, 0.0, 0.5) - 30.0).abs() < 1e-9);
    }

    #[test]
    fn a_tilted_clip_plane_turns_about_the_pivot() {
        let o = Orbit::of(&CameraSpec::default(), bounds());
        let (right, up) = o.axes();
        let pivot = DVec3::new(3.0, -4.0, 12.0);
        // A plane facing the view's right, 5 units past the pivot.
        let normal = right * 2.0;
        let offset = normal.dot(pivot) + 2.0 * 5.0;
        let distance = |n: DVec3, off: f64| (off - n.dot(pivot)) / n.length();
        // 225 points across: 90 degrees about the view's up axis.
        let (n, off) = o.clip_tilt(normal, offset, 225.0, 0.0, pivot);
        assert!(
            (n.length() - 2.0).abs() < 1e-9,
            "the normal keeps its length"
        );
        assert!(
            (n.normalize().dot(right)).abs() < 1e-9,
            "turned a right angle: {n}"
        );
        assert!(n.normalize().dot(up).abs() < 1e-9, "about the up axis: {n}");
        assert!(
            (distance(n, off) - 5.0).abs() < 1e-9,
            "5 units from the pivot still"
        );
        // In steps: where one drag of their sum ends.
        let mut step = (normal, offset);
        for _ in 0..5 {
            step = o.clip_tilt(step.0, step.1, 45.0, 0.0, pivot);
        }
        assert!((step.0 - n).length() < 1e-9 && (step.1 - off).abs() < 1e-9);
        // Down turns it about the right axis: a plane facing up tips towards the view.
        let (n2, _) = o.clip_tilt(up, up.dot(pivot), 0.0, 225.0, pivot);
        assert!(
            n2.dot(right).abs() < 1e-9 && n2.dot(up).abs() < 1e-9,
            "{n2}"
        );
        // No drag, no change; no direction, no change.
        let (n3, off3) = o.clip_tilt(normal, offset, 0.0, 0.0, pivot);
        assert!((n3 - normal).length() < 1e-12 && (off3 - offset).abs() < 1e-9);
        assert_eq!(
            o.clip_tilt(DVec3::ZERO, 1.0, 10.0, 0.0, pivot),
            (DVec3::ZERO, 1.0)
        );
    }

    #[test]
    fn a_plane_cuts_the_box_in_a_polygon_around_its_normal() {
        let b = bounds();
        let centre = (b[0] + b[1]) * 0.5;
        let on_box = |p: DVec3| {
            let inside = (0..3).all(|a| p[a] >= b[0][a] - 1e-9 && p[a] <= b[1][a] + 1e-9);
            let face =
                (0..3).any(|a| (p[a] - b[0][a]).abs() < 1e-9 || (p[a] - b[1][a]).abs() < 1e-9);
            inside && face
        };
        for (n, corners) in [
            (DVec3::X, 4),
            (DVec3::new(0.0, 1.0, 1.0), 4),
            (DVec3::new(1.0, 1.0, 1.0), 6),
            // Through two of the box's edges: their corners once each.
            (DVec3::new(1.0, 1.0, 0.0), 4),
        ] {
            let offset = n.dot(centre);
            let poly = plane_outline(n, offset, b);
            assert_eq!(poly.len(), corners, "{n}");
            for (i, p) in poly.iter().enumerate() {
                assert!((n.dot(*p) - offset).abs() < 1e-9 && on_box(*p), "{n}: {p}");
                // In order: each turn about the normal has the same sense (a convex polygon,
                // no crossing sides).
                let (q, r) = (poly[(i + 1) % poly.len()], poly[(i + 2) % poly.len()]);
                assert!((q - *p).cross(r - q).dot(n) > 0.0, "{n}: corner {i}");
            }
        }
        // An axis plane through the box cuts it in its cross-section.
        let x = plane_outline(DVec3::X, 5.0, b);
        let area: f64 = (0..x.len())
            .map(|i| x[i].cross(x[(i + 1) % x.len()]).dot(DVec3::X) * 0.5)
            .sum();
        assert!((area.abs() - 40.0 * 40.0).abs() < 1e-6, "{area}");
        // Outside the box, or without a direction: nothing.
        assert!(plane_outline(DVec3::X, 31.0, b).is_empty());
        assert!(plane_outline(DVec3::ZERO, 0.0, b).is_empty());
        // Touching the box at a corner only (where three edges meet the plane): nothing.
        let n = DVec3::ONE;
        assert!(plane_outline(n, n.dot(b[1]), b).is_empty());
    }

    #[test]
    fn drags_zooms_and_pans_stay_in_range() {
        let o = Orbit::of(&CameraSpec::default(), bounds());
        let d = o.drag(100.0, 0.0);
        assert!((d.azimuth - (o.azimuth - 40.0)).abs() < 1e-9);
        assert_eq!(o.drag(0.0, 1e6).elevation, ELEVATION_LIMIT);
        assert_eq!(o.drag(0.0, -1e6).elevation, -ELEVATION_LIMIT);
        // Azimuth wraps into [-180, 180).
        let w = o.drag(-1000.0, 0.0);
        assert!((-180.0..180.0).contains(&w.azimuth));
        assert!((o.zoom(1.0).distance - o.distance / 1.1).abs() < 1e-12);
        assert_eq!(o.zoom(1e3).distance, MIN_DISTANCE);
        // Orthographic: the view's height zooms (the eye's distance changes nothing on
        // screen there), written as camera.height, which the renderer's camera takes.
        let radius = (bounds()[1] - bounds()[0]).length() * 0.5;
        let ortho = Orbit {
            orthographic: true,
            ..o
        };
        assert!((ortho.ortho_height - 2.1 * radius).abs() < 1e-9);
        let z = ortho.zoom(2.0);
        assert_eq!(z.distance, ortho.distance);
        assert!((z.ortho_height - ortho.ortho_height / 1.21).abs() < 1e-9);
        let mut c = CameraSpec::default();
        z.apply(&mut c);
        assert_eq!(c.height, Some(z.ortho_height));
        // Back to perspective the height goes (it would draw the note that it changes nothing).
        let mut p = c.clone();
        Orbit {
            orthographic: false,
            ..z
        }
        .apply(&mut p);
        assert_eq!(p.height, None);
        let mut s = scene::spec::parse("", "s", std::path::Path::new("."), &[]).unwrap();
        s.camera = c;
        let cam = scene::compile::camera(&s, bounds()).unwrap();
        assert_eq!(
            cam.projection,
            occlusion::camera::Projection::Orthographic {
                height: z.ortho_height
            }
        );
        // A pan moves the target perpendicular to the view direction.
        let p = o.pan(3.0, 4.0);
        let moved = p.target - o.target;
        assert!((moved.length() - 5.0).abs() < 1e-9);
        assert!(moved.dot(o.forward()).abs() < 1e-9);
        // Camera paths: orbit keys about the scene's target, look-at keys once a key pans;
        // both parse as camera paths and put the eye where the orbit does.
        let dir = tempfile::tempdir().unwrap();
        let keys = [o, o.drag(300.0, -20.0), o.drag(600.0, 10.0).zoom(2.0)];
        let radius = (bounds()[1] - bounds()[0]).length() * 0.5;
        for (keys, orbit_keys) in [(keys.to_vec(), true), (vec![o, o.pan(5.0, 0.0)], false)] {
            let text = camera_path(&keys, bounds(), o.target).unwrap();
            let f = dir.path().join("p.toml");
            std::fs::write(&f, &text).unwrap();
            let path = scene::camera_path::CameraPath::load(&f).unwrap();
            assert_eq!(path.key.len(), keys.len());
            for (k, want) in path.key.iter().zip(&keys) {
                if orbit_keys {
                    let (az, el) = (k.azimuth.unwrap(), k.elevation.unwrap());
                    let dz = (az - want.azimuth).rem_euclid(360.0);
                    assert!(dz < 1e-9 || 360.0 - dz < 1e-9, "{az} {}", want.azimuth);
                    assert!((el - want.elevation).abs() < 1e-9);
                    assert!((k.distance.unwrap() - want.distance).abs() < 1e-9);
                } else {
                    let eye = DVec3::from(k.eye.unwrap());
                    let expect = want.target - want.forward() * want.distance * radius;
                    assert!((eye - expect).length() < 1e-9);
                }
            }
        }
        // The azimuth is unwrapped: from 170 to -170 turns 20 degrees, not 340.
        let a = Orbit {
            azimuth: 170.0,
            ..o
        };
        let text = camera_path(
            &[
                a,
                Orbit {
                    azimuth: -170.0,
                    ..o
                },
            ],
            bounds(),
            o.target,
        )
        .unwrap();
        assert!(text.contains("azimuth = 190.0"), "{text}");
        assert!(camera_path(&[o], bounds(), o.target).is_err());
        // Orthographic keys carry their zoom as the view's height (the distance changes
        // nothing there), which the path's cameras take.
        let flat = Orbit {
            orthographic: true,
            ..o
        };
        let keys = [flat, flat.zoom(2.0), flat.pan(5.0, 0.0).zoom(0.5)];
        assert!(keys[1].ortho_height < flat.ortho_height);
        for target in [o.target, DVec3::ZERO] {
            let text = camera_path(&keys, bounds(), target).unwrap();
            let path = scene::camera_path::CameraPath::parse(&text).unwrap();
            let base = scene::spec::CameraSpec::default();
            for (i, k) in keys.iter().enumerate() {
                let c = path.camera_at(&base, i as f64);
                assert_eq!(c.height, Some(k.ortho_height), "{text}");
            }
        }
        assert!(!text.contains("height"), "perspective keys: {text}");
        // A pivot keeps the eye and looks at the picked point.
        let b = bounds();
        let radius = (b[1] - b[0]).length() * 0.5;
        let eye = o.target - o.forward() * o.distance * radius;
        let point = o.target + DVec3::new(3.0, -2.0, 5.0);
        let q = o.pivot(eye, point, b);
        assert!((q.target - point).length() < 1e-9);
        let eye_after = q.target - q.forward() * q.distance * radius;
        assert!((eye_after - eye).length() < 1e-9);
        // The orbit written back reads back the same.
        let mut c = CameraSpec::default();
        p.apply(&mut c);
        assert_eq!(Orbit::of(&c, bounds()), p);
    }
}
