//! Manifold tracing (Algorithm 1 of the papers), one level at a time: the crossed k-simplices
//! found last are the frontier; the k-facets of their cofacets that are not yet known are the
//! candidates, deduplicated and sent to the oracle as one batch; the crossed ones are the next
//! frontier. Every order here is a sorted order, so the output does not depend on threads.

use std::ops::Range;
use std::sync::atomic::Ordering;

use foldhash::fast::FixedState;
use hashbrown::HashSet;
use rayon::prelude::*;

use super::table::{Key, Table};
use super::{Progress, StopReason, TraceContext, TraceStats};
use crate::cpu::decide::Status;
use crate::error::Result;

/// Marks a vertex not yet in the cache.
const MISSING: u32 = u32::MAX;
/// Candidates per parallel work item.
const CHUNK: usize = 512;

/// The state of one trace: the sample S, its points, the vertex-value cache, and the
/// candidates recently found not crossed.
pub(crate) struct Engine<'a, const W: usize> {
    pub ctx: TraceContext<'a>,
    pub s: Table<W>,
    pub points: Vec<f64>,
    /// Crossed simplices whose point lies outside the domain, next to S (the far ends of
    /// the edges of M-hat that the domain's boundary cuts).
    pub rim: Table<W>,
    pub rim_points: Vec<f64>,
    verts: Table<W>,
    values: Vec<f64>,
    /// Rejected candidates of the previous and the current level (re-tests are only work).
    rejected: [HashSet<Key<W>, FixedState>; 2],
    pub stats: TraceStats,
}

/// Oracle verdicts on a batch of candidates.
pub(crate) struct Verdicts {
    pub status: Vec<Status>,
    pub lambda: Vec<f64>,
}

impl<'a, const W: usize> Engine<'a, W> {
    pub fn new(ctx: TraceContext<'a>) -> Self {
        let hs = || HashSet::with_hasher(FixedState::with_seed(0x0dd5_eed5));
        Engine {
            ctx,
            s: Table::new(),
            points: Vec::new(),
            rim: Table::new(),
            rim_points: Vec::new(),
            verts: Table::new(),
            values: Vec::new(),
            rejected: [hs(), hs()],
            stats: TraceStats::default(),
        }
    }

    /// Bytes held by the trace's containers.
    pub fn bytes(&self) -> usize {
        let set = |h: &HashSet<Key<W>, FixedState>| h.allocation_size();
        self.s.bytes()
            + self.points.capacity() * 8
            + self.rim.bytes()
            + self.rim_points.capacity() * 8
            + self.verts.bytes()
            + self.values.capacity() * 8
            + set(&self.rejected[0])
            + set(&self.rejected[1])
    }

    /// Whether the trace must stop now (Ctrl-C, or the next step would pass the memory limit).
    fn must_stop(&mut self, next_bytes: usize) -> bool {
        if let Some(c) = self.ctx.cancel {
            if c.load(Ordering::Relaxed) {
                self.stats.stopped = Some(StopReason::Interrupted);
                return true;
            }
        }
        let need = (self.bytes() + next_bytes) as u64;
        if need > self.ctx.max_memory {
            self.stats.stopped = Some(StopReason::MemoryLimit {
                needed: need,
                limit: self.ctx.max_memory,
            });
            return true;
        }
        false
    }

    /// Breadth-first trace from the simplices `frontier` (indices into S) until no new
    /// crossed simplex appears, the box is exhausted or a stop is requested.
    pub fn run(&mut self, mut frontier: Range<usize>) -> Result<()> {
        let (d, k) = (self.ctx.d, self.ctx.k);
        while !frontier.is_empty() {
            let cands = self.neighbours(frontier.clone())?;
            let per_candidate = W * 8 + (k + 1) * 12 + 1 + 2 * (W * 8 + d * 8 + 8);
            if self.must_stop(cands.len() * per_candidate) {
                return Ok(());
            }
            let verdicts = self.evaluate(&cands)?;
            let start = self.s.len();
            self.accept(&cands, &verdicts)?;
            frontier = start..self.s.len();
            self.stats.levels += 1;
            if let Some(p) = self.ctx.progress {
                p(&Progress {
                    simplices: self.s.len(),
                    level: self.stats.levels,
                    frontier: frontier.len(),
                    vertices: self.verts.len(),
                });
            }
        }
        Ok(())
    }

