//! The command line's side of the checks before a trace: the warnings it prints.

use isomesh::expr::Problem;

/// The seeds (1-based) at which f's Jacobian is rank-deficient, each warned about.
pub(super) fn singular_seeds(p: &Problem, edge: f64, quiet: bool) -> Vec<usize> {
    let found = isomesh::trace::checks::singular_seeds(&p.system, &p.seeds, edge);
    if !quiet {
        for (i, x) in &found {
            eprintln!(
                "warning: seed {i} projects to {x:?}, where the Jacobian of f is rank-deficient \
                 (a crossing of branches, a cusp): the trace follows at most one branch from \
                 there; move the seed off the singular point, or use --exhaustive"
            );
        }
    }
    found.into_iter().map(|(i, _)| i).collect()
}
