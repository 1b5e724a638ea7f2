//! One trace or scan as the CLI runs it: the triangulation, the oracle, the sample, the
//! complex on demand, and the report with the CLI's keys.

use std::sync::atomic::AtomicBool;
use std::sync::{Arc, OnceLock};
use std::time::Instant;

use isomesh::complex::{Complex, Topology};
use isomesh::expr::{EquationSystem, ImplicitFunction, TriangulationSpec};
use isomesh::gpu::{Gpu, GpuOracle, Precision};
use isomesh::memory;
use isomesh::trace::{exhaustive, trace, CpuOracle, Oracle, Sample, TraceOptions};
use isomesh::{Error, Result};
use serde_json::{json, Value};

/// Which oracle decides the simplices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    Cpu,
    Gpu,
    Auto,
}

impl std::str::FromStr for Backend {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "cpu" => Ok(Backend::Cpu),
            "gpu" => Ok(Backend::Gpu),
            "auto" => Ok(Backend::Auto),
            _ => Err(Error::Spec(format!(
                "backend '{s}': use \"cpu\", \"gpu\" or \"auto\""
            ))),
        }
    }
}

/// The problem: f, where to start and look, how to triangulate.
#[derive(Clone)]
pub struct Setup {
    pub name: String,
    pub f: Arc<dyn ImplicitFunction>,
    /// f as equations, when it has them (the GPU needs them).
    pub system: Option<EquationSystem>,
    pub seeds: Vec<Vec<f64>>,
    pub bbox: Option<Vec<[f64; 2]>>,
    pub triangulation: TriangulationSpec,
}

/// How to run it.
#[derive(Clone, Debug)]
pub struct RunOptions {
    pub exhaustive: bool,
    pub backend: Backend,
    pub precision: Option<Precision>,
    pub threads: Option<usize>,
    pub search: Option<usize>,
    pub search_seed: u64,
    pub max_memory: Option<u64>,
}

/// A finished run: the sample, and the complex built from it on first use.
pub struct Traced {
    pub setup: Setup,
    pub sample: Sample,
    pub threads: usize,
    pub max_memory: u64,
    /// The report's keys known after the trace.
    pub report: Value,
    complex: OnceLock<std::result::Result<(Complex, Topology, f64), Error>>,
}

/// Runs `opts` on `setup`, stopping when `cancel` is raised.
pub fn run(setup: &Setup, opts: &RunOptions, cancel: Arc<AtomicBool>) -> Result<Traced> {
    let threads = opts.threads.unwrap_or_else(rayon::current_num_threads);
    if threads == 0 {
        return Err(Error::Spec("threads must be at least 1".into()));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| Error::Io(format!("cannot start {threads} threads: {e}")))?;
    pool.install(|| run_in_pool(setup, opts, cancel, threads))
}

