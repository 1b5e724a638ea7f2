//! The GPU oracle against the CPU: the solve, vertex and scan shaders against their CPU twins,
//! a stress test of badly conditioned simplices, and whole traces and exhaustive scans in
//! which every verdict, lambda and candidate the device returned is checked against the CPU.
//! Runs on any adapter wgpu finds (lavapipe in CI); skipped with a SKIPPED line when there is
//! none, unless ISOMESH_REQUIRE_GPU=1.

use std::ops::Range;
use std::sync::Mutex;

use isomesh::cpu::solve::{exact_lambda_signs, Status};
use isomesh::expr::{preset, Problem, Spec};
use isomesh::gpu::{Gpu, GpuOptions, GpuOracle, Precision};
use isomesh::trace::scan::candidates::candidates;
use isomesh::trace::scan::candidates::Candidates;
use isomesh::trace::scan::tiles::TilePlan;
use isomesh::trace::{
    exhaustive, scan_grid, trace, CpuOracle, Decide, DeviceValues, Evaluate, GrowingValues, Oracle,
    Sample, Scan, ScanGrid, TraceOptions,
};
use isomesh::triangulation::Triangulation;
use rand::{Rng, SeedableRng};

/// Whether ISOMESH_REQUIRE_GPU asks for the GPU tests to run (1, true or yes).
fn gpu_required() -> bool {
    std::env::var("ISOMESH_REQUIRE_GPU")
        .is_ok_and(|v| matches!(v.trim().to_ascii_lowercase().as_str(), "1" | "true" | "yes"))
}

/// An adapter, or None when there is none: then the test is skipped, with a SKIPPED line
/// written past the test harness's capture (so that a plain `cargo test` shows it), unless
/// ISOMESH_REQUIRE_GPU requires a GPU (CI, where lavapipe is installed).
fn gpu(test: &str) -> Option<Gpu> {
    match Gpu::open(true) {
        Ok(g) => Some(g),
        Err(e) if gpu_required() => panic!("ISOMESH_REQUIRE_GPU is set but {e}"),
        Err(e) => {
            use std::io::Write;
            let _ = writeln!(
                std::io::stderr(),
                "SKIPPED {test}: {e} (set ISOMESH_REQUIRE_GPU=1 to fail instead)"
            );
            None
        }
    }
}

/// The adapter again, for a test that found one.
fn reopen() -> Gpu {
    Gpu::open(true).expect("the adapter opened a moment ago")
}

fn precisions(g: &Gpu) -> Vec<Option<Precision>> {
    if g.adapter.shader_f64 {
        vec![Some(Precision::F64), Some(Precision::F32)]
    } else {
        vec![Some(Precision::F32)]
    }
}

/// A preset's name, parameters and box half-width.
type Scaled = (&'static str, Vec<(&'static str, f64)>, f64);

fn problem(name: &str, params: &[(&str, f64)]) -> Problem {
    let params: Vec<(String, f64)> = params.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    preset(name, &params).unwrap()
}

fn run(p: &Problem, oracle: &dyn Oracle) -> Sample {
    let tri = p.triangulation.build(p.dim()).unwrap();
    let opts = TraceOptions {
        seeds: p.seeds.clone(),
        bbox: p.bbox.clone(),
        ..TraceOptions::default()
    };
    trace(&p.system, &tri, oracle, &opts).unwrap()
}

/// Entries whose bits differ, and the largest difference, between two lambda arrays over the
/// rows where `crossed(i)`.
fn lambda_gap(a: &[f64], b: &[f64], n: usize, crossed: impl Fn(usize) -> bool) -> (usize, f64) {
    let (mut bits, mut worst) = (0, 0.0f64);
    for i in (0..a.len() / n).filter(|&i| crossed(i)) {
        for j in i * n..(i + 1) * n {
            bits += (a[j].to_bits() != b[j].to_bits()) as usize;
            worst = worst.max((a[j] - b[j]).abs());
        }
    }
    (bits, worst)
}

/// What a [`Shadow`] found while the device served a trace or scan.
#[derive(Debug, Default)]
struct ShadowLog {
    decided: usize,
    /// Of those, decided from vertex ids into values the device keeps.
    growing: usize,
    crossed: usize,
    verdicts_differ: usize,
    lambda_bits_differ: usize,
    lambda_worst: f64,
    values_differ: usize,
    scans: usize,
    scans_differ: usize,
}

/// An oracle that passes everything the device returns on, after checking it against the
/// CPU oracle on the same input: each batch's verdicts and lambda, each vertex value, each
/// scan's candidates.
struct Shadow<'a> {
    dev: &'a dyn Oracle,
    /// Vertices per simplex (k + 1).
    n: usize,
    cpu: CpuOracle<'a>,
    log: Mutex<ShadowLog>,
}

impl<'a> Shadow<'a> {
    fn new(dev: &'a GpuOracle, f: &'a dyn isomesh::expr::ImplicitFunction) -> Self {
        Shadow {
            dev,
            n: f.codim() + 1,
            cpu: CpuOracle::new(f),
            log: Mutex::new(ShadowLog::default()),
        }
    }

    /// The log, with the lambda check that holds on any conforming device: every lambda
    /// the oracle returns is the CPU's, bit for bit (crossings are decided on the CPU).
    fn check(&self, what: &str) -> ShadowLog {
        let log = std::mem::take(&mut *self.log.lock().unwrap());
        assert!(log.decided > 0 && log.crossed > 0, "{what}: {log:?}");
        assert_eq!(log.verdicts_differ, 0, "{what}: {log:?}");
        assert_eq!(log.values_differ, 0, "{what}: {log:?}");
        assert_eq!(log.scans_differ, 0, "{what}: {log:?}");
        assert_eq!(log.lambda_bits_differ, 0, "{what}: {log:?}");
        log
    }
}

impl Oracle for Shadow<'_> {
    fn name(&self) -> String {
        self.dev.name()
    }

    fn values(&self) -> &dyn Evaluate {
        self
    }

    fn decisions(&self) -> &dyn Decide {
        self
    }

    fn scans(&self) -> &dyn Scan {
        self
    }
}

impl Evaluate for Shadow<'_> {
    fn eval_vertices(
        &self,
        tri: &Triangulation,
        lattice: &[i32],
        values: &mut [f64],
    ) -> isomesh::Result<()> {
        self.dev.values().eval_vertices(tri, lattice, values)?;
        let mut want = vec![0.0; values.len()];
        self.cpu.eval_vertices(tri, lattice, &mut want)?;
        let differ = values
            .iter()
            .zip(&want)
            .filter(|(a, b)| a.to_bits() != b.to_bits())
            .count();
        self.log.lock().unwrap().values_differ += differ;
        Ok(())
    }
}

impl Decide for Shadow<'_> {
    fn decide(
        &self,
        values: &[f64],
        simplices: &[u32],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> isomesh::Result<isomesh::trace::Decisions> {
        let exact = self
            .dev
            .decisions()
            .decide(values, simplices, status, lambda)?;
        self.compare(values, simplices, status, lambda)?;
        Ok(exact)
    }

    /// A trace's levels: decided from vertex ids on the device, checked as above.
    fn decide_growing(
        &self,
        log: GrowingValues,
        values: &[f64],
        simplices: &[u32],
        status: &mut [Status],
        lambda: &mut [f64],
    ) -> isomesh::Result<isomesh::trace::Decisions> {
        let exact = self
            .dev
            .decisions()
            .decide_growing(log, values, simplices, status, lambda)?;
        self.log.lock().unwrap().growing += status.len();
        self.compare(values, simplices, status, lambda)?;
        Ok(exact)
    }

    fn level_slice(&self) -> Option<usize> {
        self.dev.decisions().level_slice()
    }
}

impl Shadow<'_> {
    /// The device's decisions against the CPU's, into the log.
    fn compare(
        &self,
        values: &[f64],
        simplices: &[u32],
        status: &[Status],
        lambda: &[f64],
    ) -> isomesh::Result<()> {
        let (m, n) = (status.len(), self.n);
        let (mut st, mut lam) = (vec![Status::Outside; m], vec![0.0; lambda.len()]);
        self.cpu.decide(values, simplices, &mut st, &mut lam)?;
        let (bits, worst) = lambda_gap(lambda, &lam, n, |i| st[i].crossed());
        let mut log = self.log.lock().unwrap();
        log.decided += m;
        log.crossed += st.iter().filter(|s| s.crossed()).count();
        log.verdicts_differ += status.iter().zip(&st).filter(|(a, b)| a != b).count();
        log.lambda_bits_differ += bits;
        log.lambda_worst = log.lambda_worst.max(worst);
        Ok(())
    }
}

/// The device's candidates, checked; the CPU's values (no device values).
impl Scan for Shadow<'_> {
    fn candidates(&self, grid: &ScanGrid, cubes: Range<usize>) -> isomesh::Result<Candidates> {
        let got = self.dev.scans().candidates(grid, cubes.clone())?;
        let want = candidates(grid, cubes);
        let mut log = self.log.lock().unwrap();
        log.scans += 1;
        log.scans_differ += (got != want) as usize;
        Ok(got)
    }
}

/// Random vertex values of n k-simplices, a third of them nearly degenerate (two vertices
/// almost equal) and a third with tiny components, as row indices into the values.
fn hard_batch(k: usize, count: usize, seed: u64) -> (Vec<f64>, Vec<u32>) {
    let n = k + 1;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut values = Vec::with_capacity(count * n * k);
    for s in 0..count {
        let base: Vec<f64> = (0..k).map(|_| rng.random_range(-1.0..1.0)).collect();
        for j in 0..n {
            for &b in &base {
                let v: f64 = match s % 3 {
                    0 => rng.random_range(-1.0..1.0),
                    1 if j == n - 1 => b + rng.random_range(-1e-12..1e-12),
                    1 if j == 0 => b,
                    _ => rng.random_range(-1.0..1.0) * 10f64.powi(rng.random_range(-12..2)),
                };
                values.push(v);
            }
        }
    }
    let idx = (0..(count * n) as u32).collect();
    (values, idx)
}

