//! The transfer-function editor: `[volume.transfer]` over the data's histogram. A preset
//! (`grey`, `bone`, `fire`, `cool-warm`: ramps over the data's range, transparent below 10% of
//! it, `extinction` at the top) or piecewise-linear points (`value`, `color`, `extinction` per
//! world unit), shown as the extinction curve over the histogram (linear or log scale) with
//! each point a handle: drag it to move its value and extinction, or type them in the list.
//! 2-D functions (`points (2-D)`: rows of points by gradient magnitude) show a curve per row
//! and a gradient column in the list, and are drawn in the second tab, "value × gradient", over
//! the data's value x gradient-magnitude histogram: a row is a line of handles at its gradient
//! (handle size follows extinction); drag a handle sideways to move its value, up or down to
//! move its whole row's gradient (kept between the neighbouring rows); click empty space to
//! add a row there (a copy of the nearest row); right-click a handle to remove its row.

use eframe::egui;
use scene::spec::{Color, TfPoint, TransferRange, TransferSpec};

/// The presets, by their scene names.
pub const PRESETS: &[&str] = &["grey", "bone", "fire", "cool-warm"];

/// The menu's name of 2-D functions.
const TWO_D: &str = "points (2-D)";

/// Whether the function is 2-D (its points carry gradient magnitudes).
pub fn is_2d(spec: &TransferSpec) -> bool {
    spec.points.iter().any(|p| p.gradient.is_some())
}

/// The lowest extinction the log scale shows, as a fraction of the largest.
const LOG_FLOOR: f64 = 1e-3;

/// Counts over value x gradient magnitude (`worker::histogram2d`): `counts[iv + bins[0] * ig]`,
/// values over the editor's range, gradients (value units per world unit) over `[0, gmax]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Histogram2d {
    pub bins: [usize; 2],
    pub counts: Vec<u64>,
    pub gmax: f64,
}

/// The editor's tabs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Tab {
    OneD,
    ValueGradient,
}

/// The distinct gradients of a 2-D function's rows, increasing.
pub fn rows(spec: &TransferSpec) -> Vec<f64> {
    let mut g: Vec<f64> = spec.points.iter().filter_map(|p| p.gradient).collect();
    g.sort_by(f64::total_cmp);
    g.dedup();
    g
}

/// Moves the row at gradient `from` to `to`, kept at least 0 and strictly between the rows
/// beside it (rows never merge or swap); the gradient it went to.
pub fn move_row(spec: &mut TransferSpec, from: f64, to: f64) -> f64 {
    let r = rows(spec);
    let Some(i) = r.iter().position(|&g| g == from) else {
        return from;
    };
    let top = r.last().copied().unwrap_or(1.0).max(to.abs()).max(1e-12);
    let eps = 1e-6 * top;
    let lo = if i > 0 { r[i - 1] + eps } else { 0.0 };
    let hi = r.get(i + 1).map_or(f64::INFINITY, |g| g - eps);
    let g = if lo <= hi { to.clamp(lo, hi) } else { from };
    for p in &mut spec.points {
        if p.gradient == Some(from) {
            p.gradient = Some(g);
        }
    }
    g
}

/// Adds a row at gradient `g`, a copy of the row nearest to it (nothing when `g` is a row).
pub fn add_row(spec: &mut TransferSpec, g: f64) {
    let r = rows(spec);
    let Some(&near) = r
        .iter()
        .min_by(|a, b| (*a - g).abs().total_cmp(&(*b - g).abs()))
    else {
        return;
    };
    if r.contains(&g) || !(g >= 0.0 && g.is_finite()) {
        return;
    }
    let copy: Vec<TfPoint> = spec
        .points
        .iter()
        .filter(|p| p.gradient == Some(near))
        .map(|p| TfPoint {
            gradient: Some(g),
            ..p.clone()
        })
        .collect();
    spec.points.extend(copy);
    spec.points.sort_by(|a, b| a.value.total_cmp(&b.value));
}

/// Removes the row at gradient `g` unless it is the only one.
pub fn remove_row(spec: &mut TransferSpec, g: f64) {
    if rows(spec).len() > 1 {
        spec.points.retain(|p| p.gradient != Some(g));
    }
}

