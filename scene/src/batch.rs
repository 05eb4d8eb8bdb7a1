//! Batch rendering, the library behind `umbra render --shard`, `--skip-existing` and
//! `--manifest`: which frames a shard renders ([`Shard`], from a flag or a Slurm job array's
//! variables), manifests of scenes ([`read_manifest`]), and which outputs are already done
//! ([`complete_image`]). The unit of work is a frame (or a manifest line): umbra's occlusion
//! is a per-frame light sweep, so a frame is never split, and the scheduler (Slurm, GNU
//! parallel) runs one process per shard.

use crate::render::{run_on, Cameras, FrameOutcome, Progress, RenderArgs};
use std::cell::OnceCell;
use std::path::{Path, PathBuf};

/// Shard `index` of `count`: the frames whose global index k has k mod count = index.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

/// Where a [`Shard`] came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ShardFrom {
    /// Neither a flag nor a job array: every frame.
    None,
    /// `--shard I/N`.
    Flag,
    /// `SLURM_ARRAY_TASK_ID` and its companions.
    Slurm,
}

/// The Slurm job-array variables [`Shard::from_slurm`] reads.
pub const SLURM_VARIABLES: [&str; 5] = [
    "SLURM_ARRAY_TASK_ID",
    "SLURM_ARRAY_TASK_MIN",
    "SLURM_ARRAY_TASK_COUNT",
    "SLURM_ARRAY_TASK_STEP",
    "SLURM_ARRAY_TASK_MAX",
];

