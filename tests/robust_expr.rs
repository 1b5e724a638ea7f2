//! Long and deep equations: flat chains of many terms parse, simplify, differentiate, compile,
//! evaluate, print and drop without exhausting the stack, in time linear in their size; a
//! cap on size and depth gives a clear error; positions in spec files are the file's.

mod common;

use std::process::Output;
use std::time::Instant;

use common::{isomesh, Scratch};

use isomesh::expr::program::Program;
use isomesh::expr::{parse_expr, ErrorKind, Expr, Scope};
use proptest::prelude::*;

/// A scratch directory of this test file's, removed when dropped.
fn scratch(name: &str) -> Scratch {
    Scratch::new(&format!("rexpr-{name}"))
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// A chain of `n` terms joined by `ops` in turn: the sphere x^2 + y^2 + z^2 - 1 plus terms
/// that add up to nothing much (so the manifold stays a sphere).
fn chain(n: usize, ops: &[&str]) -> String {
    let mut s = String::from("x^2 + y^2 + z^2 - 1");
    for i in 0..n {
        let op = ops[i % ops.len()];
        match op {
            "+" | "-" => s += &format!(" {op} 1e-9*x*{}", i % 7 + 1),
            _ => s += &format!(" {op} 1.{:07}", i % 9 + 1),
        }
    }
    s
}

fn spec(eq: &str) -> String {
    format!("ambient_dim = 3\nequations = [\"{eq}\"]\nseeds = [[1.0, 0.0, 0.0]]\n")
}

/// The cost of parse, derivative, compile and evaluation of `src`, in seconds.
fn pipeline_seconds(src: &str) -> f64 {
    let t = Instant::now();
    let e = parse_expr(src, &Scope::new(3)).expect("the chain parses");
    let derivs: Vec<Expr> = (0..3).map(|v| e.diff(v)).collect();
    let prog = Program::compile(std::slice::from_ref(&e), 3);
    let jac = Program::compile(&derivs, 3);
    let mut out = [0.0];
    prog.eval(&[0.5, 0.25, 0.125], &mut out);
    let mut g = [0.0; 3];
    jac.eval(&[0.5, 0.25, 0.125], &mut g);
    assert!(out[0].is_finite() && g.iter().all(|v| v.is_finite()));
    // The tree walk agrees with the compiled program.
    let tree = e.eval(&[0.5, 0.25, 0.125]);
    assert!((tree - out[0]).abs() <= 1e-9 * tree.abs().max(1.0));
    drop((e, derivs, prog, jac));
    t.elapsed().as_secs_f64()
}

#[test]
fn flat_chains_of_every_operator_do_not_exhaust_the_stack() {
    for ops in [&["+"][..], &["-"], &["*"], &["/"], &["+", "-", "*", "/"]] {
        let src = chain(50_000, ops);
        let e = parse_expr(&src, &Scope::new(3)).unwrap();
        // Print, parse back, compare, differentiate, drop: every walk of the tree.
        let printed = e.to_string();
        let again = parse_expr(&printed, &Scope::new(3)).unwrap();
        assert_eq!(again.eval(&[0.3, 0.2, 0.1]), e.eval(&[0.3, 0.2, 0.1]));
        let _ = again == e;
        let d = e.diff(0);
        assert!(d.eval(&[0.3, 0.2, 0.1]).is_finite(), "{ops:?}");
        let prog = Program::compile(&[e, d], 3);
        let src = isomesh::gpu::wgsl::emit_function(&prog, "f", isomesh::gpu::Precision::F32);
        assert!(src.is_ok(), "{ops:?}");
    }
}

#[test]
fn parse_and_compile_time_grows_linearly() {
    let small = chain(100_000, &["+", "-", "*", "+"]);
    let large = chain(1_000_000, &["+", "-", "*", "+"]);
    // Best of two for each, to damp noise from a loaded machine.
    let t1 = pipeline_seconds(&small).min(pipeline_seconds(&small));
    let t10 = pipeline_seconds(&large).min(pipeline_seconds(&large));
    assert!(
        t10 < 30.0 * t1,
        "10x the terms took {:.1}x the time ({t1:.3} s -> {t10:.3} s)",
        t10 / t1
    );
}

#[test]
fn size_and_depth_caps_give_clear_errors() {
    let s = Scope::new(3);
    let big = "x + ".repeat(isomesh::expr::parser::MAX_TOKENS / 2 + 10) + "x";
    let e = parse_expr(&big, &s).unwrap_err();
    assert_eq!(e.kind, ErrorKind::TooLarge);
    assert!(e.message.contains("tokens"), "{e}");
    for deep in [
        "(".repeat(300) + "x" + &")".repeat(300),
        "-".repeat(300) + "x",
        vec!["x"; 300].join("^"),
        "sin(".repeat(300) + "x" + &")".repeat(300),
    ] {
        let e = parse_expr(&deep, &s).unwrap_err();
        assert_eq!(e.kind, ErrorKind::TooDeep, "{e}");
        assert!(e.message.contains("nested too deeply"), "{e}");
    }
    // Within the cap, deep nesting works.
    let ok = "(".repeat(150) + "x" + &")".repeat(150);
    assert!(parse_expr(&ok, &s).is_ok());
}

#[test]
fn short_chains_keep_their_left_to_right_order() {
    // Up to the block size a chain is the usual left-associated tree.
    let e = parse_expr("x - y - z + 1 - x", &Scope::new(3)).unwrap();
    assert_eq!(e.to_string(), "((((x1 - x2) - x3) + 1.0) - x1)");
    let e = parse_expr("x / y * z / 2", &Scope::new(3)).unwrap();
    assert_eq!(e.to_string(), "(((x1 / x2) * x3) / 2.0)");
}

#[test]
fn long_chains_keep_their_value() {
    // A difference chain balanced into a tree must still mean a - b - c - ...
    let n = 1000;
    let src: Vec<String> = (0..n).map(|i| format!("{}", i + 1)).collect();
    let minus = parse_expr(&(src.join(" - ") + " + x"), &Scope::new(3)).unwrap();
    let want = 1.0 - (2..=n).map(|i| i as f64).sum::<f64>();
    assert_eq!(minus.eval(&[0.0; 3]), want);
    let div = parse_expr(&format!("x{}", " / 2 * 2".repeat(500)), &Scope::new(3)).unwrap();
    assert_eq!(div.eval(&[3.0, 0.0, 0.0]), 3.0);
    let div = parse_expr(&format!("x{}", " / 2".repeat(40)), &Scope::new(3)).unwrap();
    assert_eq!(div.eval(&[1.0, 0.0, 0.0]), 0.5f64.powi(40));
}

#[test]
fn regrouping_a_long_chain_does_not_invent_an_overflow() {
    // A balanced tree groups 8000 divisors of 1.5 into halves whose products exceed f64;
    // written left to right the quotient merely underflows, and it must parse and evaluate
    // to a number as small.
    let scope = Scope::new(3);
    let div = parse_expr(&format!("x{}", " / 1.5".repeat(8000)), &scope).unwrap();
    let left_to_right = (0..8000).fold(0.3f64, |acc, _| acc / 1.5);
    let tiny = |v: f64| (0.0..1e-300).contains(&v);
    assert!(tiny(left_to_right));
    assert!(tiny(div.eval(&[0.3, 0.0, 0.0])));
    let back = parse_expr(&div.to_string(), &scope).unwrap();
    assert_eq!(back.eval(&[0.3, 0.0, 0.0]), div.eval(&[0.3, 0.0, 0.0]));
    // A product that does overflow is evaluated as written: infinite, like the left-to-right
    // product, and the trace reports it; a division by zero is still refused at once.
    let mul = parse_expr(&format!("x{}", " * 1.5".repeat(8000)), &scope).unwrap();
    assert_eq!(mul.eval(&[0.3, 0.0, 0.0]), f64::INFINITY);
    for bad in ["x + 1/0", "x - 0/0", "sqrt(-1) * x"] {
        let err = parse_expr(bad, &scope).unwrap_err();
        assert_eq!(err.kind, ErrorKind::NonFinite, "{bad}");
    }
}

#[test]
fn check_and_trace_take_long_chains() {
    let dir = scratch("chains");
    for (i, ops) in [&["+"][..], &["-"], &["*"], &["/"], &["+", "*", "-", "/"]]
        .iter()
        .enumerate()
    {
        let name = format!("s{i}.toml");
        std::fs::write(dir.join(&name), spec(&chain(20_000, ops))).unwrap();
        let o = isomesh(&dir, &["check", &name]);
        assert!(o.status.success(), "{ops:?}: {}", text(&o));
        assert!(text(&o).contains("validated by naga"));
    }
    std::fs::write(
        dir.join("t.toml"),
        spec(&chain(20_000, &["+", "-"])) + "[triangulation]\nedge = 0.5\n",
    )
    .unwrap();
    let o = isomesh(&dir, &["trace", "t.toml", "--threads", "2", "--no-complex"]);
    assert!(o.status.success(), "{}", text(&o));
}

#[test]
fn oversized_equations_are_refused_with_the_cap() {
    let dir = scratch("oversized");
    let big = "x + ".repeat(isomesh::expr::parser::MAX_TOKENS / 2 + 1) + "x";
    std::fs::write(dir.join("big.toml"), spec(&big)).unwrap();
    let o = isomesh(&dir, &["check", "big.toml"]);
    assert!(!o.status.success());
    let t = text(&o);
    assert!(t.contains("more than 10000000 tokens"), "{t}");
    assert!(t.contains("equation 1"), "{t}");
    let deep = "(".repeat(500) + "x" + &")".repeat(500);
    std::fs::write(dir.join("deep.toml"), spec(&deep)).unwrap();
    let o = isomesh(&dir, &["trace", "deep.toml"]);
    assert!(!o.status.success());
    assert!(text(&o).contains("nested too deeply"), "{}", text(&o));
}

#[test]
fn spec_errors_give_the_file_line_and_column() {
    let dir = scratch("positions");
    let cases: [(&str, &str); 5] = [
        // (spec, expected text in the message)
        (
            "ambient_dim = 3\n\nequations = [\n  \"x^2 + y^2 - 1\",\n  \"z + * 2\",\n]\n",
            "line 5, column 8 (equation 2 of the spec file)",
        ),
        (
            "ambient_dim = 3\nequations = [\"x^2 + y^2 + z^2 - 1\", \"x^2 + q\"]\n",
            "line 2, column 44 (equation 2 of the spec file): unknown name 'q'",
        ),
        (
            "ambient_dim = 3\nequations = [\"x^2 + y^2 + z^2 - 1\"]\nboundary = [\"z $ 1\"]\n",
            "line 3, column 16 (boundary inequality 1 of the spec file)",
        ),
        (
            "ambient_dim = 3\nequations = ['''\nx^2 + y^2\n  + z^2 - 1 +\n''']\n",
            "line 5, column 1 (equation 1 of the spec file)",
        ),
        // An escape: the position is counted within the equation's text.
        (
            "ambient_dim = 3\nequations = [\"x^2 + \\u0079^2 + w\"]\n",
            "(equation 1, counted within its text): unknown name 'w'",
        ),
    ];
    for (i, (s, want)) in cases.iter().enumerate() {
        let name = format!("p{i}.toml");
        std::fs::write(dir.join(&name), s).unwrap();
        let o = isomesh(&dir, &["check", &name]);
        assert!(!o.status.success());
        assert!(text(&o).contains(want), "case {i}: {}", text(&o));
    }
}

/// A random flat chain: `n` terms, each a number, a variable or a small product, joined by
/// random operators.
fn flat_chain() -> impl Strategy<Value = String> {
    (
        1usize..20_000,
        proptest::collection::vec((0u8..4, 0u8..4), 1..64),
    )
        .prop_map(|(n, pattern)| {
            let mut s = String::from("x");
            for i in 0..n {
                let (op, term) = pattern[i % pattern.len()];
                s += [" + ", " - ", " * ", " / "][op as usize];
                s += ["y", "1.5", "(x*z)", "sin(y)"][term as usize];
            }
            s
        })
}

/// A random deeply mixed expression: nested calls, parentheses and powers around chains.
fn deep_mixed() -> impl Strategy<Value = String> {
    proptest::collection::vec((0u8..6, 1usize..40), 1..60).prop_map(|layers| {
        let mut s = String::from("x");
        for (kind, width) in layers {
            let side = vec!["y"; width].join(" * ");
            s = match kind {
                0 => format!("sin({s}) + {side}"),
                1 => format!("({s}) * ({side} - 1)"),
                2 => format!("-({s})^2 / (1 + {side})"),
                3 => format!("max({s}, {side}) - z"),
                4 => format!("exp(-({s})) + {side}"),
                _ => format!("atan2({s}, 2 + {side})"),
            };
        }
        s
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, .. ProptestConfig::default() })]

    /// Long flat chains and deeply mixed expressions parse, differentiate, compile and
    /// evaluate, the program agreeing with the tree.
    #[test]
    fn long_and_deep_expressions_go_through(src in prop_oneof![flat_chain(), deep_mixed()]) {
        let e = parse_expr(&src, &Scope::new(3)).unwrap();
        let p = [0.3, 0.7, -0.2];
        let derivs: Vec<Expr> = (0..3).map(|v| e.diff(v)).collect();
        let prog = Program::compile(std::slice::from_ref(&e), 3);
        let jac = Program::compile(&derivs, 3);
        let (mut v, mut g) = ([0.0], [0.0; 3]);
        prog.eval(&p, &mut v);
        jac.eval(&p, &mut g);
        let tree = e.eval(&p);
        prop_assert!(
            v[0].to_bits() == tree.to_bits() || (v[0].is_nan() && tree.is_nan()),
            "program {} vs tree {}", v[0], tree
        );
        for (c, d) in derivs.iter().enumerate() {
            let t = d.eval(&p);
            prop_assert!(g[c].to_bits() == t.to_bits() || (g[c].is_nan() && t.is_nan()));
        }
        let printed = e.to_string();
        let back = parse_expr(&printed, &Scope::new(3));
        prop_assert!(back.is_ok() || matches!(back, Err(ref b) if b.kind == ErrorKind::TooDeep));
    }
}
