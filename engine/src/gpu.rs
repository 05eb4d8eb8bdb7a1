//! The headless GPU context: adapter selection, device creation, capability report.
//!
//! umbra renders off screen only. Any Vulkan, Metal or DX12 adapter works; on machines without
//! a GPU, Mesa's lavapipe (Debian package `mesa-vulkan-drivers`) provides a software Vulkan
//! device, which is what CI uses. `UMBRA_ADAPTER=<substring>` picks an adapter by name.

use std::any::Any;
use std::collections::HashMap;
use std::fmt;
use std::hash::{Hash, Hasher};
use std::sync::Arc;

/// Errors of the GPU layer.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "no GPU adapter found ({0}). umbra needs a Vulkan, Metal or DX12 device; on a machine \
         without a GPU install Mesa's software Vulkan driver (Debian/Ubuntu: \
         `apt-get install mesa-vulkan-drivers`)"
    )]
    NoAdapter(String),
    /// An adapter was asked for (`--adapter`, `UMBRA_ADAPTER`) that is not there.
    #[error("{0}")]
    NoMatch(String),
    #[error("could not create a GPU device on '{adapter}': {reason}")]
    Device { adapter: String, reason: String },
    #[error("GPU operation failed: {0}")]
    Operation(String),
    /// The GPU (on lavapipe: the process) could not allocate memory for `what`.
    #[error("the GPU ran out of memory for {what} ({} MB): {detail}", bytes >> 20)]
    OutOfMemory {
        what: String,
        bytes: u64,
        detail: String,
    },
    #[error("GPU check failed: {0}")]
    Check(String),
    /// A scene setting the adapter cannot honour (the message names the scene key).
    #[error("{0}")]
    Settings(String),
}

/// Records one compute pass that dispatches `pipe` with `bind` (group 0) over a `size` image
/// in 8 x 8 workgroups: the screen-space passes' recording.
pub fn dispatch_image(
    enc: &mut wgpu::CommandEncoder,
    pipe: &wgpu::ComputePipeline,
    bind: &wgpu::BindGroup,
    size: (u32, u32),
) {
    let mut pass = enc.begin_compute_pass(&Default::default());
    pass.set_pipeline(pipe);
    pass.set_bind_group(0, bind, &[]);
    pass.dispatch_workgroups(size.0.div_ceil(8), size.1.div_ceil(8), 1);
}

/// One layer of a frame's surface terms (one f32 per pixel; layer `index` of pixel `i` at
/// `index * width * height + i` of `terms`), which a surface-term pass writes.
#[derive(Clone, Copy)]
pub struct Layer<'a> {
    pub terms: &'a wgpu::Buffer,
    pub index: u32,
}

/// What binding `i` of a layout made by [`Gpu::layout`] holds.
#[derive(Clone, Copy, Debug)]
pub enum Slot {
    Uniform,
    /// A uniform buffer bound with a dynamic offset.
    UniformDynamic,
    /// A read-only storage buffer.
    Storage,
    /// A read-only storage buffer bound with a dynamic offset.
    StorageDynamic,
    StorageRw,
    /// A filterable float 2-D texture.
    Texture,
    /// A float 2-D texture read with `textureLoad` only (r32float and the like).
    UnfilterableTexture,
    /// A float 2-D array texture read with `textureLoad` only.
    UnfilterableTextureArray,
    /// A multisampled float 2-D texture (`textureLoad` per sample).
    MultisampledTexture,
    Sampler,
    /// A write-only storage texture of this format.
    StorageTexture(wgpu::TextureFormat),
}

/// An adapter with its device and queue, and the pool of what is made once per device.
///
/// The pool (re_renderer's resource pools, in small): shader modules, bind group layouts,
/// pipeline layouts and pipelines are created once per description and handed out again
/// (wgpu handles are reference-counted clones), so a second frame compiles nothing; scratch
/// buffers ([`Gpu::scratch`]) are kept per label and size, so frames of one image size reuse
/// them. Frames are recorded and waited for one at a time, which is what makes sharing the
/// scratch buffers safe: draw from one thread at a time (two threads drawing on one `Gpu`
/// would share the frame's buffers).
pub struct Gpu {
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pool: Pool,
    /// The first fault wgpu reported outside an error scope (the device lost, an uncaptured
    /// error): [`Gpu::wait`] returns it as an error instead of wgpu's default panic.
    /// (message, whether it stays: a lost device does, an error is reported once).
    fault: Arc<std::sync::Mutex<Option<(String, bool)>>>,
    /// A storage binding limit below the adapter's (0: none), set by [`Gpu::limit_bindings`].
    binding_cap: std::sync::atomic::AtomicU64,
    /// Triangles a G-buffer pass submits at once (0: the default, u64::MAX: no limit), set by
    /// [`Gpu::set_batch_triangles`].
    batch: std::sync::atomic::AtomicU64,
}

