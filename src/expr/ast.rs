//! Expression trees: simplifying constructors (constant folding, neutral elements), direct
//! evaluation for reference, and symbolic differentiation.

use std::fmt;

use crate::memory::Ticks;

/// A one-argument operation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Op1 {
    /// -a
    Neg,
    /// sin a
    Sin,
    /// cos a
    Cos,
    /// tan a
    Tan,
    /// asin a
    Asin,
    /// acos a
    Acos,
    /// atan a
    Atan,
    /// sinh a
    Sinh,
    /// cosh a
    Cosh,
    /// tanh a
    Tanh,
    /// exp a
    Exp,
    /// natural logarithm
    Ln,
    /// square root
    Sqrt,
    /// |a|
    Abs,
    /// -1, 0 or 1
    Sign,
}

/// A two-argument operation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Op2 {
    /// a + b
    Add,
    /// a - b
    Sub,
    /// a * b
    Mul,
    /// a / b
    Div,
    /// a ^ b (real exponent)
    Pow,
    /// atan2(a, b): the angle of (b, a)
    Atan2,
    /// min(a, b)
    Min,
    /// max(a, b)
    Max,
}

/// An expression over variables x_1..x_d (indices from 0).
#[derive(Clone, Debug, PartialEq)]
pub enum Expr {
    /// A constant.
    Num(f64),
    /// Variable by 0-based index.
    Var(usize),
    /// One-argument operation.
    Un(Op1, Box<Expr>),
    /// Two-argument operation.
    Bin(Op2, Box<Expr>, Box<Expr>),
    /// Integer power, computed by repeated squaring (the same sequence on CPU and GPU).
    PowI(Box<Expr>, i32),
}

impl Op1 {
    /// Applies the operation to a number.
    #[inline]
    pub fn apply(self, a: f64) -> f64 {
        match self {
            Op1::Neg => -a,
            Op1::Sin => a.sin(),
            Op1::Cos => a.cos(),
            Op1::Tan => a.tan(),
            Op1::Asin => a.asin(),
            Op1::Acos => a.acos(),
            Op1::Atan => a.atan(),
            Op1::Sinh => a.sinh(),
            Op1::Cosh => a.cosh(),
            Op1::Tanh => a.tanh(),
            Op1::Exp => a.exp(),
            Op1::Ln => a.ln(),
            Op1::Sqrt => a.sqrt(),
            Op1::Abs => a.abs(),
            Op1::Sign => {
                if a > 0.0 {
                    1.0
                } else if a < 0.0 {
                    -1.0
                } else {
                    a * 0.0
                }
            }
        }
    }

    /// The function's name in the language (and in WGSL, but for `ln`).
    pub fn name(self) -> &'static str {
        match self {
            Op1::Neg => "-",
            Op1::Sin => "sin",
            Op1::Cos => "cos",
            Op1::Tan => "tan",
            Op1::Asin => "asin",
            Op1::Acos => "acos",
            Op1::Atan => "atan",
            Op1::Sinh => "sinh",
            Op1::Cosh => "cosh",
            Op1::Tanh => "tanh",
            Op1::Exp => "exp",
            Op1::Ln => "ln",
            Op1::Sqrt => "sqrt",
            Op1::Abs => "abs",
            Op1::Sign => "sign",
        }
    }
}

impl Op2 {
    /// Applies the operation to two numbers.
    #[inline]
    pub fn apply(self, a: f64, b: f64) -> f64 {
        match self {
            Op2::Add => a + b,
            Op2::Sub => a - b,
            Op2::Mul => a * b,
            Op2::Div => a / b,
            Op2::Pow => a.powf(b),
            Op2::Atan2 => a.atan2(b),
            Op2::Min => a.min(b),
            Op2::Max => a.max(b),
        }
    }
}

/// a^n by repeated squaring, in a fixed order shared with the WGSL emitter.
#[inline]
pub fn powi(a: f64, n: i32) -> f64 {
    let mut e = n.unsigned_abs();
    let mut base = a;
    let mut acc = 1.0;
    let mut first = true;
    while e > 0 {
        if e & 1 == 1 {
            acc = if first { base } else { acc * base };
            first = false;
        }
        e >>= 1;
        if e > 0 {
            base = base * base;
        }
    }
    if n < 0 {
        1.0 / acc
    } else {
        acc
    }
}

