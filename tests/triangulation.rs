//! Combinatorial identities, point location and geometry of the triangulation core.

use std::collections::HashSet;

use isomesh::linalg::Lu;
use isomesh::triangulation::{KeyCodec, Simplex, Triangulation, TriangulationKind, MAX_DIM};
use isomesh::Error;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// A random ordered partition of {1..d+1} into l+1 parts, as masks, in random cyclic position.
fn random_masks(rng: &mut ChaCha8Rng, d: usize, l: usize) -> Vec<u64> {
    let mut perm: Vec<usize> = (0..=d).collect();
    perm.shuffle(rng);
    let mut cuts: Vec<usize> = (1..=d).collect();
    cuts.shuffle(rng);
    let mut cuts = cuts[..l].to_vec();
    cuts.sort_unstable();
    cuts.push(d + 1);
    let mut parts = Vec::new();
    let mut start = 0;
    for c in cuts {
        parts.push(perm[start..c].iter().fold(0u64, |m, &e| m | 1 << e));
        start = c;
    }
    parts
}

fn random_simplex(rng: &mut ChaCha8Rng, d: usize, l: usize) -> Simplex {
    let v0: Vec<i32> = (0..d).map(|_| rng.random_range(-50..50)).collect();
    Simplex::from_masks(&v0, &random_masks(rng, d, l)).unwrap()
}

/// A random l-simplex of R^d whose parts have at most `max_part` elements.
fn random_simplex_small_parts(rng: &mut ChaCha8Rng, d: usize, l: usize, max_part: u32) -> Simplex {
    loop {
        let s = random_simplex(rng, d, l);
        if s.parts().iter().all(|p| p.count_ones() <= max_part) {
            return s;
        }
    }
}

fn binomial(n: u64, k: u64) -> u64 {
    (0..k).fold(1u64, |acc, i| acc * (n - i) / (i + 1))
}

fn stirling2(n: usize, k: usize) -> u128 {
    let mut s = vec![vec![0u128; k + 1]; n + 1];
    s[0][0] = 1;
    for i in 1..=n {
        for j in 1..=k.min(i) {
            s[i][j] = j as u128 * s[i - 1][j] + s[i - 1][j - 1];
        }
    }
    s[n][k]
}

fn factorial(n: usize) -> u128 {
    (1..=n as u128).product()
}

/// Number of l-cofaces of a simplex with parts of the given sizes: refinements into l+1 parts.
fn coface_count(sizes: &[usize], l: usize) -> u128 {
    // ways[t] = ways to refine the parts seen so far into t parts.
    let mut ways = vec![0u128; l + 2];
    ways[0] = 1;
    for &n in sizes {
        let mut next = vec![0u128; l + 2];
        for (t, &w) in ways.iter().enumerate() {
            if w == 0 {
                continue;
            }
            for a in 1..=n {
                if t + a <= l + 1 {
                    next[t + a] += w * factorial(a) * stirling2(n, a);
                }
            }
        }
        ways = next;
    }
    ways[l + 1]
}

fn vertex_set(s: &Simplex) -> Vec<Vec<i32>> {
    let mut v = s.vertices();
    v.sort();
    v
}

fn dims_under_test() -> Vec<usize> {
    let mut dims: Vec<usize> = (1..=12).collect();
    dims.push(30);
    dims
}

#[test]
fn faces_count_and_are_vertex_subsets() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for d in dims_under_test() {
        for _ in 0..6 {
            let l = rng.random_range(0..=d.min(12));
            let s = random_simplex(&mut rng, d, l);
            let verts = s.vertices();
            for j in 0..=l {
                let faces = s.faces(j).unwrap();
                assert_eq!(faces.len() as u64, binomial(l as u64 + 1, j as u64 + 1));
                let distinct: HashSet<_> = faces.iter().collect();
                assert_eq!(distinct.len(), faces.len(), "faces repeat for {s}, j={j}");
                // Faces come in lexicographic order of the vertex subsets they keep.
                let mut subset: Vec<usize> = (0..=j).collect();
                for f in &faces {
                    assert_eq!(f.dim(), j);
                    let expected: Vec<Vec<i32>> =
                        subset.iter().map(|&m| verts[m].clone()).collect();
                    assert_eq!(f.vertices(), expected, "face {f} of {s}");
                    // advance subset
                    let mut i = j as isize;
                    while i >= 0 && subset[i as usize] == l - j + i as usize {
                        i -= 1;
                    }
                    if i >= 0 {
                        subset[i as usize] += 1;
                        for t in i as usize + 1..=j {
                            subset[t] = subset[t - 1] + 1;
                        }
                    }
                }
            }
            if l > 0 {
                let facets = s.facets();
                let via_faces: HashSet<_> = s.faces(l - 1).unwrap().into_iter().collect();
                assert_eq!(facets.len(), l + 1);
                assert!(facets.iter().all(|f| via_faces.contains(f)));
            }
        }
    }
}

