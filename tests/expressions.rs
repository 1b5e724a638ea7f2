//! The equation language: presets against hand-written Rust, derivatives, WGSL validation,
//! error kinds and positions, spec files, combinators.

use isomesh::expr::program::{Program, Scratch};
use isomesh::expr::{
    newton_project, parse_expr, parse_system, preset, preset_names, ClosureFunction,
    EquationSystem, ErrorKind, Expr, ImplicitFunction, Scope, Spec,
};
#[cfg(feature = "gpu")]
use isomesh::gpu::wgsl::{eval_shader, Precision};
use isomesh::Error;
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

#[path = "common/exprs.rs"]
mod exprs;
use exprs::random_expr;

/// Hand-written f for each preset at its default parameters.
fn hand_written(name: &str, x: &[f64]) -> Vec<f64> {
    match name {
        "circle" => vec![x[0] * x[0] + x[1] * x[1] - 1.0],
        "sphere" => vec![x[0] * x[0] + x[1] * x[1] + x[2] * x[2] - 1.0],
        "torus" => {
            let q = (x[0] * x[0] + x[1] * x[1]).sqrt() - 1.0;
            vec![q * q + x[2] * x[2] - 0.16]
        }
        "chair" => {
            let (a, b, c) = (x[0], x[1], x[2]);
            let s = a * a + b * b + c * c - 0.8;
            vec![
                s * s - 0.4 * ((c - 1.0).powi(2) - 2.0 * a * a) * ((c + 1.0).powi(2) - 2.0 * b * b),
            ]
        }
        "flat-torus" | "cut-flat-torus" => {
            vec![
                x[0] * x[0] + x[1] * x[1] - 1.0,
                x[2] * x[2] + x[3] * x[3] - 1.0,
            ]
        }
        "3-torus" => vec![
            x[0] * x[0] + x[1] * x[1] - 0.25,
            x[2] * x[2] + x[3] * x[3] - 1.0,
            x[4] * x[4] + x[5] * x[5] - 4.0,
        ],
        "complex-cosine" => vec![
            x[0] - x[2].cos() * x[3].cosh(),
            x[1] + x[2].sin() * x[3].sinh(),
        ],
        "bagel-klein" => {
            let (s, t) = (x[3], x[4]);
            let ring = 3.0 + (s / 2.0).cos() * t.sin() - (s / 2.0).sin() * (2.0 * t).sin();
            vec![
                s.cos() * ring - x[0],
                s.sin() * ring - x[1],
                (s / 2.0).sin() * t.sin() + (s / 2.0).cos() * (2.0 * t).sin() - x[2],
            ]
        }
        other => panic!("no hand-written version of {other}"),
    }
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()).max(1.0)
}

#[test]
fn presets_match_ast_and_hand_written_rust() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for name in preset_names() {
        let p = preset(name, &[]).unwrap();
        let sys = &p.system;
        let (d, k) = (sys.ambient_dim(), sys.codim());
        let seed = &p.seeds[0];
        // The seed is on M.
        let mut f = vec![0.0; k];
        sys.eval_batch(seed, &mut f);
        let norm = f.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(norm < 1e-9, "{name}: |f(seed)| = {norm}");
        // 1,000 points around the seed, in one batch.
        let n = 1000;
        let points: Vec<f64> = (0..n * d)
            .map(|i| seed[i % d] + rng.random_range(-0.7..0.7))
            .collect();
        let mut batch = vec![0.0; n * k];
        sys.eval_batch(&points, &mut batch);
        for (i, p) in points.chunks_exact(d).enumerate() {
            let hand = hand_written(name, p);
            for (o, e) in sys.equations().iter().enumerate() {
                let tree = e.eval(p);
                let b = batch[i * k + o];
                assert_eq!(
                    b.to_bits(),
                    tree.to_bits(),
                    "{name}: batch vs tree at {p:?}"
                );
                assert!(
                    close(b, hand[o], 1e-12),
                    "{name}: {b} vs hand-written {}",
                    hand[o]
                );
            }
        }
    }
}

