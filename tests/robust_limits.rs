//! Limits and honest endings of `isomesh trace`: the memory limit in every phase, the thread
//! cap, unbounded manifolds with no box, empty results, singular seeds, and messages that
//! name what to change.

mod common;

use std::path::Path;
use std::process::Output;

use common::{isomesh, Scratch};

/// A scratch directory of this test file's, removed when dropped.
fn scratch(name: &str) -> Scratch {
    Scratch::new(&format!("rlim-{name}"))
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn report(dir: &Path) -> serde_json::Value {
    let s = std::fs::read_to_string(dir.join("r.json")).expect("the report is written");
    serde_json::from_str(&s).unwrap()
}

/// Runs a trace with `args` plus `--report r.json` in a fresh directory; the output and the
/// report.
fn trace(name: &str, spec: Option<&str>, args: &[&str]) -> (Output, serde_json::Value, Scratch) {
    let dir = scratch(name);
    let mut all = vec!["trace"];
    if let Some(s) = spec {
        std::fs::write(dir.join("s.toml"), s).unwrap();
        all.push("s.toml");
    }
    all.extend_from_slice(args);
    all.extend_from_slice(&["--report", "r.json"]);
    let o = isomesh(&dir, &all);
    let r = report(&dir);
    (o, r, dir)
}

/// A stop under the memory limit: non-zero exit, the message, an incomplete report whose
/// peak heap is within 10% of the limit.
fn assert_stopped_within(o: &Output, r: &serde_json::Value, limit: u64, message: &str) {
    assert!(!o.status.success(), "exit 0: {}", text(o));
    assert!(text(o).contains(message), "{}", text(o));
    assert_eq!(r["complete"], false, "{r}");
    assert_eq!(r["max_memory_bytes"].as_u64(), Some(limit));
    let peak = r["peak_memory_bytes"].as_u64().unwrap();
    assert!(
        peak as f64 <= 1.1 * limit as f64,
        "peak {peak} over the limit {limit}"
    );
}

#[test]
fn the_seed_search_stays_within_the_memory_limit() {
    for (i, search) in ["100000000", "6000000"].iter().enumerate() {
        let limit = 6u64 << 20;
        let (o, r, _) = trace(
            &format!("search{i}"),
            None,
            &[
                "--preset",
                "sphere",
                "--box",
                "-2,2",
                "--search",
                search,
                "--max-memory",
                "6M",
                "--threads",
                "2",
            ],
        );
        assert_stopped_within(&o, &r, limit, "memory limit");
    }
}

#[test]
fn the_trace_stays_within_the_memory_limit() {
    for (i, (radius, limit)) in [(10.0, 64u64), (6.0, 40), (3.0, 24)].iter().enumerate() {
        let spec = format!(
            "ambient_dim = 3\nequations = [\"x^2 + y^2 + z^2 - {}\"]\nseeds = [[{radius}, 0, 0]]\n\
             [triangulation]\nedge = 0.03\n",
            radius * radius
        );
        let l = format!("{limit}M");
        let (o, r, _) = trace(
            &format!("trace{i}"),
            Some(&spec),
            &["--max-memory", &l, "--threads", "2", "--no-complex"],
        );
        assert_stopped_within(&o, &r, limit << 20, "memory limit");
        assert!(r["simplex_count"].as_u64().unwrap() > 0);
    }
}

/// In high dimensions one level names a candidate per cofacet, tens of thousands per simplex:
/// the level is named in slices, each checked against the limit before it is named.
#[test]
fn one_level_of_a_high_dimensional_trace_stays_within_the_memory_limit() {
    for (d, limit) in [(15, 48u64), (18, 80)] {
        let l = format!("{limit}M");
        let (dd, m) = (d.to_string(), (d - 1).to_string());
        let (o, r, _) = trace(
            &format!("level{d}"),
            None,
            &[
                "--preset",
                "sphere",
                "--param",
                &format!("d={dd}"),
                "--param",
                &format!("m={m}"),
                "--max-memory",
                &l,
                "--threads",
                "2",
                "--no-complex",
            ],
        );
        assert_stopped_within(&o, &r, limit << 20, "memory limit");
    }
}

#[test]
fn the_complex_and_the_exports_stay_within_the_memory_limit() {
    // Traced within the limit, the complex over it.
    let (o, r, _) = trace(
        "complex",
        None,
        &[
            "--preset",
            "torus",
            "--edge",
            "0.03",
            "--max-memory",
            "24M",
            "--threads",
            "2",
        ],
    );
    assert_stopped_within(&o, &r, 24 << 20, "the cell complex needs");
    // The complex within it, the picture over it: said, and not written.
    let (o, r, dir) = trace(
        "export",
        None,
        &[
            "--preset",
            "torus",
            "--max-memory",
            "64M",
            "--png",
            "m.png",
            "--png-size",
            "8000x8000",
            "--out",
            "m.ply",
        ],
    );
    assert_stopped_within(&o, &r, 64 << 20, "the picture needs");
    assert!(text(&o).contains("not written: m.png"), "{}", text(&o));
    assert!(!dir.join("m.png").exists());
}

#[test]
fn threads_are_capped() {
    for n in ["100000", "4000"] {
        let (o, r, _) = trace(
            &format!("threads{n}"),
            None,
            &["--preset", "circle", "--threads", n],
        );
        assert!(o.status.success(), "{}", text(&o));
        assert!(text(&o).contains("running"), "{}", text(&o));
        let t = r["threads"].as_u64().unwrap();
        assert!((1..=1024).contains(&t), "{t} threads");
    }
    // One more thread than cores runs one per core: a thread beyond them only slows the
    // run down.
    let cores = std::thread::available_parallelism().unwrap().get();
    let (o, r, _) = trace(
        "threads_cores",
        None,
        &["--preset", "circle", "--threads", &(cores + 1).to_string()],
    );
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains(&format!("running {cores} ")),
        "{}",
        text(&o)
    );
    assert_eq!(r["threads"].as_u64(), Some(cores as u64));
}

