//! The GPU oracle: the intersection test's (k+1)x(k+1) solves in a WGSL compute shader
//! (`shaders/solve.wgsl`, the twin of the CPU fast path).
//!
//! What makes S the CPU's S: the shader only takes decisions that its error bound certifies.
//! In f64 it keeps certain crossings (with their lambda) and certain misses; in f32 it keeps
//! only certain misses, so every crossing point is computed by the CPU in f64. Everything else
//! is re-decided on the CPU by [`Decider`](crate::cpu::decide::Decider), exactly where needed.
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
//! ([`GpuOracle::eval_stage`]) matches its CPU twin only to a few ulps, not bit for bit, so
//! tracing does not take its values.

use std::borrow::Cow;
use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Mutex, MutexGuard, OnceLock};
use std::time::Instant;

use rayon::prelude::*;

use super::context::Gpu;
use super::wgsl::{eval_shader, validate, Precision};
use crate::cpu::decide::{filter_verdict, scaled_rows, Status};
use crate::cpu::scan::{self, pass_mask, Candidates, BASE};
use crate::error::{Error, Result};
use crate::expr::ImplicitFunction;
use crate::trace::{CpuOracle, Oracle, ScanGrid};
use crate::triangulation::Triangulation;

/// The solve shader, before its prelude.
pub const SOLVE_WGSL: &str = include_str!("../../shaders/solve.wgsl");
/// The scan's candidate generator, before its prelude.
pub const SCAN_WGSL: &str = include_str!("../../shaders/scan.wgsl");
/// Largest d whose scan candidates the GPU generates (each invocation holds two arrays of
/// 2^d words); above it the CPU generator runs.
pub const MAX_GPU_SCAN_DIM: usize = 8;

/// Consecutive cubes per invocation of the scan shader: they mostly lie in one grid row and
/// share its corner rows, which are looked up once.
const SCAN_RUN: usize = 8;
/// Safety factor of the error bound, and the largest trusted relative bound, as on the CPU.
const BOUND_FACTOR: f64 = 16.0;
const MAX_RELATIVE_BOUND: f64 = 0.125;
/// Threads per workgroup in both shaders.
const WORKGROUP: u32 = 64;
/// Simplices per pipelined chunk of a decision batch.
const PIPELINE_CHUNK: usize = 1 << 17;
/// Workgroups per dispatch row (the limit per dimension).
const MAX_GROUPS: u32 = 65_535;

/// The shaders, each with its own buffer pool: the stages of one oracle may run at once
/// (the exhaustive scan generates batch n + 1 while batch n is decided).
#[derive(Clone, Copy)]
enum Stage {
    Solve,
    Scan,
    Eval,
}
const STAGES: usize = 3;

/// Shader verdicts.
const CROSSED: u32 = 0;
const OUTSIDE: u32 = 1;

/// Counters of a GPU oracle.
#[derive(Clone, Copy, Debug, Default)]
pub struct GpuStats {
    /// Simplices sent to the solve shader.
    pub solved: u64,
    /// Of those, decided again on the CPU.
    pub rechecked: u64,
    /// Seconds the host spent submitting to and waiting on the device, summed over the
    /// threads that used the oracle (the exhaustive scan's two stages overlap).
    pub gpu_s: f64,
    /// Seconds of host work around the shader: the cheap filters, packing rows, and
    /// re-deciding uncertain simplices on the CPU (overlapped with the device's work unless
    /// phased).
    pub host_s: f64,
    /// Phased runs only ([`GpuOracle::set_phased`]): seconds uploading inputs,
    pub upload_s: f64,
    /// running the shader,
    pub compute_s: f64,
    /// and copying results back to the host.
    pub readback_s: f64,
}

/// The solve shader for k-simplices in precision `p`, validated by naga.
pub fn solve_shader(k: usize, p: Precision) -> Result<String> {
    let n = k + 1;
    let (eps, big) = match p {
        Precision::F32 => ("1.1920929e-7f", "3.4028235e38f"),
        Precision::F64 => ("2.220446049250313e-16lf", "1.7976931348623157e308lf"),
    };
    let lit = |v: f64| match p {
        Precision::F32 => format!("{v:?}f"),
        Precision::F64 => format!("{v:?}lf"),
    };
    let src = format!(
        "alias real = {ty};\nconst N: u32 = {n}u;\nconst NN: u32 = {nn}u;\nconst EPS: real = {eps};\n\
         const BOUND: real = {bound};\nconst BIG: real = {big};\n\
         const MAX_RELATIVE_BOUND: real = {rel};\n{SOLVE_WGSL}",
        bound = lit(BOUND_FACTOR),
        rel = lit(MAX_RELATIVE_BOUND),
        ty = p.ty(),
        nn = n * n
    );
    validate(&src, p)?;
    Ok(src)
}

