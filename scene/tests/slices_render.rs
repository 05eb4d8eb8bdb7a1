//! Slices, overlays, label atlases and projections (issue 19) drawn on this machine's adapter
//! (lavapipe in CI) against their CPU twins: a slice's pixels are the layers sampled at the
//! pixel's world point (`engine::planes::plane_color`), label slices show only the file's
//! labels, a slab crops exactly the points outside it, and MIP/MinIP equal the CPU extreme
//! along each ray (`occlusion::projection`).

use engine::renderer::DrawOptions;
use glam::{DMat4, DVec3};
use scene::compile::{model, upload};
use std::path::Path;
use volume::{Field, Volume};

/// A volume with one scalar field `f(world)` on `dims` with index-to-world `affine`.
fn volume_of(dims: [usize; 3], affine: DMat4, f: impl Fn(DVec3) -> f32) -> Volume {
    let mut data = vec![];
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let p = affine.transform_point3(DVec3::new(i as f64, j as f64, k as f64));
                data.push(f(p));
            }
        }
    }
    let field = Field {
        name: "v".into(),
        components: 1,
        stored: volume::ScalarType::F32,
        data,
    };
    Volume::new(dims, affine, volume::Space::Ras, field).unwrap()
}

fn write(dir: &Path, name: &str, v: &Volume) -> String {
    let p = dir.join(name);
    let f: &Field = &v.fields[0];
    volume::nifti::write(&p, v, f).unwrap();
    p.display().to_string()
}

/// The scene's frame: linear RGBA, and the model it was drawn from.
fn draw(text: &str, dir: &Path) -> (Vec<[f32; 4]>, scene::compile::Model, scene::Scene) {
    let s = scene::spec::parse(text, "test.toml", dir, &[]).unwrap();
    let gpu = engine::gpu::Gpu::new().expect("a GPU adapter (lavapipe in CI)");
    let m = model(&s).unwrap();
    let up = upload(&gpu, &m).unwrap();
    let (out, _) = up
        .draw_at(
            &s,
            &m,
            DrawOptions {
                frames: 1,
                pass_timings: false,
            },
            None,
        )
        .unwrap();
    (out.image, m, s)
}

/// The anatomy: 20 x 18 x 16 voxels of 2 x 2.5 x 3 mm, a smooth field.
fn anatomy() -> Volume {
    let a = DMat4::from_cols_array(&[
        2.0, 0.0, 0.0, 0.0, 0.0, 2.5, 0.0, 0.0, 0.0, 0.0, 3.0, 0.0, -19.0, -21.0, -22.0, 1.0,
    ]);
    volume_of([20, 18, 16], a, |p| {
        (100.0 + 40.0 * (0.15 * p.x).sin() + 30.0 * (0.1 * p.y).cos() + p.z) as f32
    })
}

#[test]
fn slices_sample_their_layers_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let anat = write(dir.path(), "anat.nii.gz", &anatomy());
    // A statistical map on a coarser, rotated grid, and a label atlas on a finer one.
    let rot = DMat4::from_rotation_z(0.3)
        * DMat4::from_cols_array(&[
            3.0, 0.0, 0.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0, 3.5, 0.0, -20.0, -24.0, -25.0, 1.0,
        ]);
    let stat = write(
        dir.path(),
        "stat.nii.gz",
        &volume_of([16, 16, 16], rot, |p| (0.2 * p.x + 0.1 * p.y) as f32),
    );
    let lab = DMat4::from_cols_array(&[
        1.5, 0.0, 0.0, 0.0, 0.0, 1.5, 0.0, 0.0, 0.0, 0.0, 1.5, 0.0, -20.0, -22.0, -23.0, 1.0,
    ]);
    let labels = write(
        dir.path(),
        "labels.nii.gz",
        &volume_of([28, 30, 32], lab, |p| {
            if p.x < -8.0 {
                0.0
            } else if p.y < 0.0 {
                3.0
            } else if p.x < 6.0 {
                7.0
            } else {
                12.0
            }
        }),
    );
    // Slices show their colours unshaded under the default head light (a head-on one would
    // otherwise take its specular highlight everywhere); `lit = true` lights them: head-on, n.l
    // = 1 and the highlight is whole, colour (ambient + diffuse) + specular = colour + 0.3.
    // FXAA (on by default) leaves a slice's pixels as they are: the anatomy's edges are the
    // data's, not aliasing.
    for (camera, slice, lift, fxaa) in [
        (
            "azimuth = 0.0\nelevation = 90.0",
            "axis = \"axial\"\nposition = 1.7",
            0.0,
            false,
        ),
        (
            "azimuth = 30.0\nelevation = 40.0",
            "normal = [0.3, -0.4, 0.85]\nposition = 2.0",
            0.0,
            false,
        ),
        (
            "azimuth = 0.0\nelevation = 90.0",
            "axis = \"axial\"\nposition = 1.7\nlit = true",
            0.3,
            false,
        ),
        (
            "azimuth = 30.0\nelevation = 40.0",
            "normal = [0.3, -0.4, 0.85]\nposition = 2.0",
            0.0,
            true,
        ),
    ] {
        let text = format!(
            r#"
background = [0.0, 0.0, 0.0]
[camera]
projection = "orthographic"
{camera}
[volume]
path = "{anat}"
render = false
[[slices]]
{slice}
window = [70.0, 170.0]
[[overlays]]
name = "stat"
path = "{stat}"
colormap = "hot"
range = [-1.0, 4.0]
opacity = 0.6
[[overlays]]
name = "atlas"
path = "{labels}"
labels = true
show = [3, 12]
opacity = 0.5
[annotate]
colorbar = "overlays.stat"
[render]
method = "ea"
width = 96
height = 80
msaa = 1
fxaa = {fxaa}
"#
        );
        let (img, m, s) = draw(&text, dir.path());
        // The overlay's colour bar: its map over its range.
        let bar = m.colorbar.as_ref().unwrap();
        assert_eq!((bar.map.as_str(), bar.range), ("hot", [-1.0, 4.0]));
        let hot = volume::colormap::Colormap::Hot.rgb(1.0 / 128.0);
        assert!((0..3).all(|k| (bar.colors[0][k] as f64 - hot[k]).abs() < 1e-6));
        let planes = m.planes.as_ref().unwrap();
        let grid = planes.grid();
        let layers = &planes.planes[0].layers;
        assert_eq!(layers.len(), 3);
        let cam = scene::compile::camera(&s, m.bounds).unwrap();
        let n = scene::slices::normal(&s.slices[0]);
        let pos = s.slices[0].position.unwrap();
        let (mut covered, mut worst, mut off) = (0, 0.0f64, 0);
        let (w, h) = (96usize, 80usize);
        for y in 0..h {
            for x in 0..w {
                let (o, d) = cam.ray(x as f64, y as f64, w, h);
                let t = (pos - n.dot(o)) / n.dot(d);
                let p = o + d * t;
                let px = img[x + w * y];
                if px[3] < 0.999 {
                    continue;
                }
                // Pixels whose centre is within a voxel of the polygon's rim may be covered
                // by rasterisation rules differently: compare inside only.
                let q = grid.affine.inverse().transform_point3(p);
                let hi = grid.dims.map(|d| d as f64 - 1.0);
                if (0..3).any(|k| q[k] < 0.05 || q[k] > hi[k] - 0.05) {
                    continue;
                }
                covered += 1;
                let want = engine::planes::plane_color(&grid, layers, p);
                let err = (0..3)
                    .map(|k| (px[k] as f64 - want[k] - lift).abs())
                    .fold(0.0, f64::max);
                // f32 against f64 and the G-buffer's 16-bit colour: well within 1.5/255.
                if err > 1.5 / 255.0 {
                    off += 1;
                }
                worst = worst.max(err);
            }
        }
        assert!(covered > 1000, "{covered} pixels of the slice");
        // Labels are the nearest voxel's: a pixel centre on a voxel boundary may round the
        // other way on the GPU (f32) - at most 2% of the pixels.
        assert!(
            off * 50 <= covered,
            "{off} of {covered} pixels differ from the CPU twin (worst {worst})"
        );
    }
}

