//! The library's entry point: a `Mesher` carries f, the triangulation and the domain into
//! its result, which builds the complex, reports and writes files with no argument given
//! twice, and gives what the command line gives.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use isomesh::expr::ClosureFunction;
#[cfg(feature = "gpu")]
use isomesh::Error;
use isomesh::{Backend, Mesher};

/// A scratch folder, removed when dropped.
struct Scratch(PathBuf);

impl Scratch {
    fn new(name: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("isomesh-mesher-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }
    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn two_spheres() -> String {
    // Two unit spheres centred at x = -2 and x = 2, as one equation.
    "variables = [\"x\", \"y\", \"z\"]\n\
     equations = [\"((x - 2)^2 + y^2 + z^2 - 1) * ((x + 2)^2 + y^2 + z^2 - 1)\"]\n\
     seeds = [[3, 0, 0]]\n\
     box = [[-3.5, 3.5], [-1.5, 1.5], [-1.5, 1.5]]\n\
     [triangulation]\nedge = 0.2\n"
        .into()
}

#[test]
fn the_box_and_seeds_reach_the_trace_and_the_scan() {
    let m = Mesher::from_toml(&two_spheres(), "two-spheres").unwrap();
    // From the spec's one seed: one sphere.
    let traced = m.trace().unwrap();
    assert_eq!(traced.topology().unwrap().components, 1);
    assert_eq!(traced.topology().unwrap().betti_mod2, Some(vec![1, 0, 1]));
    // The scan of the spec's box finds both, and so does a box search without seeds.
    let scanned = m.scan().unwrap();
    assert_eq!(scanned.topology().unwrap().components, 2);
    assert!(
        scanned.len() > traced.len() * 3 / 2,
        "{} of {}",
        scanned.len(),
        traced.len()
    );
    let searched = m.clone().seeds(vec![]).search(200).trace().unwrap();
    assert_eq!(searched.topology().unwrap().components, 2);
    assert_eq!(searched.topology().unwrap().euler_characteristic, 4);
    // A box that holds only the right-hand sphere: the scan finds one.
    let right = m
        .clone()
        .bbox(vec![[0.5, 3.5], [-1.5, 1.5], [-1.5, 1.5]])
        .scan()
        .unwrap();
    assert_eq!(right.topology().unwrap().components, 1);
    assert!(right.points().chunks_exact(3).all(|p| p[0] > 0.5));
    // A box cutting the sphere: the complex has a boundary.
    let cut = m
        .clone()
        .bbox(vec![[2.0, 3.5], [-1.5, 1.5], [-1.5, 1.5]])
        .trace()
        .unwrap();
    let t = cut.topology().unwrap();
    assert!(!t.closed && t.manifold, "{t:?}");
    assert_eq!(t.euler_characteristic, 1, "a hemisphere is a disk");
}

#[test]
fn edge_triangulation_and_offset_change_the_lattice() {
    let base = Mesher::preset("sphere", &[]).unwrap();
    let a = base.clone().edge(0.2).trace().unwrap();
    let b = base.clone().edge(0.1).trace().unwrap();
    assert!(b.len() > 3 * a.len(), "{} then {}", a.len(), b.len());
    let fk = base
        .clone()
        .edge(0.2)
        .triangulation(isomesh::triangulation::TriangulationKind::Freudenthal)
        .trace()
        .unwrap();
    assert_eq!(fk.report().triangulation, "freudenthal");
    assert_eq!(a.report().triangulation, "coxeter");
    let moved = base.clone().edge(0.2).offset_seed(7).trace().unwrap();
    assert_ne!(moved.report().offset, a.report().offset);
    for m in [&a, &b, &fk, &moved] {
        assert_eq!(m.topology().unwrap().euler_characteristic, 2);
    }
}

#[test]
fn a_closure_traces_like_the_same_equation() {
    let text = Mesher::preset("sphere", &[]).unwrap().edge(0.15);
    let f = ClosureFunction::new(3, 1, |x, out| {
        out[0] = x[0] * x[0] + x[1] * x[1] + x[2] * x[2] - 1.0
    })
    .unwrap();
    let closure = Mesher::from_function(Arc::new(f))
        .edge(0.15)
        .seeds(vec![vec![1.0, 0.0, 0.0]]);
    let (a, b) = (text.trace().unwrap(), closure.trace().unwrap());
    assert_eq!(a.len(), b.len());
    let (ta, tb) = (a.topology().unwrap(), b.topology().unwrap());
    assert_eq!(ta.cells, tb.cells);
    assert_eq!(tb.betti_mod2, Some(vec![1, 0, 1]));
    // Without a seed or a box there is nowhere to start.
    let f = ClosureFunction::new(2, 1, |x, out| out[0] = x[0] * x[0] + x[1] * x[1] - 1.0).unwrap();
    let e = Mesher::from_function(Arc::new(f)).trace().unwrap_err();
    assert!(e.to_string().contains("no seed and no box"), "{e}");
}

#[cfg(feature = "gpu")]
#[test]
fn the_gpu_backend_refuses_a_closure_and_says_why() {
    let f = ClosureFunction::new(2, 1, |x, out| out[0] = x[0] * x[0] + x[1] * x[1] - 1.0).unwrap();
    let m = Mesher::from_function(Arc::new(f))
        .seeds(vec![vec![1.0, 0.0]])
        .backend(Backend::Gpu);
    match m.trace() {
        Err(Error::Gpu(msg)) => assert!(msg.contains("equation language"), "{msg}"),
        other => panic!("expected a GPU error, got {other:?}"),
    }
    // Auto falls back to the CPU for it.
    let auto = m.backend(Backend::Auto).trace().unwrap();
    assert_eq!(auto.report().backend.backend, "cpu");
}

#[test]
fn a_cancelled_run_keeps_what_it_found_and_says_it_is_incomplete() {
    let flag = Arc::new(AtomicBool::new(true));
    let m = Mesher::preset("torus", &[]).unwrap().cancel(flag);
    let r = m.trace().unwrap();
    assert!(!r.complete());
    let report = r.report();
    assert!(!report.complete);
    assert_eq!(report.stopped.as_deref(), Some("interrupted"));
    let full = Mesher::preset("torus", &[]).unwrap().trace().unwrap();
    assert!(full.complete() && full.report().complete);
    assert!(r.len() < full.len());
}

#[test]
fn bad_settings_are_errors() {
    let m = Mesher::preset("circle", &[]).unwrap();
    assert!(m.clone().threads(0).trace().is_err());
    assert!(m.clone().edge(-1.0).trace().is_err());
    assert!(
        m.clone().bbox(vec![[0.0, 1.0]]).trace().is_err(),
        "a box of the wrong dimension"
    );
    assert!("gpu2".parse::<Backend>().is_err());
    assert_eq!("auto".parse::<Backend>().unwrap(), Backend::Auto);
    let r = m.trace().unwrap();
    let dir = Scratch::new("bad");
    assert!(r.write(dir.path("x.unknown")).is_err());
    // A curve has no triangles for STL.
    assert!(r.write(dir.path("x.stl")).is_err());
    assert!(!dir.path("x.stl").exists() && !dir.path("x.unknown").exists());
}

#[test]
fn threads_run_in_a_pool_of_their_own_and_give_the_same_sample() {
    let m = Mesher::preset("flat-torus", &[]).unwrap().edge(0.3);
    let one = m.clone().threads(1).trace().unwrap();
    let two = m.clone().threads(2).warm(true).trace().unwrap();
    assert_eq!(one.report().threads, 1);
    assert_eq!(two.report().threads, 2);
    assert_eq!(one.len(), two.len());
    assert!((0..one.len()).all(|i| one.sample().key(i) == two.sample().key(i)));
}

fn read_csv(path: &Path) -> Vec<f64> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .flat_map(|l| {
            l.split(',')
                .map(|v| v.parse::<f64>().unwrap())
                .collect::<Vec<_>>()
        })
        .collect()
}

#[test]
fn every_format_is_written_from_the_result_alone() {
    let torus = Mesher::preset("torus", &[])
        .unwrap()
        .edge(0.15)
        .trace()
        .unwrap();
    let dir = Scratch::new("formats");
    for ext in [
        "csv", "xyz", "txt", "ply", "obj", "off", "stl", "mesh", "vtu", "npz",
    ] {
        let path = dir.path(&format!("torus.{ext}"));
        torus.write(&path).unwrap();
        assert!(std::fs::metadata(&path).unwrap().len() > 100, "{ext}");
    }
    // The sample file holds the result's points, bit for bit.
    assert_eq!(read_csv(&dir.path("torus.csv")), torus.points());
    // --format overrides the extension.
    let opts = isomesh::WriteOptions {
        format: Some("csv".into()),
        ..Default::default()
    };
    torus.write_with(dir.path("points.dat"), &opts).unwrap();
    assert_eq!(read_csv(&dir.path("points.dat")), torus.points());
    // PLY is binary unless asked for text.
    let head = |p: &Path| std::fs::read(p).unwrap()[..40].to_vec();
    let text = |b: Vec<u8>| String::from_utf8_lossy(&b).into_owned();
    assert!(text(head(&dir.path("torus.ply"))).contains("format binary_little_endian"));
    let ascii = isomesh::WriteOptions {
        ascii: true,
        ..Default::default()
    };
    torus.write_with(dir.path("text.ply"), &ascii).unwrap();
    assert!(text(head(&dir.path("text.ply"))).contains("format ascii"));
    torus.picture(dir.path("torus.png"), 320, 240).unwrap();
    assert!(std::fs::metadata(dir.path("torus.png")).unwrap().len() > 1000);
    // The complex was built once, and the report now has its keys.
    let r = torus.report();
    let c = r.complex.as_ref().expect("the complex's keys");
    assert_eq!(c.euler_characteristic, 0);
    assert_eq!(c.cells, torus.complex().unwrap().counts());
}

/// The report keys README documents for a trace with its complex.
#[cfg(feature = "cli")]
const CONTRACT_KEYS: &[&str] = &[
    "name",
    "mode",
    "ambient_dim",
    "codim",
    "manifold_dim",
    "triangulation",
    "edge",
    "offset",
    "box",
    "simplex_count",
    "components",
    "backend",
    "precision",
    "recheck_share",
    "gpu_s",
    "host_s",
    "upload_bytes",
    "readback_bytes",
    "adapter",
    "threads",
    "elapsed_s",
    "simplices_per_s",
    "peak_memory_bytes",
    "bytes_per_simplex",
    "levels",
    "level_steps_s",
    "widest_level",
    "oracle_calls",
    "exact_decisions",
    "pivot_fallbacks",
    "degenerate",
    "non_finite",
    "vertices_evaluated",
    "seed_points",
    "suspect_crossings",
    "complete",
    "stopped",
    "error",
    "cells",
    "euler_characteristic",
    "manifold",
    "closed",
    "boundary_cells",
    "boundary_euler_characteristic",
    "orientable",
    "betti_mod2",
    "closed_components",
    "offender_count",
    "offenders",
    "defects",
    "complex_s",
    "topology_s",
    "projection",
];

/// The library's result and report are what `isomesh trace` writes for the same problem.
#[cfg(feature = "cli")]
#[test]
fn the_result_and_its_report_match_the_command_line() {
    let dir = Scratch::new("cli");
    for (preset, edge) in [("torus", "0.1"), ("flat-torus", "0.3"), ("circle", "0.05")] {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_isomesh"))
            .args(["trace", "--preset", preset, "--edge", edge, "--quiet"])
            .args(["--out", "s.csv", "--out", "s.keys", "--report", "r.json"])
            .current_dir(&dir.0)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let cli: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path("r.json")).unwrap()).unwrap();
        let m = Mesher::preset(preset, &[])
            .unwrap()
            .edge(edge.parse().unwrap())
            .trace()
            .unwrap();
        assert_eq!(read_csv(&dir.path("s.csv")), m.points(), "{preset}");
        // The same simplices by their keys, in the same order.
        let text = std::fs::read_to_string(dir.path("s.keys")).unwrap();
        let words = m.sample().codec().words();
        assert!(text.starts_with(&format!("# isomesh simplex keys: {words} ")));
        let cli_keys: Vec<u64> = text
            .lines()
            .skip(1)
            .flat_map(|l| l.split(' ').map(|w| w.parse::<u64>().unwrap()))
            .collect();
        let lib_keys: Vec<u64> = (0..m.len())
            .flat_map(|i| m.sample().key(i).to_vec())
            .collect();
        assert_eq!(cli_keys, lib_keys, "{preset}");
        m.complex().unwrap();
        // Both through the same JSON text and parser (serde_json's parse is not exactly
        // round-trip for every float).
        let lib: serde_json::Value = serde_json::from_str(&m.report().to_json()).unwrap();
        let keys = |v: &serde_json::Value| {
            let mut k: Vec<String> = v.as_object().unwrap().keys().cloned().collect();
            k.sort();
            k
        };
        assert_eq!(keys(&cli), keys(&lib), "{preset}");
        // The documented keys, a contract with the report's readers.
        for key in CONTRACT_KEYS {
            assert!(lib.get(key).is_some(), "{preset}: the report lacks {key}");
        }
        // One driver: every key but the clocks and the heap is the same.
        assert_same_report(&cli, &lib, preset);
    }
}

