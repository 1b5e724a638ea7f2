//! Surfaces in R^3 against the grid mesher fast-surface-nets at matched vertex counts (the
//! library's `bench::surfaces`; `isomesh bench --traces surfaces` prints the same table with
//! a plot). `cargo bench --bench surfaces [-- N,N,...]`: grid sizes, multiples of 64.

use isomesh::bench::surfaces::{crossover, measure_sizes, SURFACES};

fn main() {
    let sizes: Vec<u32> = std::env::args()
        .skip(1)
        .find(|a| !a.starts_with('-'))
        .unwrap_or_else(|| "64,128,256,512".into())
        .split(',')
        .map(|n| {
            n.trim()
                .parse()
                .expect("grid sizes: N,N,... (multiples of 64)")
        })
        .collect();
    println!("| surface | grid | vertices | grid ms | isomesh ms (trace + complex + triangles) | isomesh / grid |");
    println!("|---|---|---|---|---|---|");
    for s in &SURFACES {
        let rows = measure_sizes(s, &sizes, 3, |r| {
            println!(
                "| {} | {}^3 | {} | {:.1} | {:.1} + {:.1} + {:.1} | {:.2} |",
                s.preset,
                r.n,
                r.grid.vertices,
                r.grid_s * 1e3,
                r.stages.trace_s * 1e3,
                r.stages.complex_s * 1e3,
                r.stages.triangles_s * 1e3,
                r.ratio()
            );
        })
        .unwrap();
        match crossover(&rows) {
            Some(v) => println!("{}: isomesh faster from about {v:.3e} vertices", s.preset),
            None => println!("{}: isomesh slower at every size", s.preset),
        }
    }
}
