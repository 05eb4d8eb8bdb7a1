//! Isosurface mode against its CPU reference (`iso_reference`, the renderer of `umbra iso`):
//! the same rays, surface, normal and swept ambient term, on lavapipe; and tubes in the same
//! image.

use glam::DVec3;
use occlusion::isosurface::{ambient_at, AmbientSource, IsoSurface};
use scene::compile::{model, render_scene};

/// Singh et al.'s validation scene at `n^3` written as `dir/v.nrrd`.
fn validation_nrrd(dir: &std::path::Path, n: usize) -> std::path::PathBuf {
    write_nrrd(dir, &volume::synthetic::validation_scene(n))
}

/// `vol`'s first field written as `dir/v.nrrd`.
fn write_nrrd(dir: &std::path::Path, vol: &volume::Volume) -> std::path::PathBuf {
    let path = dir.join("v.nrrd");
    volume::nrrd::write(&path, vol, &vol.fields[0], volume::nrrd::WriteEncoding::Raw).unwrap();
    path
}

fn scene(dir: &std::path::Path, extra: &str) -> scene::spec::Scene {
    let path = validation_nrrd(dir, 40);
    let text = format!(
        "background = [0.0, 0.0, 0.0]\n[camera]\nazimuth = 35.0\nelevation = 30.0\n\
         [volume]\npath = \"{}\"\n[volume.iso]\nvalue = 0.0\ninside = \"below\"\n{extra}\
         [render]\nwidth = 72\nheight = 60\nfxaa = false\n",
        path.display()
    );
    scene::spec::parse(&text, "iso.toml", dir, &[]).unwrap()
}

#[test]
fn the_gpu_isosurface_matches_the_cpu_reference() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path(), "");
    let m = model(&s).unwrap();
    let gpu = engine::gpu::Gpu::new().expect("a GPU adapter (lavapipe in CI)");
    let (out, v) = render_scene(&gpu, &s, &m, 1).unwrap();
    let iso = m.iso.as_ref().unwrap();
    let (w, h) = (v.width as usize, v.height as usize);
    // The CPU reference on the same rays.
    let values: Vec<f32> = iso.g.clone(); // classified: inside where >= 0
    let surface = IsoSurface::new(iso.dims, iso.affine, &values, 0.0, true, &iso.sdf);
    let source = AmbientSource::Swept {
        octants: &iso.octants,
        model: &iso.model,
    };
    let (mut both, mut agree, mut only_one, mut sum) = (0, 0, 0, 0.0);
    for y in 0..h {
        for x in 0..w {
            let (o, d) = v.camera.ray(x as f64, y as f64, w, h);
            let cpu = surface.trace(o, d, 0.0, f64::INFINITY).map(|t| {
                let p = o + d * t;
                let mut n = surface.normal(p);
                if n == DVec3::ZERO {
                    n = -d;
                }
                if n.dot(d) > 0.0 {
                    n = -n;
                }
                (
                    ambient_at(&surface, &source, p, n, 0).0,
                    (p - v.camera.eye).dot(v.camera.forward()),
                )
            });
            let a = out.aov[x + w * y];
            let gpu_hit = a.depth > 0.0 && out.image[x + w * y][3] == 1.0;
            match (cpu, gpu_hit) {
                (Some((amb, depth)), true) => {
                    both += 1;
                    let e = (amb - a.combined as f64).abs();
                    sum += e;
                    if e < 0.02 && (depth - a.depth as f64).abs() < 0.5 {
                        agree += 1;
                    } else if both - agree < 6 {
                        eprintln!(
                            "({x}, {y}): cpu A {amb:.4} depth {depth:.3}, gpu A {:.4} depth {:.3}",
                            a.combined, a.depth
                        );
                    }
                }
                (None, false) => {}
                _ => only_one += 1,
            }
        }
    }
    eprintln!(
        "{both} pixels hit by both, {agree} agree, {only_one} hit by one only, mean |dA| {:.5}",
        sum / both as f64
    );
    assert!(both > w * h / 5, "{both} hits");
    assert!(agree as f64 > 0.97 * both as f64, "{agree} of {both} agree");
    assert!(
        only_one < w * h / 100 + 5,
        "{only_one} silhouette disagreements"
    );
    assert!(sum / (both as f64) < 0.005);
    // The ambient term varies: the pit and the sphere's underside are darker than tops.
    let amb: Vec<f32> = (0..w * h)
        .filter(|&i| out.aov[i].depth > 0.0)
        .map(|i| out.aov[i].combined)
        .collect();
    let lo = amb.iter().cloned().fold(1.0f32, f32::min);
    let hi = amb.iter().cloned().fold(0.0f32, f32::max);
    assert!(hi - lo > 0.3, "ambient range {lo}..{hi}");
}

