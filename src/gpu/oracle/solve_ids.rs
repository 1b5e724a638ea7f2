//! The solve stage from vertex ids (`shaders/solve_ids.wgsl`): decisions on simplices given
//! as rows of vertex indices into an array of vertex values that only grows between calls (a
//! trace's vertex cache, the bench's batch: [`GrowingValues`]). The device keeps the values
//! it was sent ([`Kept`]), so a call uploads the rows new since the last one, once per
//! vertex, and the simplices as their vertex ids (4 bytes each); the shader gathers, filters,
//! scales and solves, and only the verdicts come back. What it does not certify outside is
//! decided again on the CPU, as after [`super::solve`]'s stage.

use std::ops::Range;
use std::sync::atomic::Ordering;
use std::sync::MutexGuard;
use std::time::Instant;

use super::device::{add_time, pipeline, Kernel, Output, Pending, Stage};
use super::solve::{solve_source, PIPELINE_CHUNK};
use super::GpuOracle;
use crate::cpu::certificate::{CROSSED, OUTSIDE};
use crate::cpu::solve::Status;
use crate::error::{Error, Result};
use crate::expr::certified::DeviceReal;
use crate::gpu::wgsl::Precision;
use crate::trace::{Decisions, GrowingValues};

/// The solve shader from vertex ids, before its prelude.
pub const SOLVE_IDS_WGSL: &str = include_str!("../../../shaders/solve_ids.wgsl");

/// Rows the kept values start with, before they double.
const FIRST_ROWS: usize = 1 << 12;

/// The entry bounds of the ids shader in precision `p`, (unit, tiny): each scaled entry of
/// L lies within unit |l| + tiny of the exact value, after the bound's own rounding. f32:
/// the host rounds to nearest (u |l|) and the product with a power of two is exact but for
/// an underflow (2 MIN_NORMAL). f64: the values arrive exact, but a conforming device keeps
/// only f32's precision in the product (below 2 u32 |l|), doubled for the bound's rounding.
pub(super) fn ids_rounding(p: Precision) -> (f64, f64) {
    match p {
        Precision::F32 => (
            2.0 * <f32 as DeviceReal>::UNIT,
            2.0 * <f32 as DeviceReal>::MIN_NORMAL,
        ),
        Precision::F64 => (
            4.0 * <f64 as DeviceReal>::SPEC_UNIT,
            2.0 * <f64 as DeviceReal>::MIN_NORMAL,
        ),
    }
}

/// Whether the device holds `v` within [`ids_rounding`]'s bounds in precision `p`: 0, or
/// rounded to `p` of a magnitude in [2^-126, 2^126] (normal in f32, and within the range
/// where the shader's power of two is exact). Other values, the non-finite ones and those
/// that round to 0 included, never reach the shader: their simplices are decided on the CPU.
pub(super) fn held(v: f64, p: Precision) -> bool {
    const LOW: f64 = f32::MIN_POSITIVE as f64;
    const HIGH: f64 = 1.0 / LOW;
    let rounded = match p {
        Precision::F32 => v as f32 as f64,
        Precision::F64 => v,
    };
    v == 0.0 || (LOW..=HIGH).contains(&rounded.abs())
}

/// The shader's power of two near 1 / |v|, for a held `v`: from the exponent of f32(v),
/// 1 for 0.
pub(super) fn pow2_inverse_f32(v: f64) -> f64 {
    let e = ((v as f32).to_bits() >> 23) & 0xff;
    if e == 0 {
        return 1.0;
    }
    f32::from_bits((254 - e as i32).max(1) as u32 * (1 << 23)) as f64
}

/// The solve shader from vertex ids for k-simplices in precision `p`, validated by naga.
pub fn solve_ids_shader(k: usize, p: Precision) -> Result<String> {
    solve_source(k, p, ids_rounding(p), SOLVE_IDS_WGSL)
}

/// Vertex values kept on the device between calls: the first `rows` rows of the array
/// named `log`, each with its held bit.
pub(super) struct Kept {
    log: GrowingValues,
    rows: usize,
    values: wgpu::Buffer,
    held: wgpu::Buffer,
    /// The held bits as sent (the last word is sent again as rows arrive).
    held_bits: Vec<u32>,
}