#[test]
fn cofacets_count_and_contain_the_simplex() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for d in dims_under_test() {
        for _ in 0..8 {
            let l = rng.random_range(0..d);
            let s = if d > 12 {
                let l = rng.random_range(20..d);
                random_simplex_small_parts(&mut rng, d, l, 4)
            } else {
                random_simplex(&mut rng, d, l)
            };
            let expected: u64 = s.parts().iter().map(|p| (1u64 << p.count_ones()) - 2).sum();
            let cofacets = s.cofacets();
            assert_eq!(cofacets.len() as u64, expected);
            assert_eq!(s.cofacet_count(), expected);
            let distinct: HashSet<_> = cofacets.iter().cloned().collect();
            assert_eq!(distinct.len(), cofacets.len());
            let via_cofaces: HashSet<_> = s.cofaces(s.dim() + 1).unwrap().into_iter().collect();
            assert_eq!(via_cofaces, distinct);
            for c in &cofacets {
                assert_eq!(c.dim(), s.dim() + 1);
                assert!(
                    c.facets().contains(&s),
                    "{s} not a facet of its cofacet {c}"
                );
            }
        }
    }
}

#[test]
fn facets_by_index_and_cofacet_apexes_keep_the_vertex_order() {
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    for d in dims_under_test() {
        for _ in 0..8 {
            let l = rng.random_range(0..d.min(12));
            let s = if d > 12 {
                let l = rng.random_range(20..d);
                random_simplex_small_parts(&mut rng, d, l, 4)
            } else {
                random_simplex(&mut rng, d, l)
            };
            let verts = s.vertices();
            let mut count = 0;
            s.for_each_cofacet_apex(|c, p| {
                count += 1;
                let mut cv = c.vertices();
                assert!(
                    !verts.contains(&cv[p]),
                    "apex {p} of {c} is a vertex of {s}"
                );
                cv.remove(p);
                assert_eq!(cv, verts, "{c} without its vertex {p} is not {s} in order");
                let mut scratch = Simplex::vertex(&vec![0; d]).unwrap();
                for (q, f) in c.facets().iter().enumerate() {
                    c.facet_into(q, &mut scratch);
                    assert_eq!(&scratch, f, "facet {q} of {c}");
                    let mut fv = c.vertices();
                    fv.remove(q);
                    assert_eq!(scratch.vertices(), fv);
                }
            });
            assert_eq!(count as u64, s.cofacet_count());
        }
    }
}

#[test]
fn cofaces_count_and_relations_agree_both_ways() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for d in dims_under_test() {
        for _ in 0..5 {
            // Parts of at most 3 elements keep the coface counts small: k + 1 >= (d + 1) / 3.
            let k = if d > 12 {
                26
            } else {
                rng.random_range((d + 1).div_ceil(3) - 1..=d)
            };
            let s = random_simplex_small_parts(&mut rng, d, k, 3);
            let sizes: Vec<usize> = s.parts().iter().map(|p| p.count_ones() as usize).collect();
            for l in k..=d {
                let cofaces = s.cofaces(l).unwrap();
                assert_eq!(cofaces.len() as u128, coface_count(&sizes, l), "{s}, l={l}");
                let distinct: HashSet<_> = cofaces.iter().collect();
                assert_eq!(distinct.len(), cofaces.len());
                let mine = vertex_set(&s);
                for c in cofaces.iter().take(200) {
                    // s is a face of each coface, and its vertices are among the coface's.
                    assert!(c.faces(k).unwrap().contains(&s), "{s} not a face of {c}");
                    let theirs = vertex_set(c);
                    assert!(mine.iter().all(|v| theirs.contains(v)));
                }
            }
            // Each j-face of s has s among its k-cofaces.
            for j in 0..=k.min(4) {
                for f in s.faces(j).unwrap().iter().take(20) {
                    let fsizes: Vec<usize> =
                        f.parts().iter().map(|p| p.count_ones() as usize).collect();
                    if coface_count(&fsizes, k) < 200_000 {
                        assert!(f.cofaces(k).unwrap().contains(&s), "{f} / {s}");
                    }
                }
            }
        }
    }
}

