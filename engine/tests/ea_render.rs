//! The renderer's emission-absorption method on whatever adapter this machine has (lavapipe in
//! CI) against its f64 CPU twin, and the slice-count independence of opacity per unit length.

use engine::gpu::Gpu;
use engine::method::Method;
use engine::renderer::{self, Settings};
use engine::slice_pass::{Samples, VolumeInput};
use glam::DVec3;
use occlusion::camera::Camera;
use occlusion::emission_absorption::{reference, EaView, Transfer};
use volume::Volume;

/// A Gaussian blob on an anisotropic grid, off the origin.
fn blob() -> Volume {
    volume::synthetic::gaussian_blob([24, 20, 16], DVec3::new(-10.0, -9.0, -8.0), 30.0)
}

/// The `ea` method of the renderer, no tubes, no FXAA.
fn render(gpu: &Gpu, data: &[f32], vol: &Volume, tf: &Transfer, v: &EaView) -> Vec<[f32; 4]> {
    let data = Samples::pack(data.to_vec());
    let vi = VolumeInput {
        vol,
        data: &data,
        tf,
    };
    draw(gpu, &vi, v, Method::Ea, None).unwrap()
}

/// `method` (no tubes, no FXAA) with the storage binding limit lowered to `limit` bytes for
/// the draw (`None`: the adapter's).
fn draw(
    gpu: &Gpu,
    vi: &VolumeInput,
    v: &EaView,
    method: Method,
    limit: Option<u64>,
) -> Result<Vec<[f32; 4]>, engine::gpu::GpuError> {
    let settings = Settings {
        method,
        fxaa: false,
        ..Default::default()
    };
    gpu.limit_bindings(limit);
    let out = renderer::render(gpu, Some(vi), &[], &[], None, v, &settings, 1);
    gpu.limit_bindings(None);
    out.map(|o| o.image)
}

fn tf() -> Transfer {
    Transfer {
        points: vec![
            (0.1, [0.0, 0.0, 0.0], 0.0),
            (0.5, [0.2, 0.4, 1.0], 0.3),
            (0.9, [1.0, 0.6, 0.2], 0.9),
        ],
        rows: vec![],
    }
}

#[test]
fn gpu_image_matches_the_cpu_reference() {
    let gpu = Gpu::new().expect("a GPU adapter (CI installs mesa-vulkan-drivers for lavapipe)");
    let vol = blob();
    let data = vol.select(None).unwrap().data;
    let persp = Camera::orbit(vol.bounds(), 40.0, 25.0, 2.5, Some(40.0));
    for (cam, bg, clip) in [
        (persp, [1.0, 1.0, 1.0], vec![]),
        (
            Camera::orbit(vol.bounds(), -70.0, 60.0, 3.0, None),
            [0.1, 0.2, 0.3],
            vec![],
        ),
        // The paper's Fig. 11 cut: half the blob removed (x > 1.5 here).
        (persp, [1.0, 1.0, 1.0], vec![([1.0, 0.0, 0.0], 1.5)]),
    ] {
        let mut view = EaView::new(&vol, cam, 48, 40, None, None, bg).unwrap();
        view.clip = clip;
        let gpu_img = render(&gpu, &data, &vol, &tf(), &view);
        let cpu_img = reference(&data, &vol, &tf(), &view);
        let mut worst = 0.0f64;
        for (g, c) in gpu_img.iter().zip(&cpu_img) {
            for k in 0..4 {
                worst = worst.max((g[k] as f64 - c[k]).abs());
            }
        }
        // f32 on the GPU against f64: a few units in the fourth decimal at most.
        assert!(worst < 2e-3, "GPU and CPU differ by {worst}");
        // The blob is seen in the middle, the corners show the background.
        let centre = cpu_img[24 + 48 * 20];
        assert!(centre[3] > 0.2, "centre alpha {}", centre[3]);
        if !view.clip.is_empty() {
            // Half the blob is gone: clearly less opacity in all.
            let full = EaView::new(&vol, cam, 48, 40, None, None, bg).unwrap();
            let whole = reference(&data, &vol, &tf(), &full);
            let sum = |img: &[[f64; 4]]| img.iter().map(|p| p[3]).sum::<f64>();
            assert!(
                sum(&cpu_img) < 0.8 * sum(&whole),
                "{} vs {}",
                sum(&cpu_img),
                sum(&whole)
            );
        }
        let corner = cpu_img[0];
        assert_eq!(corner[3], 0.0);
        for k in 0..3 {
            assert!((corner[k] - bg[k]).abs() < 1e-12);
        }
    }
}

