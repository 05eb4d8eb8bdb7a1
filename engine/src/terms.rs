//! The surface terms' registry: which pass fills a method's surface-AO slot for each choice of
//! `render.surface_ao`. A new screen-space AO (the line papers' LineAO) is its pass module and
//! WGSL file, one [`SurfaceAo`] variant and one row here; composite, the scene code, the CLI
//! and the bench stay as they are.

use crate::gbuffer::GBuffer;
use crate::gpu::{Gpu, Layer};
use crate::line_ao::{LineAoPass, FACTORS};
use crate::method::{SettingError, Settings, SurfaceAo};
use crate::vicinity::{VicinityPass, VicinitySettings};
use occlusion::camera::Camera;

/// What a surface-term pass is built from: the frame's view, its G-buffer, the layer it
/// writes and the frame's settings.
pub struct TermInputs<'a> {
    pub gpu: &'a Gpu,
    pub camera: &'a Camera,
    pub size: (u32, u32),
    pub gbuf: &'a GBuffer,
    pub layer: Layer<'a>,
    pub settings: &'a Settings,
}

/// A pass that writes one layer of the surface terms.
pub trait TermPass {
    fn record(&self, enc: &mut wgpu::CommandEncoder);

    /// More AOV channels the pass writes (`occlusion.<name>.<channel>`): a buffer of
    /// `width * height` f32 per channel, one after the other, and the channels' names.
    fn channels(&self) -> Option<(&wgpu::Buffer, &'static [&'static str])> {
        None
    }
}

/// Builds a surface-term pass.
pub type BuildTerm = fn(&TermInputs) -> Result<Box<dyn TermPass>, SettingError>;

/// A row of the registry.
pub struct SurfaceAoDesc {
    pub choice: SurfaceAo,
    /// The layer's name: its AOV channel is `occlusion.<name>`, its pass timing `<name>`.
    pub name: &'static str,
    /// Checks its settings and builds the pass (`None`: the slot stays empty).
    pub build: Option<BuildTerm>,
    /// The pass reads LineAO's guard-banded normal-depth map (`gbuffer::NdMap`).
    pub needs_nd: bool,
}

/// Every choice of `render.surface_ao`.
pub const SURFACE_AO: &[SurfaceAoDesc] = &[
    SurfaceAoDesc {
        choice: SurfaceAo::Vicinity,
        name: "vicinity",
        build: Some(vicinity),
        needs_nd: false,
    },
    SurfaceAoDesc {
        choice: SurfaceAo::LineAo,
        name: "lineao",
        build: Some(line_ao),
        needs_nd: true,
    },
    SurfaceAoDesc {
        choice: SurfaceAo::None,
        name: "none",
        build: None,
        needs_nd: false,
    },
];

/// The registry's row of `choice`.
pub fn surface_ao(choice: SurfaceAo) -> &'static SurfaceAoDesc {
    SURFACE_AO
        .iter()
        .find(|d| d.choice == choice)
        .expect("every surface AO has a row in SURFACE_AO")
}

/// The layers of `method`'s surface terms, in the method table's order, with the surface AO
/// that fills each (none for partial); a slot `surface_ao` leaves empty (`none`) has none.
pub fn layers(
    method: crate::method::Method,
    choice: SurfaceAo,
) -> Vec<(&'static str, Option<SurfaceAo>)> {
    use crate::method::Term;
    method
        .desc()
        .terms
        .iter()
        .filter_map(|t| match t {
            Term::Partial => Some(("partial", None)),
            Term::SurfaceAo | Term::Ao(_) => {
                let c = match t {
                    Term::Ao(c) => *c,
                    _ => choice,
                };
                let d = surface_ao(c);
                d.build.map(|_| (d.name, Some(c)))
            }
        })
        .collect()
}

fn line_ao(t: &TermInputs) -> Result<Box<dyn TermPass>, SettingError> {
    let s = &t.settings.lineao;
    s.kernel.check()?;
    Ok(Box::new(LineAoPass::new(
        t.gpu,
        t.camera,
        t.size,
        t.gbuf,
        t.layer,
        s,
        t.settings.light,
    )))
}

impl TermPass for LineAoPass {
    fn record(&self, enc: &mut wgpu::CommandEncoder) {
        LineAoPass::record(self, enc)
    }

    fn channels(&self) -> Option<(&wgpu::Buffer, &'static [&'static str])> {
        Some((&self.factors, &FACTORS))
    }
}

fn vicinity(t: &TermInputs) -> Result<Box<dyn TermPass>, SettingError> {
    let s = t.settings;
    let v = VicinitySettings {
        samples: s.vicinity_samples,
        distance: s.vicinity_distance,
        theta_deg: s.theta_deg,
        bias: s.vicinity_bias,
    };
    v.check()?;
    Ok(Box::new(VicinityPass::new(
        t.gpu, t.camera, t.size.0, t.size.1, t.gbuf, t.layer, &v,
    )))
}

impl TermPass for VicinityPass {
    fn record(&self, enc: &mut wgpu::CommandEncoder) {
        VicinityPass::record(self, enc)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_surface_ao_choice_has_one_row_and_its_layer_a_name() {
        for c in [SurfaceAo::Vicinity, SurfaceAo::LineAo, SurfaceAo::None] {
            assert_eq!(SURFACE_AO.iter().filter(|d| d.choice == c).count(), 1);
        }
        for d in SURFACE_AO.iter().filter(|d| d.build.is_some()) {
            assert!(crate::method::TERM_NAMES.contains(&d.name), "{}", d.name);
        }
    }
}
