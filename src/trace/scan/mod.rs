// Index loops over lattice axes read as the coordinates they are.
#![allow(clippy::needless_range_loop)]
//! The exhaustive scan: every k-simplex of T in a box goes through the oracle, with no seed.
//!
//! A k-simplex in canonical form lies in the unit lattice cube at its base vertex v0 (its
//! vertices are v0 + e_S for a chain of subsets S of {1..d}) and has diameter <= edge. So f is
//! evaluated once at the lattice vertices within 2 edge of the box ([`ScanGrid`]); the
//! oracle generates the candidate simplices of the cubes based within `edge` of it (those
//! whose vertices' signs admit a zero: `candidates`, or on a GPU `shaders/scan.wgsl`)
//! and decides them, in batches of cubes sized to about 2^20 candidates.

use rayon::prelude::*;

#[cfg(feature = "internals")]
pub mod candidates;
#[cfg(not(feature = "internals"))]
pub(crate) mod candidates;
#[cfg(feature = "internals")]
pub mod device_values;
#[cfg(not(feature = "internals"))]
pub(crate) mod device_values;
mod grid;
pub mod tiles;

pub use candidates::Candidates;
pub use grid::ScanGrid;

use super::table::{Key, Table};
use super::{
    context, sample_from, warm, with_width, Engine, ImplicitFunction, Oracle, Sample, StopReason,
    TraceContext, TraceOptions, TraceStats, Triangulation,
};
use crate::cpu::solve::Status;
use crate::error::{Error, Result};
use crate::triangulation::{Simplex, MAX_DIM};
use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

/// Largest d for the scan (each cube holds 2^d corners).
pub const MAX_SCAN_DIM: usize = 16;
/// Largest d the device-resident scan takes (each cube holds 2^d corners); above it, the
/// grid's scan with device values.
pub const MAX_TILED_DIM: usize = 8;
/// Candidates per batch the batch size aims at.
const TARGET_CANDIDATES: usize = 1 << 20;
/// Fewest and most vertices (cube bases) per batch.
const BATCH_RANGE: (usize, usize) = (1 << 12, 1 << 20);

/// What a scan found: S (keys in sorted order), the simplices of S near the domain's border
/// (indices into S, in order), counters, with device values the CPU's values it computed
/// (lattice coordinates, rows of d, and values, rows of k), with the CPU's grid the vertices
/// of S (keys, sorted) and f's values there (rows of k), and the bytes its grid held.
pub(crate) struct Scanned<const W: usize> {
    pub table: Table<W>,
    pub border: Vec<u32>,
    pub stats: TraceStats,
    pub cpu_values: Option<(Vec<i32>, Vec<f64>)>,
    pub vertices: Option<(Vec<Key<W>>, Vec<f64>)>,
}

/// A crossed simplex a scan found: its key, and whether its point is near the domain's
/// border ([`Border::near`]).
pub(super) type Hit<const W: usize> = (Key<W>, bool);

/// The crossed simplices a scan has found so far, in any order.
pub(super) struct Found<'a, const W: usize> {
    border: Border<'a>,
    hits: Vec<Hit<W>>,
}

impl<'a, const W: usize> Found<'a, W> {
    /// None yet, in `ctx`'s domain.
    pub(super) fn new(ctx: &TraceContext<'a>) -> Self {
        Found {
            border: Border::new(ctx),
            hits: Vec::new(),
        }
    }

    /// Whether none was found.
    pub(super) fn is_empty(&self) -> bool {
        self.hits.is_empty()
    }

    /// The hit of the crossing `key` whose point (in the domain) is `x`.
    pub(super) fn hit(&self, key: Key<W>, x: &[f64]) -> Hit<W> {
        (key, self.border.near(x))
    }

    /// Adds a hit.
    pub(super) fn push(&mut self, hit: Hit<W>) {
        self.hits.push(hit);
    }

    /// S in key order, with the border among it.
    fn into_scanned(
        self,
        stats: TraceStats,
        cpu_values: Option<(Vec<i32>, Vec<f64>)>,
    ) -> Result<Scanned<W>> {
        let mut hits = self.hits;
        hits.par_sort_unstable();
        hits.dedup_by_key(|h| h.0);
        let border = (0..hits.len() as u32)
            .filter(|&i| hits[i as usize].1)
            .collect();
        // In place: a key takes no more room than a hit.
        let keys: Vec<Key<W>> = hits.into_iter().map(|h| h.0).collect();
        let mut table = Table::fixed();
        table.insert_new_batch(keys.as_flattened())?;
        Ok(Scanned {
            table,
            border,
            stats,
            cpu_values,
            vertices: None,
        })
    }
}

