//! The state of a trace and what its steps share: the sample S, the rim, the vertex-value
//! cache (f is evaluated once per lattice vertex per trace), the oracle calls and the
//! breadth-first loop over levels ([`super::level`] computes one level).

use std::collections::VecDeque;
use std::hash::BuildHasher;
use std::ops::Range;
use std::time::Instant;

use foldhash::fast::FixedState;
use hashbrown::HashTable;
use rayon::prelude::*;

use super::frontier::{Back, Found, Frontier, Members, Verdicts};
use super::recent::Replicas;
use super::seen::SeenVertices;
use super::sorting::sort;
use super::step_threads::{Step, StepThreads};
use super::table::{Key, Table};
use super::{
    Decisions, GrowingValues, Progress, StopReason, TraceContext, TraceStats, DEFAULT_EXTENT_STEPS,
};
use crate::cpu::solve::Status;
use crate::error::Result;

/// Marks a vertex not yet in the cache.
const MISSING: u32 = u32::MAX;
/// Candidates per parallel work item.
const CHUNK: usize = 512;

/// The state of one trace: the sample S (keys only: points are computed again from the
/// vertex cache when asked for), the rim and the vertex-value cache.
pub(crate) struct Engine<'a, const W: usize> {
    pub ctx: TraceContext<'a>,
    pub s: Table<W>,
    /// Crossed simplices whose point lies outside the domain, next to S (the far ends of
    /// the edges of M-hat that the domain's boundary cuts).
    pub rim: Table<W>,
    pub rim_points: Vec<f64>,
    /// The vertex-value cache: lattice vertices, and f at them (k values each).
    pub verts: Table<W>,
    /// It only ever grows at its end, so that the oracle may keep the rows it has seen.
    pub values: Vec<f64>,
    /// The name of `values` for the oracle ([`GrowingValues`]).
    pub values_log: GrowingValues,
    pub stats: TraceStats,
    /// Lattice base vertices of the seeds' first simplices (d each), to tell, with no box,
    /// how far the trace has gone.
    pub origins: Vec<i32>,
    /// While a breadth-first run steps: the keys of its last two levels, the only ones of
    /// S that a new level's candidates can be (see `Engine::is_new`).
    pub levels: Option<Levels<W>>,
    /// Keys of S scanned by [`Engine::s_holds`] since S's table was last brought up to
    /// date.
    scanned: usize,
    /// Whether each step of a level runs on all the pool's threads or on this one.
    split: StepThreads,
}

/// The keys of the last two levels of a breadth-first run, and the vertices cached in its
/// last few levels.
pub(crate) struct Levels<const W: usize> {
    pub keys: LevelKeys<W>,
    /// The vertices cached in the last [`recent_levels`] levels, a table per thread.
    /// Naming looks a cofacet's new vertex up there and defers it when it is not found (the
    /// deferred vertices are then looked up in the whole cache, once each).
    pub vertices: Replicas<W>,
    /// Every cached vertex, as a filter that tells most deferred vertices uncached without
    /// a lookup in the whole cache.
    pub seen: SeenVertices<W>,
    /// Where each of those levels' vertices start in the cache, oldest first, then the
    /// cache's length when they were last brought up to date.
    starts: VecDeque<usize>,
}

/// The keys of S's last two levels: per level, hash tables split by hash bits, the older
/// level's refilled with each new level (so that a level's keys are inserted once), by
/// several threads (one table each) when the level is large.
pub(crate) struct LevelKeys<const W: usize> {
    /// Level l's tables are `tables[l * LEVEL_SHARDS..(l + 1) * LEVEL_SHARDS]`.
    tables: Vec<HashTable<Key<W>>>,
    /// The newest level.
    newest: usize,
    hasher: FixedState,
}

/// Tables per level (a power of two).
const LEVEL_SHARDS: usize = 8;
/// Fewest keys a level indexes on several threads.
const PAR_LEVEL: usize = 4096;

/// The table of a key with hash `h`: bits the hash tables use for neither the bucket (low
/// bits) nor the control byte (the top seven).
#[inline]
fn level_shard(h: u64) -> usize {
    (h >> 48) as usize & (LEVEL_SHARDS - 1)
}

