//! Final compositing and shading (Schott et al., section 3.2.6, Algorithm 6, eq. 7-10), as a
//! compute pass. Shader: `shaders/composite.wgsl`.
//!
//! Where a surface is: `combined` is the min (eq. 7) or the product (eq. 8) of the method's
//! surface terms (partial and vicinity occlusion in the paper; any layers the method table
//! names), 1 without terms; the surface is shaded by the head light,
//! `combined * colour * (ambient + diffuse (n.l)) + specular (r.v)^shininess` (eq. 9; a slice
//! not `lit`, marked in the G-buffer by alpha 0.97, is `combined * colour`), and the
//! volume in front of it is composited over it, `surface (1 - alpha_v) + volume_rgb` (eq. 10).
//! Elsewhere the background takes the surface's place, composited last ("under" blending;
//! Algorithm 1 initialises the eye buffer with it, which adds it instead of attenuating it).
//! The AOVs: volumetric occlusion (the opacity-weighted mean of the occlusion along the eye
//! ray), partial, vicinity and combined occlusion, and linear depth (of the surface, or where
//! the volume becomes half opaque if that is nearer). Where the isosurface of `iso_pass` is
//! nearer than the tubes it is the surface, already shaded, its ambient term the combined AOV.

use crate::gbuffer::GBuffer;
use crate::gpu::{Gpu, Slot};
use crate::method::Combine;
use crate::prelude::{vec4, with_prelude, FrameUniform, LightUniform};
use occlusion::camera::Camera;

const SHADER: &str = include_str!("../../shaders/composite.wgsl");

/// How the surface terms combine, and the light and background.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompositeSettings {
    /// How many layers of the surface terms to fold (the method's terms).
    pub terms: u32,
    pub combine: Combine,
    /// ambient, diffuse, specular, shininess
    pub light: [f64; 4],
    pub background: [f64; 3],
    /// LineAO's paper shading (§3.3): surfaces `combined c + specular`, no ambient and
    /// diffuse terms.
    pub paper_shading: bool,
    /// The illustrative method's line and halo colours (linear RGB); `None`: shaded
    /// surfaces, halos in the background's colour.
    pub illustrative: Option<([f64; 3], [f64; 3])>,
    /// A term layer no pass writes that counts 1 everywhere (and is written so, as its
    /// AOV): the partial term of `dos` and `combined` where nothing casts light.
    pub open_layer: Option<u32>,
}

/// The G-buffer's colour and normal bindings (4, 5), single or multisampled, behind the same
/// helpers `g_col`, `g_nrm` and the constant `SAMPLES`: what the pass puts before its WGSL.
fn gbuffer_bindings(samples: u32) -> String {
    if samples > 1 {
        format!(
            "const SAMPLES: i32 = {samples};\n\
             @group(0) @binding(4) var g_color: texture_multisampled_2d<f32>;\n\
             @group(0) @binding(5) var g_normal: texture_multisampled_2d<f32>;\n\
             fn g_col(p: vec2<i32>, s: i32) -> vec4<f32> {{ return textureLoad(g_color, p, s); }}\n\
             fn g_nrm(p: vec2<i32>, s: i32) -> vec4<f32> {{ return textureLoad(g_normal, p, s); }}\n"
        )
    } else {
        "const SAMPLES: i32 = 1;\n\
         @group(0) @binding(4) var g_color: texture_2d<f32>;\n\
         @group(0) @binding(5) var g_normal: texture_2d<f32>;\n\
         fn g_col(p: vec2<i32>, s: i32) -> vec4<f32> { return textureLoad(g_color, p, 0); }\n\
         fn g_nrm(p: vec2<i32>, s: i32) -> vec4<f32> { return textureLoad(g_normal, p, 0); }\n"
            .to_string()
    }
}

/// The pass's uniform. Keep in sync with `struct Params` in `shaders/composite.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct CompositeParams {
    pub frame: FrameUniform,
    /// Linear RGB (xyz, 1).
    pub background: [f32; 4],
    pub light: LightUniform,
    /// The layers of the surface terms folded.
    pub n_terms: u32,
    /// 0: min (eq. 7), 1: product (eq. 8).
    pub product: u32,
    /// 1: LineAO's paper shading.
    pub paper_shading: u32,
    /// A term layer that reads 1 (u32::MAX: none): the partial term where no light volume
    /// is swept (nothing was marched to write it).
    pub open_layer: u32,
    /// The colour of halo samples (xyz) and whether they count as coverage (w: 1 the
    /// illustrative halo, 0 a gap halo showing the background).
    pub halo: [f32; 4],
    /// The illustrative line colour (xyz), w = 1 for the illustrative method.
    pub line: [f32; 4],
}

