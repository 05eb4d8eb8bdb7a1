//! The settings panel: the scene's `[render]` keys, `[light]`, `background` and `[[clip]]`
//! planes as widgets, each labelled with its scene key and unit and kept in the range the
//! renderer accepts, so that any state the panel makes is a scene `umbra render` draws.
//! "LineAO" edits `[render.lineao]` and "illustrative" `[render.illustrative]`. Keys the panel
//! does not show keep their scene values: `render.width`/`height` (the view's size) and
//! `render.bits`.

use eframe::egui;
use engine::method::{Combine, GeometryShadow, LineAoShading, OcclusionModel, SurfaceAo};
use scene::spec::{
    AoAlignment, AoLevels, AoVisibility, ClipSpec, Color, Device, Falloff, Scene, Stereo,
};

/// A colour key as a colour button; true when it changed.
fn colour(ui: &mut egui::Ui, key: &str, c: &mut Color) -> bool {
    let mut rgb = c.rgb().unwrap_or([1.0; 3]).map(|x| x as f32);
    ui.horizontal(|ui| {
        let changed = ui.color_edit_button_rgb(&mut rgb).changed();
        ui.label(key);
        if changed {
            *c = Color::Rgb(rgb.map(|x| x as f64));
        }
        changed
    })
    .inner
}

/// `[render.lineao]` (Eichelbaum et al. 2013; anisotropic: Köhler et al. 2011), each key in the
/// range the renderer accepts.
fn lineao(ui: &mut egui::Ui, a: &mut scene::spec::LineAoSpec) {
    ui.add(
        egui::Slider::new(&mut a.samples, 1..=1024)
            .logarithmic(true)
            .text("samples (s_h)"),
    );
    ui.add(egui::Slider::new(&mut a.levels, 1..=8).text("levels (s_r)"));
    number(ui, "r0", &mut a.r0, 1e-3..=1e3, " line widths");
    number(
        ui,
        "radius_step",
        &mut a.radius_step,
        0.0..=1e4,
        " world units",
    );
    ui.horizontal(|ui| {
        ui.add(
            egui::DragValue::new(&mut a.delta0)
                .range(0.0..=0.5)
                .speed(1e-5)
                .max_decimals(6),
        );
        ui.label("delta0 (normalised depth)");
    });
    menu(
        ui,
        "falloff",
        &mut a.falloff,
        &[(Falloff::Paper, "paper"), (Falloff::Constant, "constant")],
    );
    menu(
        ui,
        "levels_combine",
        &mut a.levels_combine,
        &[(AoLevels::Sum, "sum"), (AoLevels::Mean, "mean")],
    );
    menu(
        ui,
        "visibility",
        &mut a.visibility,
        &[
            (AoVisibility::Plane, "plane"),
            (AoVisibility::Height, "height"),
        ],
    );
    ui.add(egui::Slider::new(&mut a.light_intensity, 0.0..=1.0).text("light_intensity (I_s)"));
    ui.checkbox(&mut a.anisotropic, "anisotropic");
    if a.anisotropic {
        menu(
            ui,
            "alignment",
            &mut a.alignment,
            &[
                (AoAlignment::Invariant, "invariant"),
                (AoAlignment::Paper, "paper"),
            ],
        );
        number(ui, "intensity (I)", &mut a.intensity, 0.0..=1e4, "");
        ui.add(egui::Slider::new(&mut a.floor, 0.0..=1.0).text("floor (A0)"));
    }
    ui.add(egui::Slider::new(&mut a.guard, 0..=1024).text("guard (px)"));
    menu(
        ui,
        "shading",
        &mut a.shading,
        &[
            (LineAoShading::Phong, "phong"),
            (LineAoShading::Paper, "paper"),
        ],
    );
    number(ui, "seed", &mut a.seed, 0..=u32::MAX, "");
}

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

/// The panel; true when the scene changed. New clip planes pass through `centre`;
/// `dragged` is the clip plane that ctrl + drag over the view moves (a new plane's, at first).
pub fn panel(
    ui: &mut egui::Ui,
    s: &mut Scene,
    centre: [f64; 3],
    dragged: &mut Option<usize>,
) -> bool {
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
                "occlusion_step",
                &mut r.occlusion_step,
                &[
                    (None, "auto"),
                    (Some(1), "1 slice"),
                    (Some(2), "2 slices"),
                    (Some(4), "4 slices"),
                    (Some(8), "8 slices"),
                ],
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
    egui::CollapsingHeader::new("LineAO")
        .default_open(false)
        .show(ui, |ui| lineao(ui, &mut s.render.lineao));
    egui::CollapsingHeader::new("illustrative")
        .default_open(false)
        .show(ui, |ui| {
            colour(ui, "illustrative.line", &mut s.render.illustrative.line);
            colour(ui, "illustrative.halo", &mut s.render.illustrative.halo);
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
    // (A fixed id: the count in the title would close the section as a plane is added.)
    egui::CollapsingHeader::new(format!("clip planes ({})", s.clip.len()))
        .id_salt("clip planes")
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
                ui.radio_value(
                    dragged,
                    Some(i),
                    format!("clip[{i}]: ctrl+drag in the view"),
                );
            }
            if let Some(i) = remove {
                s.clip.remove(i);
                *dragged = match *dragged {
                    Some(d) if d == i => None,
                    Some(d) if d > i => Some(d - 1),
                    d => d,
                };
            }
            if s.clip.len() < occlusion::emission_absorption::MAX_CLIP
                && ui.button("add clip plane").clicked()
            {
                s.clip.push(ClipSpec {
                    normal: [1.0, 0.0, 0.0],
                    offset: centre[0],
                    volume_only: false,
                });
                *dragged = Some(s.clip.len() - 1);
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
