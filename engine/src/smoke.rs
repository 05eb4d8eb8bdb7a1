//! GPU smoke path: one compute dispatch and one (multisampled) render pass into a texture,
//! both read back and checked. Shader: `shaders/smoke.wgsl`.
//!
//! The render pass draws the left half of an RGBA8 target red-orange over a blue clear colour
//! with the highest MSAA count not above the one requested that the adapter supports for the
//! format (lavapipe lacks 8x, for instance), resolving into a single-sample texture.

use crate::gpu::{choose_sample_count, Gpu, GpuError};

const SHADER: &str = include_str!("../../shaders/smoke.wgsl");

/// What the smoke run found.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SmokeReport {
    pub compute_values_checked: usize,
    pub render_size: [u32; 2],
    pub sample_count: u32,
    pub msaa_note: Option<String>,
    /// Pixel at (width/4, height/2) and (3 width/4, height/2), RGBA8.
    pub left_pixel: [u8; 4],
    pub right_pixel: [u8; 4],
}

/// Runs the compute and render checks; an error names what differed.
pub fn run(gpu: &Gpu, requested_msaa: u32) -> Result<SmokeReport, GpuError> {
    let device = &gpu.device;
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("smoke.wgsl"),
        source: wgpu::ShaderSource::Wgsl(SHADER.into()),
    });

    // Compute: values[i] = i*i + 7.
    let n: u32 = 1000;
    let (storage, readback) = gpu.output_buffers("smoke values", n as u64 * 4);
    let cpipe = gpu.compute_pipeline(&module, "square", "smoke square");
    let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("smoke values"),
        layout: &cpipe.get_bind_group_layout(0),
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: storage.as_entire_binding(),
        }],
    });

    // Render: left half coloured, MSAA resolved.
    let (w, h) = (64u32, 32u32);
    let format = wgpu::TextureFormat::Rgba8Unorm;
    let (samples, msaa_note) = choose_sample_count(&gpu.adapter, format, requested_msaa);
    let tex_desc = |label, sample_count, usage| wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    };
    let resolve = device.create_texture(&tex_desc(
        "smoke target",
        1,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
    ));
    let resolve_view = resolve.create_view(&Default::default());
    let msaa = (samples > 1).then(|| {
        device.create_texture(&tex_desc(
            "smoke msaa",
            samples,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        ))
    });
    let msaa_view = msaa.as_ref().map(|t| t.create_view(&Default::default()));
    let rpipe = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("smoke draw"),
        layout: None,
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: None,
        multisample: wgpu::MultisampleState {
            count: samples,
            ..Default::default()
        },
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets: &[Some(format.into())],
        }),
        multiview_mask: None,
        cache: None,
    });
    let row_bytes = (w * 4).div_ceil(256) * 256;
    let pixels = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("smoke pixels"),
        size: (row_bytes * h) as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });

    let mut enc = device.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(&cpipe);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(n.div_ceil(64), 1, 1);
    }
    enc.copy_buffer_to_buffer(&storage, 0, &readback, 0, n as u64 * 4);
    {
        let (view, resolve_target) = match &msaa_view {
            Some(v) => (v, Some(&resolve_view)),
            None => (&resolve_view, None),
        };
        let mut pass = enc.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("smoke pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view,
                depth_slice: None,
                resolve_target,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color {
                        r: 0.0,
                        g: 0.0,
                        b: 1.0,
                        a: 1.0,
                    }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            ..Default::default()
        });
        pass.set_pipeline(&rpipe);
        pass.draw(0..6, 0..1);
    }
    enc.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture: &resolve,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &pixels,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(row_bytes),
                rows_per_image: Some(h),
            },
        },
        wgpu::Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        },
    );
    gpu.queue.submit([enc.finish()]);
    if let Some(e) = pollster::block_on(scope.pop()) {
        return Err(GpuError::Operation(format!(
            "validation error in the smoke path: {e}"
        )));
    }

    let bytes = gpu.read_buffer(&readback)?;
    let values: Vec<u32> = bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    for (i, &v) in values.iter().enumerate() {
        let want = (i as u32) * (i as u32) + 7;
        if v != want {
            return Err(GpuError::Check(format!(
                "compute: values[{i}] = {v}, expected {want}"
            )));
        }
    }
    let img = gpu.read_buffer(&pixels)?;
    let px = |x: u32, y: u32| -> [u8; 4] {
        let o = (y * row_bytes + x * 4) as usize;
        img[o..o + 4].try_into().unwrap()
    };
    let (left, right) = (px(w / 4, h / 2), px(3 * w / 4, h / 2));
    let near = |a: [u8; 4], b: [u8; 4]| {
        a.iter()
            .zip(b)
            .all(|(&x, y)| (x as i32 - y as i32).abs() <= 2)
    };
    if !near(left, [255, 128, 64, 255]) || !near(right, [0, 0, 255, 255]) {
        return Err(GpuError::Check(format!("render: left pixel {left:?} (want ~[255,128,64,255]), right pixel {right:?} (want [0,0,255,255])")));
    }
    Ok(SmokeReport {
        compute_values_checked: values.len(),
        render_size: [w, h],
        sample_count: samples,
        msaa_note,
        left_pixel: left,
        right_pixel: right,
    })
}
