//! Random expression trees, for the tests that compile, emit or certify many of them.

use isomesh::expr::{Expr, Op1, Op2};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// A random expression tree over `d` variables.
pub fn random_expr(rng: &mut ChaCha8Rng, d: usize, depth: usize) -> Expr {
    if depth == 0 || rng.random_bool(0.2) {
        return if rng.random_bool(0.6) {
            Expr::Var(rng.random_range(0..d))
        } else {
            Expr::Num(rng.random_range(-5.0..5.0))
        };
    }
    const OPS1: [Op1; 15] = [
        Op1::Neg,
        Op1::Sin,
        Op1::Cos,
        Op1::Tan,
        Op1::Asin,
        Op1::Acos,
        Op1::Atan,
        Op1::Sinh,
        Op1::Cosh,
        Op1::Tanh,
        Op1::Exp,
        Op1::Ln,
        Op1::Sqrt,
        Op1::Abs,
        Op1::Sign,
    ];
    const OPS2: [Op2; 8] = [
        Op2::Add,
        Op2::Sub,
        Op2::Mul,
        Op2::Div,
        Op2::Pow,
        Op2::Atan2,
        Op2::Min,
        Op2::Max,
    ];
    match rng.random_range(0..3) {
        0 => Expr::un(
            OPS1[rng.random_range(0..OPS1.len())],
            random_expr(rng, d, depth - 1),
        ),
        1 => Expr::powi(random_expr(rng, d, depth - 1), rng.random_range(-5..7)),
        _ => Expr::bin(
            OPS2[rng.random_range(0..OPS2.len())],
            random_expr(rng, d, depth - 1),
            random_expr(rng, d, depth - 1),
        ),
    }
}
