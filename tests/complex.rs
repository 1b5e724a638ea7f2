//! The cell complex: Euler characteristics, manifoldness at two scales, Betti numbers mod 2
//! against each preset's known topology (the library's and, independently, from the ranks
//! of the boundary matrices), boundaries cut by boxes and inequalities, orientation, and
//! clean partial results.

use isomesh::complex::{Complex, Surface, Topology};
use isomesh::expr::{preset, ClosureFunction, ImplicitFunction, Problem};
use isomesh::trace::{trace, CpuOracle, Sample, TraceOptions};
use isomesh::triangulation::Triangulation;

fn problem(name: &str, params: &[(&str, f64)]) -> Problem {
    let params: Vec<(String, f64)> = params.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    preset(name, &params).unwrap()
}

fn sample(p: &Problem) -> Sample {
    let tri = p.triangulation.build(p.dim()).unwrap();
    let oracle = CpuOracle::new(&p.system);
    let opts = TraceOptions {
        seeds: p.seeds.clone(),
        bbox: p.bbox.clone(),
        ..TraceOptions::default()
    };
    trace(&p.system, &tri, &oracle, &opts).unwrap()
}

fn complex(p: &Problem) -> (Sample, Complex, Topology) {
    let s = sample(p);
    let c = Complex::build(&s, &p.system, p.bbox.as_deref()).unwrap();
    let t = c.topology();
    (s, c, t)
}

/// Checks that hold for every complex: every edge with two vertices, every j-cell with more
/// than j facets, facet indices in range, and the boundary of a boundary zero mod 2 (each
/// (j-2)-cell meets the facets of a j-cell an even number of times).
fn assert_well_formed(what: &str, c: &Complex) {
    let counts = c.counts();
    assert_eq!(counts[0], c.vertex_count(), "{what}");
    for j in 1..=c.dim() {
        let level = c.level(j);
        for i in 0..level.len() {
            let f = level.facets(i);
            if j == 1 {
                assert_eq!(f.len(), 2, "{what}: edge {i} has {} ends", f.len());
            } else {
                assert!(f.len() > j, "{what}: {j}-cell {i} has {} facets", f.len());
            }
            assert!(f.iter().all(|&x| (x as usize) < counts[j - 1]), "{what}");
            if j >= 2 {
                let mut faces: Vec<u32> = f
                    .iter()
                    .flat_map(|&x| c.level(j - 1).facets(x as usize).iter().copied())
                    .collect();
                faces.sort_unstable();
                assert!(
                    faces.chunk_by(|a, b| a == b).all(|run| run.len() % 2 == 0),
                    "{what}: the boundary of {j}-cell {i} has a boundary"
                );
            }
        }
    }
}

/// Betti numbers mod 2 straight from the definition, b_j = C_j - rank d_j - rank d_(j+1),
/// with each boundary matrix d_j (j-cells to their facets, over GF(2)) reduced column by
/// column: none of the library's shortcuts (spanning forests, collapses, chi).
fn betti_from_ranks(c: &Complex) -> Vec<usize> {
    let m = c.dim();
    let counts = c.counts();
    let mut rank = vec![0; m + 2];
    for (j, r) in rank.iter_mut().enumerate().take(m + 1).skip(1) {
        let level = c.level(j);
        *r = gf2_rank((0..level.len()).map(|i| level.facets(i).to_vec()));
    }
    (0..=m).map(|j| counts[j] - rank[j] - rank[j + 1]).collect()
}

/// The rank over GF(2) of the matrix whose columns hold the given row indices (an index
/// listed twice cancels): column reduction on the largest index.
fn gf2_rank(columns: impl Iterator<Item = Vec<u32>>) -> usize {
    let mut pivots: std::collections::HashMap<u32, Vec<u32>> = std::collections::HashMap::new();
    for mut col in columns {
        col.sort_unstable();
        col = xor(&col, &[]);
        while let Some(&low) = col.last() {
            match pivots.get(&low) {
                Some(other) => col = xor(&col, other),
                None => break,
            }
        }
        if let Some(&low) = col.last() {
            pivots.insert(low, col);
        }
    }
    pivots.len()
}

