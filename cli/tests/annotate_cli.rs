//! `umbra render` with annotations: the title, labels, scale bar and colour bar land where the
//! layout puts them and nowhere else, and bad annotation keys are refused naming the key.

use std::path::Path;
use std::process::Command;

fn umbra() -> Command {
    Command::new(env!("CARGO_BIN_EXE_umbra"))
}

fn render(scene: &Path, png: &Path, extra: &[&str]) -> Vec<[u8; 3]> {
    let o = umbra()
        .arg("render")
        .arg(scene)
        .arg("-o")
        .arg(png)
        .args(extra)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    image::open(png)
        .unwrap()
        .to_rgb8()
        .pixels()
        .map(|p| p.0)
        .collect()
}

#[test]
fn annotations_are_drawn_in_their_places_only() {
    let dir = tempfile::tempdir().unwrap();
    let s = test_support::headsq_scene(
        dir.path(),
        "",
        "bone",
        "method = \"ea\"\nwidth = 400\nheight = 300\n",
    );
    let plain = render(&s, &dir.path().join("plain.png"), &[]);
    let ann = render(
        &s,
        &dir.path().join("ann.png"),
        &[
            "--title",
            "Head \"CT\"",
            "--orientation",
            "--scale-bar",
            "auto",
            "--colorbar",
            "volume",
        ],
    );
    let w = 400usize;
    let changed = |x0: usize, y0: usize, x1: usize, y1: usize| {
        (y0..y1)
            .flat_map(|y| (x0..x1).map(move |x| y * w + x))
            .filter(|&i| plain[i] != ann[i])
            .count()
    };
    // Text height 300/28 = 10.7 px, margins 6.4 px.
    assert!(changed(100, 0, 300, 24) > 40, "title");
    assert!(changed(0, 130, 24, 170) > 10, "left label");
    assert!(changed(376, 130, 400, 170) > 10, "right label");
    assert!(changed(0, 250, 130, 300) > 40, "scale bar");
    assert!(changed(270, 250, 400, 300) > 300, "colour bar");
    // The middle of the image (the head) is untouched.
    assert_eq!(changed(120, 60, 280, 240), 0);
    // Bad keys are refused, naming them.
    for (set, key) in [
        ("annotate.colorbar=\"tubes.0\"", "annotate.colorbar"),
        ("annotate.scale_bar=-3", "annotate.scale_bar"),
        ("annotate.scale_bar=\"big\"", "annotate.scale_bar"),
        ("annotate.colour=true", "colour"),
    ] {
        let o = umbra()
            .arg("render")
            .arg(&s)
            .arg("-o")
            .arg(dir.path().join("bad.png"))
            .args(["--set", set])
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(1), "{set}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(err.contains(key), "{set}: {err}");
    }
}

/// The illustrative method draws points, lines and tubes in one ink: a bar of their colouring
/// is refused before anything is drawn; another method draws it.
#[test]
fn a_bar_of_a_colouring_the_illustrative_method_does_not_draw_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("p.csv"),
        "x,y,z,temp\n0,0,0,1\n1,0,0,2\n0,1,0,3\n0,0,1,4\n",
    )
    .unwrap();
    let s = dir.path().join("s.toml");
    std::fs::write(
        &s,
        "[[points]]\npath = \"p.csv\"\ncolor = \"scalar:temp\"\n[annotate]\ncolorbar = \"points.0\"\n\
         [render]\nwidth = 64\nheight = 48\n",
    )
    .unwrap();
    render(&s, &dir.path().join("ok.png"), &[]);
    let png = dir.path().join("ink.png");
    let o = umbra()
        .arg("render")
        .arg(&s)
        .arg("-o")
        .arg(&png)
        .args(["--set", "render.method=\"illustrative\""])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("s.toml") && err.contains("points.0") && err.contains("illustrative"),
        "{err}"
    );
    assert!(!png.exists());
}
