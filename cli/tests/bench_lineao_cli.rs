//! `umbra bench lineao --quick` end to end: results.csv has its header and finite values, the
//! isolated lines stay open and LineAO orders the dense bundle's pixels as the ray-traced
//! reference does (positively correlated).

use std::collections::HashMap;

const HEADER: &str = "case,method,setting,ms,rmse,bias,rmse_affine,spearman,ssim,mean_visibility,pixels,ref_stderr,rmse_converged,spearman_model,rmse_affine_model";

#[test]
fn bench_lineao_quick_writes_results_with_open_isolated_lines_and_a_positive_rank_correlation() {
    let dir = tempfile::tempdir().unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_umbra"))
        .args(["bench", "lineao", "--quick", "-o"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout
            .lines()
            .any(|l| l.starts_with("dense") && l.contains("lineao")),
        "{stdout}"
    );
    assert!(dir.path().join("pareto.svg").exists());
    assert!(dir.path().join("pareto.png").exists());
    let csv = std::fs::read_to_string(dir.path().join("results.csv")).unwrap();
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
}
