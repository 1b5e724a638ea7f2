//! WGSL emitted from the same DAG the CPU evaluates ([`Program`]), checked by naga before any
//! pipeline sees it.

use std::fmt::Write;

use crate::error::{Error, Result};
use crate::expr::ast::{Op1, Op2};
use crate::expr::certified::{lattice_factor, Accuracy, Rules};
use crate::expr::program::{Node, Program};

/// What every compute stage starts with: the uniform `Params` of a dispatch.
const STAGE_WGSL: &str = include_str!("../../shaders/stage.wgsl");

/// Threads per workgroup of every stage: the host dispatches by it, and
/// [`stage_prelude`] gives it to the shaders.
pub(crate) const WORKGROUP: u32 = 64;

/// The prelude of every compute stage: `WORKGROUP` and `Params` ([`STAGE_WGSL`]).
pub(crate) fn stage_prelude() -> String {
    format!("const WORKGROUP: u32 = {WORKGROUP}u;\n{STAGE_WGSL}")
}

/// The batch-evaluation compute shader; the emitted prelude supplies `real`, `DIM`, `OUTS`
/// and `isomesh_f`.
pub const EVAL_VERTICES_WGSL: &str = include_str!("../../shaders/eval_vertices.wgsl");
/// f64 elementary functions (SPIR-V has no f64 exp, log or trigonometry).
pub const MATH_F64_WGSL: &str = include_str!("../../shaders/math_f64.wgsl");
/// The rules of certified evaluation (twin of `expr::certified::Rules`).
pub const CERTIFIED_WGSL: &str = include_str!("../../shaders/certified.wgsl");
/// The certified vertex-evaluation compute shader.
pub const EVAL_CERTIFIED_WGSL: &str = include_str!("../../shaders/eval_certified.wgsl");

/// Floating-point width of emitted code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Precision {
    /// 32-bit floats, on every adapter.
    F32,
    /// 64-bit floats, where the adapter has SHADER_F64.
    F64,
}

impl Precision {
    /// The accuracy certified evaluation assumes of a device computing at this precision.
    pub fn accuracy(self) -> Accuracy {
        match self {
            Precision::F32 => Accuracy::f32(),
            Precision::F64 => Accuracy::f64(),
        }
    }

