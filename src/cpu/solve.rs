// Index loops read as the textbook elimination they are.
#![allow(clippy::needless_range_loop)]
//! The intersection test for one k-simplex, in f64 with a certified fast path and an exact
//! fallback.
//!
//! With vertex values F_0..F_k (each in R^k) the labelling matrix is L = [1 .. 1; F_0 .. F_k].
//! The simplex is crossed iff L is nonsingular and L^-1 is lexicographically positive (every
//! row's first non-zero entry is > 0): the completely-labelled test of PL continuation. Its
//! first column is lambda, the barycentric coordinates of the crossing point; the other
//! columns only matter for exact ties (a lambda_i that is exactly 0), where they break the tie
//! as if f were shifted by (eps, eps^2, .., eps^k). With that rule every (k+1)-simplex has 0
//! or 2 crossed facets, even when f vanishes exactly at lattice vertices.
//!
//! Fast path: Gauss-Jordan inversion with partial pivoting in f64, then the a-posteriori
//! certificate of [`super::certificate`] with no entry bounds: a proof, from the residual and
//! a bound on ||I - R L|| computed with directed margins, that every lambda_i has the sign
//! the computed one has. A decision is taken when every sign it needs is proven. Otherwise
//! the same test runs in exact rational arithmetic on the f64 values, so that the decision
//! is always the exact one for the values given.

use num_bigint::BigInt;
use num_traits::{Float, One, Signed, ToPrimitive, Zero};

use super::certificate::{certify_exact, gauss_jordan, Margins, CROSSED, OUTSIDE};
use crate::linalg::pow2_inverse;

/// The verdict on one k-simplex.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum Status {
    /// Completely labelled: M crosses the simplex; lambda holds the crossing point.
    Crossed = 0,
    /// Not crossed.
    Outside = 1,
    /// L is singular (exactly, for the values given): not crossed.
    Degenerate = 2,
    /// A vertex value is NaN or infinite: not crossed.
    NonFinite = 3,
}

impl Status {
    /// Whether the simplex is crossed.
    #[inline]
    pub fn crossed(self) -> bool {
        self == Status::Crossed
    }
}

/// A decision and how it was reached.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Decision {
    /// The verdict.
    pub status: Status,
    /// Whether the exact rational path decided it (the f64 margin was too small).
    pub exact: bool,
}

/// Reusable work space for [`Decider::decide`] (one per thread).
#[derive(Clone, Debug)]
pub struct Decider {
    n: usize,
    l0: Vec<f64>,
    a: Vec<f64>,
    inv: Vec<f64>,
    margins: Margins,
}

impl Decider {
    /// Work space for k-simplices (k equations).
    pub fn new(k: usize) -> Self {
        let n = k + 1;
        Decider {
            n,
            l0: vec![0.0; n * n],
            a: vec![0.0; n * n],
            inv: vec![0.0; n * n],
            margins: Margins::of::<f64>(n),
        }
    }

    /// Decides the k-simplex whose vertex values are `values` (k+1 rows of k, vertex by
    /// vertex). Writes lambda (k+1 entries, summing to 1) when crossed.
    pub fn decide(&mut self, values: &[f64], lambda: &mut [f64]) -> Decision {
        let n = self.n;
        let k = n - 1;
        debug_assert_eq!(values.len(), n * k);
        let fast = |status| Decision {
            status,
            exact: false,
        };
        if let Some(status) = filter_verdict(k, |j, c| values[j * k + c]) {
            return fast(status);
        }
        match self.fast_path(values, lambda) {
            Some(status) => fast(status),
            None => Decision {
                status: exact_decision(values, k, lambda),
                exact: true,
            },
        }
    }

    /// The fast path alone (no NaN or sign filter first): Gauss-Jordan in f64 and the
    /// certificate, writing lambda; `None` when a needed sign is not proven. The GPU's solve
    /// shader is its twin.
    pub fn fast_path(&mut self, values: &[f64], lambda: &mut [f64]) -> Option<Status> {
        super::unrolled!(self.n, |n| self.fast_path_steps(n, values, lambda))
    }