#[test]
fn unbounded_manifolds_with_no_box_stop_early_asking_for_one() {
    for (i, (d, eq, seed)) in [
        (3, "x3 - x1^2 - x2^2", "0,0,0"),
        (3, "x1^2 + x2^2 - 1", "1,0,0"),
        (2, "x2 - 0.5*x1", "0,0"),
        (2, "x1*x2 - 1", "1,1"),
        // A plane: reaching the extent would take minutes and gigabytes; the budget of
        // simplices stops it first.
        (3, "x2 + 0.1", "0.3,-0.1,0.2"),
    ]
    .iter()
    .enumerate()
    {
        let spec =
            format!("ambient_dim = {d}\nequations = [\"{eq}\"]\n[triangulation]\nedge = 0.5\n");
        let (o, r, _) = trace(
            &format!("unbounded{i}"),
            Some(&spec),
            &["--seed", seed, "--threads", "2", "--no-complex"],
        );
        assert!(!o.status.success(), "{eq}: {}", text(&o));
        let t = text(&o);
        assert!(
            t.contains("no box was given") && t.contains("give a box"),
            "{t}"
        );
        assert!(!t.contains("smaller box"), "{t}");
        assert_eq!(r["complete"], false);
        if *d == 3 && eq.starts_with("x2 +") {
            // The plane stops on the budget of simplices, not after reaching the extent.
            let stopped = r["stopped"].as_str().unwrap();
            assert!(stopped.contains("more than a trace with no box may"), "{r}");
            assert!(r["simplex_count"].as_u64().unwrap() < 5_000_000, "{r}");
        }
    }
    // With a box the same manifold traces to completion.
    let spec =
        "ambient_dim = 3\nequations = [\"x3 - x1^2 - x2^2\"]\nbox = [[-2, 2], [-2, 2], [-1, 3]]\n";
    let (o, r, _) = trace("bounded", Some(spec), &["--seed", "0,0,0", "--no-complex"]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(r["complete"], true);
}

#[test]
fn empty_results_fail_with_the_reason() {
    let cases: [(&str, &[&str], &str); 4] = [
        // f has no zero in the box.
        (
            "ambient_dim = 3\nequations = [\"x^2 + y^2 + z^2 + 1\"]\nbox = [[-2, 2], [-2, 2], [-2, 2]]\n",
            &["--out", "m.ply", "--png", "m.png"],
            "no crossed simplex was found",
        ),
        // NaN everywhere.
        (
            "ambient_dim = 3\nequations = [\"sqrt(-1 - x^2) + y\"]\nbox = [[-2, 2], [-2, 2], [-2, 2]]\n",
            &["--out", "m.ply"],
            "NaN or infinite",
        ),
        // Zero only far outside the box.
        (
            "ambient_dim = 2\nequations = [\"x - 100\"]\nbox = [[-1, 1], [-1, 1]]\n",
            &["--out", "m.csv", "--search", "64"],
            "found no point of M",
        ),
        // Identically 0.
        (
            "ambient_dim = 3\nequations = [\"x*0 + 0*y\"]\nbox = [[-1, 1], [-1, 1], [-1, 1]]\n",
            &[],
            "identically 0",
        ),
    ];
    for (i, (spec, args, why)) in cases.iter().enumerate() {
        let dir = scratch(&format!("empty{i}"));
        std::fs::write(dir.join("s.toml"), spec).unwrap();
        let mut all = vec!["trace", "s.toml", "--threads", "2", "--report", "r.json"];
        all.extend_from_slice(args);
        let o = isomesh(&dir, &all);
        assert!(!o.status.success(), "case {i} exit 0: {}", text(&o));
        assert!(text(&o).contains(why), "case {i}: {}", text(&o));
        if i == 0 {
            assert!(
                text(&o).contains("not written: m.ply, m.png"),
                "{}",
                text(&o)
            );
            let r = report(&dir);
            assert_eq!(r["complete"], false);
            assert_eq!(r["simplex_count"], 0);
        }
        if i == 1 {
            assert!(report(&dir)["non_finite"].as_u64().unwrap() > 0);
        }
    }
}

#[test]
fn singular_seeds_are_warned_about() {
    for (i, (d, eq, seed, singular)) in [
        (2, "x1*x2", "0,0", true),
        (3, "x1^2 + x2^2 - x3^2", "0,0,0", true),
        (2, "x1^2 - x2^3", "0,0", true),
        (2, "x1*x2 - 0.25", "0.5,0.5", false),
        // Badly scaled, or steep: regular points, no warning.
        (2, "1e290 * (x1*x2 - 0.25)", "0.5,0.5", false),
        (2, "1e-295 * (x1*x2 - 0.25)", "0.5,0.5", false),
        (2, "x1^4000 - 0.5", "0.9998,0.3", false),
        (2, "x1^3700 - 0.5", "0.9998,0.3", false),
    ]
    .iter()
    .enumerate()
    {
        let spec = format!(
            "ambient_dim = {d}\nequations = [\"{eq}\"]\nbox = [{}]\n[triangulation]\nedge = 0.2\n",
            vec!["[-1, 1]"; *d].join(", ")
        );
        let (o, r, _) = trace(
            &format!("singular{i}"),
            Some(&spec),
            &["--seed", seed, "--threads", "2", "--no-complex"],
        );
        let t = text(&o);
        assert_eq!(t.contains("rank-deficient"), *singular, "{eq}: {t}");
        let listed = r["singular_seeds"].as_array().unwrap();
        assert_eq!(!listed.is_empty(), *singular, "{eq}: {r}");
    }
}

#[test]
fn a_trace_near_crossing_branches_says_so_and_how_to_get_them_all() {
    // Two lines crossing at the origin: the trace from a point of one follows the piecewise-
    // linear branch it is on, which turns at the origin; the scan finds both.
    let spec =
        "ambient_dim = 3\nequations = [\"x1*x2\", \"x3\"]\nbox = [[-1, 1], [-1, 1], [-1, 1]]\n\
                [triangulation]\nedge = 0.1\n";
    let (o, r, _) = trace(
        "crossing",
        Some(spec),
        &["--seed", "0.5,0,0", "--no-complex"],
    );
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(
        t.contains("rank-deficient") && t.contains("--exhaustive"),
        "{t}"
    );
    let near = r["singular_crossings"].as_array().unwrap();
    assert!(!near.is_empty(), "{r}");
    for x in near {
        let x: Vec<f64> = x
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let dist = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        assert!(dist < 0.2, "{x:?} is not within two edges of the crossing");
    }
    let traced = r["simplex_count"].as_u64().unwrap();
    let (o, r, _) = trace(
        "crossing_scan",
        Some(spec),
        &["--exhaustive", "--no-complex"],
    );
    assert!(!text(&o).contains("rank-deficient"), "{}", text(&o));
    assert_eq!(r["singular_crossings"].as_array().unwrap().len(), 0);
    assert!(r["simplex_count"].as_u64().unwrap() > traced, "{r}");
    // Smooth curves and surfaces, steep or flat in places: no warning.
    for (i, (eq, seed)) in [
        ("x1*x2 - 0.01\", \"x3", "0.5,0.02,0"),
        ("x1^2 + x2^2 + x3^2 - 1", "1,0,0"),
        ("x3 - x1^3", "0,0,0"),
    ]
    .iter()
    .enumerate()
    {
        let spec = format!(
            "ambient_dim = 3\nequations = [\"{eq}\"]\nbox = [[-1, 1], [-1, 1], [-1, 1]]\n\
             [triangulation]\nedge = 0.1\n"
        );
        let (o, r, _) = trace(
            &format!("smooth{i}"),
            Some(&spec),
            &["--seed", seed, "--no-complex"],
        );
        assert!(!text(&o).contains("rank-deficient"), "{eq}: {}", text(&o));
        assert_eq!(r["singular_crossings"].as_array().unwrap().len(), 0, "{eq}");
    }
}

#[test]
fn messages_name_what_to_change() {
    // A non-finite seed names the seed.
    let dir = scratch("messages");
    std::fs::write(
        dir.join("nan.toml"),
        "ambient_dim = 3\nequations = [\"x^2 + y^2 + z^2 - 1\"]\nseeds = [[1, 0, 0], [0, nan, 0]]\n",
    )
    .unwrap();
    let o = isomesh(&dir, &["check", "nan.toml"]);
    assert!(!o.status.success());
    assert!(text(&o).contains("in seed 2, coordinate 2"), "{}", text(&o));
    // A tiny edge or a far seed says what to change, not a saturated integer.
    for args in [
        &["--preset", "sphere", "--edge", "1e-300"][..],
        &["--preset", "sphere", "--edge", "1e-9"],
        &["--preset", "sphere", "--seed", "1e30,0,0"],
    ] {
        let mut all = vec!["trace"];
        all.extend_from_slice(args);
        let o = isomesh(&dir, &all);
        assert!(!o.status.success(), "{args:?}");
        let t = text(&o);
        assert!(!t.contains("9223372036854775808"), "{t}");
        assert!(
            t.contains("larger edge")
                || t.contains("off the manifold")
                || t.contains("the edge must be from 1e-100"),
            "{args:?}: {t}"
        );
    }
}

#[test]
fn high_dimensions_trace_with_no_box() {
    // A circle in R^d, d = 60 and 63, with no box (keys of 25 and 26 words): x1^2 + x2^2 =
    // 1/16 and x3 = ... = xd = 0.
    for d in [60usize, 63] {
        let mut eqs = vec!["\"x1^2 + x2^2 - 0.0625\"".to_string()];
        eqs.extend((3..=d).map(|i| format!("\"x{i}\"")));
        let seed = std::iter::once("0.25".to_string())
            .chain((1..d).map(|_| "0".to_string()))
            .collect::<Vec<_>>()
            .join(",");
        let spec = format!(
            "ambient_dim = {d}\nequations = [{}]\n[triangulation]\nedge = 0.1\n",
            eqs.join(", ")
        );
        let (o, r, _) = trace(
            &format!("dim{d}"),
            Some(&spec),
            &["--seed", &seed, "--threads", "2", "--no-complex"],
        );
        assert!(o.status.success(), "d = {d}: {}", text(&o));
        assert!(r["simplex_count"].as_u64().unwrap() > 0);
    }
}

/// A spec that never ends (a device, a pipe) is read only as far as a spec may go, under any
/// memory limit, and refused; an exhaustive scan of a NaN f says so, as the trace does.
#[cfg(unix)]
#[test]
fn endless_specs_are_refused_and_nan_scans_say_so() {
    let dir = scratch("endless");
    for limit in ["48M", "2G"] {
        let o = isomesh(&dir, &["trace", "/dev/zero", "--max-memory", limit]);
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        assert!(text(&o).contains("a spec file is at most"), "{}", text(&o));
    }
    std::fs::write(
        dir.join("nan.toml"),
        "ambient_dim = 3\nequations = [\"ln(-2 - x^2) + z\"]\nbox = [[-1, 1], [-1, 1], [-1, 1]]\n",
    )
    .unwrap();
    let o = isomesh(&dir, &["trace", "nan.toml", "--exhaustive"]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("NaN or infinite"), "{}", text(&o));
}

/// A spec of many seed points is refused under a memory limit its reading would pass: the
/// TOML reader takes about 55 bytes of heap for each byte of such a spec.
#[test]
fn a_spec_of_many_seeds_is_refused_under_a_limit_its_reading_would_pass() {
    let dir = scratch("many-seeds");
    let mut spec =
        String::from("ambient_dim = 3\nequations = [\"x1^2 + x2^2 + x3^2 - 1\"]\nseeds = [\n");
    for i in 0..200_000 {
        let t = i as f64 * 1e-3;
        spec += &format!("[{:.6}, {:.6}, 0.0],\n", t.cos(), t.sin());
    }
    spec += "]\n";
    std::fs::write(dir.join("s.toml"), &spec).unwrap();
    // 5.6 MB of text: 56 MB by the old estimate, under this limit; 307 MB of heap to read.
    let o = isomesh(
        &dir,
        &["trace", "s.toml", "--max-memory", "96M", "--no-complex"],
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("reading the spec"), "{}", text(&o));
    // The advice names the seeds, not the equations.
    assert!(text(&o).contains("fewer seed points"), "{}", text(&o));
}

/// An f of a scale far from 1 is found by the seed search and from seeds as the same f at
/// scale 1 is: the projection accepts a point within the tolerance of M, not only |f| that
/// small.
#[test]
fn badly_scaled_equations_are_found_from_seeds_and_by_the_search() {
    let sphere = "x1^2 + x2^2 + x3^2 - 0.8";
    let count = |eq: &str, seed: bool| {
        let mut spec = format!(
            "ambient_dim = 3\nequations = [\"{eq}\"]\nbox = [[-1.2, 1.2], [-1.2, 1.2], [-1.2, 1.2]]\n"
        );
        if seed {
            spec.push_str("seeds = [[0.2, 0.5, 0.6]]\n");
        }
        let (o, r, _) = trace("scaled", Some(&spec), &["--edge", "0.15", "--no-complex"]);
        assert!(o.status.success(), "{eq}: {}", text(&o));
        assert!(!text(&o).contains("rank-deficient"), "{eq}: {}", text(&o));
        r["simplex_count"].as_u64().unwrap()
    };
    for seed in [true, false] {
        let want = count(sphere, seed);
        for scale in ["3e299", "7e-302"] {
            assert_eq!(
                count(&format!("{scale} * ({sphere})"), seed),
                want,
                "{scale}"
            );
        }
    }
}
