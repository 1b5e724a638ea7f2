//! Manifold tracing: agreement with the exhaustive scan, door in / door out, accuracy of the
//! points, exact ties, determinism, and clean failures.

use std::collections::{HashMap, HashSet};

use isomesh::cpu::solve::Status;
use isomesh::expr::{preset, EquationSystem, ImplicitFunction, Problem};
use isomesh::trace::scan::candidates::{Candidates, BASE};
use isomesh::trace::{
    exhaustive, scan_grid, trace, CpuOracle, Decide, DeviceValues, Evaluate, Oracle, Sample, Scan,
    ScanGrid, StopReason, TraceOptions,
};
use isomesh::triangulation::{Simplex, Triangulation};
use isomesh::{Error, Result};

/// Preset `name` with `params`, at longest edge `edge`.
fn problem(name: &str, params: &[(&str, f64)], edge: f64) -> Problem {
    let params: Vec<(String, f64)> = params.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    let mut p = preset(name, &params).unwrap();
    p.triangulation.edge = Some(edge);
    p
}

fn run(p: &Problem, bbox: Option<Vec<[f64; 2]>>, scan: bool) -> Sample {
    let tri = p.triangulation.build(p.dim()).unwrap();
    let oracle = CpuOracle::new(&p.system);
    let opts = TraceOptions {
        seeds: p.seeds.clone(),
        bbox,
        ..TraceOptions::default()
    };
    if scan {
        exhaustive(&p.system, &tri, &oracle, &opts).unwrap()
    } else {
        trace(&p.system, &tri, &oracle, &opts).unwrap()
    }
}

/// Every (k+1)-simplex with a crossed k-face has exactly two of them.
fn assert_door_in_door_out(s: &Sample, what: &str) {
    let keys: HashSet<Simplex> = s.iter().map(|(x, _)| x).collect();
    let mut cofaces = 0;
    for (sigma, _) in s.iter() {
        for tau in sigma.cofacets() {
            let crossed = tau.facets().iter().filter(|f| keys.contains(f)).count();
            assert_eq!(crossed, 2, "{what}: {tau} has {crossed} crossed facets");
            cofaces += 1;
        }
    }
    assert!(cofaces > 0);
}

/// Points lie in their simplex and |f(p)| <= c * edge^2 for every component.
fn assert_points_accurate(p: &Problem, s: &Sample, edge: f64, c: f64) {
    let tri = p.triangulation.build(p.dim()).unwrap();
    let mut f = vec![0.0; p.system.codim()];
    let mut worst: f64 = 0.0;
    for (sigma, x) in s.iter() {
        let carrier = tri.locate_with_tolerance(&x, 1e-9).unwrap();
        assert!(
            sigma.contains(&carrier),
            "{}: point {x:?} lies in {carrier}, not in {sigma}",
            p.name
        );
        p.system.eval_batch(&x, &mut f);
        worst = f.iter().fold(worst, |m, v| m.max(v.abs()));
    }
    assert!(
        worst <= c * edge * edge,
        "{}: max |f(p)| = {worst:e} > {c} * edge^2 = {:e}",
        p.name,
        c * edge * edge
    );
}

fn cube(d: usize, r: f64) -> Vec<[f64; 2]> {
    vec![[-r, r]; d]
}