/// Triangles a G-buffer pass submits at once on a CPU adapter (2^18): lavapipe bins a
/// submission's triangles in scenes faster than its threads rasterise them, about 550 bytes a
/// triangle while they queue (1-3.5 GB for a whole-brain tractogram), so large draws are
/// submitted in batches of at most this size, each waited for (smaller in smaller scenes:
/// `gbuffer::batch_for`). Chosen by measurement (10^6 and 10^7 points, docs/benchmarks.md):
/// 2^17 saves 0.1 GB and costs 10%; 2^19 and 2^20 cost 0.1-0.3 GB more for 0-5%; no batches
/// are slower as well as larger.
pub const CPU_BATCH_TRIANGLES: u64 = 1 << 18;

/// The most bytes staged at once by [`Gpu::buffer_staged`] (64 MiB): large uploads go through
/// wgpu's staging memory in pieces, each submitted and waited for before the next.
pub const STAGING_BYTES: usize = 64 << 20;

/// The most bytes staged at once for a volume's samples (16 MiB): on a CPU adapter the staging
/// copy is host memory beside the model's samples and the GPU's, so it is kept small.
pub const VOLUME_STAGING_BYTES: usize = 16 << 20;

/// What [`Gpu::cached`] keeps: any clonable value by a key naming its description.
#[derive(Default)]
struct Pool {
    items: std::sync::Mutex<HashMap<String, Arc<dyn Any + Send + Sync>>>,
    /// How many values were made (not found) so far.
    made: std::sync::atomic::AtomicUsize,
}

/// A 64-bit hash of a hashable description (std's SipHash with fixed keys: stable in a
/// process, which is all a pool key needs).
fn key_hash<T: Hash + ?Sized>(t: &T) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    t.hash(&mut h);
    h.finish()
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
    pub max_storage_buffers_per_stage: u32,
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
            "storage buffers:    {} a shader stage",
            self.max_storage_buffers_per_stage
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

/// One adapter of [`adapters`]: what `umbra info --adapters` lists.
#[derive(Clone, Debug, serde::Serialize)]
pub struct AdapterEntry {
    /// Its position in the list, what `--adapter N` names.
    pub index: usize,
    pub name: String,
    pub backend: String,
    pub device_type: String,
    /// PCI bus id as the driver reports it (`domain:bus:device.function`), empty where it
    /// reports none (software adapters, some drivers).
    pub pci_bus_id: String,
    pub driver: String,
}

/// Every adapter this machine offers, in the order `--adapter N` counts them.
pub fn adapters() -> Vec<AdapterEntry> {
    let instance = Gpu::instance();
    let all = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
    all.iter()
        .enumerate()
        .map(|(index, a)| {
            let i = a.get_info();
            AdapterEntry {
                index,
                name: i.name,
                backend: format!("{:?}", i.backend),
                device_type: format!("{:?}", i.device_type),
                pci_bus_id: i.device_pci_bus_id,
                driver: format!("{} {}", i.driver, i.driver_info).trim().to_string(),
            }
        })
        .collect()
}

/// Which adapter to open: by its index in [`adapters`], by PCI bus id (identical GPUs of a
/// multi-GPU node differ only there) or by a part of its name.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum AdapterChoice {
    Index(usize),
    /// `[domain:]bus:device.function`, hexadecimal (what `nvidia-smi --query-gpu=pci.bus_id`
    /// and `lspci -D` print; case, zero padding and a missing domain, read as 0, do not matter).
    PciBus([u32; 4]),
    /// A case-insensitive part of the adapter's name (`llvmpipe`, `A100`).
    Name(String),
}

impl AdapterChoice {
    /// Reads a choice: a decimal number is an index; `pci:BUS` or a bus id of the form above is
    /// a PCI bus id; anything else is a part of a name.
    pub fn parse(text: &str) -> Result<AdapterChoice, String> {
        let t = text.trim();
        if t.is_empty() {
            return Err(
                "empty adapter choice: give an index, a PCI bus id or a part of a name".into(),
            );
        }
        if let Ok(k) = t.parse::<usize>() {
            return Ok(AdapterChoice::Index(k));
        }
        let bus = t.strip_prefix("pci:").or_else(|| t.strip_prefix("PCI:"));
        match (bus, parse_pci_bus_id(bus.unwrap_or(t))) {
            (_, Some(b)) => Ok(AdapterChoice::PciBus(b)),
            (Some(b), None) => Err(format!(
                "'{b}' is not a PCI bus id ([domain:]bus:device.function in hexadecimal, e.g. 0000:3b:00.0)"
            )),
            (None, None) => Ok(AdapterChoice::Name(t.to_lowercase())),
        }
    }