impl Shard {
    /// Every frame in one shard.
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// Reads `I/N` (0 <= I < N).
    pub fn parse(text: &str) -> Result<Shard, String> {
        let bad =
            || format!("shard '{text}': expected I/N with 0 <= I < N <= 4294967295, e.g. 0/4");
        let (i, n) = text.split_once('/').ok_or_else(bad)?;
        let index: u32 = i.trim().parse().map_err(|_| bad())?;
        let count: u32 = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    /// The shard of a Slurm job-array task: I = (ID - MIN) / STEP and N = COUNT, from
    /// `SLURM_ARRAY_TASK_ID`, `_MIN`, `_COUNT` and `_STEP` (1 when unset), read through `var`.
    /// `None` when `SLURM_ARRAY_TASK_ID` is unset (not an array task); an error when the
    /// variables do not make a shard (a sparse array such as `--array=1,4,9`).
    pub fn from_slurm(var: impl Fn(&str) -> Option<String>) -> Result<Option<Shard>, String> {
        let Some(id) = var(SLURM_VARIABLES[0]) else {
            return Ok(None);
        };
        let num = |name: &str, value: Option<String>| -> Result<u64, String> {
            let v = value.ok_or_else(|| {
                format!("{name} is not set beside SLURM_ARRAY_TASK_ID: give the shard as I/N")
            })?;
            v.trim()
                .parse::<u64>()
                .map_err(|_| format!("{name}='{v}' is not a whole number"))
        };
        let id = num(SLURM_VARIABLES[0], Some(id))?;
        let min = num(SLURM_VARIABLES[1], var(SLURM_VARIABLES[1]))?;
        let count = num(SLURM_VARIABLES[2], var(SLURM_VARIABLES[2]))?;
        let step = match var(SLURM_VARIABLES[3]) {
            Some(s) => match num(SLURM_VARIABLES[3], Some(s))? {
                0 => return Err("SLURM_ARRAY_TASK_STEP=0: a step of at least 1".into()),
                st => st,
            },
            None => 1,
        };
        let max = match var(SLURM_VARIABLES[4]) {
            Some(m) => Some(num(SLURM_VARIABLES[4], Some(m))?),
            None => None,
        };
        let sparse = || {
            format!(
                "SLURM_ARRAY_TASK_ID={id} with SLURM_ARRAY_TASK_MIN={min}, SLURM_ARRAY_TASK_STEP={step}, \
                 SLURM_ARRAY_TASK_COUNT={count}{} is not task I of N = COUNT evenly spaced tasks \
                 (a sparse --array list?): give the shard as I/N",
                max.map(|m| format!(", SLURM_ARRAY_TASK_MAX={m}")).unwrap_or_default()
            )
        };
        if id < min || (id - min) % step != 0 {
            return Err(sparse());
        }
        // Every task of an evenly spaced array: MAX = MIN + STEP (COUNT - 1).
        if max.is_some_and(|m| {
            count == 0 || Some(m) != step.checked_mul(count - 1).and_then(|d| d.checked_add(min))
        }) {
            return Err(sparse());
        }
        if count > u32::MAX as u64 {
            return Err(format!(
                "SLURM_ARRAY_TASK_COUNT={count}: at most {} shards",
                u32::MAX
            ));
        }
        let index = (id - min) / step;
        if count == 0 || index >= count {
            return Err(sparse());
        }
        Ok(Some(Shard {
            index: index as u32,
            count: count as u32,
        }))
    }

    /// The shard to render: `flag` (`I/N`) if given, else a Slurm array task's, else every
    /// frame.
    pub fn resolve(
        flag: Option<&str>,
        var: impl Fn(&str) -> Option<String>,
    ) -> Result<(Shard, ShardFrom), String> {
        if let Some(f) = flag {
            return Ok((Shard::parse(f)?, ShardFrom::Flag));
        }
        Ok(match Shard::from_slurm(var)? {
            Some(s) => (s, ShardFrom::Slurm),
            None => (Shard::ALL, ShardFrom::None),
        })
    }

    /// Whether frame `k` (global index) is this shard's.
    pub fn owns(&self, k: usize) -> bool {
        k as u64 % self.count as u64 == self.index as u64
    }
}

/// Whether `path` holds a whole image of `width` x `height`: a PNG or an EXR that decodes
/// completely at that size, an EXR with every channel of `channels` (the AOVs a run asks
/// for: a frame written without them is not that run's). What `--skip-existing` keeps;
/// anything else (missing, truncated, another size, another format than the extension says,
/// an EXR without the AOVs asked for) is rendered again.
pub fn complete_image(path: &Path, width: u32, height: u32, channels: &[&str]) -> bool {
    if !path.is_file() {
        return false;
    }
    let exr = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    if exr {
        exr::prelude::read_all_data_from_file(path).is_ok_and(|img| {
            img.layer_data.first().is_some_and(|l| {
                l.size.0 == width as usize
                    && l.size.1 == height as usize
                    && channels.iter().all(|c| {
                        l.channel_data
                            .list
                            .iter()
                            .any(|ch| ch.name.to_string() == *c)
                    })
            })
        })
    } else {
        image::ImageReader::open(path)
            .ok()
            .and_then(|r| r.with_guessed_format().ok())
            .and_then(|r| r.decode().ok())
            .is_some_and(|img| img.width() == width && img.height() == height)
    }
}

/// One line of a manifest: a scene (its own file, or the template) with overrides, named.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Entry {
    /// What `{name}` in the output becomes (e.g. a BIDS participant label).
    pub name: String,
    pub scene: PathBuf,
    /// `KEY=VALUE` overrides of this line, applied after the command's own.
    pub overrides: Vec<String>,
    /// Line number in the manifest, from 1.
    pub line: usize,
    /// Where the entry is written: `MANIFEST: line N`.
    pub at: String,
}

/// Longest manifest read, bytes.
pub const MAX_MANIFEST_BYTES: u64 = 64 << 20;

/// Reads a manifest: one entry per line, `NAME [SCENE] [KEY=VALUE ...]`, fields separated by
/// blanks and quoted as in a POSIX shell; blank lines and lines starting with `#` are skipped,
/// and a field starting with `#` begins a comment to the end of the line.
/// SCENE (the first field after NAME without `=`) is relative to the manifest's folder; a line
/// without one renders `template`. Names are unique and usable as file names.
pub fn read_manifest(path: &Path, template: Option<&Path>) -> Result<Vec<Entry>, String> {
    let p = path.display();
    let meta = std::fs::metadata(path).map_err(|e| format!("{p}: {e}"))?;
    if !meta.is_file() {
        return Err(format!("{p}: a manifest must be a regular file"));
    }
    if meta.len() > MAX_MANIFEST_BYTES {
        return Err(format!(
            "{p}: {} bytes; a manifest is at most {MAX_MANIFEST_BYTES} bytes",
            meta.len()
        ));
    }
    let text = volume::read_text(path, 64 << 20).map_err(|e| format!("{p}: {e}"))?;
    let dir = path.parent().unwrap_or(Path::new("."));
    parse_manifest(&text, &p.to_string(), dir, template)
}