impl<const W: usize> LevelKeys<W> {
    fn new() -> Self {
        LevelKeys {
            tables: (0..2 * LEVEL_SHARDS).map(|_| HashTable::new()).collect(),
            newest: 0,
            hasher: FixedState::default(),
        }
    }

    /// Makes the simplices `level` of S the newest level; the oldest one is forgotten.
    fn push_level(&mut self, s: &Table<W>, level: Range<usize>) {
        self.newest = 1 - self.newest;
        let hasher = &self.hasher;
        let rehash = |k: &Key<W>| hasher.hash_one(k);
        let tables = &mut self.tables[self.newest * LEVEL_SHARDS..][..LEVEL_SHARDS];
        if level.len() < PAR_LEVEL || crate::threads::threads() == 1 {
            tables.iter_mut().for_each(HashTable::clear);
            for i in level {
                let key = s.key(i);
                let h = hasher.hash_one(key);
                tables[level_shard(h)].insert_unique(h, *key, rehash);
            }
            return;
        }
        let hashes: Vec<u64> = level
            .clone()
            .into_par_iter()
            .with_min_len(1024)
            .map(|i| hasher.hash_one(s.key(i)))
            .collect();
        tables.par_iter_mut().enumerate().for_each(|(t, table)| {
            table.clear();
            table.reserve(hashes.len() / LEVEL_SHARDS, rehash);
            for (i, &h) in level.clone().zip(&hashes) {
                if level_shard(h) == t {
                    table.insert_unique(h, *s.key(i), rehash);
                }
            }
        });
    }

    /// Whether either level holds `key`.
    #[inline]
    pub fn contains(&self, key: &Key<W>) -> bool {
        let h = self.hasher.hash_one(key);
        let t = level_shard(h);
        [t, LEVEL_SHARDS + t]
            .iter()
            .any(|&t| self.tables[t].find(h, |k| k == key).is_some())
    }
}

/// Most vertices of the last levels that naming looks up in [`Levels::vertices`] (a table
/// of 16,384 buckets, 768 KiB with one-word keys); beyond, in the whole cache.
const RECENT_VERTICES: usize = 1 << 14;

/// Levels whose new vertices [`Levels::vertices`] keeps, for codimension `k`. A cofacet's
/// new vertex, when cached, was nearly always cached in the last 2k + 2 levels (counted on
/// the presets: all but a few in the last 3 for surfaces in R^3, 6 for the flat torus in
/// R^4, and 99% within 8 for the 3-torus); the rest are found in the whole cache.
pub(crate) fn recent_levels(k: usize) -> usize {
    2 * k + 2
}

impl<const W: usize> Levels<W> {
    /// Levels starting at the simplices `last` of S, with `cached` vertices in the cache.
    fn new(s: &Table<W>, last: Range<usize>, cached: usize) -> Self {
        let mut keys = LevelKeys::new();
        keys.push_level(s, last.clone());
        Levels {
            keys,
            vertices: Replicas::new(),
            seen: SeenVertices::new(),
            starts: VecDeque::from([cached]),
        }
    }

    /// Moves on to the level `next` of S: its keys and the last one's are the levels' keys,
    /// and the vertices cached since the last call are the newest of the last `window`
    /// levels' (the tables of [`Levels::vertices`] take them up when next used).
    fn advance(&mut self, s: &Table<W>, next: Range<usize>, verts: &Table<W>, window: usize) {
        self.keys.push_level(s, next);
        self.starts.push_back(verts.len());
        while self.starts.len() > window + 1 {
            self.starts.pop_front();
        }
    }

    /// Where the vertices of the last [`recent_levels`] levels start in the cache, when
    /// naming looks them up in [`Levels::vertices`]: while they are few enough for the
    /// tables to stay in a core's cache ([`RECENT_VERTICES`]), as of the level's start.
    pub fn recent_from(&self) -> Option<usize> {
        let (from, to) = (self.starts.front()?, self.starts.back()?);
        (to - from <= RECENT_VERTICES).then_some(*from)
    }
}

