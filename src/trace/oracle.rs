//! The intersection oracle, split by job so that tracing and the exhaustive scan run the same
//! on every backend: values of f at lattice vertices ([`Evaluate`]), decisions on k-simplices
//! given as rows of vertex indices ([`Decide`]), and the scan's candidates and device values
//! ([`Scan`], [`DeviceValues`]); an [`Oracle`] names the part it chose for each.

use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};

use super::ScanGrid;
use crate::cpu::batch;
use crate::cpu::solve::Status;
use crate::error::Result;
use crate::expr::ImplicitFunction;
use crate::trace::scan::candidates::{self, Candidates};
use crate::trace::scan::tiles::{twin_scan, TileFound, TilePlan};
use crate::triangulation::Triangulation;

/// How a batch of decisions ([`Decide::decide`]) was reached.
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

/// Names an array of vertex values that, between calls of [`Decide::decide_growing`] with
/// the same name, only grows at its end, its earlier rows unchanged (a trace's vertex cache):
/// an oracle may keep the rows it has seen, a device in its memory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GrowingValues(u64);

impl GrowingValues {
    /// A name no other array of this process has.
    pub fn new() -> Self {
        static NEXT: AtomicU64 = AtomicU64::new(1);
        GrowingValues(NEXT.fetch_add(1, Ordering::Relaxed))
    }
}

impl Default for GrowingValues {
    fn default() -> Self {
        Self::new()
    }
}

/// f at lattice vertices, the values every decision is made from.
pub trait Evaluate: Sync {
    /// f at lattice vertices: `lattice` holds n rows of d, `values` gets n rows of k.
    fn eval_vertices(&self, tri: &Triangulation, lattice: &[i32], values: &mut [f64])
        -> Result<()>;
}

/// Decisions on k-simplices given as rows of vertex indices.
pub trait Decide: Sync {
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

    /// [`Decide::decide`] on `values` named `log`: between calls with the same name they
    /// only grow at their end ([`GrowingValues`]), so the oracle may keep the rows it has
    /// seen (the GPU's keeps them on the device and uploads vertex ids, for k >= 2). The
    /// default decides as `decide` does.
    fn decide_growing(
        &self,
        log: GrowingValues,
        values: &[f64],
        simplices: &[u32],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> Result<Decisions> {
        let _ = log;
        self.decide(values, simplices, status, lambda)
    }

    /// Frontier simplices per slice of a trace level, for decisions that run off the CPU (a
    /// device): the level is then named and decided slice by slice, naming slice c + 1 on
    /// the CPU while slice c is decided. `None` (the default) decides each level as one
    /// batch. The traced sample does not depend on it.
    fn level_slice(&self) -> Option<usize> {
        None
    }
}

/// The exhaustive scan's own work: its candidates and, where chosen, f's values on the
/// device.
pub trait Scan: Sync {
    /// The candidate k-simplices in the cubes based at the grid vertices `cubes`, in order
    /// of base, then chain. Every backend must give exactly
    /// `trace::scan::candidates::candidates`, which is the default.
    fn candidates(&self, grid: &ScanGrid, cubes: Range<usize>) -> Result<Candidates> {
        Ok(candidates::candidates(grid, cubes))
    }

    /// Certified values and verdicts, where the scan takes f's values from the device and
    /// evaluates f on the CPU only where the device cannot decide; `None` (the default)
    /// evaluates f on the CPU everywhere.
    fn device_values(&self) -> Option<&dyn DeviceValues> {
        None
    }
}

/// The scan's values of f from a device, known within bounds, and verdicts from them.
pub trait DeviceValues: Sync {
    /// Certified values of f at lattice vertices: `lattice` holds n rows of d, `out` gets n
    /// rows of k pairs (value, bound) such that the value [`Evaluate::eval_vertices`] gives
    /// lies within the bound of the value (an infinite bound: unknown).
    fn eval_certified(&self, tri: &Triangulation, lattice: &[i32], out: &mut [f64]) -> Result<()>;

    /// Certified verdicts on k-simplices whose vertex values are known only within bounds
    /// (`values` and `bounds`: rows of k; infinite bounds unknown), per row of `simplices`
    /// (k + 1 vertex indices): [`CROSSED`](super::CROSSED) or [`OUTSIDE`](super::OUTSIDE)
    /// where that verdict holds for all values within the bounds, else
    /// [`UNCERTAIN`](super::UNCERTAIN).
    fn decide_certified(
        &self,
        values: &[f64],
        bounds: &[f64],
        simplices: &[u32],
        verdicts: &mut [u32],
    ) -> Result<()>;

    /// The exhaustive scan resident on the device ([`crate::trace::scan::tiles`]): per tile
    /// of `plan`, in order, the candidates the device could not prove outside, handed to
    /// `each(t, found)` (while the device works on the next tiles) until it returns false.
    /// By default each tile runs through the twin ([`twin_tile`], [`twin_scan`]), on
    /// [`eval_certified`](Self::eval_certified) and
    /// [`decide_certified`](Self::decide_certified).
    ///
    /// [`twin_tile`]: crate::trace::scan::tiles::twin_tile
    /// [`twin_scan`]: crate::trace::scan::tiles::twin_scan
    fn scan_tiles(
        &self,
        tri: &Triangulation,
        plan: &TilePlan,
        each: &mut dyn FnMut(usize, TileFound) -> Result<bool>,
    ) -> Result<()> {
        twin_scan(self, tri, plan, each)
    }
}

/// A backend: one part per job, each chosen when the backend is made. Tracing and the
/// exhaustive scan run the same on every backend.
pub trait Oracle: Sync {
    /// A name for reports (`cpu`, or `gpu: ` and the adapter name).
    fn name(&self) -> String;

    /// What evaluates f at lattice vertices.
    fn values(&self) -> &dyn Evaluate;

    /// What decides k-simplices.
    fn decisions(&self) -> &dyn Decide;

    /// What finds the scan's candidates (and its values on a device); the CPU's, by
    /// default.
    fn scans(&self) -> &dyn Scan {
        &CpuScan
    }
}

/// The CPU's scan: candidates enumerated on the CPU, f evaluated there.
pub struct CpuScan;

impl Scan for CpuScan {}

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

    fn values(&self) -> &dyn Evaluate {
        self
    }

    fn decisions(&self) -> &dyn Decide {
        self
    }
}

impl Evaluate for CpuOracle<'_> {
    fn eval_vertices(
        &self,
        tri: &Triangulation,
        lattice: &[i32],
        values: &mut [f64],
    ) -> Result<()> {
        batch::eval_vertices(self.f, tri, lattice, values);
        Ok(())
    }
}

impl Decide for CpuOracle<'_> {
    fn decide(
        &self,
        values: &[f64],
        simplices: &[u32],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> Result<Decisions> {
        let exact = batch::decide(self.f.codim(), values, simplices, status, lambda);
        Ok(Decisions {
            exact,
            on_device: 0,
        })
    }
}
