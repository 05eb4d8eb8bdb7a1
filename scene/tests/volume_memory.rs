//! Issue 18: 8 and 16-bit volumes are rendered in their stored type. A child process (this test binary
//! again, in child mode) loads a scene of the 3-D Shepp-Logan phantom (`uint16`, 320^3 = 62.5 MiB
//! stored) or of the same phantom at 8^3, uploads and draws it on each device path, and
//! reports its peak resident memory (`VmHWM`); the large scene may take at most 2.5 times the
//! volume's stored size more than the small one (the process, lavapipe and the images are the
//! same in both). Converted to f32 as before (4 bytes a voxel, twice held, plus the CPU
//! renderer's copy in f32 bricks) it took about 9 times.
//! A second test: a 16-bit volume past the adapter's bindings is halved until its f32 means
//! fit, and drawn.

use std::path::Path;

const CHILD: &str = "UMBRA_VOLUME_MEMORY_CHILD";

/// `combined` on the CPU renderer (its light volume is as small as the GPU's on this image);
/// `ea` on the GPU, whose light volume would count against the samples here.
fn scene_text(volume: &Path, device: &str) -> String {
    let method = if device == "cpu" { "combined" } else { "ea" };
    format!(
        r##"
[volume]
path = "{}"
[volume.transfer]
points = [
  {{ value = 190.0, color = "#000000", extinction = 0.0 }},
  {{ value = 215.0, color = "#d9a066", extinction = 0.4 }},
  {{ value = 290.0, color = "#ff3030", extinction = 80.0 }},
  {{ value = 1010.0, color = "#ffffff", extinction = 1.0 }},
]
[render]
method = "{method}"
device = "{device}"
width = 96
height = 96
"##,
        volume.display()
    )
}

/// Child: the scene at `volume` on `device`, drawn once; prints the peak and the image's mean
/// opacity.
fn child(volume: &Path, device: &str) {
    let dir = volume.parent().unwrap();
    let s = scene::spec::parse(&scene_text(volume, device), "test.toml", dir, &[]).unwrap();
    let gpu = engine::gpu::Gpu::new().expect("a GPU adapter (lavapipe in CI)");
    let mut m = scene::compile::model(&s).unwrap();
    let (_, samples, _) = m.volume.as_ref().unwrap();
    assert_eq!(
        samples.packing(),
        engine::slice_pass::Packing::U16 { offset: 0.0 },
        "kept in 16 bits"
    );
    let on_gpu = !scene::compile::drawn_on_cpu(&s, &m, &gpu);
    assert_eq!(on_gpu, device == "gpu");
    let up = scene::compile::upload_freeing_lines(&gpu, &mut m, on_gpu).unwrap();
    let (out, _) = up
        .draw(
            &s,
            &m,
            engine::renderer::DrawOptions {
                frames: 1,
                pass_timings: false,
            },
        )
        .unwrap();
    let alpha = out.image.iter().map(|p| p[3] as f64).sum::<f64>() / out.image.len() as f64;
    println!("PEAK {} ALPHA {alpha}", test_support::peak_resident_bytes());
}

/// Runs the child on `volume` and `device`: its peak and mean opacity.
fn run(volume: &Path, device: &str) -> (u64, f64) {
    let out = test_support::run_test_in_child(
        "sixteen_bit_volumes_render_within_their_stored_size",
        CHILD,
        &format!("{}\n{device}", volume.display()),
    );
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "child on {device}: {text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The harness prints the test's name on the same line.
    let line = text
        .split("PEAK ")
        .nth(1)
        .and_then(|t| t.lines().next())
        .unwrap_or_else(|| panic!("no peak in {text}"));
    let (peak, alpha) = line.split_once(" ALPHA ").unwrap();
    (peak.parse().unwrap(), alpha.parse().unwrap())
}

