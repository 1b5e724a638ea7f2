//! Batch evaluation of the presets against hand-written Rust, one thread.
//!
//! `cargo bench --bench expressions` prints a Markdown table: nanoseconds per point for the
//! compiled program and for a hand-written closure over the same points (median of 9 runs).

use std::hint::black_box;
use std::time::Instant;

use isomesh::expr::preset;
use isomesh::expr::program::Scratch;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

type Hand = fn(&[f64], &mut [f64]);

fn hand(name: &str) -> Hand {
    match name {
        "sphere" => |x, o| o[0] = x[0] * x[0] + x[1] * x[1] + x[2] * x[2] - 1.0,
        "torus" => |x, o| {
            let q = (x[0] * x[0] + x[1] * x[1]).sqrt() - 1.0;
            o[0] = q * q + x[2] * x[2] - 0.16;
        },
        "chair" => |x, o| {
            let (a, b, c) = (x[0], x[1], x[2]);
            let s = a * a + b * b + c * c - 0.8;
            let (u, v) = (c - 1.0, c + 1.0);
            o[0] = s * s - 0.4 * (u * u - 2.0 * a * a) * (v * v - 2.0 * b * b);
        },
        "flat-torus" => |x, o| {
            o[0] = x[0] * x[0] + x[1] * x[1] - 1.0;
            o[1] = x[2] * x[2] + x[3] * x[3] - 1.0;
        },
        "3-torus" => |x, o| {
            o[0] = x[0] * x[0] + x[1] * x[1] - 0.25;
            o[1] = x[2] * x[2] + x[3] * x[3] - 1.0;
            o[2] = x[4] * x[4] + x[5] * x[5] - 4.0;
        },
        "complex-cosine" => |x, o| {
            o[0] = x[0] - x[2].cos() * x[3].cosh();
            o[1] = x[1] + x[2].sin() * x[3].sinh();
        },
        _ => |x, o| {
            let (s, t) = (x[3], x[4]);
            let (ch, sh) = ((s / 2.0).cos(), (s / 2.0).sin());
            let (st, s2t) = (t.sin(), (2.0 * t).sin());
            let ring = 3.0 + ch * st - sh * s2t;
            o[0] = s.cos() * ring - x[0];
            o[1] = s.sin() * ring - x[1];
            o[2] = sh * st + ch * s2t - x[2];
        },
    }
}

fn median(mut run: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..9)
        .map(|_| {
            let s = Instant::now();
            run();
            s.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[4]
}

fn main() {
    let n = 1 << 16;
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    println!("Batch evaluation, {n} points, one thread, ns per point (median of 9)\n");
    println!("| preset | d | k | compiled program | hand-written Rust | ratio |");
    println!("|---|---|---|---|---|---|");
    for name in [
        "sphere",
        "torus",
        "chair",
        "flat-torus",
        "3-torus",
        "complex-cosine",
        "bagel-klein",
    ] {
        let p = preset(name, &[]).unwrap();
        let prog = p.system.values();
        let (d, k) = (prog.dim(), prog.outputs());
        let points: Vec<f64> = (0..n * d).map(|_| rng.random_range(-2.0..2.0)).collect();
        let mut out = vec![0.0; n * k];
        let mut scratch = Scratch::default();
        let t_prog = median(|| {
            prog.eval_batch(&points, &mut out, &mut scratch);
            black_box(&out);
        });
        let f = hand(name);
        let t_hand = median(|| {
            for (x, o) in points.chunks_exact(d).zip(out.chunks_exact_mut(k)) {
                f(black_box(x), o);
            }
            black_box(&out);
        });
        println!(
            "| {name} | {d} | {k} | {:.1} | {:.1} | {:.2} |",
            t_prog / n as f64 * 1e9,
            t_hand / n as f64 * 1e9,
            t_prog / t_hand
        );
    }
}
