//! The intersection oracle behind one trait, so that tracing and the exhaustive scan run the
//! same on every backend: values of f at lattice vertices, then decisions on k-simplices given
//! as rows of vertex indices.

use std::ops::Range;

use rayon::prelude::*;

use super::ScanGrid;
use crate::cpu::solve::{Decider, Status};
use crate::error::Result;
use crate::expr::ImplicitFunction;
use crate::trace::scan::candidates::{self, Candidates};
use crate::triangulation::Triangulation;

/// Most vertices per evaluation chunk, and simplices per decision chunk.
const CHUNK: usize = 2048;
/// Fewest vertices or simplices per chunk.
const MIN_CHUNK: usize = 64;
/// Most vertices per call of an f whose calls are serial ([`ImplicitFunction::serial`]).
const SERIAL_BATCH: usize = 1 << 16;

/// Items per parallel chunk for `len` items: about four chunks per thread, within
/// `MIN_CHUNK..=CHUNK`.
fn chunk_for(len: usize) -> usize {
    len.div_ceil(4 * rayon::current_num_threads())
        .clamp(MIN_CHUNK, CHUNK)
}

/// How a batch of decisions ([`Oracle::decide`]) was reached.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Decisions {
    /// Decisions that took the exact rational path.
    pub exact: u64,
    /// Decisions a device certified and the CPU did not redo.
    pub on_device: u64,
}

impl std::ops::AddAssign for Decisions {
    fn add_assign(&mut self, o: Decisions) {
        self.exact += o.exact;
        self.on_device += o.on_device;
    }
}

/// A backend that evaluates f and decides k-simplices, one large batch per call.
pub trait Oracle: Sync {
    /// A name for reports (`cpu`, or `gpu: ` and the adapter name).
    fn name(&self) -> String;

    /// f at lattice vertices: `lattice` holds n rows of d, `values` gets n rows of k.
    fn eval_vertices(&self, tri: &Triangulation, lattice: &[i32], values: &mut [f64])
        -> Result<()>;

    /// Decides n k-simplices: `simplices` holds n rows of k+1 indices of rows of `values`.
    /// Writes a status per simplex and, for crossed ones, lambda (n rows of k+1). Returns how
    /// many decisions needed the exact path and how many the device took.
    fn decide(
        &self,
        values: &[f64],
        simplices: &[u32],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> Result<Decisions>;

    /// Frontier simplices per slice of a trace level, for an oracle whose decisions run off
    /// the CPU (a device): the level is then named and decided slice by slice, naming slice
    /// c + 1 on the CPU while slice c is decided. `None` (the default) decides each level as
    /// one batch. The traced sample does not depend on it.
    fn level_slice(&self) -> Option<usize> {
        None
    }

    /// The exhaustive scan's candidate k-simplices in the cubes based at the grid vertices
    /// `cubes`, in order of base, then chain. Every backend must give exactly
    /// `trace::scan::candidates::candidates`, which is the default.
    fn scan_candidates(&self, grid: &ScanGrid, cubes: Range<usize>) -> Result<Candidates> {
        Ok(candidates::candidates(grid, cubes))
    }

    /// Whether the exhaustive scan takes f's values from the device with bounds
    /// ([`Oracle::eval_certified`], [`Oracle::decide_certified`]) and evaluates f on the CPU
    /// only where the device cannot decide. False, the default, for the CPU.
    fn device_values(&self) -> bool {
        false
    }

    /// Certified values of f at lattice vertices: `lattice` holds n rows of d, `out` gets n
    /// rows of k pairs (value, bound) such that the value of [`Oracle::eval_vertices`] lies
    /// within the bound of the value (an infinite bound: unknown). Only where
    /// [`Oracle::device_values`]; the default says so.
    fn eval_certified(&self, tri: &Triangulation, lattice: &[i32], out: &mut [f64]) -> Result<()> {
        let _ = (tri, lattice, out);
        Err(crate::error::Error::Trace(format!(
            "the {} oracle has no certified values",
            self.name()
        )))
    }

    /// Certified verdicts on k-simplices whose vertex values are known only within bounds
    /// (`values` and `bounds`: rows of k; infinite bounds unknown), per row of `simplices`
    /// (k + 1 vertex indices): [`CROSSED`](super::CROSSED) or [`OUTSIDE`](super::OUTSIDE)
    /// where that verdict holds for all values within the bounds, else
    /// [`UNCERTAIN`](super::UNCERTAIN), the default.
    fn decide_certified(
        &self,
        values: &[f64],
        bounds: &[f64],
        simplices: &[u32],
        verdicts: &mut [u32],
    ) -> Result<()> {
        let _ = (values, bounds, simplices);
        verdicts.fill(crate::cpu::certificate::UNCERTAIN);
        Ok(())
    }
}

/// The reference oracle: f64 on the CPU, parallel with rayon.
pub struct CpuOracle<'f> {
    f: &'f dyn ImplicitFunction,
}

