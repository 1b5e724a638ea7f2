// Index loops read as the matrix algebra they are.
#![allow(clippy::needless_range_loop)]
// `!(a < b)` is meant: a NaN must fail every test and so leave the verdict uncertain.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
//! The a-posteriori certificate of a k-simplex's verdict: a proof, computed in the device's
//! float type, that every labelling matrix within given bounds of the one at hand has the
//! same verdict. The CPU twin of `shaders/solve_certified.wgsl` (same steps, same constants:
//! [`Margins`]).
//!
//! Let L be the labelling matrix [1 .. 1; F_0 .. F_k] (n = k + 1), E >= 0 a bound on the
//! distance of its entries to those of any matrix L* it stands for (row 0 exact), and R any
//! approximate inverse of L (here Gauss-Jordan's, but the proof does not depend on how R was
//! found, so a device that contracts or rounds differently changes only how often the proof
//! succeeds). With x = R e_1, C = I - R L* and r = e_1 - L* x:
//!
//! - |C| <= |fl(I - R L)| + gamma (I + |R| |L|) + |R| E, and if its largest row sum kappa is
//!   below 1, L* is nonsingular (R L* = I - C is); the row sums of the last two terms are
//!   gamma (1 + |R| |L| 1) + |R| (E 1), so only the first costs O(n^3);
//! - delta = L*^-1 e_1 - x solves (I - C) delta = R r, so
//!   |delta| <= |R| |r| + |C| 1 ||delta||, ||delta|| <= ||R| |r|| / (1 - kappa),
//!   and |r| <= |fl(e_1 - L x)| + gamma (e_1 + |L| |x|) + E |x|.
//!
//! So lambda* = x + delta lies within rad_i of x_i. Crossed when x_i > rad_i for every i
//! (lambda* > 0: no tie, whatever the tie rule), outside when some x_i < -rad_i; else
//! uncertain. Every bound is computed upward (times `grow`, plus `tiny`: [`Margins`]), and non-finite values fail
//! every comparison towards uncertain.

use super::UNROLLED_MAX;
use crate::expr::certified::DeviceReal;

/// The verdict: crossed for every matrix within the bounds.
pub const CROSSED: u32 = 0;
/// The verdict: outside (L* nonsingular, some lambda*_i < 0) for every matrix within the
/// bounds.
pub const OUTSIDE: u32 = 1;
/// The proof failed: decide elsewhere.
pub const UNCERTAIN: u32 = 2;

/// Bounds above this fail the certificate (a power of two, finite in f32 with room).
pub const BIG: f64 = 1.2676506002282294e30; // 2^100

/// Largest contraction kappa the certificate accepts: 1 / (1 - kappa) <= 2.
pub const MAX_CONTRACTION: f64 = 0.5;

/// The constants of the certificate for n x n matrices in a float type of unit roundoff
/// `unit` whose values below `min_normal` may be flushed to zero.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Margins {
    /// Bound on gamma_{n+1} = (n + 1) u / (1 - (n + 1) u): the relative error of a dot
    /// product of n + 1 terms (with or without fused multiply-adds).
    pub gamma: f64,
    /// Factor on a computed sum of at most 2n + 4 non-negative terms that makes it an upper
    /// bound of the exact sum (with the rounding of the factor itself).
    pub grow: f64,
    /// Absolute term for underflow and flushed subnormals in such a sum.
    pub tiny: f64,
}

impl Margins {
    /// The margins for n x n matrices.
    pub fn new(n: usize, unit: f64, min_normal: f64) -> Self {
        let m = (2 * n + 4) as f64;
        Margins {
            gamma: 2.0 * (n + 2) as f64 * unit,
            grow: 1.0 + 8.0 * m * unit,
            tiny: 8.0 * (m + 2.0) * min_normal,
        }
    }

    /// The margins for type R in IEEE arithmetic (the CPU's).
    pub fn of<R: DeviceReal>(n: usize) -> Self {
        Margins::new(n, R::UNIT, R::MIN_NORMAL)
    }

    /// The margins for type R on any conforming device: at the unit the specifications
    /// promise ([`DeviceReal::SPEC_UNIT`]), which for f64 is f32's.
    pub fn device<R: DeviceReal>(n: usize) -> Self {
        Margins::new(n, R::SPEC_UNIT, R::MIN_NORMAL)
    }
}

