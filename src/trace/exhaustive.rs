// Index loops over lattice axes read as the coordinates they are.
#![allow(clippy::needless_range_loop)]
//! The exhaustive scan: every k-simplex of T in a box goes through the oracle, with no seed.
//!
//! A k-simplex in canonical form lies in the unit lattice cube at its base vertex v0 (its
//! vertices are v0 + e_S for a chain of subsets S of {1..d}) and has diameter <= edge. So f is
//! evaluated once at the lattice vertices within 2 edge of the box (found row by row along
//! one lattice axis, so a rotated lattice costs nothing for the vertices far from the box);
//! cubes based within `edge` of the box where some component of f keeps one strict sign are
//! skipped whole, and in the others the chains are enumerated depth first, pruned by
//! superset minima and maxima of f.

use rayon::prelude::*;

use super::region::{in_box, lattice_bounds};
use super::table::{Key, Table};
use super::{TraceContext, TraceStats};
use crate::cpu::decide::Status;
use crate::error::{Error, Result};
use crate::triangulation::{Simplex, MAX_DIM};

/// Largest d for the scan (each cube holds 2^d corners).
pub const MAX_SCAN_DIM: usize = 16;
/// Cubes per oracle batch.
const CUBES_PER_BATCH: usize = 8192;

/// The lattice vertices near a box, in rows along lattice axis 0: the row with id r (axes
/// 1..d-1 from r) holds u_0 in `start..start + len`, stored from `offset` on. Only rows that
/// hold vertices are kept, sorted by id.
struct Grid {
    lo: Vec<i64>,
    n: Vec<usize>,
    rows: Vec<Row>,
    total: usize,
}

#[derive(Clone, Copy, Debug)]
struct Row {
    id: usize,
    start: i64,
    len: u32,
    offset: usize,
}

impl Grid {
    /// Lattice coordinates of axes 1..d-1 of row r.
    fn row_coords(&self, mut r: usize, out: &mut [i32]) {
        for j in 1..self.n.len() {
            out[j] = (self.lo[j] + (r % self.n[j]) as i64) as i32;
            r /= self.n[j];
        }
    }

    /// Lattice coordinates of stored vertex `idx`.
    fn coords(&self, idx: usize, out: &mut [i32]) {
        let r = self.rows.partition_point(|row| row.offset <= idx) - 1;
        self.row_coords(self.rows[r].id, out);
        out[0] = (self.rows[r].start + (idx - self.rows[r].offset) as i64) as i32;
    }

    /// Storage index of the lattice vertex `v`, if it is near the box.
    fn index(&self, v: &[i32]) -> Option<usize> {
        let mut r = 0;
        let mut stride = 1;
        for j in 1..self.n.len() {
            let t = v[j] as i64 - self.lo[j];
            if t < 0 || t >= self.n[j] as i64 {
                return None;
            }
            r += t as usize * stride;
            stride *= self.n[j];
        }
        let row = self.rows[self.rows.binary_search_by_key(&r, |row| row.id).ok()?];
        let t = v[0] as i64 - row.start;
        (t >= 0 && t < row.len as i64).then(|| row.offset + t as usize)
    }
}

