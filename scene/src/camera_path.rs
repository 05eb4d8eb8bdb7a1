//! Frame sequences of one scene: turntables (`--orbit N`) and keyframed camera paths
//! (`--camera-path FILE`). Each frame is the scene with its `[camera]` replaced, so a frame
//! is exactly the image a single render with those camera keys gives.
//!
//! Turntable: frame `k` of `n` turns the camera by `k 360 / n` degrees. An orbit camera (no
//! `camera.eye`) renders at `camera.azimuth + k 360 / n`; a look-at camera turns its `eye`
//! about `target` around `up` by the same angle, in the sense in which the azimuth grows
//! (clockwise seen from the tip of `up`).
//!
//! Camera path file (TOML; unknown keys are errors naming key and line):
//!
//! ```toml
//! frames = 120              # frames in all, first key to last; or
//! # fps = 30                # frames per second of `time`: floor((t_last - t_first) fps) + 1
//! interpolation = "linear"  # or "catmull-rom" (through every key, C1)
//! [[key]]
//! time = 0.0                # seconds, increasing
//! azimuth = 30.0            # orbit keys: azimuth, elevation, distance (each defaults to
//! elevation = 20.0          #   the scene's camera value)
//! [[key]]
//! time = 4.0
//! azimuth = 390.0           # angles are not wrapped: 30 -> 390 is one full turn
//! ```
//!
//! Look-at keys give `eye` (and optionally `target`, `up`; default the scene camera's, or the
//! scene's centre for `target`); all keys of a path are of one kind. `fov_y` may be keyed in
//! either kind, and so may `height` (an orthographic camera's view height, world units); a
//! key with only `fov_y` or `height` (and `time`) joins a path of either kind. Values
//! are interpolated per component between the keys around each frame's time; `up` is
//! normalised after interpolation. Keys take the ranges of the scene's `[camera]` (`fov_y` in
//! (0, 180), `distance` above 1, `height` positive, points and heights within 1e15, `up` not
//! zero); Catmull-Rom values that
//! overshoot them are held inside.

use crate::spec::{CameraSpec, Scene};
use serde::Deserialize;
use std::path::Path;

/// How values between keys are found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Interpolation {
    #[default]
    Linear,
    CatmullRom,
}

/// One key of a camera path.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Key {
    pub time: f64,
    pub azimuth: Option<f64>,
    pub elevation: Option<f64>,
    pub distance: Option<f64>,
    pub eye: Option<[f64; 3]>,
    pub target: Option<[f64; 3]>,
    pub up: Option<[f64; 3]>,
    pub fov_y: Option<f64>,
    /// An orthographic camera's view height, world units (a perspective camera's image does
    /// not depend on it).
    pub height: Option<f64>,
}

/// A camera path file.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraPath {
    pub frames: Option<u32>,
    pub fps: Option<f64>,
    #[serde(default)]
    pub interpolation: Interpolation,
    pub key: Vec<Key>,
}

/// The most frames a sequence may have.
pub const MAX_FRAMES: u32 = 100_000;

/// Value at `t` of the samples `(t_i, v_i)` (times increasing, at least one).
fn interpolate(keys: &[(f64, f64)], t: f64, how: Interpolation) -> f64 {
    let n = keys.len();
    if n == 1 || t <= keys[0].0 {
        return keys[0].1;
    }
    if t >= keys[n - 1].0 {
        return keys[n - 1].1;
    }
    let i = keys.iter().rposition(|k| k.0 <= t).unwrap_or(0).min(n - 2);
    let (t0, p1) = keys[i];
    let (t1, p2) = keys[i + 1];
    let u = (t - t0) / (t1 - t0);
    match how {
        Interpolation::Linear => p1 + (p2 - p1) * u,
        Interpolation::CatmullRom => {
            // Tangents by finite differences over time (non-uniform keys), ends clamped.
            let m = |j: usize| -> f64 {
                let (a, b) = (j.saturating_sub(1), (j + 1).min(n - 1));
                if a == b {
                    0.0
                } else {
                    (keys[b].1 - keys[a].1) / (keys[b].0 - keys[a].0)
                }
            };
            let h = t1 - t0;
            let (m1, m2) = (m(i) * h, m(i + 1) * h);
            let (u2, u3) = (u * u, u * u * u);
            (2.0 * u3 - 3.0 * u2 + 1.0) * p1
                + (u3 - 2.0 * u2 + u) * m1
                + (-2.0 * u3 + 3.0 * u2) * p2
                + (u3 - u2) * m2
        }
    }
}