/// The margins in R, for the arithmetic.
struct In<R> {
    gamma: R,
    grow: R,
    tiny: R,
}

impl<R: DeviceReal> In<R> {
    fn new(m: &Margins) -> Self {
        In {
            gamma: R::of_up(m.gamma),
            grow: R::of_up(m.grow),
            tiny: R::of_up(m.tiny),
        }
    }

    /// An upper bound of the exact value of a non-negative sum computed as `x`.
    #[inline(always)]
    fn up(&self, x: R) -> R {
        x.mul(self.grow).add(self.tiny)
    }
}

/// Gauss-Jordan inversion with partial pivoting of the n x n row-major `a` (destroyed) into
/// `inv`, in R: false when a pivot is at most n ulps of the largest entry. The steps of the
/// solve shaders (`shaders/gauss_jordan.wgsl`) and of the f64 fast path. Inlined, so that a
/// constant n unrolls.
#[inline(always)]
pub fn gauss_jordan<R: DeviceReal>(n: usize, a: &mut [R], inv: &mut [R]) -> bool {
    let zero = R::of(0.0);
    inv[..n * n].fill(zero);
    for i in 0..n {
        inv[i * n + i] = R::of(1.0);
    }
    let scale = a[..n * n]
        .iter()
        .fold(zero, |m, &v| if v.abs() > m { v.abs() } else { m });
    let tiny = scale.mul(R::of(2.0 * R::UNIT)).mul(R::of(n as f64));
    for c in 0..n {
        let mut p = c;
        for r in c + 1..n {
            if a[r * n + c].abs() > a[p * n + c].abs() {
                p = r;
            }
        }
        if !(a[p * n + c].abs() > tiny) {
            return false;
        }
        if p != c {
            for t in 0..n {
                a.swap(p * n + t, c * n + t);
                inv.swap(p * n + t, c * n + t);
            }
        }
        let r_piv = R::of(1.0).div(a[c * n + c]);
        for t in c..n {
            a[c * n + t] = a[c * n + t].mul(r_piv);
        }
        for t in 0..n {
            inv[c * n + t] = inv[c * n + t].mul(r_piv);
        }
        if n <= UNROLLED_MAX {
            // Entry by entry: a constant n unrolls completely.
            for r in 0..n {
                if r == c {
                    continue;
                }
                let f = a[r * n + c];
                if f == zero {
                    continue;
                }
                for t in c..n {
                    a[r * n + t] = a[r * n + t].sub(f.mul(a[c * n + t]));
                }
                for t in 0..n {
                    inv[r * n + t] = inv[r * n + t].sub(f.mul(inv[c * n + t]));
                }
            }
            continue;
        }
        // Larger n: the other rows in order, each minus f times the pivot row, as slices so
        // that the loops vectorise (the same operations on each entry).
        let (a_above, a_rest) = a[..n * n].split_at_mut(c * n);
        let (a_piv, a_below) = a_rest.split_at_mut(n);
        let (i_above, i_rest) = inv[..n * n].split_at_mut(c * n);
        let (i_piv, i_below) = i_rest.split_at_mut(n);
        let a_rows = a_above
            .chunks_exact_mut(n)
            .chain(a_below.chunks_exact_mut(n));
        let i_rows = i_above
            .chunks_exact_mut(n)
            .chain(i_below.chunks_exact_mut(n));
        for (ar, ir) in a_rows.zip(i_rows) {
            let f = ar[c];
            if f == zero {
                continue;
            }
            for (x, &y) in ar[c..].iter_mut().zip(&a_piv[c..]) {
                *x = x.sub(f.mul(y));
            }
            for (x, &y) in ir.iter_mut().zip(i_piv.iter()) {
                *x = x.sub(f.mul(y));
            }
        }
    }
    true
}

/// The certificate for the n x n matrix `l` (row 0 all ones), entry bounds `e` (row 0
/// zero) and approximate inverse `inv`: [`CROSSED`], [`OUTSIDE`] or [`UNCERTAIN`].
pub fn certify<R: DeviceReal>(n: usize, l: &[R], e: &[R], inv: &[R], margins: &Margins) -> u32 {
    certify_steps::<R, true>(n, l, e, inv, margins)
}

/// The certificate for `l` itself (E = 0): the verdict of the exact matrix at hand, as the
/// f64 fast path of [`crate::cpu::solve`] takes it. Inlined, so that a constant n unrolls.
#[inline(always)]
pub fn certify_exact<R: DeviceReal>(n: usize, l: &[R], inv: &[R], margins: &Margins) -> u32 {
    certify_steps::<R, false>(n, l, &[], inv, margins)
}

