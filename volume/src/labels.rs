//! Label colour tables: FreeSurfer's `FreeSurferColorLUT.txt` format, and default colours for
//! label volumes that come without one.
//!
//! The format is plain text, one label a line: `index name R G B A`, whitespace separated,
//! `#` starting a comment (whole-line or trailing), blank lines skipped. `R G B` are integers
//! 0..=255; `A` is FreeSurfer's transparency (0 = opaque), read and checked but not used (an
//! overlay's opacity is the scene's). Names cannot contain whitespace, as in FreeSurfer.

use std::collections::BTreeMap;
use std::path::Path;

/// The name and colour of one label.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LabelEntry {
    /// The label's name (`Left-Hippocampus`, or `label 17` for default colours).
    pub name: String,
    /// Its sRGB colour.
    pub rgb: [u8; 3],
}

/// Names and colours of the labels of a label volume, by label value.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LabelTable {
    /// Every label of the table, by its integer value.
    pub entries: BTreeMap<i64, LabelEntry>,
}

/// The largest colour table file [`read_lut`] reads (16 MiB; FreeSurfer's full table is
/// about 50 KiB).
pub const MAX_LUT_BYTES: u64 = 16 << 20;

/// Reads a colour table in FreeSurfer's `FreeSurferColorLUT.txt` format (see the module
/// documentation). Errors name the file and, for its content, the line and the problem; files
/// over [`MAX_LUT_BYTES`], non-regular files and non-UTF-8 text are refused.
pub fn read_lut(path: &Path) -> Result<LabelTable, String> {
    let text = crate::io_util::read_text(path, MAX_LUT_BYTES)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    parse_lut(&text, &path.display().to_string())
}

/// Parses the text of a FreeSurfer colour table; `name` (the file's name) starts every error.
pub fn parse_lut(text: &str, name: &str) -> Result<LabelTable, String> {
    let mut entries = BTreeMap::new();
    let mut defined_on: BTreeMap<i64, usize> = BTreeMap::new();
    for (n, raw) in text.lines().enumerate() {
        let line_no = n + 1;
        let fail = |problem: String| format!("{name}: line {line_no}: {problem}");
        let content = raw.split('#').next().unwrap_or("");
        let fields: Vec<&str> = content.split_whitespace().collect();
        if fields.is_empty() {
            continue;
        }
        if fields.len() < 5 {
            return Err(fail(format!(
                "{} field{}, expected 'index name R G B A' (the A may be left out)",
                fields.len(),
                if fields.len() == 1 { "" } else { "s" }
            )));
        }
        if fields.len() > 6 {
            return Err(fail(format!(
                "{} fields, expected 'index name R G B A' (a name with spaces?)",
                fields.len()
            )));
        }
        let index: i64 = fields[0].parse().map_err(|_| {
            fail(format!(
                "the index '{}' is not an integer",
                crate::io_util::clip_text(fields[0], 40)
            ))
        })?;
        let channel = |i: usize, what: &str| -> Result<u8, String> {
            fields[i].parse::<u8>().map_err(|_| {
                fail(format!(
                    "{what} '{}' of label {index} is not an integer from 0 to 255",
                    crate::io_util::clip_text(fields[i], 40)
                ))
            })
        };
        let rgb = [
            channel(2, "red")?,
            channel(3, "green")?,
            channel(4, "blue")?,
        ];
        if fields.len() == 6 {
            channel(5, "the transparency (A)")?;
        }
        if let Some(first) = defined_on.insert(index, line_no) {
            return Err(fail(format!(
                "label {index} is defined again (first on line {first})"
            )));
        }
        entries.insert(
            index,
            LabelEntry {
                name: fields[1].to_string(),
                rgb,
            },
        );
    }
    if entries.is_empty() {
        return Err(format!(
            "{name}: no entries: a colour table has lines 'index name R G B A'"
        ));
    }
    Ok(LabelTable { entries })
}

