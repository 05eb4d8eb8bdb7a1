//! The settings panel: the scene's `[render]` keys, `[light]`, `background` and `[[clip]]`
//! planes as widgets, each labelled with its scene key and unit and kept in the range the
//! renderer accepts, so that any state the panel makes is a scene `umbra render` draws.
//! Keys the panel does not show yet keep their scene values: `render.lineao.*`,
//! `render.illustrative.*`, `render.width`/`height` (the view's size) and `render.bits`.

use eframe::egui;
use engine::method::{Combine, GeometryShadow, OcclusionModel, SurfaceAo};
use scene::spec::{ClipSpec, Color, Device, Scene, Stereo};

/// A menu of the values of an enumeration; true when it changed.
fn menu<T: PartialEq + Copy>(ui: &mut egui::Ui, key: &str, v: &mut T, all: &[(T, &str)]) -> bool {
    let before = *v;
    let name = all.iter().find(|(x, _)| x == v).map_or("?", |(_, n)| *n);
    egui::ComboBox::from_label(key)
        .selected_text(name)
        .show_ui(ui, |ui| {
            for (x, n) in all {
                ui.selectable_value(v, *x, *n);
            }
        });
    *v != before
}

/// An optional value: "auto" (None) or a number in `range` with `unit`; true when changed.
fn optional<T: egui::emath::Numeric>(
    ui: &mut egui::Ui,
    key: &str,
    v: &mut Option<T>,
    default: T,
    range: std::ops::RangeInclusive<T>,
    unit: &str,
) -> bool {
    let before = *v;
    ui.horizontal(|ui| {
        let mut auto = v.is_none();
        if ui.checkbox(&mut auto, "auto").changed() {
            *v = if auto { None } else { Some(default) };
        }
        if let Some(x) = v {
            ui.add(egui::DragValue::new(x).range(range).suffix(unit));
        }
        ui.label(key);
    });
    *v != before
}

/// A number in `range` with `unit`.
fn number<T: egui::emath::Numeric>(
    ui: &mut egui::Ui,
    key: &str,
    v: &mut T,
    range: std::ops::RangeInclusive<T>,
    unit: &str,
) -> bool {
    ui.horizontal(|ui| {
        let r = ui.add(egui::DragValue::new(v).range(range).suffix(unit));
        ui.label(key);
        r.changed()
    })
    .inner
}

