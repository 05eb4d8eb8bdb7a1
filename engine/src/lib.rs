//! umbra's engine: the GPU context, the CLI's library functions, and (later) the renderer.
//!
//! The `umbra` binary (src/main.rs) only parses arguments and calls into this library, so that
//! tests exercise the same code the command line runs.

pub mod camera;
pub mod convert;
pub mod ea_pass;
pub mod gpu;
pub mod info;
pub mod iso_cmd;
pub mod iso_reference;
pub mod render_cmd;
pub mod resample_cmd;
pub mod scene;
pub mod smoke;
pub mod sweep_cmd;
pub mod synth;
pub mod trace_cmd;
pub mod tubes_cmd;
