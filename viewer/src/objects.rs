//! The scene's objects in the viewer: the volume, `[[tubes]]`, `[[lines]]` and `[[points]]`,
//! each shown or hidden, with its size and colour editable, removable; `[[slices]]`, each
//! shown or hidden, with its position, opacity and lighting editable; and files opened into
//! the scene (typed, chosen in the file dialog or dropped on the window): a volume replaces the scene's volume, a
//! tractogram is added as `[[lines]]`, a mesh as `[[tubes]]`. A hidden object is left out of the
//! scene the renderer draws and the saved scene (what you see is what you save).

use eframe::egui;
use scene::spec::Scene;
use std::path::Path;

/// What a file is, by its name (and, for `.vtk`, its header).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Volume,
    Lines,
    Mesh,
}

/// The kind of a file to open, or why it cannot be opened (naming the file).
pub fn classify(path: &Path) -> Result<Kind, String> {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let ext = extension(&name);
    if !path.is_file() {
        return Err(format!("{}: no such file", path.display()));
    }
    Ok(match ext {
        "nii" | "hdr" | "nrrd" | "nhdr" | "vti" | "mhd" | "mha" | "slc" => Kind::Volume,
        "trk" | "tck" | "trx" => Kind::Lines,
        "ply" | "obj" => Kind::Mesh,
        "vtk" => {
            // Legacy VTK: polydata lines a tractogram, anything else a volume (or its error).
            if tubes::vtk_dataset(path).is_some_and(|d| d == "POLYDATA") {
                Kind::Lines
            } else {
                Kind::Volume
            }
        }
        _ => {
            return Err(format!(
                "{}: not a volume (.nii, .nii.gz, .nrrd, .nhdr, .vti, .mhd, .mha, .slc, .vtk), \
                 tractogram (.trk, .tck, .trx, .vtk) or mesh (.ply, .obj)",
                path.display()
            ))
        }
    })
}

/// A lower-case name's extension, `.gz` looked through.
fn extension(name: &str) -> &str {
    let stem = name.strip_suffix(".gz").unwrap_or(name);
    stem.rsplit_once('.').map_or("", |(_, e)| e)
}

/// The extensions `classify` knows (the file dialog lists these files and every folder).
const OPENABLE: &[&str] = &[
    "nii", "hdr", "nrrd", "nhdr", "vti", "mhd", "mha", "slc", "trk", "tck", "trx", "ply", "obj",
    "vtk",
];

/// Whether the file dialog lists `path`: a folder, or a file with an extension of `OPENABLE`.
pub fn listed(path: &Path) -> bool {
    path.is_dir()
        || path.file_name().is_some_and(|n| {
            OPENABLE.contains(&extension(&n.to_string_lossy().to_ascii_lowercase()))
        })
}

/// The file dialog ("browse"): an egui window over one folder at a time, listing its folders
/// (with a trailing `/`) and the files `classify` knows, "..", and open/cancel. Drawn by egui
/// itself, so it needs no GTK or desktop portal and works under Xvfb and in the UI tests.
#[derive(Default)]
pub struct Browser {
    state: Option<Shown>,
}

/// The open dialog: its folder (canonical), that folder's listing (read once per folder) and
/// the chosen file.
struct Shown {
    dir: std::path::PathBuf,
    listing: Result<Vec<Entry>, String>,
    chosen: Option<std::path::PathBuf>,
}

/// An entry of the dialog's listing.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Entry {
    pub path: std::path::PathBuf,
    pub dir: bool,
}

/// A folder's entries the dialog lists (hidden ones left out): folders first, then files, each
/// by name, case-insensitively.
pub fn entries(dir: &Path) -> std::io::Result<Vec<Entry>> {
    let mut v: Vec<Entry> = std::fs::read_dir(dir)?
        .filter_map(|e| e.ok())
        .filter(|e| !e.file_name().to_string_lossy().starts_with('.'))
        .map(|e| {
            let path = e.path();
            // A link is listed as what it points to.
            let dir = match e.file_type() {
                Ok(t) if !t.is_symlink() => t.is_dir(),
                _ => path.is_dir(),
            };
            Entry { path, dir }
        })
        .filter(|e| e.dir || listed(&e.path))
        .collect();
    v.sort_by_cached_key(|e| {
        (
            !e.dir,
            e.path
                .file_name()
                .map(|n| n.to_string_lossy().to_lowercase()),
        )
    });
    Ok(v)
}

