//! `umbra view` end to end under Xvfb (scripts/setup.sh installs it, xdotool, xwd and netpbm):
//! the window opens, shows a first image through the swapchain, a synthetic drag changes the
//! view, and the viewer ends with status 0 on SIGTERM; without a display it says so instead of
//! panicking.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn scene(dir: &std::path::Path) -> std::path::PathBuf {
    test_support::headsq_scene(dir, "", "bone", "method = \"ea\"\n")
}

/// An Xvfb server on a free display (24-bit, as Mesa's X11 swapchain needs), killed on drop;
/// the tests that use one run one at a time (the guard).
struct Xvfb(
    std::process::Child,
    String,
    #[allow(dead_code)] std::sync::MutexGuard<'static, ()>,
);

static ONE_AT_A_TIME: std::sync::Mutex<()> = std::sync::Mutex::new(());

impl Xvfb {
    fn start() -> Xvfb {
        let guard = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
        for n in (0..50).map(|i| 80 + (std::process::id() as usize + 7 * i) % 400) {
            if std::path::Path::new(&format!("/tmp/.X{n}-lock")).exists() {
                continue;
            }
            let mut child = Command::new("Xvfb")
                .args([
                    &format!(":{n}"),
                    "-screen",
                    "0",
                    "1024x768x24",
                    "-nolisten",
                    "tcp",
                ])
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .expect("Xvfb (scripts/setup.sh installs it)");
            let t = Instant::now();
            while t.elapsed() < Duration::from_secs(10) {
                if child.try_wait().unwrap().is_some() {
                    break;
                }
                if std::path::Path::new(&format!("/tmp/.X11-unix/X{n}")).exists() {
                    return Xvfb(child, format!(":{n}"), guard);
                }
                std::thread::sleep(Duration::from_millis(50));
            }
            let _ = child.kill();
            let _ = child.wait();
        }
        panic!("no Xvfb display started");
    }
}