/// Simplices whose exact lambda has one entry of +-t, t in 1e-10..1e-6 (the rest positive):
/// F_j = P_j - sum_i lambda_i P_i for random P. Rounding the values to f32 moves lambda by
/// about 1e-7, so an f32 verdict that ignored it would be wrong on some of them.
fn near_facet_batch(k: usize, count: usize, seed: u64) -> Vec<f64> {
    let n = k + 1;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut values = Vec::with_capacity(count * n * k);
    for _ in 0..count {
        let p: Vec<f64> = (0..n * k).map(|_| rng.random_range(-1.0..1.0)).collect();
        // lambda sums to 1 with lambda_z = +-t.
        let (z, t) = (
            rng.random_range(0..n),
            10f64.powf(rng.random_range(-10.0..-6.0)),
        );
        let t = if rng.random_bool(0.5) { t } else { -t };
        let mut lambda: Vec<f64> = (0..n).map(|_| rng.random_range(0.1..1.0)).collect();
        lambda[z] = 0.0;
        let rest: f64 = lambda.iter().sum();
        lambda.iter_mut().for_each(|l| *l *= (1.0 - t) / rest);
        lambda[z] = t;
        for j in 0..n {
            for c in 0..k {
                let centre: f64 = (0..n).map(|i| lambda[i] * p[i * k + c]).sum();
                values.push(p[j * k + c] - centre);
            }
        }
    }
    values
}

/// How many of `verdicts` (per simplex of `values`, k + 1 rows of k each) are not the exact
/// verdict: crossed needs every exact sign of lambda positive, outside one negative.
fn wrong_verdicts(k: usize, values: &[f64], verdicts: &[Option<Status>]) -> usize {
    let per = (k + 1) * k;
    verdicts
        .iter()
        .enumerate()
        .filter(|(i, v)| {
            let Some(v) = v else { return false };
            let signs = exact_lambda_signs(&values[i * per..(i + 1) * per], k);
            let ok = match v {
                Status::Crossed => signs.as_ref().is_some_and(|s| s.iter().all(|&x| x == 1)),
                _ => signs.as_ref().is_some_and(|s| s.contains(&-1)),
            };
            !ok
        })
        .count()
}

#[test]
fn gpu_decisions_equal_cpu_decisions_on_hard_simplices() {
    let Some(g) = gpu("gpu_decisions_equal_cpu_decisions_on_hard_simplices") else {
        return;
    };
    let has_f64 = g.adapter.shader_f64;
    drop(g);
    let f = isomesh::expr::ClosureFunction::new(4, 3, |_, o| o.fill(0.0)).unwrap();
    for precision in [Precision::F32, Precision::F64] {
        if precision == Precision::F64 && !has_f64 {
            continue;
        }
        // The adapter, then its solve emulated as any conforming device may compute it.
        for emulate in [None, Some(5)] {
            let oracle = GpuOracle::new(reopen(), &f, Some(precision)).unwrap();
            oracle.emulate_device(emulate);
            let precision = (precision, emulate);
            let cpu = CpuOracle::new(&f);
            let count = if emulate.is_some() {
                200_000
            } else {
                1_000_000
            };
            let (values, idx) = hard_batch(3, count, 7);
            let (mut s_gpu, mut s_cpu) =
                (vec![Status::Outside; count], vec![Status::Outside; count]);
            let (mut l_gpu, mut l_cpu) = (vec![0.0; count * 4], vec![0.0; count * 4]);
            oracle
                .decide(&values, &idx, &mut s_gpu, &mut l_gpu)
                .unwrap();
            cpu.decide(&values, &idx, &mut s_cpu, &mut l_cpu).unwrap();
            let mismatches = s_gpu.iter().zip(&s_cpu).filter(|(a, b)| a != b).count();
            assert_eq!(mismatches, 0, "{precision:?}: decisions differ");
            let crossed = s_cpu.iter().filter(|s| s.crossed()).count();
            assert!(crossed > 1000, "the batch should hold crossings");
            // Every crossing is decided on the CPU: its lambda is the CPU's, on any device.
            let (bits, worst) = lambda_gap(&l_gpu, &l_cpu, 4, |i| s_cpu[i].crossed());
            assert_eq!(bits, 0, "{precision:?}: lambda differs by up to {worst:e}");
            let st = oracle.stats();
            assert_eq!(st.contradicted, 0, "{precision:?}: {st:?}");
            assert_eq!(st.solved as usize, s_cpu.len() - count_filtered(&values, 3));
            eprintln!(
                "{precision:?}: {} solved, {} rechecked on the CPU, lambda within {worst:e}",
                st.solved, st.rechecked
            );
        }
    }
}

/// Simplices the host filters (a component of one strict sign) before the shader.
fn count_filtered(values: &[f64], k: usize) -> usize {
    let n = k + 1;
    values
        .chunks_exact(n * k)
        .filter(|v| {
            (0..k).any(|c| (0..n).all(|j| v[j * k + c] > 0.0) || (0..n).all(|j| v[j * k + c] < 0.0))
        })
        .count()
}

#[test]
fn gpu_traces_take_the_cpu_verdicts_lambda_and_rim() {
    let Some(g) = gpu("gpu_traces_take_the_cpu_verdicts_lambda_and_rim") else {
        return;
    };
    let modes = precisions(&g);
    drop(g);
    let cases: Vec<(&str, Vec<(&str, f64)>)> = vec![
        ("circle", vec![("edge", 0.1)]),
        ("circle", vec![("edge", 0.03)]),
        ("sphere", vec![("edge", 0.2)]),
        ("sphere", vec![("edge", 0.1)]),
        ("sphere", vec![("d", 5.0), ("edge", 0.3)]),
        ("torus", vec![("edge", 0.1)]),
        ("torus", vec![("edge", 0.07)]),
        ("chair", vec![("edge", 0.15)]),
        ("chair", vec![("edge", 0.1)]),
        ("flat-torus", vec![("edge", 0.3)]),
        ("flat-torus", vec![("edge", 0.2)]),
        (
            "3-torus",
            vec![("a", 0.5), ("b", 0.5), ("c", 0.5), ("edge", 0.7)],
        ),
        ("complex-cosine", vec![("edge", 0.25)]),
        ("complex-cosine", vec![("edge", 0.2)]),
        ("bagel-klein", vec![("edge", 0.4)]),
        ("cut-flat-torus", vec![("edge", 0.3)]),
    ];
    for precision in modes {
        for (i, (name, params)) in cases.iter().enumerate() {
            let p = problem(name, params);
            let cpu = run(&p, &CpuOracle::new(&p.system));
            // The adapter, and for every other case also its solve emulated as any
            // conforming device may compute it.
            for emulate in [None]
                .into_iter()
                .chain((i % 2 == 0).then_some(Some(i as u64)))
            {
                // Every other case decides its levels in slices of 7 frontier simplices, naming
                // the next slice while the device decides one; the others in one batch (the
                // default).
                let slice = if i % 2 == 1 { 7 } else { 0 };
                let options = GpuOptions {
                    precision,
                    level_slice: slice,
                    device_values: false,
                    ..GpuOptions::default()
                };
                let oracle = GpuOracle::with_options(reopen(), &p.system, options).unwrap();
                oracle.emulate_device(emulate);
                let shadow = Shadow::new(&oracle, &p.system);
                let gpu = run(&p, &shadow);
                let what = format!(
                    "{name} {params:?} {precision:?}, slices of {slice}, emulated {emulate:?}"
                );
                // What the device returned: every verdict and lambda of the trace.
                let log = shadow.check(&what);
                assert_eq!(
                    log.growing, log.decided,
                    "{what}: levels not decided from ids"
                );
                assert_eq!(cpu.stats.oracle_calls, gpu.stats.oracle_calls, "{what}");
                assert_eq!(cpu.sorted_keys(), gpu.sorted_keys(), "{what}: S differs");
                // The rim it decided: the same crossings outside the box, at the CPU's points.
                assert_eq!(cpu.rim_len(), gpu.rim_len(), "{what}");
                for r in 0..cpu.rim_len() {
                    assert_eq!(cpu.rim_key(r), gpu.rim_key(r), "{what}: rim {r}");
                    let (a, b) = (cpu.rim_point(r), gpu.rim_point(r));
                    assert!(
                        a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()),
                        "{what}: rim point {r}"
                    );
                }
                let st = oracle.stats();
                assert!(st.solved > 0, "{what}: the GPU did nothing");
                assert_eq!(st.contradicted, 0, "{what}: {st:?}");
                if emulate.is_none() {
                    // Only the verdicts come back from the device, 4 bytes each: every
                    // lambda is the CPU's.
                    assert_eq!(st.readback_bytes, 4 * st.solved, "{what}: {st:?}");
                }
                eprintln!("{what}: {log:?}");
            }
        }
    }
}

