//! The solve stage (`shaders/solve.wgsl`): the intersection test's (k+1)x(k+1) solves, the
//! twin of the CPU fast path [`Decider::fast_path`](crate::cpu::solve::Decider::fast_path):
//! Gauss-Jordan and the a-posteriori certificate, for every matrix within the rounding of
//! the host's values to the device's precision. A decision batch goes through in pipelined
//! chunks; what the shader does not certify is decided again on the CPU.

use std::ops::Range;
use std::sync::atomic::Ordering;
use std::time::Instant;

use rayon::prelude::*;

use super::device::{add_time, Output, Stage};
use super::GpuOracle;
use crate::cpu::batch;
use crate::cpu::certificate::{Margins, BIG, MAX_CONTRACTION, MAX_N};
use crate::cpu::solve::{filter_verdict, scaled_rows, Status};
use crate::error::{Error, Result};
use crate::expr::certified::DeviceReal;
use crate::gpu::wgsl::{stage_prelude, validate, Precision};
use crate::trace::Decisions;

/// The solve shader, before its prelude.
pub const SOLVE_WGSL: &str = include_str!("../../../shaders/solve.wgsl");
/// Gauss-Jordan inversion, shared by both solve shaders.
pub(super) const GAUSS_JORDAN_WGSL: &str = include_str!("../../../shaders/gauss_jordan.wgsl");
/// The a-posteriori certificate, shared by both solve shaders.
pub(super) const CERTIFY_WGSL: &str = include_str!("../../../shaders/certify.wgsl");
/// Simplices per pipelined chunk of a decision batch.
pub(super) const PIPELINE_CHUNK: usize = 1 << 17;
/// Shader verdicts.
const CROSSED: u32 = 0;
const OUTSIDE: u32 = 1;

/// The solve shader for k-simplices in precision `p`, validated by naga: the certificate
/// with entry bounds that cover the rounding of the host's f64 values to `p`.
pub fn solve_shader(k: usize, p: Precision) -> Result<String> {
    solve_source(k, p, packed_rounding(p), SOLVE_WGSL)
}

/// The entry bounds of the solve shader on packed rows in precision `p`, (unit, tiny): each
/// entry of L lies within unit |l| + tiny of the host's value. f32: |fl(v) - v| <= u |fl(v)|,
/// plus a flushed subnormal (computed in the shader as 2u |v| + 2 MIN_NORMAL, which stays
/// above that after its own rounding). f64: the values arrive exact, but for a device that
/// flushes subnormal inputs.
pub(super) fn packed_rounding(p: Precision) -> (f64, f64) {
    match p {
        Precision::F32 => (
            2.0 * <f32 as DeviceReal>::UNIT,
            2.0 * <f32 as DeviceReal>::MIN_NORMAL,
        ),
        Precision::F64 => (0.0, 2.0 * <f64 as DeviceReal>::MIN_NORMAL),
    }
}

/// A solve shader for k-simplices in precision `p`, validated by naga: the prelude, the
/// entry bounds `(unit, tiny)` as `ROUND_UNIT` and `ROUND_TINY`, Gauss-Jordan, the
/// certificate, then `body`.
pub(super) fn solve_source(
    k: usize,
    p: Precision,
    (unit, tiny): (f64, f64),
    body: &str,
) -> Result<String> {
    let src = format!(
        "{prelude}const ROUND_UNIT: real = {unit};\nconst ROUND_TINY: real = {tiny};\n\
         {GAUSS_JORDAN_WGSL}{CERTIFY_WGSL}{body}",
        prelude = solve_prelude(k, p)?,
        unit = p.literal(unit)?,
        tiny = p.literal(tiny)?,
    );
    validate(&src, p)?;
    Ok(src)
}