/// (preset, parameters, box, two edges, C in |f(p)| <= C edge^2).
type Case = (
    &'static str,
    Vec<(&'static str, f64)>,
    Vec<[f64; 2]>,
    [f64; 2],
    f64,
);

/// The cases of [`Case`].
///
/// C is half a bound on the Hessian of f near M (linear interpolation error on a simplex of
/// diameter `edge`): 1 for the quadrics |x|^2 - r^2; for the torus 2; for the quartic chair
/// (|H| <= 16 inside |x| <= 1.3) 8.
fn cases() -> Vec<Case> {
    vec![
        (
            "sphere",
            vec![("m", 1.0), ("d", 2.0)],
            cube(2, 1.3),
            [0.1, 0.05],
            1.0,
        ),
        (
            "sphere",
            vec![("m", 1.0), ("d", 3.0)],
            cube(3, 1.3),
            [0.2, 0.12],
            1.0,
        ),
        (
            "sphere",
            vec![("m", 2.0), ("d", 3.0)],
            cube(3, 1.3),
            [0.2, 0.1],
            1.0,
        ),
        (
            "sphere",
            vec![("m", 2.0), ("d", 4.0)],
            cube(4, 1.3),
            [0.35, 0.25],
            1.0,
        ),
        (
            "sphere",
            vec![("m", 3.0), ("d", 4.0)],
            cube(4, 1.3),
            [0.4, 0.25],
            1.0,
        ),
        (
            "sphere",
            vec![("m", 2.0), ("d", 5.0)],
            cube(5, 1.3),
            [0.5, 0.4],
            1.0,
        ),
        (
            "sphere",
            vec![("m", 3.0), ("d", 6.0)],
            cube(6, 1.3),
            [0.8, 0.6],
            1.0,
        ),
        (
            "torus",
            vec![],
            vec![[-1.6, 1.6], [-1.6, 1.6], [-0.6, 0.6]],
            [0.1, 0.06],
            2.0,
        ),
        ("chair", vec![], cube(3, 1.4), [0.1, 0.0707], 8.0),
        ("flat-torus", vec![], cube(4, 1.2), [0.3, 0.2], 1.0),
        (
            "3-torus",
            vec![],
            vec![
                [-0.7, 0.7],
                [-0.7, 0.7],
                [-1.2, 1.2],
                [-1.2, 1.2],
                [-2.2, 2.2],
                [-2.2, 2.2],
            ],
            [0.7, 0.5555],
            1.0,
        ),
    ]
}

#[test]
fn tracing_finds_exactly_the_exhaustive_scan() {
    for (name, params, bbox, edges, c) in cases() {
        for edge in edges {
            let p = problem(name, &params, edge);
            let traced = run(&p, Some(bbox.clone()), false);
            let scanned = run(&p, Some(bbox.clone()), true);
            let what = format!("{name} {params:?} edge {edge}");
            assert!(traced.len() > 10, "{what}: only {} simplices", traced.len());
            assert_eq!(
                traced.sorted_keys(),
                scanned.sorted_keys(),
                "{what}: trace {} vs scan {}",
                traced.len(),
                scanned.len()
            );
            assert_eq!(traced.stats.components, 1, "{what}");
            assert_eq!(scanned.stats.components, 1, "{what}");
            assert_door_in_door_out(&traced, &what);
            assert_points_accurate(&p, &traced, edge, c);
            // The scan's points come from f's values on its grid: the trace's, bit for bit.
            let (t, s) = (points_by_key(&traced), points_by_key(&scanned));
            let differ = t.iter().zip(&s).filter(|(a, b)| a != b).count();
            assert_eq!(differ, 0, "{what}: {differ} of {} points differ", t.len());
        }
    }
}

/// Every simplex's key and point (as bits), in key order.
fn points_by_key(s: &Sample) -> Vec<(Vec<u64>, Vec<u64>)> {
    let d = s.ambient_dim();
    let mut out: Vec<_> = s
        .points()
        .chunks_exact(d)
        .enumerate()
        .map(|(i, p)| (s.key(i).to_vec(), p.iter().map(|x| x.to_bits()).collect()))
        .collect();
    out.sort();
    out
}

#[test]
fn tracing_without_a_box_closes_up() {
    // The same manifolds with no box at all: the trace stops because M is closed.
    for name in ["circle", "torus", "flat-torus"] {
        let p = problem(name, &[], 0.1);
        let s = run(&p, None, false);
        assert_door_in_door_out(&s, name);
        assert!(s.stats.stopped.is_none());
    }
}

/// FK lattice scaled by 1/8 with offset 0 and no rotation: the six points (+-1, 0, 0).. are
/// lattice vertices where f = |x|^2 - 1 is exactly 0, so ties must be broken exactly.
#[test]
fn vertices_exactly_on_the_sphere_still_give_a_closed_result() {
    let sys = EquationSystem::parse_simple(3, &["x^2 + y^2 + z^2 - 1"]).unwrap();
    let m = vec![
        vec![0.125, 0.0, 0.0],
        vec![0.0, 0.125, 0.0],
        vec![0.0, 0.0, 0.125],
    ];
    let tri = Triangulation::custom(m).build().unwrap();
    assert_eq!(tri.offset(), &[0.0, 0.0, 0.0]);
    let mut f = [1.0];
    let mut x = [0.0; 3];
    tri.vertex_coords(&[8, 0, 0], &mut x);
    sys.eval_batch(&x, &mut f);
    assert_eq!(f[0], 0.0, "the lattice vertex (1, 0, 0) lies exactly on M");

    let oracle = CpuOracle::new(&sys);
    let opts = TraceOptions {
        seeds: vec![vec![1.0, 0.0, 0.0]],
        bbox: Some(cube(3, 1.5)),
        ..TraceOptions::default()
    };
    let s = trace(&sys, &tri, &oracle, &opts).unwrap();
    let e = exhaustive(&sys, &tri, &oracle, &opts).unwrap();
    assert_door_in_door_out(&s, "sphere with vertices on it");
    assert!(s.sorted_keys() == e.sorted_keys(), "trace and scan differ");
    assert!(
        s.stats.exact_decisions > 0,
        "the exact tie-breaking path was not exercised"
    );
    assert_eq!(s.stats.components, 1);

    // A circle of radius 5 on the integer lattice: twelve vertices (3,4), (5,0).. on it.
    let sys = EquationSystem::parse_simple(2, &["x^2 + y^2 - 25"]).unwrap();
    let tri = Triangulation::custom(vec![vec![1.0, 0.0], vec![0.0, 1.0]])
        .build()
        .unwrap();
    let oracle = CpuOracle::new(&sys);
    let opts = TraceOptions {
        seeds: vec![vec![5.0, 0.0]],
        ..TraceOptions::default()
    };
    let s = trace(&sys, &tri, &oracle, &opts).unwrap();
    assert_door_in_door_out(&s, "circle through lattice vertices");
    assert!(s.stats.exact_decisions > 0);
}

#[test]
fn output_is_the_same_with_any_thread_count_and_across_runs() {
    let p = problem("flat-torus", &[], 0.2);
    let with_threads = |n: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
            .install(|| run(&p, None, false))
    };
    let one = with_threads(1);
    let others: Vec<_> = [2, 3, 8, 16, 2].into_iter().map(with_threads).collect();
    for other in &others {
        assert_eq!(one.len(), other.len());
        for i in 0..one.len() {
            assert_eq!(one.key(i), other.key(i), "simplex {i}");
            let (a, b) = (one.point(i), other.point(i));
            assert!(a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
    }
}

#[test]
fn non_compact_graph_is_traced_inside_its_box() {
    // z = cos(w): the box is its boundary.
    let p = problem("complex-cosine", &[], 0.25);
    let bbox = p.bbox.clone();
    let s = run(&p, bbox.clone(), false);
    assert!(s.len() > 100);
    let b = bbox.clone().unwrap();
    for (_, x) in s.iter() {
        assert!(isomesh::trace::in_box(&b, &x));
    }
    let e = run(&p, bbox, true);
    assert_eq!(s.sorted_keys(), e.sorted_keys());
}

#[test]
fn automatic_seeds_find_every_component() {
    // Two disjoint unit circles: no seed, a box, one trace per component.
    let sys =
        EquationSystem::parse_simple(2, &["((x-2)^2 + y^2 - 1) * ((x+2)^2 + y^2 - 1)"]).unwrap();
    let tri = Triangulation::coxeter(2)
        .edge(0.1)
        .rotation_seed(1)
        .build()
        .unwrap();
    let oracle = CpuOracle::new(&sys);
    let opts = TraceOptions {
        bbox: Some(vec![[-3.5, 3.5], [-1.5, 1.5]]),
        ..TraceOptions::default()
    };
    let s = trace(&sys, &tri, &oracle, &opts).unwrap();
    assert_eq!(s.stats.components, 2);
    let e = exhaustive(&sys, &tri, &oracle, &opts).unwrap();
    assert_eq!(e.stats.components, 2);
    assert_eq!(s.sorted_keys(), e.sorted_keys());
}

#[test]
fn bad_requests_get_clear_errors() {
    let p = problem("sphere", &[], 0.2);
    let tri = p.triangulation.build(3).unwrap();
    let oracle = CpuOracle::new(&p.system);
    let go = |opts: TraceOptions| trace(&p.system, &tri, &oracle, &opts);

    // A seed where Newton cannot reach M (the gradient vanishes at the centre).
    let e = go(TraceOptions {
        seeds: vec![vec![0.0, 0.0, 0.0]],
        ..TraceOptions::default()
    })
    .unwrap_err();
    assert!(
        matches!(e, Error::Trace(ref m) if m.contains("off the manifold")),
        "{e}"
    );
    // Wrong dimension, non-finite seed.
    assert!(go(TraceOptions {
        seeds: vec![vec![1.0, 0.0]],
        ..TraceOptions::default()
    })
    .is_err());
    assert!(go(TraceOptions {
        seeds: vec![vec![f64::NAN, 0.0, 0.0]],
        ..TraceOptions::default()
    })
    .is_err());
    // No seed and no box.
    let e = go(TraceOptions::default()).unwrap_err();
    assert!(e.to_string().contains("no seed and no box"), "{e}");
    // The exhaustive scan needs a box, and refuses grids beyond the memory limit.
    let e = exhaustive(&p.system, &tri, &oracle, &TraceOptions::default()).unwrap_err();
    assert!(e.to_string().contains("needs a box"), "{e}");
    let e = exhaustive(
        &p.system,
        &tri,
        &oracle,
        &TraceOptions {
            bbox: Some(cube(3, 30.0)),
            max_memory: 1 << 28,
            ..TraceOptions::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("memory limit"), "{e}");
    let e = exhaustive(
        &p.system,
        &tri,
        &oracle,
        &TraceOptions {
            bbox: Some(cube(3, 1e4)),
            ..TraceOptions::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("2^32"), "{e}");
}

#[test]
fn memory_limit_and_cancel_stop_cleanly_keeping_the_sample() {
    let p = problem("torus", &[], 0.02);
    let tri = p.triangulation.build(3).unwrap();
    let oracle = CpuOracle::new(&p.system);
    let s = trace(
        &p.system,
        &tri,
        &oracle,
        &TraceOptions {
            seeds: p.seeds.clone(),
            max_memory: 200_000,
            ..TraceOptions::default()
        },
    )
    .unwrap();
    assert!(matches!(
        s.stats.stopped,
        Some(StopReason::MemoryLimit { .. })
    ));
    assert!(!s.is_empty());
    assert!(s.stats.memory_bytes <= 200_000);

    let cancel = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
    let s = trace(
        &p.system,
        &tri,
        &oracle,
        &TraceOptions {
            seeds: p.seeds.clone(),
            cancel: Some(cancel),
            ..TraceOptions::default()
        },
    )
    .unwrap();
    assert_eq!(s.stats.stopped, Some(StopReason::Interrupted));
}

#[test]
fn concurrent_exhaustive_scans_share_the_pool_without_deadlock() {
    // Each scan overlaps generating one batch with deciding the last, inside the rayon pool:
    // here more scans at once than the pool has threads, and one scan on a pool of one
    // thread. A scan that blocked a pool thread while it waited would hang; the watchdog
    // fails the test.
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let p = problem("sphere", &[], 0.03);
        let tri = p.triangulation.build(3).unwrap();
        let opts = TraceOptions {
            bbox: Some(vec![[-1.3, 1.3]; 3]),
            ..TraceOptions::default()
        };
        let run = || exhaustive(&p.system, &tri, &CpuOracle::new(&p.system), &opts).unwrap();
        let alone = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap()
            .install(run);
        let many: Vec<Sample> = std::thread::scope(|s| {
            let runs: Vec<_> = (0..=rayon::current_num_threads())
                .map(|_| s.spawn(run))
                .collect();
            runs.into_iter().map(|r| r.join().unwrap()).collect()
        });
        let same = many.iter().all(|m| m.sorted_keys() == alone.sorted_keys());
        tx.send((same, alone.len())).unwrap();
    });
    let (same, n) = rx
        .recv_timeout(std::time::Duration::from_secs(300))
        .expect("the scans did not finish: pool threads wait on each other");
    assert!(same && n > 1000, "the scans differ ({n} simplices)");
}

/// The CPU oracle with test behaviours: `cancel`, raised once it has decided a batch with
/// crossings (a Ctrl-C mid-scan); `slice`, trace levels asked for in slices of that many
/// frontier simplices, as an oracle that decides on a device does.
struct Probe<'a> {
    inner: CpuOracle<'a>,
    cancel: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
    slice: Option<usize>,
}

impl Oracle for Probe<'_> {
    fn name(&self) -> String {
        self.inner.name()
    }
    fn values(&self) -> &dyn Evaluate {
        &self.inner
    }
    fn decisions(&self) -> &dyn Decide {
        self
    }
}