/// The rows of lattice vertices whose position lies in `near` (a grown box).
fn near_grid(ctx: &TraceContext, near: &[[f64; 2]]) -> Result<Grid> {
    let d = ctx.d;
    let (lo, hi) = lattice_bounds(ctx.tri, near);
    let n: Vec<usize> = lo
        .iter()
        .zip(&hi)
        .map(|(l, h)| (h - l + 2) as usize)
        .collect();
    let rows_total = n[1..].iter().try_fold(1usize, |a, &b| a.checked_mul(b));
    let rows_total = match rows_total {
        Some(r) if r < 1 << 40 => r,
        _ => {
            return Err(Error::Trace(format!(
                "the exhaustive scan of this box needs {:.3e} lattice rows, over the memory                  limit: use a smaller box or a larger edge",
                n[1..].iter().map(|&v| v as f64).product::<f64>()
            )))
        }
    };
    let mut zero = vec![0i32; d];
    let mut origin = vec![0.0; d];
    ctx.tri.vertex_coords(&zero, &mut origin);
    // Refuse before enumerating: about vol(box) / |det A| vertices, each k values.
    let a = ctx.tri.matrix();
    let volume: f64 = near.iter().map(|[lo, hi]| hi - lo).product();
    let estimate = crate::linalg::Lu::new(&a, d).map_or(f64::INFINITY, |lu| volume / lu.abs_det());
    let bytes = estimate * (ctx.k as f64 * 8.0 + 8.0);
    if !(bytes <= ctx.max_memory as f64 && estimate < u32::MAX as f64) {
        return Err(Error::Trace(format!(
            "the exhaustive scan of this box needs about {estimate:.3e} lattice vertices, \
             about {:.1} GiB, over the memory limit of {:.1} GiB or the 2^32 vertex cap: use \
             a smaller box or a larger edge",
            bytes / (1u64 << 30) as f64,
            ctx.max_memory as f64 / (1u64 << 30) as f64
        )));
    }
    zero[0] = 1;
    let mut step = vec![0.0; d];
    ctx.tri.vertex_coords(&zero, &mut step);
    for (s, o) in step.iter_mut().zip(&origin) {
        *s -= o;
    }
    let grid0 = Grid {
        lo: lo.clone(),
        n: n.clone(),
        rows: Vec::new(),
        total: 0,
    };
    // Per row, the u_0 interval where the vertex lies in the grown box; rows go along lines
    // of axis 1, where the row origin moves by a fixed step.
    let column = |j: usize| -> Vec<f64> {
        let mut e = vec![0i32; d];
        e[j] = 1;
        let mut x = vec![0.0; d];
        ctx.tri.vertex_coords(&e, &mut x);
        x.iter().zip(&origin).map(|(a, b)| a - b).collect()
    };
    let step1 = if d > 1 { column(1) } else { vec![0.0; d] };
    let n1 = if d > 1 { n[1] } else { 1 };
    let span = |r: usize, x: &[f64]| -> Option<(usize, i64, u32)> {
        let (mut t0, mut t1) = (lo[0] as f64, (hi[0] + 1) as f64);
        for i in 0..d {
            let [a, b] = near[i];
            if step[i] == 0.0 {
                if x[i] < a || x[i] > b {
                    return None;
                }
            } else {
                let (p, q) = ((a - x[i]) / step[i], (b - x[i]) / step[i]);
                t0 = t0.max(p.min(q));
                t1 = t1.min(p.max(q));
            }
        }
        let (s, e) = (t0.ceil() as i64, t1.floor() as i64);
        (e >= s).then(|| (r, s, (e - s + 1) as u32))
    };
    let spans: Vec<(usize, i64, u32)> = (0..rows_total / n1)
        .into_par_iter()
        .flat_map_iter(|line| {
            let mut v = vec![0i32; d];
            let mut x = vec![0.0; d];
            grid0.row_coords(line * n1, &mut v);
            v[0] = 0;
            ctx.tri.vertex_coords(&v, &mut x);
            let mut out = Vec::new();
            for t in 0..n1 {
                if let Some(sp) = span(line * n1 + t, &x) {
                    out.push(sp);
                }
                for (xi, si) in x.iter_mut().zip(&step1) {
                    *xi += si;
                }
            }
            out
        })
        .collect();
    let total: usize = spans.iter().map(|s| s.2 as usize).sum();
    let need = total as u64 * (ctx.k as u64 * 8 + 8) + spans.len() as u64 * 32;
    if need > ctx.max_memory {
        return Err(Error::Trace(format!(
            "the exhaustive scan of this box needs {total} lattice vertices, about {:.1} GiB,              over the memory limit of {:.1} GiB: use a smaller box or a larger edge",
            need as f64 / (1u64 << 30) as f64,
            ctx.max_memory as f64 / (1u64 << 30) as f64
        )));
    }
    let mut offset = 0;
    let rows = spans
        .into_iter()
        .map(|(id, start, len)| {
            let row = Row {
                id,
                start,
                len,
                offset,
            };
            offset += len as usize;
            row
        })
        .collect();
    Ok(Grid { lo, n, rows, total })
}

