//! The GPU oracle against the CPU: the solve, vertex and scan shaders against their CPU twins,
//! a stress test of badly conditioned simplices, and whole traces and exhaustive scans giving
//! the same S and the same topology.
//! Runs on any adapter wgpu finds (lavapipe in CI); skipped, saying why, when there is none.

use isomesh::complex::Complex;
use isomesh::cpu::decide::Status;
use isomesh::cpu::scan::candidates;
use isomesh::expr::{preset, Problem};
use isomesh::gpu::{Gpu, GpuOracle, Precision};
use isomesh::trace::{exhaustive, scan_grid, trace, CpuOracle, Oracle, Sample, TraceOptions};
use isomesh::triangulation::Triangulation;
use rand::{Rng, SeedableRng};

/// An adapter, or None (the test is skipped, saying why) when there is none, unless
/// ISOMESH_REQUIRE_GPU is set (CI, where lavapipe is installed).
fn gpu() -> Option<Gpu> {
    match Gpu::open(true) {
        Ok(g) => Some(g),
        Err(e) if std::env::var_os("ISOMESH_REQUIRE_GPU").is_some() => {
            panic!("ISOMESH_REQUIRE_GPU is set but {e}")
        }
        Err(e) => {
            eprintln!("skipped: {e}");
            None
        }
    }
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

/// The cell complexes of two samples of `p` have the same cell counts and Betti numbers.
fn assert_same_topology(
    cpu: &Sample,
    gpu: &Sample,
    p: &Problem,
    bbox: Option<&[[f64; 2]]>,
    what: &str,
) {
    let tc = Complex::build(cpu, &p.system, bbox).unwrap().topology();
    let tg = Complex::build(gpu, &p.system, bbox).unwrap().topology();
    assert_eq!(tc.cells, tg.cells, "{what}");
    assert_eq!(tc.betti_mod2, tg.betti_mod2, "{what}");
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

#[test]
fn gpu_decisions_equal_cpu_decisions_on_hard_simplices() {
    let Some(g) = gpu() else { return };
    let has_f64 = g.adapter.shader_f64;
    drop(g);
    let f = isomesh::expr::ClosureFunction::new(4, 3, |_, o| o.fill(0.0)).unwrap();
    for precision in [Precision::F32, Precision::F64] {
        if precision == Precision::F64 && !has_f64 {
            continue;
        }
        let oracle = GpuOracle::new(gpu().unwrap(), &f, Some(precision)).unwrap();
        let cpu = CpuOracle::new(&f);
        let count = 1_000_000;
        let (values, idx) = hard_batch(3, count, 7);
        let (mut s_gpu, mut s_cpu) = (vec![Status::Outside; count], vec![Status::Outside; count]);
        let (mut l_gpu, mut l_cpu) = (vec![0.0; count * 4], vec![0.0; count * 4]);
        oracle
            .decide(&values, &idx, &mut s_gpu, &mut l_gpu)
            .unwrap();
        cpu.decide(&values, &idx, &mut s_cpu, &mut l_cpu).unwrap();
        let mismatches = s_gpu.iter().zip(&s_cpu).filter(|(a, b)| a != b).count();
        assert_eq!(mismatches, 0, "{precision:?}: decisions differ");
        let crossed = s_cpu.iter().filter(|s| s.crossed()).count();
        assert!(crossed > 1000, "the batch should hold crossings");
        let mut worst: f64 = 0.0;
        for i in 0..count {
            if s_cpu[i].crossed() {
                for j in 0..4 {
                    worst = worst.max((l_gpu[i * 4 + j] - l_cpu[i * 4 + j]).abs());
                }
            }
        }
        assert!(worst <= 1e-12, "{precision:?}: lambda differs by {worst:e}");
        let st = oracle.stats();
        assert_eq!(st.solved as usize, s_cpu.len() - count_filtered(&values, 3));
        eprintln!(
            "{precision:?}: {} solved, {} rechecked on the CPU, lambda within {worst:e}",
            st.solved, st.rechecked
        );
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
fn gpu_traces_give_the_cpu_sample_and_topology() {
    let Some(g) = gpu() else { return };
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
            let oracle = GpuOracle::new(gpu().unwrap(), &p.system, precision).unwrap();
            // Every other case decides its levels in slices of 7 frontier simplices, naming
            // the next slice while the device decides one; the others in one batch (the
            // default).
            let slice = if i % 2 == 1 { 7 } else { 0 };
            oracle.set_level_slice(slice);
            let gpu = run(&p, &oracle);
            let what = format!("{name} {params:?} {precision:?}, slices of {slice}");
            assert_eq!(cpu.stats.oracle_calls, gpu.stats.oracle_calls, "{what}");
            assert_eq!(cpu.sorted_keys(), gpu.sorted_keys(), "{what}: S differs");
            assert_eq!(cpu.rim_len(), gpu.rim_len(), "{what}");
            // The sample's points come from the cached vertex values on the CPU: the same
            // bits; rim points keep the oracle's lambda.
            assert!(cpu.points() == gpu.points(), "{what}: points differ");
            let worst = (0..cpu.rim_len())
                .flat_map(|i| cpu.rim_point(i).iter().zip(gpu.rim_point(i)))
                .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            assert!(worst <= 1e-12, "{what}: rim points differ by {worst:e}");
            assert_same_topology(&cpu, &gpu, &p, p.bbox.as_deref(), &what);
            assert!(oracle.stats().solved > 0, "{what}: the GPU did nothing");
        }
    }
}

#[test]
fn the_solve_shader_matches_its_cpu_twin() {
    let Some(g) = gpu() else { return };
    let modes = precisions(&g);
    drop(g);
    let k = 3;
    let n = k + 1;
    let count = 200_000;
    let (values, idx) = hard_batch(k, count, 11);
    // The CPU fast path on the same inputs.
    let mut decider = isomesh::cpu::decide::Decider::new(k);
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
    for precision in modes {
        let oracle = GpuOracle::new(gpu().unwrap(), &f, precision).unwrap();
        let (gpu, lambda) = oracle.solve_stage(&values, &idx).unwrap();
        let (mut differ, mut worst) = (0, 0.0f64);
        for i in 0..count {
            match (cpu[i], gpu[i]) {
                (Some(a), Some(b)) => {
                    assert_eq!(a, b, "{precision:?}: simplex {i} decided both ways");
                    if a.crossed() && precision == Some(Precision::F64) {
                        for j in 0..n {
                            worst = worst.max((lambda[i * n + j] - cpu_lambda[i * n + j]).abs());
                        }
                    }
                }
                (a, b) if a != b => differ += 1,
                _ => {}
            }
        }
        eprintln!("{precision:?}: {differ} certain on one side only, lambda within {worst:e}");
        if precision == Some(Precision::F64) {
            // The same arithmetic: at most a rounding apart, so a certainty may flip only
            // at the margin.
            assert!(differ <= count / 10_000, "{differ} verdicts differ");
            assert!(worst <= 1e-12, "lambda differs by {worst:e}");
        }
    }
}

#[test]
fn the_vertex_shader_matches_its_cpu_twin() {
    use isomesh::cpu::vertices::eval_lattice;
    use isomesh::expr::{ImplicitFunction, PRESETS};
    let Some(g) = gpu() else { return };
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
            let got = o.eval_stage(&tri, &lattice).unwrap();
            assert_eq!(got.len(), twin.len());
            let tol = match o.precision() {
                Precision::F64 => 1e-13,
                Precision::F32 => 1e-4,
            };
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
    let Some(g) = gpu() else { return };
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
fn gpu_exhaustive_scans_give_the_cpu_sample_and_topology() {
    let Some(g) = gpu() else { return };
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
        for (name, params, half) in &cases {
            let p = problem(name, params);
            let tri = p.triangulation.build(p.dim()).unwrap();
            // The preset's own box where it has one.
            let bbox = p.bbox.clone().unwrap_or_else(|| cube(p.dim(), *half));
            let opts = TraceOptions {
                bbox: Some(bbox.clone()),
                ..TraceOptions::default()
            };
            let cpu = exhaustive(&p.system, &tri, &CpuOracle::new(&p.system), &opts).unwrap();
            let oracle = GpuOracle::new(gpu().unwrap(), &p.system, precision).unwrap();
            let gpu = exhaustive(&p.system, &tri, &oracle, &opts).unwrap();
            let what = format!("{name} {params:?} {precision:?}");
            assert!(cpu.len() > 10, "{what}: only {} simplices", cpu.len());
            assert_eq!(cpu.sorted_keys(), gpu.sorted_keys(), "{what}: S differs");
            assert_eq!(cpu.stats.oracle_calls, gpu.stats.oracle_calls, "{what}");
            assert_eq!(cpu.stats.components, gpu.stats.components, "{what}");
            assert!(cpu.points() == gpu.points(), "{what}: points differ");
            assert_same_topology(&cpu, &gpu, &p, Some(&bbox), &what);
            assert!(oracle.stats().solved > 0, "{what}: the GPU did nothing");
        }
    }
}

#[test]
fn one_gpu_oracle_serves_several_threads_at_once() {
    let Some(g) = gpu() else { return };
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
