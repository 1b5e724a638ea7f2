//! One level of the trace. The crossed k-simplices found last are the frontier. For each
//! frontier simplex sigma and each of its cofacets tau, the pivot of PL continuation (door
//! in, door out: [`crate::cpu::pivot`]) names the other crossed facet of tau; the named
//! facets not yet known go to the oracle as one batch, which confirms them and gives their
//! points. Where the oracle rejects a named facet (a rounding slip of the unguarded pivot),
//! every facet of that tau is tested, so a level finds exactly the crossed k-facets of the
//! frontier's cofacets, as if every one had been tested. Every order here is a sorted
//! order, so the output does not depend on threads.

use std::ops::Range;
use std::sync::MutexGuard;
use std::time::Instant;

use rayon::prelude::*;

use super::engine::Engine;
use super::frontier::{par_claim, par_ranges, Back, Found, Frontier, Verdicts};
use super::recent::RecentVertices;
use super::sorting::{distinct_ranks, sort, sort_runs};
use super::step_threads::Step;
use super::table::Key;
use super::LevelSteps;
use crate::cpu::pivot::Pivot;
use crate::cpu::solve::Status;
use crate::error::Result;
use crate::triangulation::{copy_run, shift_by_mask, Simplex, MAX_DIM, RUN_BLOCK};

/// Frontier simplices a thread claims at a time for naming.
const SIGMA_CLAIM: usize = 32;
/// Most candidates a slice of a level names on the CPU (the limit and signals are checked
/// between slices).
const SLICE_CANDIDATES: usize = 1 << 20;
/// Fewest found simplices per parallel work item (points).
const POINT_CHUNK: usize = 128;
/// Most new vertices a level evaluates and caches at once (a stop is heeded between).
const VERTEX_PIECE: usize = 1 << 18;
/// Fewest deferred vertices per parallel work item (lookups in the whole cache).
const VERTEX_LOOKUPS: usize = 1024;
/// Fewest sorted candidates per parallel work item (their distinct keys).
const DISTINCT_CHUNK: usize = 512;

/// A k-simplex to test: the facet of cofacet tau number `via` of frontier simplex `from`
/// that lacks tau's vertex `drop`. Tau's new vertex sits at `apex_at` and has cache index
/// `apex`. `fallback` when the facet was not named by a pivot but listed with all the
/// facets of its tau.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Candidate<const W: usize> {
    key: Key<W>,
    from: u32,
    via: u32,
    apex: u32,
    apex_at: u8,
    drop: u8,
    fallback: bool,
}

/// What naming the exits of some frontier simplices gives.
struct Named<const W: usize> {
    cands: Vec<Candidate<W>>,
    /// Cofacets whose new vertex is not cached yet.
    deferred: Vec<Deferred<W>>,
    /// The pivot states ([`Pivot::state`]) of the frontier simplices that have deferred
    /// cofacets, one after the other in the order of `deferred`, and whether each loaded.
    pivots: Vec<f64>,
    loaded: Vec<bool>,
    /// Cofacets whose facets were all listed (the pivot could not run).
    fallbacks: u64,
    /// Cofacets with a non-finite value at their new vertex (no other crossed facet).
    non_finite: u64,
}

impl<const W: usize> Named<W> {
    /// Whether it holds no candidate, deferred cofacet or pivot state.
    fn is_empty(&self) -> bool {
        self.cands.is_empty()
            && self.deferred.is_empty()
            && self.pivots.is_empty()
            && self.loaded.is_empty()
    }

    /// Room for `cands` candidates and `deferred` cofacets (and as many pivot states of
    /// `state` numbers): sized up front, because growing vectors on several threads at once
    /// contends for the allocator.
    fn with_capacity(cands: usize, deferred: usize, state: usize) -> Self {
        Named {
            cands: Vec::with_capacity(cands),
            deferred: Vec::with_capacity(deferred),
            pivots: Vec::with_capacity(deferred * state),
            loaded: Vec::with_capacity(deferred),
            fallbacks: 0,
            non_finite: 0,
        }
    }

    /// Appends the parts one after another, growing each vector once (into an empty one,
    /// the first part is moved, not copied). Each part keeps its deferred cofacets and their
    /// pivot states together, so any order of the parts names the same candidates.
    fn extend(&mut self, mut parts: Vec<Named<W>>) {
        if self.is_empty() && !parts.is_empty() {
            let (fallbacks, non_finite) = (self.fallbacks, self.non_finite);
            *self = parts.remove(0);
            self.fallbacks += fallbacks;
            self.non_finite += non_finite;
        }
        self.cands
            .reserve(parts.iter().map(|p| p.cands.len()).sum());
        self.deferred
            .reserve(parts.iter().map(|p| p.deferred.len()).sum());
        self.pivots
            .reserve(parts.iter().map(|p| p.pivots.len()).sum());
        self.loaded
            .reserve(parts.iter().map(|p| p.loaded.len()).sum());
        for p in parts {
            self.cands.extend_from_slice(&p.cands);
            self.deferred.extend_from_slice(&p.deferred);
            self.pivots.extend_from_slice(&p.pivots);
            self.loaded.extend_from_slice(&p.loaded);
            self.fallbacks += p.fallbacks;
            self.non_finite += p.non_finite;
        }
    }
}

/// A cofacet whose new vertex was not cached: cofacet `via` of frontier simplex `from`,
/// made by the split `(part, subset)`, and its new vertex.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
struct Deferred<const W: usize> {
    from: u32,
    via: u32,
    part: u32,
    subset: u64,
    vertex: Key<W>,
}