#[test]
fn label_slices_show_only_labels_of_the_file_and_slabs_crop_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let anat = write(dir.path(), "anat.nii.gz", &anatomy());
    let lab = DMat4::from_scale(DVec3::splat(2.0)) * DMat4::from_translation(DVec3::splat(-10.0));
    let present = [0.0f32, 2.0, 5.0, 9.0];
    let labels = write(
        dir.path(),
        "labels.nii.gz",
        &volume_of([12, 12, 12], lab, |p| {
            present[((p.x + p.y + 100.0) / 7.0) as usize % 4]
        }),
    );
    // A tractogram of lines along z through the slab.
    let mut sl = tubes::Streamlines::new();
    for k in 0..10 {
        let pts: Vec<glam::Vec3> = (0..40)
            .map(|i| glam::Vec3::new(k as f32 - 5.0, 0.5 * k as f32, i as f32 - 20.0))
            .collect();
        sl.push(&pts);
    }
    let trk = dir.path().join("lines.tck");
    tubes::save(&trk, &sl).unwrap();
    let text = format!(
        r#"
[volume]
path = "{anat}"
render = false
[[overlays]]
name = "atlas"
path = "{labels}"
labels = true
[[slices]]
axis = "axial"
position = 1.0
volume = "atlas"
slab = 6.0
[[lines]]
path = "{}"
[render]
method = "ea"
width = 64
height = 64
"#,
        trk.display()
    );
    let (_, m, _) = draw(&text, dir.path());
    let planes = m.planes.as_ref().unwrap();
    // Nearest-neighbour resampling keeps the file's labels and nothing else.
    let atlas = &planes.fields[1];
    for v in atlas.iter().filter(|v| v.is_finite()) {
        assert!(present.contains(v), "label {v} is not in the file");
    }
    assert!(atlas.contains(&9.0));
    // The label table: 0 hidden by default, the file's labels shown, nothing else.
    match &planes.planes[0].layers[0].map {
        engine::planes::LayerMap::Labels { colors } => {
            for (l, c) in colors.iter().enumerate() {
                let shown = c[3] > 0.0;
                assert_eq!(shown, l != 0 && present.contains(&(l as f32)), "label {l}");
            }
        }
        other => panic!("not a label layer: {other:?}"),
    }
    // The slab [-2, 4] in z: every point of the line set within it, nothing outside.
    let set = &m.lines[0];
    let z: Vec<f64> = set
        .positions
        .iter()
        .map(|p| p.z as f64 + set.origin.z)
        .collect();
    assert!(!z.is_empty());
    assert!(z.iter().all(|z| (z - 1.0).abs() <= 3.0 + 1e-5), "{z:?}");
    let want = 10 * (-20..20).filter(|i| (*i as f64 - 1.0).abs() <= 3.0).count();
    assert_eq!(z.len(), want);
    // And a note says what the slab kept (a slab away from the lines removed them silently).
    let note = format!("lines[0]: the slices' slabs keep {want} of 400 points");
    assert!(m.notes.contains(&note), "{:?}", m.notes);
}

/// An overlay whose grid is in its file's own frame over a RAS+ volume (a head MR in its
/// scanner's frame over an MNI T1) is placed by the affines, with a note that nothing says the
/// frames are one; in the volume's frame, or with a transform given, no note.
#[test]
fn an_overlay_in_another_frame_is_noted() {
    let dir = tempfile::tempdir().unwrap();
    let anat = write(dir.path(), "anat.nii.gz", &anatomy());
    let grid = DMat4::from_scale(DVec3::splat(2.0)) * DMat4::from_translation(DVec3::splat(-10.0));
    let mut own = volume_of([12, 12, 12], grid, |q| q.x as f32);
    own.space = volume::Space::File;
    let own_path = dir.path().join("own.nrrd");
    volume::nrrd::write(
        &own_path,
        &own,
        &own.fields[0],
        volume::nrrd::WriteEncoding::Raw,
    )
    .unwrap();
    let ras = write(
        dir.path(),
        "ras.nii.gz",
        &volume_of([12, 12, 12], grid, |q| q.x as f32),
    );
    let notes = |path: &str, extra: &str| {
        let text = format!(
            "[volume]\npath = \"{anat}\"\nrender = false\n[[overlays]]\nname = \"o\"\npath = \"{path}\"\n{extra}[[slices]]\naxis = \"axial\"\n[render]\nmethod = \"ea\"\nwidth = 32\nheight = 32\n"
        );
        let s = scene::spec::parse(&text, "t.toml", dir.path(), &[]).unwrap();
        model(&s).unwrap().notes
    };
    let n = notes(&own_path.display().to_string(), "");
    assert!(
        n.iter().any(|n| n.contains("overlays[0]")
            && n.contains("its file's own frame")
            && n.contains("RAS+ mm")),
        "{n:?}"
    );
    let frame = |n: &Vec<String>| n.iter().any(|n| n.contains("own frame"));
    assert!(!frame(&notes(&ras, "")));
    let id = "transform = [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]\n";
    assert!(!frame(&notes(&own_path.display().to_string(), id)));
}