    #[inline(always)]
    fn fast_path_steps(&mut self, n: usize, values: &[f64], lambda: &mut [f64]) -> Option<Status> {
        let k = n - 1;
        let (l0, a, inv) = (
            &mut self.l0[..n * n],
            &mut self.a[..n * n],
            &mut self.inv[..n * n],
        );
        // Row r of L scaled by a power of two near 1/max|row|: exact, and it changes neither
        // lambda nor the signs of L^-1's entries (columns of L^-1 scale by positive factors).
        l0[..n].fill(1.0);
        scaled_rows(k, |j, c| values[j * k + c], &mut l0[n..]);
        a.copy_from_slice(l0);
        if !gauss_jordan(n, a, inv) {
            return None;
        }
        for i in 0..n {
            lambda[i] = inv[i * n];
        }
        // The a-posteriori certificate with E = 0: a proof for L itself, whatever the
        // rounding of the inversion.
        match certify_exact(n, l0, inv, &self.margins) {
            CROSSED => Some(Status::Crossed),
            OUTSIDE => Some(Status::Outside),
            _ => None,
        }
    }
}

/// Gauss-Jordan inversion with partial pivoting of the n x n row-major matrix `a`
/// (destroyed) into `inv` in f64 ([`gauss_jordan`], unrolled for small n); false when a
/// pivot is below n ulps of the largest entry.
pub(crate) fn invert(n: usize, a: &mut [f64], inv: &mut [f64]) -> bool {
    super::unrolled!(n, |m| gauss_jordan(m, &mut a[..m * m], &mut inv[..m * m]))
}

/// The verdict of the cheap filters that run before any solve, with F_j[c] = `val(j, c)`:
/// `NonFinite` for a NaN or infinite value, `Outside` when some component keeps one strict
/// sign at every vertex (no crossing), else `None`.
pub(crate) fn filter_verdict(k: usize, val: impl Fn(usize, usize) -> f64) -> Option<Status> {
    let n = k + 1;
    if (0..n).any(|j| (0..k).any(|c| !val(j, c).is_finite())) {
        return Some(Status::NonFinite);
    }
    (0..k)
        .any(|c| (0..n).all(|j| val(j, c) > 0.0) || (0..n).all(|j| val(j, c) < 0.0))
        .then_some(Status::Outside)
}

/// Rows 1..=k of L (row c + 1 holds component c at the k + 1 vertices) into `out`, each
/// scaled by a power of two near 1/max|row|: exact, and it changes neither lambda nor the
/// signs of L^-1's entries. Shared by the CPU fast path and the GPU host side.
pub fn scaled_rows(k: usize, val: impl Fn(usize, usize) -> f64, out: &mut [f64]) {
    let n = k + 1;
    for c in 0..k {
        let big = (0..n).fold(0.0f64, |m, j| m.max(val(j, c).abs()));
        let s = pow2_inverse(big);
        for j in 0..n {
            out[c * n + j] = val(j, c) * s;
        }
    }
}

/// The factors [`scaled_rows`] applies, one per component, into `out` (k entries).
pub(crate) fn scaled_row_factors(k: usize, val: impl Fn(usize, usize) -> f64, out: &mut [f64]) {
    for (c, o) in out.iter_mut().enumerate().take(k) {
        let big = (0..=k).fold(0.0f64, |m, j| m.max(val(j, c).abs()));
        *o = pow2_inverse(big);
    }
}

/// The completely-labelled test in exact integer arithmetic on the given f64 values.
///
/// Each row of L is scaled by a power of two to integers (which changes neither lambda nor
/// the signs in L^-1), then fraction-free Gaussian elimination (Bareiss) gives D = det(PL)
/// and Y = D L^-1 in integers: row i of L^-1 is lexicographically positive iff the first
/// non-zero entry of row i of Y has the sign of D.
pub fn exact_decision(values: &[f64], k: usize, lambda: &mut [f64]) -> Status {
    let n = k + 1;
    let Some((det, y)) = exact_solve(values, k, n) else {
        return Status::Degenerate;
    };
    let positive = det.is_positive();
    for i in 0..n {
        match y[i * n..(i + 1) * n].iter().find(|v| !v.is_zero()) {
            Some(v) if v.is_positive() == positive => {}
            _ => return Status::Outside,
        }
    }
    for i in 0..n {
        lambda[i] = ratio_to_f64(&y[i * n], &det);
    }
    Status::Crossed
}