/// Which crossings may have a crossed neighbour outside the domain: the rim is looked for
/// from those only.
///
/// Neighbours share a (k+1)-simplex, so their points lie within one edge of each other: in
/// a box, only a crossing whose point lies within an edge of a face may have a neighbour
/// outside. Boundary inequalities give no such bound: then every crossing may.
pub(super) struct Border<'a> {
    bbox: Option<&'a [[f64; 2]]>,
    reach: f64,
}

impl<'a> Border<'a> {
    /// The border of `ctx`'s domain.
    pub(super) fn new(ctx: &TraceContext<'a>) -> Self {
        let bbox = ctx.domain.bbox.filter(|_| !ctx.domain.has_inequalities());
        let edge = ctx.tri.edge();
        // The edge, padded for the rounding of both points and of the box test.
        let scale = bbox
            .into_iter()
            .flatten()
            .map(|[lo, hi]| lo.abs().max(hi.abs()))
            .fold(edge, f64::max);
        Border {
            bbox,
            reach: edge * (1.0 + 1e-6) + 1e-9 * scale,
        }
    }

    /// Whether a crossing whose point is `x` (in the domain) may have a crossed neighbour
    /// outside it.
    pub(super) fn near(&self, x: &[f64]) -> bool {
        let Some(bbox) = self.bbox else {
            return true;
        };
        bbox.iter()
            .zip(x)
            .any(|(&[lo, hi], &v)| v - lo <= self.reach || hi - v <= self.reach)
    }
}

/// Scans the box. Interrupted (Ctrl-C) between batches, it returns what it found so far,
/// with `stopped` set.
pub(crate) fn scan<const W: usize>(ctx: &TraceContext, bbox: &[[f64; 2]]) -> Result<Scanned<W>> {
    match ctx.oracle.scans().device_values() {
        Some(device) if ctx.d <= MAX_TILED_DIM => tiles::scan(ctx, bbox, device),
        Some(device) => scan_with_device_values(ctx, bbox, device),
        None => scan_slabs(ctx, bbox, grid::SLAB_VERTICES),
    }
}

/// Candidates, then decisions, batch after batch over the cubes `cubes` of `grid`, in
/// order: about TARGET_CANDIDATES candidates per batch at this density, the batch size
/// carried in `size` from call to call. The candidates of the next batch are generated
/// while this one is decided: on a GPU, the scan shader runs while the host settles the
/// solve shader's verdicts. Returns false when Ctrl-C stopped it.
#[allow(clippy::too_many_arguments)]
fn scan_cubes<const W: usize>(
    ctx: &TraceContext,
    grid: &ScanGrid,
    cubes: Range<usize>,
    size: &mut usize,
    mut cpu_values: Option<&mut device_values::CpuValues<'_>>,
    used: Option<&[AtomicU64]>,
    stats: &mut TraceStats,
    found: &mut Found<W>,
) -> Result<bool> {
    let k = ctx.k;
    let end = cubes.end;
    let mut cubes = cubes.start..(cubes.start + *size).min(end);
    let mut batch = if cubes.is_empty() {
        None
    } else {
        Some(ctx.oracle.scans().candidates(grid, cubes.clone())?)
    };
    while let Some(cands) = batch.take() {
        // Ctrl-C: what the batches so far found is kept.
        if ctx.interrupted() {
            stats.stopped = Some(StopReason::Interrupted);
            return Ok(false);
        }
        let m = cands.rows.len() / (k + 1);
        *size = (cubes.len() as u128 * TARGET_CANDIDATES as u128 / m.max(1) as u128)
            .clamp(BATCH_RANGE.0 as u128, BATCH_RANGE.1 as u128) as usize;
        cubes = cubes.end..(cubes.end + *size).min(end);
        let next = cubes.clone();
        // rayon::join, not an OS thread: the scan may run inside a rayon pool, whose workers
        // must keep taking work while they wait (a worker blocked on a thread join starves
        // the pool). No lock is held across either side (see `GpuOracle`'s buffer pools).
        let (ahead, decided) = rayon::join(
            || (!next.is_empty()).then(|| ctx.oracle.scans().candidates(grid, next)),
            || {
                decide_batch(
                    ctx,
                    grid,
                    &cands,
                    cpu_values.as_deref_mut(),
                    used,
                    stats,
                    found,
                )
            },
        );
        decided?;
        batch = ahead.transpose()?;
    }
    Ok(true)
}