#[test]
fn star_of_a_vertex_has_ordered_partition_counts() {
    for d in 1..=7 {
        let v = Simplex::vertex(&vec![3; d]).unwrap();
        let mut total_d = 0;
        for l in 0..=d {
            let mut set = HashSet::new();
            v.for_each_coface(l, |c| {
                set.insert(c.clone());
            })
            .unwrap();
            let expected = factorial(l + 1) * stirling2(d + 1, l + 1);
            assert_eq!(set.len() as u128, expected, "d={d}, l={l}");
            if l == d {
                total_d = set.len();
            }
        }
        assert_eq!(total_d as u128, factorial(d + 1));
    }
}

/// Cyclic shift of Definition 14, written out with explicit vectors.
fn cyclic_shift(v0: &[i32], parts: &[u64], k: usize) -> (Vec<i32>, Vec<u64>) {
    let d = v0.len();
    let mut v = v0.to_vec();
    for p in &parts[..k] {
        for e in 0..=d {
            if p & (1 << e) != 0 {
                if e == d {
                    v.iter_mut().for_each(|x| *x -= 1);
                } else {
                    v[e] += 1;
                }
            }
        }
    }
    let mut rotated = parts.to_vec();
    rotated.rotate_left(k);
    (v, rotated)
}

#[test]
fn keys_round_trip_at_every_width() {
    // Widths that do not divide 64 put coordinates across word boundaries.
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    for bits in 2..=32u32 {
        for d in [1, 2, 3, 5, 8, 13, 30] {
            let l = rng.random_range(0..=d);
            let codec = KeyCodec::new(d, l, bits).unwrap();
            let (lo, hi) = (-(1i64 << (bits - 1)), (1i64 << (bits - 1)) - 1);
            let mut key = vec![0u64; codec.words()];
            for _ in 0..20 {
                // Extremes of the range as well as values inside it.
                let v0: Vec<i32> = (0..d)
                    .map(|_| match rng.random_range(0..4) {
                        0 => lo as i32,
                        1 => hi as i32,
                        _ => rng.random_range(lo..=hi) as i32,
                    })
                    .collect();
                let mut back = vec![0i32; d];
                codec.encode_vertex(&v0, &mut key).unwrap();
                codec.decode_vertex(&key, &mut back);
                assert_eq!(back, v0, "bits {bits}, d {d}");
            }
            for _ in 0..20 {
                // Canonical form may move the base by one step per coordinate.
                let v0: Vec<i32> = (0..d)
                    .map(|_| rng.random_range(lo + 1..hi) as i32)
                    .collect();
                let s = Simplex::from_masks(&v0, &random_masks(&mut rng, d, l)).unwrap();
                codec.encode(&s, &mut key).unwrap();
                assert_eq!(codec.decode(&key), s, "bits {bits}, d {d}");
            }
            // One coordinate just out of range, either side.
            for bad in [lo - 1, hi + 1] {
                if bad < i32::MIN as i64 || bad > i32::MAX as i64 {
                    continue;
                }
                let mut v = vec![0i32; d];
                v[d - 1] = bad as i32;
                assert!(matches!(
                    codec.encode_vertex(&v, &mut key),
                    Err(Error::KeyOverflow { value, bits: b }) if value == bad && b == bits
                ));
            }
        }
    }
}

#[test]
fn cyclic_shifts_share_one_canonical_key() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for d in dims_under_test() {
        for _ in 0..10 {
            let l = rng.random_range(0..=d);
            let v0: Vec<i32> = (0..d).map(|_| rng.random_range(-1000..1000)).collect();
            let parts = random_masks(&mut rng, d, l);
            let reference = Simplex::from_masks(&v0, &parts).unwrap();
            let codec = KeyCodec::new(d, l, 16).unwrap();
            let mut key = vec![0u64; codec.words()];
            codec.encode(&reference, &mut key).unwrap();
            assert_eq!(codec.decode(&key), reference);
            let mut other = vec![0u64; codec.words()];
            for k in 0..=l {
                let (v, p) = cyclic_shift(&v0, &parts, k);
                let s = Simplex::from_masks(&v, &p).unwrap();
                assert_eq!(s, reference);
                codec.encode(&s, &mut other).unwrap();
                assert_eq!(other, key);
                assert_eq!(vertex_set(&s), vertex_set(&reference));
            }
            // The canonical base is the lexicographically smallest vertex.
            assert_eq!(reference.base(), vertex_set(&reference)[0].as_slice());
        }
    }
}

