//! Checks of a problem before it is traced, shared by every caller (the command line, the
//! library's `Mesher`, Python): equations that are identically zero, and seeds where f's
//! Jacobian is rank-deficient.

use crate::expr::{is_singular_at, newton_project, zero_equation_at, ImplicitFunction};
use crate::{Error, Result};

use super::SEED_TOLERANCE;

/// Points where f is tried for being identically 0: 64 points of the box, or within 100
/// edges (at least a millionth of their size) of the seeds when there is no box (seeded, so
/// the same each run).
fn probe_points(d: usize, bbox: Option<&[[f64; 2]]>, seeds: &[Vec<f64>], edge: f64) -> Vec<f64> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut pts = Vec::with_capacity(64 * d);
    // Boxes and seeds of another dimension are the trace's to refuse, with its message.
    let bbox = bbox.filter(|b| b.len() == d);
    let seeds: Vec<&Vec<f64>> = seeds.iter().filter(|s| s.len() == d).collect();
    for i in 0..64 {
        for c in 0..d {
            let (lo, hi) = match (bbox, seeds.get(i % seeds.len().max(1))) {
                (Some(b), _) => (b[c][0], b[c][1]),
                (None, Some(s)) => {
                    // Wide enough to move every coordinate, however fine the edge (and no
                    // wider than the numbers go, however coarse).
                    let r = (100.0 * edge).max(1e-6 * s[c].abs().max(1.0)).min(1e300);
                    (s[c] - r, s[c] + r)
                }
                (None, None) => return pts,
            };
            // A blend of the ends: finite for any finite ends, however far apart.
            let t: f64 = rng.random();
            pts.push(lo * (1.0 - t) + hi * t);
        }
    }
    pts
}

/// Refuses an equation of `f` that is 0 at every probe point (in the box, or around the
/// seeds): its zero set is no manifold, and tracing it would report every simplex as
/// degenerate.
pub fn check_not_zero(
    f: &dyn ImplicitFunction,
    bbox: Option<&[[f64; 2]]>,
    seeds: &[Vec<f64>],
    edge: f64,
) -> Result<()> {
    let d = f.ambient_dim();
    let pts = probe_points(d, bbox, seeds, edge);
    match zero_equation_at(f, &pts) {
        Some(i) => Err(Error::Spec(format!(
            "equation {} is 0 at all of {} points tried {}: it is identically 0 there, and its \
             zero set is no manifold",
            i + 1,
            pts.len() / d,
            if bbox.is_some() {
                "in the box"
            } else {
                "around the seeds"
            }
        ))),
        None => Ok(()),
    }
}

/// The seeds (1-based, with the points they project to) at which f's Jacobian is
/// rank-deficient: a crossing of branches or a cusp, from which a trace follows at most one
/// branch.
pub fn singular_seeds(
    f: &dyn ImplicitFunction,
    seeds: &[Vec<f64>],
    edge: f64,
) -> Vec<(usize, Vec<f64>)> {
    seeds
        .iter()
        .enumerate()
        .filter_map(|(i, s)| {
            let x = newton_project(f, s, SEED_TOLERANCE).ok()?;
            is_singular_at(f, &x, edge).then_some((i + 1, x))
        })
        .collect()
}

/// The equation of `f` (from 0) that is 0 at `x` and at `x` +- `h` along every axis, if one
/// is: f vanishes on a neighbourhood of `x`, not only on M.
pub fn vanishes_around(f: &dyn ImplicitFunction, x: &[f64], h: f64) -> Option<usize> {
    let d = x.len();
    let mut pts = Vec::with_capacity((2 * d + 1) * d);
    pts.extend_from_slice(x);
    for j in 0..d {
        for s in [-h, h] {
            pts.extend_from_slice(x);
            let n = pts.len();
            pts[n - d + j] += s;
        }
    }
    zero_equation_at(f, &pts)
}

/// Looks at the candidates `status` (rows of k + 1 indices into `values`, k values per
/// vertex) for a simplex where f is 0 at every vertex, and when there is one, whether f
/// vanishes around its first vertex (`coords` gives a vertex's coordinates by index):
/// the equation and the point, for [`super::TraceStats::zero_region`].
pub(crate) fn zero_region(
    f: &dyn ImplicitFunction,
    status: &[crate::cpu::solve::Status],
    rows: &[u32],
    values: &[f64],
    edge: f64,
    coords: impl Fn(usize, &mut [f64]),
) -> Option<(usize, Vec<f64>)> {
    let (d, k) = (f.ambient_dim(), f.codim());
    let n = k + 1;
    status
        .iter()
        .enumerate()
        .filter(|(_, s)| **s == crate::cpu::solve::Status::Degenerate)
        .map(|(i, _)| &rows[i * n..(i + 1) * n])
        .find_map(|row| {
            let zero = row.iter().all(|&v| {
                let v = v as usize;
                values[v * k..(v + 1) * k].iter().all(|&y| y == 0.0)
            });
            if !zero {
                return None;
            }
            let mut x = vec![0.0; d];
            coords(row[0] as usize, &mut x);
            vanishes_around(f, &x, 0.25 * edge).map(|i| (i, x))
        })
}

/// The error for f vanishing on a region: equation `i` (from 0) is identically 0 around `x`.
pub fn region_error(i: usize, x: &[f64]) -> Error {
    let at: Vec<String> = x.iter().map(|v| format!("{v:.6}")).collect();
    Error::Spec(format!(
        "equation {} is identically 0 around ({}): its zero set there is a region, not a \
         manifold, and a mesh of it would not be M (restrict the box or change f)",
        i + 1,
        at.join(", ")
    ))
}