impl Decide for Probe<'_> {
    fn decide(
        &self,
        values: &[f64],
        simplices: &[u32],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> isomesh::Result<isomesh::trace::Decisions> {
        let exact = self.inner.decide(values, simplices, status, lambda)?;
        if let Some(c) = &self.cancel {
            if status.iter().any(|s| s.crossed()) {
                c.store(true, std::sync::atomic::Ordering::Relaxed);
            }
        }
        Ok(exact)
    }
    fn level_slice(&self) -> Option<usize> {
        self.slice
    }
}

#[test]
fn an_interrupted_exhaustive_scan_keeps_what_it_found() {
    // About five million lattice vertices: several batches of cubes.
    let p = problem("sphere", &[], 0.02);
    let tri = p.triangulation.build(3).unwrap();
    let mut opts = TraceOptions {
        bbox: Some(vec![[-1.3, 1.3]; 3]),
        ..TraceOptions::default()
    };
    let full = exhaustive(&p.system, &tri, &CpuOracle::new(&p.system), &opts).unwrap();
    let cancel = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    opts.cancel = Some(cancel.clone());
    let oracle = Probe {
        inner: CpuOracle::new(&p.system),
        cancel: Some(cancel),
        slice: None,
    };
    let part = exhaustive(&p.system, &tri, &oracle, &opts).unwrap();
    assert!(full.stats.stopped.is_none());
    assert_a_kept_part(&part, &full, "stopped after a batch");
}