/// Every key of two reports of one run but those that time it or weigh its heap.
#[cfg(feature = "cli")]
fn assert_same_report(cli: &serde_json::Value, lib: &serde_json::Value, case: &str) {
    const MEASURED: [&str; 8] = [
        "elapsed_s",
        "level_steps_s",
        "host_s",
        "simplices_per_s",
        "peak_memory_bytes",
        "bytes_per_simplex",
        "complex_s",
        "topology_s",
    ];
    for (key, value) in cli.as_object().unwrap() {
        if !MEASURED.contains(&key.as_str()) {
            assert_eq!(value, &lib[key], "{case}: {key}");
        }
    }
}

/// A trace with a singular seed and a crossing of branches: the command line and the
/// library warn alike and report the same seeds and crossings (one driver, not two).
#[cfg(feature = "cli")]
#[test]
fn the_command_line_and_the_library_warn_and_report_alike() {
    let dir = Scratch::new("cli-warn");
    let spec = "ambient_dim = 3\nequations = [\"x1*x2\", \"x3\"]\n\
                box = [[-1, 1], [-1, 1], [-1, 1]]\nseeds = [[0.5, 0, 0], [0, 0, 0]]\n\
                triangulation = { edge = 0.2 }\n";
    std::fs::write(dir.path("cross.toml"), spec).unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_isomesh"))
        .args(["trace", "cross.toml", "--report", "r.json"])
        .current_dir(&dir.0)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{stderr}");
    let cli: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path("r.json")).unwrap()).unwrap();
    let m = Mesher::from_toml(spec, "cross").unwrap().trace().unwrap();
    m.complex().unwrap();
    let lib: serde_json::Value = serde_json::from_str(&m.report().to_json()).unwrap();
    assert_eq!(cli["singular_seeds"], serde_json::json!([2]), "{cli}");
    assert_same_report(&cli, &lib, "cross");
    // Each warning of the library's run is on the command line's standard error.
    assert!(!m.warnings().is_empty());
    for w in m.warnings() {
        assert!(stderr.contains(&w.to_string()), "{w} not in: {stderr}");
    }
}