/// [`read_manifest`] of text; `name` labels errors, scene paths resolve against `dir`.
pub fn parse_manifest(
    text: &str,
    name: &str,
    dir: &Path,
    template: Option<&Path>,
) -> Result<Vec<Entry>, String> {
    // A byte-order mark (editors on Windows write one) is not part of the first name.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut entries: Vec<Entry> = vec![];
    let mut seen = std::collections::HashMap::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let t = raw.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let at = |what: String| format!("{name}: line {line}: {what}");
        let fields = shlex::split(t).ok_or_else(|| at("unbalanced quotes".into()))?;
        let (label, rest) = fields.split_first().expect("a non-blank line has a field");
        check_name(label).map_err(at)?;
        if let Some(first) = seen.insert(label.clone(), line) {
            return Err(at(format!(
                "the name '{label}' is also on line {first}: every output would be written twice"
            )));
        }
        let (scene, overrides) = match rest.split_first() {
            Some((s, o)) if !s.contains('=') => (dir.join(s), o.to_vec()),
            _ => (
                template.map(Path::to_path_buf).ok_or_else(|| {
                    at(format!(
                        "'{label}' names no scene file and the command gives no template scene"
                    ))
                })?,
                rest.to_vec(),
            ),
        };
        if let Some(bad) = overrides.iter().find(|o| !o.contains('=')) {
            return Err(at(format!(
                "'{bad}' is not KEY=VALUE (only the first field after the name may be a scene)"
            )));
        }
        entries.push(Entry {
            name: label.clone(),
            scene,
            overrides,
            line,
            at: format!("{name}: line {line}"),
        });
    }
    if entries.is_empty() {
        return Err(format!("{name}: the manifest names no scene"));
    }
    Ok(entries)
}

/// Whether a manifest name can become part of a file name.
fn check_name(n: &str) -> Result<(), String> {
    if n.is_empty() || n == "." || n == ".." {
        return Err(format!("'{n}' is not a name"));
    }
    if n.len() > 200 {
        return Err(format!("a name of {} bytes; at most 200", n.len()));
    }
    if let Some(c) = n
        .chars()
        .find(|c| matches!(c, '/' | '\\' | '{' | '}' | '#') || c.is_control())
    {
        return Err(format!(
            "the name '{}' holds {c:?}; names become file names",
            n.escape_default()
        ));
    }
    Ok(())
}

/// The output of a manifest entry: every `{name}` in `pattern` replaced by `name`.
pub fn named_output(pattern: &Path, name: &str) -> Result<PathBuf, String> {
    let text = pattern.to_string_lossy();
    if !text.contains("{name}") {
        return Err(format!(
            "{}: a manifest's output needs {{name}} (e.g. out/{{name}}.png), or every line writes the same file",
            pattern.display()
        ));
    }
    Ok(PathBuf::from(text.replace("{name}", name)))
}

/// Whether `path` is an output [`named_output`] can make from `pattern` for some name (each
/// `{name}` a non-empty name without `/`; the paths compared as absolute paths): a second
/// output with such a name would be overwritten by an entry's, or overwrite it.
pub fn named_output_matches(pattern: &Path, path: &Path) -> bool {
    let abs = |p: &Path| {
        std::path::absolute(p)
            .unwrap_or_else(|_| p.to_path_buf())
            .to_string_lossy()
            .into_owned()
    };
    // Anchored in the pattern's own folder text, so `{name}` parts are not absolutised away.
    let (pat, text) = (abs(pattern), abs(path));
    let parts: Vec<&str> = pat.split("{name}").collect();
    if parts.len() < 2 {
        return pat == text;
    }
    // Greedy-free matching of literal parts with one name between each pair.
    fn rest_matches(parts: &[&str], text: &str, name: Option<&str>) -> bool {
        match parts.split_first() {
            None => text.is_empty(),
            Some((lit, more)) => {
                let Some(after) = text.strip_prefix(lit) else {
                    return false;
                };
                if more.is_empty() {
                    return after.is_empty();
                }
                // Every `{name}` stands for the same name.
                match name {
                    Some(n) => after
                        .strip_prefix(n)
                        .is_some_and(|r| rest_matches(more, r, Some(n))),
                    None => (1..=after.len())
                        .filter(|&i| after.is_char_boundary(i))
                        .map(|i| (&after[..i], &after[i..]))
                        .take_while(|(n, _)| !n.contains('/'))
                        .any(|(n, r)| rest_matches(more, r, Some(n))),
                }
            }
        }
    }
    rest_matches(&parts, &text, None)
}