impl<'a, const W: usize> Engine<'a, W> {
    pub fn new(ctx: TraceContext<'a>) -> Self {
        let split = StepThreads::new(ctx.step_threads, rayon::current_num_threads());
        Engine {
            ctx,
            s: Table::fixed(),
            rim: Table::fixed(),
            rim_points: Vec::new(),
            verts: Table::fixed(),
            values: Vec::new(),
            values_log: GrowingValues::new(),
            stats: TraceStats::default(),
            origins: Vec::new(),
            levels: None,
            scanned: 0,
            split,
        }
    }

    /// Runs `f`, the step `step` of a level of `units` frontier simplices, on all the pool's
    /// threads or on this one alone, as [`StepThreads`] chooses, and adds its time to the
    /// step's in [`TraceStats::steps`]. Within a level run alone, a step runs alone too
    /// and is not counted.
    pub(super) fn run_step<R>(
        &mut self,
        step: Step,
        units: usize,
        f: impl FnOnce(&mut Self) -> R,
    ) -> R {
        let counted = crate::threads::threads() > 1;
        let all = counted && self.split.all(step, units);
        let clock = Instant::now();
        let out = {
            let _alone = crate::threads::alone_if(!all);
            f(self)
        };
        let took = clock.elapsed();
        if counted {
            self.split.record(step, all, units, took);
        }
        if let Some(time) = self.stats.steps.of(step) {
            *time += took.as_secs_f64();
        }
        out
    }

    /// Bytes held by the trace's containers.
    pub fn bytes(&self) -> usize {
        self.s.memory_bytes()
            + self.rim.memory_bytes()
            + self.rim_points.capacity() * 8
            + self.verts.memory_bytes()
            + self.values.capacity() * 8
    }

    /// Whether the trace must stop now (Ctrl-C, or the next step would pass the memory limit).
    /// `next_bytes` is what the step holds on top of the heap in use now; the growth of the
    /// tables by `new_keys` more simplices (and their vertices) is added to it.
    pub(super) fn must_stop_growing(&mut self, next_bytes: usize, new_keys: usize) -> bool {
        if self.ctx.interrupted() {
            self.stats.stopped = Some(StopReason::Interrupted);
            return true;
        }
        let n = self.ctx.k + 1;
        let growth = self.s.growth_bytes(new_keys)
            + self.verts.growth_bytes(new_keys * n)
            + if (self.verts.len() + new_keys * n) * self.ctx.k > self.values.capacity() {
                (self.values.capacity() * 2).max(new_keys * n * self.ctx.k) * 8
            } else {
                0
            };
        // After the trace, the sample copies the vertex set, and its check for poles holds
        // two values per simplex and equation and keeps the points: room for them is kept.
        let after = self.verts.memory_bytes()
            + (self.s.len() + new_keys) * (2 * self.ctx.k + self.ctx.d) * 8;
        let need = crate::memory::in_use(self.bytes()) + (next_bytes + growth + after) as u64;
        if need > self.ctx.max_memory {
            self.stats.stopped = Some(StopReason::MemoryLimit {
                needed: need,
                limit: self.ctx.max_memory,
                boxed: self.ctx.domain.bbox.is_some(),
            });
            return true;
        }
        false
    }

    /// Whether a stop was asked for (Ctrl-C), which is then the trace's stop reason.
    pub(super) fn signalled(&mut self) -> bool {
        let stop = self.ctx.interrupted();
        if stop {
            self.stats.stopped = Some(StopReason::Interrupted);
        }
        stop
    }

    /// [`Engine::must_stop_growing`] for a step that adds no key.
    pub(super) fn must_stop(&mut self, next_bytes: usize) -> bool {
        self.must_stop_growing(next_bytes, 0)
    }

    /// With no box: how far the simplices of `members` lie from the seeds, in lattice steps:
    /// the largest, over the members, of the distance (along the farthest lattice axis) from
    /// a member's base vertex to its nearest seed's. `None` with a box or before any seed,
    /// where no extent applies.
    fn reach(&self, members: &Members) -> Option<u64> {
        let d = self.ctx.d;
        if self.ctx.domain.bbox.is_some() || self.origins.is_empty() {
            return None;
        }
        let mut v = [0i32; crate::triangulation::MAX_DIM];
        let far = members.iter().map(|i| {
            self.ctx.codec.decode_vertex(self.s.key(i), &mut v[..d]);
            self.origins
                .chunks_exact(d)
                .map(|o| {
                    o.iter()
                        .zip(&v[..d])
                        .map(|(a, b)| (i64::from(*a) - i64::from(*b)).unsigned_abs())
                        .max()
                        .unwrap_or(0)
                })
                .min()
                .unwrap_or(0)
        });
        Some(far.max().unwrap_or(0))
    }