impl Shown {
    fn at(dir: std::path::PathBuf) -> Shown {
        let dir = std::fs::canonicalize(&dir)
            .or_else(|_| std::path::absolute(&dir))
            .unwrap_or(dir);
        let listing = entries(&dir).map_err(|e| format!("{}: {e}", dir.display()));
        Shown {
            dir,
            listing,
            chosen: None,
        }
    }
}

impl Browser {
    /// Opens the dialog in `start` when it is a folder, in the folder of `start` when it is a
    /// file's path, else in the working directory.
    pub fn open(&mut self, start: &Path) {
        let dir = if start.is_dir() {
            Some(start.to_path_buf())
        } else {
            start
                .parent()
                .filter(|p| !p.as_os_str().is_empty() && p.is_dir())
                .map(Path::to_path_buf)
        };
        let dir = dir
            .or_else(|| std::env::current_dir().ok())
            .unwrap_or_else(|| ".".into());
        self.state = Some(Shown::at(dir));
    }

    pub fn is_open(&self) -> bool {
        self.state.is_some()
    }

    /// Shows the dialog while it is open; the chosen file, once.
    pub fn show(&mut self, ctx: &egui::Context) -> Option<std::path::PathBuf> {
        let shown = self.state.as_mut()?;
        let mut open = true;
        let mut done = None;
        let mut go_to = None;
        let mut cancel = false;
        egui::Window::new("open a volume, tractogram or mesh")
            .open(&mut open)
            .collapsible(false)
            .default_size([420.0, 360.0])
            .show(ctx, |ui| {
                ui.horizontal(|ui| {
                    if ui.button("..").on_hover_text("the parent folder").clicked() {
                        go_to = shown.dir.parent().map(Path::to_path_buf);
                    }
                    ui.label(shown.dir.display().to_string());
                });
                ui.separator();
                egui::ScrollArea::vertical()
                    .max_height(260.0)
                    .show(ui, |ui| match &shown.listing {
                        Ok(list) if list.is_empty() => {
                            ui.label("no folders or files to open here");
                        }
                        Ok(list) => {
                            for e in list {
                                let name = e
                                    .path
                                    .file_name()
                                    .map(|n| n.to_string_lossy().into_owned())
                                    .unwrap_or_default();
                                if e.dir {
                                    if ui.selectable_label(false, format!("{name}/")).clicked() {
                                        go_to = Some(e.path.clone());
                                    }
                                } else {
                                    let r = ui.selectable_label(
                                        shown.chosen.as_ref() == Some(&e.path),
                                        name,
                                    );
                                    if r.double_clicked() {
                                        done = Some(e.path.clone());
                                    }
                                    if r.clicked() {
                                        shown.chosen = Some(e.path.clone());
                                    }
                                }
                            }
                        }
                        Err(e) => {
                            ui.colored_label(egui::Color32::RED, e);
                        }
                    });
                ui.separator();
                ui.horizontal(|ui| {
                    if ui
                        .add_enabled(shown.chosen.is_some(), egui::Button::new("open file"))
                        .clicked()
                    {
                        done = shown.chosen.clone();
                    }
                    cancel |= ui.button("cancel").clicked();
                });
            });
        if let Some(d) = go_to {
            *shown = Shown::at(d);
        }
        if cancel {
            done = None;
        }
        if done.is_some() || cancel || !open || ctx.input(|i| i.key_pressed(egui::Key::Escape)) {
            self.state = None;
        }
        done
    }
}