/// `part`, a scan stopped by Ctrl-C, kept a part of the whole scan `full`: some of its
/// simplices, none else, with f's values at every vertex of them (every point known).
fn assert_a_kept_part(part: &Sample, full: &Sample, what: &str) {
    assert_eq!(part.stats.stopped, Some(StopReason::Interrupted), "{what}");
    assert!(
        !part.is_empty() && part.len() < full.len(),
        "{what}: {} of {}",
        part.len(),
        full.len()
    );
    let all: HashSet<&[u64]> = full.sorted_keys().into_iter().collect();
    assert!(part.sorted_keys().iter().all(|k| all.contains(k)), "{what}");
    let unknown = part.points().iter().filter(|x| !x.is_finite()).count();
    assert_eq!(unknown, 0, "{what}");
}

/// The CPU oracle raising `cancel` as it evaluates f for the `at`-th time (inside a level,
/// while its new vertices are evaluated), and counting the batches it decides afterwards.
struct StopWhileEvaluating<'a> {
    inner: CpuOracle<'a>,
    cancel: std::sync::Arc<std::sync::atomic::AtomicBool>,
    at: usize,
    evaluations: std::sync::atomic::AtomicUsize,
    decided_after: std::sync::atomic::AtomicUsize,
}

impl Oracle for StopWhileEvaluating<'_> {
    fn name(&self) -> String {
        self.inner.name()
    }
    fn values(&self) -> &dyn Evaluate {
        self
    }
    fn decisions(&self) -> &dyn Decide {
        self
    }
}

impl Evaluate for StopWhileEvaluating<'_> {
    fn eval_vertices(
        &self,
        tri: &Triangulation,
        lattice: &[i32],
        values: &mut [f64],
    ) -> Result<()> {
        use std::sync::atomic::Ordering::Relaxed;
        if self.evaluations.fetch_add(1, Relaxed) + 1 == self.at {
            self.cancel.store(true, Relaxed);
        }
        self.inner.eval_vertices(tri, lattice, values)
    }
}