impl CameraPath {
    /// Reads and checks a camera path file.
    pub fn load(path: &Path) -> Result<CameraPath, String> {
        let text =
            volume::read_text(path, 64 << 20).map_err(|e| format!("{}: {e}", path.display()))?;
        Self::parse(&text).map_err(|e| format!("{}: {e}", path.display()))
    }

    /// Parses and checks a camera path.
    pub fn parse(text: &str) -> Result<CameraPath, String> {
        let p: CameraPath = toml::from_str(text).map_err(|e| e.to_string())?;
        if p.key.is_empty() {
            return Err("key: a camera path needs at least one [[key]]".into());
        }
        for (i, k) in p.key.iter().enumerate() {
            let orbit = k.azimuth.is_some() || k.elevation.is_some() || k.distance.is_some();
            let look = k.eye.is_some() || k.target.is_some() || k.up.is_some();

            if orbit && look {
                return Err(format!(
                    "key[{i}]: give orbit angles (azimuth, elevation, distance) or eye/target/up, not both"
                ));
            }
            let values = [k.time]
                .into_iter()
                .chain(k.azimuth)
                .chain(k.elevation)
                .chain(k.distance)
                .chain(k.fov_y)
                .chain(k.height)
                .chain(k.eye.into_iter().flatten())
                .chain(k.target.into_iter().flatten())
                .chain(k.up.into_iter().flatten());
            if values.into_iter().any(|v| !v.is_finite()) {
                return Err(format!("key[{i}]: every value must be finite"));
            }
            // The ranges of the scene's `[camera]` keys.
            if let Some(f) = k.fov_y.filter(|f| !(*f > 0.0 && *f < 180.0)) {
                return Err(format!("key[{i}].fov_y: {f} is not in (0, 180) degrees"));
            }
            if let Some(h) = k
                .height
                .filter(|h| !(*h > 0.0 && *h <= volume::MAX_COORDINATE))
            {
                return Err(format!(
                    "key[{i}].height: {h} is not a positive height up to {:e}",
                    volume::MAX_COORDINATE
                ));
            }
            if let Some(d) = k.distance.filter(|d| *d <= 1.0) {
                return Err(format!(
                    "key[{i}].distance: {d} must be above 1 (bounding-sphere radii)"
                ));
            }
            for (name, v) in [("eye", k.eye), ("target", k.target), ("up", k.up)] {
                if let Some(v) = v.filter(|v| v.iter().any(|x| x.abs() > volume::MAX_COORDINATE)) {
                    return Err(format!(
                        "key[{i}].{name}: {v:?} is not a point within {:e}",
                        volume::MAX_COORDINATE
                    ));
                }
            }
            if k.up.is_some_and(|u| u == [0.0; 3]) {
                return Err(format!("key[{i}].up: [0, 0, 0] is no direction"));
            }
            if i > 0 && k.time <= p.key[i - 1].time {
                return Err(format!(
                    "key[{i}].time: {} is not after key[{}].time = {}",
                    k.time,
                    i - 1,
                    p.key[i - 1].time
                ));
            }
        }
        // A key is a look-at key when it gives eye, target or up, an orbit key when it gives an
        // angle or the distance, and of either kind when it gives only `fov_y` or `height`. A
        // path's keys are of one kind; a look-at path's first key gives the eye (later ones may
        // retarget alone).
        let look = |k: &Key| k.eye.is_some() || k.target.is_some() || k.up.is_some();
        let orbit = |k: &Key| k.azimuth.is_some() || k.elevation.is_some() || k.distance.is_some();
        if let Some(first) = p.key.iter().position(|k| look(k) || orbit(k)) {
            let first_look = look(&p.key[first]);
            if first_look && p.key[0].eye.is_none() {
                return Err("key[0]: a look-at path starts with an eye".into());
            }
            let other = |k: &Key| if first_look { orbit(k) } else { look(k) };
            if let Some(i) = p.key.iter().position(other) {
                return Err(format!(
                    "key[{i}]: all keys must be of one kind ({} like key[{first}])",
                    if first_look {
                        "eye, target or up"
                    } else {
                        "orbit angles, no eye, target or up"
                    }
                ));
            }
        }
        match (p.frames, p.fps) {
            (Some(_), Some(_)) => return Err("frames and fps: give one, not both".into()),
            (None, None) => return Err("frames or fps: give one".into()),
            (Some(n), None) if n == 0 || n > MAX_FRAMES => {
                return Err(format!("frames: {n} is not 1 to {MAX_FRAMES}"))
            }
            (None, Some(f)) if !(f.is_finite() && f > 0.0) => {
                return Err(format!("fps: {f} must be positive"))
            }
            _ => {}
        }
        if p.frame_times().len() as u64 > MAX_FRAMES as u64 {
            return Err(format!("fps: more than {MAX_FRAMES} frames"));
        }
        Ok(p)
    }