/// The sum over GF(2) of two sorted index lists (a may hold repeats, which cancel in pairs).
fn xor(a: &[u32], b: &[u32]) -> Vec<u32> {
    let mut all: Vec<u32> = a.iter().chain(b).copied().collect();
    all.sort_unstable();
    all.chunk_by(|x, y| x == y)
        .filter(|run| run.len() % 2 == 1)
        .map(|run| run[0])
        .collect()
}

/// (preset, parameters at the coarse scale, parameters at the fine scale, chi, Betti mod 2).
type Case = (
    &'static str,
    Vec<(&'static str, f64)>,
    Vec<(&'static str, f64)>,
    i64,
    Vec<usize>,
);

#[test]
fn closed_presets_are_manifolds_with_their_euler_characteristic() {
    let cases: Vec<Case> = vec![
        (
            "circle",
            vec![("edge", 0.1)],
            vec![("edge", 0.02)],
            0,
            vec![1, 1],
        ),
        (
            "sphere",
            vec![("edge", 0.2)],
            vec![("edge", 0.1)],
            2,
            vec![1, 0, 1],
        ),
        (
            "sphere",
            vec![("d", 4.0), ("edge", 0.25)],
            vec![("d", 4.0), ("edge", 0.15)],
            2,
            vec![1, 0, 1],
        ),
        (
            "sphere",
            vec![("d", 5.0), ("edge", 0.3)],
            vec![("d", 5.0), ("edge", 0.2)],
            2,
            vec![1, 0, 1],
        ),
        (
            "sphere",
            vec![("d", 6.0), ("edge", 0.35)],
            vec![("d", 6.0), ("edge", 0.25)],
            2,
            vec![1, 0, 1],
        ),
        (
            "sphere",
            vec![("m", 3.0), ("d", 4.0), ("edge", 0.35)],
            vec![("m", 3.0), ("d", 4.0), ("edge", 0.25)],
            0,
            vec![1, 0, 0, 1],
        ),
        (
            "torus",
            vec![("edge", 0.1)],
            vec![("edge", 0.05)],
            0,
            vec![1, 2, 1],
        ),
        (
            "chair",
            vec![("edge", 0.15)],
            vec![("edge", 0.0707)],
            -4,
            vec![1, 6, 1],
        ),
        (
            "flat-torus",
            vec![("edge", 0.3)],
            vec![("edge", 0.15)],
            0,
            vec![1, 2, 1],
        ),
        (
            "flat-torus",
            vec![("d", 10.0), ("edge", 0.9)],
            vec![("d", 10.0), ("edge", 0.7)],
            0,
            vec![1, 2, 1],
        ),
        (
            "3-torus",
            vec![("a", 0.5), ("b", 0.5), ("c", 0.5), ("edge", 0.7)],
            vec![("a", 0.5), ("b", 0.5), ("c", 0.5), ("edge", 0.5)],
            0,
            vec![1, 3, 3, 1],
        ),
    ];
    for (name, coarse, fine, chi, betti) in cases {
        for (scale, params) in [coarse, fine].into_iter().enumerate() {
            let p = problem(name, &params);
            let what = format!("{name} {params:?}");
            let (s, c, t) = complex(&p);
            assert_well_formed(&what, &c);
            if scale == 0 {
                assert_eq!(betti_from_ranks(&c), betti, "{what}: from the ranks");
            }
            assert_eq!(c.vertex_count(), s.len(), "{what}: closed, so V = |S|");
            assert_eq!(t.euler_characteristic, chi, "{what}: {t:?}");
            assert!(t.manifold && t.offenders.is_empty(), "{what}: {t:?}");
            assert!(
                t.closed && t.boundary_cells.iter().all(|&n| n == 0),
                "{what}"
            );
            assert_eq!(t.components, 1, "{what}");
            assert_eq!(t.betti_mod2.as_ref(), Some(&betti), "{what}");
            if c.dim() == 2 {
                assert_eq!(t.orientable, Some(true), "{what}");
            }
        }
    }
}

#[test]
fn boxes_and_inequalities_cut_a_boundary() {
    // The complex cosine and the Bagel patch are disks cut by their box.
    for (name, edge) in [("complex-cosine", 0.2), ("bagel-klein", 0.3)] {
        let p = problem(name, &[("edge", edge)]);
        let (s, c, t) = complex(&p);
        assert_well_formed(name, &c);
        assert_eq!(betti_from_ranks(&c), [1, 0, 0], "{name}: from the ranks");
        assert!(s.rim_len() > 0, "{name}: no crossing outside the box");
        assert!(t.manifold, "{name}: {t:?}");
        assert!(!t.closed, "{name}");
        assert_eq!(t.euler_characteristic, 1, "{name}: a disk");
        assert_eq!(t.boundary_euler_characteristic, 0, "{name}: a circle");
        assert_eq!(t.boundary_cells[0], t.boundary_cells[1], "{name}");
        assert_eq!(t.betti_mod2, Some(vec![1, 0, 0]), "{name}");
        // Every boundary vertex lies on a face of the box, and every vertex inside it.
        let bbox = p.bbox.as_ref().unwrap();
        for i in 0..c.vertex_count() {
            let x = c.point(i);
            let slack = bbox
                .iter()
                .zip(x)
                .map(|([lo, hi], v)| (v - lo).min(hi - v))
                .fold(f64::INFINITY, f64::min);
            assert!(slack >= -1e-12, "{name}: vertex {i} {x:?} outside the box");
            if i >= c.interior_vertex_count() {
                assert!(
                    slack.abs() < 1e-9,
                    "{name}: boundary vertex {x:?} off the box"
                );
            }
        }
    }
    // The flat torus cut by a ball (paper 000, Figure 8): a torus with a hole.
    let p = problem("cut-flat-torus", &[("edge", 0.3)]);
    let (_, c, t) = complex(&p);
    assert_well_formed("cut-flat-torus", &c);
    assert_eq!(betti_from_ranks(&c), [1, 2, 0], "from the ranks");
    assert!(t.manifold && !t.closed, "{t:?}");
    assert_eq!(t.euler_characteristic, -1);
    assert_eq!(t.boundary_euler_characteristic, 0);
    assert_eq!(t.betti_mod2, Some(vec![1, 2, 0]));
    let mut g = [0.0];
    for i in c.interior_vertex_count()..c.vertex_count() {
        p.system.eval_boundary(c.point(i), &mut g);
        assert!(g[0].abs() < 0.3 * 0.3, "boundary vertex with g = {}", g[0]);
    }
}

/// The rim (crossings outside the domain next to S) as sorted (key, point) pairs.
fn rim(s: &Sample) -> Vec<(Vec<u64>, Vec<u64>)> {
    let mut rim: Vec<_> = (0..s.rim_len())
        .map(|r| {
            let point = s.rim_point(r).iter().map(|x| x.to_bits()).collect();
            (s.rim_key(r).to_vec(), point)
        })
        .collect();
    rim.sort_unstable();
    rim
}

#[test]
fn the_scan_and_the_trace_give_the_same_clipped_complex() {
    let p = problem("complex-cosine", &[("edge", 0.25)]);
    let tri = p.triangulation.build(4).unwrap();
    let oracle = CpuOracle::new(&p.system);
    let opts = TraceOptions {
        bbox: p.bbox.clone(),
        ..TraceOptions::default()
    };
    let scanned = isomesh::trace::exhaustive(&p.system, &tri, &oracle, &opts).unwrap();
    let (traced, c, t) = complex(&p);
    assert_eq!(scanned.sorted_keys(), traced.sorted_keys());
    assert_eq!(rim(&scanned), rim(&traced));
    let c2 = Complex::build(&scanned, &p.system, p.bbox.as_deref()).unwrap();
    let t2 = c2.topology();
    assert_eq!(t.cells, t2.cells);
    assert_eq!(t.boundary_cells, t2.boundary_cells);
    assert!(t2.manifold && t2.euler_characteristic == 1);
    assert_eq!(c.vertex_count(), c2.vertex_count());
}

/// The scan looks for its rim only from the crossings within an edge of a box face (or from
/// all of them when inequalities cut M): it finds the trace's rim, keys and points bit for
/// bit, for boxes that cut M on every side and an inequality.
#[test]
fn the_scan_finds_the_rim_of_the_trace() {
    type Case<'a> = (&'a str, &'a [(&'a str, f64)], Vec<[f64; 2]>);
    let cases: [Case; 4] = [
        // Each cut leaves M in one piece (so that the trace finds all of it). A torus cut by
        // a box on four sides, one face nearly tangent to the tube.
        (
            "torus",
            &[("edge", 0.06)],
            vec![[-0.9, 1.05], [-1.5, 0.7], [-0.21, 0.399]],
        ),
        (
            "sphere",
            &[("edge", 0.05)],
            vec![[-0.8, 0.55], [-1.1, 1.1], [-1.1, 0.3]],
        ),
        // A circle in R^3 (k = 2) cut by a box.
        (
            "sphere",
            &[("m", 1.0), ("d", 3.0), ("edge", 0.04)],
            vec![[-1.2, 0.4], [-0.3, 1.2], [-0.2, 0.2]],
        ),
        // The flat torus inside the box, cut by a ball: every crossing may have a neighbour
        // outside.
        ("cut-flat-torus", &[("edge", 0.3)], vec![[-1.1, 1.1]; 4]),
    ];
    for (name, params, bbox) in cases {
        let p = problem(name, params);
        let tri = p.triangulation.build(p.dim()).unwrap();
        let oracle = CpuOracle::new(&p.system);
        // No seed (some lie outside the box): the search finds every component.
        let opts = TraceOptions {
            bbox: Some(bbox),
            search_samples: Some(4096),
            ..TraceOptions::default()
        };
        let traced = trace(&p.system, &tri, &oracle, &opts).unwrap();
        let scanned = isomesh::trace::exhaustive(&p.system, &tri, &oracle, &opts).unwrap();
        assert_eq!(scanned.sorted_keys(), traced.sorted_keys(), "{name}");
        assert!(traced.rim_len() > 0, "{name}: the box cuts nothing");
        assert_eq!(rim(&scanned), rim(&traced), "{name}");
    }
}

