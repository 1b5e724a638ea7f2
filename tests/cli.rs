//! The `isomesh` command line: the report contract, outputs, and clean failures.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn isomesh(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_isomesh"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the isomesh binary runs")
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("isomesh-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn report(dir: &Path, name: &str) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join(name)).unwrap()).unwrap()
}

#[test]
fn trace_writes_the_sample_and_the_report() {
    let dir = scratch("trace");
    let o = isomesh(
        &dir,
        &[
            "trace",
            "--preset",
            "circle",
            "--threads",
            "1",
            "--out",
            "s.csv",
            "--report",
            "r.json",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let r = report(&dir, "r.json");
    for key in [
        "ambient_dim",
        "codim",
        "triangulation",
        "edge",
        "simplex_count",
        "components",
        "backend",
        "threads",
        "elapsed_s",
        "simplices_per_s",
        "peak_memory_bytes",
    ] {
        assert!(r.get(key).is_some(), "report lacks {key}: {r}");
    }
    assert_eq!(r["ambient_dim"], 2);
    assert_eq!(r["codim"], 1);
    assert_eq!(r["triangulation"], "coxeter");
    assert_eq!(r["backend"], "cpu");
    assert_eq!(r["threads"], 1);
    assert_eq!(r["components"], 1);
    assert!(r["peak_memory_bytes"].as_u64().unwrap() > 0);
    let n = r["simplex_count"].as_u64().unwrap() as usize;
    let csv = std::fs::read_to_string(dir.join("s.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], "x1,x2");
    assert_eq!(lines.len(), n + 1);
    for l in &lines[1..] {
        let p: Vec<f64> = l.split(',').map(|v| v.parse().unwrap()).collect();
        assert!((p[0].hypot(p[1]) - 1.0).abs() < 0.01);
    }

    // Flags override the preset; the exhaustive scan agrees with the trace.
    let o = isomesh(
        &dir,
        &[
            "trace",
            "--preset",
            "circle",
            "--exhaustive",
            "--box",
            "-1.5,1.5",
            "--report",
            "e.json",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(report(&dir, "e.json")["simplex_count"], n as u64);
    let o = isomesh(
        &dir,
        &[
            "trace",
            "--preset",
            "circle",
            "--triangulation",
            "freudenthal",
            "--edge",
            "0.02",
            "--seed",
            "0,-1",
            "--report",
            "f.json",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let f = report(&dir, "f.json");
    assert_eq!(f["triangulation"], "freudenthal");
    assert_eq!(f["edge"], 0.02);
    assert!(f["simplex_count"].as_u64().unwrap() > n as u64);
}

#[test]
fn no_arguments_runs_the_default_example() {
    let dir = scratch("default");
    let o = isomesh(&dir, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("torus"), "{out}");
    assert!(out.contains("isomesh-out/torus.csv"), "{out}");
    let r = report(&dir, "isomesh-out/torus.json");
    assert_eq!(r["components"], 1);
    assert!(dir.join("isomesh-out/torus.csv").exists());
}

#[test]
fn bad_requests_fail_cleanly() {
    let dir = scratch("bad");
    let fails = |args: &[&str], needle: &str| {
        let o = isomesh(&dir, args);
        assert!(!o.status.success(), "{args:?} succeeded");
        let e = stderr(&o);
        assert!(e.contains(needle), "{args:?}: '{e}' lacks '{needle}'");
        assert!(!e.contains("panicked"), "{e}");
    };
    fails(
        &["trace", "--preset", "circle", "--backend", "gpu"],
        "no GPU oracle",
    );
    fails(
        &["trace", "--preset", "sphere", "--seed", "0,0,0"],
        "off the manifold",
    );
    fails(
        &["trace", "--preset", "sphere", "--seed", "1,0"],
        "coordinates",
    );
    fails(
        &["trace", "--preset", "circle", "--exhaustive"],
        "needs a box",
    );
    fails(&["trace", "--preset", "circle", "--box", "1,2,3"], "--box");
    fails(&["trace", "--preset", "nope"], "unknown preset");
    fails(&["trace", "--preset", "circle", "--edge=-1"], "edge");
    fails(
        &["trace", "--preset", "circle", "--out", "x.unknown"],
        "unknown output format",
    );
    fails(&["trace", "missing.toml"], "missing.toml");
}

#[test]
fn memory_limit_stops_and_keeps_what_was_traced() {
    let dir = scratch("memory");
    let o = isomesh(
        &dir,
        &[
            "trace",
            "--preset",
            "torus",
            "--edge",
            "0.01",
            "--max-memory",
            "300K",
            "--out",
            "part.csv",
            "--report",
            "part.json",
        ],
    );
    assert!(!o.status.success());
    assert!(stderr(&o).contains("memory limit"), "{}", stderr(&o));
    let r = report(&dir, "part.json");
    assert_eq!(r["complete"], false);
    let n = r["simplex_count"].as_u64().unwrap() as usize;
    assert!(n > 0);
    let rows = std::fs::read_to_string(dir.join("part.csv"))
        .unwrap()
        .lines()
        .count();
    assert_eq!(rows, n + 1);
}
