// Index loops read as the textbook pivoting step they are.
#![allow(clippy::needless_range_loop)]
//! Door in, door out: the pivoting step of PL continuation that finds, for a crossed
//! k-simplex sigma and a (k+1)-simplex tau having it as a facet, the other crossed facet of
//! tau with one matrix-vector product instead of k + 1 solves.
//!
//! With L the labelling matrix of sigma (see [`crate::cpu::solve`]) and a = [1; F(w)] the
//! column of tau's extra vertex w, the facet left when w enters is the one opposite the
//! vertex i of sigma that minimises row_i(L^-1) / (L^-1 a)_i lexicographically over the
//! (L^-1 a)_i > 0: the lexicographic ratio test of the simplex method. In exact arithmetic
//! it is the other completely labelled facet of tau, with the same tie rule as the oracle.
//! Here it runs in f64 without error bounds, so the answer is a guess that the caller
//! confirms with the exact oracle (a wrong guess is a facet the oracle finds not crossed,
//! and the caller then tests every facet of tau).

use super::solve::{invert, scaled_row_factors};

/// L^-1 of one crossed k-simplex, ready for ratio tests against its cofacets' vertices.
#[derive(Clone, Debug)]
pub struct Pivot {
    n: usize,
    /// One allocation: the row scales (k) and L^-1 (n x n), which are the state of a loaded
    /// simplex, then L (n x n) and L^-1 a (n).
    buf: Vec<f64>,
}

impl Pivot {
    /// Work space for k-simplices (k equations).
    pub fn new(k: usize) -> Self {
        let n = k + 1;
        Pivot {
            n,
            buf: vec![0.0; k + 2 * n * n + n],
        }
    }

    /// The parts of the work space: scales, L, L^-1, L^-1 a.
    #[inline(always)]
    fn parts(&mut self) -> (&mut [f64], &mut [f64], &mut [f64], &mut [f64]) {
        let n = self.n;
        let (scale, rest) = self.buf.split_at_mut(n - 1);
        let (inv, rest) = rest.split_at_mut(n * n);
        let (a, w) = rest.split_at_mut(n * n);
        (scale, a, inv, w)
    }

    /// The loaded simplex's state (its row scales and L^-1: k + (k + 1)^2 numbers; for
    /// k = 1, the two values first), for [`Pivot::restore`] to put back without inverting
    /// L again.
    pub fn state(&self) -> &[f64] {
        &self.buf[..self.n - 1 + self.n * self.n]
    }

    /// Loads the simplex whose [`Pivot::state`] this is (of a pivot for the same k).
    pub fn restore(&mut self, state: &[f64]) {
        self.buf[..state.len()].copy_from_slice(state);
    }

    /// Inverts L for the simplex with vertex values `F_j[c] = val(j, c)`; false when L is
    /// numerically singular (no ratio test then). For k = 1 it keeps the two values
    /// instead (see [`Pivot::exit`]): false when they are equal or not finite.
    pub fn load(&mut self, val: impl Fn(usize, usize) -> f64) -> bool {
        let n = self.n;
        if n == 2 {
            let (a, b) = (val(0, 0), val(1, 0));
            self.buf[..2].copy_from_slice(&[a, b]);
            return a.is_finite() && b.is_finite() && a != b;
        }
        let k = n - 1;
        let (scale, a, inv, _) = self.parts();
        scaled_row_factors(k, &val, scale);
        a[..n].fill(1.0);
        for c in 0..k {
            for j in 0..n {
                a[(c + 1) * n + j] = val(j, c) * scale[c];
            }
        }
        invert(n, a, inv)
    }

    /// The vertex of the loaded simplex that leaves when a vertex with values `f` (k
    /// entries) enters, or `None` when no entry of L^-1 a is positive (rounding trouble).
    ///
    /// For k = 1 the ratio test is a test of signs, exact: for a crossed edge with values
    /// a and b at its vertices, the vertex whose value has the sign of f (zero counting as
    /// negative, as the test's tie rule does) leaves. With a < 0 < b, L^-1 a is
    /// (b - f, f - a) / (b - a) and the ratios' first entries compare as f does with 0; at
    /// f = 0 the second entries, -1 against 1, put vertex 0 first. The other orders of a,
    /// b and f reduce to these.
    #[inline]
    pub fn exit(&mut self, f: &[f64]) -> Option<usize> {
        if self.n == 2 {
            let f = f[0];
            return f
                .is_finite()
                .then(|| usize::from((self.buf[0] > 0.0) != (f > 0.0)));
        }
        self.ratio_test(f)
    }

