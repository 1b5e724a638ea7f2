//! The test hook of [`GpuOracle::emulate_device`]: the floating-point stages (the solve and
//! the solve from vertex ids, the certified solve, the certified values) computed on the CPU by their twins in the
//! arithmetic of an emulated conforming device ([`crate::emulate`]), on the very inputs the
//! shaders would get; the host code around them runs unchanged. A simplex (or a batch of
//! vertices) draws its rounding from a stream named by the seed and its index, so the
//! results do not depend on threads.

use std::ops::Range;

use rayon::prelude::*;

use super::solve::packed_rounding;
use super::solve_ids::{held, ids_rounding, pow2_inverse_f32};
use super::GpuOracle;
use crate::cpu::certificate::{
    certify, gauss_jordan, CertifiedSolver, Margins, OUTSIDE, UNCERTAIN,
};
use crate::cpu::eval_certified::eval_lattice_certified;
use crate::emulate::{self, Emu32, Emu64};
use crate::error::{Error, Result};
use crate::expr::certified::DeviceReal;
use crate::gpu::wgsl::Precision;
use crate::triangulation::Triangulation;

/// The stream of simplex or batch `i` under `seed`.
fn stream(seed: u64, i: u64) -> u64 {
    let mut z = seed ^ i.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z ^ (z >> 31)
}

/// `shaders/solve.wgsl` for one simplex in R: rows 1..n of L from `rows`, the entry bounds
/// the shader computes (`unit` |l| + `tiny`), Gauss-Jordan, the certificate.
fn solve_one<R: DeviceReal>(
    n: usize,
    rows: &[f64],
    unit: f64,
    tiny: f64,
    lambda: &mut [f64],
) -> u32 {
    let rows: Vec<R> = rows.iter().map(|&v| R::of(v)).collect();
    solve_rows(n, &rows, unit, tiny, lambda)
}

/// `shaders/solve_ids.wgsl` for one simplex in R, from the values of its n vertices as the
/// host keeps them for the device (`vals`: k per vertex, every one held): the sign filter,
/// each row scaled on the device by the shader's power of two, then as `solve_one`.
fn solve_ids_one<R: DeviceReal>(k: usize, vals: &[f64], unit: f64, tiny: f64) -> u32 {
    let n = k + 1;
    let at = |j: usize, c: usize| R::of(vals[j * k + c]);
    let mut rows = vec![R::of(0.0); k * n];
    for c in 0..k {
        let (mut big, mut pos, mut neg) = (0.0f64, 0, 0);
        for j in 0..n {
            // Held values are normal or 0: compared and maximised exactly.
            let x = at(j, c).wide();
            big = big.max(x.abs());
            pos += usize::from(x > 0.0);
            neg += usize::from(x < 0.0);
        }
        if pos == n || neg == n {
            return OUTSIDE;
        }
        let scale = R::of(pow2_inverse_f32(big));
        for j in 0..n {
            rows[c * n + j] = at(j, c).mul(scale);
        }
    }
    solve_rows(n, &rows, unit, tiny, &mut vec![0.0; n])
}

/// The solve shaders' common end in R, on rows 1..n of L already on the device.
fn solve_rows<R: DeviceReal>(
    n: usize,
    rows: &[R],
    unit: f64,
    tiny: f64,
    lambda: &mut [f64],
) -> u32 {
    let (mut l, mut e) = (vec![R::of(1.0); n * n], vec![R::of(0.0); n * n]);
    for (t, &v) in rows.iter().enumerate() {
        l[n + t] = v;
        e[n + t] = R::of(unit).mul(v.abs()).add(R::of(tiny));
    }
    let (mut a, mut inv) = (l.clone(), vec![R::of(0.0); n * n]);
    if !gauss_jordan(n, &mut a, &mut inv) {
        lambda.fill(0.0);
        return UNCERTAIN;
    }
    for i in 0..n {
        lambda[i] = inv[i * n].wide();
    }
    certify(n, &l, &e, &inv, &Margins::device::<R>(n))
}

/// The certified solve for one simplex in R.
fn solve_certified_one<R: DeviceReal>(k: usize, l: &[f64], e: &[f64], lambda: &mut [f64]) -> u32 {
    let n = k + 1;
    let (mut lr, mut er) = (vec![R::of(1.0); n * n], vec![R::of(0.0); n * n]);
    for t in 0..k * n {
        lr[n + t] = R::of(l[t]);
        er[n + t] = R::of(e[t]);
    }
    let mut x = vec![R::of(0.0); n];
    let flag = CertifiedSolver::<R>::new(k).solve(&lr, &er, &mut x);
    for (o, xi) in lambda.iter_mut().zip(x) {
        *o = xi.wide();
    }
    flag
}

