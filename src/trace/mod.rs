//! Manifold tracing: the sample S of k-simplices of T crossed by M = f^-1(0), with one point
//! of M-hat in each, found from seeds ([`trace`]) or by scanning a box ([`scan`]).
//!
//! ```
//! use isomesh::expr::preset;
//! use isomesh::trace::{trace, CpuOracle, TraceOptions};
//!
//! let circle = preset("circle", &[]).unwrap();
//! let tri = circle.triangulation.build(2).unwrap();
//! let oracle = CpuOracle::new(&circle.system);
//! let opts = TraceOptions { seeds: circle.seeds.clone(), ..TraceOptions::default() };
//! let s = trace(&circle.system, &tri, &oracle, &opts).unwrap();
//! assert!(s.len() > 100);
//! for (simplex, point) in s.iter().take(3) {
//!     assert_eq!(simplex.dim(), 1);
//!     assert!((point[0].hypot(point[1]) - 1.0).abs() < 1e-2);
//! }
//! ```

pub mod checks;
mod engine;
mod frontier;
mod level;
mod oracle;
mod recent;
mod region;
mod sample;
pub mod scan;
mod seeds;
mod seen;
mod sorting;
mod step_threads;
mod table;
mod warm;

use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;

use serde::Serialize;

pub use crate::cpu::certificate::{CROSSED, OUTSIDE, UNCERTAIN};
pub use crate::cpu::solve::Status;
pub use oracle::{
    CpuOracle, CpuScan, Decide, Decisions, DeviceValues, Evaluate, GrowingValues, Oracle, Scan,
};
pub use region::{box_slack, coord_bits, in_box, in_box_closed, lattice_bounds, Domain};
use sample::sample_from;
pub use sample::{CrossingChecks, Sample, MAX_SINGULAR};
pub use scan::{exhaustive, scan_grid, ScanGrid, MAX_SCAN_DIM};
pub use seeds::SEED_TOLERANCE;

use crate::error::{Error, Result};
use crate::expr::spec::check_box;
use crate::expr::ImplicitFunction;
use crate::triangulation::{KeyCodec, Triangulation};
use engine::Engine;

/// Box samples for the automatic seed search when no seed is given.
pub const DEFAULT_SEARCH_SAMPLES: usize = 512;

/// What a trace starts from and what bounds it.
#[derive(Clone)]
pub struct TraceOptions<'a> {
    /// The box [lo, hi] per axis: only crossed simplices whose point lies in it are kept, so
    /// it acts as the boundary of non-compact manifolds. Needed for the seed search and the
    /// exhaustive scan.
    pub bbox: Option<Vec<[f64; 2]>>,
    /// Points on or near M (Newton-projected first).
    pub seeds: Vec<Vec<f64>>,
    /// Random box points to project onto M as extra seeds: `None` means
    /// [`DEFAULT_SEARCH_SAMPLES`] when no seed is given and none otherwise.
    pub search_samples: Option<usize>,
    /// Seed of the box sampling.
    pub search_seed: u64,
    /// Stop (keeping what was traced) before the trace's memory passes this many bytes.
    pub max_memory: u64,
    /// Set to true to stop cleanly (Ctrl-C).
    pub cancel: Option<Arc<AtomicBool>>,
    /// Called after every level.
    pub progress: Option<&'a (dyn Fn(&Progress) + Sync)>,
    /// Keep the pool's other threads polling for work while the trace runs, so that small
    /// levels use every core (they burn those cores meanwhile; the command line sets it).
    pub warm: bool,
    /// The box keys are sized for (bits per lattice coordinate), if not `bbox`: the shards
    /// of one box give it the whole box, so that their keys are the whole scan's.
    pub key_box: Option<Vec<[f64; 2]>>,
}

impl Default for TraceOptions<'_> {
    fn default() -> Self {
        TraceOptions {
            bbox: None,
            seeds: Vec::new(),
            search_samples: None,
            search_seed: 1,
            max_memory: crate::memory::default_limit(),
            cancel: None,
            progress: None,
            warm: false,
            key_box: None,
        }
    }
}

