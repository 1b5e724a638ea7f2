//! What the command line prints: the sample on standard output, short numbers, user text cut
//! and escaped, sizes in a unit that shows them, a closed pipe.

mod common;

use std::io::Read;
use std::process::Stdio;

use common::{command, isomesh, stderr, Scratch};

#[test]
fn out_dash_writes_the_sample_to_standard_output() {
    let dir = Scratch::new("stdout");
    for (format, sep, header) in [
        (None, ',', true),
        (Some("xyz"), ' ', false),
        (Some("csv"), ',', true),
    ] {
        let mut args = vec![
            "trace", "--preset", "circle", "--out", "-", "--out", "f.csv",
        ];
        if let Some(f) = format {
            args.extend(["--format", f]);
        }
        let o = isomesh(&dir.0, &args);
        assert!(o.status.success(), "{}", stderr(&o));
        let out = String::from_utf8(o.stdout.clone()).unwrap();
        let mut lines = out.lines();
        if header {
            assert_eq!(lines.next(), Some("x1,x2"));
        }
        let rows: Vec<&str> = lines.collect();
        assert!(rows.len() > 50, "{out}");
        for r in &rows {
            let v: Vec<f64> = r.split(sep).map(|t| t.parse().unwrap()).collect();
            assert_eq!(v.len(), 2, "{r}");
            assert!(((v[0] * v[0] + v[1] * v[1]).sqrt() - 1.0).abs() < 0.01);
        }
        // The same points as the file; the summary went to standard error.
        let file = std::fs::read_to_string(dir.path("f.csv")).unwrap();
        assert_eq!(file.lines().count() - usize::from(header), rows.len());
        assert!(stderr(&o).contains("wrote f.csv"), "{}", stderr(&o));
        assert!(!dir.path("-").exists());
    }
}

#[test]
fn report_dash_writes_the_report_to_standard_output() {
    let dir = Scratch::new("report-stdout");
    for preset in ["circle", "sphere"] {
        let o = isomesh(&dir.0, &["trace", "--preset", preset, "--report", "-"]);
        assert!(o.status.success(), "{}", stderr(&o));
        // Standard output is the report alone, as the file would hold it.
        let out = String::from_utf8(o.stdout.clone()).unwrap();
        let r: serde_json::Value = serde_json::from_str(&out).expect("stdout is the JSON report");
        assert_eq!(r["complete"], true, "{r}");
        assert!(r["simplex_count"].as_u64().unwrap() > 50, "{r}");
        let o2 = isomesh(&dir.0, &["trace", "--preset", preset, "--report", "r.json"]);
        let file = common::report(&dir.path("r.json"));
        assert_eq!(r["simplex_count"], file["simplex_count"]);
        for key in ["levels", "components", "euler_characteristic", "betti_mod2"] {
            assert_eq!(r[key], file[key], "{key}");
        }
        assert!(o2.status.success());
        // The summary went to standard error, and no file is named `-`.
        assert!(stderr(&o).contains("crossed"), "{}", stderr(&o));
        assert!(!dir.path("-").exists());
        std::fs::remove_file(dir.path("r.json")).unwrap();
    }
}

#[test]
fn huge_numbers_print_short() {
    let dir = Scratch::new("numbers");
    for (edge, shown) in [
        ("1e300", "1e300"),
        ("1e-30", "1e-30"),
        ("123456789012", "1.23456789012e11"),
    ] {
        std::fs::write(
            dir.path("s.toml"),
            format!(
                "ambient_dim = 2\nequations = [\"x1^2 + x2^2 - 1\"]\n[triangulation]\nedge = {edge}\n"
            ),
        )
        .unwrap();
        let o = isomesh(&dir.0, &["check", "s.toml"]);
        let all = String::from_utf8_lossy(&o.stdout).into_owned() + &stderr(&o);
        assert!(all.contains(shown), "{edge}: {all}");
        let longest = all.lines().map(str::len).max().unwrap_or(0);
        assert!(longest < 200, "{edge}: a line of {longest} characters");
    }
    let o = isomesh(
        &dir.0,
        &["trace", "--preset", "circle", "--edge", "1e300", "-q"],
    );
    assert!(stderr(&o).len() < 1000, "{}", stderr(&o));
}