#[test]
fn tubes_and_the_isosurface_share_the_image() {
    let dir = tempfile::tempdir().unwrap();
    // A tube floating above the validation scene (its grid spans [0, 100]^3).
    let mut sl = tubes::Streamlines::new();
    sl.push(&[
        glam::Vec3::new(20.0, 50.0, 115.0),
        glam::Vec3::new(80.0, 50.0, 115.0),
    ]);
    let trk = dir.path().join("t.tck");
    tubes::save(&trk, &sl).unwrap();
    let s = scene(
        dir.path(),
        &format!(
            "[[tubes]]\npath = \"{}\"\nradius = 3.0\ncolor = \"#ff0000\"\n",
            trk.display()
        ),
    );
    let m = model(&s).unwrap();
    let gpu = engine::gpu::Gpu::new().unwrap();
    let (out, v) = render_scene(&gpu, &s, &m, 1).unwrap();
    let (w, h) = (v.width as usize, v.height as usize);
    let px = |p: [f64; 3]| {
        let (x, y, _) = v.camera.to_pixel(DVec3::from(p), w, h).unwrap();
        x as usize + w * y as usize
    };
    // The tube is in front: red there; the isosurface elsewhere: grey.
    let t = out.image[px([50.0, 50.0, 118.0])];
    assert!(t[0] > 2.0 * t[1] && t[0] > 0.2, "tube pixel {t:?}");
    let b = out.image[px([70.0, 30.0, 49.0])];
    assert!((b[0] - b[1]).abs() < 0.02 && b[0] > 0.1, "box top {b:?}");
}

/// A hollow ball (a shell from radius 6 to 10) cut in half by a clipping plane through its
/// centre and seen through the cut: the cavity's floor, shut off from the sky in the uncut
/// solid, sees it through the opening. Its swept ambient term was 0 (black) when the octants
/// described the uncut solid; exactly, the bowl's bottom sees a cone of 45 degrees (the rim
/// at 45 degrees from its normal): cosine-weighted visibility 1/2.
#[test]
fn a_cut_opens_the_cavity_behind_it_to_the_sky() {
    let dir = tempfile::tempdir().unwrap();
    let n = 33usize;
    let mut nrrd = format!(
        "NRRD0004\ntype: uint8\ndimension: 3\nsizes: {n} {n} {n}\nspacing: 1 1 1\n\
         encoding: raw\n\n"
    )
    .into_bytes();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let r = [i, j, k]
                    .map(|x| (x as f64 - 16.0).powi(2))
                    .iter()
                    .sum::<f64>()
                    .sqrt();
                nrrd.push(((r - 8.0).abs() * 10.0).min(255.0).round() as u8);
            }
        }
    }
    std::fs::write(dir.path().join("shell.nrrd"), nrrd).unwrap();
    let text = |clip: &str| {
        format!(
            "background = [0.0, 0.0, 0.0]\n[camera]\nazimuth = 90.0\nelevation = 0.0\n\
             [volume]\npath = \"shell.nrrd\"\n[volume.iso]\nvalue = 20.0\ninside = \"below\"\n\
             {clip}[render]\nwidth = 48\nheight = 48\nfxaa = false\n"
        )
    };
    let gpu = engine::gpu::Gpu::new().expect("a GPU adapter (lavapipe in CI)");
    let cut = "[[clip]]\nnormal = [-1.0, 0.0, 0.0]\noffset = -16.0\n";
    let s = scene::spec::parse(&text(cut), "shell.toml", dir.path(), &[]).unwrap();
    let m = model(&s).unwrap();
    let (out, v) = render_scene(&gpu, &s, &m, 1).unwrap();
    let (w, h) = (v.width as usize, v.height as usize);
    let centre = out.aov[w / 2 + w * (h / 2)];
    // The same frame with the octants of the uncut solid (as before the cut was swept).
    let whole = scene::spec::parse(&text(""), "shell.toml", dir.path(), &[]).unwrap();
    let mut shut = model(&s).unwrap();
    shut.iso.as_mut().unwrap().octants = model(&whole).unwrap().iso.unwrap().octants;
    let (uncut, _) = render_scene(&gpu, &s, &shut, 1).unwrap();
    let before = uncut.aov[w / 2 + w * (h / 2)];
    eprintln!(
        "the cavity's floor: ambient {:.3} at depth {:.2} (uncut octants: {:.3})",
        centre.combined, centre.depth, before.combined
    );
    // The pixel shows the floor (x = 22), not the cut face (x = 16).
    let floor = (DVec3::new(22.0, 16.0, 16.0) - v.camera.eye).dot(v.camera.forward());
    assert!(
        (centre.depth as f64 - floor).abs() < 0.5,
        "depth {}",
        centre.depth
    );
    assert!(before.combined < 0.05, "{}", before.combined);
    assert!(
        (0.25..0.75).contains(&centre.combined),
        "{}",
        centre.combined
    );
    // Nothing but the isosurface: `combined` (the default method) draws it as `ea` does,
    // without sweeping a light volume over the empty medium (most of its frame before).
    assert!(
        out.light.is_none(),
        "a light volume swept for an isosurface alone"
    );
    // A light key set there changes nothing, and the frame says so.
    let mut keyed = s.clone();
    keyed.render.occlusion_step = Some(2);
    let (keyed_out, _) = scene::compile::upload(&gpu, &m)
        .unwrap()
        .draw(&keyed, &m, Default::default())
        .unwrap();
    assert!(
        keyed_out
            .notes
            .iter()
            .any(|n| n.contains("render.occlusion_step") && n.contains("isosurface alone")),
        "{:?}",
        keyed_out.notes
    );
    let mut ea = s.clone();
    ea.render.method = engine::method::Method::Ea;
    let (ea_out, _) = render_scene(&gpu, &ea, &m, 1).unwrap();
    assert_eq!(ea_out.image, out.image);
}

