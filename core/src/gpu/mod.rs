//! The GPU context: adapter selection, device creation with the limits the techniques need,
//! readback, timestamp timing and memory accounting.
//!
//! Adapter choice is deterministic: adapters are ranked by a fixed order (see
//! [`AdapterPreference`]) and then by name, so a result never depends on enumeration order.
//! Tests ask for [`AdapterPreference::Cpu`] (lavapipe) so they run the same everywhere.

mod fragments;
mod layout;
pub mod memory;
mod readback;
mod timing;
pub mod trace;

pub use fragments::{FragmentTally, TargetWrites};
pub use layout::MirrorLayout;
pub use memory::{AllocationError, LedgerEntry, MemoryBudget, MemoryLedger, largest_that_fits};
pub use readback::{
    Rgba16fImage, read_buffer, read_texture_r16f, read_texture_rgba8, read_texture_rgba16f,
};
pub use timing::{CLOCK_TOLERANCE, GpuTimer, MAX_TIMED_PASSES, PassSpan, PassTimes, clock_warning};

use std::fmt;

/// Errors from GPU setup. Each renders as one line for the user.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "no GPU adapter found{detail}: install a Vulkan driver (on a machine without a GPU, Mesa's \
         lavapipe: `apt-get install mesa-vulkan-drivers libvulkan1`)"
    )]
    NoAdapter { detail: String },
    #[error("cannot create a device on adapter \"{adapter}\": {cause}")]
    Device {
        adapter: String,
        cause: wgpu::RequestDeviceError,
    },
    #[error("GPU readback failed: {0}")]
    Readback(String),
    /// The device refused work inside an error scope ([`Gpu::scoped`]): out of memory, or a
    /// validation error.
    #[error("{what}: the GPU refused it: {cause}")]
    Refused { what: String, cause: String },
}

/// What the device refused inside [`Gpu::scoped`], in one line.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Refusal {
    pub cause: String,
}

impl Refusal {
    /// The refusal as the error of `what` was being done ("creating osm at 32 channels ...").
    pub fn during(self, what: impl Into<String>) -> GpuError {
        GpuError::Refused {
            what: what.into(),
            cause: self.cause,
        }
    }
}

/// A wgpu error as one line: its description's lines joined, blank ones dropped.
pub fn one_line(error: &wgpu::Error) -> String {
    error
        .to_string()
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}

/// Keeps Mesa's implicit Vulkan device-selection layer from printing
/// `error: XDG_RUNTIME_DIR is invalid or not set in the environment.` (twice) on a machine
/// without a display session.
///
/// The layer (`VK_LAYER_MESA_device_select`) connects to a Wayland display while the instance
/// enumerates devices, to move the display's GPU first; with no `XDG_RUNTIME_DIR` libwayland
/// prints that line. The tool ranks adapters itself ([`rank`], `--adapter`), so the layer adds
/// nothing: it is disabled through its own switch, `NODEVICE_SELECT=1`, unless the user set
/// that or chose a device for it (`MESA_VK_DEVICE_SELECT`). Surfaces (the viewer on X11 or
/// Wayland) do not depend on the layer.
///
/// Call it first in `main`, before any thread starts: it sets an environment variable.
pub fn quiet_device_select_layer() {
    let user_chose = ["NODEVICE_SELECT", "MESA_VK_DEVICE_SELECT"]
        .iter()
        .any(|v| std::env::var_os(v).is_some());
    if !user_chose {
        // SAFETY: called at the start of `main`, before any other thread exists, so nothing
        // reads the environment concurrently.
        unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
    }
}

/// Which adapter to use when several are present.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum AdapterPreference {
    /// Discrete GPU, then integrated, then virtual, then CPU (software).
    #[default]
    Auto,
    /// A CPU adapter (lavapipe / llvmpipe) only: deterministic, what tests and CI use.
    Cpu,
    /// The first adapter whose name contains this text (case-insensitive).
    Named(String),
}