/// A handle dragged in the value x gradient plot: its row's gradient now and its place in the
/// row; where the drag started (the pointer, the value and the row's gradient) and the plot's
/// gradient extent then, kept for the drag (the handle moves by the pointer's movement, and a
/// top row dragged up does not stretch the axis under the pointer).
#[derive(Clone, Copy, Debug)]
struct Drag2d {
    g: f64,
    k: usize,
    at0: egui::Pos2,
    v0: f64,
    g0: f64,
    gtop: f64,
}

/// The editor's view state: the log scale, the tab and the data it draws over.
pub struct Editor {
    pub log: bool,
    pub range: [f64; 2],
    /// The data's robust range (`volume.transfer.range = "robust"`).
    pub robust: [f64; 2],
    pub histogram: Vec<u64>,
    pub tab: Tab,
    pub histogram2d: Option<Histogram2d>,
    dragging: Option<usize>,
    /// The handle dragged in the value x gradient plot.
    dragging2d: Option<Drag2d>,
    texture: Option<egui::TextureHandle>,
}

impl Editor {
    pub fn new(range: [f64; 2], histogram: Vec<u64>) -> Editor {
        Editor {
            log: false,
            range,
            robust: range,
            histogram,
            tab: Tab::OneD,
            histogram2d: None,
            dragging: None,
            dragging2d: None,
            texture: None,
        }
    }

    /// With the data's robust range.
    pub fn with_robust(mut self, robust: [f64; 2]) -> Editor {
        self.robust = robust;
        self
    }

    /// With the value x gradient histogram (the second tab).
    pub fn with_2d(mut self, h: Histogram2d) -> Editor {
        self.set_2d(h);
        self
    }

    /// Replaces the value x gradient histogram (its image is made again when it differs).
    pub fn set_2d(&mut self, h: Histogram2d) {
        if self.histogram2d.as_ref() != Some(&h) {
            self.histogram2d = Some(h);
            self.texture = None;
        }
    }

    /// The points of `spec` as the renderer evaluates them (a preset's ramp made explicit).
    pub fn points_of(&self, spec: &TransferSpec) -> Vec<TfPoint> {
        if !spec.points.is_empty() {
            return spec.points.clone();
        }
        let range = scene::compile::preset_range(spec, self.range, || self.robust);
        scene::compile::transfer(spec, range)
            .map(|t| {
                t.points
                    .iter()
                    .map(|(v, c, e)| TfPoint {
                        value: *v,
                        color: Color::Rgb(*c),
                        extinction: *e,
                        gradient: None,
                    })
                    .collect()
            })
            .unwrap_or_default()
    }

    /// `spec` as a 2-D function of the same values at low gradients: its points as the row at
    /// gradient 0 and again at a tenth of the value range (edit either row to make edges or
    /// flat regions stand out; between rows the renderer interpolates in the gradient).
    pub fn two_d(&self, spec: &TransferSpec) -> TransferSpec {
        let pts = self.points_of(spec);
        let g1 = 0.1 * (self.range[1] - self.range[0]).max(1e-9);
        let row = |g: f64| {
            pts.iter().map(move |p| TfPoint {
                gradient: Some(g),
                ..p.clone()
            })
        };
        TransferSpec::from_points(row(0.0).chain(row(g1)).collect())
    }