#[test]
fn a_closure_with_an_inequality_gives_a_disk() {
    // The unit sphere cut by z >= 0.3: a cap, a disk bounded by a circle.
    let f = ClosureFunction::new(3, 1, |x, out| {
        out[0] = x[0] * x[0] + x[1] * x[1] + x[2] * x[2] - 1.0
    })
    .unwrap()
    .with_boundary(1, |x, out| out[0] = x[2] - 0.3);
    let tri = Triangulation::coxeter(3)
        .edge(0.1)
        .rotation_seed(3)
        .build()
        .unwrap();
    let opts = TraceOptions {
        seeds: vec![vec![0.0, 0.0, 1.0]],
        ..TraceOptions::default()
    };
    let s = trace(&f, &tri, &CpuOracle::new(&f), &opts).unwrap();
    let c = Complex::build(&s, &f, None).unwrap();
    let t = c.topology();
    assert_well_formed("cap", &c);
    assert_eq!(betti_from_ranks(&c), [1, 0, 0], "the cap from the ranks");
    assert_eq!(t.betti_mod2, Some(vec![1, 0, 0]), "the cap");
    assert!(t.manifold && !t.closed);
    assert_eq!(t.euler_characteristic, 1);
    assert_eq!(t.boundary_euler_characteristic, 0);
    for i in c.interior_vertex_count()..c.vertex_count() {
        let x = c.point(i);
        assert!(
            (x[2] - 0.3).abs() < 1e-12,
            "{x:?} is not on the plane z = 0.3"
        );
    }
    for i in 0..c.interior_vertex_count() {
        assert!(c.point(i)[2] >= 0.3);
    }
}