/// The exact signs of lambda = L^-1 e_1 (no tie rule): -1, 0 or 1 per entry, or `None`
/// when L is singular. A cheaper reference than [`exact_decision`] (one right-hand side)
/// for claims that hold strictly: crossed means every sign is 1.
#[cfg(any(test, feature = "internals"))]
pub fn exact_lambda_signs(values: &[f64], k: usize) -> Option<Vec<i8>> {
    let (det, y) = exact_solve(values, k, 1)?;
    let s = |v: &BigInt| v.is_positive() as i8 - v.is_negative() as i8;
    Some(y.iter().map(|v| s(v) * s(&det)).collect())
}

/// D = det(PL) and Y = D L^-1 [e_1 .. e_rhs] (n rows of `rhs`) in integers, with L's rows
/// scaled by powers of two to integers; `None` when L is singular.
fn exact_solve(values: &[f64], k: usize, rhs: usize) -> Option<(BigInt, Vec<BigInt>)> {
    let n = k + 1;
    let w = n + rhs;
    // [L | e_1 .. e_rhs] in integers.
    let mut m: Vec<BigInt> = vec![BigInt::zero(); n * w];
    for j in 0..n {
        m[j] = BigInt::one();
    }
    for r in 1..n {
        let row: Vec<(i64, i32)> = (0..n).map(|j| decompose(values[j * k + r - 1])).collect();
        let low = row
            .iter()
            .filter(|(mant, _)| *mant != 0)
            .map(|&(_, e)| e)
            .min()
            .unwrap_or(0);
        for (j, &(mant, e)) in row.iter().enumerate() {
            m[r * w + j] = BigInt::from(mant) << ((e - low) as usize);
        }
    }
    for i in 0..rhs {
        m[i * w + n + i] = BigInt::one();
    }
    // Forward elimination: after step c, m[r][t] for r > c is a (c+1)-minor of [L | I].
    let mut prev = BigInt::one();
    for c in 0..n {
        let p = (c..n).find(|&r| !m[r * w + c].is_zero())?;
        if p != c {
            for t in 0..w {
                m.swap(p * w + t, c * w + t);
            }
        }
        for r in c + 1..n {
            for t in c + 1..w {
                let v = (&m[c * w + c] * &m[r * w + t] - &m[r * w + c] * &m[c * w + t]) / &prev;
                m[r * w + t] = v;
            }
            m[r * w + c] = BigInt::zero();
        }
        prev = m[c * w + c].clone();
    }
    // Fraction-free back substitution: y = D x for every right-hand side.
    let det = prev;
    let mut y: Vec<BigInt> = vec![BigInt::zero(); n * rhs];
    for t in 0..rhs {
        for i in (0..n).rev() {
            let mut acc = &det * &m[i * w + n + t];
            for j in i + 1..n {
                acc -= &m[i * w + j] * &y[j * rhs + t];
            }
            y[i * rhs + t] = acc / &m[i * w + i];
        }
    }
    Some((det, y))
}

/// v = mantissa * 2^exponent exactly (v finite).
fn decompose(v: f64) -> (i64, i32) {
    let (mant, exp, sign) = v.integer_decode();
    (sign as i64 * mant as i64, exp as i32)
}