    /// [`Pivot::exit`] for k > 1: the ratio test in f64.
    #[inline(never)]
    fn ratio_test(&mut self, f: &[f64]) -> Option<usize> {
        super::unrolled!(self.n, |n| self.exit_steps(n, f))
    }

    #[inline(always)]
    fn exit_steps(&mut self, n: usize, f: &[f64]) -> Option<usize> {
        let (scale, _, inv, w) = self.parts();
        let (inv, w, scale) = (&inv[..n * n], &mut w[..n], &scale[..n - 1]);
        let f = &f[..n - 1];
        for i in 0..n {
            let row = &inv[i * n..(i + 1) * n];
            let mut s = row[0];
            for c in 1..n {
                s += row[c] * (f[c - 1] * scale[c - 1]);
            }
            w[i] = s;
        }
        let mut best: Option<usize> = None;
        for i in 0..n {
            if w[i].is_nan() || w[i] <= 0.0 {
                continue;
            }
            let Some(b) = best else {
                best = Some(i);
                continue;
            };
            // row_i / w_i < row_b / w_b, lexicographically, with both w positive.
            for c in 0..n {
                let (x, y) = (inv[i * n + c] * w[b], inv[b * n + c] * w[i]);
                if x < y {
                    best = Some(i);
                    break;
                }
                if x > y {
                    break;
                }
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::solve::{exact_decision, Status};
    use rand::{Rng, SeedableRng};

    /// Pivots on random (k+1)-simplices with crossed facets, k = 1..6: how many named the
    /// other crossed facet that the exact test finds, and how many did not. `ties` is the
    /// share of vertex values drawn from small integers (exact ties are then common).
    fn pivot_outcomes(ties: f64, per_k: usize) -> (usize, usize) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let (mut confirmed, mut wrong) = (0, 0);
        for k in 1..=6 {
            let n = k + 1;
            let mut pivot = Pivot::new(k);
            let mut lambda = vec![0.0; n];
            for _ in 0..per_k {
                // k + 2 vertices of tau; small integers make exact ties common.
                let tau: Vec<f64> = (0..(n + 1) * k)
                    .map(|_| {
                        if rng.random_bool(ties) {
                            rng.random_range(-2..=2) as f64
                        } else {
                            rng.random_range(-1.0..1.0)
                        }
                    })
                    .collect();
                let facet = |skip: usize| -> Vec<f64> {
                    (0..=n)
                        .filter(|&j| j != skip)
                        .flat_map(|j| tau[j * k..(j + 1) * k].to_vec())
                        .collect()
                };
                let crossed: Vec<usize> = (0..=n)
                    .filter(|&s| exact_decision(&facet(s), k, &mut lambda) == Status::Crossed)
                    .collect();
                assert!(crossed.is_empty() || crossed.len() == 2, "{crossed:?}");
                if crossed.is_empty() {
                    continue;
                }
                // sigma = tau without vertex crossed[0]; w = that vertex.
                let (out, other) = (crossed[0], crossed[1]);
                let sigma = facet(out);
                if !pivot.load(|j, c| sigma[j * k + c]) {
                    continue;
                }
                let Some(r) = pivot.exit(&tau[out * k..(out + 1) * k]) else {
                    continue;
                };
                // Vertex r of sigma is vertex r of tau below `out`, r + 1 from it on.
                let leaves = if r < out { r } else { r + 1 };
                if leaves == other {
                    confirmed += 1;
                } else {
                    wrong += 1;
                }
            }
        }
        (confirmed, wrong)
    }

    #[test]
    fn the_ratio_test_finds_the_other_crossed_facet() {
        // 600 draws for each k find about 1,200 pivots.
        let (confirmed, wrong) = pivot_outcomes(0.0, 600);
        assert!(confirmed > 900, "only {confirmed} pivots");
        assert_eq!(wrong, 0, "wrong exits without ties");
        // With exact ties f64 may guess wrong (the tracer then tests every facet), rarely.
        let (confirmed, wrong) = pivot_outcomes(0.3, 600);
        assert!(confirmed > 900, "only {confirmed} pivots");
        assert!(wrong * 50 < confirmed, "{wrong} wrong of {confirmed}");
    }

    #[test]
    fn for_edges_the_exit_is_the_exact_tests_other_crossed_facet() {
        // Every triangle with values in -2..=2 at its vertices (zeros and ties included)
        // and some with tiny ones: the exit that k = 1 finds by signs is the other crossed
        // edge that the exact test finds, without exception.
        let mut values: Vec<f64> = (-2..=2).map(f64::from).collect();
        values.extend([1e-300, -1e-300, 3e-17, -0.75]);
        let mut lambda = [0.0; 2];
        let (mut pivots, mut p) = (0, Pivot::new(1));
        for &x in &values {
            for &y in &values {
                for &z in &values {
                    let tau = [x, y, z];
                    let facet = |skip: usize| -> Vec<f64> {
                        (0..3).filter(|&j| j != skip).map(|j| tau[j]).collect()
                    };
                    let crossed: Vec<usize> = (0..3)
                        .filter(|&s| exact_decision(&facet(s), 1, &mut lambda) == Status::Crossed)
                        .collect();
                    for (&out, &other) in crossed.iter().zip(crossed.iter().rev()) {
                        let sigma = facet(out);
                        assert!(p.load(|j, _| sigma[j]), "{tau:?}");
                        let r = p.exit(&[tau[out]]).expect("an exit");
                        let leaves = if r < out { r } else { r + 1 };
                        assert_eq!(leaves, other, "tau {tau:?}, vertex {out} enters");
                        pivots += 1;
                    }
                }
            }
        }
        assert!(pivots > 200, "{pivots} pivots");
    }

    #[test]
    fn exact_ties_in_the_ratios_go_to_the_lexicographically_smallest_row() {
        // k = 1, sigma with values 0 and 0 at vertices 0 and 1 would be singular; take
        // F = -1, 1 (L = [[1, 1], [-1, 1]] before scaling): w = 0 enters at the midpoint,
        // L^-1 a = (1/2, 1/2), a tie in the first ratio, broken by the rows of L^-1.
        let mut p = Pivot::new(1);
        assert!(p.load(|j, _| [-1.0, 1.0][j]));
        // Rows of L^-1 (scaled): (1/2, -1/2), (1/2, 1/2); the first is smaller.
        assert_eq!(p.exit(&[0.0]), Some(0));
        let mut q = Pivot::new(1);
        assert!(q.load(|j, _| [1.0, -1.0][j]));
        assert_eq!(q.exit(&[0.0]), Some(1));
        // Without a tie the smallest ratio wins: w = -1/2 gives L^-1 a = (3/4, 1/4) for
        // F = -1, 1, so vertex 0 leaves: 1/2 / (3/4) < 1/2 / (1/4) for the first entries.
        assert_eq!(p.exit(&[-0.5]), Some(0));
        assert_eq!(p.exit(&[0.5]), Some(1));
        // Outside the segment one entry is negative: the positive one leaves.
        assert_eq!(p.exit(&[3.0]), Some(1));
        assert_eq!(p.exit(&[-3.0]), Some(0));
        assert_eq!(p.exit(&[f64::NAN]), None);
    }

    #[test]
    fn a_saved_state_loads_its_simplex_again() {
        let mut p = Pivot::new(1);
        assert!(p.load(|j, _| [-1.0, 1.0][j]));
        let saved = p.state().to_vec();
        // The row scales and L^-1.
        assert_eq!(saved.len(), 1 + 4);
        assert!(p.load(|j, _| [1.0, -1.0][j]));
        assert_eq!(p.exit(&[0.0]), Some(1));
        p.restore(&saved);
        assert_eq!(p.exit(&[0.0]), Some(0));
        assert_eq!(p.exit(&[3.0]), Some(1));
        // k = 2: F = 0, e1, e2, then the same vertices in another order.
        let mut q = Pivot::new(2);
        let f = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]];
        assert!(q.load(|j, c| f[j][c]));
        let saved = q.state().to_vec();
        assert_eq!(saved.len(), 2 + 9);
        assert!(q.load(|j, c| f[2 - j][c]));
        assert_eq!(q.exit(&[-1.0, -1.0]), Some(2));
        q.restore(&saved);
        assert_eq!(q.exit(&[-1.0, -1.0]), Some(0));
        assert_eq!(q.exit(&[2.0, -3.0]), Some(1));
    }

    #[test]
    fn a_singular_simplex_loads_no_pivot() {
        let mut p = Pivot::new(2);
        // Three vertices on a line in value space: L is singular.
        assert!(!p.load(|j, c| [[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]][j][c]));
        assert!(p.load(|j, c| [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]][j][c]));
        // F = 0, e1, e2: L^-1 a is f's barycentric coordinates (1 - f1 - f2, f1, f2) and the
        // first column of L^-1 is (1, 0, 0); for f = (0.2, 0.3) rows 1 and 2 tie at 0 in the
        // first entry and the second column, (-1, 1, 0) over the scale, puts row 2 first.
        assert_eq!(p.exit(&[0.2, 0.3]), Some(2));
        assert_eq!(p.exit(&[0.3, 0.2]), Some(2));
        // Only vertex 0's coordinate is positive.
        assert_eq!(p.exit(&[-1.0, -1.0]), Some(0));
        // Only vertex 1's.
        assert_eq!(p.exit(&[2.0, -3.0]), Some(1));
    }
}