#[test]
fn an_opaque_ray_shows_its_medium_not_the_background() {
    // A dense uniform medium (extinction 5 a unit, grey 0.2) before a white background: a ray
    // through it is opaque long before its end, so the exact pixel is the medium's 0.2. Rays
    // end at OPAQUE (1 - 1/128) and take the rest as the mean of what they showed
    // (`end_opaque`); letting the background through the rest gave 0.2 + (1 - 0.2)(1 - alpha),
    // 0.2054 here. GPU and f64 twin alike.
    let gpu = Gpu::new().expect("a GPU adapter (CI installs mesa-vulkan-drivers for lavapipe)");
    let mut vol = blob();
    vol.fields[0].data.iter_mut().for_each(|v| *v = 0.5);
    let data = vol.select(None).unwrap().data;
    let grey = Transfer {
        points: vec![(0.0, [0.2; 3], 5.0), (1.0, [0.2; 3], 5.0)],
        rows: vec![],
    };
    let cam = Camera::orbit(vol.bounds(), 0.0, 0.0, 3.0, None);
    let view = EaView::new(&vol, cam, 32, 32, None, None, [1.0; 3]).unwrap();
    let centre = 16 * 32 + 16;
    let gpu_px = render(&gpu, &data, &vol, &grey, &view)[centre].map(|x| x as f64);
    let cpu_px = reference(&data, &vol, &grey, &view)[centre];
    for (who, p) in [("GPU", gpu_px), ("twin", cpu_px)] {
        assert!(p[3] >= 0.9999, "{who}: opacity {}", p[3]);
        for (c, x) in p[..3].iter().enumerate() {
            assert!((x - 0.2).abs() < 1e-3, "{who}: channel {c} {x} against 0.2");
        }
    }
}

#[test]
fn the_image_does_not_depend_on_the_slice_count() {
    let vol = blob();
    let data = vol.select(None).unwrap().data;
    let cam = Camera::orbit(vol.bounds(), 40.0, 25.0, 2.5, Some(40.0));
    let coarse = EaView::new(&vol, cam, 40, 32, None, None, [1.0; 3]).unwrap();
    let fine = EaView::new(&vol, cam, 40, 32, Some(coarse.slices * 4), None, [1.0; 3]).unwrap();
    let (a, b) = (
        reference(&data, &vol, &tf(), &coarse),
        reference(&data, &vol, &tf(), &fine),
    );
    let diffs: Vec<f64> = a
        .iter()
        .zip(&b)
        .flat_map(|(p, q)| (0..4).map(move |k| (p[k] - q[k]).abs()))
        .collect();
    let mean = diffs.iter().sum::<f64>() / diffs.len() as f64;
    let max = diffs.iter().cloned().fold(0.0, f64::max);
    assert!(mean < 5e-3 && max < 0.03, "mean {mean}, max {max}");
    // Doubling the extinction does change it (the test can fail).
    let mut dense = tf();
    for p in &mut dense.points {
        p.2 *= 2.0;
    }
    let c = reference(&data, &vol, &dense, &coarse);
    let alpha_gain: f64 = c.iter().zip(&a).map(|(p, q)| p[3] - q[3]).sum();
    assert!(alpha_gain > 1.0, "{alpha_gain}");
}