pub struct CompositePass {
    pipe: wgpu::ComputePipeline,
    bind: wgpu::BindGroup,
    pub image: wgpu::Buffer,
    pub aov: wgpu::Buffer,
    size: (u32, u32),
}

impl CompositePass {
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        gpu: &Gpu,
        camera: &Camera,
        width: u32,
        height: u32,
        gbuf: &GBuffer,
        eye: &wgpu::Buffer,
        state: &wgpu::Buffer,
        terms: &wgpu::Buffer,
        iso: &crate::iso_pass::IsoPass,
        s: &CompositeSettings,
    ) -> CompositePass {
        let prelude = gbuffer_bindings(gbuf.samples);
        let module = gpu.shader(
            "composite.wgsl",
            &with_prelude(&format!("{prelude}{SHADER}")),
        );
        let layout = gpu.layout(
            "composite",
            wgpu::ShaderStages::COMPUTE,
            &[
                Slot::Uniform,
                Slot::Storage,
                Slot::Storage,
                Slot::StorageRw,
                if gbuf.samples > 1 {
                    Slot::MultisampledTexture
                } else {
                    Slot::UnfilterableTexture
                },
                if gbuf.samples > 1 {
                    Slot::MultisampledTexture
                } else {
                    Slot::UnfilterableTexture
                },
                Slot::UnfilterableTexture,
                Slot::StorageRw,
                Slot::StorageRw,
                Slot::Storage,
                Slot::Storage,
            ],
        );
        let pl = gpu.pipeline_layout("composite", &[&layout]);
        let pipe = gpu.compute_pipeline_with(&module, "main", &pl, "composite");
        let b = s.background;
        let params = CompositeParams {
            frame: FrameUniform::new(camera, width, height),
            background: vec4([b[0], b[1], b[2], 1.0]),
            light: s.light.into(),
            n_terms: s.terms,
            product: (s.combine == Combine::Product) as u32,
            paper_shading: s.paper_shading as u32,
            open_layer: s.open_layer.unwrap_or(u32::MAX),
            // w: whether a halo sample is coverage (the illustrative halo's ink), or shows
            // the background (a gap: no surface, alpha as the background's).
            halo: match s.illustrative {
                Some((_, h)) => vec4([h[0], h[1], h[2], 1.0]),
                None => vec4([b[0], b[1], b[2], 0.0]),
            },
            line: match s.illustrative {
                Some((l, _)) => vec4([l[0], l[1], l[2], 1.0]),
                None => [0.0; 4],
            },
        };
        let params = gpu.buffer(
            "composite params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
        );
        let n = width as u64 * height as u64;
        let image = gpu.scratch("image", n * 16, wgpu::BufferUsages::COPY_SRC);
        let aov = gpu.scratch("aov", n * 16, wgpu::BufferUsages::COPY_SRC);
        let bind = gpu.bind(
            "composite",
            &layout,
            &[
                params.as_entire_binding(),
                eye.as_entire_binding(),
                state.as_entire_binding(),
                terms.as_entire_binding(),
                wgpu::BindingResource::TextureView(&gbuf.color),
                wgpu::BindingResource::TextureView(&gbuf.normal),
                wgpu::BindingResource::TextureView(&gbuf.front),
                image.as_entire_binding(),
                aov.as_entire_binding(),
                iso.output.as_entire_binding(),
                iso.ambient.as_entire_binding(),
            ],
        );
        CompositePass {
            pipe,
            bind,
            image,
            aov,
            size: (width, height),
        }
    }

    pub fn record(&self, enc: &mut wgpu::CommandEncoder) {
        crate::gpu::dispatch_image(enc, &self.pipe, &self.bind, self.size);
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_uniform_matches_its_wgsl_struct() {
        // As the pass assembles it, single-sampled and multisampled.
        for samples in [1, 4] {
            let src = format!("{}{}", super::gbuffer_bindings(samples), super::SHADER);
            crate::prelude::assert_layout!(
                &src,
                "Params",
                super::CompositeParams {
                    frame,
                    background,
                    light,
                    n_terms,
                    product,
                    paper_shading,
                    open_layer,
                    halo,
                    line,
                }
            );
        }
    }
}