/// The golden ratio's fractional part: hues stepped by it stay well apart for any number of
/// consecutive labels.
const GOLDEN: f64 = 0.618_033_988_749_894_9;

/// A colour for each of `labels` (repeats are merged), named `label N`: the hue is
/// `frac(0.6 + N * 0.618...)` (the golden-ratio sequence, so consecutive labels get well
/// separated hues), at saturation 0.65 and value 0.95. A label's colour depends on its value
/// only, not on the other labels, so it is the same in every volume; the sequence repeats every
/// 2^24 labels (N is taken modulo 2^24).
pub fn default_colors(labels: &[i64]) -> LabelTable {
    let entries = labels
        .iter()
        .map(|&label| {
            (
                label,
                LabelEntry {
                    name: format!("label {label}"),
                    rgb: default_color(label),
                },
            )
        })
        .collect();
    LabelTable { entries }
}

/// The colour [`default_colors`] gives `label`.
fn default_color(label: i64) -> [u8; 3] {
    // Reduce first so that the product keeps its fraction in f64 for any label.
    let n = label.rem_euclid(1 << 24) as f64;
    let hue = (0.6 + n * GOLDEN).rem_euclid(1.0);
    hsv_to_rgb(hue, 0.65, 0.95).map(|v| (v * 255.0).round().clamp(0.0, 255.0) as u8)
}

