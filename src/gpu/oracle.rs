//! The GPU oracle: the intersection test's (k+1)x(k+1) solves in a WGSL compute shader
//! (`shaders/solve.wgsl`, the twin of the CPU fast path).
//!
//! What makes S the CPU's S: the shader only takes decisions that its error bound certifies.
//! In f64 it keeps certain crossings (with their lambda) and certain misses; in f32 it keeps
//! only certain misses, so every crossing point is computed by the CPU in f64. Everything else
//! is re-decided on the CPU by [`Decider`](crate::cpu::decide::Decider), exactly where needed.
//!
//! Vertex values are computed on the CPU (each lattice vertex once per trace): a GPU may
//! contract a * b + c into a fused multiply-add, which changes f by an ulp, and S is defined
//! by the CPU's values. With the same values, the f64 shader's lambda equals the CPU's where
//! the device rounds division and does not contract (lavapipe: bit-identical); elsewhere
//! points may differ by a few ulps, never the decisions.

use std::borrow::Cow;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use rayon::prelude::*;

use super::context::Gpu;
use super::wgsl::{validate, Precision};
use crate::cpu::decide::{filter_verdict, scaled_rows, Status};
use crate::error::{Error, Result};
use crate::expr::ImplicitFunction;
use crate::trace::{CpuOracle, Oracle};
use crate::triangulation::Triangulation;

/// The solve shader, before its prelude.
pub const SOLVE_WGSL: &str = include_str!("../../shaders/solve.wgsl");

/// Safety factor of the error bound, and the largest trusted relative bound, as on the CPU.
const BOUND_FACTOR: f64 = 16.0;
const MAX_RELATIVE_BOUND: f64 = 0.125;
/// Threads per workgroup in both shaders.
const WORKGROUP: u32 = 64;
/// Workgroups per dispatch row (the limit per dimension).
const MAX_GROUPS: u32 = 65_535;

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
    /// Seconds in GPU round trips (upload, compute, readback).
    pub gpu_s: f64,
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

/// The intersection oracle on a GPU.
pub struct GpuOracle<'f> {
    gpu: Gpu,
    f: &'f dyn ImplicitFunction,
    k: usize,
    precision: Precision,
    solve: wgpu::ComputePipeline,
    solved: AtomicU64,
    rechecked: AtomicU64,
    gpu_ns: AtomicU64,
    /// Buffers kept across calls, by role; they grow when a batch needs more.
    buffers: Mutex<Vec<Option<wgpu::Buffer>>>,
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
            solved: AtomicU64::new(0),
            rechecked: AtomicU64::new(0),
            gpu_ns: AtomicU64::new(0),
            buffers: Mutex::new(Vec::new()),
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
        GpuStats {
            solved: self.solved.load(Ordering::Relaxed),
            rechecked: self.rechecked.load(Ordering::Relaxed),
            gpu_s: self.gpu_ns.load(Ordering::Relaxed) as f64 * 1e-9,
        }
    }

    /// Items per dispatch so that `bytes_per_item` fits one storage binding.
    fn chunk(&self, bytes_per_item: usize) -> usize {
        let max = self.gpu.adapter.max_storage_binding.min(1 << 30) as usize;
        (max / bytes_per_item.max(1)).clamp(1, 1 << 22)
    }

    /// Runs `pipeline` over `count` items with `input` bound at 0 and outputs of the given
    /// byte sizes at 1.., returning the outputs' bytes.
    fn run(
        &self,
        pipeline: &wgpu::ComputePipeline,
        input: &[u8],
        count: usize,
        outputs: &[usize],
    ) -> Result<Vec<Vec<u8>>> {
        let mut pool = self
            .buffers
            .lock()
            .map_err(|_| Error::Gpu("a previous GPU call panicked".into()))?;
        let started = Instant::now();
        let dev = &self.gpu.device;
        let storage = wgpu::BufferUsages::STORAGE;
        let in_size = (input.len().max(16) as u64).next_multiple_of(4);
        let inbuf = reuse(
            dev,
            &mut pool,
            0,
            in_size,
            storage | wgpu::BufferUsages::COPY_DST,
        );
        if !input.is_empty() {
            self.gpu.queue.write_buffer(&inbuf, 0, input);
        }
        let outs: Vec<(wgpu::Buffer, wgpu::Buffer, u64)> = outputs
            .iter()
            .enumerate()
            .map(|(i, &size)| {
                let size = (size.max(4) as u64).next_multiple_of(4);
                let out = reuse(
                    dev,
                    &mut pool,
                    2 + 2 * i,
                    size,
                    storage | wgpu::BufferUsages::COPY_SRC,
                );
                let staging = reuse(
                    dev,
                    &mut pool,
                    3 + 2 * i,
                    size,
                    wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                );
                (out, staging, size)
            })
            .collect();
        let groups = (count as u32).div_ceil(WORKGROUP).max(1);
        let (gx, gy) = if groups > MAX_GROUPS {
            (MAX_GROUPS, groups.div_ceil(MAX_GROUPS))
        } else {
            (groups, 1)
        };
        let params: [u32; 4] = [count as u32, gx * WORKGROUP, 0, 0];
        let ubuf = reuse(
            dev,
            &mut pool,
            1,
            16,
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        self.gpu
            .queue
            .write_buffer(&ubuf, 0, bytemuck::cast_slice(&params));
        let layout = pipeline.get_bind_group_layout(0);
        let mut entries = vec![wgpu::BindGroupEntry {
            binding: 0,
            resource: inbuf.as_entire_binding(),
        }];
        for (i, (out, _, _)) in outs.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: i as u32 + 1,
                resource: out.as_entire_binding(),
            });
        }
        entries.push(wgpu::BindGroupEntry {
            binding: outs.len() as u32 + 1,
            resource: ubuf.as_entire_binding(),
        });
        let bind = dev.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &layout,
            entries: &entries,
        });
        let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: None,
                timestamp_writes: None,
            });
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(gx, gy, 1);
        }
        for (out, staging, size) in &outs {
            enc.copy_buffer_to_buffer(out, 0, staging, 0, *size);
        }
        self.gpu.queue.submit([enc.finish()]);
        let mut results = Vec::with_capacity(outs.len());
        for ((_, staging, size), &want) in outs.iter().zip(outputs) {
            let slice = staging.slice(..*size);
            let (tx, rx) = std::sync::mpsc::channel();
            slice.map_async(wgpu::MapMode::Read, move |r| {
                let _ = tx.send(r);
            });
            dev.poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| Error::Gpu(format!("waiting for the device: {e}")))?;
            rx.recv()
                .map_err(|_| Error::Gpu("the readback was dropped".into()))?
                .map_err(|e| Error::Gpu(format!("readback: {e}")))?;
            let view = slice
                .get_mapped_range()
                .map_err(|e| Error::Gpu(format!("readback: {e}")))?;
            results.push(view[..want].to_vec());
            drop(view);
            staging.unmap();
        }
        self.gpu_ns
            .fetch_add(started.elapsed().as_nanos() as u64, Ordering::Relaxed);
        Ok(results)
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

