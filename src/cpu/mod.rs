//! The CPU side: the intersection test, the door-in/door-out pivot of tracing, and the twins
//! of the GPU's vertex and scan shaders (the expressions they evaluate are compiled in
//! [`crate::expr::program`]).

/// Evaluates `$body` with `$m` bound to `$n`, in one arm per n = 2..=9 and a general arm
/// for the rest: code inlined into an arm sees n as a constant, so its loops unroll and its
/// bounds checks go, with the same operations in the same order (the same bits).
macro_rules! unrolled {
    ($n:expr, |$m:ident| $body:expr) => {
        unrolled!(@arms $n, $m, $body, 2 3 4 5 6 7 8 9)
    };
    (@arms $n:expr, $m:ident, $body:expr, $($k:literal)*) => {
        match $n {
            $($k => { let $m = $k; $body })*
            $m => $body,
        }
    };
}
pub(crate) use unrolled;

/// The largest n that [`unrolled!`] gives an arm of its own; code that sees a larger n
/// (at run time) takes its loops a row at a time instead.
pub(crate) const UNROLLED_MAX: usize = 9;

pub mod batch;
pub mod certificate;
#[cfg(test)]
mod certificate_fuzz;
#[cfg(test)]
mod fast_path_fuzz;
pub mod pivot;
pub mod solve;
#[cfg(test)]
mod solve_adversarial;

pub mod eval_certified;
#[cfg(any(test, feature = "internals"))]
pub mod eval_vertices;