#[test]
fn the_solve_shader_matches_its_cpu_twin() {
    let Some(g) = gpu("the_solve_shader_matches_its_cpu_twin") else {
        return;
    };
    let modes = precisions(&g);
    let k = 3;
    let n = k + 1;
    let count = 200_000;
    let (values, idx) = hard_batch(k, count, 11);
    // The CPU fast path on the same inputs.
    let mut decider = isomesh::cpu::solve::Decider::new(k);
    let mut cpu_lambda = vec![0.0; count * n];
    let cpu: Vec<Option<Status>> = (0..count)
        .map(|i| {
            decider.fast_path(
                &values[i * n * k..(i + 1) * n * k],
                &mut cpu_lambda[i * n..(i + 1) * n],
            )
        })
        .collect();
    let f = isomesh::expr::ClosureFunction::new(4, 3, |_, o| o.fill(0.0)).unwrap();
    // The adapter, then its solve emulated as any conforming device may compute it.
    let runs = modes.iter().flat_map(|&p| [(p, None), (p, Some(17))]);
    for (precision, emulate) in runs {
        let oracle = GpuOracle::new(reopen(), &f, precision).unwrap();
        oracle.emulate_device(emulate);
        let precision = precision.map(|p| (p, emulate));
        let (gpu, lambda) = oracle.solve_stage(&values, &idx).unwrap();
        let mut differ = 0;
        for i in 0..count {
            match (cpu[i], gpu[i]) {
                (Some(a), Some(b)) => {
                    assert_eq!(a, b, "{precision:?}: simplex {i} decided both ways")
                }
                (a, b) if a != b => differ += 1,
                _ => {}
            }
        }
        // Both sides prove their verdicts (the device with the margins of any conforming
        // device, wider than the CPU's), so they never disagree; one may be certain where
        // the other is not, and the device's lambda is its own (it reaches no output).
        let both_crossed = |i: usize| cpu[i] == Some(Status::Crossed) && gpu[i] == cpu[i];
        let (bits, worst) = lambda_gap(&lambda, &cpu_lambda, n, both_crossed);
        let decided = gpu.iter().filter(|v| v.is_some()).count();
        eprintln!(
            "{precision:?}: {decided} of {count} decided, {differ} certain on one side only, \
             lambda: {bits} entries differ, by up to {worst:e}"
        );
        assert!(decided * 2 > count, "{precision:?}: {decided} decided");
        // Every verdict is a proof about the host's f64 values, in f32 as in f64: it is the
        // exact one (strict signs of lambda), here and where rounding to f32 alone moves
        // lambda across a facet.
        let wrong = wrong_verdicts(k, &values, &gpu);
        assert_eq!(
            wrong, 0,
            "{precision:?}: {wrong} device verdicts not the exact ones"
        );
        let near = near_facet_batch(k, 20_000, 13);
        let (verdicts, _) = oracle.solve_stage(&near, &idx[..20_000 * n]).unwrap();
        let wrong = wrong_verdicts(k, &near, &verdicts);
        let decided = verdicts.iter().filter(|v| v.is_some()).count();
        eprintln!("{precision:?}: near facets, {decided} decided, {wrong} wrong");
        assert_eq!(
            wrong, 0,
            "{precision:?}: {wrong} verdicts near facets not the exact ones"
        );
        // Not everything left to the CPU: 5% decided on the adapter, 2.5% on the emulated
        // device, whose rounding is the worst the specifications allow.
        let least = if emulate.is_some() { 500 } else { 1_000 };
        assert!(
            decided > least,
            "{precision:?}: near facets, only {decided} decided"
        );
        if precision.is_some_and(|p| p.0 == Precision::F32) {
            // The f32 twin: the certificate for every matrix within the rounding to f32,
            // with the shader's bounds 2u |l| + 2 MIN_NORMAL.
            use isomesh::cpu::certificate::{CertifiedSolver, CROSSED, OUTSIDE};
            let mut solver = CertifiedSolver::<f32>::new(k);
            let (mut l, mut e) = (vec![1.0f32; n * n], vec![0.0f32; n * n]);
            let mut x = vec![0.0f32; n];
            let mut rows = vec![0.0; k * n];
            let (mut opposite, mut one_side) = (0, 0);
            for i in 0..count {
                let v = &values[i * n * k..(i + 1) * n * k];
                isomesh::cpu::solve::scaled_rows(k, |j, c| v[j * k + c], &mut rows);
                for (t, &r) in rows.iter().enumerate() {
                    l[n + t] = r as f32;
                    e[n + t] = f32::EPSILON * l[n + t].abs() + 2.0 * f32::MIN_POSITIVE;
                }
                let twin = match solver.solve(&l, &e, &mut x) {
                    CROSSED => Some(Status::Crossed),
                    OUTSIDE => Some(Status::Outside),
                    _ => None,
                };
                match (twin, gpu[i]) {
                    (Some(a), Some(b)) if a != b => opposite += 1,
                    (a, b) if a != b => one_side += 1,
                    _ => {}
                }
            }
            eprintln!("f32 twin: {one_side} certain on one side only");
            assert_eq!(
                opposite, 0,
                "f32: {opposite} verdicts opposite to the twin's"
            );
            // Any device's rounding moves certainty only at the margins: a rare event.
            assert!(
                one_side <= count / 100,
                "f32: {one_side} differ from the twin"
            );
        }
    }
}

/// Whether a component keeps one strict sign at every vertex of simplex `s` of `values`
/// (rows of k, k + 1 per simplex): the cheap filter's outside.
fn one_sign(values: &[f64], k: usize, s: usize) -> bool {
    let v = &values[s * (k + 1) * k..(s + 1) * (k + 1) * k];
    (0..k).any(|c| (0..=k).all(|j| v[j * k + c] > 0.0) || (0..=k).all(|j| v[j * k + c] < 0.0))
}

#[test]
fn the_solve_ids_shader_matches_its_cpu_twin() {
    let Some(g) = gpu("the_solve_ids_shader_matches_its_cpu_twin") else {
        return;
    };
    let modes = precisions(&g);
    let (k, n, count) = (3, 4, 100_000);
    let (mut values, idx) = hard_batch(k, count, 23);
    // Every seventh simplex has a vertex value the device cannot hold in f32 or f64 (not
    // finite, below 2^-126, above 2^126) or an exact zero, which it holds.
    let odd = [
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        1e-40,
        -1e-310,
        1e39,
        -1e200,
        0.0,
    ];
    let mut unheld = vec![false; count];
    for s in (0..count).step_by(7) {
        let v = odd[(s / 7) % odd.len()];
        values[(s * n + s % n) * k] = v;
        unheld[s] = v != 0.0;
    }
    let f = isomesh::expr::ClosureFunction::new(4, 3, |_, o| o.fill(0.0)).unwrap();
    // The adapter, then the shader emulated as any conforming device may compute it.
    let runs = modes.iter().flat_map(|&p| [(p, None), (p, Some(29))]);
    for (precision, emulate) in runs {
        let oracle = GpuOracle::new(reopen(), &f, precision).unwrap();
        oracle.emulate_device(emulate);
        let precision = precision.map(|p| (p, emulate));
        let got = oracle.solve_ids_stage(&values, &idx).unwrap();
        assert_eq!(got.len(), count);
        let taken = (0..count)
            .filter(|&s| unheld[s] && got[s].is_some())
            .count();
        assert_eq!(
            taken, 0,
            "{precision:?}: verdicts on values the device cannot hold"
        );
        // The sign filter runs on the device, on every simplex it holds.
        let missed = (0..count)
            .filter(|&s| !unheld[s] && one_sign(&values, k, s) && got[s] != Some(Status::Outside))
            .count();
        assert_eq!(missed, 0, "{precision:?}: simplices the filter let through");
        // Every verdict is the exact one, in f32 as in f64.
        let wrong = wrong_verdicts(k, &values, &got);
        assert_eq!(
            wrong, 0,
            "{precision:?}: {wrong} verdicts not the exact ones"
        );
        let solved = (0..count)
            .filter(|&s| !unheld[s] && !one_sign(&values, k, s))
            .filter(|&s| got[s].is_some())
            .count();
        let decided = got.iter().filter(|v| v.is_some()).count();
        eprintln!("{precision:?}: {decided} of {count} decided, {solved} of them by a solve");
        assert!(decided * 2 > count, "{precision:?}: {decided} decided");
        assert!(
            solved * 5 > count,
            "{precision:?}: {solved} decided by a solve"
        );
        let near = near_facet_batch(k, 20_000, 13);
        let verdicts = oracle.solve_ids_stage(&near, &idx[..20_000 * n]).unwrap();
        let wrong = wrong_verdicts(k, &near, &verdicts);
        let decided = verdicts.iter().filter(|v| v.is_some()).count();
        eprintln!("{precision:?}: near facets, {decided} decided, {wrong} wrong");
        assert_eq!(
            wrong, 0,
            "{precision:?}: {wrong} verdicts near facets not exact"
        );
        assert!(
            decided > 500,
            "{precision:?}: near facets, only {decided} decided"
        );
    }
}

#[test]
fn gpu_decisions_from_kept_values_send_each_vertex_once() {
    let Some(g) = gpu("gpu_decisions_from_kept_values_send_each_vertex_once") else {
        return;
    };
    let modes = precisions(&g);
    let (k, n, count) = (3, 4, 40_000);
    let half = count / 2;
    let (values, idx) = hard_batch(k, count, 31);
    let f = isomesh::expr::ClosureFunction::new(4, 3, |_, o| o.fill(0.0)).unwrap();
    let cpu = CpuOracle::new(&f);
    let (mut want, mut want_l) = (vec![Status::Outside; count], vec![0.0; count * n]);
    cpu.decide(&values, &idx, &mut want, &mut want_l).unwrap();
    for precision in modes {
        let oracle = GpuOracle::new(reopen(), &f, precision).unwrap();
        let rs = if oracle.precision() == Precision::F64 {
            8
        } else {
            4
        };
        let log = GrowingValues::new();
        let decide = |values: &[f64], m: usize| {
            let before = oracle.stats().upload_bytes;
            let (mut s, mut l) = (vec![Status::Outside; m], vec![0.0; m * n]);
            let how = oracle
                .decide_growing(log, values, &idx[..m * n], &mut s, &mut l)
                .unwrap();
            assert!(
                s == want[..m],
                "{precision:?}: statuses differ from the CPU's"
            );
            let (bits, worst) = lambda_gap(&l, &want_l[..m * n], n, |i| want[i].crossed());
            assert_eq!(bits, 0, "{precision:?}: lambda differs by up to {worst:e}");
            assert!(
                how.on_device > 0,
                "{precision:?}: nothing decided on the device"
            );
            oracle.stats().upload_bytes - before
        };
        // The first half's vertices, then all of them: only the new rows go up (values and
        // their held bits), with the ids and the shader's parameters.
        let rows = half * n;
        let first = decide(&values[..rows * k], half);
        let second = decide(&values, count);
        let words = (2 * rows).div_ceil(32) - rows / 32;
        let want_bytes = rows * k * rs + 4 * words + count * n * 4 + 16;
        assert_eq!(
            second as usize, want_bytes,
            "{precision:?}: first call sent {first}"
        );
        // Nothing new: the ids alone.
        let third = decide(&values, count);
        assert_eq!(third as usize, count * n * 4 + 16, "{precision:?}");
        assert_eq!(oracle.stats().contradicted, 0);
    }
}

