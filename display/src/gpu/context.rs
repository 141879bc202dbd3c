//! Finding a GPU (or Mesa's software one) and opening a device on it.

use std::sync::{Arc, Mutex, OnceLock};

/// Why the GPU front end cannot run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GpuError {
    /// No adapter at all: neither a GPU driver nor a software Vulkan.
    #[error(
        "no GPU adapter found ({0}); install a GPU driver, or Mesa's software Vulkan \
         (Debian/Ubuntu: apt-get install mesa-vulkan-drivers), or use the quadtree driver"
    )]
    NoAdapter(String),
    /// An adapter was found but refused a device.
    #[error("the GPU adapter {adapter} refused a device: {reason}")]
    Device {
        /// The adapter's name and backend.
        adapter: String,
        /// What wgpu said.
        reason: String,
    },
    /// Reading a frame back failed (a lost device, a failed map).
    #[error("reading the frame back from the GPU failed: {0}")]
    Readback(String),
    /// In a web page: the frame is still on the GPU; ask again after the
    /// page has returned to the browser.
    #[error("the frame is still on the GPU")]
    NotReady,
}

/// A wgpu device and queue, and what they run on.
#[derive(Debug)]
pub struct GpuContext {
    /// The device resources are made on.
    pub device: wgpu::Device,
    /// The queue work is submitted to.
    pub queue: wgpu::Queue,
    /// The adapter: its name, driver and backend, for reports.
    pub info: wgpu::AdapterInfo,
    /// The device's limits (texture sizes, buffer sizes).
    pub limits: wgpu::Limits,
}

impl GpuContext {
    /// Opens a device on the best adapter: a hardware GPU where there is one,
    /// else a software one (lavapipe). `WGPU_BACKEND` (vulkan, metal, dx12,
    /// gl) and `WGPU_ADAPTER_NAME` narrow the choice, as in wgpu.
    pub fn new() -> Result<GpuContext, GpuError> {
        // Vulkan, Metal or DX12 first; GL only where none of them has an
        // adapter (probing GL first would log EGL complaints on headless
        // machines that have a perfectly good Vulkan).
        let chosen = wgpu::Backends::from_env();
        let tries = match chosen {
            Some(b) => vec![b],
            // In a web page WebGL2 alone: it opens at once (WebGPU's adapter
            // comes from a promise, and nothing may wait for one there).
            None if cfg!(target_arch = "wasm32") => vec![wgpu::Backends::GL],
            None => vec![wgpu::Backends::PRIMARY, wgpu::Backends::GL],
        };
        let mut failures = Vec::new();
        let mut found = None;
        for backends in tries {
            let mut desc = wgpu::InstanceDescriptor::new_without_display_handle().with_env();
            desc.backends = backends;
            let instance = wgpu::Instance::new(desc);
            // WebGL2 gives an adapter only for a canvas.
            #[cfg(target_arch = "wasm32")]
            let surface = web_sys::OffscreenCanvas::new(1, 1)
                .ok()
                .and_then(|c| instance.create_surface(wgpu::SurfaceTarget::OffscreenCanvas(c)).ok());
            #[cfg(not(target_arch = "wasm32"))]
            let surface: Option<wgpu::Surface<'static>> = None;
            match pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                force_fallback_adapter: false,
                compatible_surface: surface.as_ref(),
                ..Default::default()
            })) {
                Ok(a) => {
                    found = Some(a);
                    break;
                }
                Err(e) => failures.push(format!("{backends:?}: {e}")),
            }
        }
        let adapter = found.ok_or_else(|| GpuError::NoAdapter(failures.join("; ")))?;
        let info = adapter.get_info();
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("holodeck display"),
            required_features: wgpu::Features::empty(),
            required_limits: limits.clone(),
            ..Default::default()
        }))
        .map_err(|e| GpuError::Device {
            adapter: describe(&info),
            reason: e.to_string(),
        })?;
        tracing::debug!("GPU: {}", describe(&info));
        Ok(GpuContext {
            device,
            queue,
            info,
            limits,
        })
    }

    /// One context for the whole process, opened on first use: devices
    /// are costly to open (seconds on a software rasterizer), and every
    /// driver of a display can share one. A failure is remembered too.
    pub fn shared() -> Result<Arc<GpuContext>, GpuError> {
        type Opened = Option<Result<Arc<GpuContext>, GpuError>>;
        static SHARED: OnceLock<Mutex<Opened>> = OnceLock::new();
        let cell = SHARED.get_or_init(|| Mutex::new(None));
        let mut slot = cell.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        slot.get_or_insert_with(|| GpuContext::new().map(Arc::new)).clone()
    }

    /// Whether this machine has a hardware GPU (not a software rasterizer)
    /// on Vulkan, Metal or DX12, or on the backend `WGPU_BACKEND` names:
    /// the adapters are listed without opening a device, once per process.
    /// Displays ask it to choose the GPU filter only where it is the faster.
    /// In a web page (WebAssembly) it is false: nothing may block there,
    /// and the page chooses its own back end.
    pub fn hardware_present() -> bool {
        if cfg!(target_arch = "wasm32") {
            return false;
        }
        static FOUND: OnceLock<bool> = OnceLock::new();
        *FOUND.get_or_init(|| {
            let backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY);
            let mut desc = wgpu::InstanceDescriptor::new_without_display_handle().with_env();
            desc.backends = backends;
            let instance = wgpu::Instance::new(desc);
            let adapters = pollster::block_on(instance.enumerate_adapters(backends));
            let hardware = adapters.iter().map(|a| a.get_info()).find(|i| {
                matches!(
                    i.device_type,
                    wgpu::DeviceType::DiscreteGpu | wgpu::DeviceType::IntegratedGpu | wgpu::DeviceType::VirtualGpu
                )
            });
            match &hardware {
                Some(info) => tracing::debug!("hardware GPU found: {}", describe(info)),
                None => tracing::debug!("no hardware GPU among {} adapter(s)", adapters.len()),
            }
            hardware.is_some()
        })
    }

    /// Starts [`GpuContext::hardware_present`]'s probe on a thread of its
    /// own, so that its cost (a fifth of a second where Mesa's software
    /// Vulkan loads) overlaps the work before the first frame.
    /// (Not in a web page, which has no threads to start.)
    pub fn probe_in_background() {
        if !cfg!(target_arch = "wasm32") {
            std::thread::spawn(GpuContext::hardware_present);
        }
    }

    /// The adapter in words ("llvmpipe (LLVM 15.0.6, 256 bits) on Vulkan,
    /// software").
    pub fn describe(&self) -> String {
        describe(&self.info)
    }

    /// True on a CPU rasterizer (lavapipe, llvmpipe, WARP).
    pub fn is_software(&self) -> bool {
        self.info.device_type == wgpu::DeviceType::Cpu
    }

    /// Waits until every submitted command has run.
    pub fn wait(&self) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Readback(e.to_string()))
    }
}

fn describe(info: &wgpu::AdapterInfo) -> String {
    let kind = match info.device_type {
        wgpu::DeviceType::Cpu => ", software",
        wgpu::DeviceType::DiscreteGpu => ", discrete GPU",
        wgpu::DeviceType::IntegratedGpu => ", integrated GPU",
        _ => "",
    };
    let driver = if info.driver_info.is_empty() {
        String::new()
    } else {
        format!(" ({})", info.driver_info)
    };
    format!("{}{driver} on {:?}{kind}", info.name, info.backend)
}
