//! SIGINT, SIGTERM and SIGHUP at each phase of a run: the first stops it between steps with
//! the partial sample and a report saying `complete: false`, no temporary file left, and exit
//! status 128 + the signal's number; a second aborts at once.
#![cfg(unix)]

mod common;

use std::io::{BufRead, BufReader};
use std::process::{Child, ExitStatus};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use common::{report, spawn, wait_for, Scratch};

/// Generous: the machine may be loaded.
const PATIENCE: Duration = Duration::from_secs(60);

/// A running isomesh and the lines of its standard error so far.
struct Run {
    child: Child,
    lines: Arc<Mutex<Vec<String>>>,
}

impl Run {
    fn start(dir: &Scratch, args: &[&str]) -> Run {
        Run::watch(spawn(&dir.0, args))
    }

    /// Reads the standard error of `child` as it comes.
    fn watch(mut child: Child) -> Run {
        let lines = Arc::new(Mutex::new(Vec::new()));
        let err = child.stderr.take().unwrap();
        let sink = lines.clone();
        std::thread::spawn(move || {
            for l in BufReader::new(err).lines().map_while(Result::ok) {
                sink.lock().unwrap().push(l);
            }
        });
        Run { child, lines }
    }

    /// Waits until a line of standard error contains `text`.
    fn wait_line(&self, text: &str) {
        let seen = wait_for(PATIENCE, || {
            self.lines.lock().unwrap().iter().any(|l| l.contains(text))
        });
        assert!(
            seen,
            "no line with {text:?}: {:?}",
            self.lines.lock().unwrap()
        );
    }

    fn signal(&self, name: &str) {
        let ok = std::process::Command::new("kill")
            .args([&format!("-{name}"), &self.child.id().to_string()])
            .status()
            .unwrap();
        assert!(ok.success());
    }

    /// The exit status, and how long it took to come.
    fn wait(mut self) -> (ExitStatus, Duration, Vec<String>) {
        let start = Instant::now();
        let mut status = None;
        let exited = wait_for(PATIENCE, || {
            status = self.child.try_wait().unwrap();
            status.is_some()
        });
        if !exited {
            let _ = self.child.kill();
            panic!("did not stop: {:?}", self.lines.lock().unwrap());
        }
        // Let the reader thread take the last lines.
        std::thread::sleep(Duration::from_millis(50));
        let lines = self.lines.lock().unwrap().clone();
        (status.unwrap(), start.elapsed(), lines)
    }
}

fn number(name: &str) -> i32 {
    match name {
        "INT" => 2,
        "TERM" => 15,
        "HUP" => 1,
        _ => unreachable!(),
    }
}

/// Sends `sig` once `line` appears and checks the stop: exit status, the report's
/// `complete: false`, stop reason and signal, the sample on disk, no `.partial` file.
fn stop_at(name: &str, args: &[&str], line: &str, sig: &str) -> serde_json::Value {
    let dir = Scratch::new(&format!("signal-{name}-{sig}"));
    let run = |all: &[&str]| Run::start(&dir, all);
    stop_run(&dir, name, args, run, line, &|r: &Run| r.signal(sig), sig)
}

/// As [`stop_at`], with the run started by `start` and signalled by `send`.
fn stop_run(
    dir: &Scratch,
    name: &str,
    args: &[&str],
    start: impl Fn(&[&str]) -> Run,
    line: &str,
    send: &dyn Fn(&Run),
    sig: &str,
) -> serde_json::Value {
    std::fs::write(
        dir.path("noseed.toml"),
        "ambient_dim = 3\nequations = [\"x1^2 + x2^2 + x3^2 - 1\"]\nbox = [[-1.5, 1.5], \
         [-1.5, 1.5], [-1.5, 1.5]]\n",
    )
    .unwrap();
    let mut all = args.to_vec();
    all.extend(["-v", "--out", "s.csv", "--report", "r.json"]);
    let run = start(&all);
    run.wait_line(line);
    send(&run);
    let (status, _, lines) = run.wait();
    assert_eq!(
        status.code(),
        Some(128 + number(sig)),
        "{name} {sig}: {lines:?}"
    );
    let mut r = report(&dir.path("r.json"));
    r["files"] = dir.files().into();
    assert_eq!(r["complete"], false, "{name} {sig}: {r}");
    assert_eq!(r["stopped"], "interrupted", "{name} {sig}");
    assert_eq!(r["signal"], format!("SIG{sig}"), "{name} {sig}");
    // The partial sample: a header and the report's count of points.
    let sample = std::fs::read_to_string(dir.path("s.csv")).unwrap();
    assert!(sample.starts_with("x1,"), "{name} {sig}");
    assert_eq!(
        sample.lines().count() - 1,
        r["simplex_count"].as_u64().unwrap() as usize,
        "{name} {sig}"
    );
    assert!(
        dir.partials().is_empty(),
        "{name} {sig}: {:?}",
        dir.partials()
    );
    assert!(
        lines.iter().any(|l| l.contains("complete: false")),
        "{name} {sig}: {lines:?}"
    );
    r
}