#[test]
fn the_eval_vertices_shader_matches_its_cpu_twin() {
    use isomesh::cpu::eval_vertices::eval_lattice;
    use isomesh::expr::{ImplicitFunction, PRESETS};
    let Some(g) = gpu("the_eval_vertices_shader_matches_its_cpu_twin") else {
        return;
    };
    for info in PRESETS {
        let p = problem(info.name, &[]);
        let (d, k) = (p.dim(), p.system.codim());
        let tri = p.triangulation.build(d).unwrap();
        // Lattice vertices around the seed: the vertex of its simplex, plus random offsets.
        let base = tri.locate(&p.seeds[0]).unwrap().base().to_vec();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(d as u64);
        let lattice: Vec<i32> = (0..3000 * d)
            .map(|i| base[i % d] + rng.random_range(-12..=12))
            .collect();
        let n = lattice.len() / d;
        let mut twin = vec![0.0; n * k];
        let (a, b) = tri.affine_map();
        eval_lattice(p.system.values(), &a, &b, &lattice, &mut twin);
        // The twin computes what tracing computes, up to the cheaper unrotated maps.
        let mut traced = vec![0.0; n * k];
        CpuOracle::new(&p.system)
            .eval_vertices(&tri, &lattice, &mut traced)
            .unwrap();
        for (t, c) in twin.iter().zip(&traced) {
            assert!(
                (t - c).abs() <= 1e-12 * (1.0 + c.abs()),
                "{}: {t} vs {c}",
                info.name
            );
        }
        for prec in precisions(&g) {
            let o = GpuOracle::new(g.clone(), &p.system, prec).unwrap();
            let got = o.eval_vertices_stage(&tri, &lattice).unwrap();
            assert_eq!(got.len(), twin.len());
            // What holds on any conforming device: its f64 operations may be as coarse as
            // f32's (the values reach no output; lavapipe's agree to about 4e-16).
            let tol = 1e-4;
            let worst = got
                .iter()
                .zip(&twin)
                .map(|(g, c)| (g - c).abs() / (1.0 + c.abs()))
                .fold(0.0, f64::max);
            assert!(
                worst <= tol,
                "{} {:?}: {worst:.2e}",
                info.name,
                o.precision()
            );
        }
    }
}

fn cube(d: usize, half: f64) -> Vec<[f64; 2]> {
    vec![[-half, half]; d]
}

#[test]
fn the_scan_shader_matches_its_cpu_twin() {
    use isomesh::expr::{ClosureFunction, ImplicitFunction};
    let Some(g) = gpu("the_scan_shader_matches_its_cpu_twin") else {
        return;
    };
    let grid_of = |f: &dyn ImplicitFunction, tri: &Triangulation, half: f64| {
        let opts = TraceOptions {
            bbox: Some(cube(tri.dim(), half)),
            ..TraceOptions::default()
        };
        scan_grid(f, tri, &CpuOracle::new(f), &opts).unwrap()
    };
    // (what, f, triangulation, box half-width, the cubes to scan: None for all).
    type Case = (String, Box<dyn ImplicitFunction>, Triangulation, f64);
    let mut cases: Vec<(Case, Option<usize>)> = Vec::new();
    for (name, params, half) in [
        ("sphere", vec![("edge", 0.2)], 1.3),
        ("flat-torus", vec![("edge", 0.3)], 1.2),
        ("sphere", vec![("d", 5.0), ("edge", 0.6)], 1.2),
        (
            "3-torus",
            vec![("a", 0.5), ("b", 0.5), ("c", 0.5), ("edge", 0.9)],
            1.1,
        ),
    ] {
        let p = problem(name, &params);
        let tri = p.triangulation.build(p.dim()).unwrap();
        let case = (
            format!("{name} {params:?}"),
            Box::new(p.system) as _,
            tri,
            half,
        );
        cases.push((case, None));
    }
    // d = 8, the largest the shader takes: a tilted hyperplane through the lattice vertex
    // nearest the box's centre (an exact zero there), NaN on one side of another hyperplane.
    // The d = 8 grid holds millions of vertices, so the scan covers 40,000 cubes around that
    // vertex.
    let tri = problem("sphere", &[("m", 7.0), ("d", 8.0), ("edge", 1.0)])
        .triangulation
        .build(8)
        .unwrap();
    let probe = ClosureFunction::new(8, 1, |x, o| o[0] = x[0]).unwrap();
    let grid = grid_of(&probe, &tri, 0.05);
    let (mut v, mut x) = (vec![0; 8], vec![0.0; 8]);
    let norm = |i: usize, v: &mut Vec<i32>, x: &mut Vec<f64>| {
        grid.coords(i, v);
        tri.vertex_coords(v, x);
        x.iter().map(|t| t * t).sum::<f64>()
    };
    let mid = (0..grid.len())
        .min_by(|&a, &b| norm(a, &mut v, &mut x).total_cmp(&norm(b, &mut v, &mut x)))
        .unwrap();
    let mut c = vec![0.0; 8];
    grid.coords(mid, &mut v);
    tri.vertex_coords(&v, &mut c);
    let plane = ClosureFunction::new(8, 1, move |x, o| {
        o[0] = if x[1] > c[1] + 0.4 {
            f64::NAN
        } else {
            (x[0] - c[0]) + 0.5 * (x[2] - c[2])
        };
    })
    .unwrap();
    cases.push((
        ("hyperplane in R^8".into(), Box::new(plane), tri, 0.05),
        Some(mid),
    ));
    for ((what, f, tri, half), middle) in &cases {
        let grid = grid_of(f.as_ref(), tri, *half);
        let cubes = match middle {
            Some(m) => m - 20_000..m + 20_000,
            None => 0..grid.len(),
        };
        let want = candidates(&grid, cubes.clone());
        assert!(want.count(grid.codim()) > 100, "{what}: too few candidates");
        if middle.is_some() {
            assert!(grid.values().contains(&0.0), "{what}: no exact zero");
            assert!(grid.values().iter().any(|v| v.is_nan()), "{what}: no NaN");
        }
        let oracle = GpuOracle::new(g.clone(), f.as_ref(), Some(Precision::F32)).unwrap();
        let got = oracle.scan_stage(&grid, cubes.clone()).unwrap();
        assert!(
            got == want,
            "{what}: {} vs {} words",
            got.rows.len(),
            want.rows.len()
        );
        // Bindings of 4 KiB: windows split down to single cubes, outputs overflow and run
        // again, and cubes whose window alone is too large (all of them at d = 8) go to the
        // CPU (on the first 3,000 cubes: each split is a dispatch).
        let cubes = cubes.start..cubes.end.min(cubes.start + 3000);
        let want = candidates(&grid, cubes.clone());
        oracle.limit_binding(4096);
        let got = oracle.scan_stage(&grid, cubes).unwrap();
        assert!(got == want, "{what}, small bindings");
    }
}

#[test]
fn gpu_exhaustive_scans_take_the_cpu_candidates_and_verdicts() {
    let Some(g) = gpu("gpu_exhaustive_scans_take_the_cpu_candidates_and_verdicts") else {
        return;
    };
    let modes = precisions(&g);
    drop(g);
    let cases: Vec<Scaled> = vec![
        ("circle", vec![("edge", 0.1)], 1.2),
        ("circle", vec![("edge", 0.03)], 1.2),
        ("sphere", vec![("edge", 0.2)], 1.2),
        ("sphere", vec![("edge", 0.1)], 1.2),
        ("torus", vec![("edge", 0.1)], 1.5),
        ("torus", vec![("edge", 0.07)], 1.5),
        ("chair", vec![("edge", 0.15)], 1.6),
        ("chair", vec![("edge", 0.1)], 1.6),
        ("flat-torus", vec![("edge", 0.3)], 1.1),
        ("flat-torus", vec![("edge", 0.2)], 1.1),
        (
            "3-torus",
            vec![("a", 0.5), ("b", 0.5), ("c", 0.5), ("edge", 0.9)],
            1.1,
        ),
        ("complex-cosine", vec![("edge", 0.3)], 0.0),
        ("complex-cosine", vec![("edge", 0.25)], 0.0),
        ("bagel-klein", vec![("edge", 0.5)], 0.0),
        ("cut-flat-torus", vec![("edge", 0.3)], 1.1),
    ];
    for precision in modes {
        for (c, (name, params, half)) in cases.iter().enumerate() {
            let p = problem(name, params);
            let tri = p.triangulation.build(p.dim()).unwrap();
            // The preset's own box where it has one.
            let bbox = p.bbox.clone().unwrap_or_else(|| cube(p.dim(), *half));
            let opts = TraceOptions {
                bbox: Some(bbox.clone()),
                ..TraceOptions::default()
            };
            let cpu = exhaustive(&p.system, &tri, &CpuOracle::new(&p.system), &opts).unwrap();
            // The adapter, and for every other case also its solve emulated.
            for emulate in [None]
                .into_iter()
                .chain((c % 2 == 1).then_some(Some(c as u64)))
            {
                let oracle = GpuOracle::new(reopen(), &p.system, precision).unwrap();
                oracle.emulate_device(emulate);
                let shadow = Shadow::new(&oracle, &p.system);
                let gpu = exhaustive(&p.system, &tri, &shadow, &opts).unwrap();
                let what = format!("{name} {params:?} {precision:?}, emulated {emulate:?}");
                // What the device returned: every scan's candidates, verdict and lambda.
                let log = shadow.check(&what);
                assert!(log.scans > 0, "{what}: the device scanned nothing");
                assert!(cpu.len() > 10, "{what}: only {} simplices", cpu.len());
                assert_eq!(cpu.sorted_keys(), gpu.sorted_keys(), "{what}: S differs");
                assert_eq!(cpu.stats.oracle_calls, gpu.stats.oracle_calls, "{what}");
                assert_eq!(cpu.stats.components, gpu.stats.components, "{what}");
                assert!(oracle.stats().solved > 0, "{what}: the GPU did nothing");
            }
        }
    }
}

