//! The render methods and the enumerations their settings take (the scene files' `render.method`,
//! `render.combine`, `render.geometry_shadow`, `render.occlusion_model` deserialise into
//! these).

use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    Combined,
    Dos,
    Vicinity,
    Ea,
    Phong,
    Illuminated,
    #[serde(rename = "lineao")]
    LineAo,
    Illustrative,
    Mip,
    #[serde(rename = "minip")]
    MinIp,
}

/// How tubes shadow the volume behind them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GeometryShadow {
    /// Only where a slice sample lies inside a tube (between its front and back faces).
    Inside,
    /// Every sample behind a surface (the paper's rule: an endless shadow column).
    Column,
}

/// How the volumetric occlusion buffer spreads shadows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OcclusionModel {
    /// The paper's constant blur per slice (a random walk: depends on the slice count).
    Paper,
    /// A blur that grows with the shadow's distance from its occluders (follows the cone).
    Cone,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Combine {
    Min,
    Product,
}

/// `render.surface_ao`: which screen-space ambient occlusion of the surfaces fills a method's
/// surface-AO slot (the next line papers add LineAO here).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum SurfaceAo {
    /// Schott et al.'s vicinity occlusion (Alg. 5, eq. 4-6; `vicinity.rs`).
    #[default]
    Vicinity,
    /// Eichelbaum et al.'s LineAO (eq. 4-16; `line_ao.rs`), on lines and tubes.
    #[serde(rename = "lineao")]
    LineAo,
    /// No surface AO: the slot is left out.
    None,
}

/// How a method shades the volume (the `march` entry of `slice_pass`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VolumeShading {
    /// Emission-absorption coloured by the volumetric occlusion buffer (the `light` pass, one
    /// dispatch per slice; Schott et al. Alg. 2-3).
    Occlusion,
    /// Emission-absorption without occlusion.
    EmissionAbsorption,
    /// Phong shading with on-the-fly gradients under the head light.
    Phong,
    /// A projection of the samples' values along the ray (the largest, or the smallest), shown
    /// through the volume's transfer function behind the surfaces (seed 002's context
    /// volume): `march` with its `PROJECTION` constant.
    Projection(Extremum),
}

/// Which value a projection keeps along a ray (MIP: `Max`, MinIP: `Min`).
pub use occlusion::projection::Extremum;

/// One occlusion term of the surfaces: a layer of one value per pixel that composite folds
/// with the others by min (eq. 7) or product (eq. 8).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Term {
    /// The volume's partial occlusion of the surfaces (Alg. 4, eq. 1-3), written by the
    /// `march` pass; needs [`VolumeShading::Occlusion`].
    Partial,
    /// The slot `render.surface_ao` fills ([`SurfaceAo`]).
    SurfaceAo,
    /// A surface AO the method fixes, whatever `render.surface_ao` says.
    Ao(SurfaceAo),
}

/// A row of the method table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MethodDesc {
    pub method: Method,
    /// The name scene files and the command line use (`render.method`).
    pub name: &'static str,
    pub volume: VolumeShading,
    /// The surface terms, in the order composite folds them.
    pub terms: &'static [Term],
    /// One line for tables and help.
    pub summary: &'static str,
}

/// The method table: every render method, its volume model and its surface terms. Adding a
/// method is one row here (and its enum variant above); a new surface term is one pass module,
/// its WGSL file and a [`SurfaceAo`] choice.
pub const METHODS: &[MethodDesc] = &[
    MethodDesc {
        method: Method::Combined,
        name: "combined",
        volume: VolumeShading::Occlusion,
        terms: &[Term::Partial, Term::SurfaceAo],
        summary:
            "volume by its occlusion buffer; surfaces by partial and surface AO (min or product)",
    },
    MethodDesc {
        method: Method::Dos,
        name: "dos",
        volume: VolumeShading::Occlusion,
        terms: &[Term::Partial],
        summary: "volume by its occlusion buffer; surfaces by partial occlusion",
    },
    MethodDesc {
        method: Method::Vicinity,
        name: "vicinity",
        volume: VolumeShading::EmissionAbsorption,
        terms: &[Term::SurfaceAo],
        summary: "emission-absorption volume; surfaces by surface AO",
    },
    MethodDesc {
        method: Method::Ea,
        name: "ea",
        volume: VolumeShading::EmissionAbsorption,
        terms: &[],
        summary: "emission-absorption volume; Phong surfaces",
    },
    MethodDesc {
        method: Method::Illuminated,
        name: "illuminated",
        volume: VolumeShading::EmissionAbsorption,
        terms: &[],
        summary: "illuminated lines and Phong tubes, no occlusion; emission-absorption volume",
    },
    MethodDesc {
        method: Method::LineAo,
        name: "lineao",
        volume: VolumeShading::EmissionAbsorption,
        terms: &[Term::Ao(SurfaceAo::LineAo)],
        summary: "emission-absorption volume; lines and tubes by LineAO (Eichelbaum et al.)",
    },
    MethodDesc {
        method: Method::Illustrative,
        name: "illustrative",
        volume: VolumeShading::EmissionAbsorption,
        terms: &[],
        summary: "unshaded line cores and halos in two colours (Everts et al.), no occlusion",
    },
    MethodDesc {
        method: Method::Mip,
        name: "mip",
        volume: VolumeShading::Projection(Extremum::Max),
        terms: &[],
        summary: "maximum intensity projection behind Phong surfaces (a context volume)",
    },
    MethodDesc {
        method: Method::MinIp,
        name: "minip",
        volume: VolumeShading::Projection(Extremum::Min),
        terms: &[],
        summary: "minimum intensity projection behind Phong surfaces",
    },
    MethodDesc {
        method: Method::Phong,
        name: "phong",
        volume: VolumeShading::Phong,
        terms: &[],
        summary: "Phong volume with gradient normals; Phong surfaces",
    },
];