impl Drop for Xvfb {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The screen of display `d` as RGB (width, height, bytes), through `xwd | xwdtopnm`.
fn capture(d: &str) -> (usize, usize, Vec<u8>) {
    let out = Command::new("sh")
        .args([
            "-c",
            &format!("xwd -root -silent -display {d} | xwdtopnm 2>/dev/null"),
        ])
        .output()
        .expect("xwd and xwdtopnm (scripts/setup.sh installs them)");
    let ppm = out.stdout;
    // P6 <w> <h> <max>\n<bytes>: four whitespace-separated tokens, then the samples.
    let mut fields = vec![];
    let mut i = 0;
    while fields.len() < 4 {
        while ppm[i].is_ascii_whitespace() {
            i += 1;
        }
        let start = i;
        while !ppm[i].is_ascii_whitespace() {
            i += 1;
        }
        fields.push(String::from_utf8_lossy(&ppm[start..i]).to_string());
    }
    assert_eq!(fields[0], "P6", "not a PPM capture");
    let (w, h): (usize, usize) = (fields[1].parse().unwrap(), fields[2].parse().unwrap());
    let data = ppm[i + 1..].to_vec();
    assert_eq!(data.len(), w * h * 3, "capture of {w} x {h}");
    (w, h, data)
}

#[test]
fn umbra_view_shows_a_first_image_under_xvfb_and_ends_on_sigterm() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let x = Xvfb::start();
    let (mut child, log) = start_viewer(&s, &x.1, [480, 360]);
    // The 3-D view (right of the controls) is on the screen and not uniform; a drag across it
    // changes it (a draft, then the full image).
    std::thread::sleep(Duration::from_secs(2));
    let (w, h, before) = capture(&x.1);
    let view = |img: &[u8]| -> Vec<f64> {
        let mut v = vec![];
        for y in h / 6..h * 5 / 6 {
            for xx in 300..460.min(w) {
                v.push(img[3 * (xx + w * y)] as f64);
            }
        }
        v
    };
    let a = view(&before);
    let mean = a.iter().sum::<f64>() / a.len() as f64;
    let spread = a.iter().map(|v| (v - mean).abs()).sum::<f64>() / a.len() as f64;
    assert!(
        spread > 2.0,
        "the view is uniform (mean {mean}, spread {spread})"
    );
    let xdo = |args: &[&str]| {
        let ok = Command::new("xdotool")
            .args(args)
            .env("DISPLAY", &x.1)
            .status()
            .expect("xdotool (scripts/setup.sh installs it)");
        assert!(ok.success(), "xdotool {args:?}");
    };
    xdo(&["mousemove", "380", "180"]);
    xdo(&["mousedown", "1"]);
    for _ in 0..8 {
        xdo(&["mousemove_relative", "--", "12", "4"]);
        std::thread::sleep(Duration::from_millis(40));
    }
    xdo(&["mouseup", "1"]);
    std::thread::sleep(Duration::from_secs(4));
    let (_, _, after) = capture(&x.1);
    let b = view(&after);
    let changed = a.iter().zip(&b).map(|(p, q)| (p - q).abs()).sum::<f64>() / a.len() as f64;
    assert!(
        changed > 1.0,
        "the view did not change after a drag ({changed})"
    );
    // SIGTERM ends it with status 0 within 5 s.
    let kill = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let status = ends_within_5_s(&mut child);
    let said: Vec<String> = log.try_iter().collect();
    assert!(status.success(), "status {status}: {}", said.join("\n"));
    // The frame log (--frame-log, beside the scene): its header, window frames, and the
    // drag's drafts and the full image at rest, each with its size and time.
    let frames = std::fs::read_to_string(s.with_file_name("frames.csv")).unwrap();
    let mut lines = frames.lines();
    assert_eq!(
        lines.next(),
        Some("seconds,event,level,width,height,total_ms")
    );
    let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
    assert!(rows.iter().all(|r| r.len() == 6), "{frames}");
    let count = |event: &str, level: &str| {
        rows.iter()
            .filter(|r| r[1] == event && r[2] == level)
            .count()
    };
    assert!(count("frame", "") > 10, "{frames}");
    assert!(
        count("image", "draft") >= 1 && count("image", "full") >= 1,
        "{frames}"
    );
    let t: Vec<f64> = rows.iter().map(|r| r[0].parse().unwrap()).collect();
    assert!(t.windows(2).all(|w| w[0] <= w[1]), "times in order");
    for r in rows.iter().filter(|r| r[1] == "image") {
        let (w, h, ms): (u32, u32, f64) = (
            r[3].parse().unwrap(),
            r[4].parse().unwrap(),
            r[5].parse().unwrap(),
        );
        assert!(w >= 16 && h >= 16 && ms > 0.0, "{r:?}");
    }
}

/// Starts the viewer on display `d` with a window of `size` and waits for its first image
/// (at most 90 s); its standard error's lines follow on the receiver.
fn start_viewer(
    scene: &std::path::Path,
    d: &str,
    size: [u32; 2],
) -> (std::process::Child, std::sync::mpsc::Receiver<String>) {
    let (w, h) = (size[0].to_string(), size[1].to_string());
    let frame_log = scene.with_file_name("frames.csv");
    let mut child = Command::new(env!("CARGO_BIN_EXE_umbra"))
        .args([
            "view",
            scene.to_str().unwrap(),
            "--width",
            &w,
            "--height",
            &h,
            "--frame-log",
            frame_log.to_str().unwrap(),
        ])
        .env("DISPLAY", d)
        .env("XDG_RUNTIME_DIR", std::env::temp_dir())
        .env("WINIT_X11_SCALE_FACTOR", "1")
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let err = child.stderr.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(err).lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let t = Instant::now();
    while t.elapsed() < Duration::from_secs(90) {
        if let Ok(line) = rx.recv_timeout(Duration::from_millis(200)) {
            if line.contains("first image") {
                return (child, rx);
            }
        }
        if let Some(status) = child.try_wait().unwrap() {
            panic!("the viewer ended early ({status})");
        }
    }
    let _ = child.kill();
    let _ = child.wait();
    panic!("no first image in 90 s");
}

