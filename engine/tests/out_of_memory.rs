//! Issue 18: running out of GPU memory is an error that names what did not fit, not an abort
//! and not a validation error about an invalid buffer. A child process (this test binary again,
//! in child mode) opens the GPU, builds a 256 MiB volume (or a tube mesh of 96 MB of
//! vertices), lowers its own address-space limit to what it uses + a little (`prlimit --pid`;
//! on lavapipe the GPU's buffers are the process's memory) and uploads it: the volume's first
//! 128 MiB part (the mesh's vertex buffer) cannot be allocated. The mesh's buffers were
//! created mapped (`create_buffer_init`), which panicked when the allocation failed.

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

/// Lowers this process's address-space limit to what it has reserved + `headroom` bytes.
fn limit_to(headroom: u64) -> u64 {
    let limit = address_space() + headroom;
    let set = std::process::Command::new("prlimit")
        .args([
            "--pid",
            &std::process::id().to_string(),
            &format!("--as={limit}"),
        ])
        .status()
        .expect("prlimit (util-linux)");
    assert!(set.success(), "prlimit --pid failed");
    limit
}

fn child(what: &str) {
    let gpu = Gpu::new().expect("a GPU adapter (lavapipe in CI)");
    if !gpu.is_cpu() {
        // A GPU's memory is not the process's: the limit would not reach it.
        println!("SKIPPED not a CPU adapter");
        return;
    }
    let (r, name, bytes) = if what == "volume" {
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
        limit_to(96 << 20);
        let r = Renderer::new(&gpu).upload(Some(&vi), &[], &[], None);
        (r.map(|_| ()), "the volume's samples", bytes)
    } else {
        // 3.4 M vertices (28 bytes each on the GPU, 96 MB), one triangle.
        let n = 3_400_000;
        let mesh = tubes::tube_mesh::TubeMesh {
            positions: vec![glam::Vec3::ONE; n],
            normals: vec![glam::Vec3::Z; n],
            colors: vec![[9, 9, 9]; n],
            indices: vec![0, 1, 2],
            ..Default::default()
        };
        // Room for the upload's CPU copy of the vertices, not for the GPU's.
        limit_to((n as u64 * 28) + (48 << 20));
        let r = Renderer::new(&gpu).upload(None, std::slice::from_ref(&mesh), &[], None);
        (r.map(|_| ()), "tube mesh 0", n as u64 * 28 + 12)
    };
    match r {
        Err(e @ GpuError::OutOfMemory { .. }) => {
            let GpuError::OutOfMemory { what, bytes: b, .. } = &e else {
                unreachable!()
            };
            assert_eq!(what, name);
            assert_eq!(*b, bytes);
            println!("REFUSED {e}");
        }
        Err(e) => panic!("another error than running out of memory: {e}"),
        Ok(()) => panic!("{bytes} bytes of {name} uploaded"),
    }
}

#[test]
#[cfg(target_os = "linux")]
fn a_volume_or_mesh_past_the_memory_left_is_an_error_naming_it() {
    if let Ok(what) = std::env::var(CHILD) {
        child(&what);
        return;
    }
    for (what, want) in [
        (
            "volume",
            "REFUSED the GPU ran out of memory for the volume's samples (256 MB)",
        ),
        (
            "mesh",
            "REFUSED the GPU ran out of memory for tube mesh 0 (90 MB)",
        ),
    ] {
        let out = test_support::run_test_in_child(
            "a_volume_or_mesh_past_the_memory_left_is_an_error_naming_it",
            CHILD,
            what,
        );
        let text = String::from_utf8_lossy(&out.stdout).to_string();
        assert!(
            out.status.success(),
            "{what}: the child failed (an abort is a failure too): {text}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        if text.contains("SKIPPED") {
            return;
        }
        assert!(text.contains(want), "{what}: {text}");
    }
}
