//! The f64 fast path ([`Decider::fast_path`]) against the exact decision on 10^7 simplices
//! (k = 1..=8) whose values are integers times powers of two: nearly tied (the origin
//! within 1 / W of a facet), exactly tied, nearly singular (an affine dependence broken by
//! one unit) and uniform. Integer values make the exact reference cheap: fraction-free
//! elimination in checked i128, with the big-integer path of [`exact_lambda_signs`] where
//! i128 would overflow. Each row is then scaled by a random power of two (exact, and it
//! changes no sign of lambda), so exponents span the whole f64 range.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::solve::{exact_lambda_signs, Decider, Status};

/// The exact signs of lambda = L^-1 e_1 for integer values `v` (k + 1 rows of k), by
/// Bareiss elimination of [L | e_1] in i128: `Some(None)` when L is singular, `None` when
/// i128 overflowed.
fn exact_signs_i128(v: &[i64], k: usize) -> Option<Option<Vec<i8>>> {
    let n = k + 1;
    let w = n + 1;
    let mut m = vec![0i128; n * w];
    for j in 0..n {
        m[j] = 1;
        for r in 1..n {
            m[r * w + j] = v[j * k + r - 1] as i128;
        }
    }
    m[n] = 1;
    let mut prev = 1i128;
    for c in 0..n {
        let Some(p) = (c..n).find(|&r| m[r * w + c] != 0) else {
            return Some(None);
        };
        if p != c {
            for t in 0..w {
                m.swap(p * w + t, c * w + t);
            }
        }
        for r in c + 1..n {
            for t in c + 1..w {
                let a = m[c * w + c].checked_mul(m[r * w + t])?;
                let b = m[r * w + c].checked_mul(m[c * w + t])?;
                m[r * w + t] = a.checked_sub(b)? / prev;
            }
            m[r * w + c] = 0;
        }
        prev = m[c * w + c];
    }
    let det = prev;
    let mut y = vec![0i128; n];
    for i in (0..n).rev() {
        let mut acc = det.checked_mul(m[i * w + n])?;
        for j in i + 1..n {
            acc = acc.checked_sub(m[i * w + j].checked_mul(y[j])?)?;
        }
        y[i] = acc / m[i * w + i];
    }
    Some(Some(
        y.iter()
            .map(|&x| (x.signum() * det.signum()) as i8)
            .collect(),
    ))
}

/// The kinds of integer data.
const KINDS: usize = 4;

/// Bits of the integer values for k (the larger k, the fewer, so i128 mostly suffices).
fn bits(k: usize) -> u32 {
    [0, 30, 18, 13, 10, 8, 7, 6, 5].get(k).copied().unwrap_or(4)
}

/// One simplex of `kind` for k: integer values, k + 1 rows of k.
fn integers(kind: usize, k: usize, rng: &mut ChaCha8Rng) -> Vec<i64> {
    let n = k + 1;
    let b = bits(k);
    let mut int = |bits: u32| rng.random_range(-(1i64 << bits)..=(1i64 << bits));
    let mut v: Vec<i64> = (0..n * k).map(|_| int(b)).collect();
    match kind {
        // The origin at lambda = w / W with one weight -1, 0 or 1: F_j = W P_j - sum w_i P_i.
        0 => {
            let h = b / 2;
            let p: Vec<i64> = (0..n * k).map(|_| int(h)).collect();
            let mut wt: Vec<i64> = (0..n).map(|_| rng.random_range(1..=(1i64 << h))).collect();
            wt[rng.random_range(0..n)] = rng.random_range(-1..=1);
            let total: i64 = wt.iter().sum();
            for c in 0..k {
                let centre: i64 = (0..n).map(|i| wt[i] * p[i * k + c]).sum();
                for j in 0..n {
                    v[j * k + c] = total * p[j * k + c] - centre;
                }
            }
        }
        // F_k = F_(k-1) + F_1 - F_0 (L singular) for k >= 2, F_1 = F_0 for k = 1.
        1 => {
            for c in 0..k {
                v[k * k + c] = if k >= 2 {
                    v[(k - 1) * k + c] + v[k + c] - v[c]
                } else {
                    v[c]
                };
            }
        }
        // Small values with zeros and repeats: exact ties and singular faces.
        2 => {
            for x in v.iter_mut() {
                *x = [0, 0, 1, -1, 2, -2, 1 << b][rng.random_range(0..7)];
            }
        }
        _ => {}
    }
    // Break the construction by one unit in one entry, or not.
    if kind < 2 && rng.random_bool(0.5) {
        let e = rng.random_range(0..n * k);
        v[e] += if rng.random_bool(0.5) { 1 } else { -1 };
    }
    v
}