    /// Breadth-first trace from the simplices `frontier` (indices into S, already evaluated)
    /// until no new crossed simplex appears, the box is exhausted or a stop is requested.
    /// The keys it adds to S are not indexed in S's table ([`Engine::s_holds`] and
    /// [`Engine::complete_rim`] index them when they look S up).
    pub fn run(&mut self, frontier: Range<usize>) -> Result<()> {
        let front = Frontier {
            rows: self.rows_of(frontier.clone())?,
            members: Members::Range(frontier.clone()),
            back: Back::default(),
        };
        self.levels = Some(Levels::new(&self.s, frontier, self.verts.len()));
        let ran = self.levels_from(front);
        self.levels = None;
        debug_assert!(self.s_is_distinct(), "a key of S twice: `levels` missed it");
        ran
    }

    /// Whether S holds no key twice (what `levels` guarantees; O(|S| log |S|), for checks).
    fn s_is_distinct(&self) -> bool {
        let mut keys: Vec<&Key<W>> = (0..self.s.len()).map(|i| self.s.key(i)).collect();
        keys.sort_unstable();
        keys.windows(2).all(|w| w[0] != w[1])
    }

    /// Whether S holds `key`, outside a breadth-first run. Its table is brought up to
    /// date only once a lookup would scan more than that costs: a trace from one seed
    /// looks up the seed's few other crossed simplices and never builds it.
    pub(super) fn s_holds(&mut self, key: &Key<W>) -> bool {
        let tail = self.s.unindexed();
        if tail > 0 && self.scanned + tail <= 4 * tail {
            self.scanned += tail;
            return self.s.find(key).is_some();
        }
        self.s.index_rest();
        self.scanned = 0;
        self.s.find(key).is_some()
    }

    /// The loop of [`Engine::run`], from the level `front`.
    ///
    /// With no box it stops where a level reaches [`DEFAULT_EXTENT_STEPS`] lattice steps
    /// from the seeds, or [`super::NO_BOX_BUDGET_STEPS`] once S is large. A level's simplices
    /// are facets of cofacets of the level before, and every vertex of a simplex lies within
    /// a step of its base vertex along each axis, so a level reaches at most two steps
    /// farther than the one before: the reach is measured again only when that bound could
    /// pass a limit.
    fn levels_from(&mut self, mut front: Frontier) -> Result<()> {
        let mut reach = self.reach(&front.members);
        while !front.members.is_empty() {
            // Points only serve to test the domain here (the sample computes its own).
            let with_points = !self.ctx.domain.is_everywhere();
            let units = front.members.len();
            let next = self.run_step(Step::Level, units, |e| -> Result<Option<Frontier>> {
                let Some(found) = e.step(&front, with_points)? else {
                    return Ok(None);
                };
                e.run_step(Step::Accepting, units, |e| {
                    let next = e.accept(found)?;
                    if let (Some(levels), Members::Range(r)) = (&mut e.levels, &next.members) {
                        let window = recent_levels(e.ctx.k);
                        levels.advance(&e.s, r.clone(), &e.verts, window);
                    }
                    Ok(Some(next))
                })
            })?;
            let Some(next) = next else {
                return Ok(());
            };
            front = next;
            let large = self.s.len() > super::NO_BOX_SIMPLICES;
            let limit = u64::from(if large {
                super::NO_BOX_BUDGET_STEPS
            } else {
                DEFAULT_EXTENT_STEPS
            });
            reach = reach.map(|r| r + 2);
            if reach.is_some_and(|r| r > limit || self.ctx.reach_every_level()) {
                reach = self.reach(&front.members);
            }
            if reach.is_some_and(|r| r > u64::from(DEFAULT_EXTENT_STEPS)) {
                self.stats.stopped = Some(StopReason::NoBox {
                    steps: DEFAULT_EXTENT_STEPS,
                    distance: DEFAULT_EXTENT_STEPS as f64 * self.ctx.tri.edge(),
                });
                return Ok(());
            }
            if large && reach.is_some_and(|r| r > u64::from(super::NO_BOX_BUDGET_STEPS)) {
                self.stats.stopped = Some(StopReason::NoBoxTooLarge {
                    simplices: self.s.len() as u64,
                });
                return Ok(());
            }
            self.stats.levels += 1;
            self.stats.widest_level = self.stats.widest_level.max(front.members.len() as u64);
            if let Some(p) = self.ctx.progress {
                p(&Progress {
                    simplices: self.s.len(),
                    level: self.stats.levels,
                    frontier: front.members.len(),
                    vertices: self.verts.len(),
                });
            }
        }
        Ok(())
    }