/// [`certify`], with the terms of E left out when not `BOUNDED` (`e` is then not read). Its
/// work space lives on the stack up to n = [`MAX_N`], on the heap above (the CPU fast path
/// serves every k).
#[inline(always)]
fn certify_steps<R: DeviceReal, const BOUNDED: bool>(
    n: usize,
    l: &[R],
    e: &[R],
    inv: &[R],
    margins: &Margins,
) -> u32 {
    if n <= MAX_N {
        let mut work = [R::of(0.0); 6 * MAX_N];
        certify_in::<R, BOUNDED>(n, l, e, inv, margins, &mut work)
    } else {
        let mut work = vec![R::of(0.0); 6 * n];
        certify_in::<R, BOUNDED>(n, l, e, inv, margins, &mut work)
    }
}

/// [`certify_steps`] with its work space `work` (at least 6 n entries).
#[inline(always)]
fn certify_in<R: DeviceReal, const BOUNDED: bool>(
    n: usize,
    l: &[R],
    e: &[R],
    inv: &[R],
    margins: &Margins,
    work: &mut [R],
) -> u32 {
    let (rho, work) = work.split_at_mut(n);
    let (s, work) = work.split_at_mut(n);
    let (se, work) = work.split_at_mut(n);
    let (kappa, work) = work.split_at_mut(n);
    let (z, acc) = work.split_at_mut(n);
    let acc = &mut acc[..n];
    let m = In::<R>::new(margins);
    let zero = R::of(0.0);
    let one = R::of(1.0);
    let big = R::of(BIG);
    let delta = |i: usize, j: usize| if i == j { one } else { zero };
    let x = |j: usize| inv[j * n];
    // rho >= |e_1 - L* x|.
    for i in 0..n {
        let (mut acc, mut mag, mut eb) = (delta(i, 0), delta(i, 0), zero);
        for j in 0..n {
            let (lij, xj) = (l[i * n + j], x(j));
            acc = acc.sub(lij.mul(xj));
            mag = mag.add(lij.abs().mul(xj.abs()));
            if BOUNDED {
                eb = eb.add(e[i * n + j].mul(xj.abs()));
            }
        }
        rho[i] = m.up(acc.abs().add(m.gamma.mul(mag)).add(eb));
    }
    // kappa_i >= row sums of |I - R L*|: of |fl(I - R L)| entry by entry, and of the other
    // two terms through the row sums s = |L| 1 and se = E 1 (the row sum of |R| |L| is
    // |R| s): O(n^2) instead of O(n^3). z >= |R| rho.
    // Both rounded up: they are factors below.
    for t in 0..n {
        let (mut st, mut set) = (zero, zero);
        for j in 0..n {
            st = st.add(l[t * n + j].abs());
            if BOUNDED {
                set = set.add(e[t * n + j]);
            }
        }
        s[t] = m.up(st);
        se[t] = m.up(set);
    }
    let mut zmax = zero;
    for i in 0..n {
        // Row i of |I - R L*|, summed. Each entry is accumulated over t in order: entry by
        // entry for a constant n (it unrolls), else a row of L at a time (it vectorises).
        let mut computed = zero;
        if n <= UNROLLED_MAX {
            for j in 0..n {
                let mut acc = delta(i, j);
                for t in 0..n {
                    acc = acc.sub(inv[i * n + t].mul(l[t * n + j]));
                }
                computed = computed.add(acc.abs());
            }
        } else {
            for (j, a) in acc.iter_mut().enumerate() {
                *a = delta(i, j);
            }
            for t in 0..n {
                let rit = inv[i * n + t];
                for (a, &ltj) in acc.iter_mut().zip(&l[t * n..(t + 1) * n]) {
                    *a = a.sub(rit.mul(ltj));
                }
            }
            computed = acc.iter().fold(zero, |c, a| c.add(a.abs()));
        }
        let (mut mag, mut eb) = (one, zero);
        for t in 0..n {
            let rit = inv[i * n + t].abs();
            mag = mag.add(rit.mul(s[t]));
            if BOUNDED {
                eb = eb.add(rit.mul(se[t]));
            }
        }
        let row = m.up(computed).add(m.gamma.mul(m.up(mag))).add(m.up(eb));
        kappa[i] = m.up(row);
        if !(kappa[i] <= R::of(MAX_CONTRACTION)) {
            return UNCERTAIN;
        }
        let mut zi = zero;
        for j in 0..n {
            zi = zi.add(inv[i * n + j].abs().mul(rho[j]));
        }
        z[i] = m.up(zi);
        if !(z[i] <= big) {
            return UNCERTAIN;
        }
        if z[i] > zmax {
            zmax = z[i];
        }
    }
    // ||delta|| <= zmax / (1 - kappa) <= 2 zmax.
    let norm = m.up(zmax.mul(R::of(2.0)));
    let mut verdict = CROSSED;
    for i in 0..n {
        let rad = m.up(z[i].add(kappa[i].mul(norm)));
        let xi = x(i);
        if xi < zero.sub(rad) {
            return OUTSIDE;
        }
        if !(xi > rad) {
            verdict = UNCERTAIN;
        }
    }
    verdict
}

