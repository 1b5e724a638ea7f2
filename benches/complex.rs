//! Cell-complex construction next to tracing, on the two cases the C++ reference (GUDHI's
//! Coxeter_triangulation, one thread) reports: the flat torus in R^4 (125,262 vertices, 4.7 s)
//! and S^2 in R^3 (16,240 vertices, 0.48 s); plus larger cases without a reference.
//!
//! `cargo bench --bench complex` prints a Markdown table: median of 3 runs with all cores.
//! "complex" is the Hasse diagram (build); "topology" the report (manifold check,
//! components, orientation, Betti numbers). `-- quick` skips the cases without a reference.

use std::time::Instant;

use isomesh::complex::Complex;
use isomesh::expr::preset;
use isomesh::trace::{trace, CpuOracle, TraceOptions};

/// (label, preset, parameters, edge, reference vertices, reference seconds for the complex).
type Row = (
    &'static str,
    &'static str,
    &'static [(&'static str, f64)],
    f64,
    Option<(u64, f64)>,
);

const ROWS: &[Row] = &[
    ("S^2 in R^3", "sphere", &[], 0.0707, Some((16_240, 0.48))),
    (
        "flat torus in R^4",
        "flat-torus",
        &[],
        0.0775,
        Some((125_262, 4.7)),
    ),
    ("chair", "chair", &[], 0.0707, None),
    ("S^3 in R^4", "sphere", &[("m", 3.0), ("d", 4.0)], 0.2, None),
    ("3-torus in R^6", "3-torus", &[], 0.5555, None),
];

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let quick = std::env::args().any(|a| a == "quick");
    println!(
        "| case | m | vertices (C++) | cells | C++ complex | trace | complex | topology | speed-up |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for &(label, name, params, edge, reference) in ROWS {
        if quick && reference.is_none() {
            continue;
        }
        let params: Vec<(String, f64)> = params.iter().map(|(n, v)| (n.to_string(), *v)).collect();
        let mut p = preset(name, &params).unwrap();
        p.triangulation.edge = Some(edge);
        let tri = p.triangulation.build(p.dim()).unwrap();
        let oracle = CpuOracle::new(&p.system);
        let opts = TraceOptions {
            seeds: p.seeds.clone(),
            ..TraceOptions::default()
        };
        let (mut tt, mut tc, mut tp) = (Vec::new(), Vec::new(), Vec::new());
        let mut counts = Vec::new();
        for _ in 0..3 {
            let t = Instant::now();
            let s = trace(&p.system, &tri, &oracle, &opts).unwrap();
            tt.push(t.elapsed().as_secs_f64());
            let t = Instant::now();
            let c = Complex::build(&s, &p.system, None).unwrap();
            tc.push(t.elapsed().as_secs_f64());
            let t = Instant::now();
            let top = c.topology();
            tp.push(t.elapsed().as_secs_f64());
            assert!(top.manifold);
            counts = top.cells;
        }
        let (tt, tc, tp) = (median(tt), median(tc), median(tp));
        let cells: Vec<String> = counts.iter().map(usize::to_string).collect();
        let (refv, refs, speed) = match reference {
            Some((v, s)) => (
                v.to_string(),
                format!("{s} s"),
                format!("{:.0}x", s / tc * counts[0] as f64 / v as f64),
            ),
            None => ("-".into(), "-".into(), "-".into()),
        };
        println!(
            "| {label} | {} | {refv} | {} | {refs} | {tt:.3} s | {tc:.3} s | {tp:.3} s | {speed} |",
            counts.len() - 1,
            cells.join(" / ")
        );
    }
}
