//! The GPU oracle: the intersection test's (k+1)x(k+1) solves in a WGSL compute shader
//! (`shaders/solve.wgsl`, the twin of the CPU fast path).
//!
//! What makes S the CPU's S: the shader only takes decisions that its error bound certifies.
//! In f64 it keeps certain crossings (with their lambda) and certain misses; in f32 it keeps
//! only certain misses, so every crossing point is computed by the CPU in f64. Everything else
//! is re-decided on the CPU by `cpu::solve::Decider`, exactly where needed.
//!
//! A batch goes through in chunks, pipelined: while the device solves one chunk, the host
//! packs the next and settles the previous one. Each round trip checks its buffers out of
//! its shader's pool, so several threads may use one oracle at once.
//!
//! Vertex values are computed on the CPU (each lattice vertex once per trace): a GPU may
//! contract a * b + c into a fused multiply-add, which changes f by an ulp, and S is defined
//! by the CPU's values. With the same values, the f64 shader's lambda equals the CPU's where
//! the device rounds division and does not contract (lavapipe: bit-identical); elsewhere
//! points may differ by a few ulps, never the decisions. The vertex shader
//! ([`GpuOracle::eval_vertices_stage`]) matches its CPU twin only to a few ulps, not bit for bit, so
//! tracing does not take its values. The certified vertex shader
//! ([`GpuOracle::eval_certified_stage`]) returns each value with a bound on its distance to the
//! CPU's (`expr::certified`): the building block for deciding on the device only
//! what those bounds make certain.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use super::context::Gpu;
use super::wgsl::Precision;
use crate::cpu::solve::Status;
use crate::error::{Error, Result};
use crate::expr::ImplicitFunction;
use crate::report::BackendInfo;
use crate::trace::scan::candidates::{candidates, Candidates};
use crate::trace::scan::tiles::{TileFound, TilePlan};
use crate::trace::{
    CpuOracle, Decide, Decisions, DeviceValues, Evaluate, GrowingValues, Oracle, Scan, ScanGrid,
};
use crate::triangulation::Triangulation;

mod device;
mod emulated;
mod eval_certified;
mod eval_vertices;
mod perturb;
mod scan;
mod solve;
mod solve_certified;
mod solve_ids;
mod tiles;

use device::{pipeline, STAGES};
pub use scan::{scan_shader, MAX_GPU_SCAN_DIM, SCAN_WGSL};
pub use solve::{solve_shader, SOLVE_WGSL};
pub use solve_certified::{solve_certified_shader, SOLVE_CERTIFIED_WGSL};
pub use solve_ids::{solve_ids_shader, SOLVE_IDS_WGSL};
pub use tiles::{
    tile_certify_shader, tile_scan_shader, tile_values_shader, TILE_CERTIFY_WGSL, TILE_SCAN_WGSL,
    TILE_VALUES_WGSL,
};

/// Counters of a GPU oracle.
#[derive(Clone, Copy, Debug, Default)]
pub struct GpuStats {
    /// Simplices sent to the solve shader.
    pub solved: u64,
    /// Of those, decided again on the CPU: every one the device did not certify outside.
    pub rechecked: u64,
    /// Crossings the device certified and the CPU's exact decision rejected: a device
    /// that broke the arithmetic the specifications promise (0 on a conforming one). The
    /// CPU's decision is the one kept.
    pub contradicted: u64,
    /// Seconds the host spent submitting to and waiting on the device, summed over the
    /// threads that used the oracle (the exhaustive scan's two stages overlap).
    pub gpu_s: f64,
    /// Seconds of host work per item inside the oracle, around the shaders: the cheap
    /// filters, packing inputs, decoding outputs, and re-deciding uncertain simplices on the
    /// CPU (overlapped with the device's work unless phased), summed over threads.
    pub host_s: f64,
    /// Bytes written to the device: shader inputs and parameters.
    pub upload_bytes: u64,
    /// Bytes copied back from the device.
    pub readback_bytes: u64,
    /// Phased runs only ([`GpuOracle::set_phased`]): seconds uploading inputs,
    pub upload_s: f64,
    /// running the shader,
    pub compute_s: f64,
    /// and copying results back to the host.
    pub readback_s: f64,
}

