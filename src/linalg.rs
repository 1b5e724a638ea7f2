// Index loops read as the textbook algorithms they are.
#![allow(clippy::needless_range_loop)]
//! Small dense linear algebra: LU with partial pivoting, for the custom and rotated
//! triangulation maps and for Newton steps. Row-major storage throughout.

/// A power of two near 1/v (1 for 0 or subnormal v): scaling by it is exact.
#[inline]
pub(crate) fn pow2_inverse(v: f64) -> f64 {
    let e = ((v.to_bits() >> 52) & 0x7ff) as i64;
    if e == 0 || e == 0x7ff {
        return 1.0;
    }
    // v in [2^(e-1023), 2^(e-1022)): multiply by 2^(1023-e), kept in the normal range.
    let t = (2046 - e).clamp(1, 2046);
    f64::from_bits((t as u64) << 52)
}

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

/// Eigen-decomposition of the symmetric n x n matrix `a` (row-major) by cyclic Jacobi
/// rotations: the eigenvalues in decreasing order, and the matching unit eigenvectors as the
/// rows of an n x n matrix.
pub fn symmetric_eigen(a: &[f64], n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut a = a.to_vec();
    let mut v = vec![0.0; n * n];
    for i in 0..n {
        v[i * n + i] = 1.0;
    }
    for _sweep in 0..64 {
        let off: f64 = (0..n)
            .flat_map(|i| (0..n).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i * n + j] * a[i * n + j])
            .sum();
        let scale: f64 = (0..n).map(|i| a[i * n + i] * a[i * n + i]).sum();
        if off <= 1e-30 * scale.max(f64::MIN_POSITIVE) {
            break;
        }
        for p in 0..n {
            for q in p + 1..n {
                let apq = a[p * n + q];
                if apq == 0.0 {
                    continue;
                }
                let theta = (a[q * n + q] - a[p * n + p]) / (2.0 * apq);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for k in 0..n {
                    let (akp, akq) = (a[k * n + p], a[k * n + q]);
                    a[k * n + p] = c * akp - s * akq;
                    a[k * n + q] = s * akp + c * akq;
                }
                for k in 0..n {
                    let (apk, aqk) = (a[p * n + k], a[q * n + k]);
                    a[p * n + k] = c * apk - s * aqk;
                    a[q * n + k] = s * apk + c * aqk;
                }
                for k in 0..n {
                    let (vkp, vkq) = (v[k * n + p], v[k * n + q]);
                    v[k * n + p] = c * vkp - s * vkq;
                    v[k * n + q] = s * vkp + c * vkq;
                }
            }
        }
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&i, &j| a[j * n + j].total_cmp(&a[i * n + i]));
    let values = order.iter().map(|&i| a[i * n + i]).collect();
    let mut vectors = vec![0.0; n * n];
    for (r, &i) in order.iter().enumerate() {
        for k in 0..n {
            vectors[r * n + k] = v[k * n + i];
        }
    }
    (values, vectors)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eigen_of_a_symmetric_matrix() {
        let a = [4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 1.0];
        let (vals, vecs) = symmetric_eigen(&a, 3);
        assert!(vals[0] >= vals[1] && vals[1] >= vals[2]);
        for r in 0..3 {
            let v = &vecs[r * 3..r * 3 + 3];
            let mut av = [0.0; 3];
            mat_vec(&a, v, &mut av);
            for k in 0..3 {
                assert!((av[k] - vals[r] * v[k]).abs() < 1e-12, "{av:?} {v:?}");
            }
        }
        let trace: f64 = vals.iter().sum();
        assert!((trace - 8.0).abs() < 1e-12);
    }
}
