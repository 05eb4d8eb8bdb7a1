//! Issue 18: a tractogram of 10^7 points round-trips through `.tck` with bounded memory. The
//! file is written streaming (`tck::write_with`, from `tubes::synthetic`), then a child
//! process (this test binary again, in child mode) reads it and writes it back; the child's
//! peak resident memory (`VmHWM` of /proc/self/status) must stay within the points it holds
//! (12 bytes each) plus a fixed allowance - reading the whole file first, as the reader did
//! before, needed twice that.

use std::io::Read;
use std::path::Path;

const CHILD: &str = "UMBRA_SCALE_CHILD";

/// 10^5 streamlines of 100 points.
fn bundles() -> tubes::synthetic::Bundles {
    tubes::synthetic::Bundles {
        count: 100_000,
        points: 100,
        ..Default::default()
    }
}

fn same_bytes(a: &Path, b: &Path) -> bool {
    let (mut fa, mut fb) = (
        std::fs::File::open(a).unwrap(),
        std::fs::File::open(b).unwrap(),
    );
    let (mut ba, mut bb) = (vec![0u8; 1 << 20], vec![0u8; 1 << 20]);
    loop {
        let na = fa.read(&mut ba).unwrap();
        let mut nb = 0;
        while nb < na {
            let k = fb.read(&mut bb[nb..na]).unwrap();
            if k == 0 {
                return false;
            }
            nb += k;
        }
        if ba[..na] != bb[..na] {
            return false;
        }
        if na == 0 {
            return fb.read(&mut bb).unwrap() == 0;
        }
    }
}

#[test]
#[cfg(target_os = "linux")]
fn ten_million_points_round_trip_with_bounded_memory() {
    if let Ok(paths) = std::env::var(CHILD) {
        // Child: read, check, write back, report the peak.
        let (input, output) = paths.split_once('\n').unwrap();
        let s = tubes::tck::read(Path::new(input)).unwrap();
        let b = bundles();
        assert_eq!(s.len(), b.count);
        assert_eq!(s.points.len() as u64, b.total_points());
        let mut line = Vec::new();
        for i in [0, 777, b.count - 1] {
            b.line(i, &mut line);
            assert_eq!(s.line(i), &line[..], "streamline {i}");
        }
        tubes::tck::write(Path::new(output), &s).unwrap();
        println!("PEAK {}", test_support::peak_resident_bytes());
        return;
    }
    let d = tempfile::tempdir().unwrap();
    let (input, output) = (d.path().join("big.tck"), d.path().join("back.tck"));
    let b = bundles();
    tubes::tck::write_with(&input, b.count, |i, out| b.line(i, out)).unwrap();
    // Header, 12 bytes a point, a NaN triplet a streamline, the Inf triplet.
    let len = std::fs::metadata(&input).unwrap().len();
    let data = 12 * (b.total_points() + b.count as u64 + 1);
    assert!(len > data && len < data + 200, "{len}");
    // The writer holds one streamline at a time.
    assert!(
        test_support::peak_resident_bytes() < len,
        "writing held the file"
    );

    let out = test_support::run_test_in_child(
        "ten_million_points_round_trip_with_bounded_memory",
        CHILD,
        &format!("{}\n{}", input.display(), output.display()),
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "child failed: {stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let peak: u64 = stdout
        .lines()
        .find_map(|l| l.split("PEAK ").nth(1))
        .and_then(|v| v.split_whitespace().next()?.parse().ok())
        .unwrap_or_else(|| panic!("no peak reported: {stdout}"));
    // The points (12 bytes each) and offsets (8 a streamline) are held once; 48 MiB cover the
    // test binary, its libraries and the 1 MiB read and write buffers. Reading the whole
    // file before parsing it needs another 121 MB.
    let held = 12 * b.total_points() + 8 * b.count as u64;
    let allowance = 48 << 20;
    assert!(
        peak <= held + allowance,
        "peak {} MB, more than the {} MB of points and offsets + {} MB",
        peak >> 20,
        held >> 20,
        allowance >> 20
    );
    assert!(same_bytes(&input, &output), "the file written back differs");
}