/// The constants both solve shaders start with, for k-simplices in precision `p`: `real`,
/// `N`, `NN`, `EPS` and the certificate's margins for any conforming device computing in p
/// ([`Margins::device`]), rounded up.
pub(super) fn solve_prelude(k: usize, p: Precision) -> Result<String> {
    let n = k + 1;
    if n > MAX_N {
        return Err(Error::Gpu(format!(
            "the solve shaders take k <= {} (k = {k})",
            MAX_N - 1
        )));
    }
    let (m, eps) = match p {
        Precision::F32 => (Margins::device::<f32>(n), f32::EPSILON as f64),
        Precision::F64 => (Margins::device::<f64>(n), f64::EPSILON),
    };
    let up = |v: f64| match p {
        Precision::F32 => p.literal(f32::of_up(v) as f64),
        Precision::F64 => p.literal(v),
    };
    Ok(format!(
        "{stage}alias real = {ty};\nconst N: u32 = {n}u;\nconst NN: u32 = {nn}u;\nconst EPS: real = {eps};\n\
         const GAMMA: real = {gamma};\nconst GROW: real = {grow};\nconst TINY: real = {tiny};\n\
         const MAX_CONTRACTION: real = {maxc};\nconst BIG: real = {big};\n",
        stage = stage_prelude(),
        ty = p.ty(),
        nn = n * n,
        eps = p.literal(eps)?,
        gamma = up(m.gamma)?,
        grow = up(m.grow)?,
        tiny = up(m.tiny)?,
        maxc = p.literal(MAX_CONTRACTION)?,
        big = p.literal(BIG)?,
    ))
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
        for (i, part) in packed.chunks(chunk * per).enumerate() {
            let c = part.len() / per;
            if let Some(seed) = self.emulated() {
                let res = self.emulated_solve(seed, &self.encode_reals(part), i * chunk);
                lam.extend(self.decode_reals(&res[0]));
                flags.extend(bytemuck::pod_collect_to_vec::<u8, u32>(&res[1]));
                continue;
            }
            let input = self.encode_reals(part);
            self.solve_chunk(Stage::Solve, &self.solve, &input, c, &mut flags, &mut lam)?;
        }
        Ok((flags, lam))
    }

    /// Runs a solve stage (`Solve` or `SolveCertified`) on the `c` simplices encoded in
    /// `input`, waits, and appends their verdicts and lambdas.
    pub(super) fn solve_chunk(
        &self,
        stage: Stage,
        pipeline: &wgpu::ComputePipeline,
        input: &[u8],
        c: usize,
        flags: &mut Vec<u32>,
        lam: &mut Vec<f64>,
    ) -> Result<()> {
        let outputs = [
            Output::read(c * (self.k + 1) * self.real_size()),
            Output::read(c * 4),
        ];
        let pending = self.submit(stage, pipeline, input, c, &outputs, false)?;
        let res = self.finish(pending)?;
        lam.extend(self.decode_reals(&res[0]));
        flags.extend(bytemuck::pod_collect_to_vec::<u8, u32>(&res[1]));
        Ok(())
    }

    #[doc(hidden)] // a stage alone, for tests and benchmarks
    /// The shader stage alone, the twin of [`Decider::fast_path`](crate::cpu::solve::Decider::fast_path): for each simplex (rows of
    /// vertex indices into `values`, as in [`Decide::decide`](crate::trace::Decide::decide)), the shader's verdict as the
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
    /// Decides a batch: while the device solves chunk c, the host packs chunk c + 1 and
    /// settles chunk c - 1 (keeps certified verdicts, re-decides the rest on the CPU).
    pub(super) fn decide_pipelined(
        &self,
        values: &[f64],
        simplices: &[u32],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> Result<Decisions> {
        let n = self.k + 1;
        let rs = self.real_size();
        let chunk = self.chunk(rs * self.k * n).min(PIPELINE_CHUNK);
        let ranges: Vec<Range<usize>> = (0..status.len())
            .step_by(chunk)
            .map(|s| s..(s + chunk).min(status.len()))
            .collect();
        // A pipeline: while the device solves chunk c, the host packs chunk c + 1 and
        // settles chunk c - 1 (keeps certified verdicts, re-decides the rest on the CPU).
        let mut decided = Decisions::default();
        let mut next = ranges
            .first()
            .map(|r| self.prepare(values, simplices, r.clone(), status));
        let mut solved: Option<(Vec<usize>, Vec<Vec<u8>>)> = None;
        for c in 0..ranges.len() {
            let (sent, bytes) = next
                .take()
                .expect("each chunk is prepared before it is sent");
            // Only the verdicts come back: settling takes every lambda from the CPU.
            let outputs = [
                Output::unread(sent.len() * n * rs),
                Output::read(sent.len() * 4),
            ];
            let emulated = self
                .emulated()
                .filter(|_| !sent.is_empty())
                .map(|seed| self.emulated_solve(seed, &bytes, ranges[c].start));
            let mut pending = if sent.is_empty() || emulated.is_some() {
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
            let mut early = emulated;
            if early.is_none() && self.phased.load(Ordering::Relaxed) {
                early = pending.take().map(|p| self.finish(p)).transpose()?;
            }
            if let Some(r) = ranges.get(c + 1) {
                next = Some(self.prepare(values, simplices, r.clone(), status));
            }
            if let Some((prev, res)) = solved.take() {
                decided += self.settle(values, simplices, &prev, &res[1], status, lambda)?;
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
            decided += self.settle(values, simplices, &prev, &res[1], status, lambda)?;
        }
        Ok(decided)
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

    /// Host side after the shader, given its verdicts on `sent` (`flags`, 4 bytes each):
    /// keeps the certified misses and decides the rest of `sent` on the CPU, in one gathered
    /// batch. The device's crossings are decided there too, so that every lambda (and so
    /// every point) is the CPU's, whatever the device's rounding; a crossing the CPU rejects
    /// is counted in [`GpuStats::contradicted`](super::GpuStats::contradicted). Returns the
    /// count of exact decisions and of those the device took.
    pub(super) fn settle(
        &self,
        values: &[f64],
        simplices: &[u32],
        sent: &[usize],
        flags: &[u8],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> Result<Decisions> {
        let started = Instant::now();
        let n = self.k + 1;
        let flags: Vec<u32> = bytemuck::pod_collect_to_vec(flags);
        let mut claimed = Vec::new();
        let recheck: Vec<usize> = sent
            .iter()
            .enumerate()
            .filter_map(|(j, &i)| match flags[j] {
                OUTSIDE => {
                    status[i] = Status::Outside;
                    None
                }
                CROSSED => {
                    claimed.push(i);
                    Some(i)
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
        let exact = batch::decide(self.k, values, &sub, &mut sub_status, &mut sub_lambda);
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
        let contradicted = claimed.iter().filter(|&&i| !status[i].crossed()).count();
        self.contradicted
            .fetch_add(contradicted as u64, Ordering::Relaxed);
        add_time(&self.host_ns, started);
        Ok(Decisions {
            exact,
            on_device: (sent.len() - recheck.len()) as u64,
        })
    }
}