/// The intersection oracle on a GPU.
pub struct GpuOracle<'f> {
    gpu: Gpu,
    f: &'f dyn ImplicitFunction,
    /// f's values at lattice vertices, which every decision starts from.
    cpu: CpuOracle<'f>,
    k: usize,
    precision: Precision,
    solve: wgpu::ComputePipeline,
    /// The stop flag that ends a wait for a shader compile ([`GpuOptions::cancel`]).
    cancel: Option<Arc<AtomicBool>>,
    /// The vertex shader, built on first use (tracing never needs it).
    eval: OnceLock<wgpu::ComputePipeline>,
    /// The scan shader, built on first use.
    scan: OnceLock<wgpu::ComputePipeline>,
    /// The certified vertex shader, built on first use.
    certified: OnceLock<wgpu::ComputePipeline>,
    /// The certified solve shader, built on first use.
    solve_certified: OnceLock<wgpu::ComputePipeline>,
    /// The solve shader from vertex ids, built on first use,
    solve_ids: OnceLock<wgpu::ComputePipeline>,
    /// and the vertex values it reads, kept between calls.
    kept: Mutex<Option<solve_ids::Kept>>,
    /// The device-resident scan's three stages, built on first use,
    tile_values: OnceLock<wgpu::ComputePipeline>,
    tile_scan: OnceLock<wgpu::ComputePipeline>,
    tile_certify: OnceLock<wgpu::ComputePipeline>,
    /// and the map its tiles share (A, b, the box of scanned bases).
    tile_map: Mutex<Option<wgpu::Buffer>>,
    /// Scan candidates per 2^16 cubes in the last dispatch, to size the next one's output.
    scan_density: AtomicU64,
    /// Most bytes per storage binding ([`GpuOracle::limit_binding`]).
    binding_limit: AtomicU64,
    /// Frontier simplices per slice of a trace level ([`GpuOptions::level_slice`]).
    level_slice: usize,
    solved: AtomicU64,
    rechecked: AtomicU64,
    contradicted: AtomicU64,
    gpu_ns: AtomicU64,
    host_ns: AtomicU64,
    upload_ns: AtomicU64,
    compute_ns: AtomicU64,
    readback_ns: AtomicU64,
    upload_bytes: AtomicU64,
    readback_bytes: AtomicU64,
    /// Split each round trip into timed, synchronous steps (for benchmarks).
    phased: AtomicBool,
    /// The exhaustive scan takes f's values from the device ([`GpuOptions::device_values`]).
    device_values: bool,
    /// Test hook: device values moved within their bounds (0: off, else a seed).
    perturb: AtomicU64,
    /// Test hook: the floating-point stages emulated on the CPU (0: off, else a seed).
    emulate: AtomicU64,
    /// Buffers kept across calls, per stage and role; they grow when a batch needs more.
    buffers: Mutex<[Vec<Option<wgpu::Buffer>>; STAGES]>,
}

/// How a [`GpuOracle`] works, fixed when it is made. The mesh does not depend on any of it.
#[derive(Clone, Debug, Default)]
pub struct GpuOptions {
    /// Shader precision; `None` picks f64 where the adapter has it, else f32.
    pub precision: Option<Precision>,
    /// Frontier simplices per slice of a trace level: wider levels are decided slice by
    /// slice, the next slice named on the CPU while the device decides one
    /// ([`crate::trace::Decide::level_slice`]). 0, the default, decides every level as one batch: it
    /// measured no gain on lavapipe, whose device work runs on the CPU's cores; slices are
    /// meant for a hardware GPU whose waits are long.
    pub level_slice: usize,
    /// The exhaustive scan stays on the device (`trace::scan::tiles`, d <= 8; above, the
    /// grid of `trace::scan::device_values`): f evaluated there with certified bounds,
    /// candidates and certified verdicts, and the CPU evaluates f only at the vertices of
    /// the simplices the device found crossed or could not decide. Off by default.
    pub device_values: bool,
    /// A stop flag (Ctrl-C): raised while the driver compiles a shader (minutes for a large
    /// system on some drivers), it ends the wait with [`Error::Interrupted`] at once, the
    /// compile left to finish on its own thread.
    pub cancel: Option<Arc<AtomicBool>>,
}

impl<'f> GpuOracle<'f> {
    /// An oracle for `f` on `gpu` with the default options but `precision` (`None` picks f64
    /// where the adapter has it).
    pub fn new(
        gpu: Gpu,
        f: &'f dyn ImplicitFunction,
        precision: Option<Precision>,
    ) -> Result<Self> {
        let options = GpuOptions {
            precision,
            ..GpuOptions::default()
        };
        Self::with_options(gpu, f, options)
    }