#[test]
fn a_two_dimensional_transfer_function_matches_the_cpu_reference() {
    // Extinction only where the gradient magnitude is high (the blob's flanks), with the
    // gradient taken by the shader and by ea_pass::gradient the same way.
    let gpu = Gpu::new().expect("a GPU adapter");
    let vol = blob();
    let data = vol.select(None).unwrap().data;
    let tf = Transfer {
        points: vec![
            (0.0, [0.0; 3], 0.0),
            (1.0, [0.0; 3], 0.0),
            (0.0, [1.0, 0.5, 0.2], 0.0),
            (1.0, [1.0, 0.5, 0.2], 2.0),
        ],
        rows: vec![(0.0, 0), (0.1, 2)],
    };
    let cam = Camera::orbit(vol.bounds(), 40.0, 25.0, 2.5, Some(40.0));
    let view = EaView::new(&vol, cam, 40, 32, None, None, [1.0; 3]).unwrap();
    let g = render(&gpu, &data, &vol, &tf, &view);
    let c = reference(&data, &vol, &tf, &view);
    let worst = g
        .iter()
        .zip(&c)
        .flat_map(|(a, b)| (0..4).map(move |k| (a[k] as f64 - b[k]).abs()))
        .fold(0.0, f64::max);
    assert!(worst < 2e-3, "GPU and CPU differ by {worst}");
    // The function does something: the flanks are seen.
    let alpha: f64 = c.iter().map(|p| p[3]).sum();
    assert!(alpha > 1.0, "{alpha}");
}

/// Issue 18: a volume larger than a storage binding is split into parts (here the binding
/// limit is lowered so that the blob's 7,680 samples take 8 parts of 1,024, then as many parts
/// of 256 words as the adapter binds, 20 on lavapipe): the image equals the whole volume's
/// exactly, with emission-absorption and with the light volume of the occlusion methods; a
/// volume needing more parts than the adapter binds is an error that says what to do.
#[test]
fn a_volume_split_into_parts_renders_as_the_whole() {
    let gpu = Gpu::new().expect("a GPU adapter (CI installs mesa-vulkan-drivers for lavapipe)");
    let vol = blob();
    let data = vol.select(None).unwrap().data;
    let cam = Camera::orbit(vol.bounds(), 40.0, 25.0, 2.5, Some(40.0));
    let view = EaView::new(&vol, cam, 48, 40, None, None, [1.0; 3]).unwrap();
    let tf = tf();
    let data = Samples::pack(data);
    let vi = VolumeInput {
        vol: &vol,
        data: &data,
        tf: &tf,
    };
    let most = engine::slice_pass::volume_parts(&gpu);
    assert!(
        most >= 16,
        "{most} parts: the adapter binds too few storage buffers for 1024^3 16-bit samples \
         in 128 MiB bindings"
    );
    // Parts of `fitting` bytes: the blob (7,680 f32 words) in exactly `most` parts. The blob
    // leaves the grid's ends empty, so a second field of noise in [0.2, 0.8] over all of it
    // (seen through at a tenth of the extinction) makes every part show in the image.
    let fitting = (7680usize.div_ceil(most) as u64 * 4).next_multiple_of(16);
    let noise = Samples::pack(
        (0..7680u32)
            .map(|i| 0.2 + 0.6 * (i.wrapping_mul(2654435761) >> 8) as f32 / (1u32 << 24) as f32)
            .collect(),
    );
    let thin = Transfer {
        points: tf.points.iter().map(|&(v, c, e)| (v, c, e * 0.1)).collect(),
        rows: vec![],
    };
    let noisy = VolumeInput {
        vol: &vol,
        data: &noise,
        tf: &thin,
    };
    for (field, vi) in [("blob", &vi), ("noise", &noisy)] {
        for method in [Method::Ea, Method::Combined] {
            let whole = draw(&gpu, vi, &view, method, None).unwrap();
            let seen = whole.iter().filter(|p| p[3] > 0.05).count();
            assert!(
                seen > 200,
                "{field}, {method:?}: the volume covers {seen} pixels"
            );
            for bytes in [4096, fitting] {
                let parts = draw(&gpu, vi, &view, method, Some(bytes)).unwrap();
                assert!(
                    whole == parts,
                    "{field}, {method:?}: the image in parts of {bytes} bytes differs"
                );
            }
        }
    }
    let too_small = (7680 / (most + 1) * 4) as u64 & !15;
    let r = draw(&gpu, &vi, &view, Method::Ea, Some(too_small));
    let e = r
        .expect_err("more parts than bindings are refused")
        .to_string();
    assert!(
        e.contains("7680 samples") && e.contains("downsample"),
        "{e}"
    );
}