impl std::str::FromStr for AdapterPreference {
    type Err = std::convert::Infallible;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Ok(match s.to_ascii_lowercase().as_str() {
            "auto" => Self::Auto,
            "cpu" => Self::Cpu,
            _ => Self::Named(s.to_owned()),
        })
    }
}

impl fmt::Display for AdapterPreference {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Auto => f.write_str("auto"),
            Self::Cpu => f.write_str("cpu"),
            Self::Named(name) => write!(f, "\"{name}\""),
        }
    }
}

/// Features the renderer uses when the adapter has them; none is required.
pub const OPTIONAL_FEATURES: wgpu::Features = wgpu::Features::TIMESTAMP_QUERY
    .union(wgpu::Features::FLOAT32_BLENDABLE)
    .union(wgpu::Features::FLOAT32_FILTERABLE)
    .union(wgpu::Features::PIPELINE_STATISTICS_QUERY);

/// llvmpipe's loop limit, 65,535, less a margin for the short loops around the ones a shader
/// budgets ([`Gpu::loop_budget`]).
pub const LLVMPIPE_LOOP_BUDGET: u32 = 60_000;

/// How a lost device's message starts ([`Gpu::take_uncaptured_error`]).
pub const DEVICE_LOST: &str = "the GPU device was lost";

/// The device, queue and what we learnt about the adapter.
pub struct Gpu {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub features: wgpu::Features,
    pub limits: wgpu::Limits,
    /// [`Gpu::clock_floor_ms`], measured once.
    clock_floor: std::sync::OnceLock<f64>,
    /// See [`Gpu::take_uncaptured_error`].
    uncaptured: std::sync::Arc<std::sync::Mutex<Option<String>>>,
}

impl Gpu {
    /// Picks an adapter by `preference` and creates a device with the adapter's own limits (the
    /// defaults allow only 32 bytes per sample, too few for 8 RGBA16F targets).
    pub async fn new(preference: &AdapterPreference) -> Result<Self, GpuError> {
        let adapter = select_adapter(&instance(), preference).await?;
        Self::from_adapter(&adapter).await
    }

    /// Creates the device on a given adapter.
    pub async fn from_adapter(adapter: &wgpu::Adapter) -> Result<Self, GpuError> {
        let info = adapter.get_info();
        let (device, queue) = adapter
            .request_device(&device_descriptor(adapter))
            .await
            .map_err(|cause| GpuError::Device {
                adapter: info.name.clone(),
                cause,
            })?;
        Ok(Self::from_device(device, queue, info))
    }

    /// Wraps a device someone else created (the viewer's, made by eframe with
    /// [`device_descriptor`]); features and limits are read from the device itself.
    ///
    /// Installs the device's last line of defence: a GPU error that no [`Gpu::scoped`] caught,
    /// or a lost device, prints one `error:` line and ends the process with status 2 on the host
    /// (wgpu's default handler panics with a backtrace), and is kept on the web. Everything that
    /// can fail for a reason the user controls (allocation sizes, budgets) is checked before or
    /// scoped, so this fires only for driver failures.
    pub fn from_device(device: wgpu::Device, queue: wgpu::Queue, info: wgpu::AdapterInfo) -> Self {
        let uncaptured = std::sync::Arc::new(std::sync::Mutex::new(None::<String>));
        #[cfg(not(target_arch = "wasm32"))]
        {
            device.on_uncaptured_error(std::sync::Arc::new(|error: wgpu::Error| {
                eprintln!("error: GPU error: {}", one_line(&error));
                std::process::exit(2);
            }));
            device.set_device_lost_callback(|reason, message| {
                // `Destroyed` is the device being dropped on purpose.
                if reason != wgpu::DeviceLostReason::Destroyed {
                    eprintln!("error: {DEVICE_LOST}: {message}");
                    std::process::exit(2);
                }
            });
        }
        // A page has no process to end: the error is kept for the page to show
        // ([`Gpu::take_uncaptured_error`]) and the page keeps working.
        #[cfg(target_arch = "wasm32")]
        {
            let kept = uncaptured.clone();
            device.on_uncaptured_error(std::sync::Arc::new(move |error: wgpu::Error| {
                if let Ok(mut slot) = kept.lock() {
                    slot.get_or_insert_with(|| format!("GPU error: {}", one_line(&error)));
                }
            }));
            let kept = uncaptured.clone();
            device.set_device_lost_callback(move |reason, message| {
                if reason != wgpu::DeviceLostReason::Destroyed
                    && let Ok(mut slot) = kept.lock()
                {
                    *slot = Some(format!("{DEVICE_LOST}: {message}"));
                }
            });
        }
        Self {
            features: device.features(),
            limits: device.limits(),
            device,
            queue,
            info,
            clock_floor: std::sync::OnceLock::new(),
            uncaptured,
        }
    }

