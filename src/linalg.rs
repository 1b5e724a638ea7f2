// Index loops read as the textbook algorithms they are.
#![allow(clippy::needless_range_loop)]
//! Small dense linear algebra: LU with partial pivoting, for the custom and rotated
//! triangulation maps and for Newton steps. Row-major storage throughout.

/// An LU factorisation with partial pivoting of an n x n matrix.
#[derive(Clone, Debug)]
pub struct Lu {
    n: usize,
    lu: Vec<f64>,
    perm: Vec<usize>,
}

impl Lu {
    /// Factorises the row-major n x n matrix `a`; `None` when it is singular to working
    /// precision (a pivot below n * eps * max|a|).
    pub fn new(a: &[f64], n: usize) -> Option<Lu> {
        assert_eq!(a.len(), n * n, "matrix must be n x n");
        let mut lu = a.to_vec();
        let mut perm: Vec<usize> = (0..n).collect();
        let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if !(scale.is_finite() && scale > 0.0) {
            return None;
        }
        let tiny = scale * f64::EPSILON * n as f64;
        for c in 0..n {
            let p = (c..n)
                .max_by(|&i, &j| lu[i * n + c].abs().total_cmp(&lu[j * n + c].abs()))
                .unwrap_or(c);
            if lu[p * n + c].abs() <= tiny {
                return None;
            }
            if p != c {
                for t in 0..n {
                    lu.swap(p * n + t, c * n + t);
                }
                perm.swap(p, c);
            }
            let pivot = lu[c * n + c];
            for r in c + 1..n {
                let factor = lu[r * n + c] / pivot;
                lu[r * n + c] = factor;
                for t in c + 1..n {
                    lu[r * n + t] -= factor * lu[c * n + t];
                }
            }
        }
        Some(Lu { n, lu, perm })
    }

    /// |det A|.
    pub fn abs_det(&self) -> f64 {
        (0..self.n).map(|i| self.lu[i * self.n + i].abs()).product()
    }

    /// Solves `A x = b`, overwriting `b` with `x`.
    pub fn solve(&self, b: &mut [f64]) {
        let n = self.n;
        let mut y: Vec<f64> = self.perm.iter().map(|&p| b[p]).collect();
        for r in 0..n {
            let mut s = y[r];
            for c in 0..r {
                s -= self.lu[r * n + c] * y[c];
            }
            y[r] = s;
        }
        for r in (0..n).rev() {
            let mut s = y[r];
            for c in r + 1..n {
                s -= self.lu[r * n + c] * y[c];
            }
            y[r] = s / self.lu[r * n + r];
        }
        b.copy_from_slice(&y);
    }
}

/// `out = a * x` for a row-major n x n matrix.
pub fn mat_vec(a: &[f64], x: &[f64], out: &mut [f64]) {
    let n = x.len();
    for (r, o) in out.iter_mut().enumerate().take(n) {
        *o = a[r * n..(r + 1) * n]
            .iter()
            .zip(x)
            .map(|(p, q)| p * q)
            .sum();
    }
}

/// Row-major product of two n x n matrices.
pub fn mat_mul(a: &[f64], b: &[f64], n: usize) -> Vec<f64> {
    let mut out = vec![0.0; n * n];
    for r in 0..n {
        for t in 0..n {
            let art = a[r * n + t];
            if art != 0.0 {
                for c in 0..n {
                    out[r * n + c] += art * b[t * n + c];
                }
            }
        }
    }
    out
}
