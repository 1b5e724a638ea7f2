//! Certified values of f (`isomesh::expr::certified`), on the CPU: the twin's bound holds
//! against the CPU's f64 value and against the exact value (256-bit arithmetic), for every
//! preset at two scales and for 1,000 random expressions, in the f32 and the f64 model and
//! on emulated conforming devices of both precisions.

use astro_float::{BigFloat, Consts, RoundingMode};
use isomesh::cpu::eval_certified::eval_lattice_certified;
use isomesh::emulate::{self, Emu32, Emu64};
use isomesh::expr::certified::Accuracy;
use isomesh::expr::program::{Node, Program};
use isomesh::expr::spec::DEFAULT_EDGE;
use isomesh::expr::{preset, Expr, Op1, Op2, PRESETS};
use isomesh::triangulation::{Triangulation, TriangulationKind};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

#[path = "common/exprs.rs"]
mod exprs;

const BITS: usize = 256;
const RM: RoundingMode = RoundingMode::ToEven;

/// The program's outputs at the exact point x = A u + b, in 256-bit arithmetic.
struct Exact {
    cc: Consts,
}

impl Exact {
    fn new() -> Self {
        Exact {
            cc: Consts::new().unwrap(),
        }
    }

    fn point(&self, a: &[f64], b: &[f64], u: &[i32]) -> Vec<BigFloat> {
        let d = u.len();
        (0..d)
            .map(|r| {
                let mut acc = BigFloat::from_f64(b[r], BITS);
                for c in 0..d {
                    let t = BigFloat::from_f64(a[r * d + c], BITS).mul(
                        &BigFloat::from_i32(u[c], BITS),
                        BITS,
                        RM,
                    );
                    acc = acc.add(&t, BITS, RM);
                }
                acc
            })
            .collect()
    }

    /// The outputs, each None where a step was not computed (an argument so large that
    /// 256 bits take too long, and the value overflows f64 anyway, or trigonometry beyond
    /// the range where the device's bound is usable).
    fn eval(&mut self, prog: &Program, x: &[BigFloat]) -> Vec<Option<BigFloat>> {
        let mut regs: Vec<Option<BigFloat>> = Vec::with_capacity(prog.nodes().len());
        let zero = BigFloat::from_f64(0.0, BITS);
        let one = BigFloat::from_f64(1.0, BITS);
        // |a| >= 2^e.
        let large = |a: &BigFloat, e: i32| a.exponent().is_some_and(|x| x > e);
        let small = |a: &BigFloat, e: i32| !a.is_zero() && a.exponent().is_some_and(|x| x < e);
        for node in prog.nodes() {
            let cc = &mut self.cc;
            let v = match *node {
                Node::Var(i) => Some(x[i].clone()),
                Node::Const(c) => Some(BigFloat::from_f64(c, BITS)),
                Node::PowI(a, n) => regs[a as usize].as_ref().map(|a| {
                    let p = a.powi(n.unsigned_abs() as usize, BITS, RM);
                    if n < 0 {
                        one.div(&p, BITS, RM)
                    } else {
                        p
                    }
                }),
                Node::Un(op, a) => regs[a as usize].as_ref().and_then(|a| {
                    let skip = match op {
                        Op1::Exp | Op1::Sinh | Op1::Cosh => large(a, 12),
                        Op1::Sin | Op1::Cos | Op1::Tan => large(a, 21),
                        _ => false,
                    };
                    (!skip).then(|| match op {
                        Op1::Neg => a.neg(),
                        Op1::Abs => a.abs(),
                        Op1::Sign => BigFloat::from_f64(
                            match a.cmp(&zero) {
                                Some(c) if c > 0 => 1.0,
                                Some(c) if c < 0 => -1.0,
                                _ => 0.0,
                            },
                            BITS,
                        ),
                        Op1::Sqrt => a.sqrt(BITS, RM),
                        Op1::Exp => a.exp(BITS, RM, cc),
                        Op1::Ln => a.ln(BITS, RM, cc),
                        Op1::Sin => a.sin(BITS, RM, cc),
                        Op1::Cos => a.cos(BITS, RM, cc),
                        Op1::Tan => a.tan(BITS, RM, cc),
                        Op1::Asin => a.asin(BITS, RM, cc),
                        Op1::Acos => a.acos(BITS, RM, cc),
                        Op1::Atan => a.atan(BITS, RM, cc),
                        Op1::Sinh => a.sinh(BITS, RM, cc),
                        Op1::Cosh => a.cosh(BITS, RM, cc),
                        Op1::Tanh => a.tanh(BITS, RM, cc),
                    })
                }),
                Node::Bin(op, a, b) => match (&regs[a as usize], &regs[b as usize]) {
                    (Some(a), Some(b)) => {
                        // Powers of a base that is not positive are never certified (and
                        // 256-bit pow stalls on them).
                        let skip = op == Op2::Pow
                            && (a.cmp(&zero).is_none_or(|c| c <= 0)
                                || large(b, 12)
                                || large(a, 64)
                                || small(a, -64));
                        (!skip).then(|| match op {
                            Op2::Add => a.add(b, BITS, RM),
                            Op2::Sub => a.sub(b, BITS, RM),
                            Op2::Mul => a.mul(b, BITS, RM),
                            Op2::Div => a.div(b, BITS, RM),
                            Op2::Min => {
                                if a.cmp(b).is_some_and(|c| c > 0) {
                                    b.clone()
                                } else {
                                    a.clone()
                                }
                            }
                            Op2::Max => {
                                if a.cmp(b).is_some_and(|c| c < 0) {
                                    b.clone()
                                } else {
                                    a.clone()
                                }
                            }
                            Op2::Pow => a.pow(b, BITS, RM, cc),
                            Op2::Atan2 => atan2(a, b, cc),
                        })
                    }
                    _ => None,
                },
            };
            // Far beyond f64's range (the CPU's value is then 0 or infinite): not followed,
            // as 256-bit series slow down there.
            regs.push(v.filter(|v| v.exponent().is_none_or(|e| e.abs() < 1100)));
        }
        prog.output_nodes()
            .iter()
            .map(|&o| regs[o as usize].clone())
            .collect()
    }
}