/// Adds the file at `path` to scene `s` (with the scene keys' defaults); what was done.
pub fn open(s: &mut Scene, path: &Path) -> Result<String, String> {
    let kind = classify(path)?;
    let p = std::path::absolute(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let toml = match kind {
        Kind::Volume => format!("[volume]\npath = {:?}\n", p.display().to_string()),
        Kind::Lines => format!("[[lines]]\npath = {:?}\n", p.display().to_string()),
        Kind::Mesh => format!("[[tubes]]\npath = {:?}\n", p.display().to_string()),
    };
    let add = scene::spec::parse(&toml, "the opened file", Path::new("."), &[])?;
    Ok(match kind {
        Kind::Volume => {
            // A scene that keeps its volume as the slices' grid only (`render = false`) keeps
            // the new one so: a slices figure does not start drawing the volume behind them.
            let grid_only = s.volume.as_ref().is_some_and(|v| !v.render);
            s.volume = add.volume;
            match (grid_only, s.volume.as_mut()) {
                (true, Some(v)) => {
                    v.render = false;
                    format!(
                        "opened {} as the volume, not drawn as the one it replaces (tick \"volume\" to draw it)",
                        p.display()
                    )
                }
                _ => format!("opened {} as the volume", p.display()),
            }
        }
        Kind::Lines => {
            s.lines.extend(add.lines);
            format!("opened {} as lines[{}]", p.display(), s.lines.len() - 1)
        }
        Kind::Mesh => {
            s.tubes.extend(add.tubes);
            format!("opened {} as tubes[{}]", p.display(), s.tubes.len() - 1)
        }
    })
}

/// A scene's objects and which are hidden: what the objects panel and opening a file change,
/// put back as a whole when an opened file turns out unreadable.
#[derive(Clone, Debug, PartialEq)]
pub struct Objects {
    volume: Option<scene::spec::VolumeSpec>,
    tubes: Vec<scene::spec::TubesSpec>,
    lines: Vec<scene::spec::LinesSpec>,
    points: Vec<scene::spec::PointsSpec>,
    slices: Vec<scene::spec::SliceSpec>,
    hidden: Hidden,
}

impl Objects {
    pub fn of(s: &Scene, hidden: &Hidden) -> Objects {
        Objects {
            volume: s.volume.clone(),
            tubes: s.tubes.clone(),
            lines: s.lines.clone(),
            points: s.points.clone(),
            slices: s.slices.clone(),
            hidden: hidden.clone(),
        }
    }

    /// Puts these objects back into `s` and `hidden`.
    pub fn restore(self, s: &mut Scene, hidden: &mut Hidden) {
        s.volume = self.volume;
        s.tubes = self.tubes;
        s.lines = self.lines;
        s.points = self.points;
        s.slices = self.slices;
        *hidden = self.hidden;
    }
}

/// The grid slices cut (the scene volume's voxel centres, `dims` and index-to-world
/// `affine`) and the volume's `bounds` (a slice's default position is their centre): what the
/// slices' position fields span.
#[derive(Clone, Debug, PartialEq)]
pub struct SliceGrid {
    pub dims: [usize; 3],
    pub affine: glam::DMat4,
    pub bounds: [glam::DVec3; 2],
    /// Whether the grid is in RAS+ millimetres (its positions read "mm"; else "units").
    pub ras: bool,
}

impl SliceGrid {
    /// The grid of model `m`'s slices (none without slices or overlays).
    pub fn of(m: &scene::compile::Model) -> Option<SliceGrid> {
        m.planes.as_ref().map(|p| SliceGrid {
            dims: p.dims,
            affine: p.affine,
            bounds: p.bounds,
            ras: m.is_ras(),
        })
    }

    /// Where slice `sl` is (its position, or the default) and the span of positions where it
    /// cuts the grid.
    pub fn position(&self, sl: &scene::spec::SliceSpec) -> (f64, [f64; 2]) {
        let n = scene::slices::normal(sl);
        (
            scene::slices::position(sl, self.bounds),
            scene::slices::extent(self.dims, self.affine, n),
        )
    }
}

/// Which objects are hidden, by kind and index.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Hidden {
    pub volume: bool,
    pub tubes: Vec<bool>,
    pub lines: Vec<bool>,
    pub points: Vec<bool>,
    pub slices: Vec<bool>,
}

