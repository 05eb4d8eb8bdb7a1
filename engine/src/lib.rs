//! umbra's renderer: the headless GPU context ([`gpu`]), the long-lived [`renderer`] (upload a
//! scene once, draw frames), the method table ([`method`]) and the passes, each one Rust
//! module with its WGSL file of the same name in `shaders/`: [`gbuffer`], [`slice_pass`]
//! (`light` and `march`), [`vicinity`], [`line_ao`], [`iso_pass`], [`composite`], [`fxaa`].
//!
//! It takes typed inputs (`occlusion::emission_absorption::EaView`, `VolumeInput`,
//! `tubes::tube_mesh::TubeMesh`) and returns images; scene files, image files and the command
//! line live in the `scene` and `umbra` crates. The maths the passes implement is in the
//! `occlusion` crate, beside its CPU twins.

pub mod composite;
pub mod fxaa;
pub mod gbuffer;
pub mod gpu;
pub mod iso_pass;
pub mod line_ao;
pub mod method;
pub mod planes;
pub mod prelude;
pub mod renderer;
pub mod slice_pass;
pub mod smoke;
pub mod terms;
pub mod vicinity;