impl GpuOracle<'_> {
    /// The ids shader, built on first use.
    fn solve_ids_pipeline(&self) -> Result<&wgpu::ComputePipeline> {
        if let Some(p) = self.solve_ids.get() {
            return Ok(p);
        }
        let src = solve_ids_shader(self.k, self.precision)?;
        let built = pipeline(&self.gpu, &src, "solve from ids", self.cancel())?;
        Ok(self.solve_ids.get_or_init(|| built))
    }

    fn kept(&self) -> Result<MutexGuard<'_, Option<Kept>>> {
        self.kept
            .lock()
            .map_err(|_| Error::Gpu("a previous GPU call panicked".into()))
    }

    /// The device's copy of `values` (named `log`), brought up to date: the rows new since
    /// the last call are uploaded (all of them for another array, or when the buffers are
    /// full: they double). `None` when the values do not fit one storage binding.
    fn keep_values(
        &self,
        log: GrowingValues,
        values: &[f64],
    ) -> Result<Option<(wgpu::Buffer, wgpu::Buffer)>> {
        let k = self.k;
        let rs = self.real_size() as u64;
        let rows = values.len() / k;
        let row_bytes = k as u64 * rs;
        let max = self.max_binding();
        if rows as u64 * row_bytes > max || rows > u32::MAX as usize {
            return Ok(None);
        }
        let started = Instant::now();
        let mut kept = self.kept()?;
        let fits = |m: &Kept| {
            m.log == log
                && m.rows <= rows
                && m.values.size() >= rows as u64 * row_bytes
                && m.held.size() >= rows.div_ceil(32) as u64 * 4
        };
        if !kept.as_ref().is_some_and(fits) {
            let cap = (2 * rows).max(FIRST_ROWS);
            let value_bytes = (cap as u64 * row_bytes).min(max / row_bytes * row_bytes);
            let cap = (value_bytes / row_bytes) as usize;
            let make = |size: u64| {
                self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("isomesh kept values"),
                    size: size.max(16).next_multiple_of(4),
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                })
            };
            *kept = Some(Kept {
                log,
                rows: 0,
                values: make(value_bytes),
                held: make(cap.div_ceil(32) as u64 * 4),
                held_bits: Vec::new(),
            });
        }
        let m = kept.as_mut().expect("made above");
        if rows > m.rows {
            let from = m.rows;
            let p = self.precision;
            let mut fresh = values[from * k..rows * k].to_vec();
            m.held_bits.resize(rows.div_ceil(32), 0);
            for (i, row) in fresh.chunks_exact_mut(k).enumerate() {
                let v = from + i;
                if row.iter().all(|&x| held(x, p)) {
                    m.held_bits[v / 32] |= 1 << (v % 32);
                } else {
                    // Nothing the device cannot hold reaches it, NaN and infinities included.
                    row.fill(0.0);
                }
            }
            let bytes = self.encode_reals(&fresh);
            let words = &m.held_bits[from / 32..];
            let q = &self.gpu.queue;
            q.write_buffer(&m.values, from as u64 * row_bytes, &bytes);
            q.write_buffer(&m.held, (from / 32) as u64 * 4, bytemuck::cast_slice(words));
            self.upload_bytes
                .fetch_add((bytes.len() + 4 * words.len()) as u64, Ordering::Relaxed);
            m.rows = rows;
        }
        add_time(&self.host_ns, started);
        if self.phased.load(Ordering::Relaxed) {
            let t = Instant::now();
            let index = self.gpu.queue.submit([]);
            self.wait(Some(index))?;
            add_time(&self.upload_ns, t);
        }
        Ok(Some((m.values.clone(), m.held.clone())))
    }

    /// Decides a batch given by vertex ids into `values` (named `log`, see
    /// [`GrowingValues`]), pipelined: while the device decides chunk c, the host settles
    /// chunk c - 1 (keeps the certified misses, decides the rest on the CPU). For k = 1, and
    /// for values too many for one storage binding, the batch goes as packed rows
    /// ([`GpuOracle::decide_pipelined`]): with one value a vertex, two ids weigh what the
    /// packed row does, and a trace keeps more vertices than it decides simplices (from ids,
    /// a GPU trace of the sphere sent 23% more bytes; of the 3-torus, k = 3, 79% fewer).
    pub(super) fn decide_from_ids(
        &self,
        log: GrowingValues,
        values: &[f64],
        simplices: &[u32],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> Result<Decisions> {
        if self.k == 1 {
            return self.decide_pipelined(values, simplices, status, lambda);
        }
        let n = self.k + 1;
        let m = status.len();
        let emulated = self.emulated();
        let kept = match emulated {
            Some(_) => None,
            None => match self.keep_values(log, values)? {
                Some(bufs) => Some(bufs),
                None => return self.decide_pipelined(values, simplices, status, lambda),
            },
        };
        let pipe = match kept {
            Some(_) => Some(self.solve_ids_pipeline()?),
            None => None,
        };
        let chunk = self.chunk(4 * n).min(PIPELINE_CHUNK);
        let ranges: Vec<Range<usize>> = (0..m)
            .step_by(chunk)
            .map(|s| s..(s + chunk).min(m))
            .collect();
        let mut decided = Decisions::default();
        let mut solved: Option<(Vec<usize>, Vec<u8>)> = None;
        for r in ranges {
            let mut early =
                emulated.map(|seed| self.emulated_solve_ids(seed, values, simplices, r.clone()));
            let mut pending = None;
            if let (Some((vals, held)), Some(pipe)) = (&kept, pipe) {
                let p = self.submit_ids(pipe, [vals, held], simplices, r.clone())?;
                if self.phased.load(Ordering::Relaxed) {
                    early = Some(self.finish(p)?.swap_remove(0));
                } else {
                    pending = Some(p);
                }
            }
            if let Some((prev, flags)) = solved.take() {
                decided += self.settle(values, simplices, &prev, &flags, status, lambda)?;
            }
            let flags = match (early, pending) {
                (Some(flags), _) => flags,
                (None, Some(p)) => self.finish(p)?.swap_remove(0),
                (None, None) => return Err(Error::Gpu("a chunk went nowhere".into())),
            };
            self.solved.fetch_add(r.len() as u64, Ordering::Relaxed);
            solved = Some((r.collect(), flags));
        }
        if let Some((prev, flags)) = solved {
            decided += self.settle(values, simplices, &prev, &flags, status, lambda)?;
        }
        Ok(decided)
    }

    /// Starts the ids shader on simplices `range` of `simplices`, with the kept values and
    /// their held bits.
    fn submit_ids(
        &self,
        pipe: &wgpu::ComputePipeline,
        kept: [&wgpu::Buffer; 2],
        simplices: &[u32],
        range: Range<usize>,
    ) -> Result<Pending> {
        let n = self.k + 1;
        let kernel = Kernel {
            pipeline: pipe,
            kept: &kept,
        };
        let ids = bytemuck::cast_slice(&simplices[range.start * n..range.end * n]);
        let outputs = [Output::read(range.len() * 4)];
        self.submit_kernel(Stage::SolveIds, kernel, ids, range.len(), &outputs, false)
    }

    #[doc(hidden)] // a stage alone, for tests
    /// The ids shader alone (or its emulation) on `simplices` (rows of k + 1 indices into
    /// `values`, rows of k), the values sent as a new array: per simplex the verdict it
    /// certified (crossed or outside), or `None` where it leaves the simplex to the CPU.
    pub fn solve_ids_stage(
        &self,
        values: &[f64],
        simplices: &[u32],
    ) -> Result<Vec<Option<Status>>> {
        let n = self.k + 1;
        let m = simplices.len() / n;
        let flags = match self.emulated() {
            Some(seed) => self.emulated_solve_ids(seed, values, simplices, 0..m),
            None => {
                let (vals, held) = self
                    .keep_values(GrowingValues::new(), values)?
                    .ok_or_else(|| Error::Gpu("the values pass one storage binding".into()))?;
                let pipe = self.solve_ids_pipeline()?;
                let chunk = self.chunk(4 * n).min(PIPELINE_CHUNK);
                let mut flags = Vec::with_capacity(4 * m);
                for start in (0..m).step_by(chunk) {
                    let r = start..(start + chunk).min(m);
                    let p = self.submit_ids(pipe, [&vals, &held], simplices, r)?;
                    flags.extend(self.finish(p)?.swap_remove(0));
                }
                flags
            }
        };
        let flags: Vec<u32> = bytemuck::pod_collect_to_vec(&flags);
        Ok(flags
            .iter()
            .map(|&f| match f {
                CROSSED => Some(Status::Crossed),
                OUTSIDE => Some(Status::Outside),
                _ => None,
            })
            .collect())
    }
}