/// The scan with f's values from the device, over the whole grid at once.
fn scan_with_device_values<const W: usize>(
    ctx: &TraceContext,
    bbox: &[[f64; 2]],
    device: &dyn crate::trace::DeviceValues,
) -> Result<Scanned<W>> {
    let grid = match grid::build(ctx, bbox) {
        // Interrupted while f is evaluated on the grid: nothing found yet, kept as such.
        Err(_) if ctx.interrupted() => {
            let stats = TraceStats {
                stopped: Some(StopReason::Interrupted),
                ..TraceStats::default()
            };
            return Found::new(ctx).into_scanned(stats, None);
        }
        g => g?,
    };
    let mut cpu_values = device_values::CpuValues::new(device);
    let mut stats = TraceStats {
        vertices: grid.len() as u64,
        device_vertex_evaluations: grid.len() as u64,
        ..TraceStats::default()
    };
    let mut found = Found::new(ctx);
    let mut size = BATCH_RANGE.0;
    scan_cubes(
        ctx,
        &grid,
        0..grid.len(),
        &mut size,
        Some(&mut cpu_values),
        None,
        &mut stats,
        &mut found,
    )?;
    // Nothing found: say whether f was NaN or infinite on the grid (such vertices have no
    // sign, so no candidate counted them).
    if found.is_empty() && stats.non_finite == 0 {
        stats.non_finite = non_finite(grid.values());
    }
    let cpu_values = cpu_values.into_lattice(&grid);
    // S's table is built without the grid alive.
    drop(grid);
    found.into_scanned(stats, Some(cpu_values))
}

/// Values of f that are NaN or infinite.
fn non_finite(values: &[f64]) -> u64 {
    values.par_iter().filter(|v| !v.is_finite()).count() as u64
}

/// The scan with the CPU's values, a slab of the grid at a time ([`grid::Slabs`], at least
/// `slab` vertices each): the vertices of S and f's values there are kept from each slab as
/// it is left.
fn scan_slabs<const W: usize>(
    ctx: &TraceContext,
    bbox: &[[f64; 2]],
    slab: usize,
) -> Result<Scanned<W>> {
    let slabs = grid::Slabs::new(ctx, bbox, slab)?;
    let mut stats = TraceStats::default();
    let mut found = Found::new(ctx);
    let mut size = BATCH_RANGE.0;
    let (mut keys, mut values) = (Vec::new(), Vec::new());
    // Vertices of the last window's next layer (the next window's first) that S uses.
    let mut carried: Vec<u32> = Vec::new();
    let mut grid_non_finite = 0;
    let mut window = None;
    for i in 0..slabs.len() {
        let mut next = slabs.window(i, window.take());
        // The grid vertices of S, one bit each: f's values there are kept for the sample.
        let used: Vec<AtomicU64> = (0..next.grid.len().div_ceil(64))
            .map(|_| AtomicU64::new(0))
            .collect();
        for &j in &carried {
            used[j as usize / 64].fetch_or(1 << (j % 64), Ordering::Relaxed);
        }
        let evaluated = slabs.evaluate(&mut next);
        // Every vertex is evaluated once: the grid's vertices so far.
        stats.vertices += next.evaluated as u64;
        stats.cpu_vertex_evaluations += next.evaluated as u64;
        match evaluated {
            // Interrupted while f is evaluated: what the slabs so far found is kept, with
            // the values of its vertices in this window's first layer.
            Err(_) if ctx.interrupted() => {
                stats.stopped = Some(StopReason::Interrupted);
                marked_vertices(ctx, &next.grid, &used, 0..next.kept, &mut keys, &mut values)?;
                break;
            }
            e => e?,
        }
        let (grid, own) = (&next.grid, next.own);
        let whole = scan_cubes(
            ctx,
            grid,
            0..own,
            &mut size,
            None,
            Some(&used),
            &mut stats,
            &mut found,
        )?;
        if found.is_empty() {
            grid_non_finite += non_finite(&grid.values()[..own * ctx.k]);
        }
        // Stopped, S may use any vertex of the window; else the next one keeps the rest.
        let kept = if whole { own } else { grid.len() };
        marked_vertices(ctx, grid, &used, 0..kept, &mut keys, &mut values)?;
        carried = marked(&used, kept..grid.len())
            .map(|j| j - kept as u32)
            .collect();
        window = Some(next);
        if !whole {
            break;
        }
    }
    drop(window);
    // Nothing found: say whether f was NaN or infinite on the grid (such vertices have no
    // sign, so no candidate counted them).
    if found.is_empty() && stats.non_finite == 0 {
        stats.non_finite = grid_non_finite;
    }
    // Storage order is key order for one-word keys (the last axis is the most significant).
    if !keys.windows(2).all(|w| w[0] < w[1]) {
        let k = ctx.k;
        let mut order: Vec<(Key<W>, u32)> = keys.into_iter().zip(0..).collect();
        order.par_sort_unstable();
        values = order
            .iter()
            .flat_map(|&(_, i)| &values[i as usize * k..(i as usize + 1) * k])
            .copied()
            .collect();
        keys = order.into_iter().map(|(key, _)| key).collect();
    }
    let mut scanned = found.into_scanned(stats, None)?;
    scanned.vertices = Some((keys, values));
    Ok(scanned)
}