/// A piece of M lying in a face of the box is kept whole: the box is closed up to the
/// rounding of the crossing points, so the plane is one disc (Euler characteristic 1) at
/// either face, as it is with the face moved a little outside, not scraps.
#[test]
fn a_manifold_in_a_face_of_the_box_is_kept_whole() {
    for (plane, row) in [(0.3, [0.3, 1.7]), (1.7, [0.3, 1.7]), (-2.25, [-2.25, 4.0])] {
        for trace in [true, false] {
            let text = format!(
                "ambient_dim = 3\nequations = [\"x2 - ({plane})\"]\n\
                 box = [[-1, 1], {row:?}, [-0.5, 0.5]]\ntriangulation = {{ edge = 0.17 }}\n"
            );
            let m = Mesher::from_toml(&text, "face").unwrap();
            let got = if trace { m.trace() } else { m.scan() }.unwrap();
            let t = got.topology().unwrap();
            assert_eq!(
                (t.components, t.euler_characteristic, t.manifold),
                (1, 1, true),
                "x2 = {plane} in {row:?}, trace {trace}"
            );
        }
    }
}

/// A run that finds nothing (no zero, or f NaN everywhere), and was not stopped, is an error
/// that says why, not an empty result that looks complete.
#[test]
fn finding_nothing_is_an_error_that_says_why() {
    for (eq, says) in [
        ("x1^2 + x2^2 + x3^2 + 0.5", "no crossed simplex was found"),
        ("sqrt(-1 - x1^2) + x2", "NaN or infinite"),
    ] {
        let text = format!(
            "ambient_dim = 3\nequations = [\"{eq}\"]\nbox = [[-1.5, 1.5], [-1.5, 1.5], [-1.5, 1.5]]\n"
        );
        let m = Mesher::from_toml(&text, "none").unwrap();
        for got in [m.trace(), m.scan()] {
            let Err(e) = got else {
                panic!("{eq}: found something")
            };
            assert!(e.to_string().contains(says), "{eq}: {e}");
        }
    }
}

