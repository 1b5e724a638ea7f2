//! Measurements behind `isomesh bench` and `cargo bench`: the intersection oracle alone on
//! the same random batches for every backend, and whole traces of the reference cases of
//! the C++ library (GUDHI's Coxeter_triangulation, one thread, on a 2-core machine), whose
//! figures live in `benches/reference.toml`, and surfaces in R^3 against a grid mesher
//! (`surfaces`, with the `surface-nets` feature).

use std::collections::BTreeMap;
use std::time::Instant;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Deserialize;

use crate::cpu::solve::Status;
use crate::error::{Error, Result};
use crate::expr::{preset, ClosureFunction, Problem};
use crate::trace::{exhaustive, trace, GrowingValues, Oracle, Sample, TraceOptions};

#[cfg(feature = "surface-nets")]
pub mod surfaces;

/// A reference case: a preset at an edge length, and what the C++ library does with it.
/// The figures are data kept with the benchmarks (`benches/reference.toml`, which says how
/// they were measured), read with [`ReferenceCase::parse_all`].
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReferenceCase {
    /// What it is, for tables.
    pub label: String,
    /// A short name, for plots.
    pub short: String,
    /// The preset.
    pub preset: String,
    /// Preset parameters.
    #[serde(default)]
    pub params: BTreeMap<String, f64>,
    /// Longest edge of a d-simplex.
    pub edge: f64,
    /// Output simplices of the C++ library.
    pub simplices: u64,
    /// Its time in seconds.
    pub seconds: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ReferenceFile {
    case: Vec<ReferenceCase>,
}

impl ReferenceCase {
    /// The cases of a reference file (`[[case]]` tables with the fields above), checked:
    /// an error names the first bad one.
    pub fn parse_all(text: &str) -> Result<Vec<ReferenceCase>> {
        let file: ReferenceFile =
            toml::from_str(text).map_err(|e| Error::Spec(format!("reference cases: {e}")))?;
        for c in &file.case {
            let positive = |v: f64| v.is_finite() && v > 0.0;
            if !(positive(c.edge) && positive(c.seconds) && c.simplices > 0) {
                return Err(Error::Spec(format!(
                    "reference case {:?}: edge, simplices and seconds must be positive",
                    c.label
                )));
            }
        }
        Ok(file.case)
    }

    /// The preset at this case's edge length.
    pub fn problem(&self) -> Result<Problem> {
        let params: Vec<(String, f64)> = self.params.iter().map(|(n, v)| (n.clone(), *v)).collect();
        let mut p = preset(&self.preset, &params)?;
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

/// An exhaustive scan of `bbox`, the rim completed.
pub fn scan_case(p: &Problem, bbox: &[[f64; 2]], oracle: &dyn Oracle) -> Result<Sample> {
    let tri = p.triangulation.build(p.dim())?;
    let opts = TraceOptions {
        bbox: Some(bbox.to_vec()),
        ..TraceOptions::default()
    };
    exhaustive(&p.system, &tri, oracle, &opts)
}

/// A box scanned by `isomesh bench --traces scans`: a preset with parameters, and the box's
/// half-widths, the last one repeated for the remaining axes.
pub struct ScanCase {
    /// Shown in the table.
    pub label: &'static str,
    /// The preset.
    pub preset: &'static str,
    /// Its parameters.
    pub params: &'static [(&'static str, f64)],
    /// Half-widths of the box, centred at 0.
    pub half: &'static [f64],
}

impl ScanCase {
    /// The preset resolved.
    pub fn problem(&self) -> Result<Problem> {
        let params: Vec<(String, f64)> = self
            .params
            .iter()
            .map(|(n, v)| (n.to_string(), *v))
            .collect();
        preset(self.preset, &params)
    }

    /// The box in R^d.
    pub fn bbox(&self, d: usize) -> Vec<[f64; 2]> {
        (0..d)
            .map(|i| {
                let h = self.half[i.min(self.half.len() - 1)];
                [-h, h]
            })
            .collect()
    }
}

/// The scans of `isomesh bench --traces scans`: a surface, curves and higher codimension.
pub const SCAN_CASES: &[ScanCase] = &[
    ScanCase {
        label: "torus in R^3",
        preset: "torus",
        params: &[("edge", 0.05)],
        half: &[2.0, 2.0, 1.0],
    },
    ScanCase {
        label: "flat torus in R^4",
        preset: "flat-torus",
        params: &[("edge", 0.15)],
        half: &[1.1],
    },
    ScanCase {
        label: "3-torus in R^6",
        preset: "3-torus",
        params: &[("a", 0.5), ("b", 0.5), ("c", 0.5), ("edge", 1.2)],
        half: &[3.0],
    },
];

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
    /// verdicts and lambda of the last run. The values are the same in every run
    /// ([`Decide::decide_growing`](crate::trace::Decide::decide_growing)): an oracle that
    /// keeps them (the GPU's, on the device, for k >= 2) is sent them in the first run only.
    pub fn time(
        &self,
        oracle: &dyn Oracle,
        repeats: usize,
    ) -> Result<(f64, Vec<Status>, Vec<f64>)> {
        let m = self.len();
        let mut status = vec![Status::Outside; m];
        let mut lambda = vec![0.0; m * (self.k + 1)];
        let log = GrowingValues::new();
        let (seconds, _) = timed(repeats, || {
            oracle.decisions().decide_growing(
                log,
                &self.values,
                &self.simplices,
                &mut status,
                &mut lambda,
            )
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_cases_parse_and_bad_ones_are_refused() {
        let good = "[[case]]\nlabel = \"a\"\nshort = \"a\"\npreset = \"sphere\"\n\
                    params = { d = 4 }\nedge = 0.5\nsimplices = 10\nseconds = 1.5\n";
        let cases = ReferenceCase::parse_all(good).unwrap();
        assert_eq!(cases.len(), 1);
        assert_eq!(cases[0].params.get("d"), Some(&4.0));
        assert_eq!(cases[0].problem().unwrap().dim(), 4);
        for bad in [
            good.replace("seconds = 1.5", "seconds = 0"),
            good.replace("edge = 0.5", "edge = -1"),
            good.replace("simplices = 10", "simplices = 0"),
            good.replace("short", "shrt"),
            good.replace("seconds = 1.5", "seconds = \"fast\""),
        ] {
            let e = ReferenceCase::parse_all(&bad).unwrap_err();
            assert!(e.to_string().contains("reference case"), "{e}");
        }
    }
}