/// Where a trace stands, after each level.
#[derive(Clone, Copy, Debug)]
pub struct Progress {
    /// Crossed simplices so far.
    pub simplices: usize,
    /// Levels done.
    pub level: u64,
    /// Simplices found by the last level.
    pub frontier: usize,
    /// Lattice vertices evaluated.
    pub vertices: usize,
}

/// Why a trace stopped early (what it found is kept).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// The cancel flag was set.
    Interrupted,
    /// Going on would pass the memory limit.
    MemoryLimit {
        /// Bytes the next level would have needed.
        needed: u64,
        /// The limit.
        limit: u64,
        /// Whether the trace had a box.
        boxed: bool,
    },
    /// With no box, M reached [`DEFAULT_EXTENT_STEPS`] lattice steps from every seed: it may
    /// be unbounded, and a box is needed to trace it.
    NoBox {
        /// The extent, in lattice steps.
        steps: u32,
        /// About that many units of length.
        distance: f64,
    },
    /// With no box, the trace found more than [`NO_BOX_SIMPLICES`] crossed simplices and
    /// reached [`NO_BOX_BUDGET_STEPS`] lattice steps from every seed: M may be unbounded (a
    /// plane reaches the extent of [`DEFAULT_EXTENT_STEPS`] only after minutes and gigabytes),
    /// and a box is needed to trace it.
    NoBoxTooLarge {
        /// The simplices found.
        simplices: u64,
    },
}

/// The most crossed simplices a trace with no box finds, once it is [`NO_BOX_BUDGET_STEPS`]
/// lattice steps from every seed, before it stops, asking for a box. (A closed manifold
/// within that distance, such as S^7 in R^8, is traced whole however many it has.)
pub const NO_BOX_SIMPLICES: usize = 1 << 22;

/// See [`NO_BOX_SIMPLICES`].
pub const NO_BOX_BUDGET_STEPS: u32 = 256;

/// How far (in lattice steps, about one edge each, along any lattice axis) a trace with no
/// box may go from its nearest seed: beyond that M is taken to be unbounded and the trace
/// stops, asking for a box.
pub const DEFAULT_EXTENT_STEPS: u32 = 1024;

impl std::fmt::Display for StopReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            StopReason::Interrupted => write!(f, "interrupted"),
            StopReason::MemoryLimit {
                needed,
                limit,
                boxed,
            } => write!(
                f,
                "stopped before passing the memory limit: the next step needs {}, the limit is \
                 {} (raise --max-memory, or use a larger edge or {})",
                crate::memory::human_bytes(*needed),
                crate::memory::human_bytes(*limit),
                if *boxed {
                    "a smaller box"
                } else {
                    "give a box: with none, M may be unbounded"
                }
            ),
            StopReason::NoBoxTooLarge { simplices } => write!(
                f,
                "no box was given and the trace found {simplices} simplices, more than a trace \
                 with no box may: M may be unbounded; give a box (--box, or box = [...] in the \
                 spec) to trace it"
            ),
            StopReason::NoBox { steps, distance } => write!(
                f,
                "no box was given and M reaches {steps} lattice steps (about {distance:.3e}) from \
                 its seeds: it may be unbounded; give a box (--box, or box = [...] in the spec) \
                 to trace it"
            ),
        }
    }
}

