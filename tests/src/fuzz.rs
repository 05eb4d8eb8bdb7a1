//! What every fuzz target asserts, beyond "no panic" (issue 17): the fuzz targets in `fuzz/`
//! call [`run`] on libFuzzer's inputs, and `tests/tests/fuzz_corpora.rs` replays the kept
//! corpora and regressions through the same function on stable, in CI.
//!
//! An input is written to a file named as its format's files are (`input.nii`, `input.trk`, ...)
//! in a per-process folder, then read by the public loader a user's command calls. When the
//! loader accepts it:
//! * volumes: every field has the grid's size; spacings are within
//!   [`volume::MIN_SPACING`, `volume::MAX_SPACING`], the affine and the bounds are finite, and the
//!   samples' memory (as `f32`) is at most [`AMPLIFICATION`] times the input plus 1 MiB (a file
//!   that names another data file is exempt: its data are elsewhere);
//! * CFD grids: finite bounds, every array sized for the points or the cells;
//! * tractograms: valid offsets and attributes, finite bounds of the finite points, and at most
//!   [`AMPLIFICATION`] bytes of points per input byte (plus 1 MiB);
//! * meshes: indices within the vertices, finite positions and normals;
//! * scenes: every camera and render number finite;
//! * point clouds: valid, finite bounds, bounded as tractograms;
//! * colour tables: named entries, no more than the input's bytes.
//!
//! A property that fails panics, which libFuzzer reports as a crash.

use std::path::{Path, PathBuf};

/// The most memory an accepted input may make per input byte: gzip's and zlib's largest
/// ratio (1032:1) times four (8-bit samples held as `f32`), rounded up.
pub const AMPLIFICATION: usize = 4200;

/// A fuzz target: a reader (or the scene parser) and the file name its inputs get.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    Nifti,
    NiftiGz,
    Nrrd,
    VtkVolume,
    VtkGrid,
    VtkXmlImage,
    VtkXmlGrid,
    MetaImage,
    Slc,
    Plot3d,
    Trk,
    Tck,
    VtkLines,
    Trx,
    Ply,
    Obj,
    Scene,
    Points,
    Lut,
}

impl Target {
    pub const ALL: [Target; 19] = [
        Target::Nifti,
        Target::NiftiGz,
        Target::Nrrd,
        Target::VtkVolume,
        Target::VtkGrid,
        Target::VtkXmlImage,
        Target::VtkXmlGrid,
        Target::MetaImage,
        Target::Slc,
        Target::Plot3d,
        Target::Trk,
        Target::Tck,
        Target::VtkLines,
        Target::Trx,
        Target::Ply,
        Target::Obj,
        Target::Scene,
        Target::Points,
        Target::Lut,
    ];

    /// The target's name: its fuzz binary, corpus and dictionary are named so.
    pub fn name(self) -> &'static str {
        match self {
            Target::Nifti => "nifti",
            Target::NiftiGz => "nifti_gz",
            Target::Nrrd => "nrrd",
            Target::VtkVolume => "vtk_volume",
            Target::VtkGrid => "vtk_grid",
            Target::VtkXmlImage => "vtk_xml_image",
            Target::VtkXmlGrid => "vtk_xml_grid",
            Target::MetaImage => "metaimage",
            Target::Slc => "slc",
            Target::Plot3d => "plot3d",
            Target::Trk => "trk",
            Target::Tck => "tck",
            Target::VtkLines => "vtk_lines",
            Target::Trx => "trx",
            Target::Ply => "ply",
            Target::Obj => "obj",
            Target::Scene => "scene",
            Target::Points => "points",
            Target::Lut => "lut",
        }
    }

    /// The file name an input is written under (the loaders choose readers by name).
    pub fn file_name(self) -> &'static str {
        match self {
            Target::Nifti => "input.nii",
            Target::NiftiGz => "input.nii.gz",
            Target::Nrrd => "input.nrrd",
            Target::VtkVolume | Target::VtkGrid => "input.vtk",
            Target::VtkXmlImage => "input.vti",
            Target::VtkXmlGrid => "input.vtu",
            Target::MetaImage => "input.mha",
            Target::Slc => "input.slc",
            Target::Plot3d => "input.xyz",
            Target::Trk => "input.trk",
            Target::Tck => "input.tck",
            Target::VtkLines => "input.lines.vtk",
            Target::Trx => "input.trx",
            Target::Ply => "input.ply",
            Target::Obj => "input.obj",
            Target::Scene => "input.toml",
            Target::Points => "input.csv",
            Target::Lut => "input.lut.txt",
        }
    }

    pub fn from_name(name: &str) -> Option<Target> {
        Target::ALL.into_iter().find(|t| t.name() == name)
    }
}