impl Hidden {
    /// Flags for every object of `s` (new objects are shown).
    fn fit(&mut self, s: &Scene) {
        self.tubes.resize(s.tubes.len(), false);
        self.lines.resize(s.lines.len(), false);
        self.points.resize(s.points.len(), false);
        self.slices.resize(s.slices.len(), false);
    }

    /// `s` without its hidden objects.
    pub fn apply(&self, s: &Scene) -> Scene {
        let keep = |flags: &[bool], i: usize| !flags.get(i).copied().unwrap_or(false);
        let mut d = s.clone();
        if self.volume {
            // Slices and overlays sample the volume's grid: with any, the volume stays in the
            // scene, not drawn.
            match (
                s.slices.is_empty() && s.overlays.is_empty(),
                d.volume.as_mut(),
            ) {
                (false, Some(v)) => v.render = false,
                _ => d.volume = None,
            }
        }
        d.tubes = s
            .tubes
            .iter()
            .enumerate()
            .filter(|(i, _)| keep(&self.tubes, *i))
            .map(|(_, t)| t.clone())
            .collect();
        d.lines = s
            .lines
            .iter()
            .enumerate()
            .filter(|(i, _)| keep(&self.lines, *i))
            .map(|(_, t)| t.clone())
            .collect();
        d.points = s
            .points
            .iter()
            .enumerate()
            .filter(|(i, _)| keep(&self.points, *i))
            .map(|(_, t)| t.clone())
            .collect();
        d.slices = s
            .slices
            .iter()
            .enumerate()
            .filter(|(i, _)| keep(&self.slices, *i))
            .map(|(_, t)| t.clone())
            .collect();
        // A colour bar of an entry follows it to its index among those kept, and goes with
        // it (or with the volume) when it is hidden: the saved scene renders as shown.
        if let Some(src) = d.annotate.colorbar.clone() {
            let hidden: Option<&[bool]> = match src.split_once('.') {
                Some(("tubes", _)) => Some(&self.tubes),
                Some(("lines", _)) => Some(&self.lines),
                Some(("points", _)) => Some(&self.points),
                Some(("slices", _)) => Some(&self.slices),
                _ => None,
            };
            let index = src
                .split_once('.')
                .and_then(|(_, n)| n.parse::<usize>().ok());
            d.annotate.colorbar = match (hidden, index) {
                (Some(flags), Some(i)) if !keep(flags, i) => None,
                (Some(flags), Some(i)) => {
                    let before = (0..i).filter(|&k| !keep(flags, k)).count();
                    let kind = src.split_once('.').map_or("", |(k, _)| k);
                    Some(format!("{kind}.{}", i - before))
                }
                _ if src == "volume" && d.volume.as_ref().is_none_or(|v| !v.render) => None,
                _ => Some(src),
            };
        }
        d
    }
}

/// One row of an object: shown, its name, a size and a colour, remove. True when removed.
fn row(
    ui: &mut egui::Ui,
    key: &str,
    path: &Path,
    shown: &mut bool,
    size: Option<(&mut f64, &str)>,
    color: &mut String,
) -> bool {
    let mut remove = false;
    ui.horizontal(|ui| {
        ui.checkbox(shown, key)
            .on_hover_text(path.display().to_string());
        if let Some((v, unit)) = size {
            ui.add(
                egui::DragValue::new(v)
                    .range(1e-3..=1e3)
                    .speed(0.02)
                    .suffix(unit),
            );
        }
        if ui.small_button("remove").clicked() {
            remove = true;
        }
    });
    ui.horizontal(|ui| {
        let l = ui.label("  color");
        ui.add(egui::TextEdit::singleline(color).desired_width(ui.available_width()))
            .labelled_by(l.id);
    });
    remove
}