/// The scan shader for k-simplices in R^d, validated by naga.
pub fn scan_shader(d: usize, k: usize) -> Result<String> {
    if !(2..=MAX_GPU_SCAN_DIM).contains(&d) || k == 0 || k >= d {
        return Err(Error::Gpu(format!(
            "the scan shader takes 1 <= k < d <= {MAX_GPU_SCAN_DIM} (k = {k}, d = {d})"
        )));
    }
    let src = format!(
        "const D: u32 = {d}u;\nconst K: u32 = {k}u;\nconst KP1: u32 = {kp1}u;\n\
         const CORNERS: u32 = {corners}u;\nconst HALF: u32 = {half}u;\n\
         const MASK: u32 = {mask}u;\nconst BASE: u32 = {base}u;\nconst RUN: u32 = {SCAN_RUN}u;\n\
         {SCAN_WGSL}",
        kp1 = k + 1,
        corners = 1u32 << d,
        half = 1u32 << (d - 1),
        mask = pass_mask(k),
        base = BASE,
    );
    validate(&src, Precision::F32)?;
    Ok(src)
}

/// The intersection oracle on a GPU.
pub struct GpuOracle<'f> {
    gpu: Gpu,
    f: &'f dyn ImplicitFunction,
    k: usize,
    precision: Precision,
    solve: wgpu::ComputePipeline,
    /// The vertex shader, built on first use (tracing never needs it).
    eval: OnceLock<wgpu::ComputePipeline>,
    /// The scan shader, built on first use.
    scan: OnceLock<wgpu::ComputePipeline>,
    /// Scan candidates per 2^16 cubes in the last dispatch, to size the next one's output.
    scan_density: AtomicU64,
    /// Most bytes per storage binding ([`GpuOracle::limit_binding`]).
    binding_limit: AtomicU64,
    /// Frontier simplices per slice of a trace level ([`GpuOracle::set_level_slice`]).
    level_slice: AtomicUsize,
    solved: AtomicU64,
    rechecked: AtomicU64,
    gpu_ns: AtomicU64,
    host_ns: AtomicU64,
    upload_ns: AtomicU64,
    compute_ns: AtomicU64,
    readback_ns: AtomicU64,
    /// Split each round trip into timed, synchronous steps (for benchmarks).
    phased: AtomicBool,
    /// Buffers kept across calls, per stage and role; they grow when a batch needs more.
    buffers: Mutex<[Vec<Option<wgpu::Buffer>>; STAGES]>,
}