#[test]
fn echoed_user_text_is_cut_and_escaped() {
    let dir = Scratch::new("user-text");
    let long = "q".repeat(200_000);
    let cases = [
        format!("x1^2 + {long} - 1"),
        format!("x1^2 + x2^2 - {long}(x1)"),
        "x1 + \u{0}".to_string(),
        "x1 + \u{7}\u{1b}[31m".to_string(),
    ];
    for eq in &cases {
        let toml = format!("ambient_dim = 2\nequations = [{}]\n", toml_string(eq));
        std::fs::write(dir.path("s.toml"), toml).unwrap();
        let o = isomesh(&dir.0, &["check", "s.toml"]);
        assert!(!o.status.success());
        let e = stderr(&o);
        assert!(e.len() < 2000, "{} bytes of message", e.len());
        assert!(
            !e.contains('\0') && !e.contains('\u{7}') && !e.contains('\u{1b}'),
            "{e:?}"
        );
    }
    // Flag values too (an argument may hold at most 128 KiB).
    let long = "q".repeat(100_000);
    let o = isomesh(&dir.0, &["trace", "--preset", &long]);
    assert!(stderr(&o).len() < 2000);
    let o = isomesh(
        &dir.0,
        &[
            "trace",
            "--preset",
            "circle",
            "--project",
            &format!("1,{long}"),
        ],
    );
    assert!(!o.status.success());
    assert!(stderr(&o).len() < 2000);
    let o = isomesh(
        &dir.0,
        &[
            "trace", "--preset", "circle", "--format", "a\u{7}b", "--out", "x.csv",
        ],
    );
    assert!(
        !o.status.success() && !stderr(&o).contains('\u{7}'),
        "{}",
        stderr(&o)
    );
}