    /// Finds the rim of a sample built elsewhere (the scan): the crossed neighbours of S
    /// outside the domain, looked for from the simplices `border` of S (indices, the only
    /// ones that may have such neighbours). Every vertex of S must be cached
    /// ([`Engine::cache_vertices_of_s`] or [`Engine::cache_sorted_values`]).
    pub fn complete_rim(&mut self, border: Vec<u32>) -> Result<()> {
        // Candidates are looked up in S's table (no levels here).
        self.s.index_rest();
        let keys: Vec<Key<W>> = border.iter().map(|&i| *self.s.key(i as usize)).collect();
        let rows = self.rows(&keys)?;
        let front = Frontier {
            members: Members::List(border),
            rows,
            back: Back::default(),
        };
        if let Some(found) = self.step(&front, true)? {
            for (key, p) in found.keys.iter().zip(found.points.chunks_exact(self.ctx.d)) {
                self.rim.insert(key)?;
                self.rim_points.extend_from_slice(p);
            }
        }
        Ok(())
    }

    /// Vertex-cache rows (k + 1 indices each) of the simplices `range` of S.
    fn rows_of(&mut self, range: Range<usize>) -> Result<Vec<u32>> {
        let keys: Vec<Key<W>> = range.map(|i| *self.s.key(i)).collect();
        self.rows(&keys)
    }

    /// Evaluates f at the vertices of S not cached yet, and caches them (sorted by key).
    pub fn cache_vertices_of_s(&mut self) -> Result<()> {
        self.rows_of(0..self.s.len()).map(drop)
    }

    /// Caches f's `values` (rows of k) at the lattice vertices `keys`, sorted, distinct and
    /// not cached yet, computed elsewhere (the scan's grid): not counted as evaluated here.
    pub(super) fn cache_sorted_values(&mut self, keys: &[Key<W>], values: &[f64]) -> Result<()> {
        debug_assert!(keys.windows(2).all(|w| w[0] < w[1]));
        debug_assert_eq!(keys.len() * self.ctx.k, values.len());
        self.verts.insert_new_batch(keys.as_flattened())?;
        self.values.extend_from_slice(values);
        Ok(())
    }

    /// Vertex-cache rows (k + 1 indices each) of `cands`, evaluating the vertices not
    /// cached yet.
    fn rows(&mut self, cands: &[Key<W>]) -> Result<Vec<u32>> {
        let mut idx = vec![0u32; cands.len() * (self.ctx.k + 1)];
        let mut missing = self.vertex_indices(cands, &mut idx, false)?;
        if !missing.is_empty() {
            self.add_vertices(&mut missing)?;
            let left = self.vertex_indices(cands, &mut idx, true)?;
            debug_assert!(left.is_empty());
        }
        Ok(idx)
    }

    /// Evaluates f at the lattice vertices `keys` (not cached yet; sorted and deduplicated
    /// here) and caches the values.
    pub(super) fn add_vertices(&mut self, keys: &mut Vec<Key<W>>) -> Result<()> {
        sort(keys);
        keys.dedup();
        self.add_sorted_vertices(keys)
    }