/// Counters of a trace or scan.
#[derive(Clone, Debug, Default, Serialize)]
pub struct TraceStats {
    /// Breadth-first levels.
    pub levels: u64,
    /// Most simplices one level found: the largest frontier, which sizes tracing's largest
    /// oracle batches.
    pub widest_level: u64,
    /// k-simplices sent to the oracle.
    pub oracle_calls: u64,
    /// Cofacets whose other crossed facet was found by testing all their facets, where the
    /// pivot could not run or named a facet the oracle rejected.
    pub pivot_fallbacks: u64,
    /// Decisions taken by the exact rational path.
    pub exact_decisions: u64,
    /// Candidates with a singular labelling matrix.
    pub degenerate: u64,
    /// Candidates, or cofacets of crossed simplices, with a non-finite vertex value (in a
    /// scan that found nothing: lattice vertices where f is not finite).
    pub non_finite: u64,
    /// Lattice vertices where f was evaluated.
    pub vertices: u64,
    /// Lattice vertices where a device evaluated f, with bounds.
    pub device_vertex_evaluations: u64,
    /// Lattice vertices where the CPU evaluated f.
    pub cpu_vertex_evaluations: u64,
    /// Decisions a device certified and the CPU did not redo.
    pub device_decisions: u64,
    /// Decisions made or redone on the CPU.
    pub cpu_decisions: u64,
    /// Connected components of S.
    pub components: usize,
    /// Projected box samples used as seeds.
    pub seed_points: u64,
    /// Wall time, seconds.
    pub elapsed_s: f64,
    /// Where the levels' wall time went (zero for a scan).
    pub steps: LevelSteps,
    /// Bytes held by the trace's own containers at the end.
    pub memory_bytes: u64,
    /// Set when the trace stopped early.
    pub stopped: Option<StopReason>,
    /// A point around which an equation of f is identically 0 (at every vertex of a simplex
    /// tried, and at points a quarter edge away along each axis): f vanishes on a region
    /// there, whose zero set is no manifold. See [`checks::region_error`].
    #[serde(skip)]
    pub zero_region: Option<(usize, Vec<f64>)>,
}

/// Where a breadth-first trace's wall time went, seconds summed over its levels, a step
/// after another: what a level does between its parallel parts is timed with them.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct LevelSteps {
    /// Naming the exits of the frontier's cofacets whose new vertex is cached (of a level
    /// in slices, the first slice's: the others are named while the oracle decides).
    pub naming: f64,
    /// Evaluating f at the cofacets' new vertices, caching them, and naming those
    /// cofacets' exits.
    pub new_vertices: f64,
    /// Sorting the named simplices and finding the distinct ones, with their rows and ways
    /// back.
    pub ordering: f64,
    /// The oracle's decisions (and the retries where it rejected a named simplex).
    pub deciding: f64,
    /// Taking the level into S and the rim, and making it the next frontier.
    pub accepting: f64,
}

impl LevelSteps {
    /// Adds the time since `since` to `step`.
    pub(crate) fn add(step: &mut f64, since: std::time::Instant) {
        *step += since.elapsed().as_secs_f64();
    }

    /// The time of the level steps `step` is part of (none for a whole level).
    pub(crate) fn of(&mut self, step: step_threads::Step) -> Option<&mut f64> {
        use step_threads::Step;
        match step {
            Step::Naming => Some(&mut self.naming),
            Step::Caching | Step::NamingDeferred => Some(&mut self.new_vertices),
            Step::Ordering => Some(&mut self.ordering),
            Step::Deciding => Some(&mut self.deciding),
            Step::Gathering | Step::Accepting => Some(&mut self.accepting),
            Step::Level => None,
        }
    }
}

impl TraceStats {
    /// Counts a batch of decisions: a status per simplex, reached as `how` says.
    pub(crate) fn count_decisions(&mut self, status: &[crate::cpu::solve::Status], how: Decisions) {
        use crate::cpu::solve::Status;
        let m = status.len() as u64;
        self.oracle_calls += m;
        self.exact_decisions += how.exact;
        self.device_decisions += how.on_device;
        self.cpu_decisions += m - how.on_device;
        for s in status {
            match s {
                Status::Degenerate => self.degenerate += 1,
                Status::NonFinite => self.non_finite += 1,
                _ => {}
            }
        }
    }

