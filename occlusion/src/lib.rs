//! umbra's papers on the CPU, without a GPU: one module per paper or concern, each opening
//! with what it implements, the pure functions the renderer's passes are built on, the CPU
//! twins of those passes, and the Monte Carlo ground truths every method is measured against.
//!
//! | paper | module | its equation index |
//! |---|---|---|
//! | Schott et al. 2012, combined surface and volumetric occlusion | [`combined`] (+ [`emission_absorption`], [`reference`](mod@reference), [`reference_tubes`]) | [`combined`] |
//! | Singh, Yuksel & House 2009, fast occlusion sweeping | [`sweeping`] (the fields, re-exported from `volume`) + [`isosurface`] | [`sweeping`] |
//! | Eichelbaum, Hlawitschka & Scheuermann 2013, LineAO (screen-space AO of dense lines and tubes) | [`line_ao`] | [`line_ao`] |
//! | Zöckler et al. 1996, illuminated lines; Mallo et al. 2005, pseudo-tubes (how line sets are shaded and sized) | [`illuminated_lines`] | [`illuminated_lines`] |
//! | maximum and minimum intensity projections (seed 002's context volume) | [`projection`] | [`projection`] |
//! | the projection conventions and the paper's texture-radius erratum | [`camera`] | [`camera`] |
//!
//! Nothing here imports `wgpu`: the `engine` crate depends on this one, never the reverse.

pub mod camera;
pub mod combined;
pub mod emission_absorption;
pub mod halos;
pub mod illuminated_lines;
pub mod isosurface;
pub mod line_ao;
pub mod projection;
pub mod reference;
pub mod reference_tubes;
pub mod rng;
pub mod settings;
pub mod stereo;
pub mod sweeping;