#[test]
fn jacobians_agree_with_central_differences() {
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    for name in preset_names() {
        let p = preset(name, &[]).unwrap();
        let sys = &p.system;
        let (d, k) = (sys.ambient_dim(), sys.codim());
        // The 50 points in one batch too: each row is that point's Jacobian, bit for bit.
        let points: Vec<f64> = (0..50)
            .flat_map(|_| {
                let seed = p.seeds[0].iter();
                seed.map(|s| s + rng.random_range(-0.3..0.3))
                    .collect::<Vec<_>>()
            })
            .collect();
        let mut batch = vec![0.0; 50 * k * d];
        sys.jacobian_batch(&points, &mut batch);
        for (x, row) in points.chunks_exact(d).zip(batch.chunks_exact(k * d)) {
            let mut j = vec![0.0; k * d];
            sys.jacobian(x, &mut j);
            let bits = |v: &[f64]| v.iter().map(|a| a.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&j), bits(row), "{name}: a batch's Jacobian at {x:?}");
            let (mut fp, mut fm) = (vec![0.0; k], vec![0.0; k]);
            for c in 0..d {
                let h = 1e-6;
                let mut xp = x.to_vec();
                xp[c] += h;
                let mut xm = x.to_vec();
                xm[c] -= h;
                sys.eval_batch(&xp, &mut fp);
                sys.eval_batch(&xm, &mut fm);
                for r in 0..k {
                    let fd = (fp[r] - fm[r]) / (2.0 * h);
                    assert!(
                        (fd - j[r * d + c]).abs() <= 1e-6 * fd.abs().max(1.0),
                        "{name}: d f{r}/d x{c}: symbolic {} vs differences {fd}",
                        j[r * d + c]
                    );
                }
            }
        }
    }
}

#[cfg(feature = "gpu")]
#[test]
fn every_preset_emits_valid_wgsl() {
    for name in preset_names() {
        let p = preset(name, &[]).unwrap();
        for prec in [Precision::F32, Precision::F64] {
            for prog in [p.system.values(), p.system.jacobian_program()] {
                if let Err(e) = eval_shader(prog, prec) {
                    panic!("{name} ({prec:?}): {e}");
                }
            }
        }
    }
}

#[test]
fn random_expressions_emit_valid_wgsl_and_round_trip() {
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let mut scratch = Scratch::default();
    for i in 0..1000 {
        let d = rng.random_range(1..=8);
        let k = rng.random_range(1..=3);
        let exprs: Vec<Expr> = (0..k).map(|_| random_expr(&mut rng, d, 6)).collect();
        // Constant folding can make a sub-expression non-finite (e.g. ln(-2)); such trees are
        // rejected by the parser, so skip them here.
        if exprs
            .iter()
            .any(|e| e.to_string().contains("NaN") || e.to_string().contains("inf"))
        {
            continue;
        }
        let prog = Program::compile(&exprs, d);
        #[cfg(feature = "gpu")]
        {
            let beyond_f32 = prog.nodes().iter().any(
                |n| matches!(n, isomesh::expr::program::Node::Const(c) if !(*c as f32).is_finite()),
            );
            for prec in [Precision::F32, Precision::F64] {
                match eval_shader(&prog, prec) {
                    Err(Error::Wgsl(m)) if prec == Precision::F32 && beyond_f32 => {
                        assert!(m.contains("does not fit in f32"), "{m}")
                    }
                    Err(e) => panic!("expression {i} ({prec:?}) {:?}: {e}", exprs),
                    Ok(_) => assert!(prec == Precision::F64 || !beyond_f32),
                }
            }
        }
        // Text form parses back to the same tree, and batch evaluation (fused instructions,
        // more points than one chunk of lanes) and evaluation at one point (one lane) equal
        // the tree bit for bit.
        let scope = Scope::new(d);
        let n = 1 + rng.random_range(0..150);
        let xs: Vec<f64> = (0..n * d).map(|_| rng.random_range(-2.0..2.0)).collect();
        let mut out = vec![0.0; n * k];
        prog.eval_batch(&xs, &mut out, &mut scratch);
        let mut alone = vec![0.0; k];
        for (p, x) in xs.chunks_exact(d).enumerate() {
            prog.eval_batch(x, &mut alone, &mut scratch);
            for (o, (a, c)) in alone.iter().zip(&out[p * k..(p + 1) * k]).enumerate() {
                assert!(
                    a.to_bits() == c.to_bits() || (a.is_nan() && c.is_nan()),
                    "one point {a} vs batch {c} for {} at point {p}",
                    exprs[o]
                );
            }
            for (o, e) in exprs.iter().enumerate() {
                let b = e.eval(x);
                if p == 0 {
                    let a = parse_expr(&e.to_string(), &scope).unwrap().eval(x);
                    assert!(
                        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
                        "expression {i}: round trip of {e}: {a} vs {b}"
                    );
                }
                let c = out[p * k + o];
                assert!(
                    c.to_bits() == b.to_bits() || (c.is_nan() && b.is_nan()),
                    "batch {c} vs tree {b} for {e} at point {p}"
                );
            }
        }
    }
}