impl Decide for StopWhileEvaluating<'_> {
    fn decide(
        &self,
        values: &[f64],
        simplices: &[u32],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> Result<isomesh::trace::Decisions> {
        use std::sync::atomic::Ordering::Relaxed;
        if self.cancel.load(Relaxed) {
            self.decided_after.fetch_add(1, Relaxed);
        }
        self.inner.decide(values, simplices, status, lambda)
    }
}

#[test]
fn a_scan_stopped_while_it_evaluates_f_keeps_what_it_found() {
    // About five million lattice vertices, evaluated in slabs of about a million: the stop
    // comes while a later slab's f is evaluated, or while it is scanned. What the slabs before
    // found is kept, with f's values at all of its vertices, those of the layer the next
    // slab was to start from included.
    let p = problem("sphere", &[], 0.02);
    let tri = p.triangulation.build(3).unwrap();
    let mut opts = TraceOptions {
        bbox: Some(vec![[-1.3, 1.3]; 3]),
        ..TraceOptions::default()
    };
    let full = exhaustive(&p.system, &tri, &CpuOracle::new(&p.system), &opts).unwrap();
    for at in [20, 33, 47, 60] {
        let cancel = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        opts.cancel = Some(cancel.clone());
        let oracle = StopWhileEvaluating {
            inner: CpuOracle::new(&p.system),
            cancel,
            at,
            evaluations: Default::default(),
            decided_after: Default::default(),
        };
        let part = exhaustive(&p.system, &tri, &oracle, &opts).unwrap();
        assert_a_kept_part(&part, &full, &format!("stopped at evaluation {at}"));
    }
}

#[test]
fn a_stop_inside_a_level_drops_the_level_undecided() {
    // A signal that comes while a level evaluates f at its new vertices: nothing more of the
    // level is decided (in high dimensions that is seconds of work), and the levels before
    // it are kept.
    for (name, params, edge) in [
        ("sphere", vec![], 0.1),
        ("sphere", vec![("d", 5.0), ("m", 4.0)], 0.4),
    ] {
        let p = problem(name, &params, edge);
        let tri = p.triangulation.build(p.dim()).unwrap();
        let full = run(&p, None, false);
        let cancel = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let oracle = StopWhileEvaluating {
            inner: CpuOracle::new(&p.system),
            cancel: cancel.clone(),
            at: 4,
            evaluations: Default::default(),
            decided_after: Default::default(),
        };
        let opts = TraceOptions {
            seeds: p.seeds.clone(),
            cancel: Some(cancel),
            ..TraceOptions::default()
        };
        let part = trace(&p.system, &tri, &oracle, &opts).unwrap();
        assert_eq!(part.stats.stopped, Some(StopReason::Interrupted), "{name}");
        assert_eq!(
            oracle.decided_after.into_inner(),
            0,
            "{name}: decided after the stop"
        );
        assert!(
            !part.is_empty() && part.len() < full.len(),
            "{name}: {} of {}",
            part.len(),
            full.len()
        );
        assert!(
            (0..part.len()).all(|i| part.key(i) == full.key(i)),
            "{name}: not a prefix"
        );
    }
}

/// Two samples are the same: keys in the same order, the same point bits, the same rim and
/// the same counters.
fn assert_same_sample(a: &Sample, b: &Sample, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: sizes");
    assert!(
        (0..a.len()).all(|i| a.key(i) == b.key(i)),
        "{what}: the keys differ"
    );
    let bits = |s: &Sample| -> Vec<u64> { s.points().iter().map(|x| x.to_bits()).collect() };
    assert!(bits(a) == bits(b), "{what}: the points differ");
    assert_eq!(a.rim_len(), b.rim_len(), "{what}: rims");
    assert!(
        (0..a.rim_len()).all(|i| a.rim_key(i) == b.rim_key(i) && a.rim_point(i) == b.rim_point(i)),
        "{what}: the rims differ"
    );
    let counters = |s: &Sample| {
        let t = &s.stats;
        [
            t.levels,
            t.widest_level,
            t.oracle_calls,
            t.pivot_fallbacks,
            t.exact_decisions,
            t.degenerate,
            t.non_finite,
            t.vertices,
            t.components as u64,
            t.seed_points,
        ]
    };
    assert_eq!(counters(a), counters(b), "{what}: counters");
}

#[test]
fn levels_decided_in_slices_trace_exactly_as_one_batch() {
    let mut problems: Vec<(Problem, Option<Vec<[f64; 2]>>)> = cases()
        .into_iter()
        .map(|(name, params, bbox, edges, _)| (problem(name, &params, edges[1]), Some(bbox)))
        .collect();
    let cosine = problem("complex-cosine", &[], 0.25);
    let bbox = cosine.bbox.clone();
    problems.push((cosine, bbox));
    problems.push((problem("torus", &[], 0.05), None));
    let mut sliced_levels = 0;
    for (p, bbox) in &problems {
        let tri = p.triangulation.build(p.dim()).unwrap();
        let opts = TraceOptions {
            seeds: p.seeds.clone(),
            bbox: bbox.clone(),
            ..TraceOptions::default()
        };
        let whole = trace(&p.system, &tri, &CpuOracle::new(&p.system), &opts).unwrap();
        let widest = whole.stats.widest_level as usize;
        for slice in [1, 7, widest / 3 + 1] {
            let oracle = Probe {
                inner: CpuOracle::new(&p.system),
                cancel: None,
                slice: Some(slice),
            };
            let sliced = trace(&p.system, &tri, &oracle, &opts).unwrap();
            let what = format!("{} in R^{}, slices of {slice}", p.name, p.dim());
            assert_same_sample(&whole, &sliced, &what);
            sliced_levels += (widest > slice) as usize;
        }
    }
    assert!(
        sliced_levels > 20,
        "only {sliced_levels} runs had a level in slices"
    );
}