/// Infinite labels are out of range like 70000 (they were accepted and drew nothing), and an
/// overlay whose every value is NaN says so, not that it lies outside the grid.
#[test]
fn infinite_labels_are_refused_and_an_empty_overlay_says_why() {
    let dir = tempfile::tempdir().unwrap();
    let anat = write(dir.path(), "anat.nii.gz", &anatomy());
    let grid = DMat4::from_scale(DVec3::splat(2.0)) * DMat4::from_translation(DVec3::splat(-10.0));
    let scene = |labels: &str, flag: &str| {
        format!(
            "[volume]\npath = \"{anat}\"\nrender = false\n[[overlays]]\nname = \"o\"\npath = \"{labels}\"\n{flag}[[slices]]\naxis = \"axial\"\n[render]\nmethod = \"ea\"\nwidth = 32\nheight = 32\n"
        )
    };
    for (name, bad) in [
        ("pinf.nii.gz", f32::INFINITY),
        ("ninf.nii.gz", f32::NEG_INFINITY),
    ] {
        let p = write(
            dir.path(),
            name,
            &volume_of([12, 12, 12], grid, |q| if q.x > 0.0 { bad } else { 2.0 }),
        );
        let s =
            scene::spec::parse(&scene(&p, "labels = true\n"), "t.toml", dir.path(), &[]).unwrap();
        let e = model(&s).err().expect("an infinite label is refused");
        assert!(e.contains("overlays[0].labels") && e.contains("inf"), "{e}");
        // The file's voxel is named (x > 0: index 11 and up along x).
        assert!(e.contains("at voxel (11, 0, 0) is outside 0..65535"), "{e}");
    }
    let nan = write(
        dir.path(),
        "nan.nii.gz",
        &volume_of([12, 12, 12], grid, |_| f32::NAN),
    );
    let s = scene::spec::parse(
        &scene(&nan, "range = [0.0, 1.0]\n"),
        "t.toml",
        dir.path(),
        &[],
    )
    .unwrap();
    let m = model(&s).unwrap();
    assert!(
        m.notes
            .iter()
            .any(|n| n.contains("every value of it is NaN")),
        "{:?}",
        m.notes
    );
    assert!(
        !m.notes.iter().any(|n| n.contains("falls inside")),
        "{:?}",
        m.notes
    );
}

#[test]
fn projections_equal_the_cpu_extreme_along_each_ray() {
    let dir = tempfile::tempdir().unwrap();
    let v = anatomy();
    let anat = write(dir.path(), "anat.nii.gz", &v);
    // Both devices: the GPU's march and the native CPU renderer (`auto` picks it on lavapipe).
    for (method, which, device) in [
        ("mip", occlusion::projection::Extremum::Max, "gpu"),
        ("minip", occlusion::projection::Extremum::Min, "gpu"),
        ("mip", occlusion::projection::Extremum::Max, "cpu"),
        ("minip", occlusion::projection::Extremum::Min, "cpu"),
    ] {
        let text = format!(
            r#"
background = [0.2, 0.3, 0.4]
[camera]
azimuth = 35.0
elevation = 20.0
[volume]
path = "{anat}"
window = [140.0, 200.0]
colormap = "viridis"
opacity = 0.8
[[clip]]
normal = [1.0, 0.0, 0.0]
offset = 6.0
[render]
method = "{method}"
device = "{device}"
width = 64
height = 56
fxaa = false
"#
        );
        let (img, m, s) = draw(&text, dir.path());
        let (vol, data, tf) = m.volume.as_ref().unwrap();
        let data = data.to_f32();
        let data: &[f32] = &data;
        // Some bricks are empty (every value below the window): the GPU skips them (MIP) or
        // ends the ray there (MinIP), the CPU twin samples everything. On a continuous field
        // ending and skipping give the same image, so this checks that the empty-brick rules
        // change nothing, not which of the two ran.
        let (_, occ) = occlusion::emission_absorption::occupancy(data, vol.dims, tf);
        let empty = occ.iter().filter(|o| **o == 0).count();
        assert!(
            empty > 0 && empty < occ.len(),
            "{empty} of {} bricks empty",
            occ.len()
        );
        let view = scene::compile::view(&s, &m).unwrap();
        let w2i = vol.affine.inverse();
        let (mut worst, mut hits) = (0.0f64, 0);
        for y in 0..56usize {
            for x in 0..64usize {
                let (o, d) = view.camera.ray(x as f64, y as f64, 64, 56);
                let e = occlusion::projection::extreme(data, vol.dims, &w2i, &view, o, d, which);
                hits += e.is_some() as usize;
                let c = occlusion::projection::shade(tf, e);
                let bg = [0.2, 0.3, 0.4];
                let px = img[x + 64 * y];
                for k in 0..3 {
                    let want = c[k] + (1.0 - c[3]) * bg[k];
                    worst = worst.max((px[k] as f64 - want).abs());
                }
            }
        }
        assert!(hits > 800, "{method}: {hits} rays meet the volume");
        // f32 samples against f64: the extreme moves by a few 1e-5 of the window.
        assert!(
            worst < 2e-3,
            "{method} on the {device}: differs from the twin by {worst}"
        );
    }
}

#[test]
fn translucent_slices_over_the_volume_match_the_cpu_twin() {
    let dir = tempfile::tempdir().unwrap();
    let anat = write(dir.path(), "anat.nii.gz", &anatomy());
    // Two translucent slices crossing inside the drawn volume (unshaded under the default
    // light, as slices are unless lit): each pixel's ray meets the volume, the nearer slice, more volume, the farther slice, in depth order. With the
    // transfer function's first point at 150 much of the volume is empty bricks, which the
    // march steps over, layers or not.
    for (lo, ext) in [(60.0, 0.05), (150.0, 0.5)] {
        translucent_slices_case(dir.path(), &anat, lo, ext);
    }
}