#[test]
fn malformed_inputs_name_kind_and_position() {
    use ErrorKind::*;
    let s3 = Scope::new(3);
    let mut s5 = Scope::new(5);
    s5.add_parameter("r", 1.5).unwrap();
    // (text, scope, kind, line, column)
    let cases: Vec<(&str, &Scope, ErrorKind, usize, usize)> = vec![
        ("", &s3, UnexpectedEnd, 1, 1),
        ("   ", &s3, UnexpectedEnd, 1, 1),
        ("x +", &s3, UnexpectedEnd, 1, 4),
        ("x + * y", &s3, UnexpectedToken, 1, 5),
        ("(x + y", &s3, UnexpectedEnd, 1, 7),
        ("x + y)", &s3, UnexpectedToken, 1, 6),
        ("x y", &s3, UnexpectedToken, 1, 3),
        ("2x", &s3, BadNumber, 1, 1),
        ("1e", &s3, BadNumber, 1, 1),
        ("1e+", &s3, BadNumber, 1, 1),
        ("1.2.3", &s3, BadNumber, 1, 1),
        ("x $ y", &s3, UnexpectedChar, 1, 3),
        ("x # 2", &s3, UnexpectedChar, 1, 3),
        ("x = 2", &s3, UnexpectedChar, 1, 3),
        ("x & y", &s3, UnexpectedChar, 1, 3),
        ("q + 1", &s3, UnknownName, 1, 1),
        ("x + radius", &s3, UnknownName, 1, 5),
        ("w + 1", &s3, UnknownName, 1, 1),
        ("x4 - 1", &s3, VariableIndex, 1, 1),
        ("x0 + y", &s3, VariableIndex, 1, 1),
        ("x1 + x6", &s5, VariableIndex, 1, 6),
        ("x + 1", &s5, UnknownName, 1, 1),
        ("foo(x)", &s3, UnknownFunction, 1, 1),
        ("x1 + r(2)", &s5, UnknownFunction, 1, 6),
        ("x(2)", &s3, UnknownFunction, 1, 1),
        ("sin(x, y)", &s3, WrongArity, 1, 1),
        ("sin()", &s3, WrongArity, 1, 1),
        ("atan2(x)", &s3, WrongArity, 1, 1),
        ("1 + max(x, y, z)", &s3, WrongArity, 1, 5),
        ("pow(x)", &s3, WrongArity, 1, 1),
        ("sin x", &s3, UnexpectedToken, 1, 1),
        ("sin", &s3, UnexpectedToken, 1, 1),
        ("sin(x", &s3, UnexpectedEnd, 1, 6),
        ("min(x,, y)", &s3, UnexpectedToken, 1, 7),
        ("1 / 0", &s3, NonFinite, 1, 1),
        ("sqrt(-1) + x", &s3, NonFinite, 1, 1),
        ("ln(0) * y", &s3, NonFinite, 1, 1),
        ("x^^2", &s3, UnexpectedToken, 1, 3),
        ("*x", &s3, UnexpectedToken, 1, 1),
        (")", &s3, UnexpectedToken, 1, 1),
        ("x,y", &s3, UnexpectedToken, 1, 2),
        ("   x +\t", &s3, UnexpectedEnd, 1, 8),
    ];
    assert!(cases.len() >= 40);
    for (text, scope, kind, line, column) in cases {
        let e = parse_expr(text, scope).unwrap_err();
        assert_eq!(
            (e.kind, e.line, e.column),
            (kind, line, column),
            "input {text:?} gave {e}"
        );
        assert!(!e.message.is_empty());
    }
    // Systems: line numbers, ';' columns, equation counts.
    let e = parse_system("x^2 + y^2 - 1\nz + * 2", &s3).unwrap_err();
    assert_eq!(
        (e.kind, e.line, e.column),
        (ErrorKind::UnexpectedToken, 2, 5)
    );
    let e = parse_system("x - 1; y + q", &s3).unwrap_err();
    assert_eq!((e.kind, e.line, e.column), (ErrorKind::UnknownName, 1, 12));
    let e = parse_system("x; y; z", &s3).unwrap_err();
    assert_eq!(e.kind, ErrorKind::Dimensions);
    let e = parse_system("\n\n", &s3).unwrap_err();
    assert_eq!(e.kind, ErrorKind::Dimensions);
    assert_eq!(parse_system("x^2 + y^2 - 1; z", &s3).unwrap().len(), 2);
    // Names.
    let mut s = Scope::new(3);
    assert_eq!(s.add_parameter("x", 1.0).unwrap_err().kind, DuplicateName);
    assert_eq!(s.add_parameter("sin", 1.0).unwrap_err().kind, DuplicateName);
    assert_eq!(s.add_parameter("r", f64::NAN).unwrap_err().kind, NonFinite);
    let names = vec!["a".to_string(), "a".to_string()];
    assert_eq!(Scope::with_names(&names).unwrap_err().kind, DuplicateName);
}

