//! The intersection oracle alone, CPU against GPU, on the same batches: k-simplices with
//! random vertex values (half of them crossed or nearly so), for k = 1..8.
//!
//! `cargo bench --bench oracle` prints a Markdown table: simplices per second (median of 3)
//! for the CPU oracle (all cores) and the GPU oracle in f32 and f64 (where the adapter has
//! it), with the share of the GPU time spent in round trips to the device and the share of
//! simplices re-decided on the CPU. Without an adapter it prints only the CPU column.

use std::time::Instant;

use isomesh::cpu::decide::Status;
use isomesh::expr::ClosureFunction;
use isomesh::gpu::{Gpu, GpuOracle, Precision};
use isomesh::trace::{CpuOracle, Oracle};
use rand::{Rng, SeedableRng};

const COUNT: usize = 200_000;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn rate(oracle: &dyn Oracle, values: &[f64], idx: &[u32], k: usize) -> f64 {
    let mut status = vec![Status::Outside; COUNT];
    let mut lambda = vec![0.0; COUNT * (k + 1)];
    median(
        (0..3)
            .map(|_| {
                let t = Instant::now();
                oracle
                    .decide(values, idx, &mut status, &mut lambda)
                    .unwrap();
                COUNT as f64 / t.elapsed().as_secs_f64()
            })
            .collect(),
    )
}

fn main() {
    let adapter = Gpu::open(true).ok().map(|g| g.adapter.clone());
    match &adapter {
        Some(a) => println!("GPU: {} ({}, {})\n", a.name, a.backend, a.device_type),
        None => println!("no GPU adapter: CPU only\n"),
    }
    println!("| k | CPU simplices/s | GPU f32 simplices/s | f32 rechecked | GPU f64 simplices/s | f64 rechecked |");
    println!("|---|---|---|---|---|---|");
    for k in 1..=8usize {
        let n = k + 1;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(k as u64);
        // Values around zero so that the sign filter passes most simplices to the solve.
        let values: Vec<f64> = (0..COUNT * n * k)
            .map(|_| rng.random_range(-1.0..1.0))
            .collect();
        let idx: Vec<u32> = (0..(COUNT * n) as u32).collect();
        let f = ClosureFunction::new(k + 1, k, |_, o| o.fill(0.0)).unwrap();
        let cpu = rate(&CpuOracle::new(&f), &values, &idx, k);
        let mut cols = vec![format!("{cpu:.3e}")];
        for p in [Precision::F32, Precision::F64] {
            let oracle = adapter
                .as_ref()
                .filter(|a| p == Precision::F32 || a.shader_f64)
                .and_then(|_| GpuOracle::new(Gpu::open(true).ok()?, &f, Some(p)).ok());
            match oracle {
                Some(o) => {
                    let r = rate(&o, &values, &idx, k);
                    let st = o.stats();
                    cols.push(format!("{r:.3e}"));
                    cols.push(format!(
                        "{:.1}%",
                        100.0 * st.rechecked as f64 / st.solved.max(1) as f64
                    ));
                }
                None => cols.extend(["-".to_string(), "-".to_string()]),
            }
        }
        println!("| {k} | {} |", cols.join(" | "));
    }
}
