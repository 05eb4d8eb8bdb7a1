//! The headless GPU context: adapter selection, device creation, capability report.
//!
//! umbra renders off screen only. Any Vulkan, Metal or DX12 adapter works; on machines without
//! a GPU, Mesa's lavapipe (Debian package `mesa-vulkan-drivers`) provides a software Vulkan
//! device, which is what CI uses. `UMBRA_ADAPTER=<substring>` picks an adapter by name.

use std::fmt;

/// Errors of the GPU layer.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "no GPU adapter found ({0}). umbra needs a Vulkan, Metal or DX12 device; on a machine \
         without a GPU install Mesa's software Vulkan driver (Debian/Ubuntu: \
         `apt-get install mesa-vulkan-drivers`)"
    )]
    NoAdapter(String),
    #[error("could not create a GPU device on '{adapter}': {reason}")]
    Device { adapter: String, reason: String },
    #[error("GPU operation failed: {0}")]
    Operation(String),
    #[error("GPU check failed: {0}")]
    Check(String),
}

/// An adapter with its device and queue.
pub struct Gpu {
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
}

/// What `umbra info --gpu` prints.
#[derive(Clone, Debug, serde::Serialize)]
pub struct GpuReport {
    pub name: String,
    pub backend: String,
    pub device_type: String,
    pub driver: String,
    pub max_texture_3d: u32,
    pub max_texture_2d: u32,
    pub max_buffer_size: u64,
    pub max_storage_buffer_binding_size: u64,
    pub max_compute_workgroup_invocations: u32,
    pub timestamp_queries: bool,
    pub msaa_rgba16f: Vec<u32>,
    pub msaa_depth32f: Vec<u32>,
}

impl fmt::Display for GpuReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "adapter:            {}", self.name)?;
        writeln!(f, "backend:            {}", self.backend)?;
        writeln!(f, "device type:        {}", self.device_type)?;
        writeln!(f, "driver:             {}", self.driver)?;
        writeln!(f, "max 3-D texture:    {}^3", self.max_texture_3d)?;
        writeln!(f, "max 2-D texture:    {}", self.max_texture_2d)?;
        writeln!(f, "max buffer size:    {} bytes", self.max_buffer_size)?;
        writeln!(
            f,
            "max storage buffer: {} bytes",
            self.max_storage_buffer_binding_size
        )?;
        writeln!(
            f,
            "max workgroup:      {} invocations",
            self.max_compute_workgroup_invocations
        )?;
        writeln!(
            f,
            "timestamp queries:  {}",
            if self.timestamp_queries { "yes" } else { "no" }
        )?;
        writeln!(f, "MSAA rgba16float:   {:?}", self.msaa_rgba16f)?;
        write!(f, "MSAA depth32float:  {:?}", self.msaa_depth32f)
    }
}

/// Sample counts (1, 2, 4, 8, 16) the adapter supports for rendering into `format`.
pub fn supported_sample_counts(adapter: &wgpu::Adapter, format: wgpu::TextureFormat) -> Vec<u32> {
    let flags = adapter.get_texture_format_features(format).flags;
    [1u32, 2, 4, 8, 16]
        .into_iter()
        .filter(|&n| n == 1 || flags.sample_count_supported(n))
        .collect()
}

/// The largest supported sample count not above `requested`, and a note when it was lowered.
pub fn choose_sample_count(
    adapter: &wgpu::Adapter,
    format: wgpu::TextureFormat,
    requested: u32,
) -> (u32, Option<String>) {
    let counts = supported_sample_counts(adapter, format);
    let chosen = counts
        .iter()
        .copied()
        .filter(|&n| n <= requested.max(1))
        .max()
        .unwrap_or(1);
    let note = (chosen != requested).then(|| {
        format!("MSAA {requested}x is not supported for {format:?} on this adapter (supported: {counts:?}); using {chosen}x")
    });
    (chosen, note)
}

impl Gpu {
    /// Opens the best adapter: `UMBRA_ADAPTER` if set, else high performance, falling back to
    /// any adapter, software ones included.
    pub fn new() -> Result<Self, GpuError> {
        pollster::block_on(Self::new_async())
    }