    /// The time of every frame.
    pub fn frame_times(&self) -> Vec<f64> {
        let (t0, t1) = (self.key[0].time, self.key[self.key.len() - 1].time);
        match (self.frames, self.fps) {
            (Some(1), _) => vec![t0],
            (Some(n), _) => (0..n)
                .map(|k| t0 + (t1 - t0) * k as f64 / (n - 1) as f64)
                .collect(),
            (None, Some(f)) => {
                let n = (((t1 - t0) * f).floor() as u64).min(MAX_FRAMES as u64) + 1;
                (0..n).map(|k| t0 + k as f64 / f).collect()
            }
            (None, None) => vec![t0],
        }
    }

    /// The scene's camera at time `t`.
    pub fn camera_at(&self, base: &CameraSpec, t: f64) -> CameraSpec {
        let how = self.interpolation;
        let series = |get: &dyn Fn(&Key) -> Option<f64>| -> Option<f64> {
            let pts: Vec<(f64, f64)> = self
                .key
                .iter()
                .filter_map(|k| get(k).map(|v| (k.time, v)))
                .collect();
            (!pts.is_empty()).then(|| interpolate(&pts, t, how))
        };
        let vec3 = |get: &dyn Fn(&Key) -> Option<[f64; 3]>| -> Option<[f64; 3]> {
            let c = |j: usize| series(&|k: &Key| get(k).map(|v| v[j]));
            Some([c(0)?, c(1)?, c(2)?])
        };
        let mut c = base.clone();
        // Catmull-Rom may overshoot its keys: the angle and the distance are held inside the
        // ranges a scene's camera allows.
        if let Some(f) = series(&|k| k.fov_y) {
            c.fov_y = f.clamp(1e-3, 179.999);
        }
        if let Some(h) = series(&|k| k.height) {
            // Held at the smallest keyed height or above: Catmull-Rom may dip below zero
            // between small heights keyed beside large ones.
            let low = self
                .key
                .iter()
                .filter_map(|k| k.height)
                .fold(f64::MAX, f64::min);
            c.height = Some(h.clamp(low, volume::MAX_COORDINATE));
        }
        if self.key[0].eye.is_some() {
            // Look-at: each of eye, target and up interpolated over the keys that give it.
            c.eye = vec3(&|k| k.eye);
            if let Some(tg) = vec3(&|k| k.target) {
                c.target = Some(tg);
            }
            if let Some(u) = vec3(&|k| k.up) {
                let l = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt();
                if l > 0.0 {
                    c.up = u.map(|x| x / l);
                }
            }
        } else {
            c.eye = None;
            c.azimuth = series(&|k| k.azimuth).unwrap_or(base.azimuth);
            c.elevation = series(&|k| k.elevation).unwrap_or(base.elevation);
            c.distance = series(&|k| k.distance)
                .unwrap_or(base.distance)
                .max(1.0 + 1e-9);
        }
        c
    }
}

/// The camera of turntable frame `k` of `n` for `base` (see the module doc); `centre` is the
/// scene's centre, the default target of a look-at camera.
pub fn orbit_camera(base: &CameraSpec, centre: [f64; 3], k: u32, n: u32) -> CameraSpec {
    let angle = 360.0 * k as f64 / n.max(1) as f64;
    let mut c = base.clone();
    match base.eye {
        None => c.azimuth = base.azimuth + angle,
        Some(eye) => {
            let target = glam::DVec3::from(base.target.unwrap_or(centre));
            let up = glam::DVec3::from(base.up).normalize_or(glam::DVec3::Z);
            let q = glam::DQuat::from_axis_angle(up, -angle.to_radians());
            let e = target + q * (glam::DVec3::from(eye) - target);
            c.eye = Some(e.to_array());
        }
    }
    c
}