/// A 3-D box whose scan spends seconds evaluating f on its grid.
const GRID: &[&str] = &[
    "trace",
    "--preset",
    "sphere",
    "--exhaustive",
    "--box",
    "-1.5,1.5",
    "--edge",
    "0.015",
];
/// A search with many box points, from a spec with no seed (written by the test).
const SEARCH: &[&str] = &[
    "trace",
    "noseed.toml",
    "--search",
    "2000000",
    "--no-complex",
];
/// A trace of many levels (about 760).
const LEVELS: &[&str] = &[
    "trace", "--preset", "sphere", "--param", "r=2", "--edge", "0.02",
];
/// A surface whose complex takes a second or two to build and whose ASCII VTU as long to write.
const MESHED: &[&str] = &[
    "trace", "--preset", "sphere", "--param", "r=2", "--edge", "0.02", "--ascii",
];

#[test]
fn the_grid_phase_of_a_scan_stops_cleanly() {
    // The whole scan's grid, for the counts of the stopped ones.
    let dir = Scratch::new("signal-grid-whole");
    let mut all = GRID.to_vec();
    all.extend(["--no-complex", "--report", "r.json"]);
    let (status, _, lines) = Run::start(&dir, &all).wait();
    assert_eq!(status.code(), Some(0), "{lines:?}");
    let whole = report(&dir.path("r.json"));
    let grid = whole["vertices_evaluated"].as_u64().unwrap();
    for sig in ["INT", "TERM", "HUP"] {
        let r = stop_at("grid", GRID, "scan: evaluating", sig);
        // Stopped while the grid was evaluated a slab at a time: f at part of it, each
        // vertex once, and the crossings of the slabs before kept.
        let evaluated = r["vertices_evaluated"].as_u64().unwrap();
        assert!(evaluated < grid, "{sig}: {evaluated} of {grid}: {r}");
        assert_eq!(r["cpu_vertex_evaluations"], evaluated, "{sig}: {r}");
        assert!(
            r["simplex_count"].as_u64().unwrap() < whole["simplex_count"].as_u64().unwrap(),
            "{sig}: {r}"
        );
    }
}

#[test]
fn the_seed_search_stops_cleanly() {
    for sig in ["INT", "TERM", "HUP"] {
        let r = stop_at("search", SEARCH, "box points projected", sig);
        // Stopped among the projections: fewer than the 2,000,000 (nearly all land in the
        // box), and none traced from.
        assert!(r["seed_points"].as_u64().unwrap() < 1_000_000, "{sig}: {r}");
        assert_eq!(r["levels"], 0, "{sig}: {r}");
        assert_eq!(r["simplex_count"], 0, "{sig}");
    }
}

#[test]
fn trace_levels_stop_cleanly_with_the_partial_sample() {
    for sig in ["INT", "TERM", "HUP"] {
        let r = stop_at("levels", LEVELS, "isomesh: level 100,", sig);
        let levels = r["levels"].as_u64().unwrap();
        assert!((100..700).contains(&levels), "{sig}: {levels} levels");
        assert!(r["simplex_count"].as_u64().unwrap() > 0, "{sig}");
    }
}

