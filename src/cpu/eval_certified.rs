//! The CPU twin of the certified vertex shader (`shaders/eval_certified.wgsl`): the device's
//! lattice-to-R^d map and f under the rules of [`crate::expr::certified`], in the device's
//! float type.

use crate::expr::certified::{certified_eval, lattice_point, Accuracy, Cv, DeviceReal, Rules};
use crate::expr::program::Program;

/// Certified values of f at lattice vertices, computed in R (f32 or f64) as the shader
/// computes them: `lattice` holds n rows of d, `a` and `b` the map x = A u + b (the
/// triangulation's [`affine_map`](crate::triangulation::Triangulation::affine_map)); n rows
/// of `prog.outputs()` pairs (value, bound), widened to f64.
pub fn eval_lattice_certified<R: DeviceReal>(
    prog: &Program,
    acc: &Accuracy,
    a: &[f64],
    b: &[f64],
    lattice: &[i32],
) -> Vec<[f64; 2]> {
    let (d, k) = (prog.dim(), prog.outputs());
    let rules = Rules::<R>::new(acc);
    let zero = Cv::exact(R::of(0.0));
    let (mut x, mut out, mut regs) = (vec![zero; d], vec![zero; k], Vec::new());
    let mut values = Vec::with_capacity(lattice.len() / d.max(1) * k);
    for u in lattice.chunks_exact(d) {
        lattice_point(&rules, a, b, u, &mut x);
        certified_eval(prog, &rules, &x, &mut out, &mut regs);
        values.extend(out.iter().map(|c| [c.v.wide(), c.e.wide()]));
    }
    values
}