#[test]
fn one_gpu_oracle_serves_several_threads_at_once() {
    let Some(g) = gpu("one_gpu_oracle_serves_several_threads_at_once") else {
        return;
    };
    let p = problem("sphere", &[("edge", 0.1)]);
    let tri = p.triangulation.build(3).unwrap();
    let opts = TraceOptions {
        bbox: Some(cube(3, 1.2)),
        ..TraceOptions::default()
    };
    let cpu = CpuOracle::new(&p.system);
    let grid = scan_grid(&p.system, &tri, &cpu, &opts).unwrap();
    // f32: every crossing's lambda comes from the CPU, so results compare bit for bit.
    let oracle = GpuOracle::new(g, &p.system, Some(Precision::F32)).unwrap();
    // Four threads on one oracle, each with its own share of the grid (so buffers of
    // different sizes cross in the pools), alternating scans and decisions.
    let shares: Vec<_> = (1..=4)
        .map(|t| {
            let cubes = 0..grid.len() * t / 4;
            let cands = candidates(&grid, cubes.clone());
            let m = cands.count(1);
            let (mut status, mut lambda) = (vec![Status::Outside; m], vec![0.0; 2 * m]);
            cpu.decide(grid.values(), &cands.rows, &mut status, &mut lambda)
                .unwrap();
            (cubes, cands, status, lambda)
        })
        .collect();
    assert!(shares[0].1.count(1) > 1000, "too few candidates");
    std::thread::scope(|s| {
        for (t, (cubes, cands, status, lambda)) in shares.iter().enumerate() {
            let (oracle, grid) = (&oracle, &grid);
            s.spawn(move || {
                for round in 0..4 {
                    let got = oracle.scan_stage(grid, cubes.clone()).unwrap();
                    assert!(
                        got == *cands,
                        "thread {t}, round {round}: candidates differ"
                    );
                    let m = status.len();
                    let (mut st, mut lam) = (vec![Status::Outside; m], vec![0.0; 2 * m]);
                    oracle
                        .decide(grid.values(), &got.rows, &mut st, &mut lam)
                        .unwrap();
                    assert!(st == *status, "thread {t}, round {round}: decisions differ");
                    for i in (0..m).filter(|&i| st[i].crossed()) {
                        assert_eq!(lam[2 * i..2 * i + 2], lambda[2 * i..2 * i + 2]);
                    }
                }
            });
        }
    });
    assert!(oracle.stats().solved > 0);
}

#[test]
fn the_eval_certified_shader_matches_its_cpu_twin() {
    use isomesh::cpu::eval_certified::eval_lattice_certified;
    use isomesh::expr::{ImplicitFunction, PRESETS};
    let Some(g) = gpu("the_eval_certified_shader_matches_its_cpu_twin") else {
        return;
    };
    for info in PRESETS {
        let p = problem(info.name, &[]);
        let (d, k) = (p.dim(), p.system.codim());
        let tri = p.triangulation.build(d).unwrap();
        let base = tri.locate(&p.seeds[0]).unwrap().base().to_vec();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(d as u64 + 7);
        let lattice: Vec<i32> = (0..2000 * d)
            .map(|i| base[i % d] + rng.random_range(-12..=12))
            .collect();
        let n = lattice.len() / d;
        // The CPU's values, as tracing computes them.
        let mut cpu = vec![0.0; n * k];
        CpuOracle::new(&p.system)
            .eval_vertices(&tri, &lattice, &mut cpu)
            .unwrap();
        let (a, b) = tri.affine_map();
        // The adapter, then the stage emulated as any conforming device may compute it.
        let runs = precisions(&g)
            .into_iter()
            .flat_map(|p| [(p, None), (p, Some(d as u64 + 3))]);
        for (prec, emulate) in runs {
            let o = GpuOracle::new(g.clone(), &p.system, prec).unwrap();
            o.emulate_device(emulate);
            let acc = o.precision().accuracy();
            let got = o.eval_certified_stage(&tri, &lattice).unwrap();
            assert_eq!(got.len(), 2 * n * k);
            let twin = match o.precision() {
                Precision::F64 => {
                    eval_lattice_certified::<f64>(p.system.values(), &acc, &a, &b, &lattice)
                }
                Precision::F32 => {
                    eval_lattice_certified::<f32>(p.system.values(), &acc, &a, &b, &lattice)
                }
            };
            let mut known = 0;
            for (i, (pair, c)) in got.chunks_exact(2).zip(&cpu).enumerate() {
                let (v, e) = (pair[0], pair[1]);
                let [tv, te] = twin[i];
                let usable = |v: f64, e: f64| e < acc.big && v.abs() < acc.big;
                if !usable(v, e) {
                    continue;
                }
                known += 1;
                assert!(
                    (c - v).abs() <= e,
                    "{} {:?}, emulated {emulate:?}: the CPU's {c} is not within {e:e} of the \
                     device's {v}",
                    info.name,
                    o.precision()
                );
                // Twin and shader compute the same rules: equal values up to the device's
                // functions, bounds of the same size.
                assert!(usable(tv, te), "{}: the twin has no bound", info.name);
                assert!(
                    (tv - v).abs() <= e + te
                        && e <= 2.0 * te + acc.tiny
                        && te <= 2.0 * e + acc.tiny,
                    "{} {:?}, emulated {emulate:?}: device ({v}, {e:e}) against twin ({tv}, \
                     {te:e})",
                    info.name,
                    o.precision()
                );
            }
            assert!(
                known as f64 >= 0.95 * (n * k) as f64,
                "{} {:?}, emulated {emulate:?}: {known} of {} values have a bound",
                info.name,
                o.precision(),
                n * k
            );
        }
    }
}