/// The distinct keys of a sorted candidate list with their rows and verdicts.
struct Decided<const W: usize> {
    keys: Vec<Key<W>>,
    rows: Vec<u32>,
    verdicts: Verdicts,
    back: Back,
}

impl<const W: usize> Decided<W> {
    fn index(&self, key: &Key<W>) -> Option<usize> {
        self.keys.binary_search(key).ok()
    }
}

/// Per-thread work space for naming exits: the frontier simplex being read, and the rest.
struct Namer<'e, 'a, const W: usize> {
    frontier: &'e Frontier,
    sigma: Simplex,
    tau: Simplex,
    work: Work<'e, 'a, W>,
}

struct Work<'e, 'a, const W: usize> {
    engine: &'e Engine<'a, W>,
    /// In a breadth-first run, this thread's table of the last levels' vertices, where
    /// cofacets' new vertices are looked up (elsewhere, the whole cache).
    recent: Option<MutexGuard<'e, RecentVertices<W>>>,
    pivot: Pivot,
    facet: Simplex,
    key: Key<W>,
    v: [i32; MAX_DIM],
    /// The vertices of the frontier simplex being read, d each.
    corners: Vec<i32>,
    /// Lattice coordinates of the new vertices of the cofacets to skip, d each.
    skip: Vec<i32>,
    out: Named<W>,
}

impl<'e, 'a, const W: usize> Namer<'e, 'a, W> {
    /// A namer for about `cands` candidates and `deferred` deferred cofacets.
    fn new(
        engine: &'e Engine<'a, W>,
        frontier: &'e Frontier,
        cands: usize,
        deferred: usize,
    ) -> Self {
        let blank = engine.ctx.codec.scratch();
        // A pivot state: k row scales and L^-1.
        let state = engine.ctx.k + (engine.ctx.k + 1).pow(2);
        Namer {
            frontier,
            sigma: blank.clone(),
            tau: blank.clone(),
            work: Work {
                engine,
                recent: None,
                pivot: Pivot::new(engine.ctx.k),
                facet: blank,
                key: [0; W],
                v: [0; MAX_DIM],
                // Padded, for `copy_run`'s fixed blocks.
                corners: vec![0; (engine.ctx.k + 1) * engine.ctx.d + RUN_BLOCK],
                skip: Vec::with_capacity(4 * engine.ctx.d),
                out: Named::with_capacity(cands, deferred, state),
            },
        }
    }

    /// Loads frontier simplex `i`, its vertices and its cofacets to skip; false when its L
    /// is numerically singular.
    fn load(&mut self, i: usize) -> bool {
        let e = self.work.engine;
        let (d, k) = (e.ctx.d, e.ctx.k);
        e.ctx
            .codec
            .decode_into_w(e.s.key(self.frontier.members.get(i)), &mut self.sigma);
        let corners = &mut self.work.corners;
        self.sigma
            .for_each_vertex(|j, v| corners[j * d..(j + 1) * d].copy_from_slice(v));
        let back = self.frontier.back.of(i);
        self.work.skip.resize(back.len() * d, 0);
        for (&b, v) in back.iter().zip(self.work.skip.chunks_exact_mut(d)) {
            e.ctx.codec.decode_vertex_w(e.verts.key(b as usize), v);
        }
        let row = &self.frontier.rows[i * (k + 1)..(i + 1) * (k + 1)];
        let values = &e.values;
        self.work.pivot.load(|j, c| values[row[j] as usize * k + c])
    }

    /// Names the exit of every cofacet of frontier simplex `i` whose new vertex is cached,
    /// and defers the others (keeping the pivot's state for them).
    fn all_cofacets(&mut self, i: usize) -> Result<()> {
        let ok = self.load(i);
        let deferred = self.work.out.deferred.len();
        let mut via = 0u32;
        let mut err = Ok(());
        let mut stop = false;
        let (sigma, tau, work) = (&self.sigma, &mut self.tau, &mut self.work);
        sigma.for_each_split(|part, subset| {
            // In high dimensions one simplex has millions of cofacets: a stop asked for
            // meanwhile leaves them unnamed (the caller drops the slice).
            stop = stop || (via % 4096 == 4095 && work.engine.ctx.interrupted());
            if err.is_ok() && !stop {
                err = work.split(sigma, tau, i as u32, via, (part, subset), ok);
            }
            via += 1;
        });
        if self.work.out.deferred.len() > deferred {
            let out = &mut self.work.out;
            out.pivots.extend_from_slice(self.work.pivot.state());
            out.loaded.push(ok);
        }
        err
    }

    /// Names the exits of the deferred cofacets `some` (all of frontier simplex `i`), with
    /// the cache indices of their new vertices; `pivot` is the simplex's pivot state and
    /// whether it loaded, kept when they were deferred (L is not inverted again).
    fn some_cofacets(
        &mut self,
        i: usize,
        some: &[(Deferred<W>, u32)],
        pivot: (&[f64], bool),
    ) -> Result<()> {
        let e = self.work.engine;
        e.ctx
            .codec
            .decode_into_w(e.s.key(self.frontier.members.get(i)), &mut self.sigma);
        let ok = pivot.1;
        self.work.pivot.restore(pivot.0);
        for (n, (t, apex)) in some.iter().enumerate() {
            if n % 4096 == 4095 && self.work.engine.ctx.interrupted() {
                break;
            }
            let p = self
                .sigma
                .cofacet_into(t.part as usize, t.subset, &mut self.tau);
            self.work
                .cofacet(&self.tau, p, i as u32, t.via, *apex, ok)?;
        }
        Ok(())
    }
}