fn translucent_slices_case(dir: &Path, anat: &str, lo: f64, ext: f64) {
    let text = format!(
        r#"
background = [0.0, 0.0, 0.0]
[camera]
projection = "orthographic"
azimuth = 25.0
elevation = 60.0
[volume]
path = "{anat}"
[volume.transfer]
points = [
  {{ value = {lo}, color = [0.2, 0.4, 1.0], extinction = 0.0 }},
  {{ value = 200.0, color = [1.0, 0.8, 0.3], extinction = {ext} }},
]
[[slices]]
axis = "axial"
position = 2.0
window = [60.0, 200.0]
colormap = "viridis"
opacity = 0.5
[[slices]]
normal = [0.35, -0.25, 0.9]
position = -3.0
window = [60.0, 200.0]
opacity = 0.35
[render]
method = "ea"
width = 128
height = 96
msaa = 1
fxaa = false
slice_distance = 0.5
"#
    );
    let (img, m, s) = draw(&text, dir);
    let (vol, data, tf) = m.volume.as_ref().unwrap();
    let data = data.to_f32();
    let data: &[f32] = &data;
    let (_, occ) = occlusion::emission_absorption::occupancy(data, vol.dims, tf);
    let empty = occ.iter().filter(|o| **o == 0).count();
    // The second case's bricks are partly empty: the march steps over them, layers or not.
    assert!(
        (lo < 100.0 || empty > 0) && empty < occ.len(),
        "lo {lo}: {empty} of {} bricks empty",
        occ.len()
    );
    let view = scene::compile::view(&s, &m).unwrap();
    let planes = m.planes.as_ref().unwrap();
    let grid = planes.grid();
    let hi = grid.dims.map(|d| d as f64 - 1.0);
    let i2w = grid.affine.inverse();
    let f = view.camera.forward();
    let (w, h) = (128usize, 96usize);
    // Per pixel: the slices' fragments (depth, colour, opacity), and whether the pixel is
    // near a rim or the slices' crossing (rasterisation and sort ties: left out).
    let frags = |x: usize, y: usize| {
        let (o, d) = view.camera.ray(x as f64, y as f64, w, h);
        let mut out = vec![];
        let mut edge = false;
        for (k, sl) in s.slices.iter().enumerate() {
            let n = scene::slices::normal(sl);
            let p = o + d * ((sl.position.unwrap() - n.dot(o)) / n.dot(d));
            let q = i2w.transform_point3(p);
            if (0..3).any(|a| q[a] < -0.05 || q[a] > hi[a] + 0.05) {
                continue;
            }
            edge |= (0..3).any(|a| q[a] < 0.1 || q[a] > hi[a] - 0.1);
            let c = engine::planes::plane_color(&grid, &planes.planes[k].layers, p);
            out.push(((p - view.camera.eye).dot(f), c, sl.opacity));
        }
        out.sort_by(|a, b| a.0.total_cmp(&b.0));
        if out.len() == 2 && (out[1].0 - out[0].0) < 0.5 {
            edge = true;
        }
        (out, edge)
    };
    let twin =
        occlusion::emission_absorption::reference_with_layers(data, vol, tf, &view, |x, y| {
            frags(x, y).0
        });
    let (mut compared, mut two, mut off, mut worst) = (0, 0, 0, 0.0f64);
    for y in 0..h {
        for x in 0..w {
            let (fr, edge) = frags(x, y);
            if edge || fr.is_empty() {
                continue;
            }
            compared += 1;
            two += (fr.len() == 2) as usize;
            let (g, c) = (img[x + w * y], twin[x + w * y]);
            let err = (0..3)
                .map(|k| (g[k] as f64 - c[k]).abs())
                .fold(0.0, f64::max);
            // Colours go through 16-bit floats in the layers and 8 bits in the slice's map.
            if err > 4e-3 {
                off += 1;
            }
            worst = worst.max(err);
        }
    }
    assert!(
        compared > 1500 && two > 300,
        "lo {lo}: {compared} pixels, {two} with both slices"
    );
    assert!(
        off * 100 <= compared,
        "lo {lo}: {off} of {compared} pixels differ from the twin (worst {worst})"
    );
}

#[test]
fn an_overlay_blended_into_the_volume_matches_the_cpu_twin() {
    let dir = tempfile::tempdir().unwrap();
    let anat = write(dir.path(), "anat.nii.gz", &anatomy());
    let rot = DMat4::from_rotation_z(0.2)
        * DMat4::from_cols_array(&[
            2.5, 0.0, 0.0, 0.0, 0.0, 2.5, 0.0, 0.0, 0.0, 0.0, 2.5, 0.0, -22.0, -24.0, -25.0, 1.0,
        ]);
    let stat = write(
        dir.path(),
        "stat.nii.gz",
        &volume_of([18, 20, 20], rot, |p| (0.3 * p.x - 0.2 * p.z) as f32),
    );
    let text = format!(
        r#"
background = [0.0, 0.0, 0.0]
[camera]
azimuth = 40.0
elevation = 25.0
[volume]
path = "{anat}"
[volume.transfer]
points = [
  {{ value = 60.0, color = [0.5, 0.5, 0.5], extinction = 0.0 }},
  {{ value = 200.0, color = [0.9, 0.9, 0.9], extinction = 0.08 }},
]
[[overlays]]
name = "stat"
path = "{stat}"
colormap = "red-yellow"
range = [1.0, 6.0]
opacity = 0.8
volume_blend = true
[render]
method = "ea"
width = 96
height = 80
fxaa = false
slice_distance = 0.5
"#
    );
    let (img, m, s) = draw(&text, dir.path());
    let (vol, data, tf) = m.volume.as_ref().unwrap();
    let data = data.to_f32();
    let data: &[f32] = &data;
    let view = scene::compile::view(&s, &m).unwrap();
    let planes = m.planes.as_ref().unwrap();
    let grid = planes.grid();
    let layer = planes.blend.as_ref().unwrap();
    let twin = occlusion::emission_absorption::reference_blended(
        data,
        vol,
        tf,
        &view,
        |_, _| vec![],
        |p| {
            let (c, a) = engine::planes::layer_color(&grid, layer, p, false);
            (c, a * layer.opacity as f64)
        },
    );
    let plain = occlusion::emission_absorption::reference(data, vol, tf, &view);
    let (mut worst, mut tinted) = (0.0f64, 0);
    for (g, (c, p)) in img.iter().zip(twin.iter().zip(&plain)) {
        for k in 0..3 {
            worst = worst.max((g[k] as f64 - c[k]).abs());
        }
        // Where the blend changed the colour visibly (red-yellow over grey).
        tinted += ((c[0] - c[2]) - (p[0] - p[2]) > 0.05) as usize;
    }
    assert!(tinted > 300, "{tinted} pixels tinted by the overlay");
    assert!(worst < 3e-3, "GPU and CPU twin differ by {worst}");
}

