//! The Rust side of `shaders/prelude.wgsl`, the WGSL every pass shares: the frame uniform and
//! the head light (keep in sync with their WGSL structs), and the source assembly that puts
//! the prelude before each pass's shader.

use occlusion::camera::Camera;

/// `shaders/prelude.wgsl`.
pub const PRELUDE: &str = include_str!("../../shaders/prelude.wgsl");

/// A pass's WGSL with the prelude before it.
pub fn with_prelude(pass: &str) -> String {
    format!("{PRELUDE}\n{pass}")
}

/// The view of one frame. Keep in sync with `struct Frame` in `shaders/prelude.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct FrameUniform {
    /// Clip to world, column-major.
    pub inv_view_proj: [[f32; 4]; 4],
    /// Eye position (xyz, 1).
    pub eye: [f32; 4],
    /// Unit viewing direction (xyz, 0).
    pub forward: [f32; 4],
    /// Width, height in pixels; unused, unused.
    pub size: [u32; 4],
}

impl FrameUniform {
    /// The frame of `camera` at `width x height` (the aspect ratio is theirs).
    pub fn new(camera: &Camera, width: u32, height: u32) -> FrameUniform {
        let aspect = width as f64 / height.max(1) as f64;
        let (e, f) = (camera.eye, camera.forward());
        FrameUniform {
            inv_view_proj: mat4(camera.view_projection(aspect).inverse()),
            eye: [e.x as f32, e.y as f32, e.z as f32, 1.0],
            forward: [f.x as f32, f.y as f32, f.z as f32, 0.0],
            size: [width, height, 0, 0],
        }
    }
}

/// The head light's Phong parameters. Keep in sync with `struct Light` in
/// `shaders/prelude.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct LightUniform {
    pub ambient: f32,
    pub diffuse: f32,
    pub specular: f32,
    pub shininess: f32,
}

impl From<[f64; 4]> for LightUniform {
    /// From `[ambient, diffuse, specular, shininess]`.
    fn from(l: [f64; 4]) -> LightUniform {
        LightUniform {
            ambient: l[0] as f32,
            diffuse: l[1] as f32,
            specular: l[2] as f32,
            shininess: l[3] as f32,
        }
    }
}

/// A matrix as WGSL's `mat4x4<f32>` (columns).
pub fn mat4(m: glam::DMat4) -> [[f32; 4]; 4] {
    m.to_cols_array_2d().map(|c| c.map(|v| v as f32))
}

/// Four values as a WGSL `vec4<f32>`.
pub fn vec4(v: [f64; 4]) -> [f32; 4] {
    v.map(|x| x as f32)
}

/// Clipping planes `(normal, offset)` as the passes' `array<vec4<f32>, 8>` (unused rows zero).
pub fn clip_planes(clip: &[([f64; 3], f64)]) -> [[f32; 4]; 8] {
    let mut out = [[0.0f32; 4]; 8];
    for (row, (n, o)) in out.iter_mut().zip(clip) {
        *row = vec4([n[0], n[1], n[2], *o]);
    }
    out
}

/// Members (name, byte offset) and size of struct `name` in WGSL `source` (the prelude
/// prepended), as naga lays it out: what the `#[repr(C)]` twins are checked against.
#[cfg(test)]
pub(crate) fn wgsl_layout(source: &str, name: &str) -> (Vec<(String, u32)>, u32) {
    let module = naga::front::wgsl::parse_str(&with_prelude(source))
        .unwrap_or_else(|e| panic!("the WGSL does not parse: {e}"));
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).unwrap();
    let (h, t) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("no struct {name}"));
    let members = match &t.inner {
        naga::TypeInner::Struct { members, .. } => members
            .iter()
            .map(|m| (m.name.clone().unwrap_or_default(), m.offset))
            .collect(),
        _ => panic!("{name} is not a struct"),
    };
    (members, layouter[h].size)
}

/// Asserts that WGSL struct `$wgsl` of `$source` and the Rust struct `$rust` have the same
/// members, in order, at the same offsets, and the same size.
#[cfg(test)]
macro_rules! assert_layout {
    ($source:expr, $wgsl:expr, $rust:ty { $($field:ident),* $(,)? }) => {{
        let (members, size) = $crate::prelude::wgsl_layout($source, $wgsl);
        let rust: Vec<(String, u32)> = vec![
            $((stringify!($field).to_string(), std::mem::offset_of!($rust, $field) as u32)),*
        ];
        assert_eq!(members, rust, "members of {} and {}", $wgsl, stringify!($rust));
        assert_eq!(size as usize, std::mem::size_of::<$rust>(), "size of {}", $wgsl);
    }};
}
#[cfg(test)]
pub(crate) use assert_layout;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_prelude_structs_match_their_rust_twins() {
        assert_layout!(
            "",
            "Frame",
            FrameUniform {
                inv_view_proj,
                eye,
                forward,
                size
            }
        );
        assert_layout!(
            "",
            "Light",
            LightUniform {
                ambient,
                diffuse,
                specular,
                shininess
            }
        );
    }
}