/// The indices in `range` whose bit is set in `used` (one per vertex), in order.
fn marked(used: &[AtomicU64], range: Range<usize>) -> impl Iterator<Item = u32> + '_ {
    let (lo, hi) = (range.start, range.end);
    (lo / 64..hi.div_ceil(64)).flat_map(move |w| {
        // The word's bits within the range.
        let mut bits = used[w].load(Ordering::Relaxed);
        if w * 64 < lo {
            bits &= !0 << (lo - w * 64);
        }
        if (w + 1) * 64 > hi {
            bits &= !(!0 << (hi - w * 64));
        }
        std::iter::from_fn(move || {
            (bits != 0).then(|| {
                let b = bits.trailing_zeros();
                bits &= bits - 1;
                (w * 64) as u32 + b
            })
        })
    })
}

/// Appends the grid vertices in `range` whose bit is set in `used` (one per vertex, in
/// storage order) to `keys`, in storage order, and f's values there (rows of k) to
/// `values`.
fn marked_vertices<const W: usize>(
    ctx: &TraceContext,
    grid: &ScanGrid,
    used: &[AtomicU64],
    range: Range<usize>,
    keys: &mut Vec<Key<W>>,
    values: &mut Vec<f64>,
) -> Result<()> {
    let (d, k) = (grid.dim(), grid.codim());
    let words = range.start / 64..range.end.div_ceil(64);
    let marked: Vec<u32> = words
        .into_par_iter()
        .step_by(64)
        .flat_map_iter(|w| {
            marked(
                used,
                (w * 64).max(range.start)..((w + 64) * 64).min(range.end),
            )
        })
        .collect();
    let from = keys.len();
    keys.resize(from + marked.len(), [0u64; W]);
    // Vertices in storage order: each piece finds its first row, then steps along.
    marked
        .par_chunks(4096)
        .zip(keys[from..].par_chunks_mut(4096))
        .try_for_each(|(idx, keys)| -> Result<()> {
            let mut r = grid.row_of(idx[0] as usize);
            let mut v = [0i32; MAX_DIM];
            for (&i, key) in idx.iter().zip(keys) {
                grid.coords_from(&mut r, i as usize, &mut v[..d]);
                ctx.codec.encode_vertex_w(&v[..d], key)?;
            }
            Ok(())
        })?;
    let at = grid.values();
    values.extend(
        marked
            .iter()
            .flat_map(|&i| &at[i as usize * k..(i as usize + 1) * k]),
    );
    Ok(())
}

/// Decides the candidates `cands` of the grid (of device values where `cpu_values` is
/// given: [`device_values`]) and appends the crossed ones whose point lies in the domain to
/// `found`, setting their vertices' bits in `used` when given.
fn decide_batch<const W: usize>(
    ctx: &TraceContext,
    grid: &ScanGrid,
    cands: &Candidates,
    cpu_values: Option<&mut device_values::CpuValues<'_>>,
    used: Option<&[AtomicU64]>,
    stats: &mut TraceStats,
    found: &mut Found<W>,
) -> Result<()> {
    let (d, k) = (ctx.d, ctx.k);
    let Candidates { rows, chains } = cands;
    let m = rows.len() / (k + 1);
    let mut status = vec![Status::Outside; m];
    let mut lambda = vec![0.0; m * (k + 1)];
    if let Some(cpu) = cpu_values {
        device_values::decide(ctx, grid, rows, cpu, stats, &mut status, &mut lambda)?;
    } else {
        let how = ctx
            .oracle
            .decisions()
            .decide(grid.values(), rows, &mut status, &mut lambda)?;
        stats.count_decisions(&status, how);
    }
    if stats.zero_region.is_none() && status.contains(&Status::Degenerate) {
        stats.zero_region = crate::trace::checks::zero_region(
            ctx.f,
            &status,
            rows,
            grid.values(),
            ctx.tri.edge(),
            |i, x| {
                let mut v = [0i32; MAX_DIM];
                grid.coords(i, &mut v[..d]);
                ctx.tri.vertex_coords(&v[..d], x);
            },
        );
    }
    // Candidates come in order of base: each piece walks the grid's rows along.
    const PIECE: usize = 1024;
    let (status, lambda) = (&status, &lambda);
    let hits: Vec<Result<Option<Hit<W>>>> = (0..m.div_ceil(PIECE))
        .into_par_iter()
        .flat_map_iter(|c| {
            let mut at = grid::RowCursor::default();
            let found = &*found;
            (c * PIECE..((c + 1) * PIECE).min(m))
                .filter(|&i| status[i].crossed())
                .map(move |i| {
                    let row = &rows[i * (k + 1)..(i + 1) * (k + 1)];
                    let chain = &chains[i * k..(i + 1) * k];
                    let lam = &lambda[i * (k + 1)..(i + 1) * (k + 1)];
                    let mut point = [0.0; MAX_DIM];
                    let mut v = [0i32; MAX_DIM];
                    grid.coords_at(&mut at, row[0] as usize, &mut v[..d]);
                    // Vertex j is v0 + e_S for the corner set S = S_j (bit a: +1 on axis a).
                    ctx.tri.barycentric_point(
                        lam,
                        |j, out| {
                            out.copy_from_slice(&v[..d]);
                            if j > 0 {
                                for (a, u) in out.iter_mut().enumerate() {
                                    *u += (chain[j - 1] >> a & 1) as i32;
                                }
                            }
                        },
                        &mut point[..d],
                    );
                    if !ctx.domain.contains(&point[..d]) {
                        return Ok(None);
                    }
                    if let Some(used) = used {
                        for &j in row {
                            used[j as usize / 64].fetch_or(1 << (j % 64), Ordering::Relaxed);
                        }
                    }
                    chain_key(ctx, &v[..d], chain).map(|key| Some(found.hit(key, &point[..d])))
                })
                .collect::<Vec<_>>()
        })
        .collect();
    for h in hits {
        if let Some(hit) = h? {
            found.push(hit);
        }
    }
    Ok(())
}