fn run_in_pool(
    setup: &Setup,
    opts: &RunOptions,
    cancel: Arc<AtomicBool>,
    threads: usize,
) -> Result<Traced> {
    let f: &dyn ImplicitFunction = setup.f.as_ref();
    let (d, k) = (f.ambient_dim(), f.codim());
    let tri = setup.triangulation.build(d)?;
    let gpu =
        match (opts.backend, &setup.system) {
            (Backend::Cpu, _) => None,
            (Backend::Gpu, None) => return Err(Error::Gpu(
                "backend \"gpu\" needs f as equations (text, a preset or a spec file): a Python \
                 function runs on the CPU backend only; use backend=\"cpu\""
                    .into(),
            )),
            (Backend::Auto, None) => None,
            (Backend::Gpu, Some(_)) => Some(Gpu::open(true)?),
            (Backend::Auto, Some(_)) => Gpu::open(false).ok(),
        };
    let cpu_oracle = CpuOracle::new(f);
    let gpu_oracle = match (gpu, &setup.system) {
        (Some(g), Some(sys)) => Some(GpuOracle::new(g, sys, opts.precision)?),
        _ => None,
    };
    let oracle: &dyn Oracle = match &gpu_oracle {
        Some(o) => o,
        None => &cpu_oracle,
    };
    let max_memory = opts.max_memory.unwrap_or_else(memory::default_limit);
    let topts = TraceOptions {
        bbox: setup.bbox.clone(),
        seeds: setup.seeds.clone(),
        search_samples: opts.search,
        search_seed: opts.search_seed,
        max_memory,
        cancel: Some(cancel),
        progress: None,
    };
    memory::reset_peak();
    let base = memory::live_bytes();
    let sample = if opts.exhaustive {
        exhaustive(f, &tri, oracle, &topts)?
    } else {
        trace(f, &tri, oracle, &topts)?
    };
    let peak = memory::peak_bytes().saturating_sub(base);
    let suspect = sample.suspect_crossings(f);
    let st = &sample.stats;
    let n = sample.len();
    let per_s = if st.elapsed_s > 0.0 {
        n as f64 / st.elapsed_s
    } else {
        0.0
    };
    let report = json!({
        "name": setup.name,
        "mode": if opts.exhaustive { "exhaustive" } else { "trace" },
        "ambient_dim": d,
        "codim": k,
        "manifold_dim": d - k,
        "triangulation": tri.kind().name(),
        "edge": tri.edge(),
        "offset": tri.offset(),
        "box": setup.bbox,
        "simplex_count": n,
        "components": st.components,
        "backend": oracle.name(),
        "precision": gpu_oracle.as_ref().map_or("f64", |o| o.precision().ty()),
        "recheck_share": gpu_oracle.as_ref().map(|o| {
            let st = o.stats();
            if st.solved > 0 { st.rechecked as f64 / st.solved as f64 } else { 0.0 }
        }),
        "gpu_s": gpu_oracle.as_ref().map(|o| o.stats().gpu_s),
        "adapter": gpu_oracle.as_ref().map(|o| o.gpu().adapter.clone()),
        "threads": threads,
        "elapsed_s": st.elapsed_s,
        "simplices_per_s": per_s,
        "peak_memory_bytes": peak,
        "bytes_per_simplex": if n > 0 { peak as f64 / n as f64 } else { 0.0 },
        "levels": st.levels,
        "widest_level": st.widest_level,
        "oracle_calls": st.oracle_calls,
        "exact_decisions": st.exact_decisions,
        "pivot_fallbacks": st.pivot_fallbacks,
        "degenerate": st.degenerate,
        "non_finite": st.non_finite,
        "vertices_evaluated": st.vertices,
        "seed_points": st.seed_points,
        "suspect_crossings": suspect,
        "complete": st.stopped.is_none(),
        "stopped": st.stopped.as_ref().map(|s| s.to_string()),
        "error": Value::Null,
    });
    Ok(Traced {
        setup: setup.clone(),
        sample,
        threads,
        max_memory,
        report,
        complex: OnceLock::new(),
    })
}

impl Traced {
    /// The cell complex and its topology, built once.
    pub fn complex(&self) -> Result<&(Complex, Topology, f64)> {
        self.complex
            .get_or_init(|| {
                if self.sample.is_empty() {
                    return Err(Error::Trace(
                        "the sample is empty: there is no complex to build".into(),
                    ));
                }
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(self.threads)
                    .build()
                    .map_err(|e| Error::Io(format!("cannot start threads: {e}")))?;
                pool.install(|| {
                    let c = Complex::build_within(
                        &self.sample,
                        self.setup.f.as_ref(),
                        self.setup.bbox.as_deref(),
                        self.max_memory,
                    )?;
                    let t0 = Instant::now();
                    let topo = c.topology();
                    Ok((c, topo, t0.elapsed().as_secs_f64()))
                })
            })
            .as_ref()
            .map_err(Clone::clone)
    }

    /// The report: the trace's keys, plus the topology's once the complex is built.
    pub fn report(&self) -> Value {
        let mut report = self.report.clone();
        if let Some(Ok((c, t, topo_s))) = self.complex.get() {
            let extra = json!({
                "components": t.components,
                "cells": t.cells,
                "euler_characteristic": t.euler_characteristic,
                "manifold": t.manifold,
                "closed": t.closed,
                "boundary_cells": t.boundary_cells,
                "boundary_euler_characteristic": t.boundary_euler_characteristic,
                "orientable": t.orientable,
                "betti_mod2": t.betti_mod2,
                "closed_components": t.closed_components,
                "offender_count": t.offender_count,
                "offenders": t.offenders,
                "defects": t.defects,
                "complex_s": c.stats.elapsed_s,
                "topology_s": topo_s,
            });
            if let (Some(r), Some(e)) = (report.as_object_mut(), extra.as_object()) {
                r.extend(e.clone());
            }
        }
        report
    }
}