impl<'f> GpuOracle<'f> {
    /// An oracle for `f` on `gpu`; `precision` None picks f64 where the adapter has it.
    pub fn new(
        gpu: Gpu,
        f: &'f dyn ImplicitFunction,
        precision: Option<Precision>,
    ) -> Result<Self> {
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
        let solve = pipeline(&gpu, &solve_shader(k, precision)?, "solve")?;
        Ok(GpuOracle {
            gpu,
            f,
            k,
            precision,
            solve,
            eval: OnceLock::new(),
            scan: OnceLock::new(),
            scan_density: AtomicU64::new(1 << 12),
            binding_limit: AtomicU64::new(1 << 30),
            level_slice: AtomicUsize::new(0),
            solved: AtomicU64::new(0),
            rechecked: AtomicU64::new(0),
            gpu_ns: AtomicU64::new(0),
            host_ns: AtomicU64::new(0),
            upload_ns: AtomicU64::new(0),
            compute_ns: AtomicU64::new(0),
            readback_ns: AtomicU64::new(0),
            phased: AtomicBool::new(false),
            buffers: Mutex::new(Default::default()),
        })
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
            gpu_s: secs(&self.gpu_ns),
            host_s: secs(&self.host_ns),
            upload_s: secs(&self.upload_ns),
            compute_s: secs(&self.compute_ns),
            readback_s: secs(&self.readback_ns),
        }
    }

    /// Zeroes the counters of [`GpuOracle::stats`].
    pub fn reset_stats(&self) {
        for c in [
            &self.solved,
            &self.rechecked,
            &self.gpu_ns,
            &self.host_ns,
            &self.upload_ns,
            &self.compute_ns,
            &self.readback_ns,
        ] {
            c.store(0, Ordering::Relaxed);
        }
    }

    /// With `on`, every round trip runs as three synchronous, timed steps (upload, compute,
    /// readback: see [`GpuStats`]) and nothing overlaps; for benchmarks. Results are the same.
    pub fn set_phased(&self, on: bool) {
        self.phased.store(on, Ordering::Relaxed);
    }

    /// Caps the bytes of one storage binding (at most the adapter's limit and 1 GiB, the
    /// default): batches are split finer. Results are the same; for bounding device memory
    /// and for testing the splitting.
    pub fn limit_binding(&self, bytes: u64) {
        self.binding_limit.store(bytes.max(256), Ordering::Relaxed);
    }

    /// Frontier simplices per slice of a trace level: wider levels are decided slice by
    /// slice, the next slice named on the CPU while the device decides one
    /// ([`Oracle::level_slice`]). 0, the default, decides every level as one batch. Results
    /// are the same. Off by default because it measured no gain on lavapipe, whose device
    /// work runs on the CPU's cores; it is meant for a hardware GPU whose waits are long.
    pub fn set_level_slice(&self, simplices: usize) {
        self.level_slice.store(simplices, Ordering::Relaxed);
    }

    /// The bytes one storage binding may hold.
    fn max_binding(&self) -> u64 {
        let limit = self.binding_limit.load(Ordering::Relaxed);
        self.gpu.adapter.max_storage_binding.min(limit)
    }

    /// Items per dispatch so that `bytes_per_item` fits one storage binding.
    fn chunk(&self, bytes_per_item: usize) -> usize {
        let max = self.max_binding() as usize;
        (max / bytes_per_item.max(1)).clamp(1, 1 << 22)
    }

    /// Uploads `input`, runs `pipeline` over `count` items with `input` bound at 0 and
    /// outputs of the given byte sizes at 1.. (zeroed first when `zeroed`), and starts
    /// copying the outputs back; the device works while the caller does other things, until
    /// [`GpuOracle::finish`]. The buffers come from `stage`'s pool and go back at the finish.
    fn submit(
        &self,
        stage: Stage,
        pipeline: &wgpu::ComputePipeline,
        input: &[u8],
        count: usize,
        outputs: &[usize],
        zeroed: bool,
    ) -> Result<Pending> {
        let phased = self.phased.load(Ordering::Relaxed);
        let started = Instant::now();
        let storage = wgpu::BufferUsages::STORAGE;
        let sizes: Vec<u64> = outputs
            .iter()
            .map(|&want| (want.max(4) as u64).next_multiple_of(4))
            .collect();
        // Slots: 0 input, 1 parameters, then output i at 2 + 2i and its staging copy next.
        let mut wanted = vec![
            (
                (input.len().max(16) as u64).next_multiple_of(4),
                storage | wgpu::BufferUsages::COPY_DST,
            ),
            (
                16,
                wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            ),
        ];
        for &size in &sizes {
            wanted.push((
                size,
                storage | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            ));
            wanted.push((
                size,
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ));
        }
        let bufs = self.check_out(stage, &wanted)?;
        let (inbuf, ubuf) = (&bufs[0], &bufs[1]);
        if !input.is_empty() {
            self.gpu.queue.write_buffer(inbuf, 0, input);
        }
        if phased {
            let index = self.gpu.queue.submit([]);
            self.wait(Some(index))?;
            add_time(&self.upload_ns, started);
        }
        let groups = (count as u32).div_ceil(WORKGROUP).max(1);
        let (gx, gy) = if groups > MAX_GROUPS {
            (MAX_GROUPS, groups.div_ceil(MAX_GROUPS))
        } else {
            (groups, 1)
        };
        let params: [u32; 4] = [count as u32, gx * WORKGROUP, 0, 0];
        self.gpu
            .queue
            .write_buffer(ubuf, 0, bytemuck::cast_slice(&params));
        let outs: Vec<&wgpu::Buffer> = bufs[2..].iter().step_by(2).collect();
        let layout = pipeline.get_bind_group_layout(0);
        let mut entries = vec![wgpu::BindGroupEntry {
            binding: 0,
            resource: inbuf.as_entire_binding(),
        }];
        for (i, out) in outs.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: i as u32 + 1,
                resource: out.as_entire_binding(),
            });
        }
        entries.push(wgpu::BindGroupEntry {
            binding: outs.len() as u32 + 1,
            resource: ubuf.as_entire_binding(),
        });
        let dev = &self.gpu.device;
        let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &layout,
            entries: &entries,
        });
        let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        if zeroed {
            for out in &outs {
                enc.clear_buffer(out, 0, None);
            }
        }
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: None,
                timestamp_writes: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        if phased {
            let t = Instant::now();
            let index = self.gpu.queue.submit([enc.finish()]);
            self.wait(Some(index))?;
            add_time(&self.compute_ns, t);
            enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        }
        for (pair, &size) in bufs[2..].chunks_exact(2).zip(&sizes) {
            enc.copy_buffer_to_buffer(&pair[0], 0, &pair[1], 0, size);
        }
        let index = self.gpu.queue.submit([enc.finish()]);
        let mut maps = Vec::with_capacity(outputs.len());
        for ((pair, &size), &want) in bufs[2..].chunks_exact(2).zip(&sizes).zip(outputs) {
            let (tx, rx) = std::sync::mpsc::channel();
            pair[1]
                .slice(..size)
                .map_async(wgpu::MapMode::Read, move |r| {
                    let _ = tx.send(r);
                });
            maps.push(Readback {
                staging: pair[1].clone(),
                size,
                want,
                mapped: rx,
            });
        }
        add_time(&self.gpu_ns, started);
        Ok(Pending {
            stage,
            buffers: bufs,
            index,
            maps,
            readback_from: Instant::now(),
        })
    }

    /// Buffers of at least the wanted sizes, with the given uses, one per slot of `stage`'s
    /// pool: the pooled one where it is large enough, else a new one. They are the caller's
    /// until [`GpuOracle::check_in`], so concurrent calls never share a buffer in flight.
    fn check_out(
        &self,
        stage: Stage,
        wanted: &[(u64, wgpu::BufferUsages)],
    ) -> Result<Vec<wgpu::Buffer>> {
        let mut taken: Vec<Option<wgpu::Buffer>> = {
            let mut pools = self.pools()?;
            let pool = &mut pools[stage as usize];
            pool.resize_with(pool.len().max(wanted.len()), || None);
            pool[..wanted.len()].iter_mut().map(Option::take).collect()
        };
        Ok(wanted
            .iter()
            .zip(taken.iter_mut())
            .map(|(&(size, usage), old)| match old.take() {
                Some(b) if b.size() >= size => b,
                _ => self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("isomesh"),
                    size,
                    usage,
                    mapped_at_creation: false,
                }),
            })
            .collect())
    }

    /// Returns buffers from [`GpuOracle::check_out`] to `stage`'s pool, keeping the larger
    /// buffer of a slot that another call filled meanwhile.
    fn check_in(&self, stage: Stage, buffers: Vec<wgpu::Buffer>) -> Result<()> {
        let mut pools = self.pools()?;
        let pool = &mut pools[stage as usize];
        pool.resize_with(pool.len().max(buffers.len()), || None);
        for (slot, b) in pool.iter_mut().zip(buffers) {
            if slot.as_ref().is_none_or(|old| old.size() < b.size()) {
                *slot = Some(b);
            }
        }
        Ok(())
    }

    fn pools(&self) -> Result<MutexGuard<'_, [Vec<Option<wgpu::Buffer>>; STAGES]>> {
        self.buffers
            .lock()
            .map_err(|_| Error::Gpu("a previous GPU call panicked".into()))
    }

    /// Waits for a submitted round trip and returns its outputs' bytes.
    fn finish(&self, pending: Pending) -> Result<Vec<Vec<u8>>> {
        let started = Instant::now();
        self.wait(Some(pending.index))?;
        let mut results = Vec::with_capacity(pending.maps.len());
        for Readback {
            staging,
            size,
            want,
            mapped,
        } in pending.maps
        {
            mapped
                .recv()
                .map_err(|_| Error::Gpu("the readback was dropped".into()))?
                .map_err(|e| Error::Gpu(format!("readback: {e}")))?;
            let slice = staging.slice(..size);
            let view = slice
                .get_mapped_range()
                .map_err(|e| Error::Gpu(format!("readback: {e}")))?;
            results.push(view[..want].to_vec());
            drop(view);
            staging.unmap();
        }
        self.check_in(pending.stage, pending.buffers)?;
        add_time(&self.gpu_ns, started);
        if self.phased.load(Ordering::Relaxed) {
            add_time(&self.readback_ns, pending.readback_from);
        }
        Ok(results)
    }

    /// Blocks until the device has done the submission `index` (None: everything submitted).
    fn wait(&self, index: Option<wgpu::SubmissionIndex>) -> Result<()> {
        self.gpu
            .device
            .poll(wgpu::PollType::Wait {
                submission_index: index,
                timeout: None,
            })
            .map(|_| ())
            .map_err(|e| Error::Gpu(format!("waiting for the device: {e}")))
    }

    fn encode_reals(&self, v: &[f64]) -> Vec<u8> {
        match self.precision {
            Precision::F64 => bytemuck::cast_slice(v).to_vec(),
            Precision::F32 => {
                let f: Vec<f32> = v.iter().map(|&x| x as f32).collect();
                bytemuck::cast_slice(&f).to_vec()
            }
        }
    }

    fn decode_reals(&self, bytes: &[u8]) -> Vec<f64> {
        match self.precision {
            Precision::F64 => bytemuck::pod_collect_to_vec(bytes),
            Precision::F32 => bytemuck::pod_collect_to_vec::<u8, f32>(bytes)
                .into_iter()
                .map(f64::from)
                .collect(),
        }
    }

    fn real_size(&self) -> usize {
        match self.precision {
            Precision::F64 => 8,
            Precision::F32 => 4,
        }
    }
}