    /// Why a run that found no crossed simplex, and was not stopped, found none: a sentence
    /// saying what to change. `exhaustive`: it was a scan; `seeds_given`: it was traced from
    /// seeds the caller gave.
    pub fn why_nothing_found(&self, exhaustive: bool, seeds_given: bool) -> String {
        let why = if self.non_finite > 0 {
            format!(
                "f is NaN or infinite at {} of the points tried (non_finite in the report) and \
                 crosses 0 nowhere else",
                self.non_finite
            )
        } else if exhaustive {
            "f changes sign on no simplex of the box at this edge (f may have no zero there, or \
             only zeros it touches without crossing: try a smaller edge or another box)"
                .to_string()
        } else if self.seed_points == 0 && !seeds_given {
            "the seed search found no point of M in the box (f may have no zero there: give a \
             seed, a larger search or another box)"
                .to_string()
        } else {
            "M was not met: f has no zero in the box at this edge (give a seed, a smaller edge \
             or another box)"
                .to_string()
        };
        format!("no crossed simplex was found: {why}")
    }
}

/// What the engine and the scan share.
pub(crate) struct TraceContext<'a> {
    pub f: &'a dyn ImplicitFunction,
    pub tri: &'a Triangulation,
    pub oracle: &'a dyn Oracle,
    pub codec: KeyCodec,
    pub d: usize,
    pub k: usize,
    pub domain: Domain<'a>,
    pub max_memory: u64,
    pub cancel: Option<&'a AtomicBool>,
    pub progress: Option<&'a (dyn Fn(&Progress) + Sync)>,
    /// How a level's steps choose their threads (tests choose other ways).
    pub step_threads: step_threads::Policy,
    /// Makes the pivot name a wrong facet, to test the fallback (unit tests only).
    #[cfg(test)]
    pub scramble_pivots: bool,
    /// Makes naming find no vertex in the last levels' tables, to test the lookups of the
    /// deferred ones in the whole cache (unit tests only).
    #[cfg(test)]
    pub forget_vertices: bool,
    /// Makes a trace with no box measure its reach at every level, not only where its
    /// bound could pass a limit (unit tests only).
    #[cfg(test)]
    pub reach_every_level: bool,
}

impl TraceContext<'_> {
    /// Whether the cancel flag (Ctrl-C) is set.
    pub fn interrupted(&self) -> bool {
        self.cancel
            .is_some_and(|c| c.load(std::sync::atomic::Ordering::Relaxed))
    }

    /// Whether a trace with no box measures its reach at every level (a test's check of
    /// the bound it uses otherwise).
    #[inline]
    pub fn reach_every_level(&self) -> bool {
        #[cfg(test)]
        return self.reach_every_level;
        #[cfg(not(test))]
        false
    }
}

/// Calls `$f::<W>($args)` with W the supported key width at least `$words`.
macro_rules! with_width {
    ($words:expr, $f:ident ( $($arg:expr),* )) => {
        match $words {
            1 => $f::<1>($($arg),*),
            2 => $f::<2>($($arg),*),
            3 => $f::<3>($($arg),*),
            4 => $f::<4>($($arg),*),
            5..=6 => $f::<6>($($arg),*),
            7..=8 => $f::<8>($($arg),*),
            9..=12 => $f::<12>($($arg),*),
            13..=16 => $f::<16>($($arg),*),
            17..=24 => $f::<24>($($arg),*),
            // d = 63 with no box: 63 coordinates of 20 bits and 63 part indices of 6 bits.
            25..=32 => $f::<32>($($arg),*),
            w => Err(Error::Trace(format!(
                "simplex keys of {w} words are not supported (at most 32): give a smaller box"
            ))),
        }
    };
}
pub(crate) use with_width;