    /// An oracle for `f` on `gpu` that works as `options` say.
    pub fn with_options(
        gpu: Gpu,
        f: &'f dyn ImplicitFunction,
        options: GpuOptions,
    ) -> Result<Self> {
        let precision = options.precision;
        let has_f64 = gpu.adapter.shader_f64;
        let precision = match precision {
            Some(Precision::F64) if !has_f64 => {
                return Err(Error::Gpu(format!(
                    "{} has no SHADER_F64: use --precision f32 or auto",
                    gpu.adapter.name
                )))
            }
            Some(p) => p,
            None if has_f64 => Precision::F64,
            None => Precision::F32,
        };
        let k = f.codim();
        let cancel = options.cancel;
        let solve = pipeline(
            &gpu,
            &solve_shader(k, precision)?,
            "solve",
            cancel.as_deref(),
        )?;
        Ok(GpuOracle {
            gpu,
            f,
            cpu: CpuOracle::new(f),
            k,
            precision,
            solve,
            eval: OnceLock::new(),
            scan: OnceLock::new(),
            certified: OnceLock::new(),
            solve_certified: OnceLock::new(),
            solve_ids: OnceLock::new(),
            kept: Mutex::new(None),
            tile_values: OnceLock::new(),
            tile_scan: OnceLock::new(),
            tile_certify: OnceLock::new(),
            tile_map: Mutex::new(None),
            scan_density: AtomicU64::new(1 << 12),
            binding_limit: AtomicU64::new(1 << 30),
            level_slice: options.level_slice,
            solved: AtomicU64::new(0),
            rechecked: AtomicU64::new(0),
            contradicted: AtomicU64::new(0),
            gpu_ns: AtomicU64::new(0),
            host_ns: AtomicU64::new(0),
            upload_ns: AtomicU64::new(0),
            compute_ns: AtomicU64::new(0),
            readback_ns: AtomicU64::new(0),
            upload_bytes: AtomicU64::new(0),
            readback_bytes: AtomicU64::new(0),
            phased: AtomicBool::new(false),
            device_values: options.device_values,
            cancel,
            perturb: AtomicU64::new(0),
            emulate: AtomicU64::new(0),
            buffers: Mutex::new(Default::default()),
        })
    }

    /// The stop flag of [`GpuOptions::cancel`].
    pub(super) fn cancel(&self) -> Option<&AtomicBool> {
        self.cancel.as_deref()
    }

    /// The precision of the shaders.
    pub fn precision(&self) -> Precision {
        self.precision
    }

    /// The adapter.
    pub fn gpu(&self) -> &Gpu {
        &self.gpu
    }

    /// What the oracle did so far.
    pub fn stats(&self) -> GpuStats {
        let secs = |c: &AtomicU64| c.load(Ordering::Relaxed) as f64 * 1e-9;
        GpuStats {
            solved: self.solved.load(Ordering::Relaxed),
            rechecked: self.rechecked.load(Ordering::Relaxed),
            contradicted: self.contradicted.load(Ordering::Relaxed),
            gpu_s: secs(&self.gpu_ns),
            host_s: secs(&self.host_ns),
            upload_s: secs(&self.upload_ns),
            compute_s: secs(&self.compute_ns),
            readback_s: secs(&self.readback_ns),
            upload_bytes: self.upload_bytes.load(Ordering::Relaxed),
            readback_bytes: self.readback_bytes.load(Ordering::Relaxed),
        }
    }

    /// Zeroes the counters of [`GpuOracle::stats`].
    pub fn reset_stats(&self) {
        for c in [
            &self.solved,
            &self.rechecked,
            &self.contradicted,
            &self.gpu_ns,
            &self.host_ns,
            &self.upload_ns,
            &self.compute_ns,
            &self.readback_ns,
            &self.upload_bytes,
            &self.readback_bytes,
        ] {
            c.store(0, Ordering::Relaxed);
        }
    }

    #[doc(hidden)] // for benchmarks
    /// With `on`, every round trip runs as three synchronous, timed steps (upload, compute,
    /// readback: see [`GpuStats`]) and nothing overlaps; for benchmarks. Results are the same.
    pub fn set_phased(&self, on: bool) {
        self.phased.store(on, Ordering::Relaxed);
    }

    #[cfg(feature = "internals")]
    /// Caps the bytes of one storage binding (at most the adapter's limit and 1 GiB, the
    /// default): batches are split finer. Results are the same; for bounding device memory
    /// and for testing the splitting.
    pub fn limit_binding(&self, bytes: u64) {
        self.binding_limit.store(bytes.max(256), Ordering::Relaxed);
    }

