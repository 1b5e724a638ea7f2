//! Boxes: where their lattice preimage lies, and how many key bits a coordinate needs.

use crate::expr::ImplicitFunction;
use crate::triangulation::Triangulation;

/// Bits per lattice coordinate in keys when no box bounds the trace.
pub const UNBOUNDED_COORD_BITS: u32 = 20;

/// Whether `x` lies in the closed box.
#[inline]
pub fn in_box(bbox: &[[f64; 2]], x: &[f64]) -> bool {
    bbox.iter().zip(x).all(|([lo, hi], v)| lo <= v && v <= hi)
}

/// How far outside a face of the box row `[lo, hi]` a point still counts as inside: 2^-46 of
/// the row's size (its width or its largest end), well above the rounding of crossing points
/// (a few 2^-53 of it) and below any distance a user's box tells apart (1e-13 of it is not
/// inside).
#[inline]
pub fn box_slack([lo, hi]: [f64; 2]) -> f64 {
    const SLACK: f64 = 1.0 / (1u64 << 46) as f64;
    SLACK * (hi - lo).max(lo.abs()).max(hi.abs())
}

/// Whether `x` lies in the closed box up to [`box_slack`].
#[inline]
pub fn in_box_closed(bbox: &[[f64; 2]], x: &[f64]) -> bool {
    bbox.iter().zip(x).all(|(&[lo, hi], &v)| {
        let e = box_slack([lo, hi]);
        lo - e <= v && v <= hi + e
    })
}

/// Integer bounds `lo..=hi` per lattice axis on the base vertices of every simplex that can
/// meet the box (the preimage of the box under x = A u + b, rounded outward with a margin).
pub fn lattice_bounds(tri: &Triangulation, bbox: &[[f64; 2]]) -> (Vec<i64>, Vec<i64>) {
    let d = tri.dim();
    let center: Vec<f64> = bbox.iter().map(|[lo, hi]| 0.5 * (lo + hi)).collect();
    let mut uc = vec![0.0; d];
    tri.point_to_lattice(&center, &mut uc);
    // Column j of A^-1 is u(b + e_j).
    let mut radius = vec![0.0; d];
    let mut x = tri.offset().to_vec();
    let mut col = vec![0.0; d];
    for j in 0..d {
        x[j] += 1.0;
        tri.point_to_lattice(&x, &mut col);
        x[j] -= 1.0;
        let half = 0.5 * (bbox[j][1] - bbox[j][0]);
        for i in 0..d {
            radius[i] += col[i].abs() * half;
        }
    }
    // Saturating: a box far beyond the lattice's range gives bounds far beyond any key's,
    // which the callers refuse, not an overflow.
    let lo = (0..d)
        .map(|i| ((uc[i] - radius[i]).floor() as i64).saturating_sub(1))
        .collect();
    let hi = (0..d)
        .map(|i| ((uc[i] + radius[i]).floor() as i64).saturating_add(1))
        .collect();
    (lo, hi)
}

/// Key bits per coordinate for a trace inside `bbox` (or unbounded): enough for every vertex
/// of every simplex that can meet the box, plus a sign bit.
pub fn coord_bits(tri: &Triangulation, bbox: Option<&[[f64; 2]]>) -> u32 {
    match bbox {
        None => UNBOUNDED_COORD_BITS,
        Some(b) => {
            let (lo, hi) = lattice_bounds(tri, b);
            let m = lo
                .iter()
                .chain(&hi)
                .map(|v| v.unsigned_abs() + 2)
                .max()
                .unwrap_or(2);
            (u64::BITS - m.leading_zeros() + 1).clamp(4, 32)
        }
    }
}

/// Where M-hat is kept: the box (if any) and the boundary inequalities g_i(x) >= 0 of f (if
/// any). A crossing point outside it ends the trace there and becomes a boundary crossing.
#[derive(Clone, Copy)]
pub struct Domain<'a> {
    /// The box.
    pub bbox: Option<&'a [[f64; 2]]>,
    f: &'a dyn ImplicitFunction,
    constraints: usize,
}

impl<'a> Domain<'a> {
    /// The domain of `f`'s boundary inequalities inside `bbox`.
    pub fn new(f: &'a dyn ImplicitFunction, bbox: Option<&'a [[f64; 2]]>) -> Self {
        let constraints = bbox.map_or(0, |b| 2 * b.len()) + f.boundary_count();
        Domain {
            bbox,
            f,
            constraints,
        }
    }

    /// Whether `f` has boundary inequalities (besides the box).
    pub fn has_inequalities(&self) -> bool {
        self.f.boundary_count() > 0
    }

    /// Whether every point is inside (no box, no inequality).
    pub fn is_everywhere(&self) -> bool {
        self.constraints == 0
    }

    /// The constraint values at `x` (box margins x_i - lo_i, hi_i - x_i, then the g_i):
    /// `x` is inside when all are >= 0.
    fn values(&self, x: &[f64], out: &mut Vec<f64>) {
        out.clear();
        if let Some(b) = self.bbox {
            for ([lo, hi], v) in b.iter().zip(x) {
                out.push(v - lo);
                out.push(hi - v);
            }
        }
        let start = out.len();
        out.resize(self.constraints, 0.0);
        if start < self.constraints {
            self.f.eval_boundary(x, &mut out[start..]);
        }
    }

    /// Whether `x` lies in the domain (a NaN constraint value counts as outside). The box
    /// is closed up to rounding: a point within [`box_slack`] of a face is inside, so that a
    /// piece of M lying in a face is kept whole, not cut apart by the rounding of its points.
    pub fn contains(&self, x: &[f64]) -> bool {
        if let Some(b) = self.bbox {
            if !in_box_closed(b, x) {
                return false;
            }
        }
        if self.f.boundary_count() == 0 {
            return true;
        }
        let mut g = [0.0f64; 16];
        let n = self.f.boundary_count();
        if n <= g.len() {
            self.f.eval_boundary(x, &mut g[..n]);
            g[..n].iter().all(|&v| v >= 0.0)
        } else {
            let mut g = vec![0.0; n];
            self.f.eval_boundary(x, &mut g);
            g.iter().all(|&v| v >= 0.0)
        }
    }

    /// For `a` inside and `b` outside, the fraction t in [0, 1] of the way from a to b where
    /// the segment leaves the domain: the first constraint to reach 0, each interpolated
    /// linearly between its values at a and b.
    pub fn exit(&self, a: &[f64], b: &[f64]) -> f64 {
        let (mut va, mut vb) = (Vec::new(), Vec::new());
        self.values(a, &mut va);
        self.values(b, &mut vb);
        // The constraints b breaks; a box margin within rounding of 0 is not broken.
        let slack = |i: usize| match self.bbox {
            Some(bx) if i < 2 * bx.len() => box_slack(bx[i / 2]),
            _ => 0.0,
        };
        va.iter()
            .zip(&vb)
            .enumerate()
            .filter(|&(i, (_, &y))| y < -slack(i) || y.is_nan())
            .map(|(_, pair)| pair)
            .map(|(&x, &y)| {
                let t = x / (x - y);
                if t.is_finite() {
                    t.clamp(0.0, 1.0)
                } else {
                    0.0
                }
            })
            .fold(1.0, f64::min)
    }
}
