//! Adapters and devices: which GPUs wgpu offers, and one opened for compute.

use std::sync::Mutex;

use crate::error::{Error, Result};
pub use crate::report::AdapterSummary;

impl AdapterSummary {
    fn of(a: &wgpu::Adapter) -> Self {
        let info = a.get_info();
        AdapterSummary {
            name: info.name.clone(),
            backend: format!("{:?}", info.backend),
            device_type: format!("{:?}", info.device_type),
            driver: format!("{} {}", info.driver, info.driver_info)
                .trim()
                .to_string(),
            shader_f64: a.features().contains(wgpu::Features::SHADER_F64),
            max_storage_binding: a.limits().max_storage_buffer_binding_size,
        }
    }
}

/// The backends to probe, in turn, until one offers a usable adapter: those named by
/// `WGPU_BACKEND` when it is set; else Vulkan, Metal and Dx12, then GL. GL (no f64 in
/// shaders) is left unloaded where it is not needed: Mesa's EGL stack, loaded next to
/// lavapipe, can abort the process at exit (a double free as one of its threads ends; see
/// [`on_own_thread`]).
fn tiers() -> Vec<wgpu::Backends> {
    match wgpu::Backends::from_env() {
        Some(b) => vec![b],
        None => vec![wgpu::Backends::PRIMARY, wgpu::Backends::SECONDARY],
    }
}

/// Preference order: hardware first, then Vulkan/Metal/Dx12 before GL (GL has no f64).
fn rank(a: &wgpu::Adapter) -> (u8, u8, u8) {
    let info = a.get_info();
    let ty = match info.device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    };
    let api = match info.backend {
        wgpu::Backend::Vulkan | wgpu::Backend::Metal | wgpu::Backend::Dx12 => 0,
        _ => 1,
    };
    let f64 = u8::from(!a.features().contains(wgpu::Features::SHADER_F64));
    (ty, api, f64)
}

/// The adapters that run compute shaders and pass `keep`, best first, from the first
/// backend tier that has any. Callers run it through [`on_own_thread`].
fn compute_adapters(keep: impl Fn(&wgpu::Adapter) -> bool) -> Vec<wgpu::Adapter> {
    for backends in tiers() {
        let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
        desc.backends = backends;
        let mut v: Vec<wgpu::Adapter> =
            pollster::block_on(wgpu::Instance::new(desc).enumerate_adapters(backends))
                .into_iter()
                .filter(|a| {
                    a.get_downlevel_capabilities()
                        .flags
                        .contains(wgpu::DownlevelFlags::COMPUTE_SHADERS)
                        && keep(a)
                })
                .collect();
        if !v.is_empty() {
            v.sort_by_key(rank);
            return v;
        }
    }
    Vec::new()
}

/// Runs `f` on a thread of its own and waits until that thread has ended.
///
/// The EGL dispatch library that the GL backend loads (libglvnd) keeps state for each thread
/// that calls it, freed both when that thread ends and when the library is unloaded as the
/// process exits. A run probes adapters on a worker of its thread pool; when the pool is
/// dropped just before the process exits, that worker's end races the unloading, and glibc
/// aborts the finished process with a double free (about one run in 500 with no Vulkan
/// driver). A joined thread has ended, its state freed, before the probe returns. (A GL
/// device in use is driven from the pool's threads too; that case stays open.) Runs `f` here
/// when no thread can be started.
fn on_own_thread<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    let mut f = Some(f);
    let joined = std::thread::scope(|s| {
        let slot = &mut f;
        let spawned = std::thread::Builder::new()
            .name("isomesh-gpu-probe".into())
            .spawn_scoped(s, move || slot.take().map(|f| f()));
        // `join` returns once the thread has ended, its thread-local destructors run (the
        // scope's own wait ends as soon as the closure has returned).
        spawned.ok().map(|h| h.join())
    });
    match joined {
        Some(Ok(out)) => out.expect("the closure ran on the thread"),
        Some(Err(panic)) => std::panic::resume_unwind(panic),
        None => f.take().expect("no thread ran the closure")(),
    }
}

/// Every adapter that runs compute shaders, best first. GL adapters are probed only when no
/// Vulkan, Metal or Dx12 adapter runs compute, or when `WGPU_BACKEND` asks for GL.
pub fn adapters() -> Vec<AdapterSummary> {
    on_own_thread(|| compute_adapters(|_| true))
        .iter()
        .map(AdapterSummary::of)
        .collect()
}

/// An open device for compute; clones share the device.
#[derive(Clone)]
pub struct Gpu {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// What it is.
    pub adapter: AdapterSummary,
}

/// The devices this process opened, one per kind of request (software adapters allowed or
/// not): every [`Gpu::open`] shares it. A Vulkan instance and device per call, created and
/// dropped from several threads at once, crashed the NVIDIA driver (a segmentation fault in
/// most runs of the GPU test suite with 8 threads); wgpu's device is built to be shared by
/// threads, and one that lives until the process ends is never torn down while another
/// thread opens one.
static OPENED: Mutex<[Option<Gpu>; 2]> = Mutex::new([None, None]);

impl Gpu {
    /// The best adapter's device, opened on first use and shared by every later call (and
    /// thread); with `allow_software` false, software adapters are skipped. Errors when none
    /// is usable (and tries again on the next call).
    pub fn open(allow_software: bool) -> Result<Self> {
        let mut opened = OPENED.lock().unwrap_or_else(|e| e.into_inner());
        let slot = &mut opened[usize::from(allow_software)];
        if let Some(g) = slot {
            return Ok(g.clone());
        }
        let g = Self::open_new(allow_software)?;
        *slot = Some(g.clone());
        Ok(g)
    }

    /// Opens a device of the best adapter, not shared, on a thread of its own
    /// ([`on_own_thread`]).
    fn open_new(allow_software: bool) -> Result<Self> {
        on_own_thread(|| Self::open_here(allow_software))
    }

    /// [`Gpu::open_new`] on the calling thread.
    fn open_here(allow_software: bool) -> Result<Self> {
        let adapter = compute_adapters(|a| {
            allow_software || a.get_info().device_type != wgpu::DeviceType::Cpu
        })
        .into_iter()
        .next()
        .ok_or_else(|| {
            Error::Gpu(if allow_software {
                "no GPU adapter: wgpu found no driver that runs compute shaders (on Linux, \
                     install a Vulkan driver, e.g. mesa-vulkan-drivers)"
                    .into()
            } else {
                "no hardware GPU adapter (software adapters are skipped)".into()
            })
        })?;
        let summary = AdapterSummary::of(&adapter);
        let mut features = wgpu::Features::empty();
        if summary.shader_f64 {
            features |= wgpu::Features::SHADER_F64;
        }
        let desc = wgpu::DeviceDescriptor {
            label: Some("isomesh"),
            required_features: features,
            required_limits: adapter.limits(),
            ..Default::default()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&desc))
            .map_err(|e| Error::Gpu(format!("{}: cannot open the device: {e}", summary.name)))?;
        Ok(Gpu {
            device,
            queue,
            adapter: summary,
        })
    }
}