impl<const W: usize> Work<'_, '_, W> {
    /// The cofacet of the loaded frontier simplex `sigma` (number `via` of simplex `from`,
    /// whose pivot is loaded when `ok`) that splits its part `split.0` into `split.1` and the
    /// rest. Its new vertex, sigma's vertex `split.0` moved by the subset, is found first:
    /// a cofacet to skip, or whose new vertex is not cached yet (deferred), is never built.
    fn split(
        &mut self,
        sigma: &Simplex,
        tau: &mut Simplex,
        from: u32,
        via: u32,
        (part, subset): (usize, u64),
        ok: bool,
    ) -> Result<()> {
        let e = self.engine;
        let d = e.ctx.d;
        copy_run(&mut self.v, 0, &self.corners, part * d, d);
        let v = &mut self.v[..d];
        shift_by_mask(v, subset, d);
        if self
            .skip
            .chunks_exact(d)
            .any(|b| b.iter().zip(&*v).all(|(x, y)| x == y))
        {
            return Ok(());
        }
        e.ctx.codec.encode_vertex_w(v, &mut self.key)?;
        // In a breadth-first run only the last levels' vertices are looked up here; the
        // others are deferred and looked up in the whole cache once each.
        let cached = match &self.recent {
            Some(recent) => recent.get(&self.key),
            None => e.verts.find(&self.key).map(|a| a as u32),
        };
        #[cfg(test)]
        let cached = cached.filter(|_| self.recent.is_none() || !e.ctx.forget_vertices);
        let Some(apex) = cached else {
            self.out.deferred.push(Deferred {
                from,
                via,
                part: part as u32,
                subset,
                vertex: self.key,
            });
            return Ok(());
        };
        let p = sigma.cofacet_into(part, subset, tau);
        debug_assert!({
            let mut at = [0; MAX_DIM];
            tau.vertex_into(p, &mut at[..d]);
            at[..d] == self.v[..d]
        });
        self.cofacet(tau, p, from, via, apex, ok)
    }

    /// Cofacet `tau` (new vertex at `p`, cache index `apex`) of frontier simplex `from`,
    /// whose pivot is loaded (`ok`): names its exit.
    fn cofacet(
        &mut self,
        tau: &Simplex,
        p: usize,
        from: u32,
        via: u32,
        apex: u32,
        ok: bool,
    ) -> Result<()> {
        let e = self.engine;
        let k = e.ctx.k;
        let fw = &e.values[apex as usize * k..(apex as usize + 1) * k];
        if fw.iter().any(|v| !v.is_finite()) {
            // Every facet of tau but the frontier simplex has a non-finite vertex value.
            self.out.non_finite += 1;
            return Ok(());
        }
        let Some(r) = ok.then(|| self.pivot.exit(fw)).flatten() else {
            self.out.fallbacks += 1;
            return e.all_facets(tau, (p, apex), from, via, None, &mut self.out.cands);
        };
        #[cfg(test)]
        let r = if e.ctx.scramble_pivots {
            (r + 1) % (k + 1)
        } else {
            r
        };
        // Vertex r of sigma sits at r in tau before the new vertex, at r + 1 after it.
        let q = if r < p { r } else { r + 1 };
        tau.facet_into(q, &mut self.facet);
        e.ctx.codec.encode_w(&self.facet, &mut self.key)?;
        if e.is_new(&self.key) {
            self.out.cands.push(Candidate {
                key: self.key,
                from,
                via,
                apex,
                apex_at: p as u8,
                drop: q as u8,
                fallback: false,
            });
        }
        Ok(())
    }
}