    /// The editor; true when the transfer function changed.
    pub fn ui(&mut self, ui: &mut egui::Ui, spec: &mut TransferSpec) -> bool {
        let before = spec.clone();
        let custom = "points";
        let current = if spec.points.is_empty() {
            spec.preset.clone()
        } else if is_2d(spec) {
            TWO_D.to_string()
        } else {
            custom.to_string()
        };
        egui::ComboBox::from_label("volume.transfer")
            .selected_text(&current)
            .show_ui(ui, |ui| {
                for p in PRESETS {
                    if ui.selectable_label(current == *p, *p).clicked() {
                        spec.preset = p.to_string();
                        spec.points.clear();
                    }
                }
                if ui.selectable_label(current == custom, custom).clicked()
                    && spec.points.is_empty()
                {
                    *spec = TransferSpec::from_points(self.points_of(spec));
                }
                if ui.selectable_label(current == TWO_D, TWO_D).clicked() && !is_2d(spec) {
                    *spec = self.two_d(spec);
                }
            });
        if spec.points.is_empty() {
            // The values the preset spans: the data's range, its robust range, or as given.
            let named = |n: &str| TransferRange::Named(n.into());
            let shown = match &spec.range {
                TransferRange::Named(n) => n.clone(),
                TransferRange::Values([lo, hi]) => format!("[{lo}, {hi}]"),
            };
            egui::ComboBox::from_label("volume.transfer.range")
                .selected_text(shown)
                .show_ui(ui, |ui| {
                    for n in ["full", "robust"] {
                        if ui.selectable_label(spec.range == named(n), n).clicked() {
                            spec.range = named(n);
                        }
                    }
                });
        }
        if self.histogram2d.is_some() {
            ui.horizontal(|ui| {
                ui.selectable_value(&mut self.tab, Tab::OneD, "1-D");
                ui.selectable_value(&mut self.tab, Tab::ValueGradient, "value × gradient");
            });
        }
        if self.tab == Tab::ValueGradient && self.histogram2d.is_some() {
            if is_2d(spec) {
                self.plot2d(ui, spec);
                self.list(ui, spec);
            } else {
                ui.label("the function is 1-D: make it 2-D to edit it over value and gradient");
                if ui.button("make 2-D").clicked() {
                    *spec = self.two_d(spec);
                }
            }
            return *spec != before;
        }
        if spec.points.is_empty() {
            ui.horizontal(|ui| {
                ui.add(
                    egui::DragValue::new(&mut spec.extinction)
                        .range(0.0..=1e4)
                        .speed(0.01)
                        .suffix(" / world unit"),
                );
                ui.label("extinction (the ramp's top)");
            });
        }
        ui.checkbox(&mut self.log, "log-scale extinction");
        self.plot(ui, spec);
        if !spec.points.is_empty() {
            self.list(ui, spec);
        }
        *spec != before
    }

