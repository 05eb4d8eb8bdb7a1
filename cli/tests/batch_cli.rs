//! `umbra render` on clusters, end to end: shards of an orbit cover every frame once and give
//! the frames one process gives, Slurm job-array variables give the partition `--shard`
//! gives, a rerun after a killed run renders only what is missing, a failing frame is recorded
//! while the others render, manifests name their outputs, `--adapter` picks or refuses.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn umbra() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_umbra"));
    // The tests choose their own shards.
    for v in scene::batch::SLURM_VARIABLES {
        c.env_remove(v);
    }
    c
}

use test_support::succeeded as ok;

/// A small, quick scene: the CT head, emission-absorption, 64 x 48.
fn scene(dir: &Path) -> PathBuf {
    test_support::headsq_scene(
        dir,
        "",
        "bone",
        "method = \"ea\"\nwidth = 64\nheight = 48\n",
    )
}

fn record(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The `index` of every entry of a record's list.
fn indices(r: &serde_json::Value, list: &str) -> Vec<usize> {
    r[list]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["index"].as_u64().unwrap() as usize)
        .collect()
}

fn pixels(p: &Path) -> Vec<u8> {
    image::open(p).unwrap().to_rgb8().into_raw()
}

/// An orbit of `n` frames into `pattern`, with extra arguments; its output.
fn orbit(s: &Path, n: u32, pattern: &Path, extra: &[&str]) -> Output {
    umbra()
        .arg("render")
        .arg(s)
        .args(["--orbit", &n.to_string(), "-o"])
        .arg(pattern)
        .args(extra)
        .output()
        .unwrap()
}

#[test]
fn shards_of_an_orbit_render_every_frame_once_and_as_one_process_does() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let one = dir.path().join("one/f_##.png");
    ok(&orbit(&s, 10, &one, &[]));
    let frame = |pattern: &Path, k: usize| {
        PathBuf::from(pattern.to_string_lossy().replace("##", &format!("{k:02}")))
    };
    for n in [1u32, 2, 3, 7] {
        let pattern = dir.path().join(format!("n{n}/f_##.png"));
        let mut seen = vec![0; 10];
        for i in 0..n {
            let rec = dir.path().join(format!("n{n}/record_{i}.json"));
            let err = ok(&orbit(
                &s,
                10,
                &pattern,
                &[
                    "--shard",
                    &format!("{i}/{n}"),
                    "--record",
                    rec.to_str().unwrap(),
                ],
            ));
            let r = record(&rec);
            let done = indices(&r, "done");
            // Shard i renders k = i, i + n, ...
            assert_eq!(
                done,
                (i as usize..10).step_by(n as usize).collect::<Vec<_>>()
            );
            assert_eq!(r["frames"].as_u64().unwrap() as usize, done.len());
            assert_eq!(r["shard"]["index"], i);
            assert_eq!(r["shard"]["count"], n);
            assert_eq!(r["shard_from"], "flag");
            // A plain line per frame in the log.
            for k in &done {
                assert!(err.contains(&format!("frame {k}: ")), "{err}");
                seen[*k] += 1;
            }
        }
        assert!(seen.iter().all(|&c| c == 1), "{n} shards: {seen:?}");
        let files = std::fs::read_dir(dir.path().join(format!("n{n}")))
            .unwrap()
            .filter(|e| e.as_ref().unwrap().path().extension().unwrap() == "png")
            .count();
        assert_eq!(files, 10);
        for k in 0..10 {
            let (a, b) = (pixels(&frame(&pattern, k)), pixels(&frame(&one, k)));
            let max = a.iter().zip(&b).map(|(x, y)| x.abs_diff(*y)).max().unwrap();
            assert!(max <= 1, "{n} shards, frame {k}: differs by {max}/255");
        }
    }
}