/// What [`run_manifest`] did: one outcome per entry of its shard.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ManifestReport {
    /// The entries this run was to render (its shard's).
    pub frames_owned: usize,
    pub done: Vec<FrameOutcome>,
    pub skipped: Vec<FrameOutcome>,
    pub failed: Vec<FrameOutcome>,
    /// The adapter's name (empty when nothing was rendered).
    pub adapter: String,
    pub seconds: f64,
    /// Each note of the renders with the names of the entries it came from.
    pub notes: Vec<(String, Vec<String>)>,
}

/// Renders the entries of `shard` (entry k, counted from 0 over the manifest's entries, with
/// k mod N = I), each with `base`'s settings, its own scene and overrides (after `base`'s), to
/// `output` with `{name}` replaced, on one GPU opened once. An entry that fails (a missing
/// scene, bad data, a failed frame) is recorded and the others go on.
pub fn run_manifest(
    entries: &[Entry],
    output: &Path,
    base: &RenderArgs,
    shard: Shard,
    progress: &mut dyn FnMut(Progress),
) -> Result<ManifestReport, String> {
    let t0 = std::time::Instant::now();
    named_output(output, "x")?;
    let gpu = OnceCell::new();
    let owned: Vec<(usize, &Entry)> = entries
        .iter()
        .enumerate()
        .filter(|(k, _)| shard.owns(*k))
        .collect();
    let mut r = ManifestReport {
        frames_owned: owned.len(),
        done: vec![],
        skipped: vec![],
        failed: vec![],
        adapter: String::new(),
        seconds: 0.0,
        notes: vec![],
    };
    let n = owned.len();
    progress(Progress::Frames(n));
    for (k, e) in owned {
        let path = named_output(output, &e.name)?;
        let mut overrides = base.overrides.clone();
        overrides.extend(e.overrides.iter().cloned());
        let args = RenderArgs {
            scene: e.scene.clone(),
            output: path.clone(),
            overrides,
            cameras: Cameras::Single,
            trail_range: None,
            shard: Shard::ALL,
            ..base.clone()
        };
        // A frame that failed on a key an override gave says so, as an entry that fails
        // before its frame does.
        let named = |mut o: FrameOutcome| {
            o.index = k;
            o.name = Some(e.name.clone());
            if let Some(err) = &mut o.error {
                // The entry's line first, then the override's blame, once each.
                if !err.starts_with(&e.at) {
                    *err = format!("{}: {err}", e.at);
                }
                if !err.contains(crate::spec::BLAME_PREFIX) {
                    let b = blame(err, base, e);
                    err.push_str(&b);
                }
            }
            o
        };
        let got = run_on(&args, &gpu, &mut |p| match p {
            Progress::Done(f, _) => {
                let mut f = f.clone();
                f.index = k;
                f.name = Some(e.name.clone());
                progress(Progress::Done(&f, n));
            }
            Progress::Skipped(o) => progress(Progress::Skipped(&named(o.clone()))),
            Progress::Failed(o) => progress(Progress::Failed(&named(o.clone()))),
            Progress::Stage(m) => progress(Progress::Stage(&format!("{}: {m}", e.name))),
            // Each entry's one frame: the run's count is the manifest's.
            Progress::Frames(_) => {}
        });
        match got {
            Ok(rep) => {
                if r.adapter.is_empty() {
                    r.adapter = rep.adapter.clone();
                }
                for m in rep.notes {
                    match r.notes.iter_mut().find(|(n, _)| *n == m) {
                        Some((_, names)) => names.push(e.name.clone()),
                        None => r.notes.push((m, vec![e.name.clone()])),
                    }
                }
                r.done.extend(rep.done.into_iter().map(named));
                r.skipped.extend(rep.skipped.into_iter().map(named));
                r.failed.extend(rep.failed.into_iter().map(named));
            }
            // The scene, its data or the GPU: the entry fails, the others go on.
            Err(error) => {
                let o = named(FrameOutcome {
                    index: k,
                    name: None,
                    path,
                    ms: None,
                    error: Some(error),
                });
                progress(Progress::Failed(&o));
                r.failed.push(o);
            }
        }
    }
    r.seconds = t0.elapsed().as_secs_f64();
    Ok(r)
}

