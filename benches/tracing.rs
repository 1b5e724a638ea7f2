//! Tracing throughput and memory on the reference cases of the C++ library (GUDHI's
//! Coxeter_triangulation, one thread, measured on a 2-core machine like ours).
//!
//! `cargo bench --bench tracing` prints a Markdown table: median of 3 runs with all cores,
//! and peak heap per output simplex measured by a counting allocator. `-- quick` skips the
//! largest case.

use std::time::Instant;

use isomesh::expr::preset;
use isomesh::memory::{self, CountingAlloc};
use isomesh::trace::{trace, CpuOracle, TraceOptions};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

/// (label, preset, parameters, edge, reference simplices, reference seconds).
type Row = (
    &'static str,
    &'static str,
    &'static [(&'static str, f64)],
    f64,
    u64,
    f64,
);

const ROWS: &[Row] = &[
    ("S^2 in R^3", "sphere", &[], 0.0707, 16_240, 0.52),
    ("chair", "chair", &[], 0.0707, 11_768, 0.34),
    ("flat torus in R^4", "flat-torus", &[], 0.0775, 125_262, 6.7),
    ("S^2 in R^8", "sphere", &[("d", 8.0)], 0.4216, 20_040, 2.0),
    (
        "flat torus in R^10",
        "flat-torus",
        &[("d", 10.0)],
        0.2335,
        502_740,
        97.0,
    ),
    ("3-torus in R^6", "3-torus", &[], 0.5555, 468_446, 54.0),
    ("3-torus in R^6", "3-torus", &[], 0.3703, 1_620_304, 263.0),
];

fn main() {
    let quick = std::env::args().any(|a| a == "quick");
    println!(
        "| case | d | k | edge | simplices (C++) | simplices | C++ time | isomesh time | speed-up | bytes/simplex |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for &(label, name, params, edge, ref_n, ref_s) in ROWS {
        if quick && ref_n > 1_000_000 {
            continue;
        }
        let params: Vec<(String, f64)> = params.iter().map(|(n, v)| (n.to_string(), *v)).collect();
        let mut p = preset(name, &params).unwrap();
        p.triangulation.edge = Some(edge);
        let d = p.dim();
        let k = p.system.equations().len();
        let tri = p.triangulation.build(d).unwrap();
        let oracle = CpuOracle::new(&p.system);
        let opts = TraceOptions {
            seeds: p.seeds.clone(),
            ..TraceOptions::default()
        };
        let mut times = Vec::new();
        let (mut n, mut peak) = (0, 0);
        for _ in 0..3 {
            memory::reset_peak();
            let base = memory::live_bytes();
            let t = Instant::now();
            let s = trace(&p.system, &tri, &oracle, &opts).unwrap();
            times.push(t.elapsed().as_secs_f64());
            peak = memory::peak_bytes() - base;
            n = s.len();
        }
        times.sort_by(f64::total_cmp);
        let t = times[1];
        let diff = 100.0 * (n as f64 - ref_n as f64) / ref_n as f64;
        println!(
            "| {label} | {d} | {k} | {edge} | {ref_n} | {n} ({diff:+.1}%) | {ref_s} s | {t:.3} s | {:.0}x | {:.0} |",
            ref_s / t * n as f64 / ref_n as f64,
            peak as f64 / n as f64
        );
    }
}