#[test]
fn slurm_array_variables_give_the_partition_the_flag_gives() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    // --array=1-3: tasks 1, 2, 3 are shards 0, 1, 2 of 3.
    for task in 1..=3u32 {
        let rec = dir.path().join(format!("slurm_{task}.json"));
        let out = umbra()
            .arg("render")
            .arg(&s)
            .args(["--orbit", "10", "-o"])
            .arg(dir.path().join("slurm/f_##.png"))
            .arg("--record")
            .arg(&rec)
            .env("SLURM_ARRAY_TASK_ID", task.to_string())
            .env("SLURM_ARRAY_TASK_MIN", "1")
            .env("SLURM_ARRAY_TASK_MAX", "3")
            .env("SLURM_ARRAY_TASK_COUNT", "3")
            .env("SLURM_ARRAY_TASK_STEP", "1")
            .output()
            .unwrap();
        ok(&out);
        let flag = dir.path().join(format!("flag_{task}.json"));
        ok(&orbit(
            &s,
            10,
            &dir.path().join("flag/f_##.png"),
            &[
                "--shard",
                &format!("{}/3", task - 1),
                "--record",
                flag.to_str().unwrap(),
            ],
        ));
        let (r, f) = (record(&rec), record(&flag));
        assert_eq!(r["shard_from"], "slurm");
        assert_eq!(r["shard"], f["shard"]);
        assert_eq!(indices(&r, "done"), indices(&f, "done"));
    }
    // One image in an array task is the task's own image, not a shard of one frame.
    let single = dir.path().join("task_2.png");
    ok(&umbra()
        .arg("render")
        .arg(&s)
        .arg("-o")
        .arg(&single)
        .env("SLURM_ARRAY_TASK_ID", "2")
        .env("SLURM_ARRAY_TASK_MIN", "1")
        .env("SLURM_ARRAY_TASK_COUNT", "3")
        .output()
        .unwrap());
    assert!(single.exists());
    // ... even in an array whose task ids are not evenly spaced (--array=1,4,9).
    let single = dir.path().join("task_4.png");
    ok(&umbra()
        .arg("render")
        .arg(&s)
        .arg("-o")
        .arg(&single)
        .env("SLURM_ARRAY_TASK_ID", "4")
        .env("SLURM_ARRAY_TASK_MIN", "1")
        .env("SLURM_ARRAY_TASK_MAX", "9")
        .env("SLURM_ARRAY_TASK_COUNT", "3")
        .output()
        .unwrap());
    assert!(single.exists());
    // A sparse array is refused, naming the variables.
    let out = umbra()
        .arg("render")
        .arg(&s)
        .args(["--orbit", "10", "-o"])
        .arg(dir.path().join("sparse/f_##.png"))
        .env("SLURM_ARRAY_TASK_ID", "9")
        .env("SLURM_ARRAY_TASK_MIN", "1")
        .env("SLURM_ARRAY_TASK_COUNT", "3")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("SLURM_ARRAY_TASK_ID=9") && err.contains("I/N"),
        "{err}"
    );
    assert!(!dir.path().join("sparse").exists());
}