/// One slice's rows: shown and `lit`, its position (world units along its normal, within the
/// grid), window (`default`, `full` or `robust`) and opacity; the fields are labelled
/// `  slices[i] position`, `  slices[i] window` and `  slices[i] opacity`.
fn slice_row(
    ui: &mut egui::Ui,
    i: usize,
    sl: &mut scene::spec::SliceSpec,
    hidden: &mut bool,
    g: &SliceGrid,
    windowed: bool,
) {
    let (at, [lo, hi]) = g.position(sl);
    let what = match sl.axis {
        Some(a) => format!("{a:?}").to_lowercase(),
        None => "oblique".into(),
    };
    ui.horizontal(|ui| {
        let mut shown = !*hidden;
        ui.checkbox(&mut shown, format!("slices[{i}]"))
            .on_hover_text(format!("{what} slice, {lo:.1} to {hi:.1} along its normal"));
        *hidden = !shown;
        ui.checkbox(&mut sl.lit, "lit")
            .on_hover_text("lit by the head light (else its colours unshaded)");
    });
    ui.horizontal(|ui| {
        let l = ui.label(format!("  slices[{i}] position"));
        let mut p = at;
        let r = ui
            .add(
                egui::DragValue::new(&mut p)
                    .range(lo..=hi)
                    .speed(((hi - lo) / 300.0).max(1e-6))
                    // A drag keeps the shown decimals: two, so that steps under a millimetre
                    // (a 300th of the span) are not rounded to whole ones.
                    .min_decimals(2)
                    .suffix(if g.ras { " mm" } else { " units" }),
            )
            .labelled_by(l.id);
        if r.changed() && p != at {
            sl.position = Some(p);
        }
    });
    // The window: the scene's (`volume.window`, else the field's finite range), the full
    // range or the robust one; values given in the scene stay until another is chosen.
    use scene::spec::Window;
    // (None for a label overlay's slice: its colours are the labels'.)
    if windowed {
        let shown = match &sl.window {
            None => "default".to_string(),
            Some(Window::Named(n)) => n.clone(),
            Some(Window::Values([a, b])) => format!("[{a}, {b}]"),
        };
        egui::ComboBox::from_label(format!("  slices[{i}] window"))
            .selected_text(shown)
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut sl.window, None, "default");
                for n in ["full", "robust"] {
                    ui.selectable_value(&mut sl.window, Some(Window::Named(n.into())), n);
                }
            });
    }
    ui.horizontal(|ui| {
        let l = ui.label(format!("  slices[{i}] opacity"));
        ui.add(
            egui::DragValue::new(&mut sl.opacity)
                .range(0.0..=1.0)
                .speed(0.01),
        )
        .labelled_by(l.id);
    });
}

/// Where the objects panel's fields are: the camera's target (transforms turn and scale about
/// it) and the grid the slices cut (their positions span it; none: no slice rows).
#[derive(Clone, Copy, Debug)]
pub struct Place<'a> {
    pub pivot: [f64; 3],
    pub grid: Option<&'a SliceGrid>,
}