#[test]
fn the_complex_and_the_writing_stop_cleanly() {
    for sig in ["INT", "TERM", "HUP"] {
        let mut args = MESHED.to_vec();
        args.extend(["--out", "m.vtu"]);
        let r = stop_at("complex", &args, "complex: building", sig);
        // The trace was whole; no mesh was written.
        assert!(r["simplex_count"].as_u64().unwrap() > 100_000);
        assert!(
            !r["files"].as_array().unwrap().contains(&"m.vtu".into()),
            "{r}"
        );
    }
    // The topology of a complex that takes a second or more to analyse.
    for sig in ["INT", "TERM", "HUP"] {
        let args = [
            "trace", "--preset", "sphere", "--param", "r=3", "--edge", "0.02", "--out", "m.ply",
        ];
        let r = stop_at("topology", &args, "complex: topology", sig);
        assert!(r["simplex_count"].as_u64().unwrap() > 100_000);
        assert!(r["betti_mod2"].is_null(), "{r}");
        assert!(
            !r["files"].as_array().unwrap().contains(&"m.ply".into()),
            "{r}"
        );
    }
    for sig in ["INT", "TERM", "HUP"] {
        let mut args = MESHED.to_vec();
        args.extend(["--out", "m.vtu", "--out", "m.ply"]);
        let r = stop_at("writing", &args, "writing m.vtu", sig);
        // The file being written is finished, the next one skipped.
        let files = r["files"].as_array().unwrap();
        assert!(files.contains(&"m.vtu".into()), "{r}");
        assert!(!files.contains(&"m.ply".into()), "{r}");
    }
}

#[test]
fn a_second_signal_aborts_promptly() {
    for second in ["INT", "TERM"] {
        let dir = Scratch::new(&format!("second-signal-{second}"));
        let mut args = MESHED.to_vec();
        args.extend([
            "-v", "--out", "s.csv", "--out", "m.vtu", "--report", "r.json",
        ]);
        let run = Run::start(&dir, &args);
        run.wait_line("writing m.vtu");
        run.signal("INT");
        run.wait_line("send it again");
        run.signal(second);
        let (status, took, lines) = run.wait();
        assert_eq!(status.code(), Some(128 + number(second)), "{lines:?}");
        assert!(took < Duration::from_secs(5), "{took:?}");
        assert!(lines.iter().any(|l| l.contains("aborted")), "{lines:?}");
        // Aborted in the middle of the write: no mesh, no report, no temporary file.
        assert_eq!(dir.files(), ["s.csv".to_string()], "{lines:?}");
    }
}

/// A supervisor that signals the process and then its process group (as GNU `timeout`,
/// shells and job runners do) asks once: the run stops cleanly and keeps what it found, it
/// does not take the copy for a second signal and abort.
#[test]
fn a_signal_to_the_process_and_its_group_stops_it_cleanly() {
    use std::os::unix::process::CommandExt;
    for round in 0..4 {
        let dir = Scratch::new(&format!("group-signal-{round}"));
        let start = |all: &[&str]| {
            let child = common::command(&dir.0, all)
                .process_group(0)
                .stdout(std::process::Stdio::null())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap();
            Run::watch(child)
        };
        // Both from one shell, as from one supervisor.
        let send = |r: &Run| {
            let pid = r.child.id();
            let ok = std::process::Command::new("sh")
                .args(["-c", &format!("kill -TERM {pid}; kill -TERM -{pid}")])
                .status()
                .unwrap();
            assert!(ok.success());
        };
        let r = stop_run(
            &dir,
            "group",
            LEVELS,
            start,
            "isomesh: level 100,",
            &send,
            "TERM",
        );
        assert!(r["simplex_count"].as_u64().unwrap() > 0, "{r}");
    }
}

/// Under GNU `timeout` (which signals the run and then its own process group) a run past its
/// time keeps its sample and its report.
#[test]
fn a_run_under_timeout_keeps_what_it_found() {
    let dir = Scratch::new("under-timeout");
    let exe = env!("CARGO_BIN_EXE_isomesh");
    let out = std::process::Command::new("timeout")
        .args([
            "-s",
            "TERM",
            "3",
            exe,
            "trace",
            "--preset",
            "sphere",
            "--param",
            "r=6",
            "--edge",
            "0.01",
            "--threads",
            "1",
            "--out",
            "s.csv",
            "--report",
            "r.json",
        ])
        .current_dir(&dir.0)
        .output()
        .expect("GNU timeout runs");
    // 124: timeout stopped it.
    assert_eq!(out.status.code(), Some(124), "{}", common::stderr(&out));
    let r = report(&dir.path("r.json"));
    assert_eq!(r["complete"], false, "{r}");
    assert_eq!(r["signal"], "SIGTERM", "{r}");
    let sample = std::fs::read_to_string(dir.path("s.csv")).unwrap();
    assert_eq!(
        sample.lines().count() - 1,
        r["simplex_count"].as_u64().unwrap() as usize
    );
    assert!(dir.partials().is_empty(), "{:?}", dir.partials());
}