#[test]
fn bad_slice_and_colour_map_keys_name_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let err = |text: &str| scene::spec::parse(text, "t.toml", dir.path(), &[]).unwrap_err();
    let e = err("[[lines]]\npath = \"x.tck\"\ncolor = \"scalar:fa\"\ncolormap = \"jet\"\n");
    assert!(
        e.contains("lines[0].colormap") && e.contains("viridis"),
        "{e}"
    );
    let e =
        err("[volume]\npath = \"v.nii\"\n[[slices]]\naxis = \"axial\"\nnormal = [0.0, 0.0, 1.0]\n");
    assert!(e.contains("slices[0].axis"), "{e}");
    let e = err("[volume]\npath = \"v.nii\"\n[[slices]]\naxis = \"axial\"\nvolume = \"fa\"\n");
    assert!(e.contains("slices[0].volume") && e.contains("'fa'"), "{e}");
    let e = err("[volume]\npath = \"v.nii\"\n[[overlays]]\nname = \"a\"\npath = \"a.nii\"\nrange = [1.0, 1.0]\n");
    assert!(e.contains("overlays[0].range"), "{e}");
    let e = err("[[slices]]\naxis = \"axial\"\n");
    assert!(e.contains("need a [volume]"), "{e}");
    let e = err("[volume]\npath = \"v.nii\"\n[render]\ntranslucent_layers = 9\n");
    assert!(e.contains("render.translucent_layers"), "{e}");
    // A window too narrow for single precision.
    let e = err("[volume]\npath = \"v.nii\"\nwindow = [1.0, 1.00000001]\n");
    assert!(e.contains("volume.window"), "{e}");
    // Too wide: its width overflows single precision (the message says so).
    let e = err("[volume]\npath = \"v.nii\"\nwindow = [-2e38, 2e38]\n");
    assert!(
        e.contains("volume.window") && e.contains("at most 3.4e38 apart"),
        "{e}"
    );
    // Blending needs a volume drawn by its transfer function.
    let blend = "[volume]\npath = \"v.nii\"\n[[overlays]]\nname = \"a\"\npath = \"a.nii\"\nvolume_blend = true\n";
    let e = err(&format!("{blend}[render]\nmethod = \"mip\"\n"));
    assert!(e.contains("overlays[0].volume_blend"), "{e}");
    // Translucent tubes with an isosurface, a label slice with a window.
    let e = err("[volume]\npath = \"v.nii\"\n[volume.iso]\nvalue = 1.0\n[[tubes]]\npath = \"t.tck\"\nopacity = 0.5\n");
    assert!(e.contains("tubes[0].opacity"), "{e}");
    let e = err("[volume]\npath = \"v.nii\"\n[[overlays]]\nname = \"a\"\npath = \"a.nii\"\nlabels = true\n[[slices]]\naxis = \"axial\"\nvolume = \"a\"\nwindow = [0.0, 5.0]\n");
    assert!(e.contains("slices[0].window"), "{e}");
}

#[test]
fn the_bundled_slices_scene_shows_anatomy_overlay_and_cropped_tracts() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let path = root.join("datasets/scenes/slices.toml");
    let s = scene::spec::load(
        &path,
        &["render.width=160".into(), "render.height=120".into()],
    )
    .unwrap();
    let gpu = engine::gpu::Gpu::new().expect("a GPU adapter (lavapipe in CI)");
    let m = model(&s).unwrap();
    // Two slices; the axial one carries the white-matter overlay, the sagittal one does not.
    let planes = m.planes.as_ref().unwrap();
    assert_eq!(planes.planes.len(), 2);
    assert_eq!(planes.planes[0].layers.len(), 2);
    assert_eq!(planes.planes[1].layers.len(), 1);
    // The tracts are cropped to the slab z in [-15, 35] (after their transform).
    for mesh in &m.meshes {
        let z: Vec<f64> = mesh
            .positions
            .iter()
            .map(|p| p.z as f64 + mesh.origin.z)
            .collect();
        assert!(!z.is_empty());
        // Tube radius 0.4: surfaces reach a little past the points.
        assert!(
            z.iter().all(|z| (-15.5..=35.5).contains(z)),
            "{:?}",
            z.iter()
                .fold((f64::MAX, f64::MIN), |a, &z| (a.0.min(z), a.1.max(z)))
        );
    }
    let up = upload(&gpu, &m).unwrap();
    let (out, _) = up.draw(&s, &m, DrawOptions::default()).unwrap();
    // Red-yellow overlay pixels (tinted: red well above blue) and grey anatomy pixels.
    let warm = out.image.iter().filter(|p| p[0] - p[2] > 0.15).count();
    let grey = out
        .image
        .iter()
        .filter(|p| p[0] > 0.05 && (p[0] - p[2]).abs() < 0.01 && p[0] < 0.9)
        .count();
    assert!(warm > 200 && grey > 200, "warm {warm}, grey {grey}");
}