impl GpuOracle<'_> {
    /// The seed of [`GpuOracle::emulate_device`], if it is on.
    pub(super) fn emulated(&self) -> Option<u64> {
        let s = self.emulate.load(std::sync::atomic::Ordering::Relaxed);
        (s != 0).then_some(s)
    }

    /// The solve stage on packed rows as the device receives them (`bytes`, k rows of k + 1
    /// per simplex), the first of them simplex `first` of the batch: the shader's outputs,
    /// lambda then flags.
    pub(super) fn emulated_solve(&self, seed: u64, bytes: &[u8], first: usize) -> Vec<Vec<u8>> {
        let (k, n) = (self.k, self.k + 1);
        let rows = self.decode_reals(bytes);
        let m = rows.len() / (k * n).max(1);
        let mut lambda = vec![0.0; m * n];
        let mut flags = vec![UNCERTAIN; m];
        // The shader's entry bounds: the rounding of the host's values to f32, or flushed
        // subnormals alone in f64.
        let (unit, tiny) = packed_rounding(self.precision);
        flags
            .par_iter_mut()
            .zip(lambda.par_chunks_mut(n))
            .zip(rows.par_chunks(k * n))
            .enumerate()
            .for_each(|(i, ((f, lam), r))| {
                emulate::seed(stream(seed, (first + i) as u64));
                *f = match self.precision {
                    Precision::F32 => solve_one::<Emu32>(n, r, unit, tiny, lam),
                    Precision::F64 => solve_one::<Emu64>(n, r, unit, tiny, lam),
                };
            });
        vec![
            self.encode_reals(&lambda),
            bytemuck::cast_slice(&flags).to_vec(),
        ]
    }

    /// The solve stage from vertex ids on simplices `range` of `simplices` (rows of n
    /// indices into `values`, rows of k): the shader's flags. A simplex with a vertex the
    /// device does not hold ([`held`]) is uncertain, as the shader leaves it.
    pub(super) fn emulated_solve_ids(
        &self,
        seed: u64,
        values: &[f64],
        simplices: &[u32],
        range: Range<usize>,
    ) -> Vec<u8> {
        let (k, n, p) = (self.k, self.k + 1, self.precision);
        let (unit, tiny) = ids_rounding(p);
        let mut flags = vec![UNCERTAIN; range.len()];
        flags.par_iter_mut().enumerate().for_each(|(i, f)| {
            let s = range.start + i;
            emulate::seed(stream(seed, s as u64));
            let mut vals = Vec::with_capacity(k * n);
            for &v in &simplices[s * n..(s + 1) * n] {
                let row = &values[v as usize * k..(v as usize + 1) * k];
                if !row.iter().all(|&x| held(x, p)) {
                    return;
                }
                vals.extend_from_slice(row);
            }
            *f = match p {
                Precision::F32 => solve_ids_one::<Emu32>(k, &vals, unit, tiny),
                Precision::F64 => solve_ids_one::<Emu64>(k, &vals, unit, tiny),
            };
        });
        bytemuck::cast_slice(&flags).to_vec()
    }

    /// The certified solve stage on packed rows and bounds: flags and x.
    pub(super) fn emulated_solve_certified(
        &self,
        seed: u64,
        l: &[f64],
        e: &[f64],
    ) -> (Vec<u32>, Vec<f64>) {
        let (k, n) = (self.k, self.k + 1);
        let per = k * n;
        let (l, e) = (
            self.decode_reals(&self.encode_reals(l)),
            self.decode_reals(&self.encode_reals(e)),
        );
        let m = l.len() / per.max(1);
        let mut lambda = vec![0.0; m * n];
        let mut flags = vec![UNCERTAIN; m];
        flags
            .par_iter_mut()
            .zip(lambda.par_chunks_mut(n))
            .enumerate()
            .for_each(|(i, (f, lam))| {
                emulate::seed(stream(seed, i as u64));
                let (li, ei) = (&l[i * per..(i + 1) * per], &e[i * per..(i + 1) * per]);
                *f = match self.precision {
                    Precision::F32 => solve_certified_one::<Emu32>(k, li, ei, lam),
                    Precision::F64 => solve_certified_one::<Emu64>(k, li, ei, lam),
                };
            });
        (flags, lambda)
    }

    /// The certified vertex stage: rows of k pairs (value, bound).
    pub(super) fn emulated_certified(
        &self,
        seed: u64,
        tri: &Triangulation,
        lattice: &[i32],
    ) -> Result<Vec<f64>> {
        let Some(system) = self.f.system() else {
            return Err(Error::Gpu(
                "the GPU evaluates only functions written in the equation language".into(),
            ));
        };
        let (a, b) = tri.affine_map();
        let acc = self.precision.accuracy();
        let d = tri.dim().max(1);
        emulate::seed(stream(
            seed,
            lattice.first().map_or(0, |&u| u as u64) ^ (lattice.len() / d) as u64,
        ));
        let pairs = match self.precision {
            Precision::F32 => {
                eval_lattice_certified::<Emu32>(system.values(), &acc, &a, &b, lattice)
            }
            Precision::F64 => {
                eval_lattice_certified::<Emu64>(system.values(), &acc, &a, &b, lattice)
            }
        };
        Ok(pairs.into_iter().flatten().collect())
    }
}