/// `shaders/math_f64.wgsl` (the plain f64 vertex shader's functions, whose values reach no
/// output: the certified shader uses the f32 built-ins) against Rust's f64 library. Its ulps
/// are printed; what is asserted holds on any conforming device, where f64 operations may
/// be as coarse as f32's: an error within (2^-14 + 2^-20 |x|) max(1, |f(x)|).
#[test]
fn math_f64_functions_are_close_to_the_cpus() {
    use isomesh::triangulation::{Triangulation, TriangulationKind};
    let Some(g) = gpu("math_f64_functions_are_close_to_the_cpus") else {
        return;
    };
    if !g.adapter.shader_f64 {
        eprintln!("SKIPPED math_f64_functions_are_close_to_the_cpus: no SHADER_F64");
        return;
    }
    let ulp = |y: f64| (f64::from_bits(y.abs().to_bits() + 1) - y.abs()).max(f64::MIN_POSITIVE);
    type Case = (&'static str, fn(f64) -> f64, [f64; 2]);
    #[rustfmt::skip]
    let fns: [Case; 14] = [
        ("exp(x)", f64::exp, [-700.0, 700.0]),
        ("ln(x)", f64::ln, [1e-30, 1e30]),
        ("ln(x)", f64::ln, [0.5, 2.0]),
        ("sin(x)", f64::sin, [-1e6, 1e6]),
        ("cos(x)", f64::cos, [-1e3, 1e3]),
        ("atan(x)", f64::atan, [-1e6, 1e6]),
        ("atan(x)", f64::atan, [-2.0, 2.0]),
        ("tan(x)", f64::tan, [-1.5, 1.5]),
        ("asin(x)", f64::asin, [-0.999, 0.999]),
        ("acos(x)", f64::acos, [-0.999, 0.999]),
        ("sinh(x)", f64::sinh, [-700.0, 700.0]),
        ("cosh(x)", f64::cosh, [-700.0, 700.0]),
        ("tanh(x)", f64::tanh, [-30.0, 30.0]),
        ("sqrt(x)", f64::sqrt, [0.0, 1e10]),
    ];
    let n = 20_000;
    for (text, reference, [lo, hi]) in fns {
        // In R^2 (a system needs fewer equations than variables), along the x1 axis.
        let text = text.replace("(x)", "(x1)");
        let system = isomesh::expr::EquationSystem::parse_simple(2, &[&text]).unwrap();
        let step = (hi - lo) / n as f64;
        let tri = Triangulation::builder(2, TriangulationKind::Freudenthal)
            .edge(step * 2f64.sqrt())
            .offset(vec![lo, 0.0])
            .build()
            .unwrap();
        let lattice: Vec<i32> = (0..=n).flat_map(|i| [i, 0]).collect();
        let o = GpuOracle::new(g.clone(), &system, Some(Precision::F64)).unwrap();
        let got = o.eval_vertices_stage(&tri, &lattice).unwrap();
        let mut worst = 0.0f64;
        for (u, dev) in lattice.chunks_exact(2).zip(&got) {
            let mut x = [0.0; 2];
            tri.vertex_coords(u, &mut x);
            // The device maps u to x itself: compare at the device's x (the same bits here).
            let y = reference(x[0]);
            let err = (dev - y).abs();
            let tol = (2f64.powi(-14) + 2f64.powi(-20) * x[0].abs()) * y.abs().max(1.0);
            assert!(
                err <= tol,
                "{text} at {}: device {dev}, Rust {y}: error {err:e}",
                x[0]
            );
            worst = worst.max(err / ulp(y));
        }
        eprintln!("{text} on [{lo}, {hi}]: within {worst} ulps");
    }
}

/// The certified solve shader against its CPU twin
/// ([`CertifiedSolver`](isomesh::cpu::certificate::CertifiedSolver)) on hard simplices with
/// value bounds of every size, and both against the exact decision of the values (which lie
/// within the bounds).
#[test]
fn the_solve_certified_shader_matches_its_cpu_twin() {
    use isomesh::cpu::certificate::{pack_rows, CertifiedSolver, CROSSED, OUTSIDE, UNCERTAIN};
    use isomesh::cpu::solve::exact_decision;
    use isomesh::expr::certified::DeviceReal;
    let Some(g) = gpu("the_solve_certified_shader_matches_its_cpu_twin") else {
        return;
    };
    fn twin<R: DeviceReal>(k: usize, l: &[f64], e: &[f64]) -> (Vec<u32>, Vec<f64>) {
        let (n, per) = (k + 1, k * (k + 1));
        let mut s = CertifiedSolver::<R>::new(k);
        let (mut lf, mut ef) = (vec![R::of(1.0); n * n], vec![R::of(0.0); n * n]);
        let mut x = vec![R::of(0.0); n];
        let (mut flags, mut lam) = (Vec::new(), Vec::new());
        for (lr, er) in l.chunks(per).zip(e.chunks(per)) {
            for i in 0..per {
                lf[n + i] = R::of(lr[i]);
                ef[n + i] = R::of(er[i]);
            }
            flags.push(s.solve(&lf, &ef, &mut x));
            lam.extend(x.iter().map(|v| v.wide()));
        }
        (flags, lam)
    }
    for k in [1, 3, 5] {
        let (n, per) = (k + 1, k * (k + 1));
        let count = 20_000;
        let (values, _) = hard_batch(k, count, 17 + k as u64);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(k as u64);
        // Bounds: none for a quarter, else 2^-r of the value, r in 8..=50.
        let bounds: Vec<f64> = values
            .iter()
            .map(|v| match rng.random_range(0..4) {
                0 => 0.0,
                _ => v.abs() * (-(rng.random_range(8..=50) as f64)).exp2(),
            })
            .collect();
        // The adapter, then the stage emulated as any conforming device may compute it.
        let runs = precisions(&g)
            .into_iter()
            .flat_map(|p| [(p, None), (p, Some(k as u64 + 29))]);
        for (prec, emulate) in runs {
            let f = isomesh::expr::ClosureFunction::new(k + 1, k, |_, o| o.fill(0.0)).unwrap();
            let o = GpuOracle::new(reopen(), &f, prec).unwrap();
            o.emulate_device(emulate);
            let p = (o.precision(), emulate);
            let (mut l, mut e) = (vec![0.0; count * per], vec![0.0; count * per]);
            for i in 0..count {
                let at = |j: usize, c: usize| i * per + j * k + c;
                let (val, bnd) = (|j, c| values[at(j, c)], |j, c| bounds[at(j, c)]);
                let (lo, eo) = (&mut l[i * per..][..per], &mut e[i * per..][..per]);
                let ok = match p.0 {
                    Precision::F32 => pack_rows::<f32>(k, val, bnd, lo, eo),
                    Precision::F64 => pack_rows::<f64>(k, val, bnd, lo, eo),
                };
                assert!(ok);
            }
            let (flags, lambda) = o.solve_certified_stage(&l, &e).unwrap();
            let (tflags, tlambda) = match p.0 {
                Precision::F32 => twin::<f32>(k, &l, &e),
                Precision::F64 => twin::<f64>(k, &l, &e),
            };
            let mut exact_l = vec![0.0; n];
            let (mut differ, mut certified) = (0, 0);
            for i in 0..count {
                let (a, b) = (flags[i], tflags[i]);
                differ += (a != b) as usize;
                assert!(a <= UNCERTAIN, "{p:?}: flag {a}");
                if a != UNCERTAIN {
                    certified += 1;
                    let want = exact_decision(&values[i * per..][..per], k, &mut exact_l);
                    let ok = (a == CROSSED) == (want == Status::Crossed)
                        && (a != OUTSIDE || want == Status::Outside);
                    assert!(
                        ok,
                        "k = {k} {p:?}: device {a}, exact {want:?} (simplex {i})"
                    );
                }
                assert!(
                    !(a != UNCERTAIN && b != UNCERTAIN && a != b),
                    "k = {k} {p:?}: device {a}, twin {b} (simplex {i})"
                );
            }
            let bits = lambda
                .iter()
                .zip(&tlambda)
                .filter(|(a, b)| a.to_bits() != b.to_bits())
                .count();
            eprintln!(
                "k = {k} {p:?}: {certified} of {count} certified, {differ} verdicts and {bits} \
                 entries of x differ from the twin"
            );
            assert!(
                certified * 2 > count,
                "k = {k} {p:?}: {certified} certified"
            );
            // Any device's rounding moves certainty only at the margins: a rare event.
            assert!(
                differ <= count / 100,
                "k = {k} {p:?}: {differ} verdicts differ"
            );
        }
    }
}

/// The scan cases of the device-values tests: every preset at two scales (a preset's own
/// box where it has one, else a cube of the half-width given).
fn device_value_cases() -> Vec<Scaled> {
    vec![
        ("circle", vec![("edge", 0.1)], 1.2),
        ("circle", vec![("edge", 0.03)], 1.2),
        ("sphere", vec![("edge", 0.2)], 1.2),
        ("sphere", vec![("edge", 0.1)], 0.8),
        ("torus", vec![("edge", 0.1)], 1.5),
        ("torus", vec![("edge", 0.07)], 1.0),
        ("chair", vec![("edge", 0.15)], 1.6),
        ("chair", vec![("edge", 0.1)], 1.0),
        ("flat-torus", vec![("edge", 0.3)], 1.1),
        ("flat-torus", vec![("edge", 0.2)], 0.8),
        (
            "3-torus",
            vec![("a", 0.5), ("b", 0.5), ("c", 0.5), ("edge", 1.2)],
            1.1,
        ),
        (
            "3-torus",
            vec![("a", 0.5), ("b", 0.5), ("c", 0.5), ("edge", 0.9)],
            0.7,
        ),
        ("complex-cosine", vec![("edge", 0.3)], 0.0),
        ("complex-cosine", vec![("edge", 0.25)], 0.0),
        // The emulated device (even cases) rounds each operation in software, about 10 us
        // a vertex in 5 dimensions: its bagel-klein scale is the coarser one.
        ("bagel-klein", vec![("edge", 0.8)], 0.0),
        ("bagel-klein", vec![("edge", 0.6)], 0.0),
        ("cut-flat-torus", vec![("edge", 0.4)], 1.1),
        ("cut-flat-torus", vec![("edge", 0.3)], 1.1),
    ]
}

/// Problems whose zero set runs through lattice vertices (an unrotated Freudenthal-Kuhn
/// lattice of spacing h with no offset), so that values at vertices are 0 or a rounding away
/// from it, within the device's bounds of 0; boxes and boundaries cut M at lattice vertices.
fn lattice_zero_cases() -> Vec<Problem> {
    let spec = |d: usize, h: f64, eqs: &[&str], bnd: &[&str], half: f64| {
        let matrix: Vec<Vec<f64>> = (0..d)
            .map(|i| (0..d).map(|j| if i == j { h } else { 0.0 }).collect())
            .collect();
        let text = format!(
            "ambient_dim = {d}\nequations = {eqs:?}\nboundary = {bnd:?}\nbox = {:?}\n\
             [triangulation]\nkind = \"custom\"\nmatrix = {matrix:?}\n",
            cube(d, half)
        );
        Spec::from_toml(&text)
            .and_then(|s| s.resolve(&eqs.join(", ")))
            .unwrap_or_else(|e| panic!("{text}: {e}"))
    };
    vec![
        // (±0.6, ±0.8) and (±1, 0) are vertices on the circle, and the box touches it there.
        spec(2, 0.1, &["x1^2 + x2^2 - 1"], &[], 1.0),
        spec(2, 0.1, &["x1 - x2"], &[], 0.7),
        spec(2, 0.1, &["0.3*x1 + 0.7*x2 - 0.1"], &["0.3 - x1"], 0.8),
        spec(3, 0.1, &["x1 + x2 + x3 - 0.3"], &[], 0.5),
        spec(3, 0.1, &["x1^2 + x2^2 + x3^2 - 0.25"], &["x3 - 0.3"], 0.6),
        // A line along lattice edges: every simplex around it is degenerate.
        spec(3, 0.1, &["x1 - 0.3", "x2 + 0.2"], &[], 0.5),
        spec(
            4,
            0.2,
            &["x1^2 + x2^2 - 1", "x3^2 + x4^2 - 1"],
            &["0.6 - x1"],
            1.0,
        ),
    ]
}

/// `got` is `want` exactly: the keys in the same order, the points bit for bit, the rim, the
/// components and the complex's topology.
fn assert_same_scan(p: &Problem, bbox: &[[f64; 2]], want: &Sample, got: &Sample, what: &str) {
    assert_eq!(want.len(), got.len(), "{what}: |S|");
    for i in 0..want.len() {
        assert_eq!(want.key(i), got.key(i), "{what}: key {i}");
    }
    let bits = |v: Vec<f64>| v.into_iter().map(f64::to_bits).collect::<Vec<_>>();
    assert!(
        bits(want.points()) == bits(got.points()),
        "{what}: the points differ"
    );
    assert_eq!(want.rim_len(), got.rim_len(), "{what}: rim");
    for r in 0..want.rim_len() {
        assert_eq!(want.rim_key(r), got.rim_key(r), "{what}: rim {r}");
        assert!(
            bits(want.rim_point(r).to_vec()) == bits(got.rim_point(r).to_vec()),
            "{what}: rim point {r}"
        );
    }
    assert_eq!(want.stats.components, got.stats.components, "{what}");
    if want.ambient_dim() - want.codim() <= 3 && !want.is_empty() {
        use isomesh::complex::Complex;
        let t = |s: &Sample| Complex::build(s, &p.system, Some(bbox)).unwrap().topology();
        let (a, b) = (t(want), t(got));
        assert_eq!(a.cells, b.cells, "{what}: cells");
        assert_eq!(a.euler_characteristic, b.euler_characteristic, "{what}");
        assert_eq!(a.betti_mod2, b.betti_mod2, "{what}");
    }
}

#[test]
fn gpu_scans_with_device_values_are_the_cpu_scans_through_lattice_zeros() {
    let Some(g) = gpu("gpu_scans_with_device_values_are_the_cpu_scans_through_lattice_zeros")
    else {
        return;
    };
    let modes = precisions(&g);
    drop(g);
    for (c, p) in lattice_zero_cases().iter().enumerate() {
        let tri = p.triangulation.build(p.dim()).unwrap();
        let bbox = p.bbox.clone().unwrap();
        let opts = TraceOptions {
            bbox: Some(bbox.clone()),
            ..TraceOptions::default()
        };
        let cpu = exhaustive(&p.system, &tri, &CpuOracle::new(&p.system), &opts).unwrap();
        assert!(cpu.len() > 10, "{}: only {} simplices", p.name, cpu.len());
        for &precision in &modes {
            // As the adapter computes them, moved within their bounds, and on an emulated
            // conforming device.
            let c = c as u64;
            for (perturb, emulate) in [(None, None), (Some(c), None), (None, Some(c))] {
                let got = device_value_scan(p, &tri, &bbox, precision, perturb, emulate);
                let what = format!(
                    "{} {precision:?}, perturbed {perturb:?}, emulated {emulate:?}",
                    p.name
                );
                assert_same_scan(p, &bbox, &cpu, &got, &what);
            }
        }
    }
}

/// Boxes whose faces pass within 1e-13 of crossings of M, on either side: whether a crossing
/// is in the box is the CPU's decision, so the device's rounding cannot move it.
#[test]
fn gpu_scans_with_device_values_keep_the_cpu_box_within_1e_13_of_crossings() {
    let Some(g) = gpu("gpu_scans_with_device_values_keep_the_cpu_box_within_1e_13_of_crossings")
    else {
        return;
    };
    let modes = precisions(&g);
    drop(g);
    let cases: [Scaled; 3] = [
        ("sphere", vec![("edge", 0.1)], 0.8),
        ("flat-torus", vec![("edge", 0.2)], 0.8),
        ("cut-flat-torus", vec![("edge", 0.3)], 1.1),
    ];
    let scan = |p: &Problem, tri: &Triangulation, bbox: &[[f64; 2]]| {
        let opts = TraceOptions {
            bbox: Some(bbox.to_vec()),
            ..TraceOptions::default()
        };
        exhaustive(&p.system, tri, &CpuOracle::new(&p.system), &opts).unwrap()
    };
    let holds = |s: &Sample, x: &[f64]| (0..s.len()).any(|i| s.point(i) == x);
    for (c, (name, params, half)) in cases.iter().enumerate() {
        let p = problem(name, params);
        let tri = p.triangulation.build(p.dim()).unwrap();
        let whole = scan(&p, &tri, &cube(p.dim(), *half));
        // The crossing furthest along x1 and the one furthest back along x2.
        let extreme = |axis: usize, sign: f64| {
            let key = |i: &usize| sign * whole.point(*i)[axis];
            whole.point(
                (0..whole.len())
                    .max_by(|i, j| key(i).total_cmp(&key(j)))
                    .unwrap(),
            )
        };
        let (a, b) = (extreme(0, 1.0), extreme(1, -1.0));
        for side in [1e-13, -1e-13] {
            // The top face of x1 just beyond (or just short of) a, the bottom face of x2 of b.
            let mut bbox = cube(p.dim(), *half);
            bbox[0][1] = a[0] + side;
            bbox[1][0] = b[1] - side;
            let cpu = scan(&p, &tri, &bbox);
            assert_eq!(holds(&cpu, &a), side > 0.0, "{name}: the CPU box at {a:?}");
            assert_eq!(holds(&cpu, &b), side > 0.0, "{name}: the CPU box at {b:?}");
            for &precision in &modes {
                for emulate in [None, Some(c as u64)] {
                    let perturb = Some(c as u64);
                    let got = device_value_scan(&p, &tri, &bbox, precision, perturb, emulate);
                    let what = format!("{name} {precision:?}, side {side}, emulated {emulate:?}");
                    assert_same_scan(&p, &bbox, &cpu, &got, &what);
                }
            }
        }
    }
}

/// The device-resident scan evaluates f on the device at the vertices of its tiles near the
/// box (as many as its tiles report), and on the CPU only at the vertices of the candidates
/// the device left open (counted here from the tiles' records, tile by tile), a small part
/// of them.
#[test]
fn gpu_scans_with_device_values_evaluate_on_the_cpu_only_what_the_device_left_open() {
    use std::collections::HashSet;
    let Some(g) =
        gpu("gpu_scans_with_device_values_evaluate_on_the_cpu_only_what_the_device_left_open")
    else {
        return;
    };
    let modes = precisions(&g);
    drop(g);
    let cases: [Scaled; 4] = [
        ("sphere", vec![("edge", 0.1)], 0.8),
        ("chair", vec![("edge", 0.1)], 1.0),
        ("flat-torus", vec![("edge", 0.2)], 0.8),
        (
            "3-torus",
            vec![("a", 0.5), ("b", 0.5), ("c", 0.5), ("edge", 0.9)],
            0.7,
        ),
    ];
    for (c, (name, params, half)) in cases.iter().enumerate() {
        let p = problem(name, params);
        let tri = p.triangulation.build(p.dim()).unwrap();
        let bbox = cube(p.dim(), *half);
        let k = isomesh::expr::ImplicitFunction::codim(&p.system);
        let plan = TilePlan::new(&tri, k, &bbox, 1 << 30).unwrap();
        for &precision in &modes {
            let perturb = (c % 2 == 1).then_some(c as u64);
            let options = GpuOptions {
                precision,
                device_values: true,
                ..GpuOptions::default()
            };
            let oracle = GpuOracle::with_options(reopen(), &p.system, options).unwrap();
            oracle.perturb_device_values(perturb);
            // The vertices of the records, per tile (a vertex on a border between tiles is
            // evaluated for each).
            let (mut open, mut evaluated) = (0, 0);
            oracle
                .scan_tiles(&tri, &plan, &mut |t, found| {
                    let tile = &plan.tiles[t];
                    evaluated += found.evaluated;
                    let mut seen = HashSet::new();
                    for r in found.records.chunks_exact(k + 2) {
                        for s in std::iter::once(0).chain(r[1..=k].iter().copied()) {
                            seen.insert(tile.corner(r[0], s));
                        }
                    }
                    open += seen.len();
                    Ok(true)
                })
                .unwrap();
            let st = device_value_scan(&p, &tri, &bbox, precision, perturb, None).stats;
            let what = format!("{name} {precision:?}: {st:?}");
            let tiled: usize = plan.tiles.iter().map(|t| t.vertices()).sum();
            assert_eq!(st.device_vertex_evaluations, evaluated, "{what}");
            assert!(
                evaluated <= tiled as u64,
                "{what}: {tiled} vertices in tiles"
            );
            assert!(
                st.cpu_vertex_evaluations <= open as u64,
                "{what}: {open} vertices of open candidates"
            );
            assert!(st.cpu_vertex_evaluations > 0, "{what}");
            assert!(
                st.cpu_vertex_evaluations * 4 < st.device_vertex_evaluations,
                "{what}"
            );
        }
    }
}

/// The tile shaders against their CPU twin in f64, on the values and places the device
/// computes (lavapipe rounds as the CPU does): the same records, candidates and unknown
/// vertices, tile by tile.
#[test]
fn the_tile_shaders_match_their_cpu_twin() {
    use isomesh::cpu::certificate::{CertifiedSolver, UNCERTAIN};
    use isomesh::expr::certified::{lattice_point, Cv, Rules};
    use isomesh::trace::scan::tiles::{twin_tile_with, Place};
    let Some(g) = gpu("the_tile_shaders_match_their_cpu_twin") else {
        return;
    };
    if !g.adapter.shader_f64 {
        return;
    }
    drop(g);
    let cases: [Scaled; 4] = [
        ("sphere", vec![("edge", 0.1)], 0.8),
        ("torus", vec![("edge", 0.07)], 1.0),
        ("flat-torus", vec![("edge", 0.2)], 0.8),
        (
            "3-torus",
            vec![("a", 0.5), ("b", 0.5), ("c", 0.5), ("edge", 0.9)],
            0.7,
        ),
    ];
    for (name, params, half) in cases {
        let p = problem(name, &params);
        let (d, k) = (p.dim(), isomesh::expr::ImplicitFunction::codim(&p.system));
        let tri = p.triangulation.build(d).unwrap();
        let plan = TilePlan::new(&tri, k, &cube(d, half), 1 << 30).unwrap();
        let options = GpuOptions {
            precision: Some(Precision::F64),
            device_values: true,
            ..GpuOptions::default()
        };
        let oracle = GpuOracle::with_options(reopen(), &p.system, options).unwrap();
        let mut device = Vec::new();
        oracle
            .scan_tiles(&tri, &plan, &mut |_, found| {
                device.push(found);
                Ok(true)
            })
            .unwrap();
        assert_eq!(device.len(), plan.tiles.len(), "{name}");
        let (a, b) = tri.affine_map();
        let rules = Rules::<f64>::new(&Precision::F64.accuracy());
        let place = |u: &[i32]| {
            let mut x = vec![Cv::exact(0.0); d];
            lattice_point(&rules, &a, &b, u, &mut x);
            let within = |bx: &[[f64; 2]]| {
                x.iter()
                    .zip(bx)
                    .all(|(c, [lo, hi])| c.v + c.e >= *lo && c.v - c.e <= *hi)
            };
            if !within(&plan.far) {
                Place::Out
            } else if within(&plan.near) {
                Place::Near
            } else {
                Place::Far
            }
        };
        let mut records = 0;
        for (t, tile) in plan.tiles.iter().enumerate() {
            let twin = twin_tile_with(
                &plan,
                tile,
                place,
                |lattice, out| oracle.eval_certified(&tri, lattice, out),
                |values, bounds, rows, out| {
                    let n = k + 1;
                    let mut solver = CertifiedSolver::<f64>::new(k);
                    for (row, o) in rows.chunks_exact(n).zip(out.iter_mut()) {
                        let (mut l, mut e) = (vec![1.0; n * n], vec![0.0; n * n]);
                        for (j, &v) in row.iter().enumerate() {
                            for c in 0..k {
                                l[(c + 1) * n + j] = values[v as usize * k + c];
                                e[(c + 1) * n + j] = bounds[v as usize * k + c];
                            }
                        }
                        let known = e.iter().all(|x| x.is_finite());
                        let mut lambda = vec![0.0; n];
                        *o = if known {
                            solver.solve(&l, &e, &mut lambda)
                        } else {
                            UNCERTAIN
                        };
                    }
                    Ok(())
                },
            )
            .unwrap();
            let mut got = device[t].clone();
            let mut sorted: Vec<&[u32]> = got.records.chunks_exact(k + 2).collect();
            sorted.sort_unstable();
            got.records = sorted.concat();
            records += twin.records.len() / (k + 2);
            let what = format!("{name}: tile {t} ({tile:?})");
            assert_eq!(got.candidates, twin.candidates, "{what}: candidates");
            assert_eq!(got.unknown, twin.unknown, "{what}: unknown vertices");
            let first_difference = got
                .records
                .chunks(k + 2)
                .zip(twin.records.chunks(k + 2))
                .find(|(a, b)| a != b);
            assert_eq!(first_difference, None, "{what}: device, twin record");
            assert_eq!(got.records.len(), twin.records.len(), "{what}: records");
        }
        assert!(records > 50, "{name}: {records} records");
    }
}

/// The device-resident scan moves at most a byte per lattice vertex up and 64 bytes per
/// candidate the device left open back (the torus at edge 0.02).
#[test]
fn the_resident_scan_moves_little_between_host_and_device() {
    let Some(g) = gpu("the_resident_scan_moves_little_between_host_and_device") else {
        return;
    };
    let modes = precisions(&g);
    drop(g);
    let p = problem("torus", &[("edge", 0.02)]);
    let tri = p.triangulation.build(3).unwrap();
    let bbox = vec![[-1.5, 1.5], [-1.5, 1.5], [-0.5, 0.5]];
    let plan = TilePlan::new(&tri, 1, &bbox, 1 << 30).unwrap();
    for precision in modes {
        let options = GpuOptions {
            precision,
            device_values: true,
            ..GpuOptions::default()
        };
        let oracle = GpuOracle::with_options(reopen(), &p.system, options).unwrap();
        let (mut open, mut vertices) = (0u64, 0u64);
        oracle
            .scan_tiles(&tri, &plan, &mut |t, found| {
                open += (found.records.len() / 3) as u64;
                vertices += plan.tiles[t].vertices() as u64;
                Ok(true)
            })
            .unwrap();
        let st = oracle.stats();
        let what = format!("{precision:?}: {open} open, {vertices} vertices, {st:?}");
        assert!(open > 100_000, "{what}");
        assert!(st.upload_bytes <= vertices, "{what}");
        assert!(st.readback_bytes <= 64 * open, "{what}");
        eprintln!(
            "{precision:?}: {:.4} bytes up per lattice vertex, {:.1} back per open candidate",
            st.upload_bytes as f64 / vertices as f64,
            st.readback_bytes as f64 / open as f64
        );
    }
}

/// An exhaustive scan of `bbox` on the GPU with device values (perturbed within their bounds
/// from `perturb`; the device emulated from `emulate`), in `precision`.
fn device_value_scan(
    p: &Problem,
    tri: &Triangulation,
    bbox: &[[f64; 2]],
    precision: Option<Precision>,
    perturb: Option<u64>,
    emulate: Option<u64>,
) -> Sample {
    let options = GpuOptions {
        precision,
        device_values: true,
        ..GpuOptions::default()
    };
    let oracle = GpuOracle::with_options(reopen(), &p.system, options).unwrap();
    oracle.perturb_device_values(perturb);
    oracle.emulate_device(emulate);
    let opts = TraceOptions {
        bbox: Some(bbox.to_vec()),
        ..TraceOptions::default()
    };
    exhaustive(&p.system, tri, &oracle, &opts).unwrap()
}

#[test]
fn gpu_scans_with_device_values_are_the_cpu_scans() {
    let Some(g) = gpu("gpu_scans_with_device_values_are_the_cpu_scans") else {
        return;
    };
    let modes = precisions(&g);
    drop(g);
    for (c, (name, params, half)) in device_value_cases().iter().enumerate() {
        let p = problem(name, params);
        let tri = p.triangulation.build(p.dim()).unwrap();
        let bbox = p.bbox.clone().unwrap_or_else(|| cube(p.dim(), *half));
        let opts = TraceOptions {
            bbox: Some(bbox.clone()),
            ..TraceOptions::default()
        };
        let cpu = exhaustive(&p.system, &tri, &CpuOracle::new(&p.system), &opts).unwrap();
        assert!(cpu.len() > 10, "{name}: only {} simplices", cpu.len());
        // Every other case with device values moved within their bounds; the others also on
        // an emulated conforming device.
        let perturb = (c % 2 == 1).then_some(c as u64);
        let emulated = (c % 2 == 0).then_some(Some(c as u64));
        let runs = modes
            .iter()
            .flat_map(|&p| [None].into_iter().chain(emulated).map(move |e| (p, e)));
        for (precision, emulate) in runs {
            let got = device_value_scan(&p, &tri, &bbox, precision, perturb, emulate);
            let what = format!(
                "{name} {params:?} {precision:?}, perturbed {perturb:?}, emulated {emulate:?}"
            );
            assert_same_scan(&p, &bbox, &cpu, &got, &what);
            let st = &got.stats;
            // The device evaluated the grid; the CPU only a small part of it.
            assert!(st.device_vertex_evaluations > 0, "{what}: {st:?}");
            assert!(
                st.cpu_vertex_evaluations * 4 < st.device_vertex_evaluations,
                "{what}: {st:?}"
            );
            eprintln!(
                "{what}: {} device and {} CPU vertex evaluations, {} device and {} CPU \
                 decisions",
                st.device_vertex_evaluations,
                st.cpu_vertex_evaluations,
                st.device_decisions,
                st.cpu_decisions
            );
        }
    }
}

#[test]
fn a_stop_during_a_shader_compile_ends_the_wait_and_keeps_the_run() {
    let Some(g) = gpu("a_stop_during_a_shader_compile_ends_the_wait_and_keeps_the_run") else {
        return;
    };
    let p = problem("sphere", &[]);
    let cancel = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(true));
    // The driver may take minutes over a large system's shader: a raised stop flag ends
    // the wait instead of building the oracle.
    let options = GpuOptions {
        cancel: Some(cancel.clone()),
        ..GpuOptions::default()
    };
    match GpuOracle::with_options(g, &p.system, options) {
        Err(isomesh::Error::Interrupted(why)) => assert!(why.contains("solve"), "{why}"),
        Err(e) => panic!("not an interruption: {e}"),
        Ok(_) => panic!("the oracle was built under a raised stop flag"),
    }
    // Through the library's front door the run is then a sample marked interrupted, with
    // its report, as a stop on the CPU backend gives.
    let m = isomesh::Mesher::from_problem(p)
        .backend(isomesh::Backend::Gpu)
        .cancel(cancel)
        .run(isomesh::mesher::Job::Trace)
        .unwrap();
    assert_eq!(
        m.sample().stats.stopped,
        Some(isomesh::trace::StopReason::Interrupted)
    );
}