    /// Finds the rim of a sample built elsewhere (the scan): the crossed neighbours of S
    /// outside the domain.
    pub fn complete_rim(&mut self) -> Result<()> {
        let cands = self.neighbours(0..self.s.len())?;
        let cands: Vec<Key<W>> = cands
            .into_iter()
            .filter(|c| self.rim.find(c).is_none())
            .collect();
        let verdicts = self.evaluate(&cands)?;
        let (crossed, points) = self.crossed_points(&cands, &verdicts);
        for (&i, p) in crossed.iter().zip(points.chunks_exact(self.ctx.d)) {
            self.rim.insert(&cands[i])?;
            self.rim_points.extend_from_slice(p);
        }
        Ok(())
    }

    /// The k-facets of the cofacets of the frontier that are neither in S nor recently
    /// rejected, sorted and deduplicated.
    fn neighbours(&self, frontier: Range<usize>) -> Result<Vec<Key<W>>> {
        let codec = &self.ctx.codec;
        let mut cands = frontier
            .into_par_iter()
            .with_min_len(64)
            .try_fold(Vec::new, |mut acc, i| -> Result<Vec<Key<W>>> {
                let own = *self.s.key(i);
                let sigma = codec.decode(&own);
                let mut key = [0u64; W];
                let mut err = None;
                sigma.for_each_cofacet(|tau| {
                    tau.for_each_facet(|f| {
                        if err.is_some() {
                            return;
                        }
                        if let Err(e) = codec.encode(f, &mut key) {
                            err = Some(e);
                            return;
                        }
                        if key != own
                            && self.s.find(&key).is_none()
                            && !self.rejected[0].contains(&key)
                            && !self.rejected[1].contains(&key)
                        {
                            acc.push(key);
                        }
                    })
                });
                match err {
                    Some(e) => Err(e),
                    None => Ok(acc),
                }
            })
            .try_reduce(Vec::new, |mut a, mut b| {
                a.append(&mut b);
                Ok(a)
            })?;
        cands.par_sort_unstable();
        cands.dedup();
        Ok(cands)
    }