    #[cfg(feature = "internals")]
    /// With `Some(seed)`, every certified value the device returns is replaced by the CPU's
    /// value plus t times its bound, t in (-1, 1) drawn from the seed and the vertex (half
    /// the time within 2^-10 of +-1): a device that rounds otherwise, within the claimed
    /// bounds. S must not change.
    pub fn perturb_device_values(&self, seed: Option<u64>) {
        self.perturb
            .store(seed.map_or(0, |s| s | 1 << 63), Ordering::Relaxed);
    }

    #[cfg(feature = "internals")]
    /// With `Some(seed)`, the solve, the certified solve and the certified values are
    /// computed on the CPU by the shaders' twins in the arithmetic of an emulated conforming
    /// device ([`crate::emulate`]: every operation rounded, and every built-in function
    /// placed, as adversarially as WGSL and Vulkan allow), on the inputs the shaders would
    /// get; everything else, the scan shader included, runs as usual. S must not change.
    pub fn emulate_device(&self, seed: Option<u64>) {
        self.emulate
            .store(seed.map_or(0, |s| s | 1 << 63), Ordering::Relaxed);
    }
}

impl Oracle for GpuOracle<'_> {
    fn name(&self) -> String {
        format!("gpu: {}", self.gpu.adapter.name)
    }

    /// The CPU's values: see the module documentation.
    fn values(&self) -> &dyn Evaluate {
        &self.cpu
    }

    fn decisions(&self) -> &dyn Decide {
        self
    }

    fn scans(&self) -> &dyn Scan {
        self
    }
}

impl Decide for GpuOracle<'_> {
    fn decide(
        &self,
        values: &[f64],
        simplices: &[u32],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> Result<Decisions> {
        self.decide_pipelined(values, simplices, status, lambda)
    }

    fn decide_growing(
        &self,
        log: GrowingValues,
        values: &[f64],
        simplices: &[u32],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> Result<Decisions> {
        self.decide_from_ids(log, values, simplices, status, lambda)
    }

    fn level_slice(&self) -> Option<usize> {
        Some(self.level_slice).filter(|&s| s > 0)
    }
}

impl Scan for GpuOracle<'_> {
    fn candidates(&self, grid: &ScanGrid, cubes: Range<usize>) -> Result<Candidates> {
        if grid.dim() > MAX_GPU_SCAN_DIM {
            return Ok(candidates(grid, cubes));
        }
        self.scan_stage(grid, cubes)
    }

    fn device_values(&self) -> Option<&dyn DeviceValues> {
        self.device_values.then_some(self as &dyn DeviceValues)
    }
}

impl DeviceValues for GpuOracle<'_> {
    fn eval_certified(&self, tri: &Triangulation, lattice: &[i32], out: &mut [f64]) -> Result<()> {
        let got = self.eval_certified_stage(tri, lattice)?;
        let big = self.precision.accuracy().big;
        for (o, g) in out.chunks_exact_mut(2).zip(got.chunks_exact(2)) {
            let (v, e) = (g[0], g[1]);
            let known = e < big && v.abs() < big;
            o[0] = v;
            o[1] = if known { e } else { f64::INFINITY };
        }
        let seed = self.perturb.load(Ordering::Relaxed);
        if seed != 0 {
            self.perturb_values(tri, lattice, seed, out)?;
        }
        Ok(())
    }

    fn decide_certified(
        &self,
        values: &[f64],
        bounds: &[f64],
        simplices: &[u32],
        verdicts: &mut [u32],
    ) -> Result<()> {
        let got = self.certified_verdicts(values, bounds, simplices)?;
        verdicts.copy_from_slice(&got);
        Ok(())
    }

    fn scan_tiles(
        &self,
        tri: &Triangulation,
        plan: &TilePlan,
        each: &mut dyn FnMut(usize, TileFound) -> Result<bool>,
    ) -> Result<()> {
        self.scan_tiles_on_device(tri, plan, each)
    }
}

impl BackendInfo {
    /// The GPU oracle `o`, with what it did so far.
    pub fn of_gpu(o: &GpuOracle) -> Self {
        use crate::trace::Oracle;
        let st = o.stats();
        BackendInfo {
            backend: o.name(),
            precision: o.precision().ty().to_string(),
            recheck_share: Some(if st.solved > 0 {
                st.rechecked as f64 / st.solved as f64
            } else {
                0.0
            }),
            gpu_s: Some(st.gpu_s),
            host_s: Some(st.host_s),
            upload_bytes: Some(st.upload_bytes),
            readback_bytes: Some(st.readback_bytes),
            adapter: Some(o.gpu().adapter.clone()),
        }
    }
}