    /// The index in `infos` this choice names, or why none.
    pub fn pick(&self, infos: &[wgpu::AdapterInfo]) -> Result<usize, String> {
        let list = || {
            let all: Vec<String> = infos
                .iter()
                .enumerate()
                .map(|(k, i)| {
                    let bus = if i.device_pci_bus_id.is_empty() {
                        String::new()
                    } else {
                        format!(" at {}", i.device_pci_bus_id)
                    };
                    format!("{k}: {} ({:?}){bus}", i.name, i.backend)
                })
                .collect();
            if all.is_empty() {
                "no adapters at all".to_string()
            } else {
                format!("the adapters are {}", all.join("; "))
            }
        };
        let found = match self {
            AdapterChoice::Index(k) => (*k < infos.len()).then_some(*k),
            AdapterChoice::PciBus(b) => infos
                .iter()
                .position(|i| parse_pci_bus_id(&i.device_pci_bus_id) == Some(*b)),
            AdapterChoice::Name(n) => infos
                .iter()
                .position(|i| i.name.to_lowercase().contains(n.as_str())),
        };
        found.ok_or_else(|| format!("{} matches no adapter: {}", self.describe(), list()))
    }

    fn describe(&self) -> String {
        match self {
            AdapterChoice::Index(k) => format!("adapter index {k}"),
            AdapterChoice::PciBus(b) => {
                format!(
                    "PCI bus id {:04x}:{:02x}:{:02x}.{:x}",
                    b[0], b[1], b[2], b[3]
                )
            }
            AdapterChoice::Name(n) => format!("adapter name '{n}'"),
        }
    }
}

/// `[domain:]bus:device.function` in hexadecimal as numbers, or `None` when `text` is not one.
pub fn parse_pci_bus_id(text: &str) -> Option<[u32; 4]> {
    let (head, function) = text.trim().rsplit_once('.')?;
    let parts: Vec<&str> = head.split(':').collect();
    let (domain, bus, device) = match parts[..] {
        [d, b, v] => (d, b, v),
        [b, v] => ("0", b, v),
        _ => return None,
    };
    let hex = |s: &str, max: u32| {
        (!s.is_empty() && s.len() <= 8)
            .then(|| u32::from_str_radix(s, 16).ok())
            .flatten()
            .filter(|&v| v <= max)
    };
    Some([
        hex(domain, u32::MAX)?,
        hex(bus, 0xff)?,
        hex(device, 0x1f)?,
        hex(function, 0x7)?,
    ])
}

impl Gpu {
    /// Opens the best adapter: the one `UMBRA_ADAPTER` names (see [`AdapterChoice`]) if set,
    /// else high performance, falling back to any adapter, software ones included.
    pub fn new() -> Result<Self, GpuError> {
        let choice = match std::env::var("UMBRA_ADAPTER") {
            Ok(v) => Some(
                AdapterChoice::parse(&v)
                    .map_err(|e| GpuError::NoMatch(format!("UMBRA_ADAPTER={v}: {e}")))?,
            ),
            Err(_) => None,
        };
        Self::open(choice.as_ref())
    }

    /// Opens the adapter `choice` names, or the best one (see [`Gpu::new`]; `UMBRA_ADAPTER` is
    /// not read) when it is `None`.
    pub fn open(choice: Option<&AdapterChoice>) -> Result<Self, GpuError> {
        pollster::block_on(Self::new_async(choice))
    }