impl<const W: usize> Engine<'_, W> {
    /// One level: the crossed k-facets of the frontier's cofacets that are neither in S nor
    /// in the rim, sorted by key, with their rows and points. `None` when the trace must
    /// stop.
    pub(super) fn step(
        &mut self,
        frontier: &Frontier,
        with_points: bool,
    ) -> Result<Option<Found<W>>> {
        if frontier.members.is_empty() {
            return Ok(Some(self.found([], with_points)));
        }
        let rows = &frontier.rows[..];
        let Some((named, first, starts)) = self.first_round(frontier)? else {
            return Ok(None);
        };

        let clock = Instant::now();
        // Round 2: every facet of the cofacets whose named facet the oracle rejected.
        // `first` holds the distinct keys of the sorted `named`, in order: key j of `first`
        // is the run of equal keys at `starts[j]` there.
        let mut retry: Vec<(u32, u32, u32)> = Vec::new();
        for (j, status) in first.verdicts.status.iter().enumerate() {
            if status.crossed() {
                continue;
            }
            let end = starts.get(j + 1).map_or(named.len(), |&e| e as usize);
            for c in &named[starts[j] as usize..end] {
                debug_assert!(first.keys[j] == c.key);
                if !c.fallback {
                    retry.push((c.from, c.via, c.apex));
                }
            }
        }
        retry.sort_unstable();
        retry.dedup();
        self.stats.pivot_fallbacks += retry.len() as u64;
        let mut second = Vec::new();
        let mut t = 0;
        while t < retry.len() {
            if self.signalled() {
                return Ok(None);
            }
            let from = retry[t].0;
            let sigma = self
                .ctx
                .codec
                .decode(self.s.key(frontier.members.get(from as usize)));
            let mut via = 0;
            let mut err = Ok(());
            sigma.for_each_cofacet_apex(|tau, p| {
                if t < retry.len() && retry[t].0 == from && retry[t].1 == via && err.is_ok() {
                    let apex = (p, retry[t].2);
                    err = self.all_facets(tau, apex, from, via, Some(&first), &mut second);
                    t += 1;
                }
                via += 1;
            });
            err?;
        }
        let second = if second.is_empty() {
            None
        } else {
            sort(&mut second);
            Some(self.decide_unique(&second, rows)?)
        };
        LevelSteps::add(&mut self.stats.steps.deciding, clock);
        let found = self.run_step(Step::Gathering, frontier.members.len(), |e| match second {
            None => e.found([first], with_points),
            Some(second) => e.found([first, second], with_points),
        });
        Ok(Some(found))
    }

    /// The most cofacets of a frontier simplex, from a sample of up to 16 spread over it.
    fn cofacets_per_simplex(&self, frontier: &Frontier) -> usize {
        let members = &frontier.members;
        let step = (members.len() / 16).max(1);
        (0..members.len())
            .step_by(step)
            .map(|i| {
                let key = self.s.key(members.get(i));
                self.ctx.codec.decode(key).cofacet_count()
            })
            .max()
            .map_or(1, |c| usize::try_from(c).unwrap_or(usize::MAX))
    }

    /// Round 1 of a level: the pivot names one facet per cofacet of every frontier simplex,
    /// and the oracle decides the named facets, each key once. Returns the named candidates,
    /// sorted, the decisions in key order and where each key's candidates start; `None`
    /// when the trace must stop.
    ///
    /// With an oracle that decides off the CPU ([`Decide::level_slice`]), a large frontier
    /// goes in slices: slice c + 1 is named while slice c is decided, and a key named in
    /// several slices is decided in the first. A verdict depends only on the key's vertex
    /// values, so the result is the same as one batch's.
    ///
    /// [`Decide::level_slice`]: super::Decide::level_slice
    #[allow(clippy::type_complexity)]
    fn first_round(
        &mut self,
        frontier: &Frontier,
    ) -> Result<Option<(Vec<Candidate<W>>, Decided<W>, Vec<u32>)>> {
        let len = frontier.members.len();
        let (d, n) = (self.ctx.d, self.ctx.k + 1);
        let per_cand = size_of::<Candidate<W>>() + n * 12 + d * 8 + 16;
        // Naming holds a candidate per cofacet (and deferred ones): in high dimensions many
        // per simplex, and a pivot state per simplex with deferred cofacets (k + n^2
        // numbers). Slices keep it within a quarter of the memory left and within
        // SLICE_CANDIDATES, so that the memory limit and a signal are heeded inside a level.
        let cofacets = self.cofacets_per_simplex(frontier);
        let state = (self.ctx.k + n * n) * size_of::<f64>();
        let per_simplex = cofacets.saturating_mul(2 * per_cand).saturating_add(state);
        let naming = |r: usize| r.saturating_mul(per_simplex);
        let room = self
            .ctx
            .max_memory
            .saturating_sub(crate::memory::in_use(self.bytes()));
        let by_memory = (usize::try_from(room / 4).unwrap_or(usize::MAX) / naming(1).max(1)).max(1);
        let by_work = (SLICE_CANDIDATES / cofacets.max(1)).max(1);
        let slice = self
            .ctx
            .oracle
            .decisions()
            .level_slice()
            .unwrap_or(len)
            .min(by_memory)
            .min(by_work)
            .max(1);
        let slices: Vec<Range<usize>> = (0..len)
            .step_by(slice)
            .map(|s| s..(s + slice).min(len))
            .collect();
        let sliced = slices.len() > 1;
        let mut held = 0;
        let mut named_all = Vec::new();
        // Unsliced: where each distinct key's candidates start, and their ways back.
        let mut whole: Option<(Vec<u32>, Back)> = None;
        let mut taken = Taken::default();
        if self.must_stop(naming(slices[0].len())) {
            return Ok(None);
        }
        let first = slices[0].clone();
        let mut next = Some(self.run_step(Step::Naming, len, |e| e.name(frontier, first)));
        for c in 0..slices.len() {
            let mut named = next
                .take()
                .expect("each slice is named before it is decided")?;
            self.name_deferred(frontier, &mut named)?;
            // Naming stops short when a signal comes: the slice is incomplete.
            if self.signalled() {
                return Ok(None);
            }
            // Counted from the candidates, whose number does not depend on the threads (the
            // deferred cofacets' does: see `Levels::vertices`).
            held += named.cands.len() * per_cand;
            // The level's new simplices: about as many as the frontier's (a manifold's levels
            // grow slowly), twice that to be safe.
            if self.must_stop_growing(held, 2 * len) {
                return Ok(None);
            }
            self.stats.pivot_fallbacks += named.fallbacks;
            self.stats.non_finite += named.non_finite;
            let mut cands = named.cands;
            let (keys, rows) = self.run_step(Step::Ordering, len, |_| {
                sort_runs(&mut cands);
                if sliced {
                    let new: Vec<&Candidate<W>> =
                        firsts(&cands).filter(|c| !taken.has(&c.key)).collect();
                    let rows = cand_rows(&new, &frontier.rows, n);
                    (new.iter().map(|c| c.key).collect(), rows)
                } else {
                    let d = distinct(&cands, &frontier.rows, n);
                    whole = Some((d.starts, d.back));
                    (d.keys, d.rows)
                }
            });
            if let Some(r) = slices.get(c + 1) {
                let now = held + (rows.len() + keys.len()) * 8 * W;
                if self.must_stop_growing(now + naming(r.len()), 2 * len) {
                    return Ok(None);
                }
            }
            let (judged, named_next) = self.run_step(Step::Deciding, len, |e| {
                let e = &*e;
                rayon::join(
                    || e.judge(&rows),
                    || slices.get(c + 1).map(|r| e.name(frontier, r.clone())),
                )
            });
            next = named_next;
            let (verdicts, exact) = judged?;
            self.count(&verdicts, exact, &rows);
            taken.push(keys, rows, verdicts);
            if sliced {
                named_all.extend_from_slice(&cands);
            } else {
                named_all = cands;
            }
        }
        if sliced {
            // Stable: merges the slices' sorted runs.
            named_all.sort();
        }
        let (starts, back) = whole.unwrap_or_else(|| {
            let starts = firsts_at(&named_all);
            let back = backs(&named_all, &frontier.rows, n, starts.len());
            (starts, back)
        });
        let first = taken.in_key_order(back, n);
        debug_assert!(first.keys.len() == starts.len());
        Ok(Some((named_all, first, starts)))
    }

    /// Round 1's naming for the frontier simplices `slice`: the exit of every cofacet whose
    /// new vertex is cached; the others are deferred.
    fn name(&self, frontier: &Frontier, slice: Range<usize>) -> Result<Named<W>> {
        // Commonly under two new candidates and one deferred cofacet per simplex.
        let share = slice.len().div_ceil(crate::threads::threads());
        let parts = par_claim(
            slice.len(),
            SIGMA_CLAIM,
            || {
                let mut namer = Namer::new(self, frontier, 2 * share, share);
                namer.work.recent = (self.levels.as_ref()).and_then(|l| {
                    let from = l.recent_from()?;
                    Some(l.vertices.mine(&self.verts, from))
                });
                namer
            },
            |namer, r| {
                for i in r {
                    // A stop asked for meanwhile: the caller drops this slice unfinished.
                    if self.ctx.interrupted() {
                        break;
                    }
                    namer.all_cofacets(slice.start + i)?;
                }
                Ok(())
            },
            |namer| self.finish(namer),
        )?;
        let mut named = Named::with_capacity(0, 0, 0);
        named.extend(parts);
        Ok(named)
    }

    /// What a namer named, its candidates sorted (unless a stop was asked for).
    fn finish(&self, mut namer: Namer<'_, '_, W>) -> Named<W> {
        if !self.ctx.interrupted() {
            namer.work.out.cands.sort_unstable();
        }
        namer.work.out
    }

    /// Evaluates f at the new vertices of the deferred cofacets of `named`, then names
    /// their exits: two steps, each on the threads [`StepThreads`] chooses.
    ///
    /// [`StepThreads`]: super::step_threads::StepThreads
    fn name_deferred(&mut self, frontier: &Frontier, named: &mut Named<W>) -> Result<()> {
        if named.deferred.is_empty() {
            return Ok(());
        }
        if self.ctx.interrupted() {
            return Ok(());
        }
        let deferred = std::mem::take(&mut named.deferred);
        let pivots = std::mem::take(&mut named.pivots);
        let loaded = std::mem::take(&mut named.loaded);
        let units = frontier.members.len();
        let Some(apex) = self.run_step(Step::Caching, units, |e| e.cache_deferred(&deferred))?
        else {
            return Ok(());
        };
        let with_apex: Vec<(Deferred<W>, u32)> = deferred.into_iter().zip(apex).collect();
        let starts: Vec<usize> = (0..with_apex.len())
            .filter(|&i| i == 0 || with_apex[i - 1].0.from != with_apex[i].0.from)
            .collect();
        // One pivot state per run of a frontier simplex's deferred cofacets, in order.
        debug_assert_eq!(loaded.len(), starts.len());
        let state = pivots.len() / loaded.len().max(1);
        let parts = self.run_step(Step::NamingDeferred, units, |e| {
            let e = &*e;
            let share = with_apex.len().div_ceil(crate::threads::threads());
            par_claim(
                starts.len(),
                SIGMA_CLAIM,
                || Namer::new(e, frontier, share, 0),
                |namer, r| {
                    for s in r {
                        if e.ctx.interrupted() {
                            break;
                        }
                        let end = starts.get(s + 1).copied().unwrap_or(with_apex.len());
                        let group = &with_apex[starts[s]..end];
                        let pivot = (&pivots[s * state..(s + 1) * state], loaded[s]);
                        namer.some_cofacets(group[0].0.from as usize, group, pivot)?;
                    }
                    Ok(())
                },
                |namer| e.finish(namer),
            )
        })?;
        named.extend(parts);
        Ok(())
    }

    /// Evaluates f at the new vertices of `deferred` not cached yet and caches them; returns
    /// each deferred cofacet's vertex-cache index of its new vertex (`None` when a stop was
    /// asked for meanwhile).
    fn cache_deferred(&mut self, deferred: &[Deferred<W>]) -> Result<Option<Vec<u32>>> {
        // The distinct vertices in key order. Those not cached yet (in a breadth-first run
        // naming looked up only the last levels' vertices) are cached in that order: each
        // gets the cache index its rank among them gives.
        let vertices: Vec<Key<W>> = deferred.iter().map(|t| t.vertex).collect();
        let (distinct, which) = distinct_ranks(&vertices);
        drop(vertices);
        // Where naming looked only in the last levels' tables, a deferred vertex may be
        // cached already (by an older level); elsewhere it was looked up and is new.
        // Most are uncached: the filter of the cache's keys spares their lookups.
        let cached: Vec<Option<usize>> = match &mut self.levels {
            Some(levels) if levels.recent_from().is_some() => {
                levels.seen.sync(&self.verts);
                let (verts, seen) = (&self.verts, &levels.seen);
                distinct
                    .par_iter()
                    .with_min_len(crate::threads::min_len(VERTEX_LOOKUPS))
                    .map(|v| seen.may_hold(v).then(|| verts.find(v)).flatten())
                    .collect()
            }
            _ => vec![None; distinct.len()],
        };
        let start = self.verts.len();
        let mut keys: Vec<Key<W>> = Vec::with_capacity(distinct.len());
        let index: Vec<u32> = distinct
            .iter()
            .zip(&cached)
            .map(|(v, c)| match c {
                Some(a) => *a as u32,
                None => {
                    keys.push(*v);
                    (start + keys.len() - 1) as u32
                }
            })
            .collect();
        drop(distinct);
        // In pieces, between which a stop is heeded (the caller then drops the slice).
        for piece in keys.chunks(VERTEX_PIECE) {
            if self.ctx.interrupted() {
                return Ok(None);
            }
            self.add_sorted_vertices(piece)?;
        }
        Ok(Some(which.iter().map(|&j| index[j as usize]).collect()))
    }

    /// Whether `key`, a facet of a cofacet of the frontier, is neither in S nor in the rim.
    ///
    /// In a breadth-first run S is looked up in its last two levels only
    /// ([`Engine::levels`], a small set held in cache), not in S's table. That is exact:
    /// the oracle's decisions are consistent (a crossed (k+1)-simplex has exactly two
    /// crossed facets, and the pivot, checked by the oracle and retried on every facet,
    /// names the other one), so the trace's neighbour relation is symmetric, a
    /// breadth-first search's neighbours lie within one level of each other, and a crossed
    /// facet named from level L lies in level L - 1, in level L, or in no level yet.
    /// Components traced before are closed under that relation, so none of them holds it.
    /// (The back lists skip the cofacets shared with level L - 1, so it is rarely asked.)
    /// A debug build checks at the end of each run that S holds no key twice.
    #[inline]
    fn is_new(&self, key: &Key<W>) -> bool {
        let in_s = match &self.levels {
            Some(levels) => levels.keys.contains(key),
            None => self.s.find(key).is_some(),
        };
        !in_s && (self.rim.is_empty() || self.rim.find(key).is_none())
    }

    /// Pushes onto `out` every facet of `tau` (cofacet `via` of frontier simplex `from`,
    /// new vertex at `apex.0` with cache index `apex.1`) but the frontier simplex, unless
    /// known or already decided in `skip`.
    fn all_facets(
        &self,
        tau: &Simplex,
        apex: (usize, u32),
        from: u32,
        via: u32,
        skip: Option<&Decided<W>>,
        out: &mut Vec<Candidate<W>>,
    ) -> Result<()> {
        let mut facet = tau.clone();
        let mut key = [0u64; W];
        for q in (0..=tau.dim()).filter(|&q| q != apex.0) {
            tau.facet_into(q, &mut facet);
            self.ctx.codec.encode_w(&facet, &mut key)?;
            if self.is_new(&key) && skip.is_none_or(|s| s.index(&key).is_none()) {
                out.push(Candidate {
                    key,
                    from,
                    via,
                    apex: apex.1,
                    apex_at: apex.0 as u8,
                    drop: q as u8,
                    fallback: true,
                });
            }
        }
        Ok(())
    }

    /// The oracle on the distinct keys of the sorted candidates `cands`; `rows` holds the
    /// frontier's vertex-cache rows.
    fn decide_unique(&mut self, cands: &[Candidate<W>], rows: &[u32]) -> Result<Decided<W>> {
        let n = self.ctx.k + 1;
        let firsts: Vec<&Candidate<W>> = firsts(cands).collect();
        let cand_rows = cand_rows(&firsts, rows, n);
        let verdicts = self.decide_rows(&cand_rows)?;
        Ok(Decided {
            keys: firsts.iter().map(|c| c.key).collect(),
            rows: cand_rows,
            verdicts,
            back: backs(cands, rows, n, firsts.len()),
        })
    }

    /// The crossing points of the simplices `keys`, whose barycentric coordinates are
    /// `lambda` (k + 1 each), d each.
    fn points_of(&self, keys: &[Key<W>], lambda: &[f64]) -> Vec<f64> {
        let (d, n) = (self.ctx.d, self.ctx.k + 1);
        let parts = par_ranges(keys.len(), POINT_CHUNK, |r| {
            let mut out = vec![0.0; r.len() * d];
            let mut s = self.ctx.codec.scratch();
            for (o, i) in out.chunks_exact_mut(d).zip(r) {
                self.point(&keys[i], &lambda[i * n..(i + 1) * n], &mut s, o);
            }
            out
        });
        parts.concat()
    }

    /// The crossed simplices of the rounds, sorted by key, with their points if asked for.
    fn found<const R: usize>(&self, rounds: [Decided<W>; R], with_points: bool) -> Found<W> {
        let (d, n) = (self.ctx.d, self.ctx.k + 1);
        if R == 1 && rounds[0].verdicts.status.iter().all(|s| s.crossed()) {
            // Every key crossed (the pivot named them all right): moved, not copied.
            let one = rounds.into_iter().next().expect("one round");
            let points = if with_points {
                self.points_of(&one.keys, &one.verdicts.lambda)
            } else {
                Vec::new()
            };
            return Found {
                keys: one.keys,
                rows: one.rows,
                points,
                back: one.back,
            };
        }
        type Hit<'r, const W: usize> = (Key<W>, &'r [u32], &'r [f64], &'r [u32]);
        let mut hits: Vec<Hit<W>> = Vec::with_capacity(rounds.iter().map(|r| r.keys.len()).sum());
        hits.extend(rounds.iter().flat_map(|r| {
            (0..r.keys.len())
                .filter(|&i| r.verdicts.status[i].crossed())
                .map(move |i| {
                    (
                        r.keys[i],
                        &r.rows[i * n..(i + 1) * n],
                        &r.verdicts.lambda[i * n..(i + 1) * n],
                        r.back.of(i),
                    )
                })
        }));
        // One round's keys are in order already.
        if R > 1 {
            hits.sort_unstable_by_key(|h| h.0);
        }
        let len = if with_points { hits.len() } else { 0 };
        let parts = par_ranges(len, POINT_CHUNK, |r| {
            let mut out = vec![0.0; r.len() * d];
            let mut s = self.ctx.codec.scratch();
            for (o, h) in out.chunks_exact_mut(d).zip(&hits[r]) {
                self.point(&h.0, h.2, &mut s, o);
            }
            out
        });
        let mut back = Back::with_capacity(hits.len(), hits.iter().map(|h| h.3.len()).sum());
        for h in &hits {
            back.push_list(h.3);
        }
        Found {
            keys: hits.iter().map(|h| h.0).collect(),
            rows: hits.iter().flat_map(|h| h.1.iter().copied()).collect(),
            points: parts.concat(),
            back,
        }
    }
}