    async fn new_async() -> Result<Self, GpuError> {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY);
        let instance = wgpu::Instance::new(desc);
        let adapter = match std::env::var("UMBRA_ADAPTER") {
            Ok(want) => {
                let all = instance.enumerate_adapters(wgpu::Backends::all()).await;
                let names: Vec<String> = all.iter().map(|a| a.get_info().name).collect();
                all.into_iter()
                    .find(|a| {
                        a.get_info()
                            .name
                            .to_lowercase()
                            .contains(&want.to_lowercase())
                    })
                    .ok_or_else(|| {
                        GpuError::NoAdapter(format!(
                            "UMBRA_ADAPTER={want} matches none of {names:?}"
                        ))
                    })?
            }
            Err(_) => {
                let opts = |power, fallback| wgpu::RequestAdapterOptions {
                    power_preference: power,
                    force_fallback_adapter: fallback,
                    compatible_surface: None,
                    apply_limit_buckets: false,
                };
                match instance
                    .request_adapter(&opts(wgpu::PowerPreference::HighPerformance, false))
                    .await
                {
                    Ok(a) => a,
                    Err(_) => instance
                        .request_adapter(&opts(wgpu::PowerPreference::None, true))
                        .await
                        .map_err(|e| GpuError::NoAdapter(e.to_string()))?,
                }
            }
        };
        let info = adapter.get_info();
        let mut features = wgpu::Features::empty();
        if adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY) {
            features |= wgpu::Features::TIMESTAMP_QUERY;
        }
        let limits = wgpu::Limits { ..adapter.limits() };
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("umbra"),
                required_features: features,
                required_limits: limits,
                experimental_features: wgpu::ExperimentalFeatures::disabled(),
                memory_hints: wgpu::MemoryHints::Performance,
                trace: wgpu::Trace::Off,
            })
            .await
            .map_err(|e| GpuError::Device {
                adapter: info.name.clone(),
                reason: e.to_string(),
            })?;
        Ok(Gpu {
            adapter,
            device,
            queue,
        })
    }

    pub fn report(&self) -> GpuReport {
        let info = self.adapter.get_info();
        let l = self.adapter.limits();
        GpuReport {
            name: info.name,
            backend: format!("{:?}", info.backend),
            device_type: format!("{:?}", info.device_type),
            driver: format!("{} {}", info.driver, info.driver_info)
                .trim()
                .to_string(),
            max_texture_3d: l.max_texture_dimension_3d,
            max_texture_2d: l.max_texture_dimension_2d,
            max_buffer_size: l.max_buffer_size,
            max_storage_buffer_binding_size: l.max_storage_buffer_binding_size,
            max_compute_workgroup_invocations: l.max_compute_invocations_per_workgroup,
            timestamp_queries: self
                .device
                .features()
                .contains(wgpu::Features::TIMESTAMP_QUERY),
            msaa_rgba16f: supported_sample_counts(&self.adapter, wgpu::TextureFormat::Rgba16Float),
            msaa_depth32f: supported_sample_counts(
                &self.adapter,
                wgpu::TextureFormat::Depth32Float,
            ),
        }
    }

    /// Waits for all submitted work.
    pub fn wait(&self) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Operation(format!("waiting for the device: {e}")))
    }

    /// Copies a buffer (which must have `MAP_READ`) back to the host.
    /// A storage buffer of `size` bytes for a compute pass to write, and a mappable buffer of
    /// the same size to copy it into for [`Gpu::read_buffer`].
    pub fn output_buffers(&self, label: &str, size: u64) -> (wgpu::Buffer, wgpu::Buffer) {
        let make = |suffix: &str, usage| {
            self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(&format!("{label} {suffix}")),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        (
            make(
                "output",
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            ),
            make(
                "readback",
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ),
        )
    }

    /// A compute pipeline for `entry` of `module`, its bind group layouts taken from the shader.
    pub fn compute_pipeline(
        &self,
        module: &wgpu::ShaderModule,
        entry: &str,
        label: &str,
    ) -> wgpu::ComputePipeline {
        self.device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(label),
                layout: None,
                module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
    }

    pub fn read_buffer(&self, buffer: &wgpu::Buffer) -> Result<Vec<u8>, GpuError> {
        let slice = buffer.slice(..);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.wait()?;
        rx.recv()
            .map_err(|_| GpuError::Operation("buffer mapping callback never ran".into()))?
            .map_err(|e| GpuError::Operation(format!("mapping a buffer: {e}")))?;
        let data = slice
            .get_mapped_range()
            .map_err(|e| GpuError::Operation(format!("reading a mapped buffer: {e:?}")))?
            .to_vec();
        buffer.unmap();
        Ok(data)
    }
}