    /// The first GPU error no [`Gpu::scoped`] caught since the last call, or a lost device
    /// (on the web, where they are kept; on the host they end the process in one line).
    pub fn take_uncaptured_error(&self) -> Option<String> {
        self.uncaptured.lock().ok().and_then(|mut slot| slot.take())
    }

    /// The clock's floor under a frame: the median round trip, in ms, of a submission that
    /// copies 16 bytes and a readback of them, what every frame's wall time pays beyond its
    /// GPU work (the submission, the wait, the mapping of the timestamps): 0.04-0.06 ms on an
    /// H200 (docs/gpu/h200-2026-12-04), against a 0.9 ms frame of 2,500 particles there.
    /// Measured once per device (nine trips, after one untimed).
    pub async fn clock_floor_ms(&self) -> f64 {
        if let Some(floor) = self.clock_floor.get() {
            return *floor;
        }
        let floor = {
            let usage = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
            let source = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("clock_floor.source"),
                size: 16,
                usage,
                mapped_at_creation: false,
            });
            let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("clock_floor.readback"),
                size: 16,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            });
            let mut trips = Vec::with_capacity(10);
            for _ in 0..10 {
                let start = web_time::Instant::now();
                let mut encoder =
                    self.device
                        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                            label: Some("clock_floor.encoder"),
                        });
                encoder.copy_buffer_to_buffer(&source, 0, &readback, 0, 16);
                self.queue.submit([encoder.finish()]);
                if crate::gpu::readback::map_and_copy(self, &readback, |_| ())
                    .await
                    .is_err()
                {
                    continue;
                }
                trips.push(start.elapsed().as_secs_f64() * 1e3);
            }
            let mut trips = trips.split_off(1.min(trips.len()));
            trips.sort_by(f64::total_cmp);
            trips.get(trips.len() / 2).copied().unwrap_or(0.0)
        };
        *self.clock_floor.get_or_init(|| floor)
    }

    /// The loop iterations one shader invocation group may run per dispatch or draw, where the
    /// adapter bounds them: llvmpipe ends every loop after 65,535 iterations, all of a shader's
    /// loops together, silently (the loop just exits). The count is per SIMD group (its lanes
    /// run in lockstep: an iteration any lane runs counts once for all, and loops that
    /// different lanes run one after the other add up), not per lane (Mesa's
    /// `lp_exec_endloop`). [`LLVMPIPE_LOOP_BUDGET`] there; `None` elsewhere.
    pub fn loop_budget(&self) -> Option<u32> {
        self.info
            .name
            .contains("llvmpipe")
            .then_some(LLVMPIPE_LOOP_BUDGET)
    }

    /// Whether GPU pass times can be measured on this adapter.
    pub fn has_timestamps(&self) -> bool {
        self.features.contains(wgpu::Features::TIMESTAMP_QUERY)
    }

    /// Whether the fragment-shader invocations of a pass can be counted on this adapter
    /// (pipeline-statistics queries: the bench's bound analysis).
    pub fn has_pipeline_statistics(&self) -> bool {
        self.features
            .contains(wgpu::Features::PIPELINE_STATISTICS_QUERY)
    }

    /// One line: adapter name, type, backend and driver.
    pub fn describe(&self) -> String {
        describe_adapter(&self.info)
    }

    /// Runs `work` inside out-of-memory and validation error scopes: what the device refuses
    /// while `work` records or creates becomes a [`Refusal`] (the caller says what it was doing
    /// with [`Refusal::during`]), instead of an uncaptured error.
    pub async fn scoped<T>(&self, work: impl Future<Output = T>) -> Result<T, Refusal> {
        let out_of_memory = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let value = work.await;
        // Scopes pop in reverse order of their pushes.
        let validation = validation.pop().await;
        let out_of_memory = out_of_memory.pop().await;
        match out_of_memory.or(validation) {
            None => Ok(value),
            Some(error) => Err(Refusal {
                cause: one_line(&error),
            }),
        }
    }

    /// Blocks until all submitted work is done.
    pub fn wait_idle(&self) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Readback(e.to_string()))
    }
}

