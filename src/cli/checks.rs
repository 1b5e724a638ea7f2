//! Checks of a problem before it is traced: equations that are identically zero, and seeds
//! where f's Jacobian is rank-deficient.

use isomesh::expr::Problem;
use isomesh::{Error, Result};

/// Points where `p`'s equations are tried for being identically 0: 64 points of the box, or
/// within 100 edges (at least a millionth of their size) of the seeds when there is no box
/// (seeded, so the same each run).
fn probe_points(p: &Problem, edge: f64) -> Vec<f64> {
    use rand::{Rng, SeedableRng};
    let d = p.dim();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut pts = Vec::with_capacity(64 * d);
    for i in 0..64 {
        for c in 0..d {
            let (lo, hi) = match (&p.bbox, p.seeds.get(i % p.seeds.len().max(1))) {
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

/// Refuses an equation that is 0 at every probe point: its zero set is no manifold, and
/// tracing it would report every simplex as degenerate.
pub(super) fn check_not_zero(
    p: &Problem,
    tri: &isomesh::triangulation::Triangulation,
) -> Result<()> {
    let pts = probe_points(p, tri.edge());
    match isomesh::expr::zero_equation_at(&p.system, &pts) {
        Some(i) => Err(Error::Spec(format!(
            "equation {} is 0 at all of {} points tried {}: it is identically 0 there, and its \
             zero set is no manifold",
            i + 1,
            pts.len() / p.dim(),
            if p.bbox.is_some() {
                "in the box"
            } else {
                "around the seeds"
            }
        ))),
        None => Ok(()),
    }
}

/// The seeds (1-based) at which f's Jacobian is rank-deficient, each warned about.
pub(super) fn singular_seeds(p: &Problem, edge: f64, quiet: bool) -> Vec<usize> {
    let mut out = Vec::new();
    for (i, s) in p.seeds.iter().enumerate() {
        let Ok(x) = isomesh::expr::newton_project(&p.system, s, isomesh::trace::SEED_TOLERANCE)
        else {
            continue;
        };
        if isomesh::expr::is_singular_at(&p.system, &x, edge) {
            out.push(i + 1);
            if !quiet {
                eprintln!(
                    "warning: seed {} projects to {x:?}, where the Jacobian of f is \
                     rank-deficient (a crossing of branches, a cusp): the trace follows at most \
                     one branch from there; move the seed off the singular point",
                    i + 1
                );
            }
        }
    }
    out
}