/// A volume that is not drawn (`volume.render = false`, its slices are) has no colours of its
/// own to show: `annotate.colorbar = "volume"` is refused and no transfer-function note is
/// made; an isosurface cannot be projected (`mip` with `[volume.iso]` is refused by name).
#[test]
fn a_volume_not_drawn_has_no_colour_bar_or_transfer_note() {
    let dir = tempfile::tempdir().unwrap();
    // Values with outliers: most in [0, 1], a few at 1000 (the note's case when drawn).
    let v = volume_of([16, 16, 16], DMat4::IDENTITY, |p| {
        if p.x == 0.0 && p.y == 0.0 {
            1000.0
        } else {
            (p.z / 15.0) as f32
        }
    });
    let path = write(dir.path(), "v.nii", &v);
    let scene = |render: bool, extra: &str| {
        format!(
            "[volume]\npath = \"{path}\"\nrender = {render}\n[[slices]]\naxis = \"axial\"\n{extra}"
        )
    };
    let parse = |t: &str| scene::spec::parse(t, "s.toml", dir.path(), &[]);
    let drawn = model(&parse(&scene(true, "")).unwrap()).unwrap();
    assert!(
        drawn.notes.iter().any(|n| n.contains("percentiles")),
        "{:?}",
        drawn.notes
    );
    // Not drawn: no transfer function's note, but its slice shows the values over the full
    // range, which the slice's note says.
    let hidden = model(&parse(&scene(false, "")).unwrap()).unwrap();
    assert!(
        !hidden.notes.iter().any(|n| n.contains("transfer.range")),
        "{:?}",
        hidden.notes
    );
    assert!(
        hidden
            .notes
            .iter()
            .any(|n| n.starts_with("slices[0].window") && n.contains("percentiles")),
        "{:?}",
        hidden.notes
    );
    // Its grid's voxels set the slices (1 mm: slices half a voxel apart), as when it is drawn,
    // not the box's diagonal over 512 (0.05 mm here).
    assert_eq!((drawn.spacing, hidden.spacing), (1.0, 1.0));
    let e = model(&parse(&scene(false, "[annotate]\ncolorbar = \"volume\"\n")).unwrap())
        .err()
        .unwrap();
    assert!(
        e.contains("annotate.colorbar") && e.contains("volume.render"),
        "{e}"
    );
    let iso = format!(
        "[volume]\npath = \"{path}\"\n[volume.iso]\nvalue = 0.5\n[render]\nmethod = \"mip\"\n"
    );
    let e = parse(&iso).unwrap_err();
    assert!(e.contains("render.method") && e.contains("mip"), "{e}");
}

/// A label overlay holds whole numbers: a value of 2.5 is refused naming the overlay (it was
/// drawn as label 3), a float file's rounding error is not.
#[test]
fn a_label_overlay_with_fractional_values_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let base = small_base(dir.path());
    for (value, ok) in [(2.0000002f32, true), (2.5, false)] {
        let labels = write(
            dir.path(),
            "l.nii",
            &volume_of([8, 8, 8], DMat4::IDENTITY, |p| {
                if p == DVec3::new(5.0, 3.0, 2.0) {
                    value
                } else {
                    1.0
                }
            }),
        );
        let text = format!(
            "[volume]\npath = \"{base}\"\n[[slices]]\naxis = \"axial\"\n\
             [[overlays]]\nname = \"l\"\npath = \"{labels}\"\nlabels = true\n"
        );
        let s = scene::spec::parse(&text, "s.toml", dir.path(), &[]).unwrap();
        match model(&s) {
            Ok(_) => assert!(ok, "{value} accepted"),
            Err(e) => {
                assert!(!ok, "{value}: {e}");
                // The file's voxel is named.
                assert!(
                    e.contains("overlays[0].labels")
                        && e.contains("2.5")
                        && e.contains("voxel (5, 3, 2)"),
                    "{e}"
                );
            }
        }
    }
}

/// Labels the table lacks are hidden with a note, unless `show` hides them anyway.
#[test]
fn labels_missing_from_the_table_are_noted_unless_show_hides_them() {
    let dir = tempfile::tempdir().unwrap();
    let base = small_base(dir.path());
    let labels = write(
        dir.path(),
        "l.nii",
        &volume_of([8, 8, 8], DMat4::IDENTITY, |p| {
            if p.x < 4.0 {
                1.0
            } else {
                300.0
            }
        }),
    );
    let lut = dir.path().join("lut.txt");
    std::fs::write(&lut, "1 one 255 0 0 0\n").unwrap();
    for (show, noted) in [
        ("", true),
        ("show = [1]\n", false),
        ("show = [1, 300]\n", true),
    ] {
        let text = format!(
            "[volume]\npath = \"{base}\"\n[[slices]]\naxis = \"axial\"\n\
             [[overlays]]\nname = \"l\"\npath = \"{labels}\"\nlabels = true\nlut = \"{}\"\n{show}",
            lut.display()
        );
        let s = scene::spec::parse(&text, "s.toml", dir.path(), &[]).unwrap();
        let m = model(&s).unwrap();
        let note = m.notes.iter().any(|n| n.contains("not in the table"));
        assert_eq!(note, noted, "{show:?}: {:?}", m.notes);
    }
}

/// An overlay's default range starts at its lowest value, which is not shown (`t <= 0` is
/// hidden, as `mip` leaves out `volume.window`'s `lo`): a map with a zero background - FA, a
/// probability map - shows the base slice there. (`t = 0` was drawn in the map's lowest colour:
/// FA's grid painted red over the anatomy.)
#[test]
fn an_overlays_zero_background_at_the_default_range_shows_the_base() {
    let dir = tempfile::tempdir().unwrap();
    let anat = write(dir.path(), "anat.nii.gz", &anatomy());
    let a = DMat4::from_scale(DVec3::splat(2.0)) * DMat4::from_translation(DVec3::splat(-10.0));
    let map = write(
        dir.path(),
        "map.nii.gz",
        &volume_of([21, 21, 21], a, |p| {
            if p.x < 0.0 {
                0.0
            } else {
                (1.0 + 0.05 * p.y) as f32
            }
        }),
    );
    let text = |overlays: bool| {
        format!(
            r#"
background = [0.0, 0.0, 0.0]
[camera]
projection = "orthographic"
azimuth = 0.0
elevation = 90.0
[volume]
path = "{anat}"
render = false
[[slices]]
axis = "axial"
position = 1.0
overlays = {overlays}
[[overlays]]
name = "map"
path = "{map}"
[light]
ambient = 1.0
diffuse = 0.0
specular = 0.0
[render]
method = "ea"
width = 64
height = 64
msaa = 1
fxaa = false
"#
        )
    };
    let (with, m, s) = draw(&text(true), dir.path());
    let (without, _, _) = draw(&text(false), dir.path());
    let cam = scene::compile::camera(&s, m.bounds).unwrap();
    let (mut background, mut mapped) = (0, 0);
    for y in 0..64 {
        for x in 0..64 {
            let (o, d) = cam.ray(x as f64, y as f64, 64, 64);
            let p = o + d * ((1.0 - o.z) / d.z);
            // Inside the map's grid [-20, 20]^3: zero where x < 0, mapped where x > 0;
            // clear of its edges and of the anatomy's, and 5 mm from x = 0 (the map is resampled
            // into the anatomy's grid of 2 mm, then sampled: 4 mm of blend).
            if p.y.abs() > 8.0 || p.x.abs() > 12.0 || p.x.abs() < 5.0 {
                continue;
            }
            let (a, b) = (with[x + 64 * y], without[x + 64 * y]);
            let diff = (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0f32, f32::max);
            if p.x < 0.0 {
                background += 1;
                assert!(
                    diff < 1e-6,
                    "({x}, {y}) at x = {:.1}: differs by {diff}: {a:?} {b:?}",
                    p.x
                );
            } else {
                mapped += 1;
                assert!(
                    diff > 0.05,
                    "({x}, {y}) at x = {:.1}: the map not shown",
                    p.x
                );
            }
        }
    }
    assert!(
        background > 50 && mapped > 50,
        "{background} / {mapped} pixels"
    );
}