/// The cameras of a sequence for `scene`: a turntable of `n` frames or a camera path.
pub enum Sequence {
    Orbit(u32),
    Path(CameraPath),
    /// The scene's camera, this many times (a trail animation).
    Still(u32),
}

impl Sequence {
    /// The `[camera]` of every frame.
    pub fn cameras(&self, scene: &Scene, centre: [f64; 3]) -> Vec<CameraSpec> {
        match self {
            Sequence::Orbit(n) => (0..*n)
                .map(|k| orbit_camera(&scene.camera, centre, k, *n))
                .collect(),
            Sequence::Path(p) => p
                .frame_times()
                .into_iter()
                .map(|t| p.camera_at(&scene.camera, t))
                .collect(),
            Sequence::Still(n) => vec![scene.camera.clone(); *n as usize],
        }
    }
}

/// The output path of frame `k`: the last run of `#` in the file name replaced by `k`,
/// zero-padded to the run's length (longer when `k` needs more digits).
pub fn frame_path(pattern: &Path, k: usize) -> Result<std::path::PathBuf, String> {
    let name = pattern
        .file_name()
        .and_then(|n| n.to_str())
        .ok_or_else(|| format!("{}: the output needs a file name", pattern.display()))?;
    let end = name.rfind('#').ok_or_else(|| {
        format!(
            "{}: a sequence's output name needs a run of # for the frame number (e.g. frame_####.png)",
            pattern.display()
        )
    })? + 1;
    let start = name[..end].trim_end_matches('#').len();
    let digits = end - start;
    let file = format!("{}{k:0digits$}{}", &name[..start], &name[end..]);
    Ok(pattern.with_file_name(file))
}

/// Whether `path` is a file [`frame_path`] can make from `pattern` for some frame (the same
/// folder, as the file system resolves it; the number zero-padded to the run or longer): a
/// second output with such a name would be overwritten by a frame, or overwrite it.
pub fn frame_path_matches(pattern: &Path, path: &Path) -> bool {
    let (Some(name), Some(file)) = (
        pattern.file_name().and_then(|n| n.to_str()),
        path.file_name().and_then(|n| n.to_str()),
    ) else {
        return false;
    };
    let Some(end) = name.rfind('#').map(|e| e + 1) else {
        return false;
    };
    let start = name[..end].trim_end_matches('#').len();
    let (prefix, suffix, digits) = (&name[..start], &name[end..], end - start);
    let number = file
        .strip_prefix(prefix)
        .and_then(|r| r.strip_suffix(suffix))
        .filter(|n| n.len() >= digits && n.bytes().all(|b| b.is_ascii_digit()));
    number.is_some() && same_folder(pattern, path)
}