/// a / b as f64, to about 1e-16 relative, for integers of any size.
fn ratio_to_f64(a: &BigInt, b: &BigInt) -> f64 {
    let shift = a.bits().max(b.bits()).saturating_sub(62);
    let (a, b) = (a >> shift, b >> shift);
    match (a.to_f64(), b.to_f64()) {
        (Some(x), Some(y)) if y != 0.0 => x / y,
        _ => f64::NAN,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edge_with_a_zero_end_is_decided_by_the_tie_rule() {
        let mut d = Decider::new(1);
        let mut l = [0.0; 2];
        // f = 0 at v0 counts as slightly negative (f shifted by +eps... i.e. f - eps < 0).
        assert_eq!(d.decide(&[0.0, 1.0], &mut l).status, Status::Crossed);
        assert_eq!(d.decide(&[0.0, -1.0], &mut l).status, Status::Outside);
        assert_eq!(d.decide(&[1.0, 0.0], &mut l).status, Status::Crossed);
        assert_eq!(d.decide(&[-2.0, 2.0], &mut l).status, Status::Crossed);
        assert_eq!(l, [0.5, 0.5]);
        assert_eq!(d.decide(&[0.0, 0.0], &mut l).status, Status::Degenerate);
        assert_eq!(d.decide(&[f64::NAN, 1.0], &mut l).status, Status::NonFinite);
    }

    #[test]
    fn fast_and_exact_paths_agree_on_random_triangles() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut d = Decider::new(2);
        let (mut l1, mut l2) = ([0.0; 3], [0.0; 3]);
        for _ in 0..2000 {
            let v: Vec<f64> = (0..6).map(|_| rng.random_range(-1.0..1.0)).collect();
            let fast = d.decide(&v, &mut l1);
            let exact = exact_decision(&v, 2, &mut l2);
            assert_eq!(fast.status, exact, "values {v:?}");
            if exact == Status::Crossed {
                for i in 0..3 {
                    assert!((l1[i] - l2[i]).abs() < 1e-9);
                }
            }
        }
    }

    #[test]
    fn exact_lambda_signs_are_the_signs_of_the_exact_solution() {
        use rand::{Rng, SeedableRng};
        // Edges: lambda_1 = f0 / (f0 - f1), lambda_0 = 1 - lambda_1.
        assert_eq!(exact_lambda_signs(&[-2.0, 2.0], 1), Some(vec![1, 1]));
        assert_eq!(exact_lambda_signs(&[2.0, -6.0], 1), Some(vec![1, 1]));
        assert_eq!(exact_lambda_signs(&[1.0, 2.0], 1), Some(vec![1, -1]));
        assert_eq!(exact_lambda_signs(&[2.0, 1.0], 1), Some(vec![-1, 1]));
        assert_eq!(exact_lambda_signs(&[0.0, 1.0], 1), Some(vec![1, 0]));
        assert_eq!(exact_lambda_signs(&[3.0, 3.0], 1), None);
        // Against the exact decision (strict signs: crossed; a negative one: outside) and
        // against f64 lambda away from 0, for k = 1..=5.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut lambda = [0.0; 6];
        for k in 1..=5 {
            for _ in 0..400 {
                let v: Vec<f64> = (0..(k + 1) * k)
                    .map(|_| rng.random_range(-1.0..1.0))
                    .collect();
                let signs = exact_lambda_signs(&v, k).expect("a random L is regular");
                let exact = exact_decision(&v, k, &mut lambda);
                if signs.iter().all(|&s| s == 1) {
                    assert_eq!(exact, Status::Crossed, "{v:?}");
                } else if signs.contains(&-1) {
                    assert_eq!(exact, Status::Outside, "{v:?}");
                }
                let mut x = vec![0.0; k + 1];
                let v = &v;
                let l: Vec<f64> = (0..=k)
                    .flat_map(|r| (0..=k).map(move |j| if r == 0 { 1.0 } else { v[j * k + r - 1] }))
                    .collect();
                let (mut a, mut inv) = (l, vec![0.0; (k + 1) * (k + 1)]);
                assert!(invert(k + 1, &mut a, &mut inv));
                for i in 0..=k {
                    x[i] = inv[i * (k + 1)];
                    if x[i].abs() > 1e-9 {
                        assert_eq!(signs[i], x[i].signum() as i8, "k = {k}, {v:?}: {x:?}");
                    }
                }
            }
        }
    }

    /// A random n x n matrix with a dominant diagonal, rows in any order.
    fn random_matrix(rng: &mut rand_chacha::ChaCha8Rng, n: usize) -> Vec<f64> {
        use rand::Rng;
        let mut a: Vec<f64> = (0..n * n).map(|_| rng.random_range(-1.0..1.0)).collect();
        for i in 0..n {
            a[i * n + i] += if rng.random_bool(0.5) { 3.0 } else { -3.0 } * n as f64;
        }
        // A row rotation: the largest entry of column 0 is then not on the diagonal.
        a.rotate_left(n * (n / 2));
        a
    }

    #[test]
    fn invert_gives_the_inverse_and_refuses_singular_matrices() {
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for n in 1..=9 {
            for _ in 0..20 {
                let a0 = random_matrix(&mut rng, n);
                let (mut a, mut inv) = (a0.clone(), vec![7.0; n * n]);
                assert!(invert(n, &mut a, &mut inv), "n = {n}");
                for r in 0..n {
                    for c in 0..n {
                        let x: f64 = (0..n).map(|t| a0[r * n + t] * inv[t * n + c]).sum();
                        let want = if r == c { 1.0 } else { 0.0 };
                        assert!((x - want).abs() < 1e-12, "n = {n}: A A^-1 [{r}][{c}] = {x}");
                    }
                }
            }
            // Two equal rows; and a zero column.
            let mut a = random_matrix(&mut rng, n);
            if n > 1 {
                let row: Vec<f64> = a[..n].to_vec();
                a[n..2 * n].copy_from_slice(&row);
            } else {
                a[0] = 0.0;
            }
            let mut inv = vec![0.0; n * n];
            assert!(!invert(n, &mut a, &mut inv), "n = {n}: singular");
        }
        // A permutation matrix needs the row swaps.
        let (mut a, mut inv) = (
            vec![0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0],
            vec![0.0; 9],
        );
        assert!(invert(3, &mut a, &mut inv));
        assert_eq!(inv, [0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    }

    #[test]
    fn rows_are_scaled_by_powers_of_two_to_a_largest_entry_in_one_to_two() {
        for v in [
            1.0,
            1.5,
            3.0,
            0.7,
            1e-300,
            6e300,
            -2.5e-7,
            f64::MAX,
            f64::MIN_POSITIVE,
        ] {
            let s = pow2_inverse(v);
            assert_eq!(
                s.to_bits() & ((1u64 << 52) - 1),
                0,
                "{v}: not a power of two"
            );
            let x = v.abs() * s;
            if v.abs() < 2.0f64.powi(1023) {
                assert!((1.0..2.0).contains(&x), "{v} * {s} = {x}");
            } else {
                assert_eq!(s, 2.0f64.powi(-1022));
            }
        }
        for v in [0.0, 1e-310, f64::INFINITY, f64::NAN] {
            assert_eq!(pow2_inverse(v), 1.0, "{v}");
        }
        let vals = [[3.0, -0.25], [-6.0, 0.5], [1.0, 0.0]];
        let mut out = [0.0; 6];
        scaled_rows(2, |j, c| vals[j][c], &mut out);
        assert_eq!(out, [0.75, -1.5, 0.25, -0.5, 1.0, 0.0]);
        let mut f = [0.0; 2];
        scaled_row_factors(2, |j, c| vals[j][c], &mut f);
        assert_eq!(f, [0.25, 2.0]);
    }

    #[test]
    fn the_sign_filter_names_only_what_is_certain() {
        let v = |rows: &'static [[f64; 2]]| move |j: usize, c: usize| rows[j][c];
        assert_eq!(
            filter_verdict(2, v(&[[1.0, 0.0], [2.0, -1.0], [3.0, 1.0]])),
            Some(Status::Outside)
        );
        assert_eq!(
            filter_verdict(2, v(&[[1.0, -1.0], [-2.0, -1.0], [3.0, -4.0]])),
            Some(Status::Outside)
        );
        assert_eq!(
            filter_verdict(2, v(&[[1.0, 0.0], [-2.0, -1.0], [3.0, 1.0]])),
            None
        );
        assert_eq!(
            filter_verdict(2, v(&[[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]])),
            None
        );
        assert_eq!(
            filter_verdict(2, v(&[[1.0, 0.0], [-2.0, f64::INFINITY], [3.0, 1.0]])),
            Some(Status::NonFinite)
        );
        assert_eq!(
            filter_verdict(2, v(&[[1.0, 1.0], [2.0, 1.0], [f64::NAN, 1.0]])),
            Some(Status::NonFinite)
        );
    }

    #[test]
    fn exact_decisions_on_known_simplices() {
        let mut l = [0.0; 3];
        assert_eq!(exact_decision(&[-1.0, 3.0], 1, &mut l), Status::Crossed);
        assert_eq!(&l[..2], &[0.75, 0.25]);
        assert_eq!(
            exact_decision(&[1.0, 0.0, 0.0, 1.0, -1.0, -1.0], 2, &mut l),
            Status::Crossed
        );
        assert_eq!(l, [1.0 / 3.0; 3]);
        // The origin outside, beyond each edge in turn.
        assert_eq!(
            exact_decision(&[1.0, 0.0, 0.0, 1.0, 1.0, 1.0], 2, &mut l),
            Status::Outside
        );
        assert_eq!(
            exact_decision(&[1.0, 1.0, 2.0, 1.0, 1.0, 2.0], 2, &mut l),
            Status::Outside
        );
        assert_eq!(
            exact_decision(&[-1.0, 2.0, 2.0, -1.0, 1.0, 1.0], 2, &mut l),
            Status::Outside
        );
        // Rows that need a swap (a zero pivot), and a singular L.
        assert_eq!(
            exact_decision(&[0.0, 1.0, 1.0, 0.0, -1.0, -1.0], 2, &mut l),
            Status::Crossed
        );
        assert_eq!(l, [1.0 / 3.0; 3]);
        assert_eq!(
            exact_decision(&[1.0, 1.0, 2.0, 2.0, 3.0, 3.0], 2, &mut l),
            Status::Degenerate
        );
        assert_eq!(exact_decision(&[0.0, 0.0], 1, &mut l), Status::Degenerate);
        // Ties: the origin on an edge or at a vertex goes by the sign of the first non-zero
        // entry of each row of L^-1 (symbolic perturbation): one side only.
        let a = exact_decision(&[0.0, 1.0], 1, &mut l);
        let b = exact_decision(&[0.0, -1.0], 1, &mut l);
        assert_eq!((a, b), (Status::Crossed, Status::Outside));
        // Over the whole exponent range, exactly.
        let tiny = f64::from_bits(1);
        assert_eq!(
            exact_decision(&[-f64::MAX, tiny], 1, &mut l),
            Status::Crossed
        );
        // lambda_0 = 2^-1074 / (2^1024 - ...) underflows to 0 in f64, lambda_1 rounds to 1.
        assert!(l[0] == 0.0 && l[1] == 1.0, "{l:?}");
        assert_eq!(
            exact_decision(&[3.0 * 2f64.powi(-1060), -2f64.powi(-1060)], 1, &mut l),
            Status::Crossed
        );
        assert_eq!(&l[..2], &[0.25, 0.75]);
        assert_eq!(exact_decision(&[3e300, -1e300], 1, &mut l), Status::Crossed);
        assert_eq!(&l[..2], &[0.25, 0.75]);
    }

    #[test]
    fn big_ratios_come_back_as_floats() {
        let big = BigInt::one() << 3000u32;
        assert_eq!(ratio_to_f64(&(&big * 3u32), &(&big * 4u32)), 0.75);
        assert_eq!(
            ratio_to_f64(&BigInt::from(-1), &BigInt::from(3)),
            -1.0 / 3.0
        );
        assert!(ratio_to_f64(&BigInt::one(), &BigInt::zero()).is_nan());
        for v in [1.5, -0.1, 6.02e23, -f64::MAX, -1e-300] {
            let (m, e) = decompose(v);
            assert_eq!(m as f64 * 2f64.powi(e), v, "{v}");
        }
        // The smallest subnormal, 2^-1074, as num-traits writes it.
        assert_eq!(decompose(f64::from_bits(1)), (2, -1075));
        assert_eq!(decompose(0.0).0, 0);
    }

    #[test]
    fn the_fast_path_certifies_only_outside_its_error_bound() {
        let mut d = Decider::new(1);
        let mut l = [0.0; 2];
        assert_eq!(d.fast_path(&[-2.0, 2.0], &mut l), Some(Status::Crossed));
        assert_eq!(l, [0.5, 0.5]);
        assert_eq!(d.fast_path(&[1.0, 3.0], &mut l), Some(Status::Outside));
        assert_eq!(d.fast_path(&[3.0, 1.0], &mut l), Some(Status::Outside));
        // lambda_0 = 1e-17 / (1 + 1e-17) is tiny, but here its residual is tiny too: the
        // certificate proves its sign (a normwise bound could not). With the rows the other
        // way round, R's large entry meets row 0's rounding, and the proof may fail; a
        // verdict it gives is the exact one. An exact zero is left to the exact tie rule.
        assert_eq!(d.fast_path(&[1e-17, -1.0], &mut l), Some(Status::Crossed));
        assert_eq!(d.fast_path(&[-1e-17, -1.0], &mut l), Some(Status::Outside));
        let mut exact = [0.0; 2];
        for v in [
            [-1.0, 1e-17],
            [-1.0, -1e-17],
            [1e-300, -1.0],
            [-1.0, 1e-300],
        ] {
            if let Some(got) = d.fast_path(&v, &mut l) {
                assert_eq!(got, exact_decision(&v, 1, &mut exact), "{v:?}");
            }
        }
        assert_eq!(d.fast_path(&[0.0, 1.0], &mut l), None);
        assert_eq!(d.fast_path(&[-1.0, 0.0], &mut l), None);
        assert_eq!(d.fast_path(&[0.0, 0.0], &mut l), None);
        assert_eq!(d.fast_path(&[1.0, 1.0], &mut l), None);
        // Conditioned beyond the certificate (kappa > 1/2): no verdict.
        let near = 1.0 + 2f64.powi(-52);
        assert_eq!(d.fast_path(&[1.0, near], &mut l), None);
        // The decision says which path decided.
        let got = d.decide(&[0.0, 1.0], &mut l);
        assert_eq!((got.status, got.exact), (Status::Crossed, true));
        let got = d.decide(&[1e-17, -1.0], &mut l);
        assert_eq!((got.status, got.exact), (Status::Crossed, false));
        let got = d.decide(&[1.0, 2.0], &mut l);
        assert_eq!((got.status, got.exact), (Status::Outside, false));
        assert!(Status::Crossed.crossed() && !Status::Outside.crossed());
        // k = 2: the origin on an edge (lambda_2 = 0 exactly) is left to the tie rule; just
        // off it, the certificate decides, as the exact test does.
        let mut d2 = Decider::new(2);
        let mut l2 = [0.0; 3];
        let mut exact = [0.0; 3];
        assert_eq!(
            d2.fast_path(&[-1.0, 0.0, 1.0, 0.0, 0.0, 1.0], &mut l2),
            None
        );
        for y in [1e-12, -1e-12, 1e-6, -0.25] {
            let v = [-1.0, y, 1.0, y, 0.0, 1.0];
            let got = d2.fast_path(&v, &mut l2);
            assert!(got.is_some(), "{v:?}");
            assert_eq!(got, Some(exact_decision(&v, 2, &mut exact)), "{v:?}");
        }
        // Two columns a few ulps apart: too ill-conditioned for a proof.
        let eps = 2f64.powi(-51);
        let v = [-1.0, -1.0, 1.0, 1.0 + eps, 1.0 + eps, 1.0];
        assert_eq!(d2.fast_path(&v, &mut l2), None);
        assert_eq!(
            d2.fast_path(&[1.0, 0.0, 0.0, 1.0, -1.0, -1.0], &mut l2),
            Some(Status::Crossed)
        );
    }
}
