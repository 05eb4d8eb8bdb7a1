//! umbra's scene files and what is made of them: the TOML schema ([`spec`]: parse, check,
//! override, save), compiling a scene into the renderer's inputs ([`compile`]: the model, the
//! camera, the slices, the settings), the tube sets and isosurface fields it loads
//! ([`tube_sets`], [`fields`]), slices of volumes and overlays ([`slices`]), frame sequences ([`camera_path`]), rendering a scene to image
//! files ([`render`]), batches of them on clusters ([`batch`]: shards, manifests, resumable
//! outputs) and the image writers ([`image_io`]). The command line, the viewer and
//! the Python package all call these.

pub mod annotate;
pub mod batch;
pub mod camera_path;
pub mod compile;
pub mod fields;
pub mod hash;
pub mod image_io;
pub mod render;
pub mod slices;
pub mod spec;
pub mod tube_sets;

pub use spec::Scene;