    /// The curve over the histogram, with the points as handles.
    fn plot(&mut self, ui: &mut egui::Ui, spec: &mut TransferSpec) {
        let size = egui::vec2(ui.available_width().max(120.0), 110.0);
        let (rect, response) = ui.allocate_exact_size(size, egui::Sense::click_and_drag());
        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 2.0, egui::Color32::from_gray(28));
        // The histogram, log counts.
        let hmax = self.histogram.iter().copied().max().unwrap_or(1).max(1) as f64;
        let n = self.histogram.len().max(1);
        for (i, &c) in self.histogram.iter().enumerate() {
            if c == 0 {
                continue;
            }
            let f = (1.0 + c as f64).ln() / (1.0 + hmax).ln();
            let x0 = rect.left() + rect.width() * i as f32 / n as f32;
            let x1 = rect.left() + rect.width() * (i + 1) as f32 / n as f32;
            let y = rect.bottom() - rect.height() * f as f32;
            painter.rect_filled(
                egui::Rect::from_min_max(egui::pos2(x0, y), egui::pos2(x1, rect.bottom())),
                0.0,
                egui::Color32::from_gray(70),
            );
        }
        let pts = self.points_of(spec);
        let emax = pts
            .iter()
            .map(|p| p.extinction)
            .fold(0.0f64, f64::max)
            .max(1e-9);
        let [lo, hi] = self.range;
        let w = (hi - lo).max(1e-30);
        let log = self.log;
        let to_y = |e: f64| {
            let f = if log {
                ((e / emax).max(LOG_FLOOR).log10() - LOG_FLOOR.log10()) / -LOG_FLOOR.log10()
            } else {
                e / emax
            };
            rect.bottom() - rect.height() * f.clamp(0.0, 1.0) as f32
        };
        let from_y = |y: f32| {
            let f = ((rect.bottom() - y) / rect.height()).clamp(0.0, 1.0) as f64;
            if log {
                if f <= 0.0 {
                    0.0
                } else {
                    emax * 10f64.powf(LOG_FLOOR.log10() * (1.0 - f))
                }
            } else {
                emax * f
            }
        };
        let to_x = |v: f64| rect.left() + rect.width() * ((v - lo) / w).clamp(0.0, 1.0) as f32;
        let from_x = |x: f32| lo + w * ((x - rect.left()) / rect.width()).clamp(0.0, 1.0) as f64;
        let line: Vec<egui::Pos2> = pts
            .iter()
            .map(|p| egui::pos2(to_x(p.value), to_y(p.extinction)))
            .collect();
        // One curve per row of equal gradient (one row for a 1-D function), the rows of
        // higher gradients fainter.
        let mut rows: Vec<(f64, Vec<egui::Pos2>)> = vec![];
        for (p, pos) in pts.iter().zip(&line) {
            let g = p.gradient.unwrap_or(0.0);
            match rows.iter_mut().find(|r| r.0 == g) {
                Some(r) => r.1.push(*pos),
                None => rows.push((g, vec![*pos])),
            }
        }
        for (i, (_, row)) in rows.into_iter().enumerate() {
            let gray = (255.0 * 0.6f32.powi(i as i32)) as u8;
            painter.add(egui::Shape::line(
                row,
                egui::Stroke::new(1.5, egui::Color32::from_gray(gray.max(60))),
            ));
        }
        for (p, pos) in pts.iter().zip(&line) {
            let c = p.color.rgb().unwrap_or([1.0; 3]);
            let fill = egui::Color32::from_rgb(
                (c[0] * 255.0) as u8,
                (c[1] * 255.0) as u8,
                (c[2] * 255.0) as u8,
            );
            painter.circle(
                *pos,
                4.0,
                fill,
                egui::Stroke::new(1.0, egui::Color32::BLACK),
            );
        }
        // Dragging a handle turns a preset into points and moves the point.
        if response.drag_started() {
            // Picked where the button went down (the drag starts a few pixels later).
            let origin = ui.input(|i| i.pointer.press_origin());
            if let Some(at) = origin.or(response.interact_pointer_pos()) {
                self.dragging = line
                    .iter()
                    .enumerate()
                    .map(|(i, p)| (i, p.distance(at)))
                    .filter(|(_, d)| *d < 10.0)
                    .min_by(|a, b| a.1.total_cmp(&b.1))
                    .map(|(i, _)| i);
            }
        }
        if let (Some(i), Some(at)) = (self.dragging, response.interact_pointer_pos()) {
            if response.dragged() {
                if spec.points.is_empty() {
                    *spec = TransferSpec::from_points(pts.clone());
                }
                let (a, b) = (
                    if i > 0 { spec.points[i - 1].value } else { lo },
                    if i + 1 < spec.points.len() {
                        spec.points[i + 1].value
                    } else {
                        hi
                    },
                );
                let p = &mut spec.points[i];
                p.value = from_x(at.x).clamp(a.min(b), a.max(b));
                p.extinction = from_y(at.y);
            }
        }
        if response.drag_stopped() {
            self.dragging = None;
        }
    }

    /// The value x gradient plot: the 2-D histogram (log counts), each row of the function a
    /// line of handles at its gradient.
    fn plot2d(&mut self, ui: &mut egui::Ui, spec: &mut TransferSpec) {
        let Some(h) = &self.histogram2d else {
            return;
        };
        let [nv, ng] = h.bins;
        let size = egui::vec2(ui.available_width().max(120.0), 160.0);
        let (rect, response) = ui.allocate_exact_size(size, egui::Sense::click_and_drag());
        response.widget_info(|| {
            egui::WidgetInfo::labeled(egui::Role::Canvas, true, "value x gradient plot")
        });
        let painter = ui.painter_at(rect);
        painter.rect_filled(rect, 2.0, egui::Color32::from_gray(28));
        let r = rows(spec);
        let gtop = self.dragging2d.map_or_else(
            || {
                h.gmax
                    .max(r.last().copied().unwrap_or(0.0) * 1.1)
                    .max(1e-9 * (self.range[1] - self.range[0]).abs())
                    .max(1e-30)
            },
            |d| d.gtop,
        );
        let texture = self.texture.get_or_insert_with(|| {
            let cmax = h.counts.iter().copied().max().unwrap_or(1).max(1) as f64;
            let mut img = egui::ColorImage::filled([nv, ng], egui::Color32::from_gray(28));
            for ig in 0..ng {
                for iv in 0..nv {
                    let c = h.counts[iv + nv * ig];
                    if c > 0 {
                        let f = (1.0 + c as f64).ln() / (1.0 + cmax).ln();
                        // Row 0 of the image is the top: the highest gradients.
                        img[(iv, ng - 1 - ig)] = egui::Color32::from_gray((40.0 + 180.0 * f) as u8);
                    }
                }
            }
            ui.ctx().load_texture(
                "value x gradient histogram",
                img,
                egui::TextureOptions::NEAREST,
            )
        });
        // The histogram spans [0, gmax] of the plot's [0, gtop].
        let frac = (h.gmax / gtop).clamp(0.0, 1.0) as f32;
        let hist_rect = egui::Rect::from_min_max(
            egui::pos2(rect.left(), rect.bottom() - rect.height() * frac),
            rect.max,
        );
        painter.image(
            texture.id(),
            hist_rect,
            egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
            egui::Color32::WHITE,
        );
        let [lo, hi] = self.range;
        let w = (hi - lo).max(1e-30);
        let to_x = |v: f64| rect.left() + rect.width() * ((v - lo) / w).clamp(0.0, 1.0) as f32;
        let from_x = |x: f32| lo + w * ((x - rect.left()) / rect.width()).clamp(0.0, 1.0) as f64;
        let to_y = |g: f64| rect.bottom() - rect.height() * (g / gtop).clamp(0.0, 1.0) as f32;
        let from_y = |y: f32| gtop * ((rect.bottom() - y) / rect.height()).clamp(0.0, 1.0) as f64;
        let emax = spec
            .points
            .iter()
            .map(|p| p.extinction)
            .fold(0.0f64, f64::max)
            .max(1e-12);
        // Handles: (row gradient, place in the row, position).
        let mut handles: Vec<(f64, usize, egui::Pos2)> = vec![];
        for &g in &r {
            let row: Vec<&TfPoint> = spec
                .points
                .iter()
                .filter(|p| p.gradient == Some(g))
                .collect();
            let line: Vec<egui::Pos2> = row
                .iter()
                .map(|p| egui::pos2(to_x(p.value), to_y(g)))
                .collect();
            painter.add(egui::Shape::line(
                line.clone(),
                egui::Stroke::new(1.0, egui::Color32::from_gray(200)),
            ));
            for (k, (p, pos)) in row.iter().zip(&line).enumerate() {
                let c = p.color.rgb().unwrap_or([1.0; 3]);
                let fill = egui::Color32::from_rgb(
                    (c[0] * 255.0) as u8,
                    (c[1] * 255.0) as u8,
                    (c[2] * 255.0) as u8,
                );
                let radius = 3.0 + 5.0 * (p.extinction / emax) as f32;
                painter.circle(
                    *pos,
                    radius,
                    fill,
                    egui::Stroke::new(1.0, egui::Color32::BLACK),
                );
                handles.push((g, k, *pos));
            }
        }
        let near = |at: egui::Pos2| {
            handles
                .iter()
                .map(|&(g, k, p)| (g, k, p.distance(at)))
                .filter(|h| h.2 < 10.0)
                .min_by(|a, b| a.2.total_cmp(&b.2))
                .map(|(g, k, _)| (g, k))
        };
        let row_index = |spec: &TransferSpec, g: f64| -> Vec<usize> {
            (0..spec.points.len())
                .filter(|&i| spec.points[i].gradient == Some(g))
                .collect()
        };
        if response.drag_started() {
            let origin = ui.input(|i| i.pointer.press_origin());
            let at0 = origin.or(response.interact_pointer_pos());
            self.dragging2d = at0.and_then(|at0| {
                let (g, k) = near(at0)?;
                let i = *row_index(spec, g).get(k)?;
                Some(Drag2d {
                    g,
                    k,
                    at0,
                    v0: spec.points[i].value,
                    g0: g,
                    gtop,
                })
            });
        }
        if let (Some(d), Some(at)) = (self.dragging2d, response.interact_pointer_pos()) {
            if response.dragged() {
                let idx = row_index(spec, d.g);
                if let Some(&i) = idx.get(d.k) {
                    let a = if d.k > 0 {
                        spec.points[idx[d.k - 1]].value
                    } else {
                        lo
                    };
                    let b = idx.get(d.k + 1).map_or(hi, |&j| spec.points[j].value);
                    let v = d.v0 + from_x(at.x) - from_x(d.at0.x);
                    spec.points[i].value = v.clamp(a.min(b), a.max(b));
                    let g = d.g0 + from_y(at.y) - from_y(d.at0.y);
                    let g2 = move_row(spec, d.g, g.max(0.0));
                    self.dragging2d = Some(Drag2d { g: g2, ..d });
                }
            }
        }
        if response.drag_stopped() {
            self.dragging2d = None;
        }
        if response.clicked() {
            if let Some(at) = response.interact_pointer_pos() {
                // Not on a handle, nor within 6 points of a row (no near-copies of it).
                if near(at).is_none() && r.iter().all(|&g| (to_y(g) - at.y).abs() > 6.0) {
                    add_row(spec, from_y(at.y));
                }
            }
        }
        if response.secondary_clicked() {
            if let Some((g, _)) = response.interact_pointer_pos().and_then(near) {
                remove_row(spec, g);
            }
        }
        ui.label(
            egui::RichText::new(format!(
                "value {lo:.4} .. {hi:.4} across, gradient 0 .. {gtop:.4} / world unit up"
            ))
            .small(),
        );
    }

    /// The points as rows of widgets: value, colour, extinction, remove; and "add point".
    fn list(&mut self, ui: &mut egui::Ui, spec: &mut TransferSpec) {
        let [lo, hi] = self.range;
        let two = is_2d(spec);
        let mut remove = None;
        for (i, p) in spec.points.iter_mut().enumerate() {
            // Wrapped: a 2-D point's row (gradient, value, colour, extinction) is wider than
            // the panel may be, and would be cut off at its edge.
            ui.horizontal_wrapped(|ui| {
                let l = ui.label(format!("points[{i}]"));
                if two {
                    let g = p.gradient.get_or_insert(0.0);
                    ui.add(
                        egui::DragValue::new(g)
                            .range(0.0..=f64::MAX)
                            .speed((hi - lo) / 500.0)
                            .prefix("gradient "),
                    )
                    .labelled_by(l.id);
                }
                ui.add(
                    egui::DragValue::new(&mut p.value)
                        .speed((hi - lo) / 500.0)
                        .prefix("value "),
                )
                .labelled_by(l.id);
                let mut rgb = p.color.rgb().unwrap_or([1.0; 3]).map(|x| x as f32);
                if ui.color_edit_button_rgb(&mut rgb).changed() {
                    p.color = Color::Rgb(rgb.map(|x| x as f64));
                }
                ui.add(
                    egui::DragValue::new(&mut p.extinction)
                        .range(0.0..=1e4)
                        .speed(0.005)
                        .prefix("extinction "),
                )
                .labelled_by(l.id);
                if ui.small_button("x").on_hover_text("remove").clicked() {
                    remove = Some(i);
                }
            });
        }
        if let Some(i) = remove {
            if spec.points.len() > 1 {
                spec.points.remove(i);
            }
        }
        if ui.button("add point").clicked() {
            let last = spec.points.last().cloned();
            spec.points.push(TfPoint {
                value: hi,
                color: last
                    .as_ref()
                    .map_or(Color::Rgb([1.0; 3]), |p| p.color.clone()),
                extinction: last.map_or(0.0, |p| p.extinction),
                gradient: None,
            });
        }
        // The renderer takes points by increasing value.
        spec.points.sort_by(|a, b| a.value.total_cmp(&b.value));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_function_made_2d_keeps_its_values_at_low_gradients() {
        let e = Editor::new([0.0, 200.0], vec![1; 16]);
        let spec = TransferSpec {
            preset: "bone".into(),
            extinction: 0.3,
            range: Default::default(),
            points: vec![],
        };
        let two = e.two_d(&spec);
        assert!(is_2d(&two) && !is_2d(&spec));
        let a = scene::compile::transfer(&spec, e.range).unwrap();
        let b = scene::compile::transfer(&two, e.range).unwrap();
        assert_eq!(b.rows.len(), 2, "two rows of gradient");
        for v in [0.0, 20.0, 77.0, 150.0, 200.0] {
            for g in [0.0, 5.0, 20.0, 100.0] {
                let (ca, ea) = a.eval(v);
                let (cb, eb) = b.eval2(v, g);
                assert!((ea - eb).abs() < 1e-12, "{v} {g}");
                assert!((0..3).all(|k| (ca[k] - cb[k]).abs() < 1e-12));
            }
        }
    }

    fn two_rows() -> TransferSpec {
        let e = Editor::new([0.0, 200.0], vec![1; 16]);
        e.two_d(&TransferSpec {
            preset: "bone".into(),
            extinction: 0.3,
            range: Default::default(),
            points: vec![],
        })
    }

    #[test]
    fn rows_move_between_their_neighbours_and_are_added_and_removed_whole() {
        let mut s = two_rows();
        assert_eq!(rows(&s), [0.0, 20.0]);
        let per_row = s.points.len() / 2;
        // Row 20 cannot pass below row 0; row 0 cannot go negative or past 20.
        let g = move_row(&mut s, 20.0, -5.0);
        assert!(g > 0.0 && g < 1e-3, "{g}");
        let g = move_row(&mut s, g, 35.0);
        assert_eq!(g, 35.0);
        assert_eq!(move_row(&mut s, 0.0, -1.0), 0.0);
        let g0 = move_row(&mut s, 0.0, 50.0);
        assert!(g0 < 35.0 && g0 > 34.99, "{g0}");
        assert_eq!(rows(&s), [g0, 35.0]);
        // A row added at 80 copies the nearest (35); the renderer takes the function.
        add_row(&mut s, 80.0);
        assert_eq!(rows(&s), [g0, 35.0, 80.0]);
        assert_eq!(s.points.len(), 3 * per_row);
        let t = scene::compile::transfer(&s, [0.0, 200.0]).unwrap();
        assert_eq!(t.rows.len(), 3);
        assert_eq!(t.eval2(120.0, 80.0), t.eval2(120.0, 35.0));
        add_row(&mut s, 80.0);
        add_row(&mut s, f64::NAN);
        assert_eq!(s.points.len(), 3 * per_row);
        remove_row(&mut s, 35.0);
        assert_eq!(rows(&s), [g0, 80.0]);
        remove_row(&mut s, g0);
        remove_row(&mut s, 80.0);
        assert_eq!(rows(&s), [80.0], "the last row stays");
    }

    #[test]
    fn a_preset_made_explicit_is_the_same_function() {
        // Over the data's range and over its robust range (the editor's points are those the
        // renderer evaluates either way, and made explicit they no longer need the range).
        let e = Editor::new([0.0, 200.0], vec![1; 16]).with_robust([40.0, 150.0]);
        for (preset, range) in PRESETS.iter().flat_map(|p| {
            [
                (p, TransferRange::Named("full".into())),
                (p, TransferRange::Named("robust".into())),
            ]
        }) {
            let spec = TransferSpec {
                preset: preset.to_string(),
                extinction: 0.3,
                range: range.clone(),
                points: vec![],
            };
            let pts = e.points_of(&spec);
            let explicit = TransferSpec {
                points: pts,
                range: Default::default(),
                ..spec.clone()
            };
            let spans = match range.is_full() {
                true => e.range,
                false => e.robust,
            };
            let a = scene::compile::transfer(&spec, spans).unwrap();
            let b = scene::compile::transfer(&explicit, [-1e9, 1e9]).unwrap();
            for v in [0.0, 13.0, 20.0, 55.5, 100.0, 180.0, 200.0] {
                let (ca, ea) = a.eval(v);
                let (cb, eb) = b.eval(v);
                assert!((ea - eb).abs() < 1e-12, "{preset} at {v}");
                for k in 0..3 {
                    assert!((ca[k] - cb[k]).abs() < 1e-12);
                }
            }
        }
    }
}
