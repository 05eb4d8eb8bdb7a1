//! Helpers for umbra's integration tests (`volume/tests/`, `tubes/tests/`, and the cross-crate
//! tests in `tests/tests/`).

use std::path::PathBuf;

/// The workspace root (this crate lives in `tests/support/`, two levels below it).
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .and_then(|p| p.parent())
        .unwrap()
        .to_path_buf()
}

/// Writes `<dir>/s.toml`: the bundled headsq volume (`datasets/vtk/headsq_64x64x93.nhdr`, 64 x
/// 64 x 93, 3.2 x 3.2 x 1.5 mm) through the transfer preset `preset` (extinction 0.05 per
/// world unit), after `head` (top-level keys, `[camera]`, `[[clip]]`) and with `render` (the
/// `[render]` keys, the method among them). The renderers' small real-data scene.
pub fn headsq_scene(dir: &std::path::Path, head: &str, preset: &str, render: &str) -> PathBuf {
    let scene = dir.join("s.toml");
    std::fs::write(
        &scene,
        format!(
            "{head}[volume]\npath = \"{}\"\n[volume.transfer]\npreset = \"{preset}\"\nextinction = 0.05\n[render]\n{render}",
            root().join("datasets/vtk/headsq_64x64x93.nhdr").display()
        ),
    )
    .unwrap();
    scene
}

/// Reader fixtures written by `tests/fixtures/make_fixtures.py` with reference libraries.
pub fn fixtures() -> PathBuf {
    root().join("tests").join("fixtures")
}

/// `../shared/data` beside the checkout (or `$UMBRA_SHARED_DATA`), when present.
pub fn shared_data() -> Option<PathBuf> {
    if let Ok(p) = std::env::var("UMBRA_SHARED_DATA") {
        let p = PathBuf::from(p);
        return p.is_dir().then_some(p);
    }
    let p = root().parent()?.join("shared").join("data");
    p.is_dir().then_some(p)
}

/// Returns the shared data folder, or prints why a test skips and returns `None`.
pub fn shared_or_skip(test: &str) -> Option<PathBuf> {
    let p = shared_data();
    if p.is_none() {
        eprintln!("SKIP {test}: ../shared/data is absent (set UMBRA_SHARED_DATA to run it)");
    }
    p
}

/// Relative closeness with an absolute floor.
pub fn close(a: f64, b: f64, rel: f64, abs: f64) -> bool {
    (a - b).abs() <= abs.max(rel * a.abs().max(b.abs()))
}

/// This process's peak resident memory in bytes (`VmHWM` of /proc/self/status, Linux): what
/// the memory tests' child processes report.
pub fn peak_resident_bytes() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("/proc/self/status");
    let line = status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))
        .expect("VmHWM in /proc/self/status");
    let kb: u64 = line
        .split_whitespace()
        .nth(1)
        .and_then(|v| v.parse().ok())
        .expect("VmHWM in kB");
    kb * 1024
}

/// Runs the test `name` of the calling test binary alone, in a child process of its own
/// (`--exact --nocapture --test-threads=1`), with the environment variable `var` set to
/// `value`, and returns its status and output. Tests that need a process to themselves (an
/// address-space limit, a peak resident size) run their measuring half this way.
pub fn run_test_in_child(name: &str, var: &str, value: &str) -> std::process::Output {
    let exe = std::env::current_exe().expect("the test binary's path");
    std::process::Command::new(exe)
        .args([name, "--exact", "--nocapture", "--test-threads=1"])
        .env(var, value)
        .output()
        .expect("starting the test binary again")
}

/// Asserts that a command (the `umbra` binary, usually) succeeded, with its standard error as
/// the failure's message, and returns that standard error (notes, progress).
pub fn succeeded(out: &std::process::Output) -> String {
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{err}");
    err
}