    /// Evaluates f at the lattice vertices `keys` (sorted, distinct and not cached yet)
    /// and caches the values, in that order.
    pub(super) fn add_sorted_vertices(&mut self, keys: &[Key<W>]) -> Result<()> {
        debug_assert!(keys.windows(2).all(|w| w[0] < w[1]));
        let (d, k) = (self.ctx.d, self.ctx.k);
        let mut lattice = vec![0i32; keys.len() * d];
        lattice
            .par_chunks_exact_mut(d)
            .zip(keys.par_iter())
            .with_min_len(crate::threads::min_len(CHUNK))
            .for_each(|(v, key)| self.ctx.codec.decode_vertex_w(key, v));
        let mut vals = vec![0.0; keys.len() * k];
        self.ctx
            .oracle
            .values()
            .eval_vertices(self.ctx.tri, &lattice, &mut vals)?;
        // Misses of the cache, deduplicated: all new.
        self.verts.insert_new_batch(keys.as_flattened())?;
        self.values.extend_from_slice(&vals);
        self.stats.vertices += keys.len() as u64;
        self.stats.cpu_vertex_evaluations += keys.len() as u64;
        Ok(())
    }

    /// Caches values of f already computed on the CPU (`lattice`: rows of d, `values`: rows
    /// of k), at vertices not cached yet; not counted again.
    pub(super) fn seed_vertices(&mut self, lattice: &[i32], values: &[f64]) -> Result<()> {
        let (d, k) = (self.ctx.d, self.ctx.k);
        let mut key = [0u64; W];
        for (v, f) in lattice.chunks_exact(d).zip(values.chunks_exact(k)) {
            self.ctx.codec.encode_vertex(v, &mut key)?;
            self.verts.insert_new(&key)?;
            self.values.extend_from_slice(f);
        }
        Ok(())
    }

    /// The oracle on simplices given as vertex-cache rows, with the counters.
    pub(super) fn decide_rows(&mut self, rows: &[u32]) -> Result<Verdicts> {
        let (verdicts, exact) = self.judge(rows)?;
        self.count(&verdicts, exact, rows);
        Ok(verdicts)
    }

    /// The oracle on simplices given as vertex-cache rows, and how the decisions were
    /// reached; the counters are left to [`Engine::count`] (so that naming may run
    /// meanwhile).
    pub(super) fn judge(&self, rows: &[u32]) -> Result<(Verdicts, Decisions)> {
        let n = self.ctx.k + 1;
        let m = rows.len() / n;
        let mut status = vec![Status::Outside; m];
        let mut lambda = vec![0.0; m * n];
        let exact = self.ctx.oracle.decisions().decide_growing(
            self.values_log,
            &self.values,
            rows,
            &mut status,
            &mut lambda,
        )?;
        Ok((Verdicts { status, lambda }, exact))
    }

