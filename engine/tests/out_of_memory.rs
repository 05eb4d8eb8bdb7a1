//! Issue 18: running out of GPU memory is an error that names what did not fit, not an abort
//! and not a validation error about an invalid buffer. A child process (this test binary again,
//! in child mode) opens the GPU, builds a 256 MiB volume, lowers its own address-space limit to
//! what it uses + 96 MiB (`prlimit --pid`; on lavapipe the GPU's buffers are the process's
//! memory) and uploads the volume: the first 128 MiB part cannot be allocated.

use engine::gpu::{Gpu, GpuError};
use engine::renderer::Renderer;
use engine::slice_pass::{Samples, VolumeInput};
use glam::DVec3;
use occlusion::emission_absorption::Transfer;

const CHILD: &str = "UMBRA_OUT_OF_MEMORY_CHILD";

/// The address space this process has reserved (`VmSize`), bytes.
fn address_space() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let kb: u64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmSize:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .expect("VmSize in /proc/self/status");
    kb * 1024
}

fn child() {
    let gpu = Gpu::new().expect("a GPU adapter (lavapipe in CI)");
    if !gpu.is_cpu() {
        // A GPU's memory is not the process's: the limit would not reach it.
        println!("SKIPPED not a CPU adapter");
        return;
    }
    let vol = volume::synthetic::gaussian_blob([512, 512, 256], DVec3::ZERO, 100.0);
    let data = Samples::pack(vol.select(None).unwrap().data);
    let bytes = data.bytes() as u64;
    let tf = Transfer {
        points: vec![(0.1, [1.0; 3], 0.0), (0.9, [1.0; 3], 1.0)],
        rows: vec![],
    };
    let vi = VolumeInput {
        vol: &vol,
        data: &data,
        tf: &tf,
    };
    let limit = address_space() + (96 << 20);
    let set = std::process::Command::new("prlimit")
        .args([
            "--pid",
            &std::process::id().to_string(),
            &format!("--as={limit}"),
        ])
        .status()
        .expect("prlimit (util-linux)");
    assert!(set.success(), "prlimit --pid failed");
    let r = Renderer::new(&gpu).upload(Some(&vi), &[], &[], None);
    match r {
        Err(e @ GpuError::OutOfMemory { .. }) => {
            let GpuError::OutOfMemory { what, bytes: b, .. } = &e else {
                unreachable!()
            };
            assert_eq!(what, "the volume's samples");
            assert_eq!(*b, bytes);
            println!("REFUSED {e}");
        }
        Err(e) => panic!("another error than running out of memory: {e}"),
        Ok(_) => panic!("{bytes} bytes uploaded within {limit} bytes of address space"),
    }
}

#[test]
#[cfg(target_os = "linux")]
fn a_volume_past_the_memory_left_is_an_error_naming_it() {
    if std::env::var(CHILD).is_ok() {
        child();
        return;
    }
    let exe = std::env::current_exe().unwrap();
    let out = std::process::Command::new(exe)
        .args([
            "a_volume_past_the_memory_left_is_an_error_naming_it",
            "--exact",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD, "1")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(
        out.status.success(),
        "the child failed (an abort is a failure too): {text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    if text.contains("SKIPPED") {
        return;
    }
    assert!(
        text.contains("REFUSED the GPU ran out of memory for the volume's samples (256 MB)"),
        "{text}"
    );
}