/// The angle of (x, y) in (-pi, pi].
fn atan2(y: &BigFloat, x: &BigFloat, cc: &mut Consts) -> BigFloat {
    let zero = BigFloat::from_f64(0.0, BITS);
    let pi = cc.pi(BITS, RM);
    if x.is_zero() {
        let half = pi.div(&BigFloat::from_f64(2.0, BITS), BITS, RM);
        return match y.cmp(&zero) {
            Some(c) if c > 0 => half,
            Some(c) if c < 0 => half.neg(),
            _ => zero,
        };
    }
    let t = y.div(x, BITS, RM).atan(BITS, RM, cc);
    if x.cmp(&zero).is_some_and(|c| c > 0) {
        t
    } else if y.cmp(&zero).is_some_and(|c| c < 0) {
        t.sub(&pi, BITS, RM)
    } else {
        t.add(&pi, BITS, RM)
    }
}

/// Whether `truth` lies within `e` of `v`.
fn within(v: f64, e: f64, truth: &BigFloat) -> bool {
    let diff = BigFloat::from_f64(v, BITS).sub(truth, BITS, RM).abs();
    // cmp gives the sign of the difference (not just -1, 0 or 1); None for NaN.
    diff.cmp(&BigFloat::from_f64(e, BITS))
        .is_some_and(|c| c <= 0)
}

/// What a check found: values checked, and how many had a usable bound.
#[derive(Default, Debug)]
struct Tally {
    values: usize,
    known: usize,
    /// Of the known, those checked against the exact value.
    exact: usize,
}

/// The models the bounds are checked in: the rules in IEEE f64 and f32, and on emulated
/// conforming devices (`isomesh::emulate`) in f64 and f32, which round every operation and
/// place every built-in function's result as adversarially as the specifications allow.
const MODELS: [&str; 4] = ["f64", "f32", "emulated f64", "emulated f32"];

/// Checks, at each lattice vertex, that the twin's bound holds against the CPU's value (as
/// tracing computes it) and, where `exact` is given, against the exact value; a tally per
/// model of [`MODELS`]. The emulated devices draw from the stream `seed`.
fn check(
    prog: &Program,
    tri: &Triangulation,
    lattice: &[i32],
    mut exact: Option<&mut Exact>,
    what: &str,
    seed: u64,
) -> [Tally; 4] {
    let (d, k) = (prog.dim(), prog.outputs());
    let (a, b) = tri.affine_map();
    // The exact values, once for every model.
    let truths: Vec<Option<Vec<Option<BigFloat>>>> = lattice
        .chunks_exact(d)
        .map(|u| {
            exact.as_mut().map(|ex| {
                let p = ex.point(&a, &b, u);
                ex.eval(prog, &p)
            })
        })
        .collect();
    let mut tallies: [Tally; 4] = Default::default();
    for (tally, model) in tallies.iter_mut().zip(MODELS) {
        emulate::seed(seed);
        let (acc, got) = match model {
            "f64" => (
                Accuracy::f64(),
                eval_lattice_certified::<f64>(prog, &Accuracy::f64(), &a, &b, lattice),
            ),
            "f32" => (
                Accuracy::f32(),
                eval_lattice_certified::<f32>(prog, &Accuracy::f32(), &a, &b, lattice),
            ),
            "emulated f64" => (
                Accuracy::f64(),
                eval_lattice_certified::<Emu64>(prog, &Accuracy::f64(), &a, &b, lattice),
            ),
            _ => (
                Accuracy::f32(),
                eval_lattice_certified::<Emu32>(prog, &Accuracy::f32(), &a, &b, lattice),
            ),
        };
        for (i, u) in lattice.chunks_exact(d).enumerate() {
            let mut x = vec![0.0; d];
            tri.vertex_coords(u, &mut x);
            let mut cpu = vec![0.0; k];
            prog.eval(&x, &mut cpu);
            let truth = &truths[i];
            for o in 0..k {
                let [v, e] = got[i * k + o];
                tally.values += 1;
                if !(e < acc.big && v.abs() < acc.big) {
                    continue;
                }
                tally.known += 1;
                assert!(
                    (cpu[o] - v).abs() <= e,
                    "{what} ({model}), vertex {u:?}, output {o}: the CPU's {} is not within \
                     {e:e} of {v}",
                    cpu[o]
                );
                if let Some(Some(t)) = truth.as_ref().map(|t| &t[o]) {
                    tally.exact += 1;
                    assert!(
                        within(v, e, t),
                        "{what} ({model}), vertex {u:?}, output {o}: the exact {} is not \
                         within {e:e} of {v}",
                        t
                    );
                }
            }
        }
    }
    tallies
}