fn num(v: f64) -> Expr {
    Expr::Num(v)
}

impl Expr {
    /// The constant value, if this is a constant.
    pub fn as_num(&self) -> Option<f64> {
        match self {
            Expr::Num(v) => Some(*v),
            _ => None,
        }
    }

    fn is(&self, v: f64) -> bool {
        self.as_num() == Some(v)
    }

    /// A one-argument operation, folded when the argument is constant.
    pub fn un(op: Op1, a: Expr) -> Expr {
        if let Some(v) = a.as_num() {
            return num(op.apply(v));
        }
        match (op, a) {
            (Op1::Neg, Expr::Un(Op1::Neg, inner)) => *inner,
            (op, a) => Expr::Un(op, Box::new(a)),
        }
    }

    /// A two-argument operation, folded and simplified.
    pub fn bin(op: Op2, a: Expr, b: Expr) -> Expr {
        if let (Some(x), Some(y)) = (a.as_num(), b.as_num()) {
            return num(op.apply(x, y));
        }
        match op {
            Op2::Add if a.is(0.0) => b,
            Op2::Add | Op2::Sub if b.is(0.0) => a,
            Op2::Add => match b {
                Expr::Un(Op1::Neg, inner) => Expr::bin(Op2::Sub, a, *inner),
                b => Expr::Bin(op, Box::new(a), Box::new(b)),
            },
            Op2::Sub if a.is(0.0) => Expr::un(Op1::Neg, b),
            Op2::Mul if a.is(0.0) || b.is(0.0) => num(0.0),
            Op2::Mul if a.is(1.0) => b,
            Op2::Mul if b.is(1.0) => a,
            Op2::Mul if a.is(-1.0) => Expr::un(Op1::Neg, b),
            Op2::Mul if b.is(-1.0) => Expr::un(Op1::Neg, a),
            Op2::Div if a.is(0.0) => num(0.0),
            Op2::Div if b.is(1.0) => a,
            Op2::Pow => match b.as_num() {
                Some(n) if n.fract() == 0.0 && n.abs() <= 64.0 => Expr::powi(a, n as i32),
                Some(0.5) => Expr::un(Op1::Sqrt, a),
                _ => Expr::Bin(op, Box::new(a), Box::new(b)),
            },
            _ => Expr::Bin(op, Box::new(a), Box::new(b)),
        }
    }

    /// a^n for an integer n.
    pub fn powi(a: Expr, n: i32) -> Expr {
        if let Some(v) = a.as_num() {
            return num(powi(v, n));
        }
        match n {
            0 => num(1.0),
            1 => a,
            _ => match a {
                Expr::PowI(inner, m) if (n as i64 * m as i64).abs() <= 64 => {
                    Expr::PowI(inner, n * m)
                }
                a => Expr::PowI(Box::new(a), n),
            },
        }
    }

    /// Sum.
    #[allow(clippy::should_implement_trait)] // a constructor that simplifies, not an operator
    pub fn add(a: Expr, b: Expr) -> Expr {
        Expr::bin(Op2::Add, a, b)
    }
    /// Difference.
    #[allow(clippy::should_implement_trait)] // a constructor that simplifies, not an operator
    pub fn sub(a: Expr, b: Expr) -> Expr {
        Expr::bin(Op2::Sub, a, b)
    }
    /// Product.
    #[allow(clippy::should_implement_trait)] // a constructor that simplifies, not an operator
    pub fn mul(a: Expr, b: Expr) -> Expr {
        Expr::bin(Op2::Mul, a, b)
    }
    /// Quotient.
    #[allow(clippy::should_implement_trait)] // a constructor that simplifies, not an operator
    pub fn div(a: Expr, b: Expr) -> Expr {
        Expr::bin(Op2::Div, a, b)
    }
    /// Negation.
    #[allow(clippy::should_implement_trait)] // a constructor that simplifies, not an operator
    pub fn neg(a: Expr) -> Expr {
        Expr::un(Op1::Neg, a)
    }