#[test]
fn nesting_limits_names_and_positions_are_exact() {
    use isomesh::expr::parser::MAX_DEPTH;
    use ErrorKind::*;
    let s = Scope::new(2);
    // Each way of nesting is allowed MAX_DEPTH deep, and refused one level deeper.
    type Nesting = (&'static str, fn(usize) -> String);
    let nestings: [Nesting; 5] = [
        ("parentheses", |n| {
            format!("{}x{}", "(".repeat(n), ")".repeat(n))
        }),
        ("minus signs", |n| format!("{}x", "-".repeat(n))),
        ("plus signs", |n| format!("{}x", "+".repeat(n))),
        ("powers", |n| format!("x{}", "^y".repeat(n))),
        ("calls", |n| {
            format!("{}x{}", "sin(".repeat(n), ")".repeat(n))
        }),
    ];
    for (what, text) in nestings {
        assert!(parse_expr(&text(MAX_DEPTH), &s).is_ok(), "{what}");
        let e = parse_expr(&text(MAX_DEPTH + 1), &s).unwrap_err();
        assert_eq!(e.kind, TooDeep, "{what}: {e}");
    }
    // A unary plus is nothing.
    assert_eq!(parse_expr("+x", &s).unwrap(), Expr::Var(0));
    // Lines and columns of an expression spanning lines, and of a system's last line.
    let e = parse_expr("x +\n  * y", &s).unwrap_err();
    assert_eq!((e.kind, e.line, e.column), (UnexpectedToken, 2, 3));
    let e = parse_system("x\ny\n\nx - y", &Scope::new(3)).unwrap_err();
    assert_eq!((e.kind, e.line), (Dimensions, 4));
    // Numbers past f64 are malformed numbers, not infinities folded later.
    assert_eq!(parse_expr("1e400 * x", &s).unwrap_err().kind, BadNumber);
    // Constants fold.
    assert_eq!(
        parse_expr("2 * 3 * x", &s).unwrap(),
        Expr::mul(Expr::Num(6.0), Expr::Var(0))
    );
    // Declared names: letters, digits and '_' not starting with a digit, none taken.
    let names =
        |v: &[&str]| Scope::with_names(&v.iter().map(|n| n.to_string()).collect::<Vec<_>>());
    for good in [&["a", "b"][..], &["_a1", "a_b"], &["u", "v", "w2"]] {
        assert!(names(good).is_ok(), "{good:?}");
    }
    for (bad, kind) in [
        (&["1x"][..], UnexpectedToken),
        (&["a-b"], UnexpectedToken),
        (&[""], UnexpectedToken),
        (&["a", "a"], DuplicateName),
        (&["pi"], DuplicateName),
        (&["e"], DuplicateName),
        (&["cos"], DuplicateName),
    ] {
        assert_eq!(names(bad).unwrap_err().kind, kind, "{bad:?}");
    }
}

#[test]
fn long_chains_are_regrouped_without_changing_their_value() {
    let s = Scope::new(2);
    let (x, y) = (2.0, 3.0);
    // Regrouped, the second half below divides by 1e300 / 1e-300, which overflows: it
    // stays as written instead of folding to an infinity (x / inf is the 0 that x / 1e300
    // * 1e-300 underflows to).
    let e = parse_expr("x * 1 * 1 * 1 * 1 / 1e300 * 1e-300 * 1 * 1 * 1", &s).unwrap();
    assert_eq!(e.eval(&[x, y]), x / 1e300 * 1e-300);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for len in [9, 10, 17, 64, 1000] {
        for _ in 0..20 {
            // Sums of small integers and products of powers of two are exact in any
            // grouping: only a wrong operator or a lost term changes them.
            let (mut sum, mut sum_text) = (x, "x".to_string());
            let (mut prod, mut prod_text) = (y, "y".to_string());
            for _ in 0..len {
                let v: i32 = rng.random_range(1..50);
                let term = if rng.random_bool(0.3) {
                    ("y", y)
                } else {
                    ("", f64::from(v))
                };
                let term_text = if term.0.is_empty() {
                    v.to_string()
                } else {
                    "y".into()
                };
                if rng.random_bool(0.5) {
                    sum -= term.1;
                    sum_text += &format!(" - {term_text}");
                } else {
                    sum += term.1;
                    sum_text += &format!(" + {term_text}");
                }
                let p = 2f64.powi(rng.random_range(-3..4));
                let (p, p_text) = if rng.random_bool(0.3) {
                    (x, "x".into())
                } else {
                    (p, p.to_string())
                };
                if rng.random_bool(0.5) {
                    prod /= p;
                    prod_text += &format!(" / {p_text}");
                } else {
                    prod *= p;
                    prod_text += &format!(" * {p_text}");
                }
            }
            for (text, want) in [(&sum_text, sum), (&prod_text, prod)] {
                let got = parse_expr(text, &s).unwrap().eval(&[x, y]);
                assert_eq!(got, want, "{text}");
            }
        }
    }
}

#[test]
fn operators_bind_as_in_mathematics() {
    let s = Scope::new(2);
    let ev = |t: &str| parse_expr(t, &s).unwrap().eval(&[2.0, 3.0]);
    assert_eq!(ev("-x^2"), -4.0);
    assert_eq!(ev("2^3^2"), 512.0);
    assert_eq!(ev("x - y - 1"), -2.0);
    assert_eq!(ev("x / y * 3"), 2.0);
    assert_eq!(ev("x ** 2 + 1"), 5.0);
    assert_eq!(ev("2e-3 * 1000 + .5"), 2.5);
    assert_eq!(ev("x^-1"), 0.5);
    assert_eq!(ev("log(e) + ln(1)"), 1.0);
    assert!((ev("atan2(y, x)") - 3f64.atan2(2.0)).abs() < 1e-15);
    assert_eq!(ev("min(x, y) + max(x, y) + abs(-x) + sign(-y)"), 6.0);
    assert!((ev("pi") - std::f64::consts::PI).abs() < 1e-15);
    assert_eq!(ev("pow(y, 2)"), 9.0);
    assert_eq!(ev("x^0.5"), 2f64.sqrt());
    // Constant folding: parameters and constant sub-expressions become numbers.
    let mut p = Scope::new(2);
    p.add_parameter("r", 1.5).unwrap();
    assert_eq!(
        parse_expr("x^2 - r^2 * 2", &p).unwrap(),
        Expr::sub(Expr::powi(Expr::Var(0), 2), Expr::Num(4.5))
    );
}

#[test]
fn spec_files_parse_and_reject_unknown_keys() {
    let text = r#"
ambient_dim = 4
variables = ["x", "y", "z", "w"]
parameters = { r = 1.0 }
equations = ["x^2 + y^2 - r^2", "z^2 + w^2 - 1"]
boundary = ["4 - (x-1)^2 - y^2 - (z-1)^2 - w^2"]
seeds = [[1.1, 0.0, 0.9, 0.1]]
box = [[-2.0, 2.0], [-2.0, 2.0], [-2.0, 2.0], [-2.0, 2.0]]
[triangulation]
kind = "coxeter"
edge = 0.05
offset_seed = 1
"#;
    let p = Spec::from_toml(text).unwrap().resolve("example").unwrap();
    assert_eq!(p.dim(), 4);
    assert_eq!(p.system.codim(), 2);
    assert_eq!(p.system.boundary().len(), 1);
    let mut f = [0.0; 2];
    p.system.eval_batch(&p.seeds[0], &mut f);
    assert!(f.iter().all(|v| v.abs() < 1e-12), "seed projected onto M");
    assert!(p.system.inside_boundary(&p.seeds[0]));
    assert!(!p.system.inside_boundary(&[-1.0, 0.0, -1.0, 0.0]));
    let t = p.triangulation.build(4).unwrap();
    assert!((t.edge() - 0.05).abs() < 1e-15);

    let bad = |t: &str| Spec::from_toml(t).and_then(|s| s.resolve("bad"));
    let base = "ambient_dim = 3\nequations = [\"x^2 + y^2 + z^2 - 1\"]\n";
    assert!(bad(base).is_ok());
    assert!(
        matches!(bad(&format!("{base}colour = 3\n")), Err(Error::Spec(m)) if m.contains("colour"))
    );
    assert!(matches!(
        bad(&format!("{base}[triangulation]\nedg = 0.1\n")),
        Err(Error::Spec(_))
    ));
    assert!(matches!(
        bad(&format!("{base}[triangulation]\nkind = \"cubic\"\n")),
        Err(Error::Triangulation(_))
    ));
    assert!(matches!(
        bad(&format!("{base}[triangulation]\nedge = -1.0\n")),
        Err(Error::Triangulation(_))
    ));
    assert!(matches!(
        bad(&format!("{base}seeds = [[1.0, 0.0]]\n")),
        Err(Error::DimensionMismatch(_))
    ));
    assert!(bad(&format!("{base}seeds = [[50.0, 0.0, 0.0]]\n")).is_ok());
    assert!(matches!(
        bad(&format!(
            "{base}box = [[1.0, 0.0], [0.0, 1.0], [0.0, 1.0]]\n"
        )),
        Err(Error::Spec(_))
    ));
    assert!(matches!(
        bad(&format!("{base}box = [[0.0, 1.0]]\n")),
        Err(Error::DimensionMismatch(_))
    ));
    assert!(matches!(
        bad(&format!("{base}variables = [\"a\", \"b\"]\n")),
        Err(Error::DimensionMismatch(_))
    ));
    assert!(matches!(
        bad("ambient_dim = 3\nequations = [\"x^2 + y^2 + z^2 - 1\", \"x^2 + q\"]\n"),
        Err(Error::Parse(e)) if e.kind == ErrorKind::UnknownName && e.line == 2 && e.column == 44
    ));
    assert!(matches!(
        bad("ambient_dim = 2\nequations = [\"x\", \"y\"]\n"),
        Err(Error::Parse(e)) if e.kind == ErrorKind::Dimensions
    ));
    assert!(matches!(
        bad("ambient_dim = 0\nequations = []\n"),
        Err(Error::Dimension(0))
    ));
    assert!(matches!(
        bad("ambient_dim = 99\nequations = [\"x1\"]\n"),
        Err(Error::Dimension(99))
    ));
    // Without ambient_dim, the variables give d; with neither, a clear error.
    let named =
        bad("variables = [\"u\", \"v\", \"t\"]\nequations = [\"u^2 + v^2 - t\"]\n").unwrap();
    assert_eq!((named.dim(), named.system.codim()), (3, 1));
    assert!(matches!(
        bad("equations = [\"x^2 + y^2 - 1\"]\n"),
        Err(Error::Spec(m)) if m.contains("ambient_dim")
    ));
    assert!(matches!(
        bad("ambient_dim = 2\nvariables = [\"u\"]\nequations = [\"u\"]\n"),
        Err(Error::DimensionMismatch(_))
    ));
    // A seed from which Newton cannot reach M: x^2 + 1 = 0 has no real zero.
    assert!(matches!(
        bad("ambient_dim = 2\nequations = [\"x^2 + 1 + 0*y\"]\nseeds = [[0.5, 0.0]]\n"),
        Err(Error::Spec(m)) if m.contains("Newton")
    ));
}

#[test]
fn presets_take_parameters_and_reject_unknown_ones() {
    let p = preset(
        "sphere",
        &[("m".into(), 3.0), ("d".into(), 6.0), ("r".into(), 2.0)],
    )
    .unwrap();
    assert_eq!(p.dim(), 6);
    assert_eq!(p.system.codim(), 3);
    assert!((p.seeds[0][0] - 2.0).abs() < 1e-12);
    assert!(matches!(
        preset("sphere", &[("q".into(), 1.0)]),
        Err(Error::Usage(_))
    ));
    assert!(matches!(
        preset("sphere", &[("m".into(), 3.0)]),
        Err(Error::Spec(_))
    ));
    assert!(matches!(
        preset("sphere", &[("d".into(), 2.5)]),
        Err(Error::Spec(_))
    ));
    assert!(matches!(preset("nope", &[]), Err(Error::Spec(_))));
    let ft = preset("flat-torus", &[("d".into(), 10.0)]).unwrap();
    assert_eq!((ft.dim(), ft.system.codim()), (10, 8));
    let chair = preset("chair", &[("d".into(), 5.0)]).unwrap();
    assert_eq!((chair.dim(), chair.system.codim()), (5, 3));
}

#[test]
fn combinators_move_manifolds_and_seeds_together() {
    let circle = EquationSystem::parse_simple(2, &["x^2 + y^2 - 1"]).unwrap();
    let torus = circle.product(&circle).unwrap();
    assert_eq!((torus.ambient_dim(), torus.codim()), (4, 2));
    let emb = torus.embed(6).unwrap();
    assert_eq!((emb.ambient_dim(), emb.codim()), (6, 4));
    let (rot, r) = emb.rotate(7).unwrap();
    let t = [0.5, -1.0, 2.0, 0.0, 0.25, 3.0];
    let moved = rot.translate(&t).unwrap();
    // The point (1, 0, 0, 1, 0, 0) of the embedded torus, rotated then translated.
    let p = [1.0, 0.0, 0.0, 1.0, 0.0, 0.0];
    let mut q = [0.0; 6];
    for i in 0..6 {
        q[i] = (0..6).map(|j| r[i * 6 + j] * p[j]).sum::<f64>() + t[i];
    }
    let mut f = [0.0; 4];
    moved.eval_batch(&q, &mut f);
    assert!(f.iter().all(|v| v.abs() < 1e-12), "{f:?}");
    // A point off the torus stays off after the same moves.
    let mut off = q;
    off[0] += 0.1;
    moved.eval_batch(&off, &mut f);
    assert!(f.iter().any(|v| v.abs() > 1e-3));
    assert!(matches!(circle.embed(1), Err(Error::DimensionMismatch(_))));
    assert!(matches!(
        circle.translate(&[1.0]),
        Err(Error::DimensionMismatch(_))
    ));
}

#[test]
fn closures_work_as_functions_and_newton_projects_onto_them() {
    let f = ClosureFunction::new(3, 1, |x, out| {
        out[0] = x[0] * x[0] + x[1] * x[1] + x[2] * x[2] - 4.0
    })
    .unwrap();
    let p = newton_project(&f, &[1.0, 1.0, 1.0], 1e-12).unwrap();
    let r = p.iter().map(|v| v * v).sum::<f64>().sqrt();
    assert!((r - 2.0).abs() < 1e-10);
    // Direction preserved: the nearest point on the sphere.
    assert!((p[0] - p[1]).abs() < 1e-12 && (p[1] - p[2]).abs() < 1e-12);
    assert!(f.system().is_none());
    assert!(matches!(
        ClosureFunction::new(2, 2, |_, _| {}),
        Err(Error::Parse(_))
    ));
    assert!(matches!(
        newton_project(&f, &[1.0, 1.0], 1e-12),
        Err(Error::DimensionMismatch(_))
    ));
    assert!(matches!(
        newton_project(&f, &[1.0, f64::NAN, 1.0], 1e-12),
        Err(Error::NonFinite { .. })
    ));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, .. ProptestConfig::default() })]

    /// The parser never panics, whatever the input.
    #[test]
    fn parser_never_panics(text in "[-+*/^(),.0-9a-z_ \\t$;]{0,40}") {
        let _ = parse_expr(&text, &Scope::new(4));
        let _ = parse_system(&text, &Scope::new(3));
    }

    /// Any printable input: an Ok or a positioned error inside the text.
    #[test]
    fn errors_point_inside_the_input(text in "\\PC{0,30}") {
        if let Err(e) = parse_expr(&text, &Scope::new(3)) {
            prop_assert_eq!(e.line, 1);
            prop_assert!(e.column >= 1 && e.column <= text.chars().count() + 1);
        }
    }
}