/// A round trip on its way, from [`GpuOracle::submit`] to [`GpuOracle::finish`], with the
/// buffers it checked out of its stage's pool.
struct Pending {
    stage: Stage,
    buffers: Vec<wgpu::Buffer>,
    index: wgpu::SubmissionIndex,
    maps: Vec<Readback>,
    readback_from: Instant,
}

/// One output on its way back: the staging buffer being mapped, its size, the bytes wanted
/// from it, and the channel that says when the mapping is done.
struct Readback {
    staging: wgpu::Buffer,
    size: u64,
    want: usize,
    mapped: std::sync::mpsc::Receiver<std::result::Result<(), wgpu::BufferAsyncError>>,
}

fn add_time(counter: &AtomicU64, since: Instant) {
    counter.fetch_add(since.elapsed().as_nanos() as u64, Ordering::Relaxed);
}

fn pipeline(gpu: &Gpu, src: &str, label: &str) -> Result<wgpu::ComputePipeline> {
    let dev = &gpu.device;
    let scope = dev.push_error_scope(wgpu::ErrorFilter::Validation);
    let module = dev.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(Cow::Borrowed(src)),
    });
    let p = dev.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: None,
        module: &module,
        entry_point: Some("main"),
        compilation_options: Default::default(),
        cache: None,
    });
    if let Some(e) = pollster::block_on(scope.pop()) {
        return Err(Error::Gpu(format!("{label} pipeline: {e}")));
    }
    Ok(p)
}

