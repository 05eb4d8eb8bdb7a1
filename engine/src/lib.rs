//! umbra's engine: the GPU context, the CLI's library functions, and the renderer
//! (`renderer`: the passes `gbuffer`, `slice_pass`, `vicinity`, `composite`, `fxaa`, each with
//! its WGSL file of the same name in `shaders/`).
//!
//! The `umbra` binary (src/main.rs) only parses arguments and calls into this library, so that
//! tests exercise the same code the command line runs.

pub mod bench_cmd;
pub mod camera;
pub mod camera_path;
pub mod composite;
pub mod convert;
pub mod demo;
pub mod ea_pass;
pub mod fxaa;
pub mod gbuffer;
pub mod gpu;
pub mod info;
pub mod iso_cmd;
pub mod iso_pass;
pub mod iso_reference;
pub mod reference;
pub mod reference_tubes;
pub mod render_cmd;
pub mod renderer;
pub mod resample_cmd;
pub mod scene;
pub mod slice_pass;
pub mod smoke;
pub mod sweep_cmd;
pub mod synth;
pub mod trace_cmd;
pub mod tubes_cmd;
pub mod vicinity;