/// The key of the k-simplex of the lattice cube based at `v0` whose vertices are v0 + e_S for
/// the empty set and the corner sets `chain` (S_1 < .. < S_k; bit j: axis j).
pub(super) fn chain_key<const W: usize>(
    ctx: &TraceContext,
    v0: &[i32],
    chain: &[u32],
) -> Result<Key<W>> {
    let (d, k) = (v0.len(), chain.len());
    let full = (1u64 << d) - 1;
    let mut parts = [0u64; MAX_DIM + 1];
    let mut prev = 0;
    for (j, &s) in chain.iter().enumerate() {
        parts[j] = s as u64 & !prev;
        prev = s as u64;
    }
    parts[k] = (full & !prev) | (1 << d);
    debug_assert!(Simplex::from_masks(v0, &parts[..=k]).is_ok());
    let mut key = [0u64; W];
    ctx.codec.encode_masks_w(v0, &parts[..=k], &mut key)?;
    Ok(key)
}

/// An error when the cancel flag (Ctrl-C) is set: for steps that have nothing to keep.
pub(super) fn cancelled(ctx: &TraceContext) -> Result<()> {
    if ctx.interrupted() {
        return Err(Error::Interrupted(
            "the exhaustive scan was interrupted".into(),
        ));
    }
    Ok(())
}

/// Connected components of S, two k-simplices being adjacent when they are facets of one
/// (k+1)-simplex: the (k+1)-cofaces of every simplex are keyed and sorted, and the simplices
/// that share one are joined. The cofaces go in passes, split by key hash, when they would
/// take more than `budget` bytes at once.
pub(crate) fn count_components<const W: usize>(
    codec: &crate::triangulation::KeyCodec,
    s: &Table<W>,
    budget: u64,
) -> Result<usize> {
    let (d, l) = (codec.ambient_dim(), codec.simplex_dim());
    if l >= d {
        return Ok(s.len());
    }
    // One more bit per coordinate: a coface's base lies one step beyond its facets' at most.
    let bits = (codec.coord_bits() + 1).min(32);
    let cofaces = crate::triangulation::KeyCodec::new(d, l + 1, bits)?;
    let key = |i: usize| s.key(i).as_slice();
    with_width!(
        cofaces.words(),
        join_cofaces(codec, &cofaces, s.len(), &key, budget)
    )
}

