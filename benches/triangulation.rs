//! Face, coface and point-location throughput in R^30 (the papers' Figure 1-2 setup).
//!
//! `cargo bench --bench triangulation` prints a Markdown table: nanoseconds per generated face or
//! coface (median of 7 runs, one thread), for simplices of several dimensions.

use std::hint::black_box;
use std::time::Instant;

use isomesh::triangulation::{Simplex, Triangulation};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const D: usize = 30;

/// A random l-simplex of R^d whose parts have (nearly) equal sizes.
fn balanced_simplex(rng: &mut ChaCha8Rng, d: usize, l: usize) -> Simplex {
    let mut perm: Vec<usize> = (0..=d).collect();
    perm.shuffle(rng);
    let n = l + 1;
    let mut parts = Vec::with_capacity(n);
    let mut start = 0;
    for i in 0..n {
        let end = (i + 1) * (d + 1) / n;
        parts.push(perm[start..end].iter().fold(0u64, |m, &e| m | 1 << e));
        start = end;
    }
    let v0: Vec<i32> = (0..d).map(|_| rng.random_range(-100..100)).collect();
    Simplex::from_masks(&v0, &parts).unwrap()
}

/// Median over 7 runs of (seconds per item) for `run`, which returns how many items it made.
fn per_item(mut run: impl FnMut() -> u64) -> (f64, u64) {
    let mut times = Vec::new();
    let mut items = 0;
    for _ in 0..7 {
        let t = Instant::now();
        items = run();
        times.push(t.elapsed().as_secs_f64() / items as f64);
    }
    times.sort_by(f64::total_cmp);
    (times[3], items)
}

/// Consumes a simplex cheaply so the generator cannot be optimised away.
#[inline]
fn touch(s: &Simplex) -> u64 {
    s.base()[0] as u64 ^ s.parts()[0]
}

fn main() {
    let mut rng = ChaCha8Rng::seed_from_u64(2024);
    println!("Triangulation core in R^{D}, one thread, ns per generated simplex (median of 7)\n");
    println!(
        "| input dim l | facets | faces (dim 2) | faces (dim l-2) | cofacets | cofaces (dim l+2) |"
    );
    println!("|---|---|---|---|---|---|");
    for l in [1usize, 2, 3, 5, 8, 12, 16, 20, 25, 28, 30] {
        let simplices: Vec<Simplex> = (0..64).map(|_| balanced_simplex(&mut rng, D, l)).collect();
        let mut cells = Vec::new();
        let (t, _) = per_item(|| {
            let mut n = 0;
            let mut acc = 0;
            for _ in 0..40 {
                for s in &simplices {
                    s.for_each_facet(|f| {
                        acc ^= touch(f);
                        n += 1;
                    });
                }
            }
            black_box(acc);
            n
        });
        cells.push(format!("{:.1}", t * 1e9));
        for j in [2usize, l.saturating_sub(2)] {
            if j > l || (j == l.saturating_sub(2) && l < 2) {
                cells.push("-".into());
                continue;
            }
            let (t, _) = per_item(|| {
                let mut n = 0;
                let mut acc = 0;
                for s in simplices.iter().take(8) {
                    s.for_each_face(j, |f| {
                        acc ^= touch(f);
                        n += 1;
                    })
                    .unwrap();
                }
                black_box(acc);
                n
            });
            cells.push(format!("{:.1}", t * 1e9));
        }
        if l < D {
            let (t, _) = per_item(|| {
                let mut n = 0;
                let mut acc = 0;
                for s in simplices.iter().take(if l < 3 { 2 } else { 64 }) {
                    s.for_each_cofacet(|f| {
                        acc ^= touch(f);
                        n += 1;
                    });
                }
                black_box(acc);
                n
            });
            cells.push(format!("{:.1}", t * 1e9));
        } else {
            cells.push("-".into());
        }
        if l + 2 <= D && l >= 3 {
            let (t, _) = per_item(|| {
                let mut n = 0;
                let mut acc = 0;
                for s in simplices.iter().take(if l < 8 { 1 } else { 16 }) {
                    s.for_each_coface(l + 2, |f| {
                        acc ^= touch(f);
                        n += 1;
                    })
                    .unwrap();
                }
                black_box(acc);
                n
            });
            cells.push(format!("{:.1}", t * 1e9));
        } else {
            cells.push("-".into());
        }
        println!("| {l} | {} |", cells.join(" | "));
    }

    println!("\n| point location in R^{D} | ns per point |");
    println!("|---|---|");
    for (name, t) in [
        (
            "coxeter",
            Triangulation::coxeter(D).edge(0.1).build().unwrap(),
        ),
        (
            "freudenthal",
            Triangulation::freudenthal(D).edge(0.1).build().unwrap(),
        ),
        (
            "coxeter, rotated",
            Triangulation::coxeter(D)
                .edge(0.1)
                .rotation_seed(1)
                .build()
                .unwrap(),
        ),
    ] {
        let points: Vec<Vec<f64>> = (0..4096)
            .map(|_| (0..D).map(|_| rng.random_range(-5.0..5.0)).collect())
            .collect();
        let (secs, _) = per_item(|| {
            let mut acc = 0;
            for p in &points {
                acc ^= touch(&t.locate(p).unwrap());
            }
            black_box(acc);
            points.len() as u64
        });
        println!("| {name} | {:.1} |", secs * 1e9);
    }
}