/// Where each key's run starts in the sorted `cands`.
fn firsts_at<const W: usize>(cands: &[Candidate<W>]) -> Vec<u32> {
    (0..cands.len())
        .filter(|&i| i == 0 || cands[i - 1].key != cands[i].key)
        .map(|i| i as u32)
        .collect()
}

/// The distinct keys of sorted candidates, with the vertex-cache rows of each key's first
/// candidate, where its candidates start and its way back.
struct Distinct<const W: usize> {
    keys: Vec<Key<W>>,
    rows: Vec<u32>,
    starts: Vec<u32>,
    back: Back,
}

/// [`Distinct`] of the sorted `cands` (`rows` holds the frontier's), on several threads:
/// each takes a range of the candidates that splits no key's run.
fn distinct<const W: usize>(cands: &[Candidate<W>], rows: &[u32], n: usize) -> Distinct<W> {
    let one = |r: Range<usize>| {
        let mut out = Distinct {
            keys: Vec::with_capacity(r.len()),
            rows: Vec::with_capacity(r.len() * n),
            starts: Vec::with_capacity(r.len()),
            back: Back::with_capacity(r.len(), r.len()),
        };
        for i in r.clone() {
            let c = &cands[i];
            if i == r.start || cands[i - 1].key != c.key {
                if i > r.start {
                    out.back.end_list();
                }
                out.keys.push(c.key);
                out.starts.push(i as u32);
                let kept = (0..=n).filter(|&t| t != c.drop as usize);
                out.rows.extend(kept.map(|t| tau_vertex(c, rows, n, t)));
            }
            out.back
                .push_vertex(tau_vertex(c, rows, n, c.drop as usize));
        }
        if !r.is_empty() {
            out.back.end_list();
        }
        out
    };
    let threads = crate::threads::threads();
    let chunk = cands.len().div_ceil(4 * threads).max(DISTINCT_CHUNK);
    if threads == 1 || cands.len() <= chunk {
        return one(0..cands.len());
    }
    let mut ranges = Vec::new();
    let mut start = 0;
    while start < cands.len() {
        let mut end = (start + chunk).min(cands.len());
        while end < cands.len() && cands[end - 1].key == cands[end].key {
            end += 1;
        }
        ranges.push(start..end);
        start = end;
    }
    let parts: Vec<Distinct<W>> = ranges.into_par_iter().map(one).collect();
    Distinct {
        keys: parts.iter().flat_map(|p| p.keys.iter().copied()).collect(),
        rows: parts.iter().flat_map(|p| p.rows.iter().copied()).collect(),
        starts: parts
            .iter()
            .flat_map(|p| p.starts.iter().copied())
            .collect(),
        back: Back::concat(parts.into_iter().map(|p| p.back)),
    }
}