/// Whether two paths' folders are one folder (resolved by the file system where they exist).
pub fn same_folder(a: &Path, b: &Path) -> bool {
    let dir = |p: &Path| {
        let d = volume::folder_of(p);
        d.canonicalize()
            .or_else(|_| std::path::absolute(d))
            .unwrap_or_else(|_| d.to_path_buf())
    };
    dir(a) == dir(b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_names_replace_the_last_run_of_hashes() {
        let p = Path::new("out/frame_####.png");
        assert_eq!(frame_path(p, 7).unwrap(), Path::new("out/frame_0007.png"));
        assert_eq!(
            frame_path(p, 12345).unwrap(),
            Path::new("out/frame_12345.png")
        );
        assert_eq!(
            frame_path(Path::new("a#b_##.exr"), 3).unwrap(),
            Path::new("a#b_03.exr")
        );
        assert!(frame_path(Path::new("out/frame.png"), 0)
            .unwrap_err()
            .contains("run of #"));
        // What the pattern can make, and what it cannot.
        let m = |a: &str| frame_path_matches(p, Path::new(a));
        assert!(m("out/frame_0007.png") && m("out/frame_12345.png") && m("./out/frame_0000.png"));
        assert!(!m("out/frame_007.png") && !m("out/frame_000x.png") && !m("frame_0007.png"));
        assert!(!m("out/frame_0007.exr") && !m("out/record.json"));
        let q = Path::new("a#b_##.exr");
        assert!(frame_path_matches(q, Path::new("a#b_03.exr")));
        assert!(!frame_path_matches(q, Path::new("a3b_03.exr")));
    }

    #[test]
    fn a_turntable_turns_the_azimuth_or_the_eye_by_equal_steps() {
        let base = CameraSpec::default();
        let c = orbit_camera(&base, [0.0; 3], 3, 8);
        assert!((c.azimuth - (base.azimuth + 135.0)).abs() < 1e-12);
        // A look-at camera on the -y axis looking at the origin, z up: a quarter turn brings
        // it to -x (as the azimuth's 0 -> 90 degrees does for an orbit camera).
        let look = CameraSpec {
            eye: Some([0.0, -5.0, 1.0]),
            target: Some([0.0, 0.0, 0.0]),
            ..CameraSpec::default()
        };
        let e = orbit_camera(&look, [9.0; 3], 1, 4).eye.unwrap();
        assert!((e[0] + 5.0).abs() < 1e-12 && e[1].abs() < 1e-12 && (e[2] - 1.0).abs() < 1e-12);
        let orbit = occlusion::camera::Camera::orbit(
            [glam::DVec3::splat(-1.0), glam::DVec3::splat(1.0)],
            90.0,
            0.0,
            3.0,
            Some(35.0),
        );
        assert!(orbit.eye.x < -1.0 && orbit.eye.y.abs() < 1e-9);
    }

    #[test]
    fn paths_interpolate_between_keys_and_hit_them() {
        let p = CameraPath::parse(
            "frames = 5\n[[key]]\ntime = 0\nazimuth = 0\n[[key]]\ntime = 1\nazimuth = 90\nelevation = 10\n[[key]]\ntime = 2\nazimuth = 360\n",
        )
        .unwrap();
        assert_eq!(p.frame_times(), vec![0.0, 0.5, 1.0, 1.5, 2.0]);
        let base = CameraSpec::default();
        let az: Vec<f64> = p
            .frame_times()
            .iter()
            .map(|&t| p.camera_at(&base, t).azimuth)
            .collect();
        assert_eq!(az, vec![0.0, 45.0, 90.0, 225.0, 360.0]);
        // A value keyed once holds everywhere.
        assert_eq!(p.camera_at(&base, 0.2).elevation, 10.0);
        // Catmull-Rom passes through the keys and is smooth between.
        let c = CameraPath {
            interpolation: Interpolation::CatmullRom,
            ..p.clone()
        };
        for (t, want) in [(0.0, 0.0), (1.0, 90.0), (2.0, 360.0)] {
            assert!((c.camera_at(&base, t).azimuth - want).abs() < 1e-9);
        }
        let mid = c.camera_at(&base, 1.5).azimuth;
        assert!(mid > 90.0 && mid < 360.0, "{mid}");
        // A look-at key may retarget alone: the eye holds, the target moves.
        let r = CameraPath::parse(
            "frames = 3\n[[key]]\ntime = 0\neye = [0, -10, 0]\ntarget = [0, 0, 0]\n[[key]]\ntime = 2\ntarget = [2, 0, 0]\n",
        )
        .unwrap();
        let mid = r.camera_at(&base, 1.0);
        assert_eq!(mid.eye, Some([0.0, -10.0, 0.0]));
        assert_eq!(mid.target, Some([1.0, 0.0, 0.0]));
        // fps: floor(2 * 2) + 1 = 5 frames, 0.5 s apart.
        let f = CameraPath::parse("fps = 2\n[[key]]\ntime = 0\n[[key]]\ntime = 2\n").unwrap();
        assert_eq!(f.frame_times(), vec![0.0, 0.5, 1.0, 1.5, 2.0]);
    }

    #[test]
    fn bad_paths_are_refused_naming_the_key() {
        let bad = |t: &str, want: &str| {
            let e = CameraPath::parse(t).unwrap_err();
            assert!(e.contains(want), "{t}: {e}");
        };
        bad("frames = 2\n", "key");
        bad(
            "frames = 2\n[[key]]\ntime = 1\n[[key]]\ntime = 1\n",
            "key[1].time",
        );
        bad(
            "frames = 2\n[[key]]\ntime = 0\neye = [1, 2, 3]\nazimuth = 3\n",
            "key[0]",
        );
        bad(
            "frames = 2\n[[key]]\ntime = 0\neye = [1, 2, 3]\n[[key]]\ntime = 1\nazimuth = 3\n",
            "key[1]",
        );
        bad(
            "frames = 2\n[[key]]\ntime = 0\ntarget = [1, 2, 3]\n",
            "key[0]: a look-at path starts with an eye",
        );
        bad("[[key]]\ntime = 0\n", "frames or fps");
        bad("frames = 0\n[[key]]\ntime = 0\n", "frames");
        bad("frames = 2\n[[key]]\ntime = 0\nzoom = 2\n", "zoom");
        bad("fps = 1e9\n[[key]]\ntime = 0\n[[key]]\ntime = 1\n", "fps");
        bad("frames = 2\n[[key]]\ntime = nan\n", "finite");
        // The ranges of the scene's [camera].
        let k = |v: &str| format!("frames = 2\n[[key]]\ntime = 0\n{v}\n");
        bad(&k("distance = -1.0"), "key[0].distance");
        bad(&k("distance = 0.5"), "key[0].distance");
        bad(&k("fov_y = 0.0"), "key[0].fov_y");
        bad(&k("fov_y = 200.0"), "key[0].fov_y");
        bad(&k("height = 0.0"), "key[0].height");
        bad(&k("height = 1e16"), "key[0].height");
        bad(&k("eye = [1, 2, 3]\nup = [0, 0, 0]"), "key[0].up");
        bad(&k("eye = [1e16, 2, 3]"), "key[0].eye");
        bad(
            "frames = 2\n[[key]]\ntime = 0\nfov_y = 20\n[[key]]\ntime = 1\neye = [1, 2, 3]\n",
            "key[0]: a look-at path starts with an eye",
        );
    }

    #[test]
    fn orthographic_heights_are_keyed_like_fov_y_and_held_positive() {
        let base = CameraSpec::default();
        for first in ["eye = [0, -10, 0]", "azimuth = 10"] {
            let p = CameraPath::parse(&format!(
                "frames = 3\n[[key]]\ntime = 0\n{first}\nheight = 40\n[[key]]\ntime = 1\nheight = 20\n"
            ))
            .unwrap();
            let h: Vec<Option<f64>> = p
                .frame_times()
                .iter()
                .map(|&t| p.camera_at(&base, t).height)
                .collect();
            assert_eq!(h, [Some(40.0), Some(30.0), Some(20.0)], "{first}");
        }
        // No key gives a height: the scene's stays.
        let p = CameraPath::parse(
            "frames = 2\n[[key]]\ntime = 0\nazimuth = 1\n[[key]]\ntime = 1\nazimuth = 2\n",
        )
        .unwrap();
        let base = CameraSpec {
            height: Some(7.0),
            ..CameraSpec::default()
        };
        assert_eq!(p.camera_at(&base, 0.5).height, Some(7.0));
        // Catmull-Rom from a tall view down to a thin one and back overshoots below zero
        // between the thin keys (-12.5 halfway): held at the smallest key.
        let p = CameraPath::parse(
            "frames = 61\ninterpolation = \"catmull-rom\"\n[[key]]\ntime = 0\nheight = 100\n\
             [[key]]\ntime = 1\nheight = 0.01\n[[key]]\ntime = 2\nheight = 0.01\n\
             [[key]]\ntime = 3\nheight = 100\n",
        )
        .unwrap();
        let low = p
            .frame_times()
            .iter()
            .map(|&t| p.camera_at(&CameraSpec::default(), t).height.unwrap())
            .fold(f64::MAX, f64::min);
        assert_eq!(low, 0.01);
    }

    #[test]
    fn a_key_with_only_fov_y_joins_a_path_of_either_kind() {
        let base = CameraSpec::default();
        for first in ["eye = [0, -10, 0]", "azimuth = 10"] {
            let p = CameraPath::parse(&format!(
                "frames = 3\n[[key]]\ntime = 0\n{first}\nfov_y = 40\n[[key]]\ntime = 1\nfov_y = 20\n"
            ))
            .unwrap();
            let f: Vec<f64> = p
                .frame_times()
                .iter()
                .map(|&t| p.camera_at(&base, t).fov_y)
                .collect();
            assert_eq!(f, [40.0, 30.0, 20.0], "{first}");
        }
        // Catmull-Rom overshoot is held inside the camera's ranges.
        let p = CameraPath::parse(
            "frames = 41\ninterpolation = \"catmull-rom\"\n[[key]]\ntime = 0\ndistance = 9\n\
             [[key]]\ntime = 1\ndistance = 1.01\n[[key]]\ntime = 2\ndistance = 1.01\n",
        )
        .unwrap();
        assert!(p
            .frame_times()
            .iter()
            .all(|&t| p.camera_at(&base, t).distance > 1.0));
    }
}
