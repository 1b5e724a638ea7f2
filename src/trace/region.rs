//! Boxes: where their lattice preimage lies, and how many key bits a coordinate needs.

use crate::triangulation::Triangulation;

/// Bits per lattice coordinate in keys when no box bounds the trace.
pub const UNBOUNDED_COORD_BITS: u32 = 20;

/// Whether `x` lies in the closed box.
#[inline]
pub fn in_box(bbox: &[[f64; 2]], x: &[f64]) -> bool {
    bbox.iter().zip(x).all(|([lo, hi], v)| lo <= v && v <= hi)
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
    let lo = (0..d)
        .map(|i| (uc[i] - radius[i]).floor() as i64 - 1)
        .collect();
    let hi = (0..d)
        .map(|i| (uc[i] + radius[i]).floor() as i64 + 1)
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