/// The first candidate of each key of the sorted `cands`.
fn firsts<const W: usize>(cands: &[Candidate<W>]) -> impl Iterator<Item = &Candidate<W>> {
    cands
        .iter()
        .enumerate()
        .filter(|(i, c)| *i == 0 || cands[i - 1].key != c.key)
        .map(|(_, c)| c)
}

/// Vertex t of candidate c's cofacet tau, as a cache index: tau's row is the frontier
/// simplex's (`n` of `rows`) with the new vertex inserted at `apex_at`.
fn tau_vertex<const W: usize>(c: &Candidate<W>, rows: &[u32], n: usize, t: usize) -> u32 {
    let sigma = &rows[c.from as usize * n..(c.from as usize + 1) * n];
    match t.cmp(&(c.apex_at as usize)) {
        std::cmp::Ordering::Less => sigma[t],
        std::cmp::Ordering::Equal => c.apex,
        std::cmp::Ordering::Greater => sigma[t - 1],
    }
}

/// The vertex-cache rows (`n` each) of candidates: their tau without its vertex `drop`;
/// `rows` holds the frontier's.
fn cand_rows<const W: usize>(cands: &[&Candidate<W>], rows: &[u32], n: usize) -> Vec<u32> {
    let mut out = vec![0u32; cands.len() * n];
    for (c, row) in cands.iter().zip(out.chunks_exact_mut(n)) {
        let kept = (0..=n).filter(|&t| t != c.drop as usize);
        for (o, t) in row.iter_mut().zip(kept) {
            *o = tau_vertex(c, rows, n, t);
        }
    }
    out
}