/// The most surface terms a frame folds.
pub const MAX_TERMS: usize = 4;

/// The names of every surface-term layer a frame can have, in AOV order (`occlusion.<name>`).
pub const TERM_NAMES: &[&str] = &["partial", "vicinity", "lineao"];

impl Method {
    /// The method's row of [`METHODS`].
    pub fn desc(self) -> &'static MethodDesc {
        METHODS
            .iter()
            .find(|d| d.method == self)
            .expect("every method has a row in METHODS")
    }

    /// The method named `name` (as scene files spell it), or the list of names.
    pub fn from_name(name: &str) -> Result<Method, String> {
        METHODS
            .iter()
            .find(|d| d.name == name)
            .map(|d| d.method)
            .ok_or_else(|| {
                format!(
                    "'{name}' is not one of {}",
                    METHODS
                        .iter()
                        .map(|d| d.name)
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            })
    }
}

/// Everything about how a frame is shaded.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    pub method: Method,
    pub theta_deg: f64,
    pub blur_samples: u32,
    pub vicinity_samples: u32,
    pub vicinity_distance: f64,
    /// Vicinity depth bias, world units.
    pub vicinity_bias: f64,
    pub geometry_extinction: f64,
    /// The paper's endless shadow column behind surfaces.
    pub column: bool,
    pub combine: Combine,
    pub fxaa: bool,
    /// ambient, diffuse, specular, shininess
    pub light: [f64; 4],
    /// Occlusion buffer cell edge in pixels (None: chosen, `occlusion::combined::light_grid`).
    pub occlusion_cell: Option<u32>,
    /// Eye slices per step of the light volume (None: chosen,
    /// `occlusion::combined::light_step`).
    pub occlusion_step: Option<u32>,
    /// The cone-following occlusion model instead of the paper's.
    pub cone: bool,
    /// G-buffer samples per pixel (lowered to what the adapter supports, with a note).
    pub msaa: u32,
    /// What fills the methods' surface-AO slot.
    pub surface_ao: SurfaceAo,
    /// LineAO's parameters (used where a method's terms include it).
    pub lineao: LineAo,
    /// The time every line set's trail is drawn at, in place of its own `now` (animations).
    pub trail_now: Option<f32>,
    /// The illustrative method's line and halo colours (linear RGB).
    pub illustrative: ([f64; 3], [f64; 3]),
    /// Translucent layers peeled per pixel (1 to `gbuffer::MAX_PEEL_LAYERS`; used only when
    /// the scene has translucent meshes or slices).
    pub translucent_layers: u32,
}

/// How LineAO darkens the surfaces it occludes (`render.lineao.shading`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum LineAoShading {
    /// umbra's head-light Phong with the AO as the occlusion factor (seed 002):
    /// `(1 - AO) c (ambient + diffuse n.l) + specular`.
    #[default]
    Phong,
    /// The paper's §3.3: `c (1 - AO) + specular` (the AO replaces ambient and diffuse).
    Paper,
}

/// LineAO's settings: the kernel's (the CPU twin's struct; its line width and light material
/// are set per pixel and from [`Settings::light`] by the pass) and the frame's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineAo {
    pub kernel: occlusion::line_ao::LineAoSettings,
    /// The guard band's cap, pixels: the G-buffer's depth and normals are rendered this far
    /// beyond the viewport at most (0: no band).
    pub guard: u32,
    pub shading: LineAoShading,
}

impl Default for LineAo {
    fn default() -> Self {
        LineAo {
            kernel: Default::default(),
            guard: 64,
            shading: LineAoShading::Phong,
        }
    }
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            method: Method::Combined,
            theta_deg: 25.0,
            blur_samples: 3,
            vicinity_samples: 32,
            vicinity_distance: 2.0,
            vicinity_bias: 0.1,
            geometry_extinction: 10.0,
            column: false,
            combine: Combine::Min,
            fxaa: true,
            light: [0.3, 0.7, 0.3, 32.0],
            occlusion_cell: None,
            occlusion_step: None,
            cone: false,
            msaa: 4,
            surface_ao: SurfaceAo::Vicinity,
            lineao: LineAo::default(),
            trail_now: None,
            illustrative: ([0.0; 3], [1.0; 3]),
            translucent_layers: 4,
        }
    }
}

pub use occlusion::settings::{require, SettingError};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_method_has_one_row_named_as_serde_names_it() {
        for m in [
            Method::Combined,
            Method::Dos,
            Method::Vicinity,
            Method::Ea,
            Method::Phong,
            Method::Illuminated,
            Method::LineAo,
            Method::Illustrative,
        ] {
            let d = m.desc();
            assert_eq!(METHODS.iter().filter(|r| r.method == m).count(), 1);
            let serde_name = serde_json::to_value(m).unwrap();
            assert_eq!(serde_name, d.name);
            assert_eq!(Method::from_name(d.name).unwrap(), m);
            // The partial term reads the occlusion buffer.
            if d.terms.contains(&Term::Partial) {
                assert_eq!(d.volume, VolumeShading::Occlusion);
            }
            assert!(d.terms.len() <= MAX_TERMS);
        }
        assert!(Method::from_name("ssao")
            .unwrap_err()
            .contains("combined, dos"));
    }
}