    /// Evaluates at `x` by walking the tree (the reference for the batch evaluator).
    pub fn eval(&self, x: &[f64]) -> f64 {
        match self {
            Expr::Num(v) => *v,
            Expr::Var(i) => x[*i],
            Expr::Un(op, a) => op.apply(a.eval(x)),
            Expr::Bin(op, a, b) => op.apply(a.eval(x), b.eval(x)),
            Expr::PowI(a, n) => powi(a.eval(x), *n),
        }
    }

    /// Largest variable index used, plus one (0 for a constant).
    pub fn arity(&self) -> usize {
        match self {
            Expr::Num(_) => 0,
            Expr::Var(i) => i + 1,
            Expr::Un(_, a) | Expr::PowI(a, _) => a.arity(),
            Expr::Bin(_, a, b) => a.arity().max(b.arity()),
        }
    }

    /// Replaces every variable i by `subs[i]`.
    pub fn substitute(&self, subs: &[Expr]) -> Expr {
        match self {
            Expr::Num(v) => num(*v),
            Expr::Var(i) => subs[*i].clone(),
            Expr::Un(op, a) => Expr::un(*op, a.substitute(subs)),
            Expr::Bin(op, a, b) => Expr::bin(*op, a.substitute(subs), b.substitute(subs)),
            Expr::PowI(a, n) => Expr::powi(a.substitute(subs), *n),
        }
    }

    /// The partial derivative with respect to variable `v`, simplified.
    pub fn diff(&self, v: usize) -> Expr {
        match self.derive(v, &mut Ticks::unchecked()) {
            Ok(e) => e,
            Err(_) => unreachable!("unchecked steps never fail"),
        }
    }

    /// [`Expr::diff`], stopping with the limit once the heap passes this thread's memory
    /// limit (see [`crate::memory::within`]).
    pub fn diff_within_limit(&self, v: usize) -> Result<Expr, crate::Error> {
        self.derive(v, &mut Ticks::checked())
            .map_err(|limit| crate::Error::MemoryLimit {
                what: "differentiating the equations".into(),
                limit,
                advice: "write smaller equations".into(),
            })
    }

    fn derive(&self, v: usize, ticks: &mut Ticks) -> Result<Expr, u64> {
        use Expr as E;
        ticks.tick()?;
        Ok(match self {
            E::Num(_) => num(0.0),
            E::Var(i) => num(if *i == v { 1.0 } else { 0.0 }),
            E::Un(op, a) => {
                let da = a.derive(v, ticks)?;
                if da.is(0.0) {
                    return Ok(num(0.0));
                }
                let a = (**a).clone();
                let outer = match op {
                    Op1::Neg => num(-1.0),
                    Op1::Sin => E::un(Op1::Cos, a),
                    Op1::Cos => E::neg(E::un(Op1::Sin, a)),
                    Op1::Tan => E::powi(E::un(Op1::Cos, a), -2),
                    Op1::Asin => {
                        E::div(num(1.0), E::un(Op1::Sqrt, E::sub(num(1.0), E::powi(a, 2))))
                    }
                    Op1::Acos => {
                        E::div(num(-1.0), E::un(Op1::Sqrt, E::sub(num(1.0), E::powi(a, 2))))
                    }
                    Op1::Atan => E::div(num(1.0), E::add(num(1.0), E::powi(a, 2))),
                    Op1::Sinh => E::un(Op1::Cosh, a),
                    Op1::Cosh => E::un(Op1::Sinh, a),
                    Op1::Tanh => E::sub(num(1.0), E::powi(E::un(Op1::Tanh, a), 2)),
                    Op1::Exp => E::un(Op1::Exp, a),
                    Op1::Ln => E::div(num(1.0), a),
                    Op1::Sqrt => E::div(num(0.5), E::un(Op1::Sqrt, a)),
                    Op1::Abs => E::un(Op1::Sign, a),
                    Op1::Sign => num(0.0),
                };
                E::mul(outer, da)
            }
            E::PowI(a, n) => {
                let da = a.derive(v, ticks)?;
                if da.is(0.0) {
                    return Ok(num(0.0));
                }
                E::mul(E::mul(num(*n as f64), E::powi((**a).clone(), n - 1)), da)
            }
            E::Bin(op, a, b) => {
                let (da, db) = (a.derive(v, ticks)?, b.derive(v, ticks)?);
                if da.is(0.0) && db.is(0.0) {
                    return Ok(num(0.0));
                }
                // Operands are copied only where the derivative uses them (copying them at
                // every level of a sum made long sums quadratic).
                let ab = || ((**a).clone(), (**b).clone());
                match op {
                    Op2::Add => E::add(da, db),
                    Op2::Sub => E::sub(da, db),
                    // A zero derivative's product is zero: its operand is not copied.
                    Op2::Mul => E::add(scaled(da, b), scaled(db, a)),
                    Op2::Div => E::div(
                        E::sub(scaled(da, b), scaled(db, a)),
                        E::powi((**b).clone(), 2),
                    ),
                    Op2::Pow => {
                        // d(a^b) = a^b (b' ln a + b a' / a)
                        let (a, b) = ab();
                        let p = E::bin(Op2::Pow, a.clone(), b.clone());
                        let t1 = E::mul(db, E::un(Op1::Ln, a.clone()));
                        let t2 = E::div(E::mul(b, da), a);
                        E::mul(p, E::add(t1, t2))
                    }
                    Op2::Atan2 => {
                        // atan2(a, b)' = (b a' - a b') / (a^2 + b^2)
                        let (a, b) = ab();
                        let den = E::add(E::powi(a.clone(), 2), E::powi(b.clone(), 2));
                        E::div(E::sub(E::mul(b, da), E::mul(a, db)), den)
                    }
                    Op2::Min | Op2::Max => {
                        // s = sign(a - b); min' = ((1 - s) a' + (1 + s) b') / 2, max swaps.
                        let (a, b) = ab();
                        let s = E::un(Op1::Sign, E::sub(a, b));
                        let (wa, wb) = if *op == Op2::Min {
                            (E::sub(num(1.0), s.clone()), E::add(num(1.0), s))
                        } else {
                            (E::add(num(1.0), s.clone()), E::sub(num(1.0), s))
                        };
                        E::mul(num(0.5), E::add(E::mul(wa, da), E::mul(wb, db)))
                    }
                }
            }
        })
    }
}