/// The pooled buffer in `slot`, replaced by a larger one when it holds fewer than `size`
/// bytes.
fn reuse(
    dev: &wgpu::Device,
    pool: &mut Vec<Option<wgpu::Buffer>>,
    slot: usize,
    size: u64,
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    if pool.len() <= slot {
        pool.resize(slot + 1, None);
    }
    match &pool[slot] {
        Some(b) if b.size() >= size => b.clone(),
        _ => {
            let b = dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some("isomesh"),
                size,
                usage,
                mapped_at_creation: false,
            });
            pool[slot] = Some(b.clone());
            b
        }
    }
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
            let res = self.run(
                &self.solve,
                &self.encode_reals(part),
                c,
                &[c * n * rs, c * 4],
            )?;
            lam.extend(self.decode_reals(&res[0]));
            flags.extend(bytemuck::pod_collect_to_vec::<u8, u32>(&res[1]));
        }
        Ok((flags, lam))
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

    fn decide(
        &self,
        values: &[f64],
        simplices: &[u32],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> Result<u64> {
        let k = self.k;
        let n = k + 1;
        let count = status.len();
        // Host side: the CPU's cheap filters, then the scaled rows of L for the rest.
        let val =
            |i: usize| move |j: usize, c: usize| values[simplices[i * n + j] as usize * k + c];
        let pre: Vec<Option<Status>> = (0..count)
            .into_par_iter()
            .map(|i| filter_verdict(k, val(i)))
            .collect();
        let sent: Vec<usize> = (0..count).filter(|&i| pre[i].is_none()).collect();
        let mut packed = vec![0.0; sent.len() * k * n];
        packed
            .par_chunks_mut(k * n)
            .zip(&sent)
            .for_each(|(r, &i)| scaled_rows(k, val(i), r));
        let (flags, lam) = self.solve_packed(&packed, sent.len())?;
        self.solved.fetch_add(sent.len() as u64, Ordering::Relaxed);
        for (i, p) in pre.iter().enumerate() {
            if let Some(s) = p {
                status[i] = *s;
            }
        }
        // Keep what the bound certifies; decide the rest on the CPU.
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
        // The CPU oracle on the rest, gathered into one batch.
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
        Ok(exact)
    }
}
