//! WGSL emitted from the same DAG the CPU evaluates ([`Program`]), checked by naga before any
//! pipeline sees it.

use std::fmt::Write;

use crate::error::{Error, Result};
use crate::expr::ast::{Op1, Op2};
use crate::expr::program::{Node, Program};

/// The batch-evaluation compute shader; the emitted prelude supplies `real`, `DIM`, `OUTS`
/// and `isomesh_f`.
pub const EVAL_VERTICES_WGSL: &str = include_str!("../../shaders/eval_vertices.wgsl");
/// f64 elementary functions (SPIR-V has no f64 exp, log or trigonometry).
pub const MATH_F64_WGSL: &str = include_str!("../../shaders/math_f64.wgsl");

/// Floating-point width of emitted code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Precision {
    /// 32-bit floats, on every adapter.
    F32,
    /// 64-bit floats, where the adapter has SHADER_F64.
    F64,
}

impl Precision {
    /// The WGSL scalar type.
    pub fn ty(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }

    fn literal(self, v: f64) -> Result<String> {
        let text = match self {
            Precision::F32 => {
                let f = v as f32;
                if !f.is_finite() {
                    return Err(Error::Wgsl(format!("the constant {v} does not fit in f32")));
                }
                format!("{:?}f", f.abs())
            }
            Precision::F64 => format!("{:?}lf", v.abs()),
        };
        Ok(if v.is_sign_negative() {
            format!("(-{text})")
        } else {
            text
        })
    }
}

fn call1(p: Precision, op: Op1, a: &str) -> String {
    let native = match op {
        Op1::Neg => return format!("-{a}"),
        Op1::Sqrt => "sqrt",
        Op1::Abs => "abs",
        Op1::Sign => "sign",
        Op1::Ln => "log",
        other => other.name(),
    };
    let needs_lib = p == Precision::F64 && !matches!(op, Op1::Sqrt | Op1::Abs | Op1::Sign);
    if needs_lib {
        format!("m64_{}({a})", op.name())
    } else {
        format!("{native}({a})")
    }
}

fn call2(p: Precision, op: Op2, a: &str, b: &str) -> String {
    match op {
        Op2::Add => format!("{a} + {b}"),
        Op2::Sub => format!("{a} - {b}"),
        Op2::Mul => format!("{a} * {b}"),
        Op2::Div => format!("{a} / {b}"),
        Op2::Min => format!("min({a}, {b})"),
        Op2::Max => format!("max({a}, {b})"),
        Op2::Pow if p == Precision::F64 => format!("m64_pow({a}, {b})"),
        Op2::Pow => format!("pow({a}, {b})"),
        Op2::Atan2 if p == Precision::F64 => format!("m64_atan2({a}, {b})"),
        Op2::Atan2 => format!("atan2({a}, {b})"),
    }
}

/// `fn NAME(x: array<real, D>) -> array<real, K>` computing the program's outputs; one `let`
/// per DAG node, in the CPU's order; integer powers by the CPU's squaring sequence.
pub fn emit_function(prog: &Program, name: &str, p: Precision) -> Result<String> {
    let ty = p.ty();
    let (d, k) = (prog.dim(), prog.outputs());
    let mut s = String::new();
    let _ = writeln!(
        s,
        "fn {name}(x: array<{ty}, {d}>) -> array<{ty}, {}> {{",
        k.max(1)
    );
    let v = |i: u32| format!("v{i}");
    for (i, node) in prog.nodes().iter().enumerate() {
        let rhs = match *node {
            Node::Var(c) => format!("x[{c}]"),
            Node::Const(c) => p.literal(c)?,
            Node::Un(op, a) => call1(p, op, &v(a)),
            Node::Bin(op, a, b) => call2(p, op, &v(a), &v(b)),
            Node::PowI(a, n) => {
                // Mirror of ast::powi: acc takes the first set bit's power, then multiplies.
                let mut e = n.unsigned_abs();
                let mut base = v(a);
                let mut acc: Option<String> = None;
                let mut t = 0;
                while e > 0 {
                    if e & 1 == 1 {
                        acc = Some(match acc {
                            None => base.clone(),
                            Some(prev) => {
                                let name = format!("p{i}_{t}");
                                t += 1;
                                let _ = writeln!(s, "    let {name} = {prev} * {base};");
                                name
                            }
                        });
                    }
                    e >>= 1;
                    if e > 0 {
                        let name = format!("p{i}_{t}");
                        t += 1;
                        let _ = writeln!(s, "    let {name} = {base} * {base};");
                        base = name;
                    }
                }
                let acc = acc.unwrap_or_else(|| p.literal(1.0).unwrap_or_default());
                if n < 0 {
                    format!("{} / {acc}", p.literal(1.0)?)
                } else {
                    acc
                }
            }
        };
        let _ = writeln!(s, "    let v{i}: {ty} = {rhs};");
    }
    let outs: Vec<String> = prog.output_nodes().iter().map(|&o| v(o)).collect();
    let outs = if outs.is_empty() {
        vec![p.literal(0.0)?]
    } else {
        outs
    };
    let _ = writeln!(
        s,
        "    return array<{ty}, {}>({});\n}}",
        k.max(1),
        outs.join(", ")
    );
    Ok(s)
}

/// The vertex-evaluation shader for `prog` (`shaders/eval_vertices.wgsl`: lattice vertices
/// to R^d, then f), validated.
pub fn eval_shader(prog: &Program, p: Precision) -> Result<String> {
    let mut src = String::new();
    let _ = writeln!(
        src,
        "alias real = {ty};\nconst DIM: u32 = {d}u;\nconst OUTS: u32 = {k}u;\nalias Point = array<{ty}, {d}>;",
        ty = p.ty(),
        d = prog.dim(),
        k = prog.outputs().max(1)
    );
    if p == Precision::F64 {
        src.push_str(MATH_F64_WGSL);
    }
    src.push_str(&emit_function(prog, "isomesh_f", p)?);
    src.push_str(EVAL_VERTICES_WGSL);
    validate(&src, p)?;
    Ok(src)
}

/// Parses and validates WGSL with naga; naga's rendered message on failure.
pub fn validate(src: &str, p: Precision) -> Result<naga::Module> {
    let module =
        naga::front::wgsl::parse_str(src).map_err(|e| Error::Wgsl(e.emit_to_string(src)))?;
    let mut caps = naga::valid::Capabilities::empty();
    if p == Precision::F64 {
        caps |= naga::valid::Capabilities::FLOAT64;
    }
    naga::valid::Validator::new(naga::valid::ValidationFlags::all(), caps)
        .validate(&module)
        .map_err(|e| Error::Wgsl(e.emit_to_string(src)))?;
    Ok(module)
}