/// What one batch saw.
#[derive(Clone, Copy, Debug, Default)]
struct Tally {
    cases: usize,
    decided: usize,
    /// Cases the big-integer reference decided (i128 overflowed).
    big: usize,
    /// Cases where the signs of the computed lambda alone disagree with the exact ones.
    naive_wrong: usize,
}

fn run(k: usize, kind: usize, cases: usize, seed: u64) -> Tally {
    let n = k + 1;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut d = Decider::new(k);
    let mut lambda = vec![0.0; n];
    let mut t = Tally::default();
    for case in 0..cases {
        let ints = integers(kind, k, &mut rng);
        let mut v: Vec<f64> = ints.iter().map(|&x| x as f64).collect();
        for c in 0..k {
            let s = (rng.random_range(-600..=600) as f64).exp2();
            for j in 0..n {
                v[j * k + c] *= s;
            }
        }
        let signs = match exact_signs_i128(&ints, k) {
            Some(s) => {
                // The i128 reference against the big integers, on a sample.
                if case % 1000 == 0 {
                    assert_eq!(s, exact_lambda_signs(&v, k), "k = {k}, {ints:?}");
                }
                s
            }
            None => {
                t.big += 1;
                exact_lambda_signs(&v, k)
            }
        };
        let crossed = signs.as_ref().is_some_and(|s| s.iter().all(|&x| x == 1));
        let outside = signs.as_ref().is_some_and(|s| s.contains(&-1));
        let got = d.fast_path(&v, &mut lambda);
        t.cases += 1;
        t.decided += got.is_some() as usize;
        t.naive_wrong += (lambda.iter().all(|&l| l > 0.0) != crossed) as usize;
        let ok = match got {
            Some(Status::Crossed) => crossed,
            Some(_) => outside,
            None => true,
        };
        assert!(
            ok,
            "k = {k}, kind {kind}, case {case}: fast path {got:?}, exact signs {signs:?}, \
             values {v:?}"
        );
    }
    t
}

/// [`run`] for every k of `ks` and every kind, `cases` each, in parallel; each tally with
/// its k and kind. The fast path must decide nearly all uniform cases (one that refuses
/// everything is sound but fails here, as does a wrong inverse, whose residual is then too
/// large to certify anything).
fn run_all(ks: std::ops::RangeInclusive<usize>, cases: usize) -> Vec<(usize, usize, Tally)> {
    let jobs: Vec<(usize, usize)> = ks
        .flat_map(|k| (0..KINDS).map(move |kind| (k, kind)))
        .collect();
    let tallies: Vec<(usize, usize, Tally)> = jobs
        .par_iter()
        .map(|&(k, kind)| (k, kind, run(k, kind, cases, (k * 10 + kind) as u64)))
        .collect();
    for &(k, kind, t) in &tallies {
        if kind == 3 {
            assert!(
                t.decided * 100 >= 99 * t.cases,
                "k = {k}, kind {kind}: {t:?}"
            );
        }
    }
    tallies
}

#[test]
fn the_fast_path_is_the_exact_decision_on_ten_million_integer_simplices() {
    const CASES: usize = 312_500; // x 8 k x 4 kinds = 10^7
    let tallies = run_all(1..=8, CASES);
    let total: usize = tallies.iter().map(|t| t.2.cases).sum();
    // The i128 reference decides most (the big integers' share sets the time).
    let big: usize = tallies.iter().map(|t| t.2.big).sum();
    assert!(big * 20 <= total, "{big} of {total} overflowed i128");
    // The built kinds reach the margins: the naive signs are wrong somewhere in each (the
    // uniform kind is the ordinary case).
    for kind in 0..KINDS - 1 {
        let wrong: usize = tallies
            .iter()
            .filter(|t| t.1 == kind)
            .map(|t| t.2.naive_wrong)
            .sum();
        assert!(wrong > 20, "kind {kind}: the naive signs are never wrong");
    }
    for t in &tallies {
        eprintln!("{t:?}");
    }
}

#[test]
fn the_fast_path_above_the_unrolled_sizes_is_the_exact_decision() {
    // n = k + 1 from 10 to 17: the elimination and the certificate's residual go a row at a
    // time there (`UNROLLED_MAX`), not entry by entry.
    let tallies = run_all(9..=16, 400);
    // The near ties are reached at these sizes too.
    let wrong: usize = tallies.iter().map(|t| t.2.naive_wrong).sum();
    assert!(wrong > 0, "the naive signs are never wrong: {tallies:?}");
}