/// Scans the box; returns S (keys in sorted order, W words each) and counters.
pub(crate) fn scan<const W: usize>(
    ctx: &TraceContext,
    bbox: &[[f64; 2]],
) -> Result<(Table<W>, TraceStats)> {
    let (d, k) = (ctx.d, ctx.k);
    if d > MAX_SCAN_DIM {
        return Err(Error::Trace(format!(
            "the exhaustive scan handles d <= {MAX_SCAN_DIM} (d = {d}); trace from seeds instead"
        )));
    }
    // Every simplex based at v0 has v0 as a vertex and diameter <= edge, so only bases
    // within `edge` of the box matter, and their cubes' corners lie within 2 edge of it.
    let edge = ctx.tri.edge();
    let grown =
        |r: f64| -> Vec<[f64; 2]> { bbox.iter().map(|[lo, hi]| [lo - r, hi + r]).collect() };
    let near_base = grown(edge);
    let grid = near_grid(ctx, &grown(2.0 * edge + 1e-9 * (1.0 + edge)))?;
    let total = grid.total;
    if total >= u32::MAX as usize {
        return Err(Error::Trace(format!(
            "the exhaustive scan of this box needs {total} lattice vertices (> 2^32): use a \
             smaller box or a larger edge"
        )));
    }
    let mut stats = TraceStats {
        vertices: total as u64,
        ..TraceStats::default()
    };
    let mut values = vec![0.0; total * k];
    let mut cubes: Vec<usize> = Vec::new();
    let slab = 1 << 16;
    for start in (0..total).step_by(slab) {
        cancelled(ctx)?;
        let end = (start + slab).min(total);
        let mut lattice = vec![0i32; (end - start) * d];
        lattice
            .par_chunks_mut(d)
            .enumerate()
            .for_each(|(i, v)| grid.coords(start + i, v));
        ctx.oracle
            .eval_vertices(ctx.tri, &lattice, &mut values[start * k..end * k])?;
        let bases: Vec<usize> = lattice
            .par_chunks(d)
            .enumerate()
            .filter_map(|(i, v)| {
                let mut x = [0.0f64; MAX_DIM];
                ctx.tri.vertex_coords(v, &mut x[..d]);
                in_box(&near_base, &x[..d]).then_some(start + i)
            })
            .collect();
        cubes.extend(bases);
    }

    let codec = &ctx.codec;
    let mut found: Vec<Key<W>> = Vec::new();
    for batch in cubes.chunks(CUBES_PER_BATCH) {
        cancelled(ctx)?;
        let chains: Vec<(Vec<u32>, Vec<u64>)> = batch
            .par_iter()
            .map(|&cube| cube_chains(&grid, &values, k, cube))
            .collect();
        let rows: Vec<u32> = chains.iter().flat_map(|c| c.0.iter().copied()).collect();
        let masks: Vec<u64> = chains.iter().flat_map(|c| c.1.iter().copied()).collect();
        let m = rows.len() / (k + 1);
        let mut status = vec![Status::Outside; m];
        let mut lambda = vec![0.0; m * (k + 1)];
        stats.exact_decisions += ctx
            .oracle
            .decide(&values, &rows, &mut status, &mut lambda)?;
        stats.oracle_calls += m as u64;
        for s in &status {
            match s {
                Status::Degenerate => stats.degenerate += 1,
                Status::NonFinite => stats.non_finite += 1,
                _ => {}
            }
        }
        let hits: Vec<Result<Option<Key<W>>>> = (0..m)
            .into_par_iter()
            .filter(|&i| status[i].crossed())
            .map(|i| {
                let row = &rows[i * (k + 1)..(i + 1) * (k + 1)];
                let chain = &masks[i * k..(i + 1) * k];
                let lam = &lambda[i * (k + 1)..(i + 1) * (k + 1)];
                let mut point = vec![0.0; d];
                let mut v = [0i32; MAX_DIM];
                ctx.tri.barycentric_point(
                    lam,
                    |j, out| grid.coords(row[j] as usize, out),
                    &mut point,
                );
                if !ctx.domain.contains(&point) {
                    return Ok(None);
                }
                grid.coords(row[0] as usize, &mut v[..d]);
                let full = (1u64 << d) - 1;
                let mut parts = [0u64; MAX_DIM + 1];
                let mut prev = 0;
                for (j, &s) in chain.iter().enumerate() {
                    parts[j] = s & !prev;
                    prev = s;
                }
                parts[k] = (full & !prev) | (1 << d);
                let simplex = Simplex::from_masks(&v[..d], &parts[..=k])?;
                let mut key = [0u64; W];
                codec.encode(&simplex, &mut key)?;
                Ok(Some(key))
            })
            .collect();
        for h in hits {
            if let Some(key) = h? {
                found.push(key);
            }
        }
    }
    found.par_sort_unstable();
    let mut table = Table::new();
    for key in &found {
        table.insert(key)?;
    }
    Ok((table, stats))
}

fn cancelled(ctx: &TraceContext) -> Result<()> {
    match ctx.cancel {
        Some(c) if c.load(std::sync::atomic::Ordering::Relaxed) => {
            Err(Error::Trace("interrupted".into()))
        }
        _ => Ok(()),
    }
}