/// What the tool asks of a device on `adapter`: the optional features it has, and its own
/// limits (the defaults allow only 32 bytes per sample, too few for 8 RGBA16F targets).
pub fn device_descriptor(adapter: &wgpu::Adapter) -> wgpu::DeviceDescriptor<'static> {
    wgpu::DeviceDescriptor {
        label: Some("smokeshadow.device"),
        required_features: adapter.features() & OPTIONAL_FEATURES,
        required_limits: adapter.limits(),
        ..Default::default()
    }
}

/// Whether an adapter satisfies `preference`.
pub fn matches(preference: &AdapterPreference, info: &wgpu::AdapterInfo) -> bool {
    match preference {
        AdapterPreference::Auto => true,
        AdapterPreference::Cpu => info.device_type == wgpu::DeviceType::Cpu,
        AdapterPreference::Named(name) => info
            .name
            .to_ascii_lowercase()
            .contains(&name.to_ascii_lowercase()),
    }
}

/// The order adapters are preferred in: hardware first, Vulkan first, then by name.
pub fn rank(info: &wgpu::AdapterInfo) -> (u8, u8, String) {
    (
        type_rank(info.device_type),
        backend_rank(info.backend),
        info.name.clone(),
    )
}

/// A wgpu instance on the native backends (Vulkan, Metal, DX12; not GL, whose GLSL path lacks
/// what the renderer uses); `WGPU_BACKEND` overrides.
pub fn instance() -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = wgpu::Backends::PRIMARY;
    wgpu::Instance::new(desc.with_env())
}

/// One line describing an adapter.
pub fn describe_adapter(info: &wgpu::AdapterInfo) -> String {
    format!(
        "{} ({:?}, {:?}, driver {} {})",
        info.name, info.device_type, info.backend, info.driver, info.driver_info
    )
}

fn type_rank(t: wgpu::DeviceType) -> u8 {
    match t {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    }
}

fn backend_rank(b: wgpu::Backend) -> u8 {
    match b {
        wgpu::Backend::Vulkan => 0,
        wgpu::Backend::Metal => 1,
        wgpu::Backend::Dx12 => 2,
        _ => 3,
    }
}

/// All adapters, in the deterministic order used for selection.
pub async fn ranked_adapters(instance: &wgpu::Instance) -> Vec<wgpu::Adapter> {
    let mut adapters = instance.enumerate_adapters(wgpu::Backends::all()).await;
    adapters.sort_by_key(|a| rank(&a.get_info()));
    adapters
}

async fn select_adapter(
    instance: &wgpu::Instance,
    preference: &AdapterPreference,
) -> Result<wgpu::Adapter, GpuError> {
    let adapters = ranked_adapters(instance).await;
    let found = adapters
        .into_iter()
        .find(|a| matches(preference, &a.get_info()));
    found.ok_or_else(|| GpuError::NoAdapter {
        detail: match preference {
            AdapterPreference::Auto => String::new(),
            other => format!(" matching {other}"),
        },
    })
}