#[test]
fn a_rerun_after_a_killed_run_renders_only_what_is_missing() {
    let dir = tempfile::tempdir().unwrap();
    // Slower frames (the occlusion sweep at 192 x 144), so that the kill lands mid-sequence.
    let s = test_support::headsq_scene(
        dir.path(),
        "",
        "bone",
        "method = \"dos\"\nwidth = 192\nheight = 144\n",
    );
    let pattern = dir.path().join("out/f_##.png");
    let frame = |k: usize| dir.path().join(format!("out/f_{k:02}.png"));
    let mut child = spawned_until(
        umbra()
            .arg("render")
            .arg(&s)
            .args(["--orbit", "10", "-o"])
            .arg(&pattern),
        &frame(1),
    );
    child.kill().unwrap();
    child.wait().unwrap();
    let existed: BTreeSet<usize> = (0..10).filter(|&k| frame(k).exists()).collect();
    assert!(
        existed.contains(&1),
        "the first frames were written before the kill"
    );
    // What a killed writer leaves, and a frame cut short (e.g. a copy interrupted).
    std::fs::write(dir.path().join("out/.f_09.png.999999999.tmp"), b"partial").unwrap();
    let cut = *existed.iter().next().unwrap();
    let bytes = std::fs::read(frame(cut)).unwrap();
    std::fs::write(frame(cut), &bytes[..bytes.len() / 3]).unwrap();
    let kept: BTreeSet<usize> = existed.iter().copied().filter(|&k| k != cut).collect();
    let stamps: Vec<_> = kept
        .iter()
        .map(|&k| std::fs::metadata(frame(k)).unwrap().modified().unwrap())
        .collect();
    let rec = dir.path().join("rerun.json");
    ok(&orbit(
        &s,
        10,
        &pattern,
        &["--skip-existing", "--record", rec.to_str().unwrap()],
    ));
    let r = record(&rec);
    let skipped: BTreeSet<usize> = indices(&r, "skipped").into_iter().collect();
    let done: BTreeSet<usize> = indices(&r, "done").into_iter().collect();
    assert_eq!(skipped, kept, "only complete frames are kept");
    assert_eq!(
        done,
        (0..10)
            .filter(|k| !kept.contains(k))
            .collect::<BTreeSet<_>>()
    );
    for (k, t) in kept.iter().zip(stamps) {
        assert_eq!(
            std::fs::metadata(frame(*k)).unwrap().modified().unwrap(),
            t,
            "frame {k} was rewritten"
        );
    }
    assert!(
        image::open(frame(cut)).is_ok(),
        "the cut frame is whole again"
    );
    let left: Vec<_> = std::fs::read_dir(dir.path().join("out"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(left.is_empty(), "stale temporary files: {left:?}");
    // Nothing left to do: the scene is not even read again, and nothing is rendered.
    let again = dir.path().join("again.json");
    ok(&orbit(
        &s,
        10,
        &pattern,
        &["--shard", "0/1", "--record", again.to_str().unwrap()],
    ));
    let r = record(&again);
    assert_eq!(indices(&r, "skipped").len(), 10);
    assert!(indices(&r, "done").is_empty());
}

/// A resubmitted shard whose frames are all complete leaves the timings of the run that
/// rendered them (it wrote zeros over them, found by a new user), and a run asking for AOVs
/// renders again the EXRs written without them (they were kept as complete).
#[test]
fn a_rerun_keeps_the_timings_and_renders_exrs_again_for_their_aovs() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let pattern = dir.path().join("o/f_#.exr");
    let timings = dir.path().join("t.json");
    let t = ["--timings-json", timings.to_str().unwrap()];
    ok(&orbit(&s, 2, &pattern, &t));
    let first = std::fs::read_to_string(&timings).unwrap();
    let j: serde_json::Value = serde_json::from_str(&first).unwrap();
    assert!(j["total_ms"].as_f64().unwrap() > 0.0, "{first}");
    let out = orbit(&s, 2, &pattern, &[&t[..], &["--skip-existing"]].concat());
    ok(&out);
    assert_eq!(std::fs::read_to_string(&timings).unwrap(), first);
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("is left as it was"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // With --aov the frames without AOVs are not complete: both rendered again, with Z;
    // then complete.
    let rec = dir.path().join("r.json");
    let aov = [
        "--aov",
        "--skip-existing",
        "--record",
        rec.to_str().unwrap(),
    ];
    for list in ["done", "skipped"] {
        ok(&orbit(&s, 2, &pattern, &aov));
        assert_eq!(indices(&record(&rec), list), [0, 1], "{list}");
        assert!(scene::batch::complete_image(
            &dir.path().join("o/f_0.exr"),
            64,
            48,
            &["Z", "occlusion.combined"]
        ));
    }
}

#[test]
fn a_failing_frame_is_recorded_and_the_others_still_render() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    // Frame 4's output is a folder: its write fails.
    std::fs::create_dir_all(dir.path().join("out/f_04.png")).unwrap();
    let rec = dir.path().join("r.json");
    let out = orbit(
        &s,
        6,
        &dir.path().join("out/f_##.png"),
        &["--record", rec.to_str().unwrap()],
    );
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("1 of 6 frames failed") && err.contains("f_04.png"),
        "{err}"
    );
    let r = record(&rec);
    assert_eq!(indices(&r, "done"), [0, 1, 2, 3, 5]);
    assert_eq!(indices(&r, "failed"), [4]);
    assert!(r["failed"][0]["error"]
        .as_str()
        .unwrap()
        .contains("f_04.png"));
    for k in [0, 1, 2, 3, 5] {
        assert!(dir.path().join(format!("out/f_{k:02}.png")).is_file());
    }
    // What fails before any frame (here the scene) is in the record too.
    let rec = dir.path().join("setup.json");
    let out = orbit(
        &dir.path().join("missing.toml"),
        6,
        &dir.path().join("out2/f_##.png"),
        &["--shard", "1/2", "--record", rec.to_str().unwrap()],
    );
    assert_eq!(out.status.code(), Some(1));
    let r = record(&rec);
    assert!(r["error"].as_str().unwrap().contains("missing.toml"), "{r}");
    assert_eq!(r["shard"]["index"], 1);
    assert!(indices(&r, "done").is_empty());
    // Before the shard is known (bad Slurm variables), the shard is null.
    let out = umbra()
        .arg("render")
        .arg(&s)
        .args(["--orbit", "6", "-o"])
        .arg(dir.path().join("out3/f_##.png"))
        .arg("--record")
        .arg(&rec)
        .env("SLURM_ARRAY_TASK_ID", "x")
        .env("SLURM_ARRAY_TASK_MIN", "0")
        .env("SLURM_ARRAY_TASK_COUNT", "3")
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let r = record(&rec);
    assert!(
        r["shard"].is_null() && r["error"].as_str().unwrap().contains("SLURM_ARRAY_TASK_ID"),
        "{r}"
    );
}