fn triangulations(d: usize) -> Vec<Triangulation> {
    vec![
        Triangulation::freudenthal(d).edge(0.3).build().unwrap(),
        Triangulation::coxeter(d).edge(0.3).build().unwrap(),
        Triangulation::coxeter(d)
            .edge(0.17)
            .offset_seed(9)
            .rotation_seed(5)
            .build()
            .unwrap(),
        Triangulation::freudenthal(d)
            .edge(0.4)
            .offset((0..d).map(|i| 0.1 * i as f64).collect())
            .rotation_seed(6)
            .build()
            .unwrap(),
    ]
}

/// Barycentric coordinates of x in the d-simplex s.
fn barycentric(t: &Triangulation, s: &Simplex, x: &[f64]) -> Vec<f64> {
    let d = t.dim();
    let p = t.simplex_coords(s);
    let mut m = vec![0.0; d * d];
    for r in 0..d {
        for c in 0..d {
            m[r * d + c] = p[(c + 1) * d + r] - p[r];
        }
    }
    let mut rhs: Vec<f64> = (0..d).map(|r| x[r] - p[r]).collect();
    Lu::new(&m, d).unwrap().solve(&mut rhs);
    let mut lambda = vec![1.0 - rhs.iter().sum::<f64>()];
    lambda.extend(rhs);
    lambda
}

#[test]
fn point_location_finds_the_containing_simplex() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for d in (1..=12).chain([30]) {
        for t in triangulations(d) {
            for _ in 0..20 {
                let x: Vec<f64> = (0..d).map(|_| rng.random_range(-3.0..3.0)).collect();
                let s = t.locate(&x).unwrap();
                assert_eq!(s.dim(), d, "a random point lies inside a d-simplex");
                let lambda = barycentric(&t, &s, &x);
                let worst = lambda.iter().cloned().fold(f64::INFINITY, f64::min);
                assert!(worst >= -1e-9, "{:?}: barycentric {worst} in {s}", t.kind());
            }
        }
    }
}

#[test]
fn points_on_lower_dimensional_faces_are_located_on_them() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    for d in (1..=12).chain([30]) {
        // Exact: FK unscaled, no offset, dyadic weights.
        let fk = Triangulation::freudenthal(d)
            .edge((d as f64).sqrt())
            .offset(vec![0.0; d])
            .build()
            .unwrap();
        for t in triangulations(d).into_iter().chain([fk.clone()]) {
            for _ in 0..10 {
                let l = rng.random_range(0..=d);
                let s = random_simplex(&mut rng, d, l);
                let p = t.simplex_coords(&s);
                let mut x = vec![0.0; d];
                let mut w: Vec<f64> = (0..=l).map(|_| rng.random_range(0.5..1.5)).collect();
                let sum: f64 = w.iter().sum();
                w.iter_mut().for_each(|x| *x /= sum);
                for (i, wi) in w.iter().enumerate() {
                    for c in 0..d {
                        x[c] += wi * p[i * d + c];
                    }
                }
                let found = t.locate_with_tolerance(&x, 1e-9).unwrap();
                assert_eq!(found, s, "{:?} d={d}", t.kind());
            }
        }
        // Exact location (no tolerance) on FK with dyadic barycentres.
        for _ in 0..10 {
            let l = [0usize, 1, 3, 7].into_iter().rfind(|&l| l <= d).unwrap();
            let s = random_simplex(&mut rng, d, l);
            let p = fk.simplex_coords(&s);
            let x: Vec<f64> = (0..d)
                .map(|c| (0..=l).map(|i| p[i * d + c]).sum::<f64>() / (l + 1) as f64)
                .collect();
            assert_eq!(fk.locate(&x).unwrap(), s);
        }
    }
}

fn sorted_edges(t: &Triangulation, s: &Simplex) -> Vec<f64> {
    let d = t.dim();
    let p = t.simplex_coords(s);
    let mut e = Vec::new();
    for i in 0..=s.dim() {
        for j in i + 1..=s.dim() {
            let len: f64 = (0..d)
                .map(|c| (p[i * d + c] - p[j * d + c]).powi(2))
                .sum::<f64>()
                .sqrt();
            e.push(len);
        }
    }
    e.sort_by(f64::total_cmp);
    e
}