/// f identically 0 on a region (here a half-space of the box) is found where the trace or
/// scan meets it, not only at probe points: an error naming an equation and a point, not a
/// mesh that looks like a manifold.
#[test]
fn f_vanishing_on_a_region_is_an_error() {
    for eq in ["max(x2 + 0.35, 0)", "min(x1 - 0.6, 0) * (x3^2 + 1)"] {
        let text = format!(
            "ambient_dim = 3\nequations = [\"{eq}\"]\nbox = [[-1, 1], [-1, 1], [-1, 1]]\n\
             triangulation = {{ edge = 0.21 }}\n"
        );
        let m = Mesher::from_toml(&text, "region").unwrap();
        for got in [m.trace(), m.scan()] {
            let Err(e) = got else {
                panic!("{eq}: accepted")
            };
            assert!(
                e.to_string().contains("equation 1 is identically 0 around"),
                "{eq}: {e}"
            );
        }
    }
    // A zero set that only touches such a region elsewhere is fine.
    let m = Mesher::from_toml(
        "ambient_dim = 3\nequations = [\"x1^2 + x2^2 + x3^2 - 0.5\"]\n\
         box = [[-1, 1], [-1, 1], [-1, 1]]\n",
        "sphere",
    )
    .unwrap();
    assert!(m.scan().is_ok());
}

/// A complex stopped by its cancel flag is the typed interruption, and a later call, not
/// cancelled, builds it.
#[test]
fn a_cancelled_complex_is_an_interruption_and_can_be_built_later() {
    let torus = Mesher::preset("torus", &[])
        .unwrap()
        .edge(0.2)
        .trace()
        .unwrap();
    match torus.complex_cancellable(&AtomicBool::new(true)) {
        Err(isomesh::Error::Interrupted(m)) => assert!(m.contains("interrupted"), "{m}"),
        other => panic!("not an interruption: {:?}", other.map(|c| c.counts())),
    }
    let t = torus.topology().unwrap();
    assert_eq!(t.euler_characteristic, 0);
}