#[test]
#[cfg(target_os = "linux")]
fn sixteen_bit_volumes_render_within_their_stored_size() {
    if let Ok(args) = std::env::var(CHILD) {
        let (volume, device) = args.split_once('\n').unwrap();
        child(Path::new(volume), device);
        return;
    }
    let d = tempfile::tempdir().unwrap();
    let write = |n: usize| {
        let vol = volume::synthetic::shepp_logan(n);
        let path = d.path().join(format!("phantom{n}.nrrd"));
        volume::nrrd::write(&path, &vol, vol.default(), volume::nrrd::WriteEncoding::Raw).unwrap();
        path
    };
    let (small, big) = (write(8), write(320));
    let stored = 2 * 320u64.pow(3);
    for device in ["cpu", "gpu"] {
        let (base, _) = run(&small, device);
        let (peak, alpha) = run(&big, device);
        let growth = peak.saturating_sub(base);
        eprintln!(
            "{device}: peak {} MiB, 8^3 scene {} MiB: {:.2} x the stored {} MiB; mean opacity {alpha:.3}",
            peak >> 20,
            base >> 20,
            growth as f64 / stored as f64,
            stored >> 20
        );
        assert!(alpha > 0.05, "{device}: the phantom is drawn ({alpha})");
        assert!(
            growth as f64 <= 2.5 * stored as f64,
            "{device}: {} MiB over the small scene for a volume of {} MiB stored",
            growth >> 20,
            stored >> 20
        );
    }
}

/// A 16-bit volume past the adapter's bindings is refused unless `volume.downsample` asks for
/// it to be halved; then it is halved until its f32 means fit (the bindings lowered so that
/// all the adapter's parts hold just under 13,824 f32 samples, twice that in 16 bits): 48^3
/// halves to 24^3 (13,824 samples, which would fit as 16-bit but not as the f32 means they
/// are) and again to 12^3, and the frame is drawn.
#[test]
fn integer_volumes_past_the_bindings_are_halved_until_their_means_fit() {
    let d = tempfile::tempdir().unwrap();
    let vol = volume::synthetic::shepp_logan(48);
    let path = d.path().join("phantom48.nrrd");
    volume::nrrd::write(&path, &vol, vol.default(), volume::nrrd::WriteEncoding::Raw).unwrap();
    let text = scene_text(&path, "gpu");
    let gpu = engine::gpu::Gpu::new().expect("a GPU adapter (lavapipe in CI)");
    let parts = engine::slice_pass::volume_parts(&gpu) as u64;
    let binding = (13_823 / parts * 4) & !15;
    // Not asked for: a GPU frame is an error naming the key.
    let s = scene::spec::parse(&text, "test.toml", d.path(), &[]).unwrap();
    let m = scene::compile::model(&s).unwrap();
    gpu.limit_bindings(Some(binding));
    // The upload keeps the volume off the GPU (a CPU frame draws it whole); a GPU frame is the
    // error.
    let up = scene::compile::upload(&gpu, &m).unwrap();
    let opts = engine::renderer::DrawOptions {
        frames: 1,
        pass_timings: false,
    };
    let e = up.draw(&s, &m, opts).err();
    let mut on_cpu = s.clone();
    on_cpu.render.device = scene::spec::Device::Cpu;
    let cpu = up.draw(&on_cpu, &m, opts).map(|(out, _)| out);
    gpu.limit_bindings(None);
    let e = e.expect("refused without volume.downsample");
    assert!(
        e.contains("volume.downsample") && e.contains("48 x 48 x 48"),
        "{e}"
    );
    let cpu = cpu.expect("the CPU renderer draws it whole");
    assert!(cpu.image.iter().any(|p| p[3] > 0.05));
    let s = scene::spec::parse(
        &text,
        "test.toml",
        d.path(),
        &["volume.downsample=true".into()],
    )
    .unwrap();
    let m = scene::compile::model(&s).unwrap();
    gpu.limit_bindings(Some(binding));
    let up = scene::compile::upload(&gpu, &m);
    let drawn = up.as_ref().map(|up| {
        up.draw(
            &s,
            &m,
            engine::renderer::DrawOptions {
                frames: 1,
                pass_timings: false,
            },
        )
    });
    gpu.limit_bindings(None);
    let notes = &up.as_ref().unwrap().notes;
    assert!(
        notes.iter().any(|n| n.contains("to 12 x 12 x 12")),
        "{notes:?}"
    );
    let (out, _) = drawn.unwrap().unwrap();
    assert!(
        out.image.iter().any(|p| p[3] > 0.05),
        "the phantom is drawn"
    );
}