/// `s` as a TOML basic string.
fn toml_string(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if c.is_control() => out.push_str(&format!("\\u{:04X}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

#[test]
fn memory_messages_use_a_unit_that_shows_the_size() {
    let dir = Scratch::new("units");
    for limit in ["200K", "600K"] {
        let o = isomesh(
            &dir.0,
            &[
                "trace",
                "--preset",
                "sphere",
                "--edge",
                "0.05",
                "--max-memory",
                limit,
                "-q",
            ],
        );
        let e = stderr(&o);
        assert!(!o.status.success(), "{limit}: {e}");
        assert!(e.contains("KiB") || e.contains("MiB"), "{limit}: {e}");
        assert!(!e.contains("0.00 GiB"), "{limit}: {e}");
    }
}

#[test]
fn a_closed_pipe_ends_output_quietly() {
    let dir = Scratch::new("pipe");
    for args in [
        &["check", "--preset", "torus"][..],
        &["presets"][..],
        &["trace", "--preset", "circle", "--out", "-"][..],
    ] {
        let mut child = command(&dir.0, args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Read one byte, then close the pipe, as `| head -c 1` does.
        let mut out = child.stdout.take().unwrap();
        let mut byte = [0u8; 1];
        let _ = out.read(&mut byte);
        drop(out);
        let o = child.wait_with_output().unwrap();
        let e = stderr(&o);
        assert!(!e.contains("panicked"), "{args:?}: {e}");
        assert!(o.status.code().is_some(), "{args:?}: killed by a signal");
    }
}

#[test]
fn check_prints_equations_in_the_spec_names() {
    let dir = Scratch::new("check-names");
    std::fs::write(
        dir.path("n.toml"),
        "variables = [\"u\", \"v\", \"w\"]\nequations = [\"u^2 + v^2 + w^2 - 1\"]\n\
         boundary = [\"w - u\"]\nseeds = [[1, 0, 0]]\n",
    )
    .unwrap();
    let o = isomesh(&dir.0, &["check", "n.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).unwrap();
    assert!(out.contains("variables: u, v, w"), "{out}");
    assert!(
        out.contains("f1 = ((((u^2) + (v^2)) + (w^2)) - 1.0)"),
        "{out}"
    );
    assert!(out.contains("boundary: (w - u) >= 0"), "{out}");
    assert!(!out.contains("x1"), "{out}");
}

/// Boxes that are empty, not finite or wider than the numbers go, seeds that are not
/// finite, edges near the largest number and scans far beyond the lattice's range: each a
/// clear error (exit code 1), never a panic, from the command line and from the library.
#[test]
fn bad_boxes_seeds_and_scales_are_errors_not_panics() {
    let dir = Scratch::new("bad-boxes");
    let cases: [(&[&str], &str); 8] = [
        (&["--box", "0.5,-0.5"], "lo < hi"),
        (&["--box", "-nan,1.5"], "lo < hi"),
        (&["--box", "-3,inf"], "lo < hi"),
        (
            &["--box", "-1.5e308,1e308"],
            "wider than the largest number",
        ),
        (&["--seed", "0.2,-inf,0"], "non-finite value"),
        (&["--seed", "nan,nan,nan"], "non-finite value"),
        (
            &["--box", "-2e305,2e305", "--exhaustive"],
            "exhaustive scan",
        ),
        (&["--box", "-4e12,4e12", "--exhaustive"], "exhaustive scan"),
    ];
    for (flags, says) in cases {
        let mut args = vec!["trace", "--preset", "sphere", "--no-complex"];
        args.extend_from_slice(flags);
        let o = isomesh(&dir.0, &args);
        let e = stderr(&o);
        assert!(!e.contains("panicked"), "{flags:?}: {e}");
        assert_eq!(o.status.code(), Some(1), "{flags:?}: {e}");
        assert!(e.contains(says), "{flags:?}: {e}");
    }
    // Edges beyond the lattice's range: refused as the flag is read (a usage error, 2).
    for edge in ["3e307", "7e-311", "2e150"] {
        let args = ["trace", "--preset", "sphere", "--edge", edge];
        let o = isomesh(&dir.0, &args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "--edge {edge}: {e}");
        assert!(e.contains("out of range"), "--edge {edge}: {e}");
    }
    // An oracle batch that cannot fit: refused before it is allocated.
    for count in ["3000000000000", "250000000"] {
        let o = isomesh(
            &dir.0,
            &["bench", "--count", count, "--traces", "none", "--k", "1-8"],
        );
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "--count {count}: {e}");
        assert!(e.contains("--count"), "--count {count}: {e}");
    }
    // The library refuses the same boxes before any work.
    for bbox in [
        vec![[-1.5e308, 1e308]; 3],
        vec![[2.0, -2.0]; 3],
        vec![[-2e305, 2e305]; 3],
    ] {
        let got = isomesh::Mesher::preset("sphere", &[])
            .unwrap()
            .bbox(bbox.clone())
            .scan();
        assert!(got.is_err(), "{bbox:?}");
    }
}

/// Each message names what is at fault as the user wrote it: a flag is not called a spec,
/// a declared name or a count of equations has no line and column, a parameter may not take
/// a coordinate's name (it would silently replace the coordinate), and sizes below a byte or
/// edges beyond the lattice's range are refused when read.
#[test]
fn messages_name_the_flag_or_name_at_fault() {
    let dir = Scratch::new("fault-names");
    let spec = |name: &str, text: &str| {
        std::fs::write(dir.path(name), text).unwrap();
        name.to_string()
    };
    let sphere = "equations = [\"x1^2 + x2^2 + x3^2 - 1\"]\nbox = [[-2, 2], [-2, 2], [-2, 2]]\n";
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec![
                "--preset".into(),
                "sphere".into(),
                "--box".into(),
                "3,-3".into(),
            ],
            "--box: ",
        ),
        (
            vec![
                "--preset".into(),
                "torus".into(),
                "--param".into(),
                "nope=2".into(),
            ],
            "preset 'torus' has no parameter 'nope'",
        ),
        (
            vec![spec(
                "p.toml",
                &format!("ambient_dim = 3\nparameters = {{ x2 = 0.5 }}\n{sphere}"),
            )],
            "always name the coordinates (x2 is coordinate 2)",
        ),
        (
            vec![spec(
                "v.toml",
                &format!("variables = [\"x2\", \"x1\", \"x3\"]\n{sphere}"),
            )],
            "always name the coordinates",
        ),
        (
            vec![spec(
                "k.toml",
                "ambient_dim = 2\nequations = [\"x1\", \"x2\", \"x1 + x2\"]\n",
            )],
            "3 equations in 2 variables",
        ),
        (
            vec![spec(
                "m.toml",
                &format!(
                    "ambient_dim = 3\n{sphere}[triangulation]\nkind = \"custom\"\nmatrix = \
                     [[3e250, 0, 0], [0, 1, 0], [0, 0, 1]]\n"
                ),
            )],
            "out of range",
        ),
    ];
    let huge = spec(
        "huge.toml",
        &format!("ambient_dim = 18446744073709551615\n{sphere}"),
    );
    let large = spec(
        "large.toml",
        &format!("ambient_dim = 18446744073709551614\n{sphere}"),
    );
    let custom = spec(
        "c.toml",
        &format!(
            "ambient_dim = 3\n{sphere}[triangulation]\nkind = \"custom\"\nmatrix = [[0.3, 0, 0], \
             [0, 0.3, 0], [0, 0, 0.3]]\n"
        ),
    );
    let mut cases = cases;
    cases.push((
        vec![huge],
        "ambient_dim = 18446744073709551615 is not supported",
    ));
    cases.push((
        vec![large],
        "ambient dimension 18446744073709551614 is not supported",
    ));
    cases.push((
        vec![custom, "--edge".into(), "0.2".into()],
        "--edge: this spec's triangulation is custom",
    ));
    for (args, says) in cases {
        let mut all: Vec<&str> = vec!["trace", "-q"];
        all.extend(args.iter().map(String::as_str));
        let o = isomesh(&dir.0, &all);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {e}");
        assert!(e.contains(says), "{args:?}: {e}");
        assert!(
            !e.contains("spec: --") && !e.contains("spec: preset"),
            "{args:?}: {e}"
        );
        assert!(
            !e.contains("line 1, column 1:") && !e.contains("line 1, column 1 ("),
            "{args:?}: {e}"
        );
    }
    // A parameter with a coordinate's name is refused whatever the dimension; other names
    // that start with x are fine.
    let o = isomesh(
        &dir.0,
        &[
            "trace",
            "-q",
            &spec(
                "ok.toml",
                &format!("ambient_dim = 3\nparameters = {{ xa = 1, x0y = 2 }}\n{sphere}"),
            ),
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let o = isomesh(
        &dir.0,
        &["trace", "--preset", "sphere", "--max-memory", "0.25"],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("less than one byte"), "{}", stderr(&o));
}