#[test]
fn surfaces_in_r3_face_along_the_gradient() {
    // Signed volume of the oriented triangles: positive, close to the enclosed volume.
    for (name, params, volume) in [
        (
            "sphere",
            vec![("edge", 0.1)],
            4.0 / 3.0 * std::f64::consts::PI,
        ),
        (
            "torus",
            vec![("edge", 0.05)],
            2.0 * std::f64::consts::PI.powi(2) * 0.4 * 0.4,
        ),
    ] {
        let p = problem(name, &params);
        let (_, c, _) = complex(&p);
        let surf = Surface::new(&c, Some(&p.system));
        assert!(surf.orientable && surf.bad_cells == 0);
        let mut v = 0.0;
        for t in surf.triangles() {
            let [a, b, d] = t.map(|i| c.point(i as usize));
            v += (a[0] * (b[1] * d[2] - b[2] * d[1]) - a[1] * (b[0] * d[2] - b[2] * d[0])
                + a[2] * (b[0] * d[1] - b[1] * d[0]))
                / 6.0;
        }
        assert!(
            (v - volume).abs() < 0.02 * volume,
            "{name}: signed volume {v}, expected {volume}"
        );
        // Every edge between two polygons is walked once each way.
        let mut walks = std::collections::HashMap::new();
        for i in 0..surf.len() {
            let poly = surf.polygon(i);
            for w in 0..poly.len() {
                let e = (poly[w], poly[(w + 1) % poly.len()]);
                *walks.entry(e).or_insert(0) += 1;
            }
        }
        for (&(a, b), &n) in &walks {
            assert_eq!(n, 1, "{name}: edge {a}->{b} walked {n} times");
            assert_eq!(
                walks.get(&(b, a)),
                Some(&1),
                "{name}: {a}->{b} has no reverse"
            );
        }
    }
}