impl GpuOracle<'_> {
    /// The solve shader on `m` simplices given as packed scaled rows (k rows of k + 1 each):
    /// per simplex a verdict (0 crossed, 1 outside, 2 uncertain) and lambda.
    fn solve_packed(&self, packed: &[f64], m: usize) -> Result<(Vec<u32>, Vec<f64>)> {
        let n = self.k + 1;
        let per = self.k * n;
        let rs = self.real_size();
        let chunk = self.chunk(rs * per);
        let mut flags = Vec::with_capacity(m);
        let mut lam = Vec::with_capacity(m * n);
        for part in packed.chunks(chunk * per) {
            let c = part.len() / per;
            let pending = self.submit(
                Stage::Solve,
                &self.solve,
                &self.encode_reals(part),
                c,
                &[c * n * rs, c * 4],
                false,
            )?;
            let res = self.finish(pending)?;
            lam.extend(self.decode_reals(&res[0]));
            flags.extend(bytemuck::pod_collect_to_vec::<u8, u32>(&res[1]));
        }
        Ok((flags, lam))
    }

    /// The vertex shader's pipeline, built the first time it is asked for.
    fn eval_pipeline(&self) -> Result<&wgpu::ComputePipeline> {
        if let Some(p) = self.eval.get() {
            return Ok(p);
        }
        let Some(system) = self.f.system() else {
            return Err(Error::Gpu(
                "the GPU evaluates only functions written in the equation language".into(),
            ));
        };
        let built = pipeline(
            &self.gpu,
            &eval_shader(system.values(), self.precision)?,
            "eval_vertices",
        )?;
        Ok(self.eval.get_or_init(|| built))
    }

    /// The vertex shader alone (`shaders/eval_vertices.wgsl`), the twin of
    /// [`eval_lattice`](crate::cpu::vertices::eval_lattice): f at the lattice vertices
    /// `lattice` (rows of d) of `tri`, mapped to R^d inside the shader; rows of k values.
    /// Tracing does not use it (see the module documentation): it is the building block of
    /// GPU-side scans, and measured by `isomesh bench`.
    pub fn eval_stage(&self, tri: &Triangulation, lattice: &[i32]) -> Result<Vec<f64>> {
        let eval = self.eval_pipeline()?;
        let (d, k) = (tri.dim(), self.k);
        if self.f.ambient_dim() != d {
            return Err(Error::DimensionMismatch(format!(
                "the triangulation is in R^{d}, f in R^{}",
                self.f.ambient_dim()
            )));
        }
        let exact = match self.precision {
            Precision::F32 => 1 << 24,
            Precision::F64 => i32::MAX,
        };
        if lattice.iter().any(|&u| u.unsigned_abs() > exact as u32) {
            return Err(Error::Gpu(format!(
                "lattice coordinates beyond {exact} do not fit the {} shader exactly",
                self.precision.ty()
            )));
        }
        let (a, b) = tri.affine_map();
        let head: Vec<f64> = a.into_iter().chain(b).collect();
        let rs = self.real_size();
        let chunk = self.chunk(rs * d.max(k));
        let mut values = Vec::with_capacity(lattice.len() / d.max(1) * k);
        for part in lattice.chunks(chunk * d) {
            let count = part.len() / d;
            let input: Vec<f64> = head
                .iter()
                .copied()
                .chain(part.iter().map(|&u| u as f64))
                .collect();
            let pending = self.submit(
                Stage::Eval,
                eval,
                &self.encode_reals(&input),
                count,
                &[count * k * rs],
                false,
            )?;
            values.extend(self.decode_reals(&self.finish(pending)?[0]));
        }
        Ok(values)
    }

    /// The shader stage alone, the twin of [`Decider::fast_path`](crate::cpu::decide::Decider::fast_path): for each simplex (rows of
    /// vertex indices into `values`, as in [`Oracle::decide`]), the shader's verdict as the
    /// fast path's `Option<Status>` (None: uncertain), and lambda. No host filter runs first.
    pub fn solve_stage(
        &self,
        values: &[f64],
        simplices: &[u32],
    ) -> Result<(Vec<Option<Status>>, Vec<f64>)> {
        let (k, n) = (self.k, self.k + 1);
        let m = simplices.len() / n;
        let mut packed = vec![0.0; m * k * n];
        packed
            .par_chunks_mut(k * n)
            .zip(simplices.par_chunks(n))
            .for_each(|(r, idx)| scaled_rows(k, |j, c| values[idx[j] as usize * k + c], r));
        let (flags, lam) = self.solve_packed(&packed, m)?;
        let verdicts = flags
            .iter()
            .map(|&f| match f {
                CROSSED => Some(Status::Crossed),
                OUTSIDE => Some(Status::Outside),
                _ => None,
            })
            .collect();
        Ok((verdicts, lam))
    }
}

