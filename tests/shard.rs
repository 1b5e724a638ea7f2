//! Sharded scans: the parts of a box's shards assemble into exactly the whole box's scan,
//! its keys, points (bit for bit) and cell complex (every facet list, in the same order),
//! whatever the cuts; a part missing, doubled or with too narrow a halo is an error.

use isomesh::complex::Complex;
use isomesh::shard::{self, Part, Shard};
use isomesh::Mesher;

fn mesher(name: &str, params: &[(&str, f64)], edge: f64, whole: &[[f64; 2]]) -> Mesher {
    let params: Vec<(String, f64)> = params.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    Mesher::preset(name, &params)
        .unwrap()
        .edge(edge)
        .bbox(whole.to_vec())
}

fn parts(m: &Mesher, shards: &[Shard]) -> Vec<Part> {
    parts_with(m, shards, shard::default_halo(m).unwrap())
}

fn parts_with(m: &Mesher, shards: &[Shard], halo: f64) -> Vec<Part> {
    shards
        .iter()
        .map(|s| shard::scan(m, s, halo).unwrap())
        .collect()
}

/// Every vertex, every cell and its facets, and the interior/boundary split.
fn assert_same_complex(what: &str, a: &Complex, b: &Complex) {
    assert_eq!(a.counts(), b.counts(), "{what}: cell counts");
    assert_eq!(
        a.interior_vertex_count(),
        b.interior_vertex_count(),
        "{what}"
    );
    let bits = |c: &Complex| c.points().iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert!(bits(a) == bits(b), "{what}: vertex coordinates differ");
    for j in 1..=a.dim() {
        let (la, lb) = (a.level(j), b.level(j));
        assert_eq!(la.interior(), lb.interior(), "{what}: interior {j}-cells");
        for i in 0..la.len() {
            assert_eq!(la.facets(i), lb.facets(i), "{what}: facets of {j}-cell {i}");
        }
    }
    assert_eq!(a.stats.defects, b.stats.defects, "{what}: defects");
}

/// The assembled scan equals the single scan of the whole box.
fn check(what: &str, m: &Mesher, cuts: &[Vec<f64>]) -> usize {
    check_with(what, m, cuts, shard::default_halo(m).unwrap())
}

fn check_with(what: &str, m: &Mesher, cuts: &[Vec<f64>], halo: f64) -> usize {
    let whole = m.domain_box().unwrap().to_vec();
    let shards = shard::grid(&whole, cuts).unwrap();
    let all = shard::assemble(&parts_with(m, &shards, halo)).unwrap();
    let single = m.scan().unwrap();
    let s = single.sample();
    let keys: Vec<u64> = (0..s.len()).flat_map(|i| s.key(i).to_vec()).collect();
    assert_eq!(all.key_words, s.codec().words(), "{what}");
    assert!(all.keys == keys, "{what}: keys differ");
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert!(
        bits(&all.points) == bits(&s.points()),
        "{what}: points differ"
    );
    let c = single.complex().unwrap();
    assert_same_complex(what, &all.complex, c);
    assert_eq!(
        serde_json::to_value(all.complex.topology()).unwrap(),
        serde_json::to_value(c.topology()).unwrap(),
        "{what}: topology"
    );
    s.len()
}