/// The k-simplices of the cube at grid vertex `cube` that pass the sign test: rows of k+1
/// grid indices, and their chains S_1 < .. < S_k (k masks each).
fn cube_chains(grid: &Grid, values: &[f64], k: usize, cube: usize) -> (Vec<u32>, Vec<u64>) {
    let d = grid.n.len();
    let corners = 1usize << d;
    let mut base = [0i32; MAX_DIM];
    grid.coords(cube, &mut base[..d]);
    // Storage index of every corner v0 + e_S (all near the box for a base near it).
    let mut corner = vec![0usize; corners];
    let mut v = [0i32; MAX_DIM];
    for (s, c) in corner.iter_mut().enumerate() {
        for j in 0..d {
            v[j] = base[j] + ((s >> j) & 1) as i32;
        }
        match grid.index(&v[..d]) {
            Some(i) => *c = i,
            None => return (Vec::new(), Vec::new()),
        }
    }
    let index = |s: usize| corner[s];
    // Minima and maxima of each component over the supersets of every corner set.
    let mut sup_min = vec![0.0; corners * k];
    for s in 0..corners {
        let v = index(s);
        sup_min[s * k..(s + 1) * k].copy_from_slice(&values[v * k..(v + 1) * k]);
    }
    let mut sup_max = sup_min.clone();
    for j in 0..d {
        for s in 0..corners {
            if s & (1 << j) == 0 {
                let t = s | (1 << j);
                for c in 0..k {
                    sup_min[s * k + c] = sup_min[s * k + c].min(sup_min[t * k + c]);
                    sup_max[s * k + c] = sup_max[s * k + c].max(sup_max[t * k + c]);
                }
            }
        }
    }
    let mut out = (Vec::new(), Vec::new());
    // sup over the supersets of the empty set: the whole cube.
    if (0..k).any(|c| sup_min[c] > 0.0 || sup_max[c] < 0.0) {
        return out;
    }
    let mut chain = vec![0usize; k + 1];
    let run_min = [f64::INFINITY; MAX_SCAN_DIM];
    let run_max = [f64::NEG_INFINITY; MAX_SCAN_DIM];
    let mut walk = ChainWalk {
        d,
        k,
        values,
        index: &index,
        sup_min: &sup_min,
        sup_max: &sup_max,
        chain: &mut chain,
        out: &mut out,
    };
    walk.step(0, 0, run_min, run_max);
    out
}

struct ChainWalk<'a, F: Fn(usize) -> usize> {
    d: usize,
    k: usize,
    values: &'a [f64],
    index: &'a F,
    sup_min: &'a [f64],
    sup_max: &'a [f64],
    chain: &'a mut [usize],
    out: &'a mut (Vec<u32>, Vec<u64>),
}

impl<F: Fn(usize) -> usize> ChainWalk<'_, F> {
    /// Chain position `depth` holds the corner set `s`; extends it to all full chains.
    fn step(
        &mut self,
        depth: usize,
        s: usize,
        mut run_min: [f64; MAX_SCAN_DIM],
        mut run_max: [f64; MAX_SCAN_DIM],
    ) {
        let k = self.k;
        let v = (self.index)(s);
        for c in 0..k {
            run_min[c] = run_min[c].min(self.values[v * k + c]);
            run_max[c] = run_max[c].max(self.values[v * k + c]);
        }
        self.chain[depth] = s;
        if depth == k {
            if (0..k).all(|c| run_min[c] <= 0.0 && run_max[c] >= 0.0) {
                for &t in self.chain.iter() {
                    self.out.0.push((self.index)(t) as u32);
                }
                self.out.1.extend(self.chain[1..].iter().map(|&t| t as u64));
            }
            return;
        }
        // Later vertices are supersets of s: prune when a sign can no longer change.
        for c in 0..k {
            let lo = run_min[c].min(self.sup_min[s * k + c]);
            let hi = run_max[c].max(self.sup_max[s * k + c]);
            if lo > 0.0 || hi < 0.0 {
                return;
            }
        }
        let free = ((1usize << self.d) - 1) & !s;
        if (free.count_ones() as usize) < k - depth {
            return;
        }
        // Every non-empty subset of the free elements, in increasing order.
        let mut add = free & free.wrapping_neg();
        loop {
            self.step(depth + 1, s | add, run_min, run_max);
            if add == free {
                break;
            }
            add = (add.wrapping_sub(free)) & free;
        }
    }
}

/// Connected components of S, two k-simplices being adjacent when they are facets of one
/// (k+1)-simplex.
pub(crate) fn count_components<const W: usize>(
    codec: &crate::triangulation::KeyCodec,
    s: &Table<W>,
) -> Result<usize> {
    let n = s.len();
    let pairs: Vec<(u32, u32)> = (0..n)
        .into_par_iter()
        .flat_map_iter(|i| {
            let own = *s.key(i);
            let mut out = Vec::new();
            let mut key = [0u64; W];
            codec.decode(&own).for_each_cofacet(|tau| {
                tau.for_each_facet(|f| {
                    if codec.encode(f, &mut key).is_ok() {
                        if let Some(j) = s.find(&key) {
                            if j as usize > i {
                                out.push((i as u32, j));
                            }
                        }
                    }
                })
            });
            out
        })
        .collect();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    fn root(p: &mut [u32], mut i: u32) -> u32 {
        while p[i as usize] != i {
            p[i as usize] = p[p[i as usize] as usize];
            i = p[i as usize];
        }
        i
    }
    let mut components = n;
    for (a, b) in pairs {
        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
        if ra != rb {
            parent[ra.max(rb) as usize] = ra.min(rb);
            components -= 1;
        }
    }
    Ok(components)
}