/// [`count_components`] with coface keys of V words, for the `n` simplices `key(i)`.
fn join_cofaces<'s, const V: usize>(
    codec: &crate::triangulation::KeyCodec,
    cofaces: &crate::triangulation::KeyCodec,
    n: usize,
    key: &(dyn Fn(usize) -> &'s [u64] + Sync),
    budget: u64,
) -> Result<usize> {
    // Simplices decode into a scratch per thread (a fresh simplex per key cost a clear and
    // a copy of its full-size arrays).
    let total: u64 = (0..n)
        .into_par_iter()
        .map_init(
            || codec.scratch(),
            |s, i| {
                codec.decode_into(key(i), s);
                s.cofacet_count()
            },
        )
        .sum();
    const CHUNK: usize = 4096;
    // Collected in pieces, then joined: twice the entries' bytes at the join.
    let entry = 2 * size_of::<([u64; V], u32)>() as u64;
    let passes = (total.saturating_mul(entry) / budget.max(1) + 1).min(u32::MAX as u64);
    let hasher = foldhash::fast::FixedState::default();
    // Cofaces per simplex and pass, on average: a piece's first capacity.
    let per_pass = (total / (n as u64).max(1) / passes + 1) as usize;
    let mut parent: Vec<u32> = (0..n as u32).collect();
    let mut components = n;
    for pass in 0..passes {
        // A piece per chunk of simplices, then one parallel copy into place.
        let pieces: Vec<Vec<([u64; V], u32)>> = (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map_init(
                || codec.scratch(),
                |s, c| {
                    let range = c * CHUNK..((c + 1) * CHUNK).min(n);
                    let mut out = Vec::with_capacity(range.len() * per_pass);
                    let mut coface = [0u64; V];
                    for i in range {
                        codec.decode_into(key(i), s);
                        s.for_each_cofacet(|tau| {
                            // A coface past the coordinate range joins nothing (none of S
                            // is there).
                            if cofaces
                                .encode_masks_w(tau.base(), tau.parts(), &mut coface)
                                .is_ok()
                                && (passes == 1
                                    || std::hash::BuildHasher::hash_one(&hasher, coface) % passes
                                        == pass)
                            {
                                out.push((coface, i as u32));
                            }
                        });
                    }
                    out
                },
            )
            .collect();
        for (a, b) in joins(pieces) {
            if union(&mut parent, a, b) {
                components -= 1;
            }
        }
    }
    Ok(components)
}

/// Pairs (coface, simplex) per bucket of [`joins`]: about this many, so that a bucket's map
/// stays in cache.
const BUCKET_PAIRS: usize = 1 << 15;

/// The simplices to join for the pairs (coface, simplex) in `pieces`: each simplex with the
/// first one listed with the same coface. The pairs are split into buckets by a hash of the
/// coface (a counting sort of each piece), and each bucket is matched through a small hash
/// map, in parallel.
fn joins<const V: usize>(mut pieces: Vec<Vec<([u64; V], u32)>>) -> Vec<(u32, u32)> {
    let total: usize = pieces.iter().map(Vec::len).sum();
    // Each piece keeps a start per bucket, and each bucket visits every piece: at most a
    // quarter as many (piece, bucket) as pairs.
    let most = total / (4 * pieces.len()).max(1);
    let bits = (total / BUCKET_PAIRS).min(most).max(1).ilog2().min(16);
    let buckets = 1usize << bits;
    // A hasher of its own: the maps' hashes must not be equal in their top bits.
    let split = foldhash::fast::FixedState::with_seed(0x5eed);
    let bucket = |key: &[u64; V]| match bits {
        0 => 0,
        _ => (std::hash::BuildHasher::hash_one(&split, key) >> (64 - bits)) as usize,
    };
    // Per piece, its pairs ordered by bucket, and where each bucket starts (buckets + 1).
    let starts: Vec<Vec<usize>> = pieces
        .par_iter_mut()
        .map(|piece| {
            let ids: Vec<u32> = piece.iter().map(|p| bucket(&p.0) as u32).collect();
            let mut start = vec![0usize; buckets + 1];
            for &b in &ids {
                start[b as usize + 1] += 1;
            }
            for b in 0..buckets {
                start[b + 1] += start[b];
            }
            let mut at = start.clone();
            let mut sorted = vec![([0u64; V], 0u32); piece.len()];
            for (p, &b) in piece.iter().zip(&ids) {
                sorted[at[b as usize]] = *p;
                at[b as usize] += 1;
            }
            *piece = sorted;
            start
        })
        .collect();
    (0..buckets)
        .into_par_iter()
        .map_init(hashbrown::HashMap::<[u64; V], u32>::new, |first, b| {
            first.clear();
            let mut out = Vec::new();
            for (piece, start) in pieces.iter().zip(&starts) {
                for &(key, i) in &piece[start[b]..start[b + 1]] {
                    match first.entry(key) {
                        hashbrown::hash_map::Entry::Occupied(e) => out.push((*e.get(), i)),
                        hashbrown::hash_map::Entry::Vacant(e) => {
                            e.insert(i);
                        }
                    }
                }
            }
            out
        })
        .flatten_iter()
        .collect()
}

/// Joins the sets of `a` and `b` (union-find with path halving, the smaller index the root);
/// whether they were apart.
fn union(parent: &mut [u32], a: u32, b: u32) -> bool {
    fn root(p: &mut [u32], mut i: u32) -> u32 {
        while p[i as usize] != i {
            p[i as usize] = p[p[i as usize] as usize];
            i = p[i as usize];
        }
        i
    }
    let (ra, rb) = (root(parent, a), root(parent, b));
    if ra == rb {
        return false;
    }
    parent[ra.max(rb) as usize] = ra.min(rb);
    true
}

/// Every crossed k-simplex of `tri` whose point lies in `opts.bbox` (required), with no seed.
/// Components are counted by a union-find over shared (k+1)-cofaces.
pub fn exhaustive(
    f: &dyn ImplicitFunction,
    tri: &Triangulation,
    oracle: &dyn Oracle,
    opts: &TraceOptions,
) -> Result<Sample> {
    let ctx = context(f, tri, oracle, opts)?;
    scan_box(opts)?;
    let words = ctx.codec.words();
    warm::maybe(opts.warm, || with_width!(words, exhaustive_with(ctx)))
}

fn scan_box<'a>(opts: &'a TraceOptions) -> Result<&'a [[f64; 2]]> {
    opts.bbox.as_deref().ok_or_else(|| {
        Error::Trace("the exhaustive scan needs a box (spec `box`, or --box)".into())
    })
}