/// Each distinct key's way back, from the sorted candidates `cands`: the vertices of their
/// cofacets tau that they lack (tau's other crossed facet, if it is crossed, is the
/// frontier simplex).
fn backs<const W: usize>(cands: &[Candidate<W>], rows: &[u32], n: usize, keys: usize) -> Back {
    let mut back = Back::with_capacity(keys, cands.len());
    for (i, c) in cands.iter().enumerate() {
        if i > 0 && cands[i - 1].key != c.key {
            back.end_list();
        }
        back.push_vertex(tau_vertex(c, rows, n, c.drop as usize));
    }
    if !cands.is_empty() {
        back.end_list();
    }
    back
}

/// Round 1's decisions in the order they were taken: slice by slice, in key order within
/// a slice, no key twice.
#[derive(Default)]
struct Taken<const W: usize> {
    keys: Vec<Key<W>>,
    rows: Vec<u32>,
    status: Vec<Status>,
    lambda: Vec<f64>,
    /// Where each slice's keys start.
    starts: Vec<usize>,
}

impl<const W: usize> Taken<W> {
    /// Whether an earlier slice decided `key`.
    fn has(&self, key: &Key<W>) -> bool {
        let ends = self.starts.iter().skip(1).copied().chain([self.keys.len()]);
        self.starts
            .iter()
            .zip(ends)
            .any(|(&s, e)| self.keys[s..e].binary_search(key).is_ok())
    }