/// A pole or a jump of f makes the PL approximation change sign without a zero; the sample
/// reports such crossings, and none on the smooth tracing cases.
#[test]
fn poles_and_jumps_are_reported_and_smooth_functions_are_not() {
    for (name, params, bbox, edges, _) in cases() {
        for edge in edges {
            let p = problem(name, &params, edge);
            let s = run(&p, Some(bbox.clone()), false);
            let n = s.suspect_crossings(&p.system);
            assert_eq!(n, 0, "{name} {params:?} edge {edge}: {n} of {}", s.len());
        }
    }
    let jumps: [(usize, &str); 3] = [
        // No zero at all: a pole along x = 0.
        (2, "1/x"),
        // No zero in the box: a jump along x = 0.1.
        (2, "(x - 0.1) / abs(x - 0.1) + 0.5 * y"),
        // The unit sphere, and a pole along x = 0.3.
        (3, "(x^2 + y^2 + z^2 - 1) / (x - 0.3)"),
    ];
    for (d, eq) in jumps {
        let sys = EquationSystem::parse_simple(d, &[eq]).unwrap();
        let tri = Triangulation::coxeter(d)
            .edge(0.05)
            .offset_seed(1)
            .rotation_seed(1)
            .build()
            .unwrap();
        let opts = TraceOptions {
            bbox: Some(cube(d, 1.0)),
            ..TraceOptions::default()
        };
        let s = exhaustive(&sys, &tri, &CpuOracle::new(&sys), &opts).unwrap();
        let n = s.suspect_crossings(&sys);
        assert!(!s.is_empty() && n > 0, "{eq}: {n} of {}", s.len());
    }
}

#[test]
fn closures_trace_like_equations() {
    let p = problem("torus", &[], 0.1);
    let f = isomesh::expr::ClosureFunction::new(3, 1, |x, out| {
        out[0] = (x[0].hypot(x[1]) - 1.0).powi(2) + x[2] * x[2] - 0.16;
    })
    .unwrap();
    let tri = p.triangulation.build(3).unwrap();
    let opts = TraceOptions {
        seeds: p.seeds.clone(),
        ..TraceOptions::default()
    };
    let a = trace(&f, &tri, &CpuOracle::new(&f), &opts).unwrap();
    let b = trace(&p.system, &tri, &CpuOracle::new(&p.system), &opts).unwrap();
    // Different rounding in f may flip a rare near-tie; the meshes agree almost everywhere.
    let ka: HashSet<&[u64]> = a.sorted_keys().into_iter().collect();
    let common = b.sorted_keys().iter().filter(|k| ka.contains(*k)).count();
    assert!(common as f64 >= 0.999 * a.len().max(b.len()) as f64);
    assert_door_in_door_out(&a, "closure torus");
}

/// The scan's candidates, by brute force from the definition: every chain of corners of
/// every scanned cube where each component of f has a value <= 0 and one >= 0 (NaN values
/// count as neither), in order of base vertex, then chain.
fn brute_candidates(grid: &ScanGrid) -> Candidates {
    let (d, k) = (grid.dim(), grid.codim());
    let mut index = HashMap::new();
    let mut v = vec![0i32; d];
    for i in 0..grid.len() {
        grid.coords(i, &mut v);
        index.insert(v.clone(), i as u32);
    }
    let mut out = Candidates::default();
    for cube in (0..grid.len()).filter(|&i| grid.codes()[i] & BASE != 0) {
        let mut base = vec![0i32; d];
        grid.coords(cube, &mut base);
        let corner: Option<Vec<u32>> = (0..1usize << d)
            .map(|s| {
                let c: Vec<i32> = (0..d).map(|j| base[j] + (s >> j & 1) as i32).collect();
                index.get(&c).copied()
            })
            .collect();
        let Some(corner) = corner else { continue };
        let mut chains = vec![vec![0usize]];
        for _ in 0..k {
            chains = chains
                .into_iter()
                .flat_map(|c| {
                    let last = *c.last().unwrap();
                    (last + 1..1 << d)
                        .filter(move |&t| t & last == last)
                        .map(move |t| [c.clone(), vec![t]].concat())
                })
                .collect();
        }
        chains.sort();
        for chain in chains {
            let admits = (0..k).all(|c| {
                let vals = || {
                    chain
                        .iter()
                        .map(|&s| grid.values()[corner[s] as usize * k + c])
                };
                vals().any(|x| x <= 0.0) && vals().any(|x| x >= 0.0)
            });
            if admits {
                out.rows.extend(chain.iter().map(|&s| corner[s]));
                out.chains.extend(chain[1..].iter().map(|&s| s as u32));
            }
        }
    }
    out
}

