//! The `isomesh` command line: the report contract, outputs, and clean failures.

mod common;

use std::path::Path;
use std::process::{Command, Output};

fn isomesh(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_isomesh"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the isomesh binary runs")
}

/// A scratch directory, removed when the test ends.
fn scratch(name: &str) -> common::Scratch {
    common::Scratch::new(name)
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Whether ISOMESH_REQUIRE_GPU asks for the GPU tests to run (1, true or yes).
fn gpu_required() -> bool {
    std::env::var("ISOMESH_REQUIRE_GPU")
        .is_ok_and(|v| matches!(v.trim().to_ascii_lowercase().as_str(), "1" | "true" | "yes"))
}

/// The default adapter as `isomesh info` lists it (None when there is none, a failure when
/// ISOMESH_REQUIRE_GPU requires one); a skip is written past the test harness's capture,
/// so that it shows in a plain `cargo test`.
fn gpu_adapter(dir: &Path, test: &str) -> Option<String> {
    let o = isomesh(dir, &["info"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    if let Some(line) = out.lines().find(|l| l.starts_with("* ")) {
        return Some(line.to_string());
    }
    assert!(
        !gpu_required(),
        "ISOMESH_REQUIRE_GPU is set but there is no GPU adapter"
    );
    use std::io::Write;
    let _ = writeln!(
        std::io::stderr(),
        "SKIPPED {test}: no GPU adapter (set ISOMESH_REQUIRE_GPU=1 to fail instead)"
    );
    None
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
        "oracle_calls",
        "pivot_fallbacks",
        "widest_level",
        "suspect_crossings",
    ] {
        assert!(r.get(key).is_some(), "report lacks {key}: {r}");
    }
    assert_eq!(r["suspect_crossings"], 0);
    assert!(r["widest_level"].as_u64().unwrap() >= 2);
    // The levels' steps: each timed, together within the trace's wall time.
    let steps = r["level_steps_s"].as_object().unwrap();
    let mut names: Vec<&str> = steps.keys().map(String::as_str).collect();
    names.sort_unstable();
    assert_eq!(
        names,
        [
            "accepting",
            "deciding",
            "naming",
            "new_vertices",
            "ordering"
        ],
        "{r}"
    );
    let each: Vec<f64> = steps.values().map(|v| v.as_f64().unwrap()).collect();
    assert!(each.iter().all(|&s| s > 0.0), "{r}");
    let sum: f64 = each.iter().sum();
    assert!(sum <= r["elapsed_s"].as_f64().unwrap(), "{r}");
    // Pivoting: about one oracle call per output simplex, no fallback on a plain circle.
    let calls = r["oracle_calls"].as_u64().unwrap();
    let count = r["simplex_count"].as_u64().unwrap();
    assert!(
        calls < 2 * count,
        "{calls} oracle calls for {count} simplices"
    );
    assert_eq!(r["pivot_fallbacks"], 0);
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
    assert_eq!(r["euler_characteristic"], 0);
    for f in ["torus.csv", "torus.ply", "torus.png"] {
        assert!(dir.join("isomesh-out").join(f).exists(), "{f}");
    }
}

#[test]
fn the_report_carries_the_topology_and_meshes_are_written() {
    let dir = scratch("topology");
    let o = isomesh(
        &dir,
        &[
            "trace",
            "--preset",
            "complex-cosine",
            "--param",
            "edge=0.2",
            "--out",
            "cc.vtu",
            "--out",
            "cc.npz",
            "--out",
            "cc.data",
            "--format",
            "obj",
            "--png",
            "cc.png",
            "--png-size",
            "300x200",
            "--report",
            "r.json",
        ],
    );
    // --format applies to every --out, so the three files are all OBJ.
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("manifold with boundary"), "{out}");
    let r = report(&dir, "r.json");
    let cells: Vec<u64> = r["cells"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    assert_eq!(cells.len(), 3);
    assert_eq!(
        r["euler_characteristic"].as_i64().unwrap(),
        cells[0] as i64 - cells[1] as i64 + cells[2] as i64
    );
    assert_eq!(r["euler_characteristic"], 1);
    assert_eq!(r["manifold"], true);
    assert_eq!(r["closed"], false);
    assert_eq!(r["orientable"], true);
    assert_eq!(r["components"], 1);
    assert_eq!(r["betti_mod2"], serde_json::json!([1, 0, 0]));
    let b = r["boundary_cells"].as_array().unwrap();
    assert_eq!(b.len(), 2);
    assert!(b[0].as_u64().unwrap() > 0);
    let obj = std::fs::read_to_string(dir.join("cc.data")).unwrap();
    let faces = obj.lines().filter(|l| l.starts_with("f ")).count();
    assert_eq!(faces as u64, cells[2]);
    assert!(obj.starts_with("# isomesh: complex-cosine; d = 4, m = 2; projection: pca"));
    assert!(dir.join("cc.png").exists());

    // A closed 3-manifold: Betti numbers for m = 3, and no orientability entry.
    let o = isomesh(
        &dir,
        &[
            "trace",
            "--preset",
            "sphere",
            "--param",
            "m=3",
            "--param",
            "d=4",
            "--param",
            "edge=0.35",
            "--out",
            "s3.mesh",
            "--report",
            "s3.json",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let r = report(&dir, "s3.json");
    assert_eq!(r["cells"].as_array().unwrap().len(), 4);
    assert_eq!(r["euler_characteristic"], 0);
    assert_eq!(r["closed"], true);
    assert_eq!(r["orientable"], serde_json::Value::Null);
    assert_eq!(r["betti_mod2"], serde_json::json!([1, 0, 0, 1]));
    assert!(std::fs::read_to_string(dir.join("s3.mesh"))
        .unwrap()
        .contains("Tetrahedra"));
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
    fails(
        &["trace", "--preset", "circle", "--out", "c.off"],
        "cannot hold a 1-manifold",
    );
    fails(
        &[
            "trace",
            "--preset",
            "circle",
            "--out",
            "c.ply",
            "--no-complex",
        ],
        "--no-complex",
    );
    fails(
        &[
            "trace", "--preset", "circle", "--out", "c.ply", "--format", "doc",
        ],
        "--format doc",
    );
    fails(
        &[
            "trace",
            "--preset",
            "torus",
            "--png",
            "t.png",
            "--png-size",
            "10x10",
        ],
        "64 to 8192",
    );
    fails(
        &[
            "trace",
            "--preset",
            "flat-torus",
            "--out",
            "t.ply",
            "--project",
            "1,9",
        ],
        "projection",
    );
    assert!(!dir.join("c.off").exists() && !dir.join("c.off.partial").exists());
}

#[test]
fn a_pole_is_meshed_with_a_warning() {
    let dir = scratch("pole");
    std::fs::write(
        dir.join("pole.toml"),
        "variables = [\"x\", \"y\"]\nequations = [\"1/x\"]\nbox = [[-1, 1], [-1, 1]]\n",
    )
    .unwrap();
    let o = isomesh(
        &dir,
        &[
            "trace",
            "pole.toml",
            "--exhaustive",
            "--edge",
            "0.05",
            "--no-complex",
            "--report",
            "r.json",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("warning:") && e.contains("pole or a jump"),
        "{e}"
    );
    let r = report(&dir, "r.json");
    assert!(r["simplex_count"].as_u64().unwrap() > 0);
    assert!(r["suspect_crossings"].as_u64().unwrap() > 0, "{r}");
}

/// Runs isomesh with every GPU driver hidden.
fn isomesh_without_gpu(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_isomesh"))
        .args(args)
        .current_dir(dir)
        .env("VK_ICD_FILENAMES", "/nonexistent.json")
        .env("__EGL_VENDOR_LIBRARY_FILENAMES", "/nonexistent.json")
        .env("NODEVICE_SELECT", "1")
        .output()
        .expect("the isomesh binary runs")
}

#[test]
fn without_a_gpu_auto_falls_back_and_gpu_fails_cleanly() {
    let dir = scratch("nogpu");
    let o = isomesh_without_gpu(
        &dir,
        &[
            "trace",
            "--preset",
            "circle",
            "--backend",
            "auto",
            "--report",
            "r.json",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("using the CPU"), "{}", stderr(&o));
    assert_eq!(report(&dir, "r.json")["backend"], "cpu");
    let o = isomesh_without_gpu(&dir, &["trace", "--preset", "circle", "--backend", "gpu"]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("no GPU adapter") && !e.contains("panicked"),
        "{e}"
    );
    let o = isomesh_without_gpu(&dir, &["info"]);
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("no GPU adapter"));
}

#[test]
fn the_gpu_backend_reports_itself_and_matches_the_cpu() {
    let dir = scratch("gpu");
    if gpu_adapter(&dir, "the_gpu_backend_reports_itself_and_matches_the_cpu").is_none() {
        return;
    }
    for precision in ["auto", "f32"] {
        let o = isomesh(
            &dir,
            &[
                "trace",
                "--preset",
                "torus",
                "--param",
                "edge=0.1",
                "--backend",
                "gpu",
                "--precision",
                precision,
                "--report",
                "g.json",
                "--out",
                "g.csv",
            ],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let g = report(&dir, "g.json");
        assert!(g["backend"].as_str().unwrap().starts_with("gpu: "), "{g}");
        let share = g["recheck_share"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&share));
        // What crossed between host and device: inputs of every dispatch, verdicts back.
        assert!(g["upload_bytes"].as_u64().unwrap() > 0, "{g}");
        assert!(g["readback_bytes"].as_u64().unwrap() > 0, "{g}");
        assert!(g["host_s"].as_f64().unwrap() >= 0.0, "{g}");
        if precision == "f32" {
            assert_eq!(g["precision"], "f32");
        }
        let o = isomesh(
            &dir,
            &[
                "trace", "--preset", "torus", "--param", "edge=0.1", "--report", "c.json", "--out",
                "c.csv",
            ],
        );
        assert!(o.status.success());
        let c = report(&dir, "c.json");
        assert_eq!(g["simplex_count"], c["simplex_count"]);
        assert!(c["upload_bytes"].is_null() && c["host_s"].is_null(), "{c}");
        assert_eq!(g["cells"], c["cells"]);
        let read = |f: &str| std::fs::read_to_string(dir.join(f)).unwrap();
        assert_eq!(
            read("g.csv"),
            read("c.csv"),
            "{precision}: the samples differ"
        );
    }
    // --device-values reaches the oracle through the library's driver: the scan's values
    // come from the device, and the sample is the CPU's.
    let scan = |extra: &[&str], name: &str| {
        let mut args = vec![
            "trace",
            "--preset",
            "flat-torus",
            "--exhaustive",
            "--box",
            "-1.1,1.1",
            "--edge",
            "0.3",
            "--out",
        ];
        let csv = format!("{name}.csv");
        let json = format!("{name}.json");
        args.extend([csv.as_str(), "--report", json.as_str()]);
        args.extend_from_slice(extra);
        let o = isomesh(&dir, &args);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        (
            std::fs::read_to_string(dir.join(&csv)).unwrap(),
            report(&dir, &json),
        )
    };
    let (cpu, _) = scan(&[], "scan-cpu");
    let (dev, r) = scan(&["--backend", "gpu", "--device-values"], "scan-dev");
    assert!(r["device_vertex_evaluations"].as_u64().unwrap() > 0, "{r}");
    assert!(r["device_decisions"].as_u64().unwrap() > 0, "{r}");
    assert_eq!(cpu, dev, "the device-value scan's sample differs");
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

#[test]
fn bench_compares_the_oracles_and_traces_and_plots() {
    let dir = scratch("bench");
    let adapter = gpu_adapter(&dir, "bench_compares_the_oracles_and_traces_and_plots");
    let gpu = adapter.is_some();
    let backend = if gpu { "gpu" } else { "cpu" };
    let o = isomesh(
        &dir,
        &[
            "bench",
            "--k",
            "1,3",
            "--count",
            "3000",
            "--repeats",
            "1",
            "--traces",
            "quick,scans",
            "--backend",
            backend,
            "--json",
            "b.json",
            "--png",
            "b.png",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let b = report(&dir, "b.json");
    let oracle = b["oracle"].as_array().unwrap();
    // Per k: the CPU row, then with a GPU one row per precision it runs (f32, and f64 where
    // the adapter has SHADER_F64), each with the same verdicts as the CPU.
    let mut names = vec!["cpu"];
    if let Some(a) = &adapter {
        names.push("gpu f32");
        if a.contains("SHADER_F64 yes") {
            names.push("gpu f64");
        }
    }
    let want: Vec<(u64, &str)> = [1, 3]
        .iter()
        .flat_map(|&k| names.iter().map(move |&n| (k, n)))
        .collect();
    let got: Vec<(u64, &str)> = oracle
        .iter()
        .map(|r| (r["k"].as_u64().unwrap(), r["oracle"].as_str().unwrap()))
        .collect();
    assert_eq!(got, want, "oracle rows");
    for row in oracle {
        assert!(row["simplices_per_s"].as_f64().unwrap() > 0.0, "{row}");
        if row["oracle"] != "cpu" {
            assert_eq!(row["same_verdicts"].as_bool(), Some(true), "{row}");
            for key in ["host_ns", "upload_ns", "compute_ns", "readback_ns"] {
                assert!(row[key].as_f64().unwrap() > 0.0, "{key}: {row}");
            }
        }
    }
    let traces = b["traces"].as_array().unwrap();
    assert_eq!(
        traces.len(),
        4,
        "the quick set: cases up to 200,000 simplices"
    );
    for row in traces {
        let (n, want) = (
            row["simplices"].as_f64().unwrap(),
            row["reference_simplices"].as_f64().unwrap(),
        );
        assert!((n - want).abs() <= 0.03 * want, "{row}");
        assert!(row["cpu_speedup"].as_f64().unwrap() > 0.0);
        if gpu {
            assert_eq!(row["same_sample"], true, "{row}");
        }
    }
    let scans = b["scans"].as_array().unwrap();
    assert_eq!(scans.len(), 3, "{scans:?}");
    for row in scans {
        assert!(row["simplices"].as_u64().unwrap() > 0, "{row}");
        if gpu {
            // With device values the device evaluated f near the box (in tiles, whose
            // borders it evaluates once per tile), the CPU at a small part of it.
            assert_eq!(row["same_sample"], true, "{row}");
            let (dev, cpu) = (
                row["device_vertex_evaluations"].as_u64().unwrap(),
                row["cpu_vertex_evaluations"].as_u64().unwrap(),
            );
            assert!(0 < cpu && cpu * 4 < dev, "{row}");
            let decided =
                row["device_decisions"].as_u64().unwrap() + row["cpu_decisions"].as_u64().unwrap();
            assert!(decided >= row["simplices"].as_u64().unwrap(), "{row}");
        }
    }
    for row in traces {
        if gpu {
            let decided =
                row["device_decisions"].as_u64().unwrap() + row["cpu_decisions"].as_u64().unwrap();
            assert!(decided > 0, "{row}");
        }
    }
    let png = std::fs::read(dir.join("b.png")).unwrap();
    let decoder = png::Decoder::new(std::io::Cursor::new(png));
    let info = decoder.read_info().unwrap();
    assert_eq!(
        (info.info().width, info.info().height),
        (1400, 480),
        "two panels"
    );
    // Nonsense is refused with a message.
    for args in [
        &["bench", "--k", "99"][..],
        &["bench", "--k", "0", "--traces", "none", "--png", "x.png"],
        &["bench", "--count", "0"],
    ] {
        let o = isomesh(&dir, args);
        assert!(!o.status.success(), "{args:?}");
        assert!(!stderr(&o).contains("panicked"), "{}", stderr(&o));
    }
}
