//! The transfer-function editor: `[volume.transfer]` over the data's histogram. A preset
//! (`grey`, `bone`, `fire`, `cool-warm`: ramps over the data's range, transparent below 10% of
//! it, `extinction` at the top) or piecewise-linear points (`value`, `color`, `extinction` per
//! world unit), shown as the extinction curve over the histogram (linear or log scale) with
//! each point a handle: drag it to move its value and extinction, or type them in the list.
//! 2-D functions (`points (2-D)`: rows of points by gradient magnitude) show a curve per row
//! and a gradient column in the list.

use eframe::egui;
use scene::spec::{Color, TfPoint, TransferSpec};

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

/// The editor's view state: the log scale and the data it draws over.
pub struct Editor {
    pub log: bool,
    pub range: [f64; 2],
    pub histogram: Vec<u64>,
    dragging: Option<usize>,
}

impl Editor {
    pub fn new(range: [f64; 2], histogram: Vec<u64>) -> Editor {
        Editor {
            log: false,
            range,
            histogram,
            dragging: None,
        }
    }

    /// The points of `spec` as the renderer evaluates them (a preset's ramp made explicit).
    pub fn points_of(&self, spec: &TransferSpec) -> Vec<TfPoint> {
        if !spec.points.is_empty() {
            return spec.points.clone();
        }
        scene::compile::transfer(spec, self.range)
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
        TransferSpec {
            points: row(0.0).chain(row(g1)).collect(),
            ..spec.clone()
        }
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
                    spec.points = self.points_of(spec);
                }
            });
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
                    spec.points = pts.clone();
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

    /// The points as rows of widgets: value, colour, extinction, remove; and "add point".
    fn list(&mut self, ui: &mut egui::Ui, spec: &mut TransferSpec) {
        let [lo, hi] = self.range;
        let two = is_2d(spec);
        let mut remove = None;
        for (i, p) in spec.points.iter_mut().enumerate() {
            ui.horizontal(|ui| {
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

    #[test]
    fn a_preset_made_explicit_is_the_same_function() {
        let e = Editor::new([0.0, 200.0], vec![1; 16]);
        for preset in PRESETS {
            let spec = TransferSpec {
                preset: preset.to_string(),
                extinction: 0.3,
                points: vec![],
            };
            let pts = e.points_of(&spec);
            let explicit = TransferSpec {
                points: pts,
                ..spec.clone()
            };
            let a = scene::compile::transfer(&spec, e.range).unwrap();
            let b = scene::compile::transfer(&explicit, e.range).unwrap();
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
