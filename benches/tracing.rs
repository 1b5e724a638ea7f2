//! Tracing throughput and memory on the reference cases of the C++ library (GUDHI's
//! Coxeter_triangulation, one thread, measured on a 2-core machine like ours).
//!
//! `cargo bench --bench tracing` prints a Markdown table: the median of 3 to 25 runs (about
//! a second per case) with all cores, and peak heap per output simplex measured by a
//! counting allocator. The cases and the C++ figures are in `benches/reference.toml`.
//! `-- quick` runs the cases up to 200,000 simplices.

use std::time::Instant;

use isomesh::bench::{trace_case, ReferenceCase};
use isomesh::memory::{self, CountingAlloc};
use isomesh::trace::CpuOracle;

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

fn main() {
    let quick = std::env::args().any(|a| a == "quick");
    println!(
        "| case | d | k | edge | simplices (C++) | simplices | C++ time | isomesh time | speed-up | bytes/simplex |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let cases = ReferenceCase::parse_all(include_str!("reference.toml")).unwrap();
    for case in &cases {
        let (label, edge, ref_n, ref_s) = (&case.label, case.edge, case.simplices, case.seconds);
        if quick && ref_n > 200_000 {
            continue;
        }
        let p = case.problem().unwrap();
        let d = p.dim();
        let k = p.system.equations().len();
        let oracle = CpuOracle::new(&p.system);
        let mut times = Vec::new();
        let (mut n, mut peak) = (0, 0);
        // At least 3 runs, more for the small cases (up to about a second in all).
        let started = Instant::now();
        while times.len() < 3 || (times.len() < 25 && started.elapsed().as_secs_f64() < 1.0) {
            memory::reset_peak();
            let base = memory::live_bytes();
            let t = Instant::now();
            let s = trace_case(&p, &oracle).unwrap();
            times.push(t.elapsed().as_secs_f64());
            peak = memory::peak_bytes() - base;
            n = s.len();
        }
        times.sort_by(f64::total_cmp);
        let t = times[times.len() / 2];
        let diff = 100.0 * (n as f64 - ref_n as f64) / ref_n as f64;
        println!(
            "| {label} | {d} | {k} | {edge} | {ref_n} | {n} ({diff:+.1}%) | {ref_s} s | {t:.3} s | {:.0}x | {:.0} |",
            case.speedup(n, t),
            peak as f64 / n as f64
        );
    }
}