/// The lattice vertices the exhaustive scan of `opts`' box reads, with f (from `oracle`) and
/// sign codes at each: what [`Scan::candidates`](crate::trace::Scan::candidates) generates candidates from. For
/// comparing candidate generators; [`exhaustive`] builds its own.
pub fn scan_grid(
    f: &dyn ImplicitFunction,
    tri: &Triangulation,
    oracle: &dyn Oracle,
    opts: &TraceOptions,
) -> Result<ScanGrid> {
    let ctx = context(f, tri, oracle, opts)?;
    grid::build(&ctx, scan_box(opts)?)
}

fn exhaustive_with<const W: usize>(ctx: TraceContext) -> Result<Sample> {
    let start = Instant::now();
    let bbox = ctx.domain.bbox.expect("checked by exhaustive()");
    let codec = ctx.codec;
    let scanned = scan::<W>(&ctx, bbox)?;
    // For the cofaces at once: an eighth of the memory left, and never under 16 MiB.
    let room = ctx
        .max_memory
        .saturating_sub(crate::memory::in_use(scanned.table.memory_bytes()));
    let budget = (room / 8).max(16 << 20);
    let components = count_components(&codec, &scanned.table, budget)?;
    let mut engine: Engine<W> = Engine::new(ctx);
    engine.s = scanned.table;
    engine.stats = scanned.stats;
    if let Some((lattice, values)) = &scanned.cpu_values {
        engine.seed_vertices(lattice, values)?;
    }
    match &scanned.vertices {
        Some((keys, values)) => engine.cache_sorted_values(keys, values)?,
        None => engine.cache_vertices_of_s()?,
    }
    engine.complete_rim(scanned.border)?;
    let mut stats = engine.stats.clone();
    stats.components = components;
    stats.memory_bytes = engine.bytes() as u64;
    stats.elapsed_s = start.elapsed().as_secs_f64();
    let tri = engine.ctx.tri;
    sample_from(codec, tri, engine, stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::expr::preset;
    use crate::trace::CpuOracle;

    /// The buckets' joins link the simplices that share a coface exactly as grouping all
    /// pairs by coface does: 200,000 pairs in three pieces, over 60,000 cofaces (many
    /// buckets).
    #[test]
    fn joins_group_the_simplices_of_each_coface() {
        let n = 200_000u32;
        let mut pieces = vec![Vec::new(); 3];
        let mut cofaces = Vec::new();
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        for i in 0..n {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let key = [x % 60_000];
            cofaces.push(key);
            pieces[(x >> 32) as usize % 3].push((key, i));
        }
        let mut joined: Vec<u32> = (0..n).collect();
        let mut got = n as usize;
        for (a, b) in joins(pieces) {
            assert_eq!(cofaces[a as usize], cofaces[b as usize]);
            got -= union(&mut joined, a, b) as usize;
        }
        let mut grouped: Vec<u32> = (0..n).collect();
        let mut want = n as usize;
        let mut by_key: Vec<([u64; 1], u32)> = cofaces.iter().copied().zip(0..n).collect();
        by_key.sort_unstable();
        for run in by_key.chunk_by(|a, b| a.0 == b.0) {
            for &(_, j) in &run[1..] {
                want -= union(&mut grouped, run[0].1, j) as usize;
            }
        }
        assert_eq!(got, want);
        assert!(want > 50_000 && want < 70_000, "{want}");
    }

    /// A scan in many slabs finds what one window over the whole grid finds: the same S,
    /// border, vertices of S and values there, bit for bit, and evaluates f once per vertex.
    #[test]
    fn slabs_scan_as_one_window() {
        type Case<'a> = (&'a str, &'a [(&'a str, f64)], [[f64; 2]; 3]);
        let cases: [Case; 2] = [
            (
                "torus",
                &[("edge", 0.04)],
                [[-1.5, 1.5], [-1.5, 0.9], [-0.5, 0.5]],
            ),
            // k = 2: a circle, its box cut so that some slabs hold none of it.
            (
                "sphere",
                &[("m", 1.0), ("d", 3.0), ("edge", 0.015)],
                [[-0.5, 1.5], [-2.0, 2.0], [-1.0, 1.0]],
            ),
        ];
        for (name, params, bbox) in cases {
            let params: Vec<(String, f64)> =
                params.iter().map(|(n, v)| (n.to_string(), *v)).collect();
            let p = preset(name, &params).unwrap();
            let tri = p.triangulation.build(p.dim()).unwrap();
            let oracle = CpuOracle::new(&p.system);
            let opts = TraceOptions {
                bbox: Some(bbox.to_vec()),
                ..TraceOptions::default()
            };
            let ctx = context(&p.system, &tri, &oracle, &opts).unwrap();
            let one: Scanned<1> = scan_slabs(&ctx, &bbox, usize::MAX).unwrap();
            assert_eq!(grid::Slabs::new(&ctx, &bbox, usize::MAX).unwrap().len(), 1);
            assert!(one.table.len() > 1000, "{name}: {}", one.table.len());
            for slab in [1, 5000] {
                let count = grid::Slabs::new(&ctx, &bbox, slab).unwrap().len();
                assert!(count > 10, "{name}: {count} slabs of {slab}");
                let many: Scanned<1> = scan_slabs(&ctx, &bbox, slab).unwrap();
                let keys = |s: &Scanned<1>| {
                    (0..s.table.len())
                        .map(|i| *s.table.key(i))
                        .collect::<Vec<_>>()
                };
                assert_eq!(keys(&many), keys(&one), "{name}, slabs of {slab}");
                assert_eq!(many.border, one.border, "{name}, slabs of {slab}");
                let bits = |s: &Scanned<1>| {
                    let (keys, values) = s.vertices.as_ref().unwrap();
                    let bits: Vec<u64> = values.iter().map(|v| v.to_bits()).collect();
                    (keys.clone(), bits)
                };
                assert_eq!(bits(&many), bits(&one), "{name}, slabs of {slab}");
                assert_eq!(many.stats.vertices, one.stats.vertices);
                assert_eq!(many.stats.cpu_vertex_evaluations, one.stats.vertices);
                assert_eq!(many.stats.oracle_calls, one.stats.oracle_calls);
            }
        }
    }

    /// Components counted through shared cofaces, against the known count of pieces a box
    /// cuts M into, in one pass and in many.
    #[test]
    fn components_are_the_pieces_the_box_cuts() {
        type Case<'a> = (&'a str, &'a [(&'a str, f64)], [[f64; 2]; 3], usize);
        let cases: [Case; 4] = [
            // The slab |x| <= 0.3 cuts two arcs of the tube.
            (
                "torus",
                &[("edge", 0.08)],
                [[-0.3, 0.3], [-2.0, 2.0], [-1.0, 1.0]],
                2,
            ),
            (
                "torus",
                &[("edge", 0.08)],
                [[-2.0, 2.0], [-2.0, 2.0], [-1.0, 1.0]],
                1,
            ),
            // A circle in R^3 (k = 2), cut into two arcs.
            (
                "sphere",
                &[("m", 1.0), ("d", 3.0), ("edge", 0.05)],
                [[-0.5, 0.5], [-2.0, 2.0], [-1.0, 1.0]],
                2,
            ),
            // A band of the sphere.
            (
                "sphere",
                &[("edge", 0.1)],
                [[-2.0, 2.0], [-2.0, 2.0], [-0.4, 0.5]],
                1,
            ),
        ];
        for (name, params, bbox, pieces) in cases {
            let params: Vec<(String, f64)> =
                params.iter().map(|(n, v)| (n.to_string(), *v)).collect();
            let p = preset(name, &params).unwrap();
            let tri = p.triangulation.build(p.dim()).unwrap();
            let oracle = CpuOracle::new(&p.system);
            let opts = TraceOptions {
                bbox: Some(bbox.to_vec()),
                ..TraceOptions::default()
            };
            let sample = exhaustive(&p.system, &tri, &oracle, &opts).unwrap();
            assert_eq!(sample.stats.components, pieces, "{name} in {bbox:?}");
            let ctx = context(&p.system, &tri, &oracle, &opts).unwrap();
            assert_eq!(ctx.codec.words(), 1);
            let mut s: Table<1> = Table::fixed();
            for i in 0..sample.len() {
                s.insert(sample.key(i)).unwrap();
            }
            for budget in [1 << 40, 1 << 16] {
                let components = count_components(&ctx.codec, &s, budget).unwrap();
                assert_eq!(components, pieces, "{name} in {bbox:?}, budget {budget}");
            }
        }
    }
}
