//! The CPU twin of the GPU's vertex shader (`shaders/eval_vertices.wgsl`): lattice vertices
//! to R^d through a dense affine map, then f, with the same operations in the same order.

use crate::expr::program::{Program, Scratch};

/// f at lattice vertices: `lattice` holds n rows of d integer coordinates, `a` (d x d,
/// row-major) and `b` the affine map x = A u + b, `out` gets n rows of `prog.outputs()`.
/// Each x_r is summed as the shader does: a_r0 u_0 + a_r1 u_1 + ... then + b_r.
pub fn eval_lattice(prog: &Program, a: &[f64], b: &[f64], lattice: &[i32], out: &mut [f64]) {
    let d = prog.dim();
    let n = lattice.len().checked_div(d).unwrap_or(0);
    let mut x = vec![0.0; n * d];
    for (u, p) in lattice.chunks_exact(d).zip(x.chunks_exact_mut(d)) {
        for (r, xr) in p.iter_mut().enumerate() {
            let row = &a[r * d..(r + 1) * d];
            let mut acc = row[0] * u[0] as f64;
            for c in 1..d {
                acc += row[c] * u[c] as f64;
            }
            *xr = acc + b[r];
        }
    }
    prog.eval_batch(&x, out, &mut Scratch::default());
}