/// HSV (hue in [0, 1), saturation, value) to RGB, components in [0, 1].
fn hsv_to_rgb(h: f64, s: f64, v: f64) -> [f64; 3] {
    let h6 = h.rem_euclid(1.0) * 6.0;
    let sector = (h6.floor() as usize).min(5);
    let f = h6 - sector as f64;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - s * f), v * (1.0 - s * (1.0 - f)));
    match sector {
        0 => [v, t, p],
        1 => [q, v, p],
        2 => [p, v, t],
        3 => [p, q, v],
        4 => [t, p, v],
        _ => [v, p, q],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "\
#$Id: FreeSurferColorLUT.txt $

#No. Label Name:                            R   G   B   A
0   Unknown                                 0   0   0   0
2   Left-Cerebral-White-Matter            245 245 245   0   # trailing comment
\t17\tLeft-Hippocampus\t220\t216\t20\t0
1000 ctx-lh-unknown 25 5 25
";

    #[test]
    fn parses_a_good_table() {
        let t = parse_lut(GOOD, "lut.txt").unwrap();
        assert_eq!(t.entries.len(), 4);
        assert_eq!(
            t.entries[&2],
            LabelEntry {
                name: "Left-Cerebral-White-Matter".into(),
                rgb: [245, 245, 245]
            }
        );
        assert_eq!(t.entries[&17].rgb, [220, 216, 20]);
        assert_eq!(t.entries[&0].name, "Unknown");
        assert_eq!(t.entries[&1000].rgb, [25, 5, 25]);
        let negative = parse_lut("-1 Neg 1 2 3 0\r\n", "x").unwrap();
        assert_eq!(negative.entries[&-1].rgb, [1, 2, 3]);
    }

    fn error(text: &str) -> String {
        parse_lut(text, "lut.txt").unwrap_err()
    }

    #[test]
    fn bad_tables_name_the_line_and_problem() {
        let cases: [(&str, &str); 9] = [
            (
                "0 Unknown 0 0 0 0\n\n5 Vent 1 2\n",
                "lut.txt: line 3: 4 fields",
            ),
            (
                "# c\nx Name 1 2 3 0\n",
                "lut.txt: line 2: the index 'x' is not an integer",
            ),
            (
                "1.5 Name 1 2 3 0\n",
                "line 1: the index '1.5' is not an integer",
            ),
            (
                "7 Name 256 2 3 0\n",
                "line 1: red '256' of label 7 is not an integer from 0 to 255",
            ),
            ("7 Name 1 -2 3 0\n", "line 1: green '-2' of label 7"),
            ("7 Name 1 2 blue 0\n", "line 1: blue 'blue' of label 7"),
            (
                "7 Name 1 2 3 0.5\n",
                "line 1: the transparency (A) '0.5' of label 7",
            ),
            ("7 Left Hippo 1 2 3 0\n", "line 1: 7 fields"),
            (
                "1 A 1 2 3 0\n2 B 1 2 3 0\n1 C 1 2 3 0\n",
                "line 3: label 1 is defined again (first on line 1)",
            ),
        ];
        for (text, want) in cases {
            let e = error(text);
            assert!(e.contains(want), "{text:?}: {e}");
            assert!(e.starts_with("lut.txt: line "), "{e}");
        }
        for empty in ["", "# only a comment\n\n   \n"] {
            let e = error(empty);
            assert!(e.starts_with("lut.txt: no entries"), "{e}");
        }
    }

    #[test]
    fn reads_the_fixture_and_refuses_bad_files() {
        let fixture =
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/overlay/labels_lut.txt");
        let t = read_lut(&fixture).unwrap();
        let labels: Vec<i64> = t.entries.keys().copied().collect();
        assert_eq!(labels, [0, 2, 5, 17, 53]);
        assert_eq!(t.entries[&5].name, "Left-Inf-Lat-Vent");
        assert_eq!(t.entries[&5].rgb, [196, 58, 250]);

        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing.txt");
        let e = read_lut(&missing).unwrap_err();
        assert!(e.starts_with(&missing.display().to_string()), "{e}");
        let e = read_lut(dir.path()).unwrap_err();
        assert!(e.contains("directory"), "{e}");
        let bad = dir.path().join("bad.txt");
        std::fs::write(&bad, "0 Unknown 0 0 0 0\n3 Bad 1 2\n").unwrap();
        let e = read_lut(&bad).unwrap_err();
        assert_eq!(
            e,
            format!(
                "{}: line 2: 4 fields, expected 'index name R G B A' (the A may be left out)",
                bad.display()
            )
        );
        let binary = dir.path().join("binary.txt");
        std::fs::write(&binary, [0xff, 0xfe, 0x00]).unwrap();
        assert!(read_lut(&binary).unwrap_err().contains("UTF-8"));
    }

    #[test]
    fn default_colors_are_distinct_and_stable() {
        let labels: Vec<i64> = (0..24).chain([41, 53, 1000, 2035, -1]).collect();
        let t = default_colors(&labels);
        assert_eq!(t.entries.len(), labels.len());
        assert_eq!(t.entries[&17].name, "label 17");
        assert_eq!(t, default_colors(&labels));
        // A label's colour does not depend on the others.
        assert_eq!(default_colors(&[17]).entries[&17], t.entries[&17]);
        let colours: Vec<[u8; 3]> = t.entries.values().map(|e| e.rgb).collect();
        for (a, ca) in colours.iter().enumerate() {
            for cb in &colours[a + 1..] {
                assert_ne!(ca, cb);
            }
        }
        // Consecutive labels are clearly apart.
        for n in 0..23 {
            let (a, b) = (t.entries[&n].rgb, t.entries[&(n + 1)].rgb);
            let d: i32 = (0..3).map(|c| (a[c] as i32 - b[c] as i32).abs()).sum();
            assert!(d > 60, "labels {n} and {}: {a:?} {b:?}", n + 1);
        }
        assert!(default_colors(&[]).entries.is_empty());
        assert_eq!(default_colors(&[3, 3]).entries.len(), 1);
        // Extreme labels get colours too (the hue sequence repeats every 2^24 labels).
        let extreme = default_colors(&[i64::MIN, i64::MAX]);
        assert_eq!(extreme.entries[&i64::MIN].rgb, t.entries[&0].rgb);
        assert_eq!(extreme.entries[&i64::MAX].rgb, t.entries[&-1].rgb);
    }
}