/// The warnings of a run, as text.
fn notes(m: &isomesh::Manifold) -> String {
    m.warnings()
        .iter()
        .map(|w| w.to_string())
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn auto_takes_the_gpu_only_where_the_calibration_measured_it_faster() {
    use isomesh::gpu::calibration::{Calibration, Entry, Speedups};
    use isomesh::{Backend, Mesher};
    let Some(g) = gpu("auto_takes_the_gpu_only_where_the_calibration_measured_it_faster") else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("isomesh-auto-{}", std::process::id()));
    let file = dir.join("calibration.toml");
    let torus = Mesher::preset("torus", &[])
        .unwrap()
        .edge(0.1)
        .bbox(vec![[-1.5, 1.5], [-1.5, 1.5], [-0.5, 0.5]])
        .threads(2);
    // As on a hardware adapter (the hook lets auto open this one), with this file.
    let auto = torus
        .clone()
        .backend(Backend::Auto)
        .auto_opens_software(true)
        .calibration(Some(file.clone()));
    let cpu_trace = torus.trace().unwrap();
    let cpu_scan = torus.scan().unwrap();

    // Nothing measured: the CPU, and the note says how to measure.
    let t = auto.trace().unwrap();
    assert_eq!(t.report().backend.backend, "cpu");
    assert!(notes(&t).contains("isomesh bench"), "{}", notes(&t));

    // Traces measured slower, scans faster with device values than without.
    let mut c = Calibration::default();
    c.record(Entry {
        traces: Some(Speedups {
            cases: 4,
            gpu: 0.5,
            device_values: None,
        }),
        scans: Some(Speedups {
            cases: 2,
            gpu: 1.5,
            device_values: Some(2.0),
        }),
        ..Entry::new(&g.adapter, 2)
    });
    c.save(&file).unwrap();
    let t = auto.trace().unwrap();
    assert_eq!(t.report().backend.backend, "cpu");
    assert!(notes(&t).contains("0.50x"), "{}", notes(&t));
    assert_eq!(t.sample().sorted_keys(), cpu_trace.sample().sorted_keys());
    let s = auto.scan().unwrap();
    let r = s.report();
    assert!(
        r.backend.backend.starts_with("gpu"),
        "{}",
        r.backend.backend
    );
    assert!(
        r.device_vertex_evaluations > 0,
        "the scan took device values"
    );
    assert!(notes(&s).is_empty(), "{}", notes(&s));
    assert_eq!(s.sample().sorted_keys(), cpu_scan.sample().sorted_keys());

    // A file that is not a calibration: the CPU, and the note names the file.
    std::fs::write(&file, "adapter = 1\n").unwrap();
    let s = auto.scan().unwrap();
    assert_eq!(s.report().backend.backend, "cpu");
    assert!(notes(&s).contains("calibration file"), "{}", notes(&s));

    // Without the hook auto never opens a software adapter, whatever the file says.
    c.save(&file).unwrap();
    if g.adapter.is_software() {
        let s = torus
            .clone()
            .backend(Backend::Auto)
            .calibration(Some(file.clone()))
            .scan()
            .unwrap();
        assert_eq!(s.report().backend.backend, "cpu");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