/// Fields read from files are swept again for the scene's cut with the subsurface opacity
/// their octants file records (`umbra_subsurface`): a sweep with `--subsurface 0.5` and one
/// without give other octants for the same cut, and the uncut scene keeps the files' own.
#[test]
fn fields_from_files_keep_their_subsurface_opacity_when_cut() {
    let dir = tempfile::tempdir().unwrap();
    let path = validation_nrrd(dir.path(), 24);
    let sweep = |name: &str, alpha: Option<f32>| {
        let out = dir.path().join(format!("{name}.nrrd"));
        scene::fields::run(
            &scene::fields::SweepArgs {
                input: path.clone(),
                iso: 0.0,
                output: out.clone(),
                octants_out: None,
                inside: volume::distance_sweep::Inside::Below,
                field: None,
                sdf_only: false,
                init: volume::distance_sweep::InitMethod::Gradient,
                method: volume::distance_sweep::DistanceMethod::ClosestPoint,
                tolerance: 1e-3,
                subsurface_alpha: alpha,
            },
            &|_| {},
        )
        .unwrap();
        let octants = scene::fields::default_octants_path(&out);
        let header = std::fs::read(&octants).unwrap();
        let text = String::from_utf8_lossy(&header[..header.len().min(2000)]).to_string();
        let want = alpha.map_or("umbra_subsurface:=none".to_string(), |a| {
            format!("umbra_subsurface:={a:?}")
        });
        assert!(text.contains(&want), "{want} in\n{text}");
        out
    };
    let (plain, soft) = (sweep("plain", None), sweep("soft", Some(0.5)));
    let octants = |fields: &std::path::Path, clip: &str| {
        let text = format!(
            "[volume]\npath = \"v.nrrd\"\n[volume.iso]\nvalue = 0.0\ninside = \"below\"\n\
             fields = \"{}\"\n{clip}[render]\nwidth = 16\nheight = 16\n",
            fields.display()
        );
        let s = scene::spec::parse(&text, "iso.toml", dir.path(), &[]).unwrap();
        model(&s).unwrap().iso.unwrap().octants
    };
    let cut = "[[clip]]\nnormal = [1.0, 0.0, 0.0]\noffset = 50.0\n";
    let (plain_cut, soft_cut) = (octants(&plain, cut), octants(&soft, cut));
    assert_ne!(
        plain_cut, soft_cut,
        "the subsurface opacity kept through the cut"
    );
    // Soft everywhere at least as open; the cut opens the plain solid.
    let sum = |o: &volume::occlusion_sweep::OctantFields| -> u64 {
        o.octants.iter().flatten().map(|&v| v as u64).sum()
    };
    assert!(sum(&soft_cut) > sum(&plain_cut));
    assert!(sum(&plain_cut) > sum(&octants(&plain, "")));
}

/// NaN samples in isosurface mode are taken as outside (as `umbra sweep` takes them), and the
/// render says so, as the volume's rendering says of its gaps (a new user found it silent).
#[test]
fn nan_samples_in_isosurface_mode_are_noted() {
    let dir = tempfile::tempdir().unwrap();
    let mut vol = volume::synthetic::validation_scene(24);
    let n = vol.fields[0].data.len();
    for k in [n / 3, n / 2, n / 2 + 1] {
        vol.fields[0].data[k] = f32::NAN;
    }
    let path = write_nrrd(dir.path(), &vol);
    let text = format!(
        "[volume]\npath = \"{}\"\n[volume.iso]\nvalue = 0.0\ninside = \"below\"\n\
         [render]\nwidth = 32\nheight = 32\n",
        path.display()
    );
    let s = scene::spec::parse(&text, "iso.toml", dir.path(), &[]).unwrap();
    let m = model(&s).unwrap();
    assert!(
        m.notes
            .iter()
            .any(|n| n.contains("3 NaN samples are taken as outside the isosurface")),
        "{:?}",
        m.notes
    );
}

/// An isosurface of a field the file does not have, or of a vector field, names
/// `volume.field`, not the level.
#[test]
fn a_bad_isosurface_field_names_volume_field() {
    let dir = tempfile::tempdir().unwrap();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap();
    for (field, says) in [("nope", "no such field"), ("data:x", "")] {
        let text = format!(
            "[volume]\npath = \"{}\"\nfield = \"{field}\"\n[volume.iso]\nvalue = 1000.0\n",
            root.join("datasets/vtk/headsq_64x64x93.nhdr").display()
        );
        let s = scene::spec::parse(&text, "iso.toml", dir.path(), &[]).unwrap();
        let Err(e) = scene::compile::model(&s) else {
            panic!("{field}: an isosurface was made");
        };
        assert!(
            e.starts_with("volume.field: ") && e.contains(says),
            "{field}: {e}"
        );
    }
}