/// What one scan dispatch reads: a window of the grid's rows and codes, relative to the
/// first vertex of its first row.
struct ScanWindow {
    /// The vertex the window starts at.
    lo: usize,
    /// The shader's input words.
    input: Vec<u32>,
}

/// The window that holds every corner of the cubes based at `cubes`, or None when its ids
/// or its size do not fit u32 words and `max_bytes`.
fn scan_window(grid: &ScanGrid, cubes: &Range<usize>, max_bytes: u64) -> Option<ScanWindow> {
    let d = grid.dim();
    let rows = grid.rows();
    let first = grid.row_of(cubes.start);
    let (id0, lo) = (rows[first].id, rows[first].offset);
    let reach: usize = (1..d).map(|j| grid.stride(j)).sum();
    let last_id = rows[grid.row_of(cubes.end - 1)].id + reach;
    let end = rows.partition_point(|r| r.id <= last_id);
    let hi = rows.get(end).map_or(grid.len(), |r| r.offset);
    let count = end - first;
    let words = 5 + (d - 1) + 5 * count + (hi - lo);
    if last_id - id0 > u32::MAX as usize || (words as u64) * 4 > max_bytes {
        return None;
    }
    let mut input = Vec::with_capacity(words);
    input.extend([
        (cubes.start - lo) as u32,
        count as u32,
        0,
        0,
        cubes.len() as u32,
    ]);
    input.extend((1..d).map(|j| grid.stride(j) as u32));
    for r in &rows[first..end] {
        input.extend([
            (r.id - id0) as u32,
            r.start as i32 as u32,
            r.len,
            (r.offset - lo) as u32,
            grid.top_axes(r.id),
        ]);
    }
    input[3] = input.len() as u32;
    input.extend_from_slice(&grid.codes()[lo..hi]);
    Some(ScanWindow { lo, input })
}

