//! The intersection oracle alone, CPU against GPU, on the same batches: k-simplices with
//! random vertex values (half of them crossed or nearly so), for k = 1..8.
//!
//! `cargo bench --bench oracle` prints a Markdown table: simplices per second (median of 3)
//! for the CPU oracle (all cores) and the GPU oracle in f32 and f64 (where the adapter has
//! it), with the share of simplices re-decided on the CPU. Without an adapter it prints only
//! the CPU column. `isomesh bench` gives more: where the GPU's time goes, traces, a plot.

use isomesh::bench::OracleBatch;
use isomesh::gpu::{Gpu, GpuOracle, Precision};
use isomesh::trace::CpuOracle;

const COUNT: usize = 200_000;

fn main() {
    let gpu = Gpu::open(true).ok();
    match &gpu {
        Some(g) => println!(
            "GPU: {} ({}, {})\n",
            g.adapter.name, g.adapter.backend, g.adapter.device_type
        ),
        None => println!("no GPU adapter: CPU only\n"),
    }
    println!("| k | CPU simplices/s | GPU f32 simplices/s | f32 rechecked | GPU f64 simplices/s | f64 rechecked |");
    println!("|---|---|---|---|---|---|");
    for k in 1..=8usize {
        let batch = OracleBatch::random(k, COUNT, k as u64).unwrap();
        let (cpu, _, _) = batch.time(&CpuOracle::new(&batch.function), 3).unwrap();
        let mut cols = vec![format!("{cpu:.3e}")];
        for p in [Precision::F32, Precision::F64] {
            let oracle = gpu
                .as_ref()
                .filter(|g| p == Precision::F32 || g.adapter.shader_f64)
                .and_then(|g| GpuOracle::new(g.clone(), &batch.function, Some(p)).ok());
            match oracle {
                Some(o) => {
                    let (r, _, _) = batch.time(&o, 3).unwrap();
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
