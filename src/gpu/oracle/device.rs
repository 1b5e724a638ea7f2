//! Device plumbing shared by the stages: buffer pools per stage, submitting a dispatch and
//! reading its outputs back, pipelines, and the encoding of reals for the shaders.

use std::borrow::Cow;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::MutexGuard;
use std::time::Instant;

use super::GpuOracle;
use crate::error::{Error, Result};
use crate::gpu::context::Gpu;
use crate::gpu::wgsl::{Precision, WORKGROUP};

/// Workgroups per dispatch row (the limit per dimension).
const MAX_GROUPS: u32 = 65_535;

/// The shaders, each with its own buffer pool: the stages of one oracle may run at once
/// (the exhaustive scan generates batch n + 1 while batch n is decided).
#[derive(Clone, Copy)]
pub(super) enum Stage {
    Solve,
    Scan,
    EvalVertices,
    EvalCertified,
    SolveCertified,
    SolveIds,
}
pub(super) const STAGES: usize = 6;

/// A pipeline and the buffers kept on the device that it reads, bound after its parameters
/// (at 2 + the number of outputs, on).
#[derive(Clone, Copy)]
pub(super) struct Kernel<'a> {
    pub pipeline: &'a wgpu::ComputePipeline,
    pub kept: &'a [&'a wgpu::Buffer],
}