impl GpuOracle<'_> {
    /// The scan shader's pipeline for R^d, built the first time it is asked for.
    fn scan_pipeline(&self, d: usize) -> Result<&wgpu::ComputePipeline> {
        if let Some(p) = self.scan.get() {
            return Ok(p);
        }
        let built = pipeline(&self.gpu, &scan_shader(d, self.k)?, "scan")?;
        Ok(self.scan.get_or_init(|| built))
    }

    /// The scan shader alone (`shaders/scan.wgsl`), the twin of
    /// [`scan::candidates`]: the candidates of the cubes based at the grid vertices
    /// `cubes`, in the same order (the device appends them in any order; the host sorts).
    /// Needs d <= [`MAX_GPU_SCAN_DIM`].
    pub fn scan_stage(&self, grid: &ScanGrid, cubes: Range<usize>) -> Result<Candidates> {
        let (d, k) = (grid.dim(), grid.codim());
        if k != self.k {
            return Err(Error::DimensionMismatch(format!(
                "the grid is of codimension {}, f of {}",
                k, self.k
            )));
        }
        let pipeline = self.scan_pipeline(d)?;
        let record = 2 * k + 1;
        let max_bytes = self.max_binding();
        let mut words: Vec<u32> = Vec::new();
        let mut pending = vec![cubes];
        while let Some(range) = pending.pop() {
            if range.is_empty() {
                continue;
            }
            let window = scan_window(grid, &range, max_bytes);
            let found = match window {
                Some(w) => self.scan_dispatch(pipeline, w, range.len(), record, max_bytes)?,
                None => None,
            };
            match found {
                Some(f) => words.extend(f),
                None if range.len() == 1 => {
                    let mut one = Candidates::default();
                    scan::cube_candidates(grid, range.start, &mut Default::default(), &mut one);
                    for (r, c) in one.rows.chunks(k + 1).zip(one.chains.chunks(k)) {
                        words.extend_from_slice(r);
                        words.extend_from_slice(c);
                    }
                }
                None => {
                    // Too large for one binding: halves, the first one next.
                    let mid = range.start + range.len() / 2;
                    pending.push(mid..range.end);
                    pending.push(range.start..mid);
                }
            }
        }
        Ok(sorted_candidates(&words, k))
    }

    /// One dispatch of the scan shader over the `cubes` cubes of `window`: its records with
    /// global vertex indices, or None when they would not fit `max_bytes`.
    fn scan_dispatch(
        &self,
        pipeline: &wgpu::ComputePipeline,
        mut window: ScanWindow,
        cubes: usize,
        record: usize,
        max_bytes: u64,
    ) -> Result<Option<Vec<u32>>> {
        let k = self.k;
        let max_cap = (max_bytes / (4 * record as u64)) as usize;
        let density = self.scan_density.load(Ordering::Relaxed) as usize;
        let mut cap = (cubes * density / (1 << 16) * 5 / 4 + 1024).min(max_cap);
        loop {
            window.input[2] = cap as u32;
            let pending = self.submit(
                Stage::Scan,
                pipeline,
                bytemuck::cast_slice(&window.input),
                cubes.div_ceil(SCAN_RUN),
                &[4, cap * record * 4],
                true,
            )?;
            let res = self.finish(pending)?;
            let found = bytemuck::pod_read_unaligned::<u32>(&res[0][..4]) as usize;
            self.scan_density
                .store((found * (1 << 16) / cubes.max(1)) as u64, Ordering::Relaxed);
            if found <= cap {
                let mut out: Vec<u32> = bytemuck::pod_collect_to_vec(&res[1][..found * record * 4]);
                let lo = window.lo as u32;
                for rec in out.chunks_exact_mut(record) {
                    for v in &mut rec[..=k] {
                        *v += lo;
                    }
                }
                return Ok(Some(out));
            }
            if found > max_cap {
                return Ok(None);
            }
            cap = found;
        }
    }
}

/// Records of 2k + 1 words (k + 1 vertices, k corner sets) as candidates in the CPU's order:
/// by base vertex, then chain.
fn sorted_candidates(words: &[u32], k: usize) -> Candidates {
    let record = 2 * k + 1;
    let mut recs: Vec<&[u32]> = words.chunks_exact(record).collect();
    recs.par_sort_unstable_by(|a, b| a[0].cmp(&b[0]).then_with(|| a[k + 1..].cmp(&b[k + 1..])));
    let mut out = Candidates {
        rows: Vec::with_capacity(recs.len() * (k + 1)),
        chains: Vec::with_capacity(recs.len() * k),
    };
    for r in recs {
        out.rows.extend_from_slice(&r[..=k]);
        out.chains.extend_from_slice(&r[k + 1..]);
    }
    out
}

impl Oracle for GpuOracle<'_> {
    fn name(&self) -> String {
        format!("gpu: {}", self.gpu.adapter.name)
    }

    fn eval_vertices(
        &self,
        tri: &Triangulation,
        lattice: &[i32],
        values: &mut [f64],
    ) -> Result<()> {
        // On the CPU: see the module documentation.
        CpuOracle::new(self.f).eval_vertices(tri, lattice, values)
    }

    fn level_slice(&self) -> Option<usize> {
        Some(self.level_slice.load(Ordering::Relaxed)).filter(|&s| s > 0)
    }

    fn scan_candidates(&self, grid: &ScanGrid, cubes: Range<usize>) -> Result<Candidates> {
        if grid.dim() > MAX_GPU_SCAN_DIM {
            return Ok(scan::candidates(grid, cubes));
        }
        self.scan_stage(grid, cubes)
    }

    fn decide(
        &self,
        values: &[f64],
        simplices: &[u32],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> Result<u64> {
        let n = self.k + 1;
        let rs = self.real_size();
        let chunk = self.chunk(rs * self.k * n).min(PIPELINE_CHUNK);
        let ranges: Vec<Range<usize>> = (0..status.len())
            .step_by(chunk)
            .map(|s| s..(s + chunk).min(status.len()))
            .collect();
        // A pipeline: while the device solves chunk c, the host packs chunk c + 1 and
        // settles chunk c - 1 (keeps certified verdicts, re-decides the rest on the CPU).
        let mut exact = 0;
        let mut next = ranges
            .first()
            .map(|r| self.prepare(values, simplices, r.clone(), status));
        let mut solved: Option<(Vec<usize>, Vec<Vec<u8>>)> = None;
        for c in 0..ranges.len() {
            let (sent, bytes) = next
                .take()
                .expect("each chunk is prepared before it is sent");
            let outputs = [sent.len() * n * rs, sent.len() * 4];
            let mut pending = if sent.is_empty() {
                None
            } else {
                Some(self.submit(
                    Stage::Solve,
                    &self.solve,
                    &bytes,
                    sent.len(),
                    &outputs,
                    false,
                )?)
            };
            let mut early = None;
            if self.phased.load(Ordering::Relaxed) {
                early = pending.take().map(|p| self.finish(p)).transpose()?;
            }
            if let Some(r) = ranges.get(c + 1) {
                next = Some(self.prepare(values, simplices, r.clone(), status));
            }
            if let Some((prev, res)) = solved.take() {
                exact += self.settle(values, simplices, &prev, &res, status, lambda)?;
            }
            let res = match (early, pending) {
                (Some(res), _) => res,
                (None, Some(p)) => self.finish(p)?,
                (None, None) => vec![Vec::new(), Vec::new()],
            };
            self.solved.fetch_add(sent.len() as u64, Ordering::Relaxed);
            solved = Some((sent, res));
        }
        if let Some((prev, res)) = solved {
            exact += self.settle(values, simplices, &prev, &res, status, lambda)?;
        }
        Ok(exact)
    }
}