/// Scan grids for the candidate tests: exact zeros at lattice vertices, NaN regions, and
/// k = 1, 2, 3.
fn scan_grids() -> Vec<(String, ScanGrid)> {
    let grid = |f: &dyn ImplicitFunction, tri: &Triangulation, half: f64| {
        let opts = TraceOptions {
            bbox: Some(cube(tri.dim(), half)),
            ..TraceOptions::default()
        };
        scan_grid(f, tri, &CpuOracle::new(f), &opts).unwrap()
    };
    let eighth = Triangulation::custom(vec![
        vec![0.125, 0.0, 0.0],
        vec![0.0, 0.125, 0.0],
        vec![0.0, 0.0, 0.125],
    ])
    .build()
    .unwrap();
    let sphere = EquationSystem::parse_simple(3, &["x^2 + y^2 + z^2 - 1"]).unwrap();
    let holed = isomesh::expr::ClosureFunction::new(3, 2, |x, o| {
        o[0] = x[0];
        o[1] = if x[1] > 0.5 {
            f64::NAN
        } else {
            x[1] * x[1] + x[2] - 0.25
        };
    })
    .unwrap();
    let mut out = vec![
        (
            "sphere, zeros at vertices".into(),
            grid(&sphere, &eighth, 1.3),
        ),
        ("NaN for y > 0.5, k = 2".into(), grid(&holed, &eighth, 1.0)),
    ];
    for (name, params, edge, half) in [
        ("flat-torus", vec![], 0.3, 1.2),
        ("sphere", vec![("m", 2.0), ("d", 5.0)], 0.6, 1.2),
    ] {
        let p = problem(name, &params, edge);
        let tri = p.triangulation.build(p.dim()).unwrap();
        out.push((name.into(), grid(&p.system, &tri, half)));
    }
    out
}

#[test]
fn the_scan_generates_every_chain_whose_signs_admit_a_zero() {
    for (what, grid) in scan_grids() {
        let want = brute_candidates(&grid);
        assert!(want.count(grid.codim()) > 100, "{what}: too few candidates");
        let got = isomesh::trace::scan::candidates::candidates(&grid, 0..grid.len());
        assert!(
            got == want,
            "{what}: {} vs {}",
            got.rows.len(),
            want.rows.len()
        );
        // In pieces, as the scan's batches run.
        let mut pieces = Candidates::default();
        for start in (0..grid.len()).step_by(777) {
            let end = (start + 777).min(grid.len());
            pieces.append(&mut isomesh::trace::scan::candidates::candidates(
                &grid,
                start..end,
            ));
        }
        assert!(pieces == want, "{what}: batches differ");
    }
}

#[test]
fn the_scan_grid_holds_exactly_the_vertices_near_its_box() {
    // Box [-h, h]^d off centre by `shift`; the grid holds the vertices within two edges.
    let cases: Vec<(&str, Triangulation, f64, f64)> = vec![
        (
            "Coxeter d=2",
            Triangulation::coxeter(2).edge(0.3).build().unwrap(),
            1.0,
            0.0,
        ),
        (
            "Coxeter d=3, offset, rotated",
            Triangulation::coxeter(3)
                .edge(0.4)
                .offset_seed(3)
                .rotation_seed(5)
                .build()
                .unwrap(),
            0.9,
            0.17,
        ),
        (
            "Freudenthal d=4, offset",
            Triangulation::freudenthal(4)
                .edge(0.7)
                .offset_seed(1)
                .build()
                .unwrap(),
            0.6,
            -0.3,
        ),
        (
            "Coxeter d=5",
            Triangulation::coxeter(5).edge(0.8).build().unwrap(),
            0.5,
            0.1,
        ),
        (
            "Coxeter d=6, offset, rotated",
            Triangulation::coxeter(6)
                .edge(1.0)
                .offset_seed(2)
                .rotation_seed(3)
                .build()
                .unwrap(),
            0.3,
            0.05,
        ),
        (
            "sheared d=3",
            Triangulation::custom(vec![
                vec![0.2, 0.15, 0.0],
                vec![0.0, 0.2, -0.1],
                vec![0.05, 0.0, 0.25],
            ])
            .build()
            .unwrap(),
            0.8,
            0.05,
        ),
    ];
    for (what, tri, half, shift) in cases {
        let d = tri.dim();
        let probe = isomesh::expr::ClosureFunction::new(d, 1, |x, o| o[0] = x[0]).unwrap();
        let bbox: Vec<[f64; 2]> = (0..d).map(|_| [shift - half, shift + half]).collect();
        let opts = TraceOptions {
            bbox: Some(bbox.clone()),
            ..TraceOptions::default()
        };
        let grid = scan_grid(&probe, &tri, &CpuOracle::new(&probe), &opts).unwrap();
        let reach = 2.0 * tri.edge();
        let slack = 1e-7;
        let within = |x: &[f64], r: f64| {
            bbox.iter()
                .zip(x)
                .all(|([l, h], v)| *v >= l - r && *v <= h + r)
        };
        // Every held vertex is near the box, once.
        let (mut v, mut x) = (vec![0i32; d], vec![0.0; d]);
        let mut held = HashSet::new();
        for i in 0..grid.len() {
            grid.coords(i, &mut v);
            tri.vertex_coords(&v, &mut x);
            assert!(
                within(&x, reach + slack),
                "{what}: {v:?} is far from the box"
            );
            assert!(held.insert(v.clone()), "{what}: {v:?} held twice");
            assert_eq!(grid.values()[i], x[0], "{what}: f at {v:?}");
        }
        // Every lattice vertex near the box is held: all lattice points of the box around
        // the grown box's corners.
        let (mut lo, mut hi) = (vec![i64::MAX; d], vec![i64::MIN; d]);
        let mut u = vec![0.0; d];
        for corner in 0..1usize << d {
            let c: Vec<f64> = (0..d)
                .map(|j| {
                    bbox[j][corner >> j & 1] + if corner >> j & 1 == 1 { reach } else { -reach }
                })
                .collect();
            tri.point_to_lattice(&c, &mut u);
            for j in 0..d {
                lo[j] = lo[j].min(u[j].floor() as i64 - 1);
                hi[j] = hi[j].max(u[j].ceil() as i64 + 1);
            }
        }
        let mut near = 0;
        let mut v = lo.iter().map(|&l| l as i32).collect::<Vec<_>>();
        'all: loop {
            tri.vertex_coords(&v, &mut x);
            if within(&x, reach - slack) {
                assert!(
                    held.contains(&v),
                    "{what}: {v:?} is near the box but not held"
                );
                near += 1;
            }
            for j in 0..d {
                if (v[j] as i64) < hi[j] {
                    v[j] += 1;
                    continue 'all;
                }
                v[j] = lo[j] as i32;
            }
            break;
        }
        assert!(
            near > 100 && near <= grid.len(),
            "{what}: {near} near, {} held",
            grid.len()
        );
    }
}

