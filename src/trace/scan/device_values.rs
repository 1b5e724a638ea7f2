//! The exhaustive scan with f's values from a device ([`Scan::device_values`]): the grid
//! holds the device's values with bounds that contain the CPU's values, sign codes admit
//! both signs wherever a bound reaches 0 (so the candidates are a superset of the CPU's),
//! and the device certifies verdicts that hold for every value within the bounds. The CPU
//! evaluates f only at the vertices of the candidates the device found crossed or could not
//! decide, keeps of those exactly its own candidates, and decides them from its own values.
//! So S, its order and its points are the CPU backend's, whatever the device's rounding.
//!
//! [`Scan::device_values`]: crate::trace::Scan::device_values

// `!(a > b)` is meant: a NaN value or bound must give both signs.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use std::collections::HashMap;

use rayon::prelude::*;

use super::candidates::{pass_mask, sign_code};
use super::ScanGrid;
use crate::cpu::batch;
use crate::cpu::certificate::{CROSSED, OUTSIDE};
use crate::cpu::solve::Status;
use crate::error::{Error, Result};
use crate::trace::{Decisions, DeviceValues, TraceContext, TraceStats};

/// The sign code of a vertex whose component values are known within bounds: bit 2c unless
/// component c is certainly > 0, bit 2c + 1 unless it is certainly < 0 (both for an
/// unknown value). Every value within the bounds has a [`sign_code`] inside it.
#[inline]
pub fn bounded_sign_code(values: &[f64], bounds: &[f64]) -> u32 {
    values
        .iter()
        .zip(bounds)
        .enumerate()
        .fold(0, |code, (c, (&v, &e))| {
            code | (!(v - e > 0.0) as u32) << (2 * c) | (!(v + e < 0.0) as u32) << (2 * c + 1)
        })
}

/// The CPU's values of f at the grid vertices it needed so far: output-sensitive (the
/// vertices of candidates the device did not rule out), and the device that rules out the
/// others.
pub(super) struct CpuValues<'a> {
    device: &'a dyn DeviceValues,
    slot: HashMap<u32, u32>,
    values: Vec<f64>,
}

impl<'a> CpuValues<'a> {
    /// None yet, for the scan whose device values come from `device`.
    pub(super) fn new(device: &'a dyn DeviceValues) -> Self {
        CpuValues {
            device,
            slot: HashMap::new(),
            values: Vec::new(),
        }
    }

    /// Evaluates f on the CPU at the vertices of `rows` not held yet; returns how many.
    fn ensure(&mut self, ctx: &TraceContext, grid: &ScanGrid, rows: &[u32]) -> Result<u64> {
        let (d, k) = (ctx.d, ctx.k);
        let mut new: Vec<u32> = rows
            .iter()
            .copied()
            .filter(|v| !self.slot.contains_key(v))
            .collect();
        new.par_sort_unstable();
        new.dedup();
        if new.is_empty() {
            return Ok(0);
        }
        let mut lattice = vec![0i32; new.len() * d];
        lattice
            .par_chunks_mut(d)
            .zip(&new)
            .for_each(|(out, &v)| grid.coords(v as usize, out));
        let first = self.values.len() / k.max(1);
        self.values.resize((first + new.len()) * k, 0.0);
        ctx.oracle
            .values()
            .eval_vertices(ctx.tri, &lattice, &mut self.values[first * k..])?;
        for (i, &v) in new.iter().enumerate() {
            self.slot.insert(v, (first + i) as u32);
        }
        Ok(new.len() as u64)
    }

    /// The vertices held, as lattice coordinates (rows of d), and their values (rows of k).
    pub(super) fn into_lattice(self, grid: &ScanGrid) -> (Vec<i32>, Vec<f64>) {
        let d = grid.dim();
        let mut lattice = vec![0i32; self.slot.len() * d];
        for (&v, &s) in &self.slot {
            grid.coords(
                v as usize,
                &mut lattice[s as usize * d..(s as usize + 1) * d],
            );
        }
        (lattice, self.values)
    }

    fn slot(&self, v: u32) -> u32 {
        self.slot[&v]
    }

    fn code(&self, k: usize, v: u32) -> u32 {
        let s = self.slot(v) as usize;
        sign_code(&self.values[s * k..(s + 1) * k])
    }
}

/// Decides the candidates `rows` of a grid of device values into `status` and `lambda`
/// (the CPU's, from its own values), counting into `stats`.
pub(super) fn decide(
    ctx: &TraceContext,
    grid: &ScanGrid,
    rows: &[u32],
    cpu: &mut CpuValues<'_>,
    stats: &mut TraceStats,
    status: &mut [Status],
    lambda: &mut [f64],
) -> Result<()> {
    let (k, n) = (ctx.k, ctx.k + 1);
    let m = rows.len() / n;
    let mut verdicts = vec![0u32; m];
    cpu.device
        .decide_certified(grid.values(), grid.bounds(), rows, &mut verdicts)?;
    let open: Vec<usize> = (0..m).filter(|&i| verdicts[i] != OUTSIDE).collect();
    let open_rows: Vec<u32> = open
        .iter()
        .flat_map(|&i| rows[i * n..(i + 1) * n].iter().copied())
        .collect();
    stats.cpu_vertex_evaluations += cpu.ensure(ctx, grid, &open_rows)?;
    // The CPU's own candidates: those whose CPU sign codes admit a zero.
    let mask = pass_mask(k);
    let mut kept = Vec::with_capacity(open.len());
    for (o, &i) in open.iter().enumerate() {
        let row = &open_rows[o * n..(o + 1) * n];
        let code = row.iter().fold(0, |c, &v| c | cpu.code(k, v));
        if code & mask == mask {
            kept.push(o);
        } else if verdicts[i] == CROSSED {
            return Err(contradiction(i, "not a candidate"));
        }
    }
    let sub: Vec<u32> = kept
        .iter()
        .flat_map(|&o| open_rows[o * n..(o + 1) * n].iter().map(|&v| cpu.slot(v)))
        .collect();
    let mut st = vec![Status::Outside; kept.len()];
    let mut lam = vec![0.0; kept.len() * n];
    let exact = batch::decide(k, &cpu.values, &sub, &mut st, &mut lam);
    for ((&o, &s), l) in kept.iter().zip(&st).zip(lam.chunks_exact(n)) {
        let i = open[o];
        if verdicts[i] == CROSSED && !s.crossed() {
            return Err(contradiction(i, &format!("{s:?}")));
        }
        status[i] = s;
        if s.crossed() {
            lambda[i * n..(i + 1) * n].copy_from_slice(l);
        }
    }
    // The device's OUTSIDE verdicts stand; the open candidates were decided on the CPU.
    let on_device = (m - open.len()) as u64;
    stats.count_decisions(&status[..m], Decisions { exact, on_device });
    Ok(())
}

/// The error when the CPU contradicts a crossing the device certified: a value bound did
/// not hold, so the device's other verdicts cannot be trusted either.
fn contradiction(i: usize, cpu: &str) -> Error {
    Error::DeviceBound(format!(
        "the device certified candidate {i} of a scan batch as crossed, but the CPU's \
         values make it {cpu}: a bound of the device's values of f does not hold (rerun \
         without device values, and report this as a bug)"
    ))
}
