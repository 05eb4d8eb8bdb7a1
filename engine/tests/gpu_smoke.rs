//! The GPU smoke path on whatever adapter this machine has (lavapipe in CI): one compute
//! dispatch and one multisampled render pass, read back and checked inside `smoke::run`; here
//! we check the report and the MSAA fallback rule.

use engine::gpu::{choose_sample_count, supported_sample_counts, Gpu};

#[test]
fn compute_and_render_read_back_correctly() {
    let gpu = Gpu::new().expect("a GPU adapter (CI installs mesa-vulkan-drivers for lavapipe)");
    let report = gpu.report();
    assert!(report.max_texture_3d >= 256, "{report}");
    let smoke = engine::smoke::run(&gpu, 8).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(smoke.compute_values_checked, 1000);
    assert!(smoke.sample_count >= 1 && smoke.sample_count <= 8);
    let supported = supported_sample_counts(&gpu.adapter, wgpu::TextureFormat::Rgba8Unorm);
    assert!(supported.contains(&smoke.sample_count));
    // The note appears exactly when the request was lowered.
    assert_eq!(smoke.msaa_note.is_some(), smoke.sample_count != 8);
    // One sample is always accepted, and a request is never raised.
    assert_eq!(
        choose_sample_count(&gpu.adapter, wgpu::TextureFormat::Rgba8Unorm, 1),
        (1, None)
    );
    let (n, _) = choose_sample_count(&gpu.adapter, wgpu::TextureFormat::Rgba8Unorm, 3);
    assert!(n <= 3 && supported.contains(&n));
}
