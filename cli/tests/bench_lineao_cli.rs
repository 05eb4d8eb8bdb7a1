//! `umbra bench lineao --quick` end to end: results.csv has its header and finite values, the
//! isolated lines stay open and LineAO orders the dense bundle's pixels as the ray-traced
//! reference does (positively correlated); the anisotropic group's tables: anisotropic LineAO
//! keeps about A0 of the classic occlusion among parallel lines and about all of it at a
//! crossing, and the roll-invariant alignment varies less with the camera's roll than the
//! paper's.

use std::collections::HashMap;

const HEADER: &str = "case,method,setting,ms,rmse,bias,rmse_affine,spearman,ssim,mean_visibility,pixels,ref_stderr,rmse_converged,spearman_model,rmse_affine_model";

#[test]
fn bench_lineao_quick_writes_the_accuracy_and_the_anisotropic_tables() {
    let tmp = tempfile::tempdir().unwrap();
    // A relative output folder: the scenes written under it must still find their data.
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_umbra"))
        .current_dir(tmp.path())
        .args(["bench", "lineao", "--quick", "-o", "out"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let dir = tmp.path().join("out");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout
            .lines()
            .any(|l| l.starts_with("dense") && l.contains("lineao")),
        "{stdout}"
    );
    assert!(dir.join("pareto.svg").exists());
    assert!(dir.join("pareto.png").exists());
    let csv = std::fs::read_to_string(dir.join("results.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some(HEADER));
    let names: Vec<&str> = HEADER.split(',').collect();
    let rows: Vec<HashMap<&str, &str>> = lines
        .map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            assert_eq!(v.len(), names.len(), "{l}");
            names.iter().copied().zip(v).collect()
        })
        .collect();
    let num = |r: &HashMap<&str, &str>, k: &str| -> f64 { r[k].parse().unwrap() };
    let find = |case: &str, method: &str, setting: &str| {
        rows.iter()
            .find(|r| r["case"] == case && r["method"] == method && r["setting"] == setting)
            .unwrap_or_else(|| panic!("no row {case} {method} {setting} in\n{csv}"))
    };
    for case in ["isolated", "dense"] {
        for (method, setting) in [
            ("lineao", "paper"),
            ("lineao", "pseudo-cylinder"),
            ("ssao", "cpu from Z"),
        ] {
            let r = find(case, method, setting);
            for k in [
                "ms",
                "rmse",
                "bias",
                "rmse_affine",
                "ssim",
                "mean_visibility",
                "ref_stderr",
            ] {
                assert!(num(r, k).is_finite(), "{case} {method} {k} = {}", r[k]);
            }
            assert!(num(r, "pixels") > 100.0, "{case}: {}", r["pixels"]);
        }
        let reference = find(case, "reference", "");
        assert!(num(reference, "mean_visibility") > 0.0 && num(reference, "ms") > 0.0);
    }
    // Isolated lines stay open (the paper's flat strips); the reference agrees they are nearly
    // open.
    let iso = find("isolated", "lineao", "paper");
    assert!(
        num(iso, "mean_visibility") >= 0.85,
        "{}",
        iso["mean_visibility"]
    );
    assert!(num(find("isolated", "reference", ""), "mean_visibility") >= 0.85);
    // In the dense bundle LineAO ranks the pixels as the ray-traced AO does, and darkens.
    let dense = find("dense", "lineao", "paper");
    assert!(num(dense, "spearman") > 0.3, "{}", dense["spearman"]);
    assert!(
        num(dense, "spearman_model") > 0.3,
        "{}",
        dense["spearman_model"]
    );
    assert!(num(dense, "mean_visibility") < num(iso, "mean_visibility"));
    let vicinity = rows
        .iter()
        .find(|r| r["case"] == "dense" && r["method"] == "vicinity")
        .unwrap();
    assert!(num(vicinity, "spearman") > 0.0);

    // The anisotropic group (run by default).
    let table = |name: &str, header: &str| -> Vec<HashMap<String, String>> {
        let text = std::fs::read_to_string(dir.join(name)).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some(header), "{name}");
        let names: Vec<&str> = header.split(',').collect();
        lines
            .map(|l| {
                let v: Vec<&str> = l.split(',').collect();
                assert_eq!(v.len(), names.len(), "{name}: {l}");
                names
                    .iter()
                    .map(|n| n.to_string())
                    .zip(v.iter().map(|x| x.to_string()))
                    .collect()
            })
            .collect()
    };
    let f = |r: &HashMap<String, String>, k: &str| -> f64 { r[k].parse().unwrap() };
    let summary = table("aniso_summary.csv", SUMMARY_HEADER);
    let setting = |alignment: &str, intensity: &str| {
        summary
            .iter()
            .find(|r| r["alignment"] == alignment && r["intensity"] == intensity)
            .unwrap_or_else(|| panic!("no summary row {alignment} {intensity}"))
    };
    assert_eq!(summary.len(), 7, "classic and 2 alignments x 3 intensities");
    for r in &summary {
        assert_eq!(r["rolls"], "7");
    }
    let (inv, paper) = (setting("invariant", "15"), setting("paper", "15"));
    // Parallel lines: about A0 = 0.1 of the classic occlusion at every roll; a 60-degree
    // crossing: all of it for the invariant form at every roll.
    for r in [inv, paper] {
        assert!(
            f(r, "ratio_parallel_max") < 0.5,
            "{}: {}",
            r["alignment"],
            r["ratio_parallel_max"]
        );
    }
    assert!(
        f(inv, "ratio_crossing_min") > 0.7,
        "{}",
        inv["ratio_crossing_min"]
    );
    // The paper's |t.x| sees the crossing as parallel at the roll where its bisector is
    // horizontal (30 degrees), and its crossing occlusion varies with the roll; the invariant
    // form's hardly.
    assert!(
        f(paper, "ratio_crossing_min") < 0.5,
        "{}",
        paper["ratio_crossing_min"]
    );
    assert!(
        f(inv, "cv_occlusion_crossing") < 0.5 * f(paper, "cv_occlusion_crossing"),
        "{} {}",
        inv["cv_occlusion_crossing"],
        paper["cv_occlusion_crossing"]
    );
    let roll = table("aniso_roll.csv", ROLL_HEADER);
    assert_eq!(roll.len(), 49);
    for r in &roll {
        for k in ["occlusion_parallel", "occlusion_crossing"] {
            assert!(f(r, k).is_finite(), "{k} {r:?}");
        }
        assert!(f(r, "parallel_pixels") > 100.0 && f(r, "crossing_pixels") > 100.0);
    }
    assert!(dir.join("aniso_roll.svg").exists());
    // The trail animation: every row finite; LineAO's visibility changes from frame to frame.
    let flicker = table("aniso_flicker.csv", FLICKER_HEADER);
    assert_eq!(flicker.len(), 5, "3 LineAO settings and 2 references");
    for r in &flicker {
        for k in ["mean_occlusion", "mean_abs_change", "rms_change", "pixels"] {
            assert!(f(r, k).is_finite(), "{k} {r:?}");
        }
        assert!(f(r, "pixels") > 100.0, "{r:?}");
    }
    let classic = flicker.iter().find(|r| r["setting"] == "classic").unwrap();
    assert!(f(classic, "mean_abs_change") > 0.0);
}

const ROLL_HEADER: &str = "method,alignment,intensity,roll_deg,pixels,mean_visibility,occlusion,occlusion_parallel,occlusion_crossing,ratio_parallel,ratio_crossing,g_align_parallel,g_align_crossing,parallel_pixels,crossing_pixels,ms";
const SUMMARY_HEADER: &str = "method,alignment,intensity,rolls,cv_visibility,cv_occlusion,cv_occlusion_parallel,cv_occlusion_crossing,ratio_parallel_mean,ratio_parallel_min,ratio_parallel_max,ratio_crossing_mean,ratio_crossing_min,ratio_crossing_max";
const FLICKER_HEADER: &str = "method,setting,frames,pixels,mean_occlusion,mean_abs_change,relative_change,frac_change_above_0.05,pearson_with_reference_change,pearson_with_model_change,rms_change,rms_change_denoised,noise_floor,ref_stderr,ms";