#[test]
fn manifests_render_one_named_scene_per_line_sharded_the_same_way() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    std::fs::create_dir_all(dir.path().join("study")).unwrap();
    // sub-02 has its own scene file, beside the manifest.
    std::fs::copy(&s, dir.path().join("study/sub-02.toml")).unwrap();
    let manifest = dir.path().join("study/subjects.txt");
    std::fs::write(
        &manifest,
        "# participant  scene  overrides\n\
         sub-01 camera.azimuth=0\n\
         sub-02 sub-02.toml camera.azimuth=90\n\
         sub-03 missing.toml\n\
         sub-04 camera.azimuth=180 'render.method=\"ea\"'\n\
         \n\
         sub-05 camera.azimuth=270\n",
    )
    .unwrap();
    let pattern = dir.path().join("out/{name}/{name}_t1.png");
    let mut done = BTreeSet::new();
    let mut failed = vec![];
    for i in 0..2 {
        let rec = dir.path().join(format!("m{i}.json"));
        let out = umbra()
            .arg("render")
            .arg(&s)
            .arg("--manifest")
            .arg(&manifest)
            .arg("-o")
            .arg(&pattern)
            .args([
                "--shard",
                &format!("{i}/2"),
                "--record",
                rec.to_str().unwrap(),
            ])
            .output()
            .unwrap();
        let r = record(&rec);
        for f in r["done"].as_array().unwrap() {
            let name = f["name"].as_str().unwrap().to_string();
            assert_eq!(
                Path::new(f["path"].as_str().unwrap()),
                dir.path().join(format!("out/{name}/{name}_t1.png"))
            );
            done.insert(name);
        }
        for f in r["failed"].as_array().unwrap() {
            failed.push((
                i,
                f["name"].as_str().unwrap().to_string(),
                f["error"].as_str().unwrap().to_string(),
            ));
        }
        // Entry k (from 0, over the entries) is shard k mod 2's.
        assert!(indices(&r, "done")
            .iter()
            .chain(&indices(&r, "failed"))
            .all(|k| k % 2 == i));
        let err = String::from_utf8_lossy(&out.stderr);
        for f in r["done"].as_array().unwrap() {
            let line = format!("frame {} {}: ", f["index"], f["name"].as_str().unwrap());
            assert!(err.contains(&line), "{line} in {err}");
        }
        assert!(err.contains(&format!("shard {i}/2: ")), "{err}");
        // The shard with the missing scene exits 1, after the others were done.
        assert_eq!(
            out.status.success(),
            i == 1,
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    assert_eq!(
        done,
        ["sub-01", "sub-02", "sub-04", "sub-05"]
            .map(String::from)
            .into()
    );
    assert_eq!(failed.len(), 1);
    let (shard, name, error) = &failed[0];
    assert_eq!((*shard, name.as_str()), (0, "sub-03"));
    assert!(
        error.contains("subjects.txt: line 4") && error.contains("missing.toml"),
        "{error}"
    );
    // The overrides took effect: each subject's camera turned.
    let img = |n: &str| pixels(&dir.path().join(format!("out/{n}/{n}_t1.png")));
    assert_ne!(img("sub-01"), img("sub-02"));
    assert_ne!(img("sub-04"), img("sub-05"));
    // Without {name} every line would write one file: refused before any work.
    let out = umbra()
        .arg("render")
        .arg(&s)
        .arg("--manifest")
        .arg(&manifest)
        .arg("-o")
        .arg(dir.path().join("one.png"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("{name}"));
    assert!(!dir.path().join("one.png").exists());
    // A line whose scene does not parse: its FAILED line in the log holds the cause on one
    // line (the TOML parser's quote of the line and its marks spanned four more).
    std::fs::write(dir.path().join("study/broken.toml"), "[volume\n").unwrap();
    let bad = dir.path().join("study/bad.txt");
    std::fs::write(&bad, "sub-01\nsub-06 broken.toml\n").unwrap();
    let out = umbra()
        .arg("render")
        .arg(&s)
        .arg("--manifest")
        .arg(&bad)
        .arg("-o")
        .arg(&pattern)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    let line = err
        .lines()
        .find(|l| l.contains("FAILED"))
        .unwrap_or_default();
    assert!(
        line.contains("sub-06") && line.contains("broken.toml") && line.contains("unclosed table"),
        "{err}"
    );
}

#[test]
fn the_adapter_is_chosen_by_index_or_refused_naming_the_adapters() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let list = umbra()
        .args(["info", "--adapters", "--json"])
        .output()
        .unwrap();
    ok(&list);
    let adapters: serde_json::Value = serde_json::from_slice(&list.stdout).unwrap();
    let first = adapters[0]["name"].as_str().unwrap().to_string();
    let out = umbra()
        .arg("render")
        .arg(&s)
        .args(["--adapter", "0", "--json", "-o"])
        .arg(dir.path().join("a.png"))
        .output()
        .unwrap();
    ok(&out);
    let r: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(r["adapter"], first.as_str());
    let out = umbra()
        .arg("render")
        .arg(&s)
        .args(["--adapter", "0000:fe:1f.7", "-o"])
        .arg(dir.path().join("b.png"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("PCI bus id 0000:fe:1f.7 matches no adapter")
            && err.contains(&first)
            && !err.contains("mesa-vulkan-drivers"),
        "{err}"
    );
    assert!(!dir.path().join("b.png").exists());
}

#[test]
fn a_gpu_command_without_xdg_runtime_dir_prints_no_error_line() {
    // Slurm jobs and containers often have no XDG_RUNTIME_DIR; Mesa's device-select layer then
    // printed "error: XDG_RUNTIME_DIR is invalid or not set" twice, on success.
    let out = umbra()
        .args(["info", "--adapters"])
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("NODEVICE_SELECT")
        .env_remove("MESA_VK_DEVICE_SELECT")
        .output()
        .unwrap();
    let err = ok(&out);
    assert!(!err.contains("XDG_RUNTIME_DIR"), "{err}");
    assert!(!String::from_utf8_lossy(&out.stdout).is_empty());
}

/// Records and checks of a batch task that fails early: a command line that does not parse
/// (its record still written, exit 1 for a bad value, negative counts included), a record
/// folder made before bad Slurm variables fail, a record path ending in `/` and an output
/// folder blocked by a file refused before any frame, and the scene's data failing after
/// complete frames were skipped (those stay `skipped`, the rest `failed`; the temporary file
/// a killed run left beside a complete frame removed).
#[test]
fn a_task_that_fails_early_leaves_its_record_and_renders_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(d);
    let run = |args: &[&str]| {
        umbra()
            .arg("render")
            .arg(&s)
            .args(args)
            .current_dir(d)
            .output()
            .unwrap()
    };
    let err = |o: &Output| String::from_utf8_lossy(&o.stderr).into_owned();
    // Values the parser refuses: exit 1, and the record says why.
    for (i, (bad, flag)) in [
        (&["--orbit", "3", "--method", "foo"][..], "--method"),
        (&["--orbit", "-1"], "--orbit"),
        (&["--orbit", "3", "--frames", "-2"], "--frames"),
        (&["--orbit=0"], "--orbit"),
        // A negative shard is a bad shard, written with or without `=` (the first exited 2).
        (&["--orbit", "3", "--shard", "-1/2"], "-1/2"),
        (&["--orbit", "3", "--shard=-1/2"], "-1/2"),
    ]
    .into_iter()
    .enumerate()
    {
        let rec = format!("p{i}/r.json");
        let mut args = vec!["-o", "o/f_#.png", "--record", &rec];
        args.extend_from_slice(bad);
        let o = run(&args);
        assert_eq!(o.status.code(), Some(1), "{bad:?}: {}", err(&o));
        let r = record(&d.join(&rec));
        assert!(r["error"].as_str().unwrap().contains(flag), "{r}");
        assert!(r["shard"].is_null(), "{r}");
        // The count the command line gives (it read 0 whatever the command line said).
        if bad.starts_with(&["--orbit", "3"]) {
            assert_eq!(r["frames"], 3, "{bad:?}: {r}");
        }
    }
    for (args, frames) in [
        (&["-o", "a.png", "--method", "foo"][..], 1),
        (
            &["-o", "t_#.png", "--trail-range", "0:1:7", "--method", "foo"],
            7,
        ),
        (
            &[
                "-o",
                "t_#.png",
                "--camera-path",
                "p.toml",
                "--method",
                "foo",
            ],
            0,
        ),
        (
            &[
                "-o",
                "t_#.png",
                "--trail-range",
                "0:1:7",
                "--camera-path",
                "p.toml",
                "--method",
                "foo",
            ],
            0,
        ),
        (
            &[
                "-o",
                "t_#.png",
                "--camera-path",
                "p.toml",
                "--orbit",
                "4",
                "--method",
                "foo",
            ],
            4,
        ),
    ] {
        let mut a = args.to_vec();
        a.extend(["--record", "u/r.json"]);
        assert_eq!(run(&a).status.code(), Some(1), "{args:?}");
        assert_eq!(record(&d.join("u/r.json"))["frames"], frames, "{args:?}");
    }
    assert!(!d.join("o").exists());
    // An option without its value is a malformed command line (exit 2), its record written.
    let o = run(&["-o", "o/f_#.png", "--record", "m/r.json", "--orbit"]);
    assert_eq!(o.status.code(), Some(2), "{}", err(&o));
    assert!(record(&d.join("m/r.json"))["error"]
        .as_str()
        .unwrap()
        .contains("--orbit"));
    // An explicitly empty value is a bad value (exit 1), not a missing one.
    let o = run(&["--orbit", "3", "-o", "o/f_#.png", "--frames", ""]);
    assert_eq!(o.status.code(), Some(1), "{}", err(&o));
    // A value missing before `--record`: the record is still written (the scan took
    // `--record` for the missing value and skipped its path).
    let o = run(&["-o", "o/f_#.png", "--orbit", "--record", "mv/r.json"]);
    assert_eq!(o.status.code(), Some(2), "{}", err(&o));
    assert!(d.join("mv/r.json").exists(), "{}", err(&o));
    // `--record` without its value: no record file named after the next flag.
    let o = run(&["-o", "o/f_#.png", "--record", "--orbit", "3"]);
    assert_eq!(o.status.code(), Some(2), "{}", err(&o));
    assert!(!d.join("--orbit").exists());
    // `--shard` followed by another option is never taken as a shard: a malformed command
    // line (exit 2) where the option's own value is left over, else the option refused as
    // the shard's value (exit 1); nothing rendered either way.
    for (args, code) in [
        (&["-o", "o/f_#.png", "--shard", "--orbit", "3"][..], 2),
        (&["--orbit", "3", "--shard", "-o", "o/f_#.png"], 2),
        (&["--orbit", "3", "-o", "o/f_#.png", "--shard", "--json"], 1),
    ] {
        let o = run(args);
        assert_eq!(o.status.code(), Some(code), "{args:?}: {}", err(&o));
        assert!(!d.join("o").exists(), "{args:?}");
    }
    let o = run(&["--orbit", "3", "-o", "o/f_#.png", "--shard", "--json"]);
    assert!(err(&o).contains("is an option, not a shard"), "{}", err(&o));
    // A record or timings file the output pattern also makes is refused before any frame (a
    // frame would overwrite it, or it a frame).
    for args in [
        &["--orbit", "3", "-o", "sq/f_#.png", "--record", "sq/f_1.png"][..],
        &[
            "--orbit",
            "3",
            "-o",
            "sq/f_##.png",
            "--timings-json",
            "./sq/f_002.png",
        ],
    ] {
        let o = run(args);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", err(&o));
        assert!(err(&o).contains("output pattern"), "{}", err(&o));
        assert!(!d.join("sq/f_0.png").exists() && !d.join("sq/f_00.png").exists());
    }
    std::fs::write(d.join("m.txt"), "a\nb\n").unwrap();
    let o = run(&[
        "--manifest",
        "m.txt",
        "-o",
        "mm/{name}.png",
        "--record",
        "mm/b.png",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", err(&o));
    assert!(err(&o).contains("output pattern"), "{}", err(&o));
    assert!(!d.join("mm/a.png").exists());
    // Names the pattern cannot make are fine.
    let o = run(&[
        "--orbit",
        "2",
        "-o",
        "sq/f_##.png",
        "--record",
        "sq/f_1.json",
    ]);
    ok(&o);
    // Bad Slurm variables: the record's new folder is made first.
    let o = umbra()
        .arg("render")
        .arg(&s)
        .args([
            "--orbit",
            "6",
            "-o",
            "o/f_#.png",
            "--record",
            "slurm/r.json",
        ])
        .current_dir(d)
        .env("SLURM_ARRAY_TASK_ID", "4")
        .env("SLURM_ARRAY_TASK_MIN", "1")
        .env("SLURM_ARRAY_TASK_MAX", "9")
        .env("SLURM_ARRAY_TASK_COUNT", "3")
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(record(&d.join("slurm/r.json"))["shard"].is_null());
    // Record paths naming a folder (ending in / or /.) and an output folder that is a file:
    // refused before any frame.
    for rec in ["rsrec/", "rdir/."] {
        let o = run(&["--orbit", "2", "-o", "rs/f_#.png", "--record", rec]);
        assert_eq!(o.status.code(), Some(1));
        assert!(
            err(&o).contains(rec) && !d.join("rs").exists(),
            "{rec}: {}",
            err(&o)
        );
    }
    std::fs::write(d.join("afile"), b"").unwrap();
    let o = run(&["--orbit", "2", "-o", "afile/f_#.png"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        err(&o).contains("afile/f_0.png") && err(&o).contains("afile is a file, not a folder"),
        "{}",
        err(&o)
    );
    assert!(!err(&o).contains("frame 0"), "{}", err(&o));
    // Complete frames skipped, then the data missing: skipped and failed both recorded.
    let g = d.join("g");
    std::fs::create_dir_all(&g).unwrap();
    let vtk = test_support::root().join("datasets/vtk");
    for f in ["headsq_64x64x93.nhdr", "headsq_64x64x93_int16le.raw"] {
        std::fs::copy(vtk.join(f), g.join(f)).unwrap();
    }
    std::fs::write(
        g.join("s.toml"),
        "[volume]\npath = \"headsq_64x64x93.nhdr\"\n[render]\nmethod = \"ea\"\nwidth = 64\nheight = 48\n",
    )
    .unwrap();
    let seq = |extra: &[&str]| {
        umbra()
            .arg("render")
            .arg(g.join("s.toml"))
            .args(["--orbit", "3", "-o"])
            .arg(g.join("o/f_#.png"))
            .args(extra)
            .output()
            .unwrap()
    };
    ok(&seq(&[]));
    std::fs::remove_file(g.join("headsq_64x64x93_int16le.raw")).unwrap();
    std::fs::remove_file(g.join("o/f_1.png")).unwrap();
    std::fs::write(g.join("o/.f_0.png.999999999.tmp"), b"partial").unwrap();
    let rec = g.join("r.json");
    let o = seq(&["--shard", "0/1", "--record", rec.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    let r = record(&rec);
    assert_eq!(r["frames"], 3);
    assert_eq!(indices(&r, "skipped"), [0, 2]);
    assert_eq!(indices(&r, "failed"), [1]);
    assert!(r["failed"][0]["error"]
        .as_str()
        .unwrap()
        .contains("headsq_64x64x93_int16le.raw"));
    assert!(
        err(&o).contains("shard 0/1: 0 of 3 frames rendered, 2 skipped"),
        "{}",
        err(&o)
    );
    assert!(!g.join("o/.f_0.png.999999999.tmp").exists());
}

/// A run whose scene fails before any frame records the shard's frame count the command line
/// gives (it recorded 0), so that a job array's records add up.
#[test]
fn a_failed_run_records_the_frames_it_was_given() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = d.join("missing.toml");
    std::fs::write(&s, "[volume]\npath = \"nope.nii\"\n").unwrap();
    for (extra, want) in [
        (&["--orbit", "3"][..], 3),
        (&["--orbit", "5", "--shard", "1/2"], 2),
        (&[], 1),
    ] {
        let rec = d.join("r.json");
        let o = umbra()
            .arg("render")
            .arg(&s)
            .args(["-o", "o/f_#.png", "--record"])
            .arg(&rec)
            .args(extra)
            .current_dir(d)
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(1), "{extra:?}");
        let r = record(&rec);
        assert_eq!(r["frames"], want, "{extra:?}: {r}");
        assert!(r["error"].as_str().unwrap().contains("nope.nii"), "{r}");
    }
    // A bad shard: the frames the command line gives (the shard is unknown; it said 0).
    let rec = d.join("r.json");
    let o = umbra()
        .arg("render")
        .arg(&s)
        .args([
            "-o",
            "o/f_#.png",
            "--orbit",
            "8",
            "--shard",
            "5/3",
            "--record",
        ])
        .arg(&rec)
        .current_dir(d)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let r = record(&rec);
    assert_eq!(r["frames"], 8, "{r}");
    assert!(r["shard"].is_null() && r["error"].as_str().unwrap().contains("--shard"));
}

/// A record that names a file the run refuses to write over (a frame of its output pattern,
/// its single image) is refused and that file left as it was (the error path wrote the record
/// over it anyway: a finished frame became JSON).
#[test]
fn a_record_naming_an_output_is_refused_and_writes_nothing_there() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = scene(d);
    std::fs::create_dir_all(d.join("cl")).unwrap();
    std::fs::write(d.join("cl/f_0.png"), b"a finished frame").unwrap();
    let o = umbra()
        .arg("render")
        .arg(&s)
        .args(["--orbit", "4", "-o", "cl/f_#.png", "--record", "cl/f_0.png"])
        .current_dir(d)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(
        std::fs::read(d.join("cl/f_0.png")).unwrap(),
        b"a finished frame"
    );
    let o = umbra()
        .arg("render")
        .arg(&s)
        .args(["-o", "same.png", "--record", "same.png"])
        .current_dir(d)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    assert!(!d.join("same.png").exists());
}

/// Interrupted (SIGTERM, as a Slurm time limit sends), a run writes its record: the frames it
/// finished and an error saying it was interrupted - not no record, nor an earlier run's left
/// in place.
#[cfg(unix)]
#[test]
fn an_interrupted_run_records_what_it_did() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = test_support::headsq_scene(
        d,
        "",
        "bone",
        "method = \"dos\"\nwidth = 192\nheight = 144\n",
    );
    let rec = d.join("r.json");
    std::fs::write(&rec, r#"{"an": "earlier run's record"}"#).unwrap();
    let frame = |k: usize| d.join(format!("out/f_{k:02}.png"));
    let child = spawned_until(
        umbra()
            .arg("render")
            .arg(&s)
            .args(["--orbit", "40", "-o", "out/f_##.png", "--record"])
            .arg(&rec)
            .current_dir(d),
        &frame(1),
    );
    assert!(std::process::Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap()
        .success());
    let status = { child }.wait().unwrap();
    assert_eq!(status.code(), None, "ended by the signal");
    let r = record(&rec);
    assert!(r["error"].as_str().unwrap().contains("SIGTERM"), "{r}");
    assert_eq!(r["frames"], 40, "{r}");
    let done = indices(&r, "done");
    assert!(done.contains(&1), "{r}");
    for k in &done {
        assert!(frame(*k).exists(), "frame {k} recorded done but missing");
    }
    assert!(done.len() < 40, "{r}");
    // A camera path's frames are counted once it is read (the record said 0).
    let path = d.join("p.toml");
    std::fs::write(
        &path,
        "frames = 400\n[[key]]\ntime = 0\nazimuth = 0\n[[key]]\ntime = 1\nazimuth = 90\n",
    )
    .unwrap();
    let frame = |k: usize| d.join(format!("cp/f_{k:03}.png"));
    let child = spawned_until(
        umbra()
            .arg("render")
            .arg(&s)
            .args(["-o", "cp/f_###.png", "--record"])
            .arg(&rec)
            .arg("--camera-path")
            .arg(&path)
            .current_dir(d),
        &frame(1),
    );
    assert!(std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap()
        .success());
    assert_eq!(
        { child }.wait().unwrap().code(),
        None,
        "ended by the signal"
    );
    let r = record(&rec);
    assert!(r["error"].as_str().unwrap().contains("SIGINT"), "{r}");
    assert_eq!(r["frames"], 400, "{r}");
    // Seconds count to the signal (they stopped at the last frame ended: 0.0004 s for a single
    // image interrupted after a second). One image timed over 400 draws, interrupted at 1.5 s.
    let t = std::time::Instant::now();
    let child = umbra()
        .arg("render")
        .arg(&s)
        .args(["-o", "one.png", "--frames", "400", "--record"])
        .arg(&rec)
        .current_dir(d)
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    assert!(std::process::Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap()
        .success());
    assert_eq!(
        { child }.wait().unwrap().code(),
        None,
        "ended by the signal"
    );
    // After the process has ended: the signal is handled after `kill` returns, so only the
    // time to the end bounds what the record may say.
    let lived = t.elapsed().as_secs_f64();
    let r = record(&rec);
    assert_eq!(r["frames"], 1, "{r}");
    let seconds = r["seconds"].as_f64().unwrap();
    assert!(
        seconds > 0.5 * lived && seconds <= lived,
        "{seconds} s recorded, the run lived {lived} s: {r}"
    );
}

/// `cmd` started (standard error discarded), returned once `frame` exists (or after two
/// minutes): a run to stop mid-sequence.
fn spawned_until(cmd: &mut Command, frame: &Path) -> std::process::Child {
    let child = cmd.stderr(std::process::Stdio::null()).spawn().unwrap();
    let t0 = std::time::Instant::now();
    while !frame.exists() && t0.elapsed().as_secs() < 120 {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child
}