/// This process's scratch folder (in /dev/shm where it exists: no disk writes per input).
fn scratch() -> &'static Path {
    static DIR: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        let base = Path::new("/dev/shm");
        let base = if base.is_dir() {
            base.to_path_buf()
        } else {
            std::env::temp_dir()
        };
        let d = base.join(format!("umbra-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    })
}

/// Whether the input names a data file beside it (NRRD `data file`, MetaImage
/// `ElementDataFile` other than LOCAL): its samples then come from elsewhere.
fn names_other_file(data: &[u8]) -> bool {
    let text = String::from_utf8_lossy(&data[..data.len().min(1 << 16)]).to_ascii_lowercase();
    text.contains("data file")
        || text.contains("datafile")
        || (text.contains("elementdatafile") && !text.contains("local"))
}

/// Reads `data` as `target` reads its files and asserts the properties above when it is
/// accepted; errors are fine, panics and violated properties are not.
pub fn run(target: Target, data: &[u8]) {
    let dir = scratch();
    // Threads (the replay test) get their own file.
    let tid = format!("{:?}", std::thread::current().id())
        .chars()
        .filter(|c| c.is_ascii_digit())
        .collect::<String>();
    let sub = dir.join(tid);
    std::fs::create_dir_all(&sub).unwrap();
    let path = sub.join(target.file_name());
    if target == Target::Trx {
        // A directory left by an earlier input is no file to write over.
        let _ = std::fs::remove_dir_all(&path);
    }
    std::fs::write(&path, data).unwrap();
    let limit = AMPLIFICATION.saturating_mul(data.len()) + (1 << 20);
    match target {
        Target::Nifti
        | Target::NiftiGz
        | Target::Nrrd
        | Target::VtkVolume
        | Target::VtkXmlImage
        | Target::MetaImage
        | Target::Slc => {
            if let Ok(v) = volume::load(&path) {
                check_volume(&v, (!names_other_file(data)).then_some(limit));
            }
        }
        Target::VtkGrid | Target::VtkXmlGrid | Target::Plot3d => {
            if let Ok((g, _)) = volume::load_grid(&path, None) {
                let [lo, hi] = g.bounds();
                assert!(lo.is_finite() && hi.is_finite(), "grid bounds {lo} {hi}");
                let (np, nc) = (g.n_points(), g.n_cells());
                for a in &g.arrays {
                    let n = a.data.len() / a.components.max(1);
                    let want = if a.on_cells { nc } else { np };
                    assert_eq!(n, want, "array {} of {n} tuples", a.name);
                }
            }
        }
        Target::Trk | Target::Tck | Target::VtkLines | Target::Trx => {
            if let Ok(s) = tubes::load(&path) {
                s.validate().unwrap();
                if let Some([lo, hi]) = s.bounds() {
                    assert!(lo.is_finite() && hi.is_finite());
                }
                assert!(s.points.len() * 12 <= limit, "{} points", s.points.len());
            }
        }
        Target::Ply | Target::Obj => {
            if let Ok(m) = tubes::mesh_io::read(&path) {
                let n = m.positions.len();
                assert!(m.indices.iter().all(|&i| (i as usize) < n));
                assert!(m.origin.is_finite());
                assert!(m.positions.iter().all(|p| p.is_finite()));
                assert!(m.normals.iter().all(|p| p.is_finite()));
            }
        }
        Target::Points => {
            if let Ok(s) = tubes::points::read(&path) {
                s.validate().unwrap();
                if let Some([lo, hi]) = s.bounds() {
                    assert!(lo.is_finite() && hi.is_finite());
                }
                assert!(s.points.len() * 12 <= limit, "{} points", s.points.len());
            }
        }
        Target::Lut => {
            if let Ok(t) = volume::labels::read_lut(&path) {
                // Every entry named, at most one a line of the input.
                assert!(t.entries.values().all(|e| !e.name.is_empty()));
                assert!(t.entries.len() <= data.iter().filter(|&&b| b == b'\n').count() + 1);
            }
        }
        Target::Scene => {
            if let Ok(text) = std::str::from_utf8(data) {
                if let Ok(s) = scene::spec::parse(text, "input.toml", dir, &[]) {
                    let c = &s.camera;
                    assert!(c.distance.is_finite() && c.fov_y.is_finite());
                    assert!(c.azimuth.is_finite() && c.elevation.is_finite());
                    assert!(s.clip.len() <= 8);
                    assert!(s
                        .clip
                        .iter()
                        .all(|p| p.normal.iter().all(|v| v.is_finite())));
                }
            }
        }
    }
}

/// The volume properties of the module doc; `limit` bounds the samples' bytes.
pub fn check_volume(v: &volume::Volume, limit: Option<usize>) {
    v.validate().unwrap();
    for s in v.spacing() {
        assert!(
            (volume::MIN_SPACING..=volume::MAX_SPACING).contains(&s),
            "spacing {s}"
        );
    }
    assert!(v.affine.to_cols_array().iter().all(|x| x.is_finite()));
    let [lo, hi] = v.bounds();
    assert!(lo.is_finite() && hi.is_finite(), "bounds {lo} {hi}");
    let bytes: usize = v.fields.iter().map(|f| f.data.len() * 4).sum();
    if let Some(l) = limit {
        assert!(
            bytes <= l,
            "{bytes} bytes of samples from a {}-byte bound",
            l
        );
    }
}