/// Where an entry's error is about a key an override gave (the command's, then the line's
/// `KEY=VALUE` fields, as they applied), a sentence naming it: " (the value comes from
/// render.width=0 on m.txt: line 2, not from the scene file)"; else nothing.
fn blame(error: &str, base: &RenderArgs, e: &Entry) -> String {
    let split = |kv: &String| {
        let (k, v) = kv.split_once('=').unwrap_or((kv.as_str(), ""));
        (k.trim().to_string(), v.to_string())
    };
    let overrides: Vec<(String, String, String)> = base
        .overrides
        .iter()
        .map(|kv| {
            let (k, v) = split(kv);
            (k, v, format!("the override {kv}"))
        })
        .chain(e.overrides.iter().map(|kv| {
            let (k, v) = split(kv);
            (k, v, format!("{kv} on {}", e.at))
        }))
        .collect();
    match crate::spec::blamed_override(error, &overrides) {
        Some(label) => format!(
            " {}{label}, not from the scene file)",
            crate::spec::BLAME_PREFIX
        ),
        None => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// An entry that fails (before any frame, on a key its line gave) is recorded with its
    /// line and the override named once (it was named twice).
    #[test]
    fn a_failed_entry_names_its_line_and_the_override_once() {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("t.toml");
        std::fs::write(&scene, "[[lines]]\npath = \"a.tck\"\n").unwrap();
        let entries =
            parse_manifest("b render.width=0\n", "m.txt", dir.path(), Some(&scene)).unwrap();
        let base = RenderArgs {
            frames: 1,
            ..Default::default()
        };
        let mut failed_lines = vec![];
        let r = run_manifest(
            &entries,
            &dir.path().join("out/{name}.png"),
            &base,
            Shard::ALL,
            &mut |p| {
                if let Progress::Failed(o) = p {
                    failed_lines.push(o.error.clone().unwrap_or_default());
                }
            },
        )
        .unwrap();
        let err = r.failed[0].error.as_deref().unwrap();
        assert!(err.starts_with("m.txt: line 1: "), "{err}");
        assert_eq!(err.matches(crate::spec::BLAME_PREFIX).count(), 1, "{err}");
        assert!(err.contains("render.width=0 on m.txt: line 1"), "{err}");
        assert_eq!(failed_lines, [err.to_string()]);
    }

    #[test]
    fn an_entrys_error_about_an_overridden_key_names_the_override_that_applied_last() {
        let base = RenderArgs {
            overrides: vec!["render.width=64".into(), "slices.0.window=[0, 1]".into()],
            ..Default::default()
        };
        let e = &parse_manifest(
            "b render.width=0 camera.azimuth=10\n",
            "m.txt",
            Path::new("."),
            Some(Path::new("t.toml")),
        )
        .unwrap()[0];
        let err = "t.toml: scene key render.width: 0 pixels is not within 1..16384";
        assert_eq!(
            blame(err, &base, e),
            " (the value comes from render.width=0 on m.txt: line 1, not from the scene file)"
        );
        // The command's own override, where the line leaves the key alone.
        let err = "t.toml: scene key slices[0].window: bad";
        assert_eq!(
            blame(err, &base, e),
            " (the value comes from the override slices.0.window=[0, 1], not from the scene file)"
        );
        // A key no override set, or no key at all.
        assert_eq!(blame("t.toml: scene key render.height: bad", &base, e), "");
        assert_eq!(blame("t.toml: No such file or directory", &base, e), "");
        // A data file's path is named by the path, not its key.
        let e = &parse_manifest(
            "s tubes.0.path=sub-02/nothere.trk\n",
            "m.txt",
            Path::new("."),
            Some(Path::new("t.toml")),
        )
        .unwrap()[0];
        let err = "t.toml: tubes[0]: /data/sub-02/nothere.trk: No such file or directory";
        assert_eq!(
            blame(err, &base, e),
            " (the value comes from tubes.0.path=sub-02/nothere.trk on m.txt: line 1, not from the scene file)"
        );
        assert_eq!(
            blame("t.toml: tubes[0]: /data/other.trk: bad", &base, e),
            ""
        );
        // Only the whole file name: not one that ends or begins with it.
        let e = &parse_manifest(
            "s volume.path=a.nii\n",
            "m.txt",
            Path::new("."),
            Some(Path::new("t.toml")),
        )
        .unwrap()[0];
        assert_eq!(
            blame("t.toml: overlays[0].path (/d/fa.nii): bad", &base, e),
            ""
        );
        assert_eq!(blame("t.toml: tubes[0]: /d/a.nii.gz: bad", &base, e), "");
        assert!(blame("t.toml: tubes[0]: /d/a.nii: bad", &base, e).contains("volume.path=a.nii"));
    }

    fn env(pairs: &[(&str, &str)]) -> impl Fn(&str) -> Option<String> {
        let m: HashMap<String, String> = pairs
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        move |k| m.get(k).cloned()
    }

    #[test]
    fn shards_cover_every_frame_exactly_once() {
        for frames in [1usize, 7, 10, 1000] {
            for count in [1u32, 2, 3, 7, 10, 13] {
                let mut hits = vec![0; frames];
                for index in 0..count {
                    let s = Shard { index, count };
                    (0..frames)
                        .filter(|&k| s.owns(k))
                        .for_each(|k| hits[k] += 1);
                }
                assert!(
                    hits.iter().all(|&h| h == 1),
                    "{frames} frames, {count} shards"
                );
            }
        }
    }

    #[test]
    fn shard_flags_are_read_and_checked() {
        assert_eq!(Shard::parse("2/7"), Ok(Shard { index: 2, count: 7 }));
        assert_eq!(Shard::parse(" 0 / 1 "), Ok(Shard::ALL));
        for bad in ["7/7", "1/0", "-1/3", "1", "a/3", "1/3/4", "", "1/"] {
            assert!(
                Shard::parse(bad).unwrap_err().contains("0 <= I < N"),
                "{bad}"
            );
        }
    }

    #[test]
    fn slurm_arrays_give_the_shards_the_flag_gives() {
        // --array=0-4 and --array=1-5: the same five shards.
        for min in [0u32, 1] {
            for task in 0..5u32 {
                let (id, min_s) = ((min + task).to_string(), min.to_string());
                let max_s = (min + 4).to_string();
                let v = env(&[
                    ("SLURM_ARRAY_TASK_ID", &id),
                    ("SLURM_ARRAY_TASK_MIN", &min_s),
                    ("SLURM_ARRAY_TASK_MAX", &max_s),
                    ("SLURM_ARRAY_TASK_COUNT", "5"),
                    ("SLURM_ARRAY_TASK_STEP", "1"),
                ]);
                assert_eq!(
                    Shard::resolve(None, &v),
                    Ok((
                        Shard {
                            index: task,
                            count: 5
                        },
                        ShardFrom::Slurm
                    ))
                );
                // The flag wins over the variables.
                assert_eq!(
                    Shard::resolve(Some("0/2"), &v),
                    Ok((Shard { index: 0, count: 2 }, ShardFrom::Flag))
                );
            }
        }
        // A step of 0 is no array Slurm makes: refused, not read as 1.
        let v = env(&[
            ("SLURM_ARRAY_TASK_ID", "1"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
            ("SLURM_ARRAY_TASK_STEP", "0"),
        ]);
        assert!(Shard::resolve(None, &v).unwrap_err().contains("STEP=0"));
        // --array=10-40:10 (STEP 10): tasks 10, 20, 30, 40 are shards 0..3 of 4.
        let v = env(&[
            ("SLURM_ARRAY_TASK_ID", "30"),
            ("SLURM_ARRAY_TASK_MIN", "10"),
            ("SLURM_ARRAY_TASK_MAX", "40"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
            ("SLURM_ARRAY_TASK_STEP", "10"),
        ]);
        assert_eq!(Shard::from_slurm(v), Ok(Some(Shard { index: 2, count: 4 })));
        // Not an array task.
        assert_eq!(
            Shard::resolve(None, env(&[])),
            Ok((Shard::ALL, ShardFrom::None))
        );
        // A sparse list --array=1,4,9 (COUNT 3, MIN 1): task 9 is not shard 8 of 3.
        let v = env(&[
            ("SLURM_ARRAY_TASK_ID", "9"),
            ("SLURM_ARRAY_TASK_MIN", "1"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
        ]);
        assert!(Shard::from_slurm(v).unwrap_err().contains("sparse"));
        // ... and with MAX set (as Slurm sets it) every task of it is refused, task 1 too,
        // as is --array=0,2,3 where task 2 would pass for shard 2 of 3.
        for (id, min, max, count) in [
            ("1", "1", "9", "3"),
            ("4", "1", "9", "3"),
            ("2", "0", "3", "3"),
        ] {
            let v = env(&[
                ("SLURM_ARRAY_TASK_ID", id),
                ("SLURM_ARRAY_TASK_MIN", min),
                ("SLURM_ARRAY_TASK_MAX", max),
                ("SLURM_ARRAY_TASK_COUNT", count),
                ("SLURM_ARRAY_TASK_STEP", "1"),
            ]);
            assert!(
                Shard::from_slurm(v)
                    .unwrap_err()
                    .contains("SLURM_ARRAY_TASK_MAX"),
                "{id}"
            );
        }
        let v = env(&[("SLURM_ARRAY_TASK_ID", "3")]);
        assert!(Shard::from_slurm(v)
            .unwrap_err()
            .contains("SLURM_ARRAY_TASK_MIN is not set"));
        let v = env(&[
            ("SLURM_ARRAY_TASK_ID", "x"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_COUNT", "3"),
        ]);
        assert!(Shard::from_slurm(v)
            .unwrap_err()
            .contains("not a whole number"));
        // An evenly spaced array of more tasks than shards can be: the limit, not "sparse".
        let v = env(&[
            ("SLURM_ARRAY_TASK_ID", "4294967296"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_MAX", "4294967296"),
            ("SLURM_ARRAY_TASK_COUNT", "4294967297"),
        ]);
        let e = Shard::from_slurm(v).unwrap_err();
        assert!(
            e.contains("at most 4294967295") && !e.contains("sparse"),
            "{e}"
        );
    }

    #[test]
    fn manifests_name_scenes_or_the_template_with_overrides() {
        let dir = Path::new("/data/study");
        let text = "# participants\n\
                    sub-01 scenes/sub-01.toml\n\
                    \n\
                    sub-02 volume.path=\"/data/sub 02/T1w.nii.gz\" camera.azimuth=90\n\
                    sub-03 scenes/three.toml 'render.method=\"ea\"'  # its own scene\n";
        let e = parse_manifest(text, "m.txt", dir, Some(Path::new("/t/template.toml"))).unwrap();
        let bom = format!("\u{feff}{text}");
        assert_eq!(
            parse_manifest(&bom, "m.txt", dir, Some(Path::new("/t/template.toml"))).unwrap(),
            e
        );
        assert_eq!(e.len(), 3);
        assert_eq!(e[0].scene, dir.join("scenes/sub-01.toml"));
        assert!(e[0].overrides.is_empty());
        assert_eq!((e[0].line, e[1].line, e[2].line), (2, 4, 5));
        assert_eq!(e[1].scene, Path::new("/t/template.toml"));
        assert_eq!(
            e[1].overrides,
            ["volume.path=/data/sub 02/T1w.nii.gz", "camera.azimuth=90"]
        );
        assert_eq!(e[2].overrides, ["render.method=\"ea\""]);
        assert_eq!(e[2].name, "sub-03");
    }

    #[test]
    fn bad_manifests_are_refused_naming_the_line() {
        let t = Some(Path::new("t.toml"));
        let err = |text: &str, template| {
            parse_manifest(text, "m.txt", Path::new("."), template).unwrap_err()
        };
        assert!(err("a s.toml\nb s.toml\na s.toml\n", t)
            .contains("line 3: the name 'a' is also on line 1"));
        assert!(err("a camera.azimuth=3\n", None).contains("line 1: 'a' names no scene"));
        assert!(err("a s.toml other.toml\n", t).contains("'other.toml' is not KEY=VALUE"));
        assert!(err("a \"s.toml\n", t).contains("unbalanced quotes"));
        assert!(err("../x s.toml\n", t).contains("names become file names"));
        assert!(err("..\n", t).contains("not a name"));
        assert!(err("# nothing\n\n", t).contains("names no scene"));
    }

    #[test]
    fn a_manifest_output_needs_the_name() {
        assert_eq!(
            named_output(Path::new("out/{name}/{name}_t1.png"), "sub-01").unwrap(),
            Path::new("out/sub-01/sub-01_t1.png")
        );
        assert!(named_output(Path::new("out/x.png"), "a")
            .unwrap_err()
            .contains("{name}"));
        // Which other outputs an entry could overwrite.
        let p = Path::new("out/{name}/{name}_t1.png");
        let m = |a: &str| named_output_matches(p, Path::new(a));
        assert!(m("out/sub-01/sub-01_t1.png") && m("out/a/a_t1.png"));
        assert!(!m("out/a/b_t1.png") && !m("out/a/b/a/b_t1.png") && !m("out/_t1.png"));
        assert!(!m("out/a/a_t1.json") && !m("other/a/a_t1.png"));
        let flat = Path::new("mm/{name}.png");
        assert!(named_output_matches(flat, Path::new("mm/a.png")));
        assert!(named_output_matches(flat, Path::new("./mm/record.png")));
        assert!(!named_output_matches(flat, Path::new("mm/record.json")));
    }

    #[test]
    fn only_whole_images_of_the_right_size_are_complete() {
        let dir = tempfile::tempdir().unwrap();
        let png = dir.path().join("a.png");
        let rgb = vec![[0.5f32, 0.2, 0.1]; 8 * 6];
        crate::image_io::write_rgb_png(&png, 8, 6, &rgb).unwrap();
        assert!(complete_image(&png, 8, 6, &[]));
        assert!(!complete_image(&png, 6, 8, &[]));
        // Truncated: the first half of the file.
        let bytes = std::fs::read(&png).unwrap();
        let cut = dir.path().join("cut.png");
        std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
        assert!(!complete_image(&cut, 8, 6, &[]));
        std::fs::write(&cut, b"").unwrap();
        assert!(!complete_image(&cut, 8, 6, &[]));
        assert!(!complete_image(&dir.path().join("missing.png"), 8, 6, &[]));
        assert!(!complete_image(dir.path(), 8, 6, &[]));
        let exr = dir.path().join("a.exr");
        let rgba = vec![[0.5f32, 0.2, 0.1, 1.0]; 8 * 6];
        crate::image_io::write_exr(&exr, 8, 6, &rgba, &[]).unwrap();
        assert!(complete_image(&exr, 8, 6, &[]));
        // Without the AOVs a run asks for it is not that run's frame; with them it is.
        assert!(!complete_image(&exr, 8, 6, &["Z"]));
        let aov = dir.path().join("aov.exr");
        let z = vec![("Z".to_string(), vec![1.0f32; 8 * 6])];
        crate::image_io::write_exr(&aov, 8, 6, &rgba, &z).unwrap();
        assert!(complete_image(&aov, 8, 6, &["Z"]));
        let bytes = std::fs::read(&exr).unwrap();
        std::fs::write(&exr, &bytes[..bytes.len() - 40]).unwrap();
        assert!(!complete_image(&exr, 8, 6, &[]));
    }
}