    /// Writes the vertex-cache index of every vertex of every candidate into `idx` (k+1 per
    /// candidate), `MISSING` where the vertex is not cached; returns the missing vertex keys.
    /// With `only_missing`, rows without a `MISSING` entry are left alone.
    fn vertex_indices(
        &self,
        cands: &[Key<W>],
        idx: &mut [u32],
        only_missing: bool,
    ) -> Result<Vec<Key<W>>> {
        let n = self.ctx.k + 1;
        let codec = &self.ctx.codec;
        let missing = cands
            .par_chunks(CHUNK)
            .zip(idx.par_chunks_mut(CHUNK * n))
            .map(|(cs, rows)| -> Result<Vec<Key<W>>> {
                let mut miss = Vec::new();
                let mut vk = [0u64; W];
                for (c, row) in cs.iter().zip(rows.chunks_exact_mut(n)) {
                    if only_missing && !row.contains(&MISSING) {
                        continue;
                    }
                    let mut err = None;
                    codec.decode(c).for_each_vertex(|i, v| {
                        if let Err(e) = codec.encode_vertex(v, &mut vk) {
                            err = Some(e);
                            return;
                        }
                        row[i] = match self.verts.find(&vk) {
                            Some(j) => j,
                            None => {
                                miss.push(vk);
                                MISSING
                            }
                        };
                    });
                    if let Some(e) = err {
                        return Err(e);
                    }
                }
                Ok(miss)
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(missing.concat())
    }

    /// Runs the oracle on `cands`: vertex values first (each lattice vertex once per trace),
    /// then the decisions.
    pub fn evaluate(&mut self, cands: &[Key<W>]) -> Result<Verdicts> {
        let (d, k) = (self.ctx.d, self.ctx.k);
        let n = k + 1;
        let mut idx = vec![0u32; cands.len() * n];
        let mut missing = self.vertex_indices(cands, &mut idx, false)?;
        if !missing.is_empty() {
            missing.par_sort_unstable();
            missing.dedup();
            let mut lattice = vec![0i32; missing.len() * d];
            lattice
                .par_chunks_mut(d)
                .zip(&missing)
                .for_each(|(v, key)| self.ctx.codec.decode_vertex(key, v));
            let mut vals = vec![0.0; missing.len() * k];
            self.ctx
                .oracle
                .eval_vertices(self.ctx.tri, &lattice, &mut vals)?;
            for key in &missing {
                self.verts.insert(key)?;
            }
            self.values.extend_from_slice(&vals);
            self.stats.vertices += missing.len() as u64;
            let left = self.vertex_indices(cands, &mut idx, true)?;
            debug_assert!(left.is_empty());
        }
        let mut status = vec![Status::Outside; cands.len()];
        let mut lambda = vec![0.0; cands.len() * n];
        self.stats.exact_decisions +=
            self.ctx
                .oracle
                .decide(&self.values, &idx, &mut status, &mut lambda)?;
        self.stats.oracle_calls += cands.len() as u64;
        for s in &status {
            match s {
                Status::Degenerate => self.stats.degenerate += 1,
                Status::NonFinite => self.stats.non_finite += 1,
                _ => {}
            }
        }
        Ok(Verdicts { status, lambda })
    }

    /// The crossing point of candidate `key` with barycentric coordinates `lambda`.
    pub fn point(&self, key: &Key<W>, lambda: &[f64], out: &mut [f64]) {
        let d = self.ctx.d;
        out.fill(0.0);
        let mut x = [0.0f64; crate::triangulation::MAX_DIM];
        self.ctx.codec.decode(key).for_each_vertex(|i, v| {
            self.ctx.tri.vertex_coords(v, &mut x[..d]);
            for (o, xi) in out.iter_mut().zip(&x[..d]) {
                *o += lambda[i] * xi;
            }
        });
    }

    /// The crossed candidates (their indices) and their crossing points, d per crossed one,
    /// in candidate order, in one flat array.
    pub fn crossed_points(&self, cands: &[Key<W>], v: &Verdicts) -> (Vec<usize>, Vec<f64>) {
        let n = self.ctx.k + 1;
        let d = self.ctx.d;
        let crossed: Vec<usize> = (0..cands.len())
            .filter(|&i| v.status[i].crossed())
            .collect();
        let mut points = vec![0.0; crossed.len() * d];
        points
            .par_chunks_mut(d)
            .zip(&crossed)
            .for_each(|(p, &i)| self.point(&cands[i], &v.lambda[i * n..(i + 1) * n], p));
        (crossed, points)
    }

    /// Puts the crossed candidates that lie in the domain into S (in candidate order), the
    /// crossed ones outside it into the rim, and the others into the current rejected set.
    pub fn accept(&mut self, cands: &[Key<W>], v: &Verdicts) -> Result<()> {
        let d = self.ctx.d;
        let (crossed, points) = self.crossed_points(cands, v);
        let mut rejected = std::mem::take(&mut self.rejected[0]);
        rejected.clear();
        let mut next = crossed.iter().zip(points.chunks_exact(d)).peekable();
        for (i, key) in cands.iter().enumerate() {
            let hit = match next.peek() {
                Some(&(&j, p)) if j == i => {
                    next.next();
                    Some(p)
                }
                _ => None,
            };
            match hit {
                Some(p) if self.ctx.domain.contains(p) => {
                    self.s.insert(key)?;
                    self.points.extend_from_slice(p);
                }
                Some(p) => {
                    if self.rim.find(key).is_none() {
                        self.rim.insert(key)?;
                        self.rim_points.extend_from_slice(p);
                    }
                    rejected.insert(*key);
                }
                None => {
                    rejected.insert(*key);
                }
            }
        }
        self.rejected[0] = std::mem::replace(&mut self.rejected[1], rejected);
        Ok(())
    }
}