    /// The WGSL scalar type.
    pub fn ty(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F64 => "f64",
        }
    }

    /// `v` as a WGSL literal of this precision (rounded to nearest in f32).
    pub(crate) fn literal(self, v: f64) -> Result<String> {
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

/// Emits the `let`s of a^|n| by the CPU's squaring sequence ([`crate::expr::ast::powi`]: the
/// accumulator takes the first set bit's power, then multiplies), `mul` writing one product;
/// the name of the result, or None for n = 0. Temporaries are named `p{node}_{t}`.
fn emit_powi(
    s: &mut String,
    node: usize,
    a: String,
    n: i32,
    mul: impl Fn(&str, &str) -> String,
) -> Option<String> {
    let mut e = n.unsigned_abs();
    let mut base = a;
    let mut acc: Option<String> = None;
    let mut t = 0;
    let mut temp = |s: &mut String, rhs: String| {
        let name = format!("p{node}_{t}");
        t += 1;
        let _ = writeln!(s, "    let {name} = {rhs};");
        name
    };
    while e > 0 {
        if e & 1 == 1 {
            acc = Some(match acc {
                None => base.clone(),
                Some(prev) => temp(s, mul(&prev, &base)),
            });
        }
        e >>= 1;
        if e > 0 {
            base = temp(s, mul(&base, &base));
        }
    }
    acc
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
                let acc = emit_powi(&mut s, i, v(a), n, |x, y| format!("{x} * {y}"))
                    .unwrap_or_else(|| p.literal(1.0).unwrap_or_default());
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
    src.push_str(&stage_prelude());
    src.push_str(EVAL_VERTICES_WGSL);
    validate(&src, p)?;
    Ok(src)
}

/// The device primitives the certified rules build on: WGSL's f32 built-ins, whose accuracy
/// the specifications bound (sin and cos after a reduction to [-pi, pi], where that bound
/// holds); in f64, the same built-ins on arguments converted to f32, since no f64 elementary
/// function has a bound any specification promises ([`Accuracy::f64`] adds the conversion).
fn certified_primitives(p: Precision) -> String {
    let lo = (std::f64::consts::TAU - 6.28125) as f32;
    let (to32, back) = match p {
        Precision::F64 => ("f32", "f64"),
        Precision::F32 => ("", ""),
    };
    format!(
        "// x - 2 pi n: n * 6.28125 is exact for |n| < 2^15, and so is the difference.
fn cb_reduce(x: f32) -> f32 {{
    let n = round(x * 0.15915494f);
    let r = (x - n * 6.28125f) - n * {lo:?}f;
    return clamp(r, -3.1415925f, 3.1415925f);
}}
fn cb_dev_exp(x: real) -> real {{ return {back}(exp({to32}(x))); }}
fn cb_dev_ln(x: real) -> real {{ return {back}(log({to32}(x))); }}
fn cb_dev_sin(x: real) -> real {{ return {back}(sin(cb_reduce({to32}(x)))); }}
fn cb_dev_cos(x: real) -> real {{ return {back}(cos(cb_reduce({to32}(x)))); }}
fn cb_dev_atan2(y: real, x: real) -> real {{ return {back}(atan2({to32}(y), {to32}(x))); }}
"
    )
}

/// The CB_* constants of `shaders/certified.wgsl`, from [`Accuracy`].
fn certified_constants(p: Precision, acc: &Accuracy) -> Result<String> {
    let mut s = String::new();
    let consts = [
        ("CB_UNIT", acc.unit),
        ("CB_CPU", acc.cpu),
        ("CB_CPU_FN", acc.cpu_fn),
        ("CB_TINY", acc.tiny),
        ("CB_GROW", acc.grow),
        ("CB_BIG", acc.big),
        ("CB_DIV", acc.div),
        ("CB_DIV_MIN", acc.div_range[0]),
        ("CB_DIV_MAX", acc.div_range[1]),
        ("CB_SQRT", acc.sqrt),
        ("CB_SQRT_MIN", acc.sqrt_range[0]),
        ("CB_SQRT_MAX", acc.sqrt_range[1]),
        ("CB_EXP0", acc.exp0),
        ("CB_EXP1", acc.exp1),
        ("CB_EXP_MAX", acc.exp_max),
        ("CB_LN_REL", acc.ln_rel),
        ("CB_LN_ABS", acc.ln_abs),
        ("CB_LN_MIN", acc.ln_range[0]),
        ("CB_LN_MAX", acc.ln_range[1]),
        ("CB_TRIG_ABS", acc.trig_abs),
        ("CB_TRIG_REL", acc.trig_rel),
        ("CB_TRIG_MAX", acc.trig_max),
        ("CB_ATAN_REL", acc.atan_rel),
        ("CB_ATAN_ABS", acc.atan_abs),
        ("CB_ATAN_MIN", acc.atan_range[0]),
        ("CB_ATAN_MAX", acc.atan_range[1]),
        ("CB_BUILTIN_FLUSH", acc.builtin_flush),
    ];
    for (name, v) in consts {
        let _ = writeln!(s, "const {name}: real = {};", p.literal(v)?);
    }
    Ok(s)
}

/// `fn NAME(x: array<Cv, D>) -> array<Cv, K>`: the program's certified outputs, one `let`
/// per DAG node in the CPU's order, each a rule of `shaders/certified.wgsl` (the twin of
/// `expr::certified::certified_eval`).
pub fn emit_certified_function(prog: &Program, name: &str, p: Precision) -> Result<String> {
    let (d, k) = (prog.dim(), prog.outputs().max(1));
    let mut s = String::new();
    let _ = writeln!(s, "fn {name}(x: array<Cv, {d}>) -> array<Cv, {k}> {{");
    let c = |i: u32| format!("c{i}");
    for (i, node) in prog.nodes().iter().enumerate() {
        let rhs = match *node {
            Node::Var(j) => format!("x[{j}]"),
            Node::Const(v) => {
                let (cv, ce) = match p {
                    Precision::F32 => {
                        let r = Rules::<f32>::new(&p.accuracy()).constant(v);
                        (r.v as f64, r.e as f64)
                    }
                    Precision::F64 => {
                        let r = Rules::<f64>::new(&p.accuracy()).constant(v);
                        (r.v, r.e)
                    }
                };
                format!("Cv({}, {})", p.literal(cv)?, p.literal(ce)?)
            }
            Node::Un(op, a) => match op {
                Op1::Sqrt => format!("cb_sqrt({}, true)", c(a)),
                Op1::Neg => format!("cb_neg({})", c(a)),
                other => format!("cb_{}({})", other.name(), c(a)),
            },
            Node::Bin(op, a, b) => match op {
                Op2::Add => format!("cb_add({}, {}, true)", c(a), c(b)),
                Op2::Sub => format!("cb_sub({}, {}, true)", c(a), c(b)),
                Op2::Mul => format!("cb_mul({}, {}, true)", c(a), c(b)),
                Op2::Div => format!("cb_div({}, {}, true)", c(a), c(b)),
                Op2::Min => format!("cb_min({}, {})", c(a), c(b)),
                Op2::Max => format!("cb_max({}, {})", c(a), c(b)),
                Op2::Pow => format!("cb_pow({}, {})", c(a), c(b)),
                Op2::Atan2 => format!("cb_atan2({}, {})", c(a), c(b)),
            },
            Node::PowI(a, n) => {
                // Rules::powi: the CPU's squaring sequence.
                let acc = emit_powi(&mut s, i, c(a), n, |x, y| format!("cb_mul({x}, {y}, true)"))
                    .unwrap_or_else(|| "cb_exact(real(1.0))".into());
                if n < 0 {
                    format!("cb_div(cb_exact(real(1.0)), {acc}, true)")
                } else {
                    acc
                }
            }
        };
        let _ = writeln!(s, "    let c{i}: Cv = {rhs};");
    }
    let outs: Vec<String> = prog.output_nodes().iter().map(|&o| c(o)).collect();
    let outs = if outs.is_empty() {
        vec!["cb_exact(real(0.0))".into()]
    } else {
        outs
    };
    let _ = writeln!(s, "    return array<Cv, {k}>({});\n}}", outs.join(", "));
    Ok(s)
}

/// The certified vertex-evaluation shader for `prog` (`shaders/eval_certified.wgsl`), validated.
pub fn certified_shader(prog: &Program, p: Precision) -> Result<String> {
    let mut src = certified_prelude(prog, p)?;
    src.push_str(EVAL_CERTIFIED_WGSL);
    validate(&src, p)?;
    Ok(src)
}

/// What a shader of certified values of f starts with: `real`, `DIM`, `OUTS`, the CB_*
/// constants, `LATTICE_FACTOR`, the device primitives, `shaders/certified.wgsl`,
/// `isomesh_fc` and the stage prelude.
pub(crate) fn certified_prelude(prog: &Program, p: Precision) -> Result<String> {
    let acc = p.accuracy();
    let d = prog.dim();
    let mut src = String::new();
    let _ = writeln!(
        src,
        "alias real = {ty};\nconst DIM: u32 = {d}u;\nconst OUTS: u32 = {k}u;",
        ty = p.ty(),
        k = prog.outputs().max(1)
    );
    src.push_str(&certified_constants(p, &acc)?);
    let _ = writeln!(
        src,
        "const LATTICE_FACTOR: real = {};",
        p.literal(lattice_factor(&acc, d))?
    );
    src.push_str(&certified_primitives(p));
    src.push_str(CERTIFIED_WGSL);
    src.push_str(&emit_certified_function(prog, "isomesh_fc", p)?);
    src.push_str(&stage_prelude());
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
