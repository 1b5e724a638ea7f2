//! The CPU's batches: f at many lattice vertices and decisions on many k-simplices, in
//! parallel with rayon (the CPU oracle, `trace::CpuOracle`, and the GPU's fallbacks).

use rayon::prelude::*;

use crate::cpu::solve::Decider;
use crate::cpu::solve::Status;
use crate::expr::ImplicitFunction;
use crate::triangulation::Triangulation;

/// Most vertices per evaluation chunk, and simplices per decision chunk.
const CHUNK: usize = 2048;
/// Fewest vertices or simplices per chunk.
const MIN_CHUNK: usize = 64;
/// Most vertices per call of an f whose calls are serial ([`ImplicitFunction::serial`]).
const SERIAL_BATCH: usize = 1 << 16;

/// Items per parallel chunk for `len` items: about four chunks per thread, within
/// `MIN_CHUNK..=CHUNK`; all of them on a thread that runs its steps alone
/// ([`crate::threads`]).
fn chunk_for(len: usize) -> usize {
    match crate::threads::threads() {
        // One chunk: the calling thread's.
        1 => len.max(1),
        threads => len.div_ceil(4 * threads).clamp(MIN_CHUNK, CHUNK),
    }
}

/// f at lattice vertices of `tri`: `lattice` holds n rows of d, `values` gets n rows of k.
pub fn eval_vertices(
    f: &dyn ImplicitFunction,
    tri: &Triangulation,
    lattice: &[i32],
    values: &mut [f64],
) {
    let (d, k) = (tri.dim(), f.codim());
    if f.serial() {
        // One call per SERIAL_BATCH vertices, the coordinates computed in parallel.
        let mut x = vec![0.0; lattice.len()];
        x.par_chunks_mut(CHUNK * d)
            .zip(lattice.par_chunks(CHUNK * d))
            .with_min_len(crate::threads::min_len(1))
            .for_each(|(p, lat)| {
                tri.vertices_coords(lat, p);
            });
        for (p, out) in x
            .chunks(SERIAL_BATCH * d)
            .zip(values.chunks_mut(SERIAL_BATCH * k))
        {
            f.eval_batch(p, out);
        }
        return;
    }
    let chunk = chunk_for(lattice.len() / d);
    lattice
        .par_chunks(chunk * d)
        .zip(values.par_chunks_mut(chunk * k))
        .for_each_init(Vec::new, |x, (lat, out)| {
            x.resize(lat.len(), 0.0);
            tri.vertices_coords(lat, x);
            f.eval_batch(x, out);
        });
}

/// The CPU's decisions ([`Decider`], in parallel) of the k-simplices `simplices` (rows of k + 1
/// indices of rows of `values`): statuses, lambda of the crossed ones; returns the count of
/// exact decisions.
pub fn decide(
    k: usize,
    values: &[f64],
    simplices: &[u32],
    status: &mut [Status],
    lambda: &mut [f64],
) -> u64 {
    let n = k + 1;
    let chunk = chunk_for(status.len());
    let exact = simplices
        .par_chunks(chunk * n)
        .zip(status.par_chunks_mut(chunk))
        .zip(lambda.par_chunks_mut(chunk * n))
        .map_init(
            || (Decider::new(k), vec![0.0; n * k]),
            |(decider, local), ((idx, st), lam)| {
                let mut exact = 0;
                for ((row, s), l) in idx
                    .chunks_exact(n)
                    .zip(st.iter_mut())
                    .zip(lam.chunks_exact_mut(n))
                {
                    for (j, &v) in row.iter().enumerate() {
                        let v = v as usize;
                        local[j * k..(j + 1) * k].copy_from_slice(&values[v * k..(v + 1) * k]);
                    }
                    let dec = decider.decide(local, l);
                    *s = dec.status;
                    exact += dec.exact as u64;
                }
                exact
            },
        )
        .sum();
    exact
}