/// The objects panel and the file field; true when the scene changed. `to_open` receives the
/// file the field asks to open (the caller opens it: [`open`]).
pub fn panel(
    ui: &mut egui::Ui,
    s: &mut Scene,
    hidden: &mut Hidden,
    open_path: &mut String,
    to_open: &mut Option<std::path::PathBuf>,
    place: Place,
    browse: &mut bool,
) -> bool {
    let (pivot, grid) = (place.pivot, place.grid);
    hidden.fit(s);
    let before = Objects::of(s, hidden);
    if let Some(v) = s.volume.as_mut() {
        // Shown: drawn. A volume the scene does not draw (`render = false`, its slices' grid)
        // is shown by drawing it.
        let was = !hidden.volume && v.render;
        let mut shown = was;
        ui.checkbox(&mut shown, "volume")
            .on_hover_text(v.path.display().to_string());
        if shown != was {
            hidden.volume = !shown;
            if shown {
                v.render = true;
            }
        }
    }
    let mut remove = None;
    for (i, t) in s.tubes.iter_mut().enumerate() {
        let mut shown = !hidden.tubes[i];
        let path = t.path.clone();
        if row(
            ui,
            &format!("tubes[{i}]"),
            &path,
            &mut shown,
            Some((&mut t.radius, " radius")),
            &mut t.color,
        ) {
            remove = Some(("tubes", i));
        }
        crate::transform::editor(ui, &format!("tubes[{i}]"), &mut t.transform, pivot);
        hidden.tubes[i] = !shown;
    }
    for (i, l) in s.lines.iter_mut().enumerate() {
        let mut shown = !hidden.lines[i];
        let path = l.path.clone();
        if row(
            ui,
            &format!("lines[{i}]"),
            &path,
            &mut shown,
            Some((&mut l.width, " width")),
            &mut l.color,
        ) {
            remove = Some(("lines", i));
        }
        crate::transform::editor(ui, &format!("lines[{i}]"), &mut l.transform, pivot);
        hidden.lines[i] = !shown;
    }
    for (i, p) in s.points.iter_mut().enumerate() {
        let mut shown = !hidden.points[i];
        let path = p.path.clone();
        if row(
            ui,
            &format!("points[{i}]"),
            &path,
            &mut shown,
            Some((&mut p.size, " size")),
            &mut p.color,
        ) {
            remove = Some(("points", i));
        }
        crate::transform::editor(ui, &format!("points[{i}]"), &mut p.transform, pivot);
        hidden.points[i] = !shown;
    }
    if let Some(g) = grid {
        // Slices of a label overlay take the labels' colours: no window.
        let labels: Vec<String> = s
            .overlays
            .iter()
            .filter(|o| o.labels)
            .map(|o| o.name.clone())
            .collect();
        for (i, sl) in s.slices.iter_mut().enumerate() {
            let windowed = sl.volume.as_ref().is_none_or(|v| !labels.contains(v));
            slice_row(ui, i, sl, &mut hidden.slices[i], g, windowed);
        }
    }
    match remove {
        Some(("tubes", i)) => {
            s.tubes.remove(i);
            hidden.tubes.remove(i);
        }
        Some(("lines", i)) => {
            s.lines.remove(i);
            hidden.lines.remove(i);
        }
        Some(("points", i)) => {
            s.points.remove(i);
            hidden.points.remove(i);
        }
        _ => {}
    }
    // The field as wide as the panel leaves it, the buttons on a row of their own: a row
    // wider than the panel put "browse…" under its edge.
    let mut enter = false;
    ui.horizontal(|ui| {
        let l = ui.label("open");
        let r = ui
            .add(egui::TextEdit::singleline(open_path).desired_width(ui.available_width()))
            .labelled_by(l.id);
        enter = r.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
    });
    ui.horizontal(|ui| {
        *browse |= ui.button("browse…").clicked();
        let go = ui.button("add").clicked() || enter;
        if go && !open_path.trim().is_empty() {
            *to_open = Some(open_path.trim().into());
        }
    });
    ui.label(egui::RichText::new("a path, the file dialog, or drop a file on the window").small());
    hidden.fit(s);
    before != Objects::of(s, hidden)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn root() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .parent()
            .unwrap()
            .to_path_buf()
    }

    #[test]
    fn files_open_by_kind_and_bad_ones_say_why() {
        let r = root();
        let mut s = scene::spec::parse("", "empty", Path::new("."), &[]).unwrap();
        let vol = r.join("datasets/vtk/headsq_64x64x93.nhdr");
        assert!(open(&mut s, &vol).unwrap().contains("as the volume"));
        assert!(s.volume.as_ref().unwrap().path.is_absolute());
        assert!(s.volume.as_ref().unwrap().render);
        // In place of a volume kept as the slices' grid only, the new one is not drawn either.
        s.volume.as_mut().unwrap().render = false;
        let mni = r.join("datasets/mni/mni_icbm152_t1_tal_nlin_sym_09a.nii.gz");
        assert!(open(&mut s, &mni).unwrap().contains("not drawn"));
        assert!(!s.volume.as_ref().unwrap().render);
        assert!(s
            .volume
            .as_ref()
            .unwrap()
            .path
            .ends_with("mni_icbm152_t1_tal_nlin_sym_09a.nii.gz"));
        s.volume.as_mut().unwrap().render = true;
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("notes.txt");
        std::fs::write(&bad, "x").unwrap();
        let e = open(&mut s, &bad).unwrap_err();
        assert!(e.contains("notes.txt") && e.contains("tractogram"), "{e}");
        let e = open(&mut s, &dir.path().join("missing.trk")).unwrap_err();
        assert!(
            e.contains("missing.trk") && e.contains("no such file"),
            "{e}"
        );
        // A legacy VTK file is a volume by its header, else lines.
        let img = dir.path().join("a.vtk");
        std::fs::write(
            &img,
            "# vtk DataFile Version 3.0\nx\nASCII\nDATASET STRUCTURED_POINTS\n",
        )
        .unwrap();
        assert_eq!(classify(&img).unwrap(), Kind::Volume);
        let poly = dir.path().join("b.vtk");
        std::fs::write(
            &poly,
            "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\n",
        )
        .unwrap();
        assert_eq!(classify(&poly).unwrap(), Kind::Lines);
        let mesh = dir.path().join("m.ply");
        std::fs::write(&mesh, "ply\n").unwrap();
        assert!(open(&mut s, &mesh).unwrap().contains("tubes[0]"));
        assert_eq!(s.tubes.len(), 1);
    }

    #[test]
    fn hidden_objects_are_left_out_of_the_drawn_scene() {
        let r = root();
        let mut s = scene::spec::parse("", "empty", Path::new("."), &[]).unwrap();
        open(&mut s, &r.join("datasets/vtk/headsq_64x64x93.nhdr")).unwrap();
        let dir = tempfile::tempdir().unwrap();
        for n in ["a.ply", "b.ply", "c.ply"] {
            let p = dir.path().join(n);
            std::fs::write(&p, "ply\n").unwrap();
            open(&mut s, &p).unwrap();
        }
        let mut h = Hidden::default();
        h.fit(&s);
        h.tubes[1] = true;
        h.volume = true;
        let d = h.apply(&s);
        assert!(d.volume.is_none());
        let names: Vec<_> = d
            .tubes
            .iter()
            .map(|t| t.path.file_name().unwrap().to_owned())
            .collect();
        assert_eq!(names, ["a.ply", "c.ply"]);
        assert_eq!(h.apply(&s).tubes.len(), 2);
        assert_eq!(Hidden::default().apply(&s), s);
        // With slices the hidden volume stays as their grid, not drawn; a hidden slice is
        // left out.
        let mut t = s.clone();
        let text = format!(
            "[volume]\npath = \"{}\"\n[[slices]]\naxis = \"axial\"\n[[slices]]\naxis = \"coronal\"\n",
            r.join("datasets/vtk/headsq_64x64x93.nhdr").display()
        );
        t.slices = scene::spec::parse(&text, "slices", Path::new("."), &[])
            .unwrap()
            .slices;
        h.fit(&t);
        h.slices[0] = true;
        let d = h.apply(&t);
        assert!(d.volume.as_ref().is_some_and(|v| !v.render));
        assert_eq!(d.slices.len(), 1);
        assert_eq!(d.slices[0].axis, Some(scene::spec::SliceAxis::Coronal));
        // A colour bar follows its entry's index, and goes with it or with the volume.
        let bar = |t: &Scene, h: &Hidden, src: &str| {
            let mut t = t.clone();
            t.annotate.colorbar = Some(src.into());
            h.apply(&t).annotate.colorbar
        };
        assert_eq!(bar(&t, &h, "slices.1").as_deref(), Some("slices.0"));
        assert_eq!(bar(&t, &h, "slices.0"), None);
        assert_eq!(bar(&t, &h, "volume"), None);
        h.tubes = vec![true, false, false];
        assert_eq!(bar(&s, &h, "tubes.2").as_deref(), Some("tubes.1"));
        assert_eq!(bar(&s, &h, "tubes.0"), None);
        assert_eq!(
            bar(&s, &Hidden::default(), "tubes.2").as_deref(),
            Some("tubes.2")
        );
    }
}