#[test]
fn a_stopped_trace_gives_a_complex_that_says_so() {
    let p = problem("torus", &[("edge", 0.05)]);
    let tri = p.triangulation.build(3).unwrap();
    let oracle = CpuOracle::new(&p.system);
    let opts = TraceOptions {
        seeds: p.seeds.clone(),
        max_memory: 300_000,
        ..TraceOptions::default()
    };
    let s = trace(&p.system, &tri, &oracle, &opts).unwrap();
    assert!(s.stats.stopped.is_some() && !s.is_empty());
    let c = Complex::build(&s, &p.system, None).unwrap();
    let t = c.topology();
    assert!(!t.manifold, "a partial torus passed the manifold check");
    assert!(t.defects > 0 || t.offender_count > 0);
    assert!(t.betti_mod2.is_none());
}

#[test]
fn a_complex_over_the_memory_limit_is_refused() {
    let p = problem("torus", &[("edge", 0.05)]);
    let s = sample(&p);
    let e = Complex::build_within(&s, &p.system, None, 1 << 20).unwrap_err();
    assert!(e.to_string().contains("memory limit"), "{e}");
    assert!(Complex::build_within(&s, &p.system, None, 1 << 30).is_ok());
}

#[test]
fn the_complex_does_not_depend_on_the_thread_count() {
    let p = problem("chair", &[("edge", 0.1)]);
    let build = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let (_, c, _) = complex(&p);
            let s = Surface::new(&c, Some(&p.system));
            (
                c.points().to_vec(),
                (0..s.len())
                    .map(|i| s.polygon(i).to_vec())
                    .collect::<Vec<_>>(),
            )
        })
    };
    let one = build(1);
    for threads in [2, 3, 8, 16] {
        assert!(build(threads) == one, "{threads} threads");
    }
}