fn context<'a>(
    f: &'a dyn ImplicitFunction,
    tri: &'a Triangulation,
    oracle: &'a dyn Oracle,
    opts: &'a TraceOptions,
) -> Result<TraceContext<'a>> {
    let (d, k) = (f.ambient_dim(), f.codim());
    if tri.dim() != d {
        return Err(Error::DimensionMismatch(format!(
            "f takes {d} coordinates, the triangulation is of R^{}",
            tri.dim()
        )));
    }
    if k == 0 || k >= d {
        return Err(Error::DimensionMismatch(format!(
            "{k} equations in R^{d}: tracing needs 1 <= k < d"
        )));
    }
    if let Some(b) = &opts.bbox {
        check_box(b, d)?;
    }
    let bbox = opts.bbox.as_deref();
    if let Some(b) = &opts.key_box {
        check_box(b, d)?;
    }
    let codec = KeyCodec::new(d, k, coord_bits(tri, opts.key_box.as_deref().or(bbox)))?;
    Ok(TraceContext {
        f,
        tri,
        oracle,
        codec,
        d,
        k,
        domain: Domain::new(f, bbox),
        max_memory: opts.max_memory,
        cancel: opts.cancel.as_deref(),
        progress: opts.progress,
        step_threads: step_threads::Policy::default(),
        #[cfg(test)]
        scramble_pivots: false,
        #[cfg(test)]
        forget_vertices: false,
        #[cfg(test)]
        reach_every_level: false,
    })
}

/// Traces M = f^-1(0) on `tri` from the seeds (and/or a box search) in `opts`, with `oracle`.
/// An early stop (Ctrl-C, memory limit) still returns what was traced, with
/// `stats.stopped` set.
pub fn trace(
    f: &dyn ImplicitFunction,
    tri: &Triangulation,
    oracle: &dyn Oracle,
    opts: &TraceOptions,
) -> Result<Sample> {
    let ctx = context(f, tri, oracle, opts)?;
    let search = opts.search_samples.unwrap_or(if opts.seeds.is_empty() {
        DEFAULT_SEARCH_SAMPLES
    } else {
        0
    });
    if search > 0 && opts.bbox.is_none() {
        return Err(Error::Trace(
            "no seed and no box: give a seed point near M, or a box to search for it".into(),
        ));
    }
    let mut seeds = Vec::with_capacity(opts.seeds.len());
    for (i, s) in opts.seeds.iter().enumerate() {
        let p = crate::expr::newton_project(f, s, SEED_TOLERANCE)
            .map_err(|e| Error::Trace(format!("seed {} {s:?} is off the manifold: {e}", i + 1)))?;
        if !ctx.domain.contains(&p) {
            return Err(Error::Trace(format!(
                "seed {} {s:?} projects to {p:?}, outside the box or the boundary inequalities",
                i + 1
            )));
        }
        seeds.push(p);
    }
    let words = ctx.codec.words();
    // On a worker of the pool, levels too small to split run on this thread with no
    // hand-over to another, and the other threads stay awake for the larger ones.
    warm::maybe(opts.warm, || {
        with_width!(words, trace_with(f, ctx, &seeds, search, opts.search_seed))
    })
}