/// The viewer's status, waiting at most 5 s.
fn ends_within_5_s(child: &mut std::process::Child) -> std::process::ExitStatus {
    let t = Instant::now();
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s;
        }
        if t.elapsed() > Duration::from_secs(5) {
            let _ = child.kill();
            panic!("the viewer did not end within 5 s");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn umbra_view_ends_with_success_when_its_window_is_destroyed_or_on_sigint() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let x = Xvfb::start();
    // Another X client destroys the window.
    let (mut child, log) = start_viewer(&s, &x.1, [400, 300]);
    let found = Command::new("xdotool")
        .args(["search", "--name", "umbra view"])
        .env("DISPLAY", &x.1)
        .output()
        .expect("xdotool (scripts/setup.sh installs it)");
    let id = String::from_utf8_lossy(&found.stdout)
        .lines()
        .next()
        .expect("the viewer's window")
        .to_string();
    let ok = Command::new("xdotool")
        .args(["windowclose", &id])
        .env("DISPLAY", &x.1)
        .status()
        .unwrap();
    assert!(ok.success());
    let status = ends_within_5_s(&mut child);
    let said: Vec<String> = log.try_iter().collect();
    assert!(
        status.success(),
        "window destroyed: {status}: {}",
        said.join("\n")
    );
    // Ctrl+C.
    let (mut child, _log) = start_viewer(&s, &x.1, [400, 300]);
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let status = ends_within_5_s(&mut child);
    assert!(status.success(), "SIGINT: {status}");
}

#[test]
fn umbra_view_without_a_display_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let out = Command::new(env!("CARGO_BIN_EXE_umbra"))
        .args(["view", s.to_str().unwrap()])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("DISPLAY"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    // A scene that does not read says so first, display or not.
    let out = Command::new(env!("CARGO_BIN_EXE_umbra"))
        .args(["view", s.to_str().unwrap(), "--set", "render.widht=10"])
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("widht") && !err.contains("DISPLAY"),
        "{err}"
    );
    // An empty DISPLAY is none (winit's text, with its source path, was printed).
    let out = Command::new(env!("CARGO_BIN_EXE_umbra"))
        .args(["view", s.to_str().unwrap()])
        .env("DISPLAY", "")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("DISPLAY is not set") && !err.contains(".rs:"),
        "{err}"
    );
    // The frame log is never the scene (it was emptied before the scene was read), and it
    // is created only once the window paints (the Xvfb test above sees it then): a viewer that
    // fails first - with no display, or past the display's check on a scene it cannot read -
    // leaves none.
    let view = |scene: &std::path::Path, log: &std::path::Path, display: Option<&str>| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_umbra"));
        c.args([
            "view",
            scene.to_str().unwrap(),
            "--frame-log",
            log.to_str().unwrap(),
        ])
        .env_remove("WAYLAND_DISPLAY");
        match display {
            Some(d) => c.env("DISPLAY", d),
            None => c.env_remove("DISPLAY"),
        };
        let out = c.output().unwrap();
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let text = std::fs::read(&s).unwrap();
    let e = view(&s, &s, None);
    assert!(
        e.contains("--frame-log") && e.contains("the same file as the input"),
        "{e}"
    );
    assert_eq!(std::fs::read(&s).unwrap(), text, "the scene was changed");
    let log = dir.path().join("logs/new/frames.csv");
    view(&s, &log, None);
    assert!(!log.exists(), "a log of a viewer that never showed");
    let missing = dir.path().join("missing.toml");
    let err = view(&missing, &log, Some(":97"));
    assert!(err.contains("missing.toml"), "{err}");
    assert!(!log.exists(), "a log of a viewer whose scene failed");
    // A window size that is no size is refused before anything opens, naming the flag.
    for bad in ["nan", "0", "-5", "1e9"] {
        let out = Command::new(env!("CARGO_BIN_EXE_umbra"))
            .args(["view", s.to_str().unwrap(), &format!("--width={bad}")])
            .output()
            .unwrap();
        assert!(!out.status.success(), "--width {bad}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains("--width") && err.contains("200..16384"),
            "{err}"
        );
    }
}