impl GpuOracle<'_> {
    /// The bytes one storage binding may hold.
    pub(super) fn max_binding(&self) -> u64 {
        let limit = self.binding_limit.load(Ordering::Relaxed);
        self.gpu.adapter.max_storage_binding.min(limit)
    }

    /// Items per dispatch so that `bytes_per_item` fits one storage binding.
    pub(super) fn chunk(&self, bytes_per_item: usize) -> usize {
        let max = self.max_binding() as usize;
        (max / bytes_per_item.max(1)).clamp(1, 1 << 22)
    }

    /// Uploads `input`, runs `pipeline` over `count` items with `input` bound at 0 and
    /// `outputs` at 1.. (zeroed first when `zeroed`), and starts copying back those to be
    /// read; the device works while the caller does other things, until
    /// [`GpuOracle::finish`]. The buffers come from `stage`'s pool and go back at the finish.
    pub(super) fn submit(
        &self,
        stage: Stage,
        pipeline: &wgpu::ComputePipeline,
        input: &[u8],
        count: usize,
        outputs: &[Output],
        zeroed: bool,
    ) -> Result<Pending> {
        let kernel = Kernel {
            pipeline,
            kept: &[],
        };
        self.submit_kernel(stage, kernel, input, count, outputs, zeroed)
    }

    /// [`GpuOracle::submit`] of a kernel that also reads buffers kept on the device.
    pub(super) fn submit_kernel(
        &self,
        stage: Stage,
        kernel: Kernel<'_>,
        input: &[u8],
        count: usize,
        outputs: &[Output],
        zeroed: bool,
    ) -> Result<Pending> {
        let pipeline = kernel.pipeline;
        let phased = self.phased.load(Ordering::Relaxed);
        let started = Instant::now();
        let storage = wgpu::BufferUsages::STORAGE;
        let sizes: Vec<u64> = outputs
            .iter()
            .map(|o| (o.bytes.max(4) as u64).next_multiple_of(4))
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
        for (&size, o) in sizes.iter().zip(outputs) {
            wanted.push((
                size,
                storage | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
            ));
            // An output left on the device keeps its slot with a staging buffer it never uses.
            wanted.push((
                if o.read { size } else { 4 },
                wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            ));
        }
        let bufs = self.check_out(stage, &wanted)?;
        let (inbuf, ubuf) = (&bufs[0], &bufs[1]);
        if !input.is_empty() {
            self.gpu.queue.write_buffer(inbuf, 0, input);
        }
        let params_bytes = 16;
        self.upload_bytes
            .fetch_add(input.len() as u64 + params_bytes, Ordering::Relaxed);
        let read_bytes: u64 = sizes
            .iter()
            .zip(outputs)
            .filter(|(_, o)| o.read)
            .map(|(s, _)| s)
            .sum();
        self.readback_bytes.fetch_add(read_bytes, Ordering::Relaxed);
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
        for (i, kept) in kernel.kept.iter().enumerate() {
            entries.push(wgpu::BindGroupEntry {
                binding: (outs.len() + 2 + i) as u32,
                resource: kept.as_entire_binding(),
            });
        }
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
        for ((pair, &size), o) in bufs[2..].chunks_exact(2).zip(&sizes).zip(outputs) {
            if o.read {
                enc.copy_buffer_to_buffer(&pair[0], 0, &pair[1], 0, size);
            }
        }
        let index = self.gpu.queue.submit([enc.finish()]);
        let mut maps = Vec::with_capacity(outputs.len());
        for ((pair, &size), o) in bufs[2..].chunks_exact(2).zip(&sizes).zip(outputs) {
            if !o.read {
                maps.push(None);
                continue;
            }
            let (tx, rx) = std::sync::mpsc::channel();
            pair[1]
                .slice(..size)
                .map_async(wgpu::MapMode::Read, move |r| {
                    let _ = tx.send(r);
                });
            maps.push(Some(Readback {
                staging: pair[1].clone(),
                size,
                want: o.bytes,
                mapped: rx,
            }));
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

    /// Waits for a submitted round trip and returns its outputs' bytes (none for an output
    /// not read back).
    pub(super) fn finish(&self, pending: Pending) -> Result<Vec<Vec<u8>>> {
        let started = Instant::now();
        self.wait(Some(pending.index))?;
        let mut results = Vec::with_capacity(pending.maps.len());
        for map in pending.maps {
            let Some(Readback {
                staging,
                size,
                want,
                mapped,
            }) = map
            else {
                results.push(Vec::new());
                continue;
            };
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

    /// Blocks until the device has done the submission `index` (None: everything
    /// submitted). With a stop flag ([`GpuOptions::cancel`](super::GpuOptions::cancel)) it
    /// looks at the flag every [`COMPILE_POLL`] and ends with [`Error::Interrupted`] when it
    /// is raised: a driver may compile a shader on its first dispatch, for minutes.
    pub(super) fn wait(&self, index: Option<wgpu::SubmissionIndex>) -> Result<()> {
        let timeout = self.cancel().map(|_| COMPILE_POLL);
        loop {
            let polled = self.gpu.device.poll(wgpu::PollType::Wait {
                submission_index: index.clone(),
                timeout,
            });
            match polled {
                Ok(_) => return Ok(()),
                Err(wgpu::PollError::Timeout) if timeout.is_some() => {
                    if self.cancel().is_some_and(|c| c.load(Ordering::Relaxed)) {
                        return Err(Error::Interrupted(
                            "stopped while waiting for the device".into(),
                        ));
                    }
                }
                Err(e) => return Err(Error::Gpu(format!("waiting for the device: {e}"))),
            }
        }
    }

    pub(super) fn encode_reals(&self, v: &[f64]) -> Vec<u8> {
        match self.precision {
            Precision::F64 => bytemuck::cast_slice(v).to_vec(),
            Precision::F32 => {
                let f: Vec<f32> = v.iter().map(|&x| x as f32).collect();
                bytemuck::cast_slice(&f).to_vec()
            }
        }
    }

    pub(super) fn decode_reals(&self, bytes: &[u8]) -> Vec<f64> {
        match self.precision {
            Precision::F64 => bytemuck::pod_collect_to_vec(bytes),
            Precision::F32 => bytemuck::pod_collect_to_vec::<u8, f32>(bytes)
                .into_iter()
                .map(f64::from)
                .collect(),
        }
    }

    pub(super) fn real_size(&self) -> usize {
        match self.precision {
            Precision::F64 => 8,
            Precision::F32 => 4,
        }
    }
}

/// An output buffer of a shader stage: its size in bytes, and whether it is copied back.
#[derive(Clone, Copy, Debug)]
pub(super) struct Output {
    pub bytes: usize,
    pub read: bool,
}

impl Output {
    /// An output copied back.
    pub fn read(bytes: usize) -> Self {
        Output { bytes, read: true }
    }

    /// An output the shader writes but the host never reads.
    pub fn unread(bytes: usize) -> Self {
        Output { bytes, read: false }
    }
}

/// A round trip on its way, from [`GpuOracle::submit`] to [`GpuOracle::finish`], with the
/// buffers it checked out of its stage's pool.
pub(super) struct Pending {
    stage: Stage,
    buffers: Vec<wgpu::Buffer>,
    index: wgpu::SubmissionIndex,
    /// Per output, its readback (none for an output left on the device).
    maps: Vec<Option<Readback>>,
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

pub(super) fn add_time(counter: &AtomicU64, since: Instant) {
    counter.fetch_add(since.elapsed().as_nanos() as u64, Ordering::Relaxed);
}

/// The compute pipeline of WGSL `src`. With a stop flag the driver compiles on a thread of
/// its own: raising the flag ends the wait with [`Error::Interrupted`] within
/// [`COMPILE_POLL`] (some drivers take minutes over a large system), the compile left to
/// finish there.
pub(super) fn pipeline(
    gpu: &Gpu,
    src: &str,
    label: &str,
    cancel: Option<&AtomicBool>,
) -> Result<wgpu::ComputePipeline> {
    use std::sync::mpsc::RecvTimeoutError;
    let Some(cancel) = cancel else {
        return compile(gpu, src, label);
    };
    let stopped = || Error::Interrupted(format!("stopped while the {label} shader compiled"));
    if cancel.load(Ordering::Relaxed) {
        return Err(stopped());
    }
    let (tx, rx) = std::sync::mpsc::channel();
    let (gpu, src, name) = (gpu.clone(), src.to_owned(), label.to_owned());
    std::thread::Builder::new()
        .name(format!("isomesh-compile-{label}"))
        .spawn(move || {
            let _ = tx.send(compile(&gpu, &src, &name));
        })
        .map_err(|e| Error::Gpu(format!("{label} pipeline: no thread to compile on: {e}")))?;
    loop {
        match rx.recv_timeout(COMPILE_POLL) {
            Ok(built) => return built,
            Err(RecvTimeoutError::Timeout) if cancel.load(Ordering::Relaxed) => {
                return Err(stopped())
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => {
                return Err(Error::Gpu(format!("{label} pipeline: the compile failed")))
            }
        }
    }
}

/// How often a wait for a shader compile looks at the stop flag.
const COMPILE_POLL: std::time::Duration = std::time::Duration::from_millis(20);

/// Compiles WGSL `src` into a compute pipeline on this thread.
fn compile(gpu: &Gpu, src: &str, label: &str) -> Result<wgpu::ComputePipeline> {
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