/// Lattice vertices around `p`: its simplex's base vertex plus random offsets up to `r`.
fn around(tri: &Triangulation, p: &[f64], n: usize, r: i32, rng: &mut ChaCha8Rng) -> Vec<i32> {
    let base = tri.locate(p).unwrap().base().to_vec();
    let d = base.len();
    (0..n * d)
        .map(|i| base[i % d] + rng.random_range(-r..=r))
        .collect()
}

#[test]
fn preset_bounds_hold_against_the_cpu_and_the_exact_values() {
    let mut exact = Exact::new();
    for info in PRESETS {
        let p = preset(info.name, &[]).unwrap();
        let d = p.dim();
        for scale in [1.0, 0.05] {
            let mut spec = p.triangulation.clone();
            spec.edge = Some(spec.edge.unwrap_or(DEFAULT_EDGE) * scale);
            let tri = spec.build(d).unwrap();
            let mut rng = ChaCha8Rng::seed_from_u64(d as u64);
            let lattice = around(&tri, &p.seeds[0], 200, 20, &mut rng);
            let what = format!("{} at scale {scale}", info.name);
            let tallies = check(
                p.system.values(),
                &tri,
                &lattice,
                Some(&mut exact),
                &what,
                d as u64 * 10 + (scale == 1.0) as u64,
            );
            // Usable bounds almost everywhere: a bound that is always "unknown" would hold
            // trivially and certify nothing.
            for (t, model) in tallies.into_iter().zip(MODELS) {
                assert!(
                    t.known as f64 >= 0.95 * t.values as f64,
                    "{what} ({model}): only {} of {} values have a bound",
                    t.known,
                    t.values
                );
            }
        }
    }
}

#[test]
fn random_expression_bounds_hold_against_the_cpu_and_the_exact_values() {
    let mut rng = ChaCha8Rng::seed_from_u64(29);
    let mut exact = Exact::new();
    let (mut total, mut checked) = (Tally::default(), 0);
    while checked < 1000 {
        let d = rng.random_range(1..=4);
        let k = rng.random_range(1..=2);
        let e: Vec<Expr> = (0..k).map(|_| exprs::random_expr(&mut rng, d, 5)).collect();
        if e.iter().any(|e| {
            let s = e.to_string();
            s.contains("NaN") || s.contains("inf")
        }) {
            continue;
        }
        checked += 1;
        let prog = Program::compile(&e, d);
        let kind = if rng.random_bool(0.5) {
            TriangulationKind::Coxeter
        } else {
            TriangulationKind::Freudenthal
        };
        let offset: Vec<f64> = (0..d).map(|_| rng.random_range(-0.5..0.5)).collect();
        let mut builder = Triangulation::builder(d, kind)
            .edge(rng.random_range(0.01..0.2))
            .offset(offset);
        if rng.random_bool(0.5) {
            builder = builder.rotation_seed(rng.random());
        }
        let tri = builder.build().unwrap();
        let lattice: Vec<i32> = (0..20 * d).map(|_| rng.random_range(-30..=30)).collect();
        // Every expression a stream of its own: 1,000 streams of rounding choices.
        let [t, ..] = check(
            &prog,
            &tri,
            &lattice,
            Some(&mut exact),
            &format!("{e:?}"),
            checked as u64,
        );
        total.values += t.values;
        total.known += t.known;
        total.exact += t.exact;
    }
    // Random trees leave their domains often (ln, asin, division by a value near 0), but a
    // good share must be certified (in the f64 model).
    assert!(
        total.known as f64 >= 0.75 * total.values as f64 && total.exact >= 20_000,
        "{total:?}"
    );
}