/// Largest n = k + 1 the certificate's fixed-size work space holds.
pub const MAX_N: usize = 16;

/// Work space for [`CertifiedSolver::solve`], in R.
#[derive(Clone, Debug)]
pub struct CertifiedSolver<R> {
    n: usize,
    margins: Margins,
    a: Vec<R>,
    inv: Vec<R>,
}

impl<R: DeviceReal> CertifiedSolver<R> {
    /// Work space for k-simplices (n = k + 1 <= [`MAX_N`]), with the margins of any
    /// conforming device ([`Margins::device`]): the twin of the certified solve shader.
    pub fn new(k: usize) -> Self {
        Self::with_margins(k, Margins::device::<R>(k + 1))
    }

    /// [`CertifiedSolver::new`] with other margins.
    pub fn with_margins(k: usize, margins: Margins) -> Self {
        let n = k + 1;
        assert!(n <= MAX_N, "the certificate holds k <= {}", MAX_N - 1);
        CertifiedSolver {
            n,
            margins,
            a: vec![R::of(0.0); n * n],
            inv: vec![R::of(0.0); n * n],
        }
    }

    /// Inverts `l` (n x n, row 0 ones) by Gauss-Jordan in R and certifies the verdict for
    /// every matrix within `e` of it; writes x = R e_1 into `lambda` (zeros when the
    /// inversion failed).
    pub fn solve(&mut self, l: &[R], e: &[R], lambda: &mut [R]) -> u32 {
        let n = self.n;
        self.a.copy_from_slice(&l[..n * n]);
        if !gauss_jordan(n, &mut self.a, &mut self.inv) {
            lambda[..n].fill(R::of(0.0));
            return UNCERTAIN;
        }
        for i in 0..n {
            lambda[i] = self.inv[i * n];
        }
        certify(n, l, e, &self.inv, &self.margins)
    }
}

/// Rows 1..=k of L and of its entry bounds E for one simplex, as the certified solve takes
/// them, in values of R (widened to f64): F_j\[c\] = `val(j, c)` within `bound(j, c)`. Each
/// row is scaled by a power of two near 1 / max_j (|F_j\[c\]| + bound) (neither lambda nor the
/// verdict change), L's entries rounded to R with the rounding added to E, E rounded up,
/// and every bound grown by two of R's smallest normals (flushed subnormals). False when a
/// value or a bound is not finite: the simplex is then uncertain.
pub fn pack_rows<R: DeviceReal>(
    k: usize,
    val: impl Fn(usize, usize) -> f64,
    bound: impl Fn(usize, usize) -> f64,
    l_out: &mut [f64],
    e_out: &mut [f64],
) -> bool {
    let n = k + 1;
    for c in 0..k {
        let mut big = 0.0f64;
        for j in 0..n {
            let (v, e) = (val(j, c), bound(j, c));
            if !(v.is_finite() && e.is_finite()) {
                return false;
            }
            big = big.max(v.abs() + e);
        }
        let s = crate::linalg::pow2_inverse(big);
        for j in 0..n {
            let lv = val(j, c) * s;
            let lr = R::of(lv).wide();
            let ev =
                (bound(j, c) * s + (lr - lv).abs() + 2.0 * R::MIN_NORMAL) * (1.0 + 2f64.powi(-50));
            l_out[c * n + j] = lr;
            e_out[c * n + j] = R::of_up(ev).wide();
        }
    }
    true
}