/// A 2D texture binding of `sample_type`.
pub fn texture_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    sample_type: wgpu::TextureSampleType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Texture {
            sample_type,
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

/// A 2D storage texture binding of `format` with `access`.
pub fn storage_texture_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    access: wgpu::StorageTextureAccess,
    format: wgpu::TextureFormat,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::StorageTexture {
            access,
            format,
            view_dimension: wgpu::TextureViewDimension::D2,
        },
        count: None,
    }
}

/// A 3D texture binding of `sample_type` (a density grid's voxels, a cloud's noise).
pub fn texture_3d_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    sample_type: wgpu::TextureSampleType,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Texture {
            sample_type,
            view_dimension: wgpu::TextureViewDimension::D3,
            multisampled: false,
        },
        count: None,
    }
}

/// A uniform buffer binding.
pub fn uniform_entry(binding: u32, visibility: wgpu::ShaderStages) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Uniform,
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// A storage buffer binding.
pub fn storage_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
    read_only: bool,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

/// The descriptor of a storage buffer of `size` bytes (at least 16) that can be cleared and
/// read back.
pub fn storage_descriptor(label: &str, size: u64) -> wgpu::BufferDescriptor<'_> {
    wgpu::BufferDescriptor {
        label: Some(label),
        size: size.max(16),
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_DST
            | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    }
}

/// Texels per row of a texture that holds a linear array: element i at texel (i % ROW_TEXELS,
/// i / ROW_TEXELS), `row_texel` in shaders/common/rows.wgsl (2^12, so an index splits with a
/// mask and a shift). llvmpipe fetches a texture's texels for the lanes of a SIMD group in one
/// gather, where it loads a storage buffer's words lane by lane: arrays a hot loop reads go
/// there (`exact`'s lists and spheres, `dsm`'s capture nodes).
pub const ROW_TEXELS: u32 = 4096;

/// Rows a row texture of more than one row is padded to a multiple of: drivers allocate a 2D
/// texture in whole tiles of rows (lavapipe pads its height to a multiple of 4), so the rows
/// are asked for, and counted, as the driver holds them.
pub const ROW_TILE: u64 = 4;

/// The most rows a row texture may have on a device whose 2D textures are at most
/// `max_dimension` texels a side: whole tiles of [`ROW_TILE`] rows.
pub fn max_texture_rows(max_dimension: u32) -> u64 {
    u64::from(max_dimension) / ROW_TILE * ROW_TILE
}

/// Width and height of a row texture for `texels` elements: rows of [`ROW_TEXELS`], the one row
/// narrower when there are fewer, at least 1x1; more than one row padded to whole tiles of
/// [`ROW_TILE`] rows.
pub fn row_texture_size(texels: u64) -> (u32, u32) {
    let width = texels.clamp(1, u64::from(ROW_TEXELS)) as u32;
    let rows = match texels.div_ceil(u64::from(ROW_TEXELS)) {
        0 | 1 => 1,
        rows => rows.next_multiple_of(ROW_TILE),
    };
    (width, u32::try_from(rows).unwrap_or(u32::MAX))
}

/// The descriptor of a plain 2D texture: one layer, one mip level, one sample, no other view
/// formats.
pub fn texture_2d_descriptor<'a>(
    label: &'a str,
    (width, height): (u32, u32),
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
) -> wgpu::TextureDescriptor<'a> {
    wgpu::TextureDescriptor {
        label: Some(label),
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: 1,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format,
        usage,
        view_formats: &[],
    }
}

/// The descriptor of a row texture (see [`ROW_TEXELS`]) for `texels` elements of `format`.
pub fn row_texture_descriptor<'a>(
    label: &'a str,
    format: wgpu::TextureFormat,
    usage: wgpu::TextureUsages,
    texels: u64,
) -> wgpu::TextureDescriptor<'a> {
    texture_2d_descriptor(label, row_texture_size(texels), format, usage)
}

/// A bind-group entry for a texture `view`.
pub fn texture_binding(binding: u32, view: &wgpu::TextureView) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: wgpu::BindingResource::TextureView(view),
    }
}

/// A bind-group entry for all of `buffer`.
pub fn bind_entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}