fn trace_with<const W: usize>(
    f: &dyn ImplicitFunction,
    ctx: TraceContext,
    seeds: &[Vec<f64>],
    search: usize,
    search_seed: u64,
) -> Result<Sample> {
    let start = Instant::now();
    let codec = ctx.codec;
    let bbox = ctx.domain.bbox.map(<[_]>::to_vec);
    let mut engine: Engine<W> = Engine::new(ctx);
    let traced = (|| {
        for s in seeds {
            if engine.stats.stopped.is_some() {
                return Ok(());
            }
            engine.trace_from_point(s)?;
        }
        if search > 0 && engine.stats.stopped.is_none() {
            let b = bbox.expect("checked by trace()");
            engine.trace_from_box(f, &b, search, search_seed)?;
        }
        Ok(())
    })();
    match traced {
        // An oracle stopped by the cancel flag (a wait on a device): the levels accepted
        // so far are the sample, as for a stop between levels.
        Err(Error::Interrupted(_)) => engine.stats.stopped = Some(StopReason::Interrupted),
        other => other?,
    }
    let mut stats = engine.stats.clone();
    stats.memory_bytes = engine.bytes() as u64;
    stats.elapsed_s = start.elapsed().as_secs_f64();
    let tri = engine.ctx.tri;
    sample_from(codec, tri, engine, stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::expr::preset;

    /// Preset `name` traced at `edge` by the CPU oracle, then twice more with its context
    /// changed by `alter`: with whole levels, and with levels decided in slices of 5 frontier
    /// simplices.
    fn traced_with(
        name: &str,
        edge: f64,
        alter: impl Fn(&mut TraceContext<'_>),
    ) -> (Sample, [Sample; 2]) {
        let mut p = preset(name, &[]).unwrap();
        p.triangulation.edge = Some(edge);
        let tri = p.triangulation.build(p.dim()).unwrap();
        let oracle = CpuOracle::new(&p.system);
        let opts = TraceOptions {
            seeds: p.seeds.clone(),
            ..TraceOptions::default()
        };
        let plain = trace(&p.system, &tri, &oracle, &opts).unwrap();
        let seeds: Vec<Vec<f64>> = p
            .seeds
            .iter()
            .map(|s| crate::expr::newton_project(&p.system, s, SEED_TOLERANCE).unwrap())
            .collect();
        let sliced = Sliced(CpuOracle::new(&p.system));
        let altered = [&oracle as &dyn Oracle, &sliced].map(|o| {
            let mut ctx = context(&p.system, &tri, o, &opts).unwrap();
            alter(&mut ctx);
            let words = ctx.codec.words();
            with_width!(words, trace_with(&p.system, ctx, &seeds, 0, 1)).unwrap()
        });
        (plain, altered)
    }

    /// Whether `a` and `b` hold the same simplices in the same order, with the same points.
    fn assert_same_sample(a: &Sample, b: &Sample, name: &str) {
        assert_eq!(a.len(), b.len(), "{name}");
        assert!(
            (0..a.len()).all(|i| a.key(i) == b.key(i)),
            "{name}: the samples differ"
        );
        assert_eq!(a.points(), b.points(), "{name}");
    }

    /// Where the pivot names a wrong facet, the oracle rejects it and every facet of its
    /// cofacet is tested: the trace is the same, in the same order.
    #[test]
    fn wrong_pivots_fall_back_to_testing_every_facet() {
        for (name, edge) in [("sphere", 0.2), ("flat-torus", 0.3), ("3-torus", 0.8)] {
            let (right, [wrong, wrong_sliced]) =
                traced_with(name, edge, |c| c.scramble_pivots = true);
            assert_eq!(right.stats.pivot_fallbacks, 0, "{name}");
            assert!(wrong.stats.pivot_fallbacks > 0, "{name}: no fallback");
            assert_eq!(
                wrong.stats.pivot_fallbacks, wrong_sliced.stats.pivot_fallbacks,
                "{name}"
            );
            assert_eq!(wrong.stats.oracle_calls, wrong_sliced.stats.oracle_calls);
            for other in [&wrong, &wrong_sliced] {
                assert_same_sample(&right, other, name);
            }
        }
    }

    /// A level's steps give the same trace on all the pool's threads as on one: with every
    /// level, and every step of the levels not run alone, switching ways in turn, S, its
    /// order and points, and the counters are those of a one-thread pool.
    #[test]
    fn steps_switching_between_one_thread_and_all_give_the_same_trace() {
        for (name, edge) in [
            ("sphere", 0.05),
            ("chair", 0.1),
            ("flat-torus", 0.3),
            ("3-torus", 0.8),
        ] {
            let one = crate::test_pool(1).install(|| traced_with(name, edge, |_| {}).0);
            let (plain, switching) = crate::test_pool(3).install(|| {
                traced_with(name, edge, |c| {
                    c.step_threads = step_threads::Policy::Alternate;
                })
            });
            for other in [&plain, &switching[0], &switching[1]] {
                assert_same_sample(&one, other, name);
                let (a, b) = (&one.stats, &other.stats);
                assert_eq!(a.vertices, b.vertices, "{name}");
                assert_eq!(a.oracle_calls, b.oracle_calls, "{name}");
                assert_eq!(a.levels, b.levels, "{name}");
                assert_eq!(a.widest_level, b.widest_level, "{name}");
            }
        }
    }

    /// Where naming finds no vertex in its thread's table of the last levels' vertices, the
    /// deferred vertices are found in the whole cache: the trace is the same, and each
    /// vertex is cached and evaluated once.
    #[test]
    fn vertices_missed_in_the_last_levels_are_found_in_the_whole_cache() {
        for (name, edge) in [("sphere", 0.1), ("flat-torus", 0.3), ("3-torus", 0.8)] {
            let (right, forgot) = traced_with(name, edge, |c| c.forget_vertices = true);
            for other in &forgot {
                assert_same_sample(&right, other, name);
                assert_eq!(right.stats.vertices, other.stats.vertices, "{name}");
                assert_eq!(
                    right.stats.cpu_vertex_evaluations, other.stats.cpu_vertex_evaluations,
                    "{name}"
                );
                assert_eq!(right.stats.oracle_calls, other.stats.oracle_calls, "{name}");
            }
        }
    }

    /// With no box, a trace that measures how far its levels reach only where the bound of
    /// two lattice steps a level could pass the extent stops at the same level, with the
    /// same S, as one that measures every level.
    #[test]
    fn the_extent_stops_a_trace_where_measuring_every_level_would() {
        let cases: [(&[&str], &[f64], f64); 3] = [
            (&["x2 - 0.5*x1"], &[0.0, 0.0], 0.5),
            (&["x1*x2 - 1"], &[1.0, 1.0], 0.5),
            (
                &["x1^2 + x2^2 - 1", "x3 - 0.25*x4"],
                &[1.0, 0.0, 0.0, 0.0],
                0.7,
            ),
        ];
        for (eqs, seed, edge) in cases {
            let d = seed.len();
            let f = crate::expr::EquationSystem::parse_simple(d, eqs).unwrap();
            let tri = crate::triangulation::Triangulation::coxeter(d)
                .edge(edge)
                .build()
                .unwrap();
            let oracle = CpuOracle::new(&f);
            let opts = TraceOptions {
                seeds: vec![seed.to_vec()],
                ..TraceOptions::default()
            };
            let seeds = vec![crate::expr::newton_project(&f, seed, SEED_TOLERANCE).unwrap()];
            let [bounded, every] = [false, true].map(|every| {
                let mut ctx = context(&f, &tri, &oracle, &opts).unwrap();
                ctx.reach_every_level = every;
                let words = ctx.codec.words();
                with_width!(words, trace_with(&f, ctx, &seeds, 0, 1)).unwrap()
            });
            assert!(
                matches!(every.stats.stopped, Some(StopReason::NoBox { .. })),
                "{eqs:?}: {:?}",
                every.stats.stopped
            );
            assert_eq!(bounded.stats.stopped, every.stats.stopped, "{eqs:?}");
            assert_eq!(bounded.stats.levels, every.stats.levels, "{eqs:?}");
            assert_same_sample(&bounded, &every, &format!("{eqs:?}"));
        }
    }

    /// The CPU oracle, deciding trace levels in slices of 5 frontier simplices.
    struct Sliced<'f>(CpuOracle<'f>);

    impl Oracle for Sliced<'_> {
        fn name(&self) -> String {
            self.0.name()
        }
        fn values(&self) -> &dyn Evaluate {
            &self.0
        }
        fn decisions(&self) -> &dyn Decide {
            self
        }
    }

    impl Decide for Sliced<'_> {
        fn decide(
            &self,
            values: &[f64],
            simplices: &[u32],
            status: &mut [crate::cpu::solve::Status],
            lambda: &mut [f64],
        ) -> Result<super::Decisions> {
            self.0.decide(values, simplices, status, lambda)
        }
        fn decide_growing(
            &self,
            log: super::GrowingValues,
            values: &[f64],
            simplices: &[u32],
            status: &mut [crate::cpu::solve::Status],
            lambda: &mut [f64],
        ) -> Result<super::Decisions> {
            self.0
                .decide_growing(log, values, simplices, status, lambda)
        }
        fn level_slice(&self) -> Option<usize> {
            Some(5)
        }
    }
}