/// An 8^3 volume of its z coordinate (unit voxels at the origin) in `dir`: the base of the
/// label checks.
fn small_base(dir: &Path) -> String {
    write(
        dir,
        "v.nii",
        &volume_of([8, 8, 8], DMat4::IDENTITY, |p| p.z as f32),
    )
}

/// The `p`-th quantile (a fraction) of `v`, as numpy's default (linear) interpolation gives it.
fn percentile(v: &[f32], p: f64) -> f64 {
    let mut s: Vec<f64> = v
        .iter()
        .filter(|x| x.is_finite())
        .map(|&x| x as f64)
        .collect();
    s.sort_by(f64::total_cmp);
    let at = p * (s.len() - 1) as f64;
    let (k, f) = (at.floor() as usize, at.fract());
    s[k] + f * (s[(k + 1).min(s.len() - 1)] - s[k])
}

/// `"robust"` windows span the 2nd to 98th percentiles of the field's finite values (slices of
/// the volume, `volume.window` for slices and for `mip`, an overlay's `range` and a slice of
/// it), `"full"` the finite range; slices left at the full range of a field that a few
/// outliers stretch get a note naming them, an explicit window none.
#[test]
fn robust_and_full_windows_span_the_percentiles_and_the_range() {
    let dir = tempfile::tempdir().unwrap();
    // Values in [0, 1] with one voxel in 97 at 1000 (an inlet's speed in a room's flow), and
    // a NaN gap that no window counts.
    let a = DMat4::from_scale(DVec3::splat(2.0));
    let mut v = volume_of([20, 18, 16], a, |p| {
        let (i, j, k) = (
            (p.x / 2.0) as usize,
            (p.y / 2.0) as usize,
            (p.z / 2.0) as usize,
        );
        let n = i + 20 * (j + 18 * k);
        match n {
            _ if n == 5 => f32::NAN,
            _ if n % 97 == 0 => 1000.0,
            _ => ((i * 7 + j * 13 + k * 29) % 101) as f32 / 100.0,
        }
    });
    let values = v.fields[0].data.clone();
    let (lo, hi) = (percentile(&values, 0.02), percentile(&values, 0.98));
    assert!(hi <= 1.0 && lo > 0.0, "{lo} {hi}");
    let path = write(dir.path(), "v.nii", &v);
    v.fields[0].data.iter_mut().for_each(|x| *x *= 2.0);
    let twice = write(dir.path(), "w.nii", &v);
    let model_of = |text: &str| {
        let s = scene::spec::parse(
            &format!("[volume]\npath = \"{path}\"\n{text}"),
            "t.toml",
            dir.path(),
            &[],
        )
        .unwrap();
        model(&s).unwrap()
    };
    let window = |m: &scene::compile::Model, i: usize| match &m.planes.as_ref().unwrap().planes[i]
        .layers[0]
        .map
    {
        engine::planes::LayerMap::Scalar { lo, hi, .. } => [*lo, *hi],
        _ => panic!("a scalar layer"),
    };
    let near = |w: [f64; 2], e: [f64; 2]| {
        assert!(
            (w[0] - e[0]).abs() <= 1e-9 * e[0].abs().max(1.0)
                && (w[1] - e[1]).abs() <= 1e-9 * e[1].abs().max(1.0),
            "{w:?} against {e:?}"
        )
    };
    let noted = |m: &scene::compile::Model| {
        m.notes
            .iter()
            .filter(|n| n.contains("window = \"robust\""))
            .cloned()
            .collect::<Vec<_>>()
    };
    // The default: the full range, and a note naming the slices at it.
    let m = model_of("[[slices]]\naxis = \"axial\"\n[[slices]]\naxis = \"coronal\"\nwindow = [0.0, 1.0]\n[[slices]]\naxis = \"sagittal\"\n");
    near(window(&m, 0), [0.0, 1000.0]);
    let notes = noted(&m);
    assert_eq!(notes.len(), 1, "{:?}", m.notes);
    assert!(
        notes[0].contains("slices[0].window, slices[2].window")
            && !notes[0].contains("slices[1]")
            && notes[0].contains("v.nii"),
        "{}",
        notes[0]
    );
    // Planned again (the viewer's menu): the notes follow the windows.
    assert!(scene::slices::is_slice_note(&notes[0]));
    let mut s2 = scene::spec::parse(
        &format!("[volume]\npath = \"{path}\"\n[[slices]]\naxis = \"axial\"\nwindow = \"robust\"\n[[slices]]\naxis = \"coronal\"\nwindow = [0.0, 1.0]\n[[slices]]\naxis = \"sagittal\"\n"),
        "t.toml",
        dir.path(),
        &[],
    )
    .unwrap();
    let (_, again) = m.planes.as_ref().unwrap().replan(&s2).unwrap();
    assert!(
        again.len() == 1
            && again[0].starts_with("slices[2].window (")
            && scene::slices::is_slice_note(&again[0]),
        "{again:?}"
    );
    s2.slices[2].window = Some(scene::spec::Window::Named("full".into()));
    assert!(m.planes.as_ref().unwrap().replan(&s2).unwrap().1.is_empty());
    // "robust" on the slice, or on the volume for every slice; "full" says it is meant.
    let m = model_of("[[slices]]\naxis = \"axial\"\nwindow = \"robust\"\n");
    near(window(&m, 0), [lo, hi]);
    assert!(noted(&m).is_empty(), "{:?}", m.notes);
    let m = model_of("window = \"robust\"\n[[slices]]\naxis = \"axial\"\n");
    near(window(&m, 0), [lo, hi]);
    let m = model_of("window = \"robust\"\n[[slices]]\naxis = \"axial\"\nwindow = \"full\"\n");
    near(window(&m, 0), [0.0, 1000.0]);
    assert!(noted(&m).is_empty(), "{:?}", m.notes);
    // An overlay's range, and a slice of the overlay: its own values (twice the volume's).
    let m = model_of(&format!(
        "[[overlays]]\nname = \"w\"\npath = \"{twice}\"\nrange = \"robust\"\n\
         [[slices]]\naxis = \"axial\"\nvolume = \"w\"\n\
         [[slices]]\naxis = \"axial\"\nvolume = \"w\"\nwindow = \"full\"\n"
    ));
    near(window(&m, 0), [2.0 * lo, 2.0 * hi]);
    near(window(&m, 1), [0.0, 2000.0]);
    match &m.planes.as_ref().unwrap().overlays[0].0 {
        engine::planes::LayerMap::Scalar { lo: a, hi: b, .. } => {
            near([*a, *b], [2.0 * lo, 2.0 * hi])
        }
        _ => panic!("a scalar overlay"),
    }
    // A slice's colour bar: its colour map over its window, with the volume not drawn too.
    let m = model_of("render = false\ncolormap = \"viridis\"\n[[slices]]\naxis = \"axial\"\nwindow = \"robust\"\n[annotate]\ncolorbar = \"slices.0\"\n");
    let bar = m.colorbar.as_ref().expect("the slice's colour bar");
    near(bar.range, [lo, hi]);
    assert_eq!((bar.label.as_str(), bar.map.as_str()), ("data", "viridis"));
    let m = model_of(&format!(
        "[[overlays]]\nname = \"w\"\npath = \"{twice}\"\n\
         [[slices]]\naxis = \"axial\"\n[[slices]]\naxis = \"axial\"\nvolume = \"w\"\n\
         window = [0.5, 1.5]\ncolormap = \"hot\"\n[annotate]\ncolorbar = \"slices.1\"\n"
    ));
    let bar = m.colorbar.as_ref().expect("the overlay slice's colour bar");
    assert_eq!(
        (bar.label.as_str(), bar.map.as_str(), bar.range),
        ("w", "hot", [0.5, 1.5])
    );
    let e = scene::spec::parse(
        &format!("[volume]\npath = \"{path}\"\n[[slices]]\naxis = \"axial\"\n[annotate]\ncolorbar = \"slices.1\"\n"),
        "t.toml",
        dir.path(),
        &[],
    )
    .unwrap_err();
    assert!(
        e.contains("annotate.colorbar") && e.contains("one [[slices]] entry (slices.0)"),
        "{e}"
    );
    // MIP through a robust window: its colour bar spans it.
    let m = model_of(
        "window = \"robust\"\n[render]\nmethod = \"mip\"\n[annotate]\ncolorbar = \"volume\"\n",
    );
    near(m.colorbar.as_ref().unwrap().range, [lo, hi]);
    assert!(noted(&m).is_empty(), "{:?}", m.notes);
    // Over the full range by default: a note on the outliers, naming the key.
    let m = model_of("[render]\nmethod = \"mip\"\n");
    let notes = noted(&m);
    assert!(
        notes.len() == 1 && notes[0].contains("volume.window = \"robust\""),
        "{:?}",
        m.notes
    );
    // Names other than "full" and "robust" are refused, naming the key; a saved scene keeps
    // the name.
    let e = scene::spec::parse(
        &format!("[volume]\npath = \"{path}\"\n[[slices]]\naxis = \"axial\"\nwindow = \"wide\"\n"),
        "t.toml",
        dir.path(),
        &[],
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("slices[0].window") && e.contains("'wide'"),
        "{e}"
    );
    let s = scene::spec::parse(
        &format!("[volume]\npath = \"{path}\"\nwindow = \"robust\"\n"),
        "t.toml",
        dir.path(),
        &[],
    )
    .unwrap();
    let text = scene::spec::to_toml(&s).unwrap();
    assert!(text.contains("window = \"robust\""), "{text}");
    // A constant field: its robust range is its full range, widened as a default window is
    // (the renderer needs a width; it was refused on the GPU).
    let flat = volume_of([6, 5, 4], a, |_| 7.0);
    let flat = write(dir.path(), "flat.nii", &flat);
    let s = scene::spec::parse(
        &format!(
            "[volume]\npath = \"{flat}\"\nwindow = \"robust\"\n[[slices]]\naxis = \"axial\"\n"
        ),
        "t.toml",
        dir.path(),
        &[],
    )
    .unwrap();
    let m = model(&s).unwrap();
    let [wlo, whi] = window(&m, 0);
    assert!(wlo == 7.0 && (whi as f32) > 7.0, "{wlo} {whi}");
    // A width that single precision holds only as a subnormal is refused, naming the key.
    let e = scene::spec::parse(
        &format!("[volume]\npath = \"{path}\"\nwindow = [1e-38, 0.0]\n"),
        "t.toml",
        dir.path(),
        &[],
    )
    .unwrap_err();
    assert!(e.contains("volume.window") && e.contains("1.2e-38"), "{e}");
}