/// Issue 18: an integer-valued volume (the stored type of most scans) goes to the GPU as 8- or
/// 16-bit integers (`slice_pass::Packing`): its image equals, within float rounding, that of
/// the same volume shifted by a quarter (which stays f32) under the transfer function shifted
/// alike; packed volumes split into parts render as the whole.
#[test]
fn integer_volumes_packed_in_8_and_16_bits_render_as_f32() {
    use engine::slice_pass::Packing;
    let gpu = Gpu::new().expect("a GPU adapter (CI installs mesa-vulkan-drivers for lavapipe)");
    let vol = blob();
    let blob = vol.select(None).unwrap().data;
    let cam = Camera::orbit(vol.bounds(), 40.0, 25.0, 2.5, Some(40.0));
    let view = EaView::new(&vol, cam, 48, 40, None, None, [1.0; 3]).unwrap();
    for (scale, offset, want) in [
        (200.0f32, -20.0f32, Packing::U8 { offset: -20.0 }),
        (5000.0, 100.0, Packing::U16 { offset: 100.0 }),
    ] {
        let ints: Vec<f32> = blob.iter().map(|v| (v * scale).round() + offset).collect();
        assert_eq!(Packing::of(&ints), want);
        let shifted: Vec<f32> = ints.iter().map(|v| v + 0.25).collect();
        assert_eq!(Packing::of(&shifted), Packing::F32);
        let tf_at = |d: f64| Transfer {
            points: tf()
                .points
                .iter()
                .map(|&(v, c, e)| (v * scale as f64 + offset as f64 + d, c, e))
                .collect(),
            rows: vec![],
        };
        let (tf0, tf1) = (tf_at(0.0), tf_at(0.25));
        let packed = render(&gpu, &ints, &vol, &tf0, &view);
        let float = render(&gpu, &shifted, &vol, &tf1, &view);
        let seen = packed.iter().filter(|p| p[3] > 0.05).count();
        assert!(seen > 200, "{want:?}: the blob covers {seen} pixels");
        let worst = packed
            .iter()
            .zip(&float)
            .map(|(p, q)| (0..4).map(|c| (p[c] - q[c]).abs()).fold(0.0, f32::max))
            .fold(0.0, f32::max);
        assert!(worst < 1e-3, "{want:?}: differs from f32 by {worst}");
        // 1,024 samples a part: eight parts.
        let ints = Samples::pack(ints);
        assert_eq!(ints.packing(), want);
        let vi = VolumeInput {
            vol: &vol,
            data: &ints,
            tf: &tf0,
        };
        let parts = draw(
            &gpu,
            &vi,
            &view,
            Method::Ea,
            Some(4096 / want.per_word() as u64),
        )
        .unwrap();
        assert!(parts == packed, "{want:?}: the parts' image differs");
    }
}