/// The panel; true when the scene changed. New clip planes pass through `centre`.
pub fn panel(ui: &mut egui::Ui, s: &mut Scene, centre: [f64; 3]) -> bool {
    let before = (
        s.render.clone(),
        s.light.clone(),
        s.background.clone(),
        s.clip.clone(),
    );
    let r = &mut s.render;
    egui::CollapsingHeader::new("render")
        .default_open(false)
        .show(ui, |ui| {
            optional(ui, "slices", &mut r.slices, 256, 2..=16384, "");
            optional(
                ui,
                "slice_distance",
                &mut r.slice_distance,
                1.0,
                1e-3..=1e3,
                " world units",
            );
            ui.add(egui::Slider::new(&mut r.theta, 1.0..=89.0).text("theta (°)"));
            ui.add(egui::Slider::new(&mut r.blur_samples, 1..=9).text("blur_samples (n x n)"));
            optional(
                ui,
                "occlusion_cell",
                &mut r.occlusion_cell,
                2,
                1..=16,
                " px",
            );
            menu(
                ui,
                "occlusion_model",
                &mut r.occlusion_model,
                &[
                    (OcclusionModel::Paper, "paper"),
                    (OcclusionModel::Cone, "cone"),
                ],
            );
            number(
                ui,
                "geometry_extinction",
                &mut r.geometry_extinction,
                0.0..=1e4,
                " / world unit",
            );
            menu(
                ui,
                "geometry_shadow",
                &mut r.geometry_shadow,
                &[
                    (GeometryShadow::Inside, "inside"),
                    (GeometryShadow::Column, "column"),
                ],
            );
            menu(
                ui,
                "surface_ao",
                &mut r.surface_ao,
                &[
                    (SurfaceAo::Vicinity, "vicinity"),
                    (SurfaceAo::LineAo, "lineao"),
                    (SurfaceAo::None, "none"),
                ],
            );
            menu(
                ui,
                "combine",
                &mut r.combine,
                &[(Combine::Min, "min"), (Combine::Product, "product")],
            );
            ui.add(egui::Slider::new(&mut r.vicinity_samples, 1..=118).text("vicinity_samples"));
            number(
                ui,
                "vicinity_distance",
                &mut r.vicinity_distance,
                1e-3..=1e3,
                " world units",
            );
            optional(
                ui,
                "vicinity_bias",
                &mut r.vicinity_bias,
                0.1,
                0.0..=1e3,
                " world units",
            );
            menu(
                ui,
                "msaa",
                &mut r.msaa,
                &[(1, "1"), (2, "2"), (4, "4"), (8, "8")],
            );
            ui.checkbox(&mut r.fxaa, "fxaa");
            menu(
                ui,
                "device",
                &mut r.device,
                &[
                    (Device::Auto, "auto"),
                    (Device::Gpu, "gpu"),
                    (Device::Cpu, "cpu"),
                ],
            );
            menu(
                ui,
                "stereo",
                &mut r.stereo,
                &[(Stereo::None, "none"), (Stereo::Anaglyph, "anaglyph")],
            );
            if r.stereo == Stereo::Anaglyph {
                optional(
                    ui,
                    "eye_separation",
                    &mut r.eye_separation,
                    5.0,
                    0.0..=1e4,
                    " world units",
                );
                optional(
                    ui,
                    "convergence",
                    &mut r.convergence,
                    100.0,
                    1e-3..=1e6,
                    " world units",
                );
            }
        });
    egui::CollapsingHeader::new("light and background")
        .default_open(false)
        .show(ui, |ui| {
            let l = &mut s.light;
            ui.add(egui::Slider::new(&mut l.ambient, 0.0..=1.0).text("light.ambient"));
            ui.add(egui::Slider::new(&mut l.diffuse, 0.0..=1.0).text("light.diffuse"));
            ui.add(egui::Slider::new(&mut l.specular, 0.0..=1.0).text("light.specular"));
            ui.add(egui::Slider::new(&mut l.shininess, 1.0..=256.0).text("light.shininess"));
            let mut rgb = s.background.rgb().unwrap_or([1.0; 3]).map(|x| x as f32);
            ui.horizontal(|ui| {
                if ui.color_edit_button_rgb(&mut rgb).changed() {
                    s.background = Color::Rgb(rgb.map(|x| x as f64));
                }
                ui.label("background");
            });
        });
    egui::CollapsingHeader::new(format!("clip planes ({})", s.clip.len()))
        .default_open(false)
        .show(ui, |ui| {
            let mut remove = None;
            for (i, c) in s.clip.iter_mut().enumerate() {
                ui.horizontal(|ui| {
                    ui.label(format!("clip[{i}] normal"));
                    for x in &mut c.normal {
                        ui.add(egui::DragValue::new(x).speed(0.01).range(-1.0..=1.0));
                    }
                });
                ui.horizontal(|ui| {
                    ui.add(
                        egui::DragValue::new(&mut c.offset)
                            .speed(0.5)
                            .suffix(" world units"),
                    );
                    ui.label("offset");
                    ui.checkbox(&mut c.volume_only, "volume_only");
                    if ui.button("remove").clicked() {
                        remove = Some(i);
                    }
                });
            }
            if let Some(i) = remove {
                s.clip.remove(i);
            }
            if s.clip.len() < occlusion::emission_absorption::MAX_CLIP
                && ui.button("add clip plane").clicked()
            {
                s.clip.push(ClipSpec {
                    normal: [1.0, 0.0, 0.0],
                    offset: centre[0],
                    volume_only: false,
                });
            }
        });
    // A plane needs a direction: a normal dragged to zero becomes +x again.
    for c in &mut s.clip {
        if c.normal.iter().all(|x| *x == 0.0) {
            c.normal = [1.0, 0.0, 0.0];
        }
    }
    before
        != (
            s.render.clone(),
            s.light.clone(),
            s.background.clone(),
            s.clip.clone(),
        )
}