#[test]
fn integer_powers_follow_the_cpus_squaring_sequence() {
    // x^n for large n: the bound must cover the CPU's sequence of roundings, which differs
    // from the exact power by up to about 2 log2(n) roundings.
    let mut exact = Exact::new();
    for n in [3, 7, 13, 31, 64, -5, -17] {
        let e = Expr::powi(Expr::Var(0), n);
        let prog = Program::compile(std::slice::from_ref(&e), 1);
        let tri = Triangulation::builder(1, TriangulationKind::Freudenthal)
            .edge(0.013)
            .offset(vec![0.1])
            .build()
            .unwrap();
        let lattice: Vec<i32> = (-80..=80).collect();
        let [t, ..] = check(
            &prog,
            &tri,
            &lattice,
            Some(&mut exact),
            &format!("x^{n}"),
            0,
        );
        assert!(t.known >= t.values - 2, "x^{n} (f64): {t:?}");
    }
}

/// Values whose bound the CPU's value falls outside, on the emulated device R under `acc`,
/// over `count` random expressions (20 vertices each).
fn violations_on<R: isomesh::expr::certified::DeviceReal>(acc: &Accuracy, count: usize) -> usize {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let mut found = 0;
    for i in 0..count {
        let d = rng.random_range(1..=3);
        let e = vec![exprs::random_expr(&mut rng, d, 5)];
        let prog = Program::compile(&e, d);
        let tri = Triangulation::builder(d, TriangulationKind::Freudenthal)
            .edge(rng.random_range(0.01..0.2))
            .build()
            .unwrap();
        let lattice: Vec<i32> = (0..20 * d).map(|_| rng.random_range(-30..=30)).collect();
        let (a, b) = tri.affine_map();
        emulate::seed(i as u64);
        let got = eval_lattice_certified::<R>(&prog, acc, &a, &b, &lattice);
        for (u, [v, err]) in lattice.chunks_exact(d).zip(got) {
            let mut x = vec![0.0; d];
            tri.vertex_coords(u, &mut x);
            let mut cpu = [0.0];
            prog.eval(&x, &mut cpu);
            let known = err < acc.big && v.abs() < acc.big;
            // NaN counts as outside.
            let inside = (cpu[0] - v).abs() <= err;
            found += (known && !inside) as usize;
        }
    }
    found
}

#[test]
fn a_halved_accuracy_claim_is_found_out_on_the_emulated_device() {
    // The claims as they stand hold (the tests above); each of these halved does not, on
    // an emulated device that uses the freedom the specifications leave.
    let full = Accuracy::f32();
    assert_eq!(violations_on::<Emu32>(&full, 400), 0);
    type Halve = fn(&mut Accuracy);
    let halved: [(&str, Halve); 4] = [
        ("unit", |a| a.unit /= 2.0),
        ("exp0", |a| a.exp0 /= 2.0),
        ("ln_abs", |a| a.ln_abs /= 2.0),
        ("trig_abs", |a| a.trig_abs /= 2.0),
    ];
    for (name, halve) in halved {
        let mut acc = full;
        halve(&mut acc);
        let found = violations_on::<Emu32>(&acc, 400);
        eprintln!("{name} halved: {found} values outside their bound");
        assert!(found > 0, "{name} halved: nothing found");
    }
}

#[test]
fn claims_measured_on_one_device_fail_on_a_conforming_one() {
    // The f64 claims as they were before the specifications were read: IEEE f64 + - * and
    // elementary functions within a few f64 ulps (what lavapipe showed). On an emulated f64
    // device at single precision, as the specifications allow, they do not hold (an NVIDIA
    // H200 already broke one: sinh 209 ulps off); the specifications' claims do.
    let u = f64::EPSILON / 2.0;
    let measured = Accuracy {
        unit: u,
        div: 5.0 * u,
        sqrt: 12.0 * u,
        exp0: 16.0 * u,
        exp1: 0.0,
        ln_rel: 16.0 * u,
        ln_abs: 16.0 * u,
        trig_abs: 16.0 * u,
        trig_rel: 4.0 * u,
        atan_rel: 32.0 * u,
        atan_abs: 16.0 * u,
        grow: 1.0 + 64.0 * u,
        ..Accuracy::f64()
    };
    let found = violations_on::<Emu64>(&measured, 200);
    eprintln!("measured claims: {found} values outside their bound");
    assert!(found > 100, "{found}");
    assert_eq!(violations_on::<Emu64>(&Accuracy::f64(), 200), 0);
}