/// The march steps over empty bricks (`empty_slabs` in `shaders/slice_pass.wgsl`) without
/// missing a sample: thin sheets and a small cube in a large empty grid (every brick in front
/// of them empty), seen from oblique, axis-aligned and clipped views, match the f64 twin,
/// which takes every slice. A step that went a few slices too far passes through a sheet.
#[test]
fn empty_bricks_are_stepped_over_without_missing_a_sample() {
    let gpu = Gpu::new().expect("a GPU adapter (CI installs mesa-vulkan-drivers for lavapipe)");
    let mut vol =
        volume::synthetic::gaussian_blob([64, 48, 40], DVec3::new(-32.0, -21.0, -24.0), 30.0);
    let dims = vol.dims;
    let mut field = vec![0.0f32; dims[0] * dims[1] * dims[2]];
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                // Sheets one voxel thick across the grid, tilted ones, and a cube.
                let sheet = i == 41 || j == 13 || (i + 2 * k) % 37 == 0;
                let cube = (20..24).contains(&i) && (30..34).contains(&j) && (18..22).contains(&k);
                if sheet || cube {
                    field[vol.index(i, j, k)] = 1.0;
                }
            }
        }
    }
    vol.fields[0].data = field;
    let data = vol.select(None).unwrap().data;
    let dense = Transfer {
        points: vec![
            (0.05, [0.9, 0.5, 0.2], 0.0),
            (0.5, [0.3, 0.7, 0.9], 0.4),
            (1.0, [0.2, 0.6, 1.0], 0.8),
        ],
        rows: vec![],
    };
    let b = vol.bounds();
    let mut shown = 0;
    for (cam, clip) in [
        (Camera::orbit(b, 40.0, 25.0, 2.5, Some(40.0)), vec![]),
        (Camera::orbit(b, -110.0, -35.0, 2.2, Some(30.0)), vec![]),
        (Camera::orbit(b, 0.0, 0.0, 2.0, None), vec![]),
        (Camera::orbit(b, 90.0, 0.0, 2.0, None), vec![]),
        (
            Camera::orbit(b, 40.0, 25.0, 2.5, Some(40.0)),
            vec![([0.6, 0.8, 0.0], 2.0)],
        ),
    ] {
        let mut view = EaView::new(&vol, cam, 64, 48, None, None, [1.0; 3]).unwrap();
        view.clip = clip;
        let gpu_img = render(&gpu, &data, &vol, &dense, &view);
        let cpu_img = reference(&data, &vol, &dense, &view);
        let mut worst = 0.0f64;
        for (g, c) in gpu_img.iter().zip(&cpu_img) {
            for k in 0..4 {
                worst = worst.max((g[k] as f64 - c[k]).abs());
            }
        }
        assert!(worst < 2e-3, "{cam:?}: GPU and CPU differ by {worst}");
        shown += cpu_img.iter().filter(|p| p[3] > 0.05).count();
        // The maximum projection steps over the same bricks: its maximum is a sheet's.
        let samples = Samples::pack(data.clone());
        let vi = VolumeInput {
            vol: &vol,
            data: &samples,
            tf: &dense,
        };
        let mip = draw(&gpu, &vi, &view, Method::Mip, None).unwrap();
        let (w, h) = (64usize, 48usize);
        let w2i = vol.affine.inverse();
        let mut worst = 0.0f64;
        for y in 0..h {
            for x in 0..w {
                let (o, d) = view.camera.ray(x as f64, y as f64, w, h);
                let e = occlusion::projection::extreme(
                    &data,
                    dims,
                    &w2i,
                    &view,
                    o,
                    d,
                    occlusion::projection::Extremum::Max,
                );
                let c = occlusion::projection::shade(&dense, e);
                let px = mip[x + w * y];
                for k in 0..3 {
                    let want = c[k] + (1.0 - c[3]) * view.background[k];
                    worst = worst.max((px[k] as f64 - want).abs());
                }
            }
        }
        assert!(worst < 2e-3, "{cam:?}: the GPU's MIP differs by {worst}");
    }
    assert!(shown > 2000, "{shown} pixels show a sheet");
}