#[test]
fn sharded_scans_assemble_into_the_whole_scan() {
    // (preset, parameters, edge, box)
    type Case<'a> = (&'a str, Vec<(&'a str, f64)>, f64, Vec<[f64; 2]>);
    let cases: Vec<Case> = vec![
        ("sphere", vec![], 0.15, vec![[-1.3, 1.3]; 3]),
        // The box cuts the sphere: boundary cells on its faces.
        (
            "sphere",
            vec![],
            0.15,
            vec![[-1.3, 0.55], [-0.8, 1.3], [-1.3, 1.3]],
        ),
        (
            "torus",
            vec![],
            0.12,
            vec![[-1.5, 1.5], [-1.5, 1.5], [-0.5, 0.5]],
        ),
        ("flat-torus", vec![], 0.35, vec![[-1.2, 1.2]; 4]),
    ];
    for (name, params, edge, whole) in &cases {
        let m = mesher(name, params, *edge, whole);
        let d = whole.len();
        for n in [1, 2, 5, 8] {
            let counts = shard::split_count(whole, n);
            assert_eq!(counts.iter().product::<usize>(), n);
            let what = format!("{name} in {whole:?}, {n} shards {counts:?}");
            let found = check(&what, &m, &shard::uniform_cuts(whole, &counts));
            assert!(found > 100, "{what}: only {found} simplices");
        }
        // Uneven cuts on every axis.
        let cuts: Vec<Vec<f64>> = (0..d)
            .map(|a| {
                let [lo, hi] = whole[a];
                vec![lo + 0.37 * (hi - lo), lo + 0.41 * (hi - lo)]
            })
            .collect();
        check(&format!("{name}, uneven cuts"), &m, &cuts);
        // The narrowest halo allowed, one edge, is enough.
        let edge = m.build_triangulation().unwrap().edge();
        let cuts = shard::uniform_cuts(whole, &shard::split_count(whole, 8));
        check_with(&format!("{name}, a halo of one edge"), &m, &cuts, edge);
    }
}

#[test]
fn cuts_through_crossings_and_lattice_vertices_lose_nothing() {
    let whole = vec![[-1.3, 1.3]; 3];
    let m = mesher("sphere", &[], 0.15, &whole);
    let single = m.scan().unwrap();
    let pts = single.sample().points();
    // Cuts at a crossing's coordinate exactly, and 1e-12 on either side of others.
    let x = |i: usize, a: usize| pts[i * 3 + a];
    let n = single.len();
    let cuts = |c: Vec<f64>| {
        let mut c = c;
        c.sort_by(f64::total_cmp);
        c.dedup();
        c
    };
    let through = vec![
        cuts(vec![x(n / 3, 0), x(n / 2, 0) + 1e-12]),
        cuts(vec![x(n / 5, 1) - 1e-12]),
        cuts(vec![x(n / 7, 2), x(2 * n / 3, 2) + 1e-12]),
    ];
    check("cuts through crossings", &m, &through);
    // Cuts through lattice vertices: the corners of crossed simplices.
    let tri = m.build_triangulation().unwrap();
    let s = single.sample();
    let mut corner = vec![0.0; 3];
    let (simplex, _) = s.iter().nth(n / 4).unwrap();
    tri.vertex_coords(simplex.base(), &mut corner);
    let lattice = vec![vec![corner[0]], vec![corner[1]], vec![corner[2]]];
    check("cuts through lattice vertices", &m, &lattice);
}

#[test]
fn a_missing_or_doubled_part_and_a_narrow_halo_are_errors() {
    let whole = vec![[-1.3, 1.3]; 3];
    let m = mesher("sphere", &[], 0.2, &whole);
    let shards = shard::grid(&whole, &shard::uniform_cuts(&whole, &[2, 2, 1])).unwrap();
    let mut p = parts(&m, &shards);
    let doubled = [p.clone(), vec![p[0].clone()]].concat();
    let e = shard::assemble(&doubled).unwrap_err().to_string();
    assert!(e.contains("overlap"), "{e}");
    p.remove(1);
    let e = shard::assemble(&p).unwrap_err().to_string();
    assert!(e.contains("owned by no shard"), "{e}");
    let edge = m.build_triangulation().unwrap().edge();
    let e = shard::scan(&m, &shards[0], 0.5 * edge)
        .unwrap_err()
        .to_string();
    assert!(e.contains("halo"), "{e}");
    // Cuts outside the box or out of order.
    assert!(shard::grid(&whole, &[vec![2.0], vec![], vec![]]).is_err());
    assert!(shard::grid(&whole, &[vec![0.5, 0.1], vec![], vec![]]).is_err());
}

#[test]
fn ownership_is_half_open_and_closed_at_the_upper_faces() {
    let whole = vec![[0.0, 1.0]; 2];
    let shards = shard::grid(&whole, &[vec![0.5], vec![]]).unwrap();
    assert_eq!(shards.len(), 2);
    let owners = |x: &[f64]| shards.iter().filter(|s| s.owns(x)).count();
    for x in [
        [0.0, 0.0],
        [0.5, 0.5],
        [1.0, 1.0],
        [0.5 - 1e-16, 1.0],
        [0.25, 0.75],
    ] {
        assert_eq!(owners(&x), 1, "{x:?}");
    }
    assert!(shards[1].owns(&[0.5, 0.2]) && !shards[0].owns(&[0.5, 0.2]));
    assert_eq!(owners(&[1.0 + 1e-15, 0.5]), 0);
    assert_eq!(shard::split_count(&[[0.0, 4.0], [0.0, 1.0]], 8), vec![8, 1]);
    assert_eq!(shard::split_count(&[[0.0, 1.0]; 3], 8), vec![2, 2, 2]);
    assert_eq!(shard::split_count(&[[0.0, 1.0]; 3], 5), vec![5, 1, 1]);
}