/// Slices have no inside: under the default `render.geometry_shadow = "inside"` they cast no
/// light, so a scene of slices alone sweeps no light volume with `combined` and draws what
/// `vicinity` draws (the partial term 1); under `"column"` they cast the paper's column, which
/// is swept.
#[test]
fn slices_alone_sweep_no_light_volume_unless_they_cast_columns() {
    let dir = tempfile::tempdir().unwrap();
    let anat = write(dir.path(), "anat.nii.gz", &anatomy());
    let gpu = engine::gpu::Gpu::new().expect("a GPU adapter (lavapipe in CI)");
    let frame = |method: &str, extra: &str| {
        let text = format!(
            "[camera]\nazimuth = 30.0\nelevation = 25.0\n[volume]\npath = \"{anat}\"\nrender = false\n\
             [[slices]]\naxis = \"axial\"\n[[slices]]\naxis = \"sagittal\"\n\
             [render]\nwidth = 64\nheight = 48\nmethod = \"{method}\"\n{extra}"
        );
        let s = scene::spec::parse(&text, "t.toml", dir.path(), &[]).unwrap();
        let m = model(&s).unwrap();
        let up = upload(&gpu, &m).unwrap();
        up.draw_at(&s, &m, DrawOptions::default(), None).unwrap().0
    };
    let combined = frame("combined", "");
    let vicinity = frame("vicinity", "");
    assert!(combined.light.is_none(), "a light volume swept");
    assert!(combined.aov.iter().all(|a| a.partial == 1.0));
    assert_eq!(combined.image, vicinity.image);
    let column = frame("combined", "geometry_shadow = \"column\"\n");
    assert!(column.light.is_some(), "columns behind slices cast light");
}