impl GpuOracle<'_> {
    /// Host side before the shader, for the simplices in `range`: the CPU's cheap filters
    /// (their verdicts go straight into `status`), then the scaled rows of L for the rest,
    /// encoded for upload. Returns the indices sent and the bytes.
    fn prepare(
        &self,
        values: &[f64],
        simplices: &[u32],
        range: Range<usize>,
        status: &mut [Status],
    ) -> (Vec<usize>, Vec<u8>) {
        let started = Instant::now();
        let (k, n) = (self.k, self.k + 1);
        let val =
            |i: usize| move |j: usize, c: usize| values[simplices[i * n + j] as usize * k + c];
        let start = range.start;
        let pre: Vec<Option<Status>> = range
            .into_par_iter()
            .map(|i| filter_verdict(k, val(i)))
            .collect();
        let mut sent = Vec::new();
        for (o, p) in pre.iter().enumerate() {
            match p {
                Some(s) => status[start + o] = *s,
                None => sent.push(start + o),
            }
        }
        let mut packed = vec![0.0; sent.len() * k * n];
        packed
            .par_chunks_mut(k * n)
            .zip(&sent)
            .for_each(|(r, &i)| scaled_rows(k, val(i), r));
        let bytes = self.encode_reals(&packed);
        add_time(&self.host_ns, started);
        (sent, bytes)
    }

    /// Host side after the shader: keeps what the bound certifies and decides the rest of
    /// `sent` on the CPU, in one gathered batch. Returns the count of exact decisions.
    fn settle(
        &self,
        values: &[f64],
        simplices: &[u32],
        sent: &[usize],
        res: &[Vec<u8>],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> Result<u64> {
        let started = Instant::now();
        let n = self.k + 1;
        let lam = self.decode_reals(&res[0]);
        let flags: Vec<u32> = bytemuck::pod_collect_to_vec(&res[1]);
        let keep_crossed = self.precision == Precision::F64;
        let recheck: Vec<usize> = sent
            .iter()
            .enumerate()
            .filter_map(|(j, &i)| match flags[j] {
                OUTSIDE => {
                    status[i] = Status::Outside;
                    None
                }
                CROSSED if keep_crossed => {
                    status[i] = Status::Crossed;
                    lambda[i * n..(i + 1) * n].copy_from_slice(&lam[j * n..(j + 1) * n]);
                    None
                }
                _ => Some(i),
            })
            .collect();
        self.rechecked
            .fetch_add(recheck.len() as u64, Ordering::Relaxed);
        let sub: Vec<u32> = recheck
            .iter()
            .flat_map(|&i| simplices[i * n..(i + 1) * n].iter().copied())
            .collect();
        let mut sub_status = vec![Status::Outside; recheck.len()];
        let mut sub_lambda = vec![0.0; recheck.len() * n];
        let exact =
            CpuOracle::new(self.f).decide(values, &sub, &mut sub_status, &mut sub_lambda)?;
        for ((&i, &s), l) in recheck
            .iter()
            .zip(&sub_status)
            .zip(sub_lambda.chunks_exact(n))
        {
            status[i] = s;
            if s.crossed() {
                lambda[i * n..(i + 1) * n].copy_from_slice(l);
            }
        }
        add_time(&self.host_ns, started);
        Ok(exact)
    }
}
