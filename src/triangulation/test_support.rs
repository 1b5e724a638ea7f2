//! Helpers for the unit tests of this module: random simplices and the definitions the code
//! under test is checked against, written the plain way.

use rand::seq::SliceRandom;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::Simplex;

/// A random l-simplex of R^d with base coordinates in `-r..=r`, built from its definition:
/// a random ordered partition of {1..d+1} into l+1 non-empty parts (in any cyclic position;
/// `Simplex::from_masks` brings it to canonical form).
pub(crate) fn random_simplex(rng: &mut ChaCha8Rng, d: usize, l: usize, r: i32) -> Simplex {
    let v0: Vec<i32> = (0..d).map(|_| rng.random_range(-r..=r)).collect();
    Simplex::from_masks(&v0, &random_partition(rng, d, l)).expect("a valid partition")
}

/// A random ordered partition of {1..d+1} (bit j-1 for element j) into l+1 non-empty parts.
pub(crate) fn random_partition(rng: &mut ChaCha8Rng, d: usize, l: usize) -> Vec<u64> {
    let mut elems: Vec<usize> = (0..=d).collect();
    elems.shuffle(rng);
    // l distinct cut points among 1..=d split the shuffled elements into l+1 runs.
    let mut cuts: Vec<usize> = (1..=d).collect();
    cuts.shuffle(rng);
    let mut cuts = cuts[..l].to_vec();
    cuts.sort_unstable();
    cuts.push(d + 1);
    let mut parts = Vec::with_capacity(l + 1);
    let mut start = 0;
    for c in cuts {
        parts.push(elems[start..c].iter().fold(0u64, |m, &e| m | 1 << e));
        start = c;
    }
    parts
}

/// The vertices of the simplex `(v0, parts)` by Definition 13: v_i = v_{i-1} plus the steps
/// e_j of part i, with e_{d+1} = -(e_1 + ... + e_d). `parts` need not be canonical.
pub(crate) fn vertices_by_definition(v0: &[i32], parts: &[u64]) -> Vec<Vec<i32>> {
    let d = v0.len();
    let mut v = v0.to_vec();
    let mut out = vec![v.clone()];
    for &p in &parts[..parts.len() - 1] {
        for j in 0..=d {
            if p >> j & 1 == 1 {
                if j == d {
                    v.iter_mut().for_each(|x| *x -= 1);
                } else {
                    v[j] += 1;
                }
            }
        }
        out.push(v.clone());
    }
    out
}

/// Every ordered partition of {1..d+1} into `n` non-empty parts with d+1 in the last part
/// (canonical), by brute force over part assignments.
pub(crate) fn canonical_partitions(d: usize, n: usize) -> Vec<Vec<u64>> {
    let mut out = Vec::new();
    let total = n.pow(d as u32);
    for code in 0..total {
        let mut parts = vec![0u64; n];
        parts[n - 1] |= 1 << d;
        let mut c = code;
        for e in 0..d {
            parts[c % n] |= 1 << e;
            c /= n;
        }
        if parts.iter().all(|&p| p != 0) {
            out.push(parts);
        }
    }
    out
}

/// Every l-simplex of R^d whose base lies within `r` of `center` in every coordinate.
pub(crate) fn simplices_near(center: &[i32], l: usize, r: i32) -> Vec<Simplex> {
    let d = center.len();
    let partitions = canonical_partitions(d, l + 1);
    let side = (2 * r + 1) as usize;
    let mut out = Vec::new();
    for code in 0..side.pow(d as u32) {
        let mut c = code;
        let base: Vec<i32> = center
            .iter()
            .map(|&x| {
                let off = (c % side) as i32 - r;
                c /= side;
                x + off
            })
            .collect();
        for p in &partitions {
            out.push(Simplex::from_masks(&base, p).expect("a canonical partition"));
        }
    }
    out
}

/// The simplex with vertices `vs` (in order, consecutive ones a step apart), read off their
/// differences: part i holds the elements j with v_{i+1} - v_i = e_j, the last part the rest
/// (with d+1).
pub(crate) fn simplex_from_vertices(vs: &[Vec<i32>]) -> Simplex {
    let d = vs[0].len();
    let mut parts: Vec<u64> = vs
        .windows(2)
        .map(|w| {
            (0..d)
                .filter(|&j| w[1][j] - w[0][j] == 1)
                .fold(0, |m, j| m | 1 << j)
        })
        .collect();
    let used = parts.iter().fold(0u64, |m, p| m | p);
    parts.push((((1u64 << d) - 1) | (1 << d)) & !used);
    Simplex::from_masks(&vs[0], &parts).expect("vertices of a simplex")
}