#[test]
fn coxeter_simplices_are_congruent_with_the_requested_edge() {
    for d in 2..=8 {
        let t = Triangulation::coxeter(d)
            .edge(0.25)
            .rotation_seed(3)
            .build()
            .unwrap();
        let origin = Simplex::vertex(&vec![0; d]).unwrap();
        let mut reference: Option<Vec<f64>> = None;
        let mut count = 0;
        origin
            .for_each_coface(d, |s| {
                count += 1;
                let e = sorted_edges(&t, s);
                match &reference {
                    None => reference = Some(e),
                    Some(r) => {
                        for (a, b) in r.iter().zip(&e) {
                            assert!((a - b).abs() < 1e-12, "d={d}: {r:?} vs {e:?}");
                        }
                    }
                }
            })
            .unwrap();
        assert_eq!(count as u128, factorial(d + 1));
        let longest = *reference.unwrap().last().unwrap();
        assert!((longest - 0.25).abs() < 1e-12);
    }
    // Freudenthal-Kuhn simplices are not all congruent in general, but their longest edge is
    // the cube diagonal, set by `edge`.
    let fk = Triangulation::freudenthal(3).edge(0.5).build().unwrap();
    let s = fk.locate(&[0.11, 0.52, 0.33]).unwrap();
    assert!((sorted_edges(&fk, &s).last().unwrap() - 0.5).abs() < 1e-12);
}

/// Circumcentre of a d-simplex with vertices p (rows).
fn circumcentre(p: &[f64], d: usize) -> Vec<f64> {
    // 2 (p_i - p_0) . c = |p_i|^2 - |p_0|^2
    let mut m = vec![0.0; d * d];
    let mut rhs = vec![0.0; d];
    let n0: f64 = p[..d].iter().map(|x| x * x).sum();
    for i in 1..=d {
        for c in 0..d {
            m[(i - 1) * d + c] = 2.0 * (p[i * d + c] - p[c]);
        }
        rhs[i - 1] = p[i * d..(i + 1) * d].iter().map(|x| x * x).sum::<f64>() - n0;
    }
    Lu::new(&m, d).unwrap().solve(&mut rhs);
    rhs
}

#[test]
fn coxeter_is_delaunay() {
    for d in 2..=5 {
        let t = Triangulation::coxeter(d)
            .edge(1.0)
            .offset(vec![0.0; d])
            .build()
            .unwrap();
        // Lattice points of the cube [-2, 2]^d, which holds the star of the origin with margin.
        let mut lattice = Vec::new();
        let side = 5i32;
        for mut n in 0..side.pow(d as u32) {
            let mut v = vec![0i32; d];
            for x in v.iter_mut() {
                *x = n % side - 2;
                n /= side;
            }
            let mut coords = vec![0.0; d];
            t.vertex_coords(&v, &mut coords);
            lattice.push(coords);
        }
        let origin = Simplex::vertex(&vec![0; d]).unwrap();
        let mut min_gap = f64::INFINITY;
        origin
            .for_each_coface(d, |s| {
                let p = t.simplex_coords(s);
                let c = circumcentre(&p, d);
                let r2: f64 = (0..d).map(|i| (p[i] - c[i]).powi(2)).sum();
                for q in &lattice {
                    let dist2: f64 = (0..d).map(|i| (q[i] - c[i]).powi(2)).sum();
                    let gap = dist2 - r2;
                    assert!(
                        gap > -1e-9,
                        "d={d}: a vertex inside the circumsphere of {s}"
                    );
                    if gap > 1e-9 {
                        min_gap = min_gap.min(gap);
                    }
                }
            })
            .unwrap();
        assert!(min_gap.is_finite());
    }
}

#[test]
fn custom_matrix_reproduces_a_given_triangulation() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for d in [2, 3, 5, 9] {
        let cox = Triangulation::coxeter(d)
            .edge(0.3)
            .offset_seed(4)
            .build()
            .unwrap();
        let a = cox.matrix();
        let rows: Vec<Vec<f64>> = (0..d).map(|r| a[r * d..(r + 1) * d].to_vec()).collect();
        let custom = Triangulation::custom(rows)
            .offset(cox.offset().to_vec())
            .build()
            .unwrap();
        assert_eq!(custom.kind(), TriangulationKind::Custom);
        for _ in 0..50 {
            let x: Vec<f64> = (0..d).map(|_| rng.random_range(-2.0..2.0)).collect();
            let s = cox.locate(&x).unwrap();
            assert_eq!(custom.locate(&x).unwrap(), s);
            let (p, q) = (cox.simplex_coords(&s), custom.simplex_coords(&s));
            for (a, b) in p.iter().zip(&q) {
                assert!((a - b).abs() < 1e-12);
            }
        }
    }
}