    fn instance() -> wgpu::Instance {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY);
        wgpu::Instance::new(desc)
    }

    async fn new_async(choice: Option<&AdapterChoice>) -> Result<Self, GpuError> {
        let instance = Self::instance();
        let adapter = match choice {
            Some(want) => {
                let all = instance.enumerate_adapters(wgpu::Backends::all()).await;
                let infos: Vec<wgpu::AdapterInfo> = all.iter().map(|a| a.get_info()).collect();
                let k = want.pick(&infos).map_err(if infos.is_empty() {
                    GpuError::NoAdapter
                } else {
                    GpuError::NoMatch
                })?;
                all.into_iter()
                    .nth(k)
                    .expect("pick returns an index of the list")
            }
            None => {
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
        // Timestamps between passes of one command buffer (per-pass GPU times of a frame).
        let between =
            wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS;
        if adapter.features().contains(between) {
            features |= between;
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
        type Fault = Arc<std::sync::Mutex<Option<(String, bool)>>>;
        let fault: Fault = Arc::default();
        let keep = |f: &Fault, msg: String, stays: bool| {
            if let Ok(mut g) = f.lock() {
                if g.as_ref().is_none_or(|(_, s)| !s) {
                    *g = Some((msg, stays));
                }
            }
        };
        let f = fault.clone();
        device.set_device_lost_callback(move |reason, msg| {
            keep(
                &f,
                format!("the GPU device was lost ({reason:?}): {msg}; the driver may have reset it (a frame too long for its watchdog, or too much memory): try a smaller image or scene"),
                true,
            )
        });
        let f = fault.clone();
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            keep(&f, format!("GPU error: {e}"), false)
        }));
        Ok(Gpu {
            binding_cap: 0.into(),
            batch: 0.into(),
            adapter,
            device,
            queue,
            pool: Pool::default(),
            fault,
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
            max_storage_buffers_per_stage: l.max_storage_buffers_per_shader_stage,
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

    /// The value kept under `key`, made by `make` the first time it is asked for.
    pub fn cached<T: Clone + Send + Sync + 'static>(
        &self,
        key: String,
        make: impl FnOnce() -> T,
    ) -> T {
        if let Some(v) = self.pool_get::<T>(&key) {
            return v;
        }
        // Made outside the lock: `make` may itself ask the pool.
        self.pool_put(key, make())
    }

    /// Keeps `v` under `key` (replacing what was there), counts it as made, and returns it.
    fn pool_put<T: Clone + Send + Sync + 'static>(&self, key: String, v: T) -> T {
        self.pool
            .made
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.pool
            .items
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .insert(key, Arc::new(v.clone()));
        v
    }

    fn pool_get<T: Clone + 'static>(&self, key: &str) -> Option<T> {
        let items = self.pool.items.lock().unwrap_or_else(|e| e.into_inner());
        items.get(key).and_then(|v| v.downcast_ref::<T>()).cloned()
    }

    /// How many pooled objects (modules, layouts, pipelines, scratch buffers) were created so
    /// far: constant across frames that compile and allocate nothing new.
    pub fn pool_made(&self) -> usize {
        self.pool.made.load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Whether per-pass times come from timestamps written between the passes of a command
    /// buffer: where the adapter can, except on CPU adapters. On lavapipe (measured at
    /// 1024 x 768, the demo scene) the timestamps between compute passes are not ordered after
    /// the previous pass's work - FXAA read 0.07 ms against 62 ms by fences, the difference
    /// landing in the pass before - so there each pass is timed alone with fences.
    pub fn has_pass_timestamps(&self) -> bool {
        self.device.features().contains(
            wgpu::Features::TIMESTAMP_QUERY | wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS,
        ) && self.adapter.get_info().device_type != wgpu::DeviceType::Cpu
    }

    /// Whether the adapter is a CPU (lavapipe, llvmpipe, WARP).
    pub fn is_cpu(&self) -> bool {
        self.adapter.get_info().device_type == wgpu::DeviceType::Cpu
    }

    /// Waits for all submitted work.
    pub fn wait(&self) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Operation(format!("waiting for the device: {e}")))?;
        self.check_fault()
    }

    /// The fault wgpu reported outside an error scope since the device was opened, if any.
    pub fn check_fault(&self) -> Result<(), GpuError> {
        let Ok(mut g) = self.fault.lock() else {
            return Ok(());
        };
        match g.clone() {
            Some((m, stays)) => {
                if !stays {
                    *g = None;
                }
                Err(GpuError::Operation(m))
            }
            None => Ok(()),
        }
    }

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

    /// A bind group layout whose binding `i` is `slots[i]`, visible to `stages`.
    pub fn layout(
        &self,
        label: &str,
        stages: wgpu::ShaderStages,
        slots: &[Slot],
    ) -> wgpu::BindGroupLayout {
        let key = format!("layout {label} {stages:?} {slots:?}");
        self.cached(key, || self.make_layout(label, stages, slots))
    }

    fn make_layout(
        &self,
        label: &str,
        stages: wgpu::ShaderStages,
        slots: &[Slot],
    ) -> wgpu::BindGroupLayout {
        let entries: Vec<wgpu::BindGroupLayoutEntry> = slots
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let buffer = |ty, has_dynamic_offset| wgpu::BindingType::Buffer {
                    ty,
                    has_dynamic_offset,
                    min_binding_size: None,
                };
                let texture = |filterable, multisampled| wgpu::BindingType::Texture {
                    sample_type: wgpu::TextureSampleType::Float { filterable },
                    view_dimension: wgpu::TextureViewDimension::D2,
                    multisampled,
                };
                let ty = match s {
                    Slot::Uniform => buffer(wgpu::BufferBindingType::Uniform, false),
                    Slot::UniformDynamic => buffer(wgpu::BufferBindingType::Uniform, true),
                    Slot::Storage => {
                        buffer(wgpu::BufferBindingType::Storage { read_only: true }, false)
                    }
                    Slot::StorageDynamic => {
                        buffer(wgpu::BufferBindingType::Storage { read_only: true }, true)
                    }
                    Slot::StorageRw => {
                        buffer(wgpu::BufferBindingType::Storage { read_only: false }, false)
                    }
                    Slot::Texture => texture(true, false),
                    Slot::UnfilterableTexture => texture(false, false),
                    Slot::UnfilterableTextureArray => wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2Array,
                        multisampled: false,
                    },
                    Slot::MultisampledTexture => texture(false, true),
                    Slot::Sampler => {
                        wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering)
                    }
                    Slot::StorageTexture(format) => wgpu::BindingType::StorageTexture {
                        access: wgpu::StorageTextureAccess::WriteOnly,
                        format: *format,
                        view_dimension: wgpu::TextureViewDimension::D2,
                    },
                };
                wgpu::BindGroupLayoutEntry {
                    binding: i as u32,
                    visibility: stages,
                    ty,
                    count: None,
                }
            })
            .collect();
        self.device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries: &entries,
            })
    }

    /// A bind group whose binding `i` is `resources[i]`.
    pub fn bind(
        &self,
        label: &str,
        layout: &wgpu::BindGroupLayout,
        resources: &[wgpu::BindingResource],
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = resources
            .iter()
            .enumerate()
            .map(|(i, r)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: r.clone(),
            })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout,
            entries: &entries,
        })
    }

    /// A pipeline layout of the given bind group layouts (group `i` is `layouts[i]`).
    pub fn pipeline_layout(
        &self,
        label: &str,
        layouts: &[&wgpu::BindGroupLayout],
    ) -> wgpu::PipelineLayout {
        let key = format!("pipeline layout {label} {:x}", key_hash(layouts));
        self.cached(key, || {
            let l: Vec<Option<&wgpu::BindGroupLayout>> = layouts.iter().map(|l| Some(*l)).collect();
            self.device
                .create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                    label: Some(label),
                    bind_group_layouts: &l,
                    immediate_size: 0,
                })
        })
    }

    /// A compute pipeline for `entry` of `module` with an explicit layout.
    pub fn compute_pipeline_with(
        &self,
        module: &wgpu::ShaderModule,
        entry: &str,
        layout: &wgpu::PipelineLayout,
        label: &str,
    ) -> wgpu::ComputePipeline {
        self.compute_pipeline_constants(module, entry, layout, label, &[])
    }

    /// As [`Gpu::compute_pipeline_with`], with values for the shader's `override` constants.
    pub fn compute_pipeline_constants(
        &self,
        module: &wgpu::ShaderModule,
        entry: &str,
        layout: &wgpu::PipelineLayout,
        label: &str,
        constants: &[(&str, f64)],
    ) -> wgpu::ComputePipeline {
        let bits: Vec<(&str, u64)> = constants.iter().map(|(k, v)| (*k, v.to_bits())).collect();
        let key = format!(
            "compute {label} {entry} {:x}",
            key_hash(&(module, layout, bits))
        );
        self.cached(key, || {
            self.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(label),
                    layout: Some(layout),
                    module,
                    entry_point: Some(entry),
                    compilation_options: wgpu::PipelineCompilationOptions {
                        constants,
                        ..Default::default()
                    },
                    cache: None,
                })
        })
    }

    /// A buffer holding `bytes` with `usage`.
    /// Checks that a buffer of `bytes` with `usage` fits this adapter (its largest buffer and,
    /// for storage buffers, its largest binding), naming the buffer and both sizes: wgpu would
    /// otherwise panic inside `create_buffer` (the 2.6 GB tube vertex buffer of a whole-brain
    /// tractogram) or fail validation at draw time.
    pub fn check_buffer(
        &self,
        label: &str,
        bytes: u64,
        usage: wgpu::BufferUsages,
    ) -> Result<(), GpuError> {
        let l = self.device.limits();
        let (most, what) = if usage.contains(wgpu::BufferUsages::STORAGE) {
            (self.storage_limit(), "storage binding")
        } else {
            (l.max_buffer_size, "buffer")
        };
        if bytes > most {
            return Err(GpuError::Operation(format!(
                "{label}: {} MB, more than this adapter's largest {what} ({} MB): draw fewer \
                 streamlines or triangles (a selection, a subsample, fewer tube sides)",
                bytes >> 20,
                most >> 20
            )));
        }
        Ok(())
    }

    /// The largest storage binding data may use: the adapter's largest binding and buffer,
    /// or less after [`Gpu::limit_bindings`].
    pub fn storage_limit(&self) -> u64 {
        let l = self.device.limits();
        let most = l.max_storage_buffer_binding_size.min(l.max_buffer_size);
        match self.binding_cap.load(std::sync::atomic::Ordering::Relaxed) {
            0 => most,
            cap => cap.min(most),
        }
    }

    /// Lowers the storage binding limit that data are split by to `bytes` (rounded down to a
    /// multiple of 16, at least 64; `None`: the adapter's again), so that small data exercise
    /// the split of large ones.
    pub fn limit_bindings(&self, bytes: Option<u64>) {
        let cap = bytes.map_or(0, |b| (b & !15).max(64));
        self.binding_cap
            .store(cap, std::sync::atomic::Ordering::Relaxed);
    }

    /// The most triangles a G-buffer pass submits at once: [`CPU_BATCH_TRIANGLES`] on a CPU
    /// adapter, no limit on a GPU, or what [`Gpu::set_batch_triangles`] set.
    pub fn batch_triangles(&self) -> Option<u64> {
        match self.batch.load(std::sync::atomic::Ordering::Relaxed) {
            0 => self.is_cpu().then_some(CPU_BATCH_TRIANGLES),
            u64::MAX => None,
            n => Some(n),
        }
    }

    /// Sets the batch size of [`Gpu::batch_triangles`] (`Some(n)`: at most `n`, at least 1;
    /// `None`: no limit); tests split small scenes this way.
    pub fn set_batch_triangles(&self, n: Option<u64>) {
        let v = n.map_or(u64::MAX, |n| n.clamp(1, u64::MAX - 1));
        self.batch.store(v, std::sync::atomic::Ordering::Relaxed);
    }

    /// Runs `make`, which allocates GPU memory for `what` (`bytes` in all), and returns the GPU
    /// running out of memory meanwhile as [`GpuError::OutOfMemory`] naming it. Without this a
    /// buffer that could not be allocated surfaces later as a validation error about an
    /// invalid buffer (or the first write to it does), which names nothing a user can change.
    pub fn allocating<T>(
        &self,
        what: &str,
        bytes: u64,
        make: impl FnOnce() -> Result<T, GpuError>,
    ) -> Result<T, GpuError> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let valid = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let out = make();
        let invalid = pollster::block_on(valid.pop());
        let short = pollster::block_on(oom.pop());
        if let Some(e) = short {
            return Err(GpuError::OutOfMemory {
                what: what.to_string(),
                bytes,
                detail: e.to_string(),
            });
        }
        if let Some(e) = invalid {
            return Err(GpuError::Operation(format!("{what}: {e}")));
        }
        out
    }

    /// A buffer holding `bytes`, filled through staging copies of at most [`STAGING_BYTES`]
    /// each, submitted and waited for in turn: the transient memory of an upload stays
    /// bounded whatever its size (`create_buffer_init` would stage all of it at once).
    pub fn buffer_staged(
        &self,
        label: &str,
        bytes: &[u8],
        usage: wgpu::BufferUsages,
    ) -> Result<wgpu::Buffer, GpuError> {
        self.buffer_staged_by(label, bytes, usage, STAGING_BYTES)
    }

    /// [`Gpu::buffer_staged`] with pieces of at most `piece` bytes (a multiple of 4).
    pub fn buffer_staged_by(
        &self,
        label: &str,
        bytes: &[u8],
        usage: wgpu::BufferUsages,
        piece: usize,
    ) -> Result<wgpu::Buffer, GpuError> {
        if bytes.len() <= piece {
            return Ok(self.buffer(label, bytes, usage));
        }
        let buf = self.writable(label, bytes.len(), usage);
        let mut at = 0;
        while at < bytes.len() {
            let end = (at + piece).min(bytes.len());
            self.write_padded(&buf, at, &bytes[at..end]);
            self.queue.submit([]);
            self.wait()?;
            at = end;
        }
        Ok(buf)
    }

    /// A buffer holding `bytes` (padded with zeros to a multiple of 4), written through the
    /// queue. Not `create_buffer_init`: that maps the new buffer and panics when the GPU could
    /// not allocate it, where this leaves an out-of-memory error for [`Gpu::allocating`] (or
    /// the uncaptured-error handler) to report.
    pub fn buffer(&self, label: &str, bytes: &[u8], usage: wgpu::BufferUsages) -> wgpu::Buffer {
        let buf = self.writable(label, bytes.len(), usage);
        self.write_padded(&buf, 0, bytes);
        buf
    }

    /// An unmapped buffer of `len` bytes rounded up to a multiple of 4, writable by the queue.
    fn writable(&self, label: &str, len: usize, usage: wgpu::BufferUsages) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: (len as u64).next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT),
            usage: usage | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// Queues `bytes` into `buf` at byte `at` (a multiple of 4), zero-padded to a multiple of 4.
    fn write_padded(&self, buf: &wgpu::Buffer, at: usize, bytes: &[u8]) {
        if bytes.is_empty() {
            return;
        }
        if bytes.len().is_multiple_of(4) {
            self.queue.write_buffer(buf, at as u64, bytes);
        } else {
            let mut padded = bytes.to_vec();
            padded.resize(bytes.len().next_multiple_of(4), 0);
            self.queue.write_buffer(buf, at as u64, &padded);
        }
    }

    /// A storage buffer of `size` bytes (at least 16) that a pass writes in full before it is
    /// read in every frame: one per label is pooled and handed out again while the size
    /// stays the same (a new size replaces it), so its contents are whatever the last frame
    /// left.
    pub fn scratch(&self, label: &str, size: u64, extra: wgpu::BufferUsages) -> wgpu::Buffer {
        let key = format!("scratch {label} {extra:?}");
        self.sized(key, size.max(16), || self.zeroed(label, size, extra))
    }

    /// The value pooled under `key` while its description `desc` (a size, a sample count) is
    /// the same; else a new one from `make`, which replaces it in the pool (the old one is
    /// released when its last user drops it).
    pub fn sized_entry<D, T>(&self, key: String, desc: D, make: impl FnOnce() -> T) -> T
    where
        D: PartialEq + Clone + Send + Sync + 'static,
        T: Clone + Send + Sync + 'static,
    {
        if let Some((d, v)) = self.pool_get::<(D, T)>(&key) {
            if d == desc {
                return v;
            }
        }
        self.pool_put(key, (desc, make())).1
    }

    /// The buffer pooled under `key` while its size is `size`; else a new one from `make`
    /// (of that size), which replaces it in the pool.
    pub fn sized(
        &self,
        key: String,
        size: u64,
        make: impl FnOnce() -> wgpu::Buffer,
    ) -> wgpu::Buffer {
        if let Some(b) = self.pool_get::<wgpu::Buffer>(&key) {
            if b.size() == size {
                return b;
            }
        }
        self.pool_put(key, make())
    }

    /// A new storage buffer of `size` bytes (at least 16), zero-filled (not pooled).
    pub fn zeroed(&self, label: &str, size: u64, extra: wgpu::BufferUsages) -> wgpu::Buffer {
        self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: size.max(16),
            usage: wgpu::BufferUsages::STORAGE | extra,
            mapped_at_creation: false,
        })
    }

    /// A WGSL module, compiled once per label and source; compile errors come back through
    /// the caller's error scope.
    pub fn shader(&self, label: &str, source: &str) -> wgpu::ShaderModule {
        let key = format!("shader {label} {:x}", key_hash(source));
        self.cached(key, || {
            self.device
                .create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some(label),
                    source: wgpu::ShaderSource::Wgsl(source.into()),
                })
        })
    }

    /// Copies a buffer (which must have `MAP_READ`) back to the host.
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
        let data = slice.get_mapped_range().map(|r| r.to_vec());
        // Unmapped whatever happened: a pooled buffer left mapped would fail every later copy.
        buffer.unmap();
        data.map_err(|e| GpuError::Operation(format!("reading a mapped buffer: {e:?}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info(name: &str, bus: &str) -> wgpu::AdapterInfo {
        let mut i = wgpu::AdapterInfo::new(wgpu::DeviceType::DiscreteGpu, wgpu::Backend::Vulkan);
        i.name = name.into();
        i.device_pci_bus_id = bus.into();
        i
    }

    /// A buffer over the adapter's limits is an error naming it and both sizes, before wgpu
    /// sees it (issue 17: the 2.6 GB vertex buffer panicked inside wgpu).
    #[test]
    fn buffers_over_the_adapters_limits_are_errors_naming_them() {
        let Ok(g) = Gpu::new() else {
            eprintln!("skipped: no GPU adapter");
            return;
        };
        let l = g.device.limits();
        let v = wgpu::BufferUsages::VERTEX;
        let s = wgpu::BufferUsages::STORAGE;
        assert!(g
            .check_buffer("tube vertices", l.max_buffer_size, v)
            .is_ok());
        let e = g
            .check_buffer("tube vertices", l.max_buffer_size + 1, v)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("tube vertices") && e.contains("largest buffer"),
            "{e}"
        );
        let most = l.max_storage_buffer_binding_size.min(l.max_buffer_size);
        assert_eq!(g.storage_limit(), most);
        assert!(g.check_buffer("line points", most, s).is_ok());
        let e = g
            .check_buffer("line points", most + 1, s)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("line points") && e.contains("storage binding"),
            "{e}"
        );
        // A lowered limit, rounded down to 16 bytes, and lifted again.
        g.limit_bindings(Some(1000));
        assert_eq!(g.storage_limit(), 992);
        assert!(g.check_buffer("line points", 992, s).is_ok());
        assert!(g.check_buffer("line points", 993, s).is_err());
        g.limit_bindings(None);
        assert_eq!(g.storage_limit(), most);
    }

    /// A buffer filled in pieces holds every byte, the last piece's odd length included.
    #[test]
    fn staged_buffers_hold_every_piece() {
        let Ok(g) = Gpu::new() else {
            eprintln!("skipped: no GPU adapter");
            return;
        };
        let bytes: Vec<u8> = (0..10_003u32).map(|i| (i * 7 % 251) as u8).collect();
        let usage = wgpu::BufferUsages::COPY_SRC;
        let buf = g.buffer_staged_by("staged", &bytes, usage, 1000).unwrap();
        let back = g.device.create_buffer(&wgpu::BufferDescriptor {
            label: None,
            size: buf.size(),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = g.device.create_command_encoder(&Default::default());
        enc.copy_buffer_to_buffer(&buf, 0, &back, 0, buf.size());
        g.queue.submit([enc.finish()]);
        let got = g.read_buffer(&back).unwrap();
        assert_eq!(buf.size(), 10_004);
        assert_eq!(&got[..bytes.len()], &bytes[..]);
    }

    #[test]
    fn pci_bus_ids_compare_as_numbers_whatever_their_spelling() {
        // nvidia-smi pads the domain to 8 digits in capitals; Vulkan and lspci -D use 4.
        let want = Some([0, 0x3b, 0, 0]);
        assert_eq!(parse_pci_bus_id("00000000:3B:00.0"), want);
        assert_eq!(parse_pci_bus_id("0000:3b:00.0"), want);
        assert_eq!(parse_pci_bus_id("3b:00.0"), want);
        assert_eq!(parse_pci_bus_id("0001:3b:1f.7"), Some([1, 0x3b, 0x1f, 7]));
        for bad in [
            "",
            "3b",
            "3b:00",
            "0000:3b:20.0",
            "0000:3b:00.8",
            "0000:xx:00.0",
            "a:b:c:d.0",
        ] {
            assert_eq!(parse_pci_bus_id(bad), None, "{bad}");
        }
    }

    #[test]
    fn an_adapter_is_chosen_by_index_bus_id_or_name() {
        let infos = [
            info("NVIDIA H100", "0000:17:00.0"),
            info("NVIDIA H100", "0000:3b:00.0"),
            info("llvmpipe (LLVM 19)", ""),
        ];
        let pick = |t: &str| AdapterChoice::parse(t).unwrap().pick(&infos);
        assert_eq!(pick("1"), Ok(1));
        assert_eq!(pick("00000000:3B:00.0"), Ok(1));
        assert_eq!(pick("pci:17:00.0"), Ok(0));
        assert_eq!(pick("LLVMpipe"), Ok(2));
        // Identical names: the first; the bus id tells them apart.
        assert_eq!(pick("h100"), Ok(0));
        let e = pick("3").unwrap_err();
        assert!(
            e.contains("adapter index 3") && e.contains("1: NVIDIA H100 (Vulkan) at 0000:3b:00.0"),
            "{e}"
        );
        assert!(pick("0000:5e:00.0")
            .unwrap_err()
            .contains("PCI bus id 0000:5e:00.0"));
        assert!(AdapterChoice::parse("pci:zz")
            .unwrap_err()
            .contains("not a PCI bus id"));
        assert!(AdapterChoice::parse(" ").is_err());
    }
}
