//! The certified solve stage (`shaders/solve_certified.wgsl`): verdicts proven for every
//! labelling matrix within the bounds of the device's values; the twin of
//! [`CertifiedSolver`](crate::cpu::certificate::CertifiedSolver).

use std::time::Instant;

use rayon::prelude::*;

use super::device::{add_time, pipeline, Stage};
use super::solve::{solve_prelude, CERTIFY_WGSL, GAUSS_JORDAN_WGSL};
use super::GpuOracle;
use crate::cpu::certificate::{pack_rows, UNCERTAIN};
use crate::error::Result;
use crate::gpu::wgsl::{validate, Precision};

/// The certified solve shader, before its prelude.
pub const SOLVE_CERTIFIED_WGSL: &str = include_str!("../../../shaders/solve_certified.wgsl");

/// The certified solve shader for k-simplices in precision `p`, validated by naga; its
/// margins are `cpu::certificate::Margins::device` for p, rounded up.
pub fn solve_certified_shader(k: usize, p: Precision) -> Result<String> {
    let src = format!(
        "{prelude}{GAUSS_JORDAN_WGSL}{CERTIFY_WGSL}{SOLVE_CERTIFIED_WGSL}",
        prelude = solve_prelude(k, p)?
    );
    validate(&src, p)?;
    Ok(src)
}

impl GpuOracle<'_> {
    /// The certified solve's pipeline, built the first time it is asked for.
    fn solve_certified_pipeline(&self) -> Result<&wgpu::ComputePipeline> {
        if let Some(p) = self.solve_certified.get() {
            return Ok(p);
        }
        let built = pipeline(
            &self.gpu,
            &solve_certified_shader(self.k, self.precision)?,
            "solve_certified",
            self.cancel(),
        )?;
        Ok(self.solve_certified.get_or_init(|| built))
    }

    #[doc(hidden)] // a stage alone, for tests
    /// The certified solve shader alone on packed rows ([`pack_rows`]: k rows of k + 1
    /// values and the same of bounds per simplex): per simplex a verdict
    /// ([`CROSSED`](crate::cpu::certificate::CROSSED), `OUTSIDE` or `UNCERTAIN`) and x.
    pub fn solve_certified_stage(&self, l: &[f64], e: &[f64]) -> Result<(Vec<u32>, Vec<f64>)> {
        let (k, n) = (self.k, self.k + 1);
        let per = k * n;
        let m = l.len() / per.max(1);
        if let Some(seed) = self.emulated() {
            return Ok(self.emulated_solve_certified(seed, l, e));
        }
        let pipe = self.solve_certified_pipeline()?;
        let rs = self.real_size();
        let chunk = self.chunk(2 * rs * per);
        let (mut flags, mut lam) = (Vec::with_capacity(m), Vec::with_capacity(m * n));
        for start in (0..m).step_by(chunk) {
            let end = (start + chunk).min(m);
            let c = end - start;
            let packing = Instant::now();
            let mut input = Vec::with_capacity(2 * c * per);
            for i in start..end {
                input.extend_from_slice(&l[i * per..(i + 1) * per]);
                input.extend_from_slice(&e[i * per..(i + 1) * per]);
            }
            let input = self.encode_reals(&input);
            add_time(&self.host_ns, packing);
            self.solve_chunk(Stage::SolveCertified, pipe, &input, c, &mut flags, &mut lam)?;
        }
        Ok((flags, lam))
    }

    /// Certified verdicts on k-simplices whose vertex values (`values`, rows of k) are known
    /// within `bounds` (the same shape; infinite: unknown): per row of `simplices` (k + 1
    /// vertex indices), `CROSSED` or `OUTSIDE` when that holds for every value within the
    /// bounds, else `UNCERTAIN`.
    pub fn certified_verdicts(
        &self,
        values: &[f64],
        bounds: &[f64],
        simplices: &[u32],
    ) -> Result<Vec<u32>> {
        let packing = Instant::now();
        let (k, n) = (self.k, self.k + 1);
        let per = k * n;
        let m = simplices.len() / n;
        let mut l = vec![0.0; m * per];
        let mut e = vec![0.0; m * per];
        let packed: Vec<bool> = l
            .par_chunks_mut(per)
            .zip(e.par_chunks_mut(per))
            .zip(simplices.par_chunks(n))
            .map(|((l, e), idx)| {
                let at = |j: usize, c: usize| idx[j] as usize * k + c;
                let (val, bnd) = (|j, c| values[at(j, c)], |j, c| bounds[at(j, c)]);
                match self.precision {
                    Precision::F32 => pack_rows::<f32>(k, val, bnd, l, e),
                    Precision::F64 => pack_rows::<f64>(k, val, bnd, l, e),
                }
            })
            .collect();
        let sent: Vec<usize> = (0..m).filter(|&i| packed[i]).collect();
        let gather = |src: &[f64]| -> Vec<f64> {
            sent.iter()
                .flat_map(|&i| src[i * per..(i + 1) * per].iter().copied())
                .collect()
        };
        let (l, e) = (gather(&l), gather(&e));
        add_time(&self.host_ns, packing);
        let (flags, _) = self.solve_certified_stage(&l, &e)?;
        let mut out = vec![UNCERTAIN; m];
        for (&i, f) in sent.iter().zip(flags) {
            out[i] = f;
        }
        Ok(out)
    }
}