    /// Counts the decisions `v` on the candidates `rows`, reached as `how` says, and looks
    /// at degenerate ones for a region where f vanishes.
    pub(super) fn count(&mut self, v: &Verdicts, how: Decisions, rows: &[u32]) {
        let before = self.stats.degenerate;
        self.stats.count_decisions(&v.status, how);
        if self.stats.degenerate > before && self.stats.zero_region.is_none() {
            let (ctx, verts) = (&self.ctx, &self.verts);
            let coords = |i: usize, x: &mut [f64]| {
                let mut v = [0i32; crate::triangulation::MAX_DIM];
                ctx.codec.decode_vertex(verts.key(i), &mut v[..ctx.d]);
                ctx.tri.vertex_coords(&v[..ctx.d], x);
            };
            self.stats.zero_region = super::checks::zero_region(
                ctx.f,
                &v.status,
                rows,
                &self.values,
                ctx.tri.edge(),
                coords,
            );
        }
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
            .with_min_len(crate::threads::min_len(1))
            .map(|(cs, rows)| -> Result<Vec<Key<W>>> {
                let mut miss = Vec::new();
                let mut vk = [0u64; W];
                let mut s = codec.scratch();
                for (c, row) in cs.iter().zip(rows.chunks_exact_mut(n)) {
                    if only_missing && !row.contains(&MISSING) {
                        continue;
                    }
                    let mut err = None;
                    codec.decode_into_w(c, &mut s);
                    s.for_each_vertex(|i, v| {
                        if let Err(e) = codec.encode_vertex_w(v, &mut vk) {
                            err = Some(e);
                            return;
                        }
                        row[i] = match self.verts.find(&vk) {
                            Some(j) => j as u32,
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
        let idx = self.rows(cands)?;
        self.decide_rows(&idx)
    }

    /// The crossing point of candidate `key` with barycentric coordinates `lambda`; `s` is
    /// scratch (from the codec's [`scratch`](crate::triangulation::KeyCodec::scratch)).
    pub fn point(
        &self,
        key: &Key<W>,
        lambda: &[f64],
        s: &mut crate::triangulation::Simplex,
        out: &mut [f64],
    ) {
        self.ctx.codec.decode_into_w(key, s);
        self.ctx
            .tri
            .barycentric_point(lambda, |i, v| s.vertex_into(i, v), out);
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
            .with_min_len(crate::threads::min_len(1))
            .for_each_init(
                || self.ctx.codec.scratch(),
                |s, (p, &i)| self.point(&cands[i], &v.lambda[i * n..(i + 1) * n], s, p),
            );
        (crossed, points)
    }

    /// Appends a level's new simplices `keys` to S.
    fn push_level_keys(&mut self, keys: &[Key<W>]) -> Result<()> {
        if self.levels.is_some() {
            // A breadth-first run looks its levels up in `levels`: S's table waits until
            // a lookup needs it ([`Engine::s_holds`]).
            self.s.push_unindexed(keys.as_flattened())?;
        } else {
            self.s.insert_new_batch(keys.as_flattened())?;
        }
        Ok(())
    }

    /// Puts what a level found into S where its point lies in the domain (in key order),
    /// into the rim otherwise; returns the new simplices of S as the next frontier.
    pub fn accept(&mut self, found: Found<W>) -> Result<Frontier> {
        let (d, n) = (self.ctx.d, self.ctx.k + 1);
        let start = self.s.len();
        // No point computed: the domain is everything.
        let outside: Vec<bool> = if found.points.is_empty() {
            Vec::new()
        } else {
            found
                .points
                .par_chunks_exact(d)
                .with_min_len(crate::threads::min_len(256))
                .map(|p| !self.ctx.domain.contains(p))
                .collect()
        };
        if !outside.contains(&true) {
            // All inside: the level's vectors move on as they are.
            self.push_level_keys(&found.keys)?;
            return Ok(Frontier {
                members: Members::Range(start..self.s.len()),
                rows: found.rows,
                back: found.back,
            });
        }
        let mut rows = Vec::with_capacity(found.rows.len());
        let mut back = Back::with_capacity(found.keys.len(), found.back.vertex_count());
        let mut inside = Vec::with_capacity(found.keys.len());
        // A level's keys are distinct and in neither S nor the rim (see `step`).
        for (i, (key, row)) in found
            .keys
            .iter()
            .zip(found.rows.chunks_exact(n))
            .enumerate()
        {
            if outside.get(i) == Some(&true) {
                self.rim.insert_new(key)?;
                self.rim_points
                    .extend_from_slice(&found.points[i * d..(i + 1) * d]);
            } else {
                inside.push(*key);
                rows.extend_from_slice(row);
                back.push_from(&found.back, i);
            }
        }
        self.push_level_keys(&inside)?;
        Ok(Frontier {
            members: Members::Range(start..self.s.len()),
            rows,
            back,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_level_keys_hold_the_last_two_levels_at_every_thread_count() {
        // Levels of 5,000 keys (indexed on several threads) and of 10 (on one).
        let sizes = [5000, 10, 5000, 5000, 10, 10, 5000];
        let mut s = Table::<2>::fixed();
        let keys: Vec<u64> = (0..sizes.iter().sum::<usize>() as u64)
            .flat_map(|i| [i.wrapping_mul(0x9e37_79b9_7f4a_7c15), i])
            .collect();
        s.push_unindexed(&keys).unwrap();
        for threads in [1, 2, 3, 8] {
            crate::test_pool(threads).install(|| {
                let mut levels = LevelKeys::new();
                let mut start = 0;
                let mut last = 0..0;
                for &size in &sizes {
                    let level = start..start + size;
                    levels.push_level(&s, level.clone());
                    for i in 0..s.len() {
                        let held = level.contains(&i) || last.contains(&i);
                        assert_eq!(levels.contains(s.key(i)), held, "{threads} threads");
                    }
                    assert!(!levels.contains(&[1, u64::MAX]));
                    (start, last) = (level.end, level);
                }
            });
        }
    }
}