/// `d * e`, copying `e` only when `d` is not zero.
fn scaled(d: Expr, e: &Expr) -> Expr {
    if d.is(0.0) {
        num(0.0)
    } else {
        Expr::mul(d, e.clone())
    }
}

impl fmt::Display for Expr {
    /// Fully parenthesised text in the language, which parses back to the same tree.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        Named {
            expr: self,
            names: None,
        }
        .fmt(f)
    }
}

impl Expr {
    /// The expression as text with variable i called `names[i]` (x1, x2... past the list).
    pub fn with_names<'a>(&'a self, names: &'a [String]) -> impl fmt::Display + 'a {
        Named {
            expr: self,
            names: Some(names),
        }
    }
}

/// An expression printed with its variables' names.
struct Named<'a> {
    expr: &'a Expr,
    names: Option<&'a [String]>,
}

impl fmt::Display for Named<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let sub = |expr| Named {
            expr,
            names: self.names,
        };
        match self.expr {
            Expr::Num(v) => {
                if *v < 0.0 {
                    write!(f, "({v:?})")
                } else {
                    write!(f, "{v:?}")
                }
            }
            Expr::Var(i) => match self.names.and_then(|n| n.get(*i)) {
                Some(name) => f.write_str(name),
                None => write!(f, "x{}", i + 1),
            },
            Expr::Un(Op1::Neg, a) => write!(f, "(-{})", sub(a)),
            Expr::Un(op, a) => write!(f, "{}({})", op.name(), sub(a)),
            Expr::PowI(a, n) => write!(f, "({}^{n})", sub(a)),
            Expr::Bin(op, a, b) => {
                let (a, b) = (sub(a), sub(b));
                match op {
                    Op2::Add => write!(f, "({a} + {b})"),
                    Op2::Sub => write!(f, "({a} - {b})"),
                    Op2::Mul => write!(f, "({a} * {b})"),
                    Op2::Div => write!(f, "({a} / {b})"),
                    Op2::Pow => write!(f, "pow({a}, {b})"),
                    Op2::Atan2 => write!(f, "atan2({a}, {b})"),
                    Op2::Min => write!(f, "min({a}, {b})"),
                    Op2::Max => write!(f, "max({a}, {b})"),
                }
            }
        }
    }
}