    /// Appends a slice's decisions.
    fn push(&mut self, keys: Vec<Key<W>>, rows: Vec<u32>, v: Verdicts) {
        self.starts.push(self.keys.len());
        if self.keys.is_empty() {
            (self.keys, self.rows, self.status, self.lambda) = (keys, rows, v.status, v.lambda);
        } else {
            self.keys.extend_from_slice(&keys);
            self.rows.extend_from_slice(&rows);
            self.status.extend_from_slice(&v.status);
            self.lambda.extend_from_slice(&v.lambda);
        }
    }

    /// The decisions in key order, with the ways back `back` of their keys in key order
    /// (`n` vertices to a row).
    fn in_key_order(self, back: Back, n: usize) -> Decided<W> {
        if self.starts.len() <= 1 {
            return Decided {
                keys: self.keys,
                rows: self.rows,
                verdicts: Verdicts {
                    status: self.status,
                    lambda: self.lambda,
                },
                back,
            };
        }
        // A stable sort finds the slices' sorted runs and merges them.
        let mut order: Vec<(Key<W>, u32)> = (0..self.keys.len())
            .map(|i| (self.keys[i], i as u32))
            .collect();
        order.sort();
        /// The entries of `v` (n per key) in `order`.
        fn gather<T: Copy>(v: &[T], order: &[(impl Sized, u32)], n: usize) -> Vec<T> {
            order
                .iter()
                .flat_map(|o| v[o.1 as usize * n..(o.1 as usize + 1) * n].iter().copied())
                .collect()
        }
        Decided {
            keys: gather(&self.keys, &order, 1),
            rows: gather(&self.rows, &order, n),
            verdicts: Verdicts {
                status: gather(&self.status, &order, 1),
                lambda: gather(&self.lambda, &order, n),
            },
            back,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distinct_keys_are_the_same_at_every_thread_count() {
        // Sorted candidates with runs of 1 to 7 equal keys, over a frontier of 50 rows.
        let n = 3;
        let rows: Vec<u32> = (0..50 * n as u32).map(|i| i * 7 % 1000).collect();
        let mut cands: Vec<Candidate<1>> = (0..6000u32)
            .map(|i| Candidate {
                key: [u64::from(i / (1 + i % 7))],
                from: i % 50,
                via: i % 5,
                apex: 2000 + i,
                apex_at: (i % 4) as u8,
                drop: (i % 3) as u8,
                fallback: i % 11 == 0,
            })
            .collect();
        cands.sort();
        let want_firsts: Vec<&Candidate<1>> = firsts(&cands).collect();
        let want_rows = cand_rows(&want_firsts, &rows, n);
        let want_back = backs(&cands, &rows, n, want_firsts.len());
        for threads in [1, 2, 3, 8] {
            let got = crate::test_pool(threads).install(|| distinct(&cands, &rows, n));
            let keys: Vec<Key<1>> = want_firsts.iter().map(|c| c.key).collect();
            assert!(got.keys == keys, "{threads} threads");
            assert!(got.rows == want_rows, "{threads} threads");
            assert!(got.starts == firsts_at(&cands), "{threads} threads");
            for j in 0..keys.len() {
                assert_eq!(got.back.of(j), want_back.of(j), "{threads} threads");
            }
            assert_eq!(got.back.vertex_count(), cands.len());
        }
    }
}
