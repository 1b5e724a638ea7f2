//! Measurements behind `isomesh bench` and `cargo bench`: the intersection oracle alone on
//! the same random batches for every backend, and whole traces of the reference cases of
//! the C++ library (GUDHI's Coxeter_triangulation, one thread, on a 2-core machine).

use std::time::Instant;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::cpu::decide::Status;
use crate::error::Result;
use crate::expr::{preset, ClosureFunction, Problem};
use crate::trace::{trace, Oracle, Sample, TraceOptions};

/// A reference case: a preset at an edge length, and what the C++ library does with it.
#[derive(Clone, Copy, Debug)]
pub struct ReferenceCase {
    /// What it is, for tables.
    pub label: &'static str,
    /// A short name, for plots.
    pub short: &'static str,
    /// The preset.
    pub preset: &'static str,
    /// Preset parameters.
    pub params: &'static [(&'static str, f64)],
    /// Longest edge of a d-simplex.
    pub edge: f64,
    /// Output simplices of the C++ library.
    pub simplices: u64,
    /// Its time in seconds.
    pub seconds: f64,
}

/// The C++ library's figures, from the tracing issue.
pub const REFERENCE_CASES: &[ReferenceCase] = &[
    ReferenceCase {
        label: "S^2 in R^3",
        short: "S2/R3",
        preset: "sphere",
        params: &[],
        edge: 0.0707,
        simplices: 16_240,
        seconds: 0.52,
    },
    ReferenceCase {
        label: "chair",
        short: "chair",
        preset: "chair",
        params: &[],
        edge: 0.0707,
        simplices: 11_768,
        seconds: 0.34,
    },
    ReferenceCase {
        label: "flat torus in R^4",
        short: "T2/R4",
        preset: "flat-torus",
        params: &[],
        edge: 0.0775,
        simplices: 125_262,
        seconds: 6.7,
    },
    ReferenceCase {
        label: "S^2 in R^8",
        short: "S2/R8",
        preset: "sphere",
        params: &[("d", 8.0)],
        edge: 0.4216,
        simplices: 20_040,
        seconds: 2.0,
    },
    ReferenceCase {
        label: "flat torus in R^10",
        short: "T2/R10",
        preset: "flat-torus",
        params: &[("d", 10.0)],
        edge: 0.2335,
        simplices: 502_740,
        seconds: 97.0,
    },
    ReferenceCase {
        label: "3-torus in R^6",
        short: "T3/R6",
        preset: "3-torus",
        params: &[],
        edge: 0.5555,
        simplices: 468_446,
        seconds: 54.0,
    },
    ReferenceCase {
        label: "3-torus in R^6 (fine)",
        short: "T3/R6 fine",
        preset: "3-torus",
        params: &[],
        edge: 0.3703,
        simplices: 1_620_304,
        seconds: 263.0,
    },
];

impl ReferenceCase {
    /// The preset at this case's edge length.
    pub fn problem(&self) -> Result<Problem> {
        let params: Vec<(String, f64)> = self
            .params
            .iter()
            .map(|(n, v)| (n.to_string(), *v))
            .collect();
        let mut p = preset(self.preset, &params)?;
        p.triangulation.edge = Some(self.edge);
        Ok(p)
    }

    /// Throughput relative to the C++ library: (n / seconds) / (its n / its seconds).
    pub fn speedup(&self, simplices: usize, seconds: f64) -> f64 {
        (simplices as f64 / seconds) / (self.simplices as f64 / self.seconds)
    }
}

/// Traces `p` with `oracle` from its seeds.
pub fn trace_case(p: &Problem, oracle: &dyn Oracle) -> Result<Sample> {
    let tri = p.triangulation.build(p.dim())?;
    let opts = TraceOptions {
        seeds: p.seeds.clone(),
        warm: true,
        ..TraceOptions::default()
    };
    trace(&p.system, &tri, oracle, &opts)
}

/// A batch of k-simplices for the oracle alone: random vertex values in [-1, 1] (so that
/// the cheap sign filter passes most of them to the solve, and a good share is crossed),
/// each simplex with its own k + 1 vertices.
pub struct OracleBatch {
    /// The codimension.
    pub k: usize,
    /// Vertex values, rows of k.
    pub values: Vec<f64>,
    /// Rows of k + 1 vertex indices.
    pub simplices: Vec<u32>,
    /// A stand-in function of the right dimensions (the oracle only needs k).
    pub function: ClosureFunction,
}

impl OracleBatch {
    /// `count` random k-simplices from `seed`.
    pub fn random(k: usize, count: usize, seed: u64) -> Result<OracleBatch> {
        let n = k + 1;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let values = (0..count * n * k)
            .map(|_| rng.random_range(-1.0..1.0))
            .collect();
        let simplices = (0..(count * n) as u32).collect();
        let function = ClosureFunction::new(k + 1, k, |_, o| o.fill(0.0))?;
        Ok(OracleBatch {
            k,
            values,
            simplices,
            function,
        })
    }

    /// Simplices in the batch.
    pub fn len(&self) -> usize {
        self.simplices.len() / (self.k + 1)
    }

    /// Whether the batch is empty.
    pub fn is_empty(&self) -> bool {
        self.simplices.is_empty()
    }

    /// Runs `oracle` on the batch `repeats` times: the median simplices per second, and the
    /// verdicts and lambda of the last run.
    pub fn time(
        &self,
        oracle: &dyn Oracle,
        repeats: usize,
    ) -> Result<(f64, Vec<Status>, Vec<f64>)> {
        let m = self.len();
        let mut status = vec![Status::Outside; m];
        let mut lambda = vec![0.0; m * (self.k + 1)];
        let (seconds, _) = timed(repeats, || {
            oracle.decide(&self.values, &self.simplices, &mut status, &mut lambda)
        })?;
        Ok((m as f64 / seconds, status, lambda))
    }
}

/// Runs `f` `repeats` times (at least once): the median seconds and the last result.
pub fn timed<T>(repeats: usize, mut f: impl FnMut() -> Result<T>) -> Result<(f64, T)> {
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..repeats.max(1) {
        let t = Instant::now();
        last = Some(f()?);
        times.push(t.elapsed().as_secs_f64());
    }
    Ok((median(times), last.expect("at least one run")))
}

/// The median of `v` (the upper one for an even count); NaN when empty.
pub fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}