/// An oracle whose device certifies every candidate crossed: the CPU's values, taken as
/// exact, contradict it.
struct LyingDevice<'f>(CpuOracle<'f>);

impl Oracle for LyingDevice<'_> {
    fn name(&self) -> String {
        "lying device".into()
    }
    fn values(&self) -> &dyn Evaluate {
        &self.0
    }
    fn decisions(&self) -> &dyn Decide {
        &self.0
    }
    fn scans(&self) -> &dyn Scan {
        self
    }
}

impl Scan for LyingDevice<'_> {
    fn device_values(&self) -> Option<&dyn DeviceValues> {
        Some(self)
    }
}

impl DeviceValues for LyingDevice<'_> {
    fn eval_certified(&self, t: &Triangulation, lattice: &[i32], out: &mut [f64]) -> Result<()> {
        let mut v = vec![0.0; out.len() / 2];
        self.0.eval_vertices(t, lattice, &mut v)?;
        for (pair, x) in out.chunks_exact_mut(2).zip(v) {
            pair.copy_from_slice(&[x, 0.0]);
        }
        Ok(())
    }
    fn decide_certified(
        &self,
        _: &[f64],
        _: &[f64],
        _: &[u32],
        verdicts: &mut [u32],
    ) -> Result<()> {
        verdicts.fill(isomesh::cpu::certificate::CROSSED);
        Ok(())
    }
}

/// A device verdict that the CPU's exact decision contradicts stops the scan with the typed
/// error that says a device bound does not hold, not with a mesh built on it.
#[test]
fn a_device_verdict_the_cpu_contradicts_is_a_device_bound_error() {
    // Codimension 2: a triangle whose vertex signs admit a zero need not be crossed.
    let p = preset("flat-torus", &[]).unwrap();
    let tri = Triangulation::coxeter(4).edge(0.4).build().unwrap();
    let opts = TraceOptions {
        bbox: Some(vec![[-1.2, 1.2]; 4]),
        ..TraceOptions::default()
    };
    let lying = LyingDevice(CpuOracle::new(&p.system));
    match exhaustive(&p.system, &tri, &lying, &opts) {
        Err(Error::DeviceBound(m)) => assert!(m.contains("does not hold"), "{m}"),
        other => panic!("not a device-bound error: {:?}", other.map(|s| s.len())),
    }
    // The same scan with the CPU's own verdicts works.
    assert!(exhaustive(&p.system, &tri, &CpuOracle::new(&p.system), &opts).is_ok());
}

#[test]
fn the_points_the_crossing_checks_keep_are_the_points() {
    // The checks keep S's points; later copies are the points computed afresh, bit for bit.
    for (name, params, edge) in [
        ("sphere", vec![], 0.1),
        ("flat-torus", vec![], 0.3),
        ("sphere", vec![("d", 8.0)], 0.8),
    ] {
        let p = problem(name, &params, edge);
        let s = run(&p, None, false);
        let fresh = s.points();
        let (d, bytes) = (s.ambient_dim(), s.memory_bytes());
        assert!(s.len() > 100, "{name}");
        s.check_crossings(&p.system);
        assert_eq!(s.memory_bytes(), bytes + s.len() * d * 8, "{name}: counted");
        let bits = |v: &[f64]| -> Vec<u64> { v.iter().map(|x| x.to_bits()).collect() };
        assert!(
            bits(&s.points()) == bits(&fresh),
            "{name}: the kept points differ"
        );
        assert!(
            (0..s.len()).all(|i| bits(&s.point(i)) == bits(&fresh[i * d..(i + 1) * d])),
            "{name}"
        );
    }
}