#[test]
fn bad_input_gets_typed_errors() {
    assert!(matches!(
        Simplex::vertex(&[]).unwrap_err(),
        Error::Dimension(0)
    ));
    assert!(matches!(
        Simplex::vertex(&vec![0; MAX_DIM + 1]).unwrap_err(),
        Error::Dimension(d) if d == MAX_DIM + 1
    ));
    assert!(Simplex::vertex(&vec![0; MAX_DIM]).is_ok());
    assert!(matches!(
        Triangulation::coxeter(0).build(),
        Err(Error::Dimension(0))
    ));
    assert!(matches!(
        Triangulation::coxeter(70).build(),
        Err(Error::Dimension(70))
    ));
    let t = Triangulation::coxeter(3).build().unwrap();
    assert!(matches!(
        t.locate(&[0.0, f64::NAN, 1.0]),
        Err(Error::NonFinite { index: 1, .. })
    ));
    assert!(matches!(
        t.locate(&[0.0, 1.0]),
        Err(Error::DimensionMismatch(_))
    ));
    assert!(matches!(
        Triangulation::coxeter(3).edge(-1.0).build(),
        Err(Error::Triangulation(_))
    ));
    assert!(matches!(
        Triangulation::coxeter(3).edge(f64::INFINITY).build(),
        Err(Error::Triangulation(_))
    ));
    assert!(matches!(
        Triangulation::custom(vec![vec![1.0, 2.0], vec![2.0, 4.0]]).build(),
        Err(Error::Triangulation(_))
    ));
    assert!(matches!(
        Triangulation::custom(vec![vec![1.0, 2.0], vec![2.0]]).build(),
        Err(Error::DimensionMismatch(_))
    ));
    let s = Simplex::from_parts(&[0, 0], &[vec![1], vec![2, 3]]).unwrap();
    assert!(matches!(s.faces(2), Err(Error::InvalidSimplex(_))));
    assert!(matches!(s.cofaces(0), Err(Error::InvalidSimplex(_))));
    assert!(matches!(s.cofaces(3), Err(Error::InvalidSimplex(_))));
    for bad in [
        vec![vec![1], vec![2]],
        vec![vec![1], vec![1, 2, 3]],
        vec![vec![1, 4], vec![2, 3]],
        vec![vec![1, 2, 3], vec![]],
    ] {
        assert!(matches!(
            Simplex::from_parts(&[0, 0], &bad),
            Err(Error::InvalidSimplex(_))
        ));
    }
    let codec = KeyCodec::new(2, 1, 8).unwrap();
    let far = Simplex::from_parts(&[200, 0], &[vec![1], vec![2, 3]]).unwrap();
    let mut key = vec![0; codec.words()];
    assert!(matches!(
        codec.encode(&far, &mut key),
        Err(Error::KeyOverflow {
            value: 200,
            bits: 8
        })
    ));
    let vertex = Simplex::vertex(&[0, 0]).unwrap();
    assert!(matches!(
        codec.encode(&vertex, &mut key),
        Err(Error::InvalidSimplex(_))
    ));
}

#[test]
fn vertex_coordinates_in_batches_are_those_of_one_vertex_at_a_time_bit_for_bit() {
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    for d in 1..=10 {
        for kind in [TriangulationKind::Coxeter, TriangulationKind::Freudenthal] {
            for rotation in [None, Some(3)] {
                let mut b = Triangulation::builder(d, kind).edge(0.0173).offset_seed(5);
                if let Some(seed) = rotation {
                    b = b.rotation_seed(seed);
                }
                let t = b.build().unwrap();
                // Zeros (signed zeros in the products), small and large coordinates.
                let lattice: Vec<i32> = (0..200 * d)
                    .map(|i| match i % 5 {
                        0 => 0,
                        1 => rng.random_range(-3..=3),
                        _ => rng.random_range(-(1 << 20)..=(1 << 20)),
                    })
                    .collect();
                let mut batch = vec![f64::NAN; lattice.len()];
                t.vertices_coords(&lattice, &mut batch);
                for (v, x) in lattice.chunks_exact(d).zip(batch.chunks_exact(d)) {
                    let mut one = vec![0.0; d];
                    t.vertex_coords(v, &mut one);
                    let bits = |p: &[f64]| p.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
                    assert_eq!(
                        bits(x),
                        bits(&one),
                        "d {d}, {kind:?}, rotation {rotation:?}"
                    );
                }
            }
        }
    }
}