impl<'f> CpuOracle<'f> {
    /// The CPU oracle for `f`.
    pub fn new(f: &'f dyn ImplicitFunction) -> Self {
        CpuOracle { f }
    }
}

impl Oracle for CpuOracle<'_> {
    fn name(&self) -> String {
        "cpu".into()
    }

    fn eval_vertices(
        &self,
        tri: &Triangulation,
        lattice: &[i32],
        values: &mut [f64],
    ) -> Result<()> {
        let (d, k) = (tri.dim(), self.f.codim());
        if self.f.serial() {
            // One call per SERIAL_BATCH vertices, the coordinates computed in parallel.
            let mut x = vec![0.0; lattice.len()];
            x.par_chunks_mut(CHUNK * d)
                .zip(lattice.par_chunks(CHUNK * d))
                .for_each(|(p, lat)| {
                    for (v, p) in lat.chunks_exact(d).zip(p.chunks_exact_mut(d)) {
                        tri.vertex_coords(v, p);
                    }
                });
            for (p, out) in x
                .chunks(SERIAL_BATCH * d)
                .zip(values.chunks_mut(SERIAL_BATCH * k))
            {
                self.f.eval_batch(p, out);
            }
            return Ok(());
        }
        let chunk = chunk_for(lattice.len() / d);
        lattice
            .par_chunks(chunk * d)
            .zip(values.par_chunks_mut(chunk * k))
            .for_each_init(Vec::new, |x, (lat, out)| {
                x.resize(lat.len(), 0.0);
                for (v, p) in lat.chunks_exact(d).zip(x.chunks_exact_mut(d)) {
                    tri.vertex_coords(v, p);
                }
                self.f.eval_batch(x, out);
            });
        Ok(())
    }

    fn decide(
        &self,
        values: &[f64],
        simplices: &[u32],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> Result<Decisions> {
        let exact = decide_on_cpu(self.f.codim(), values, simplices, status, lambda);
        Ok(Decisions {
            exact,
            on_device: 0,
        })
    }
}

/// The CPU's decisions ([`Decider`], in parallel) of the k-simplices `simplices` (rows of k + 1
/// indices of rows of `values`): statuses, lambda of the crossed ones, and the count of
/// exact decisions, as [`Oracle::decide`] gives them.
pub(crate) fn decide_on_cpu(
    k: usize,
    values: &[f64],
    simplices: &[u32],
    status: &mut [Status],
    lambda: &mut [f64],
) -> u64 {
    let n = k + 1;
    let chunk = chunk_for(status.len());
    let exact = simplices
        .par_chunks(chunk * n)
        .zip(status.par_chunks_mut(chunk))
        .zip(lambda.par_chunks_mut(chunk * n))
        .map_init(
            || (Decider::new(k), vec![0.0; n * k]),
            |(decider, local), ((idx, st), lam)| {
                let mut exact = 0;
                for ((row, s), l) in idx
                    .chunks_exact(n)
                    .zip(st.iter_mut())
                    .zip(lam.chunks_exact_mut(n))
                {
                    for (j, &v) in row.iter().enumerate() {
                        let v = v as usize;
                        local[j * k..(j + 1) * k].copy_from_slice(&values[v * k..(v + 1) * k]);
                    }
                    let dec = decider.decide(local, l);
                    *s = dec.status;
                    exact += dec.exact as u64;
                }
                exact
            },
        )
        .sum();
    exact
}
