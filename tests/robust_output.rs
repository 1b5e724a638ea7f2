//! Output paths and output flags: what may be written, checked before anything is traced;
//! outputs never replace the input spec, each other, a device, a link's target or a FIFO;
//! concurrent runs on one path each write a whole file of their own.

mod common;

use common::{isomesh, stderr, Scratch};

/// A run whose trace takes a while, so a refusal after it would be visible.
const SLOW: [&str; 6] = ["trace", "--preset", "sphere", "--edge", "0.03", "-q"];

fn run(dir: &Scratch, extra: &[&str]) -> std::process::Output {
    let args: Vec<&str> = SLOW.iter().chain(extra).copied().collect();
    isomesh(&dir.0, &args)
}

#[cfg(unix)]
#[test]
fn special_files_are_refused_and_left_untouched() {
    use std::os::unix::fs::FileTypeExt;
    let dir = Scratch::new("special");
    std::fs::write(dir.path("victim.txt"), "keep me").unwrap();
    std::os::unix::fs::symlink(dir.path("victim.txt"), dir.path("link.csv")).unwrap();
    std::os::unix::fs::symlink(dir.path("absent.txt"), dir.path("dangling.json")).unwrap();
    std::fs::create_dir(dir.path("folder.ply")).unwrap();
    let fifo = std::process::Command::new("mkfifo")
        .arg(dir.path("pipe.csv"))
        .status()
        .unwrap();
    assert!(fifo.success());
    let _socket = std::os::unix::net::UnixListener::bind(dir.path("sock.csv")).unwrap();
    let cases: Vec<(Vec<String>, &str)> = vec![
        (vec!["--out".into(), "/dev/null".into()], "a device"),
        (vec!["--out".into(), "/dev/full".into()], "a device"),
        (vec!["--report".into(), "/dev/null".into()], "a device"),
        (vec!["--out".into(), "link.csv".into()], "a symbolic link"),
        (
            vec!["--report".into(), "dangling.json".into()],
            "a symbolic link",
        ),
        (vec!["--out".into(), "folder.ply".into()], "a directory"),
        (vec!["--out".into(), "pipe.csv".into()], "a FIFO"),
        (vec!["--out".into(), "sock.csv".into()], "a socket"),
        (vec!["--png".into(), "/dev/null".into()], "a device"),
    ];
    let before = dir.files();
    for (flags, what) in &cases {
        let mut extra: Vec<&str> = flags.iter().map(String::as_str).collect();
        extra.extend(["--out", "good.csv"]);
        let o = run(&dir, &extra);
        let e = stderr(&o);
        assert!(!o.status.success(), "{flags:?} accepted");
        assert!(e.contains(what), "{flags:?}: {e}");
        assert!(e.contains("regular file"), "{flags:?}: {e}");
        // Refused before tracing: the sample, written first after a trace, is absent.
        assert_eq!(dir.files(), before, "{flags:?}: files changed");
    }
    assert_eq!(
        std::fs::read_to_string(dir.path("victim.txt")).unwrap(),
        "keep me"
    );
    assert!(std::fs::symlink_metadata(dir.path("link.csv"))
        .unwrap()
        .file_type()
        .is_symlink());
    assert!(!dir.path("absent.txt").exists());
    for dev in ["/dev/null", "/dev/full"] {
        assert!(std::fs::metadata(dev).unwrap().file_type().is_char_device());
    }
    assert!(std::fs::metadata(dir.path("pipe.csv"))
        .unwrap()
        .file_type()
        .is_fifo());
}

#[test]
fn an_output_naming_the_spec_or_another_output_is_refused() {
    let dir = Scratch::new("same");
    let spec = "ambient_dim = 2\nequations = [\"x1^2 + x2^2 - 1\"]\nseeds = [[1, 0]]\n";
    std::fs::write(dir.path("s.toml"), spec).unwrap();
    std::fs::create_dir(dir.path("sub")).unwrap();
    std::fs::hard_link(dir.path("s.toml"), dir.path("hard.json")).unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(".", dir.path("here")).unwrap();
    let mut cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["--report", "s.toml"], "input spec"),
        (vec!["--report", "./s.toml"], "input spec"),
        (vec!["--report", "sub/../s.toml"], "input spec"),
        (vec!["--report", "hard.json"], "input spec"),
        (vec!["--out", "a.csv", "--report", "a.csv"], "same file"),
        (vec!["--out", "m.ply", "--png", "m.ply"], "same file"),
        (vec!["--out", "a.csv", "--out", "./a.csv"], "same file"),
        (vec!["--out", "a.csv", "--out", "sub/../a.csv"], "same file"),
        (vec!["--out", "a.csv", "--out", "new/../a.csv"], "same file"),
        (
            vec!["--out", "sub/a.csv", "--report", "sub//a.csv"],
            "same file",
        ),
    ];
    #[cfg(unix)]
    cases.push((vec!["--out", "a.csv", "--out", "here/a.csv"], "same file"));
    let before = dir.files();
    for (flags, what) in &cases {
        let mut args = vec!["trace", "s.toml", "-q"];
        args.extend(flags);
        let o = isomesh(&dir.0, &args);
        let e = stderr(&o);
        assert!(!o.status.success(), "{flags:?} accepted");
        assert!(e.contains(what), "{flags:?}: {e}");
        assert_eq!(dir.files(), before, "{flags:?}: files changed");
        assert_eq!(std::fs::read_to_string(dir.path("s.toml")).unwrap(), spec);
    }
    assert!(dir.files().iter().all(|f| f != "new"));
    // Distinct paths still work, and an existing regular output is replaced.
    std::fs::write(dir.path("a.csv"), "old").unwrap();
    let o = isomesh(
        &dir.0,
        &[
            "trace",
            "s.toml",
            "-q",
            "--out",
            "a.csv",
            "--report",
            "sub/a.json",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::read_to_string(dir.path("a.csv"))
        .unwrap()
        .starts_with("x1,x2\n"));
    assert_eq!(std::fs::read_to_string(dir.path("s.toml")).unwrap(), spec);
}

#[test]
fn concurrent_runs_on_one_out_each_write_a_whole_file() {
    let dir = Scratch::new("concurrent");
    // Runs of one size (different lattice offsets, so different points) end together, and
    // their writes of some MB overlap.
    const RUNS: usize = 4;
    for round in 0..2 {
        let children: Vec<_> = (0..RUNS)
            .map(|i| {
                let (own, seed) = (format!("own{i}.csv"), format!("{}", 1 + i + RUNS * round));
                common::command(
                    &dir.0,
                    &[
                        "trace",
                        "--preset",
                        "sphere",
                        "--edge",
                        "0.025",
                        "--offset-seed",
                        &seed,
                        "--no-complex",
                        "-q",
                        "--out",
                        "same.csv",
                        "--out",
                        &own,
                    ],
                )
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
            })
            .collect();
        for c in children {
            let o = c.wait_with_output().unwrap();
            assert!(o.status.success(), "round {round}: {}", stderr(&o));
        }
        let same = std::fs::read(dir.path("same.csv")).unwrap();
        let own: Vec<Vec<u8>> = (0..RUNS)
            .map(|i| std::fs::read(dir.path(&format!("own{i}.csv"))).unwrap())
            .collect();
        assert_ne!(own[0], own[1]);
        assert!(
            own.contains(&same),
            "round {round}: same.csv is no run's sample"
        );
        assert!(dir.partials().is_empty(), "{:?}", dir.partials());
    }
}

#[test]
fn output_flags_are_checked_before_tracing() {
    let dir = Scratch::new("flags");
    let cases: &[(&[&str], &str)] = &[
        (&["--out", "x.foo"], "unknown output format"),
        (&["--out", "x"], "unknown output format"),
        (&["--out", "y.csv", "--format", "bogus"], "--format bogus"),
        (&["--format", "csv"], "give --out"),
        (&["--project", "1,1,1"], "repeated"),
        (&["--project", "1,2,9"], "from 1 to 3"),
        (&["--project", "0,1"], "from 1 to 3"),
        (&["--project", "1,2,3,1"], "1 to 3 coordinates"),
        (&["--png", "p.png", "--png-size", "0x0"], "64 to 8192"),
        (&["--png", "p.png", "--png-size", "9000x600"], "64 to 8192"),
        (
            &["--png", "p.png", "--png-size", "100000x100000"],
            "64 to 8192",
        ),
        // Flags that would be ignored.
        (&["--png-size", "640x480"], "give --png too"),
        (
            &["--exhaustive", "--seed", "0,0,1"],
            "--seed starts a trace",
        ),
        (
            &["--exhaustive", "--search", "100"],
            "--search starts a trace",
        ),
        (&["--png", "p.png", "--png-size", "12"], "WIDTHxHEIGHT"),
        (&["--no-complex", "--out", "m.ply"], "--no-complex"),
        (&["--no-complex", "--png", "p.png"], "--no-complex"),
        (
            &[
                "--out", "m.mesh", "--out", "c.off", "--param", "d=4", "--param", "m=1",
            ],
            "cannot hold",
        ),
        (&["--precision", "f32"], "--precision"),
        (&["--level-slice", "100"], "--level-slice"),
        (&["--device-values"], "the CPU backend"),
        (
            &["--device-values", "--backend", "auto"],
            "applies to exhaustive scans",
        ),
        (&["--out", "-", "--format", "ply"], "standard output"),
        (&["--out", "-", "--out", "-"], "twice"),
        (
            &["--out", "-", "--report", "-"],
            "both ask for standard output",
        ),
        (&["--png", "-"], "--png -"),
    ];
    for (flags, what) in cases {
        let mut extra = flags.to_vec();
        if flags != &["--format", "csv"] {
            extra.extend(["--out", "good.csv"]);
        }
        let o = run(&dir, &extra);
        let e = stderr(&o);
        assert!(!o.status.success(), "{flags:?} accepted");
        assert!(e.contains(what), "{flags:?}: {e}");
        assert!(dir.files().is_empty(), "{flags:?}: {:?}", dir.files());
    }
}

#[test]
fn negative_and_bad_numbers_get_a_clear_message() {
    let dir = Scratch::new("numbers");
    let cases: &[(&[&str], &str)] = &[
        (&["--edge", "-1"], "must be positive"),
        (&["--edge", "0"], "must be positive"),
        (&["--edge", "nan"], "must be positive"),
        (&["--edge", "inf"], "must be positive"),
        (&["--edge", "abc"], "not a number"),
        (&["--threads", "-1"], "negative"),
        (&["--search", "-5"], "negative"),
        (&["--offset-seed", "-2"], "negative"),
        (&["--max-memory", "-1G"], "positive"),
    ];
    for (flags, what) in cases {
        let mut args = vec!["trace", "--preset", "circle", "-q"];
        args.extend(*flags);
        let o = isomesh(&dir.0, &args);
        let e = stderr(&o);
        assert!(!o.status.success(), "{flags:?} accepted");
        assert!(e.contains(what), "{flags:?}: {e}");
        assert!(!e.contains("unexpected argument"), "{flags:?}: {e}");
    }
}

#[test]
fn param_overrides_a_spec_and_box_rows_are_checked() {
    let dir = Scratch::new("spec-values");
    std::fs::write(
        dir.path("c.toml"),
        "ambient_dim = 2\nparameters = { r = 1 }\nequations = [\"x1^2 + x2^2 - r^2\"]\n\
         seeds = [[1, 0]]\n",
    )
    .unwrap();
    let radius = |extra: &[&str]| -> f64 {
        let mut args = vec!["trace", "c.toml", "-q", "--no-complex", "--out", "s.csv"];
        args.extend(extra);
        let o = isomesh(&dir.0, &args);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        let text = std::fs::read_to_string(dir.path("s.csv")).unwrap();
        let rows: Vec<f64> = text
            .lines()
            .skip(1)
            .map(|l| {
                let v: Vec<f64> = l.split(',').map(|t| t.parse().unwrap()).collect();
                (v[0] * v[0] + v[1] * v[1]).sqrt()
            })
            .collect();
        rows.iter().sum::<f64>() / rows.len() as f64
    };
    assert!((radius(&[]) - 1.0).abs() < 0.01);
    assert!((radius(&["--param", "r=2"]) - 2.0).abs() < 0.01);
    assert!((radius(&["--param", "r=0.5"]) - 0.5).abs() < 0.01);
    let o = isomesh(&dir.0, &["trace", "c.toml", "--param", "q=2"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("no such parameter") && stderr(&o).contains("it has r"));
    for (rows, n) in [
        ("[[-2, 2, 3], [-2, 2]]", 3),
        ("[[-2, 2], [-2, 2, 0, 1]]", 4),
        ("[[-2], [-2, 2]]", 1),
    ] {
        std::fs::write(
            dir.path("b.toml"),
            format!("ambient_dim = 2\nequations = [\"x1^2 + x2^2 - 1\"]\nbox = {rows}\n"),
        )
        .unwrap();
        let o = isomesh(&dir.0, &["check", "b.toml"]);
        let e = stderr(&o);
        assert!(!o.status.success(), "{rows} accepted");
        assert!(e.contains(&format!("has {n} numbers")), "{rows}: {e}");
    }
}

/// An output that cannot be written (here a name so long that its temporary file's name is
/// refused) is reported failed on its own: the outputs after it and the report are written.
#[test]
fn a_failed_output_does_not_cost_the_others() {
    let dir = Scratch::new("one-fails");
    // 249 characters: a valid name, but not with the temporary file's prefix and suffix.
    let long = format!("{}.csv", "q".repeat(245));
    for first in [long.as_str(), "m.ply"] {
        let mut names = vec![long.as_str(), "good.csv", "m.ply", "good.obj"];
        names.retain(|n| *n != first);
        names.insert(0, first);
        let mut extra = Vec::new();
        for n in &names {
            extra.extend(["--out", n]);
        }
        extra.extend(["--report", "r.json"]);
        let o = run(&dir, &extra);
        let e = stderr(&o);
        assert!(!o.status.success(), "{first}: {e}");
        assert!(
            e.contains("File name too long") || e.contains("name too long"),
            "{e}"
        );
        assert_eq!(
            dir.files(),
            ["good.csv", "good.obj", "m.ply", "r.json"],
            "{first}: {e}"
        );
        let r = common::report(&dir.path("r.json"));
        assert_eq!(r["complete"], false, "{r}");
        assert_eq!(r["not_written"], serde_json::json!([long]), "{r}");
        assert!(r["error"].as_str().unwrap().contains("too long"), "{r}");
        for f in dir.files() {
            std::fs::remove_file(dir.path(&f)).unwrap();
        }
    }
}

/// `--out -` and `--report -` with standard output closed are refused before the trace (the
/// bytes would go nowhere); with files only, the run works.
#[cfg(unix)]
#[test]
fn a_closed_standard_output_is_refused_or_left_alone() {
    let dir = Scratch::new("closed-stdout");
    let exe = env!("CARGO_BIN_EXE_isomesh");
    let sh = |args: &str| {
        std::process::Command::new("sh")
            .args(["-c", &format!("exec \"$0\" {args} >&-"), exe])
            .current_dir(&dir.0)
            .output()
            .unwrap()
    };
    for flag in ["--out", "--report"] {
        let o = sh(&format!("trace --preset sphere --edge 0.1 {flag} -"));
        let e = stderr(&o);
        assert!(!o.status.success(), "{flag}: {e}");
        assert!(e.contains("standard output is closed"), "{flag}: {e}");
    }
    // With files only, the run works and the summary lines go nowhere.
    let o = sh("trace --preset sphere --edge 0.1 --out s.csv --report r.json");
    assert!(o.status.success(), "{}", stderr(&o));
    let sample = std::fs::read_to_string(dir.path("s.csv")).unwrap();
    let r = common::report(&dir.path("r.json"));
    assert!(sample.starts_with("x1,") && !sample.contains("wrote"));
    assert_eq!(
        sample.lines().count() - 1,
        r["simplex_count"].as_u64().unwrap() as usize
    );
}

/// `isomesh bench` checks its outputs as the trace does, before measuring.
#[test]
fn bench_outputs_are_checked_before_measuring() {
    let dir = Scratch::new("bench-outputs");
    let cases: &[(&[&str], &str)] = &[
        (&["--json", "a.x", "--png", "a.x"], "the same file"),
        (&["--json", "a.json", "--png", "./a.json"], "the same file"),
        (&["--json", "/dev/null"], "a device"),
        (&["--png", "."], "a directory"),
    ];
    for (flags, what) in cases {
        let mut args = vec![
            "bench",
            "--backend",
            "cpu",
            "--k",
            "1",
            "--count",
            "1000",
            "--traces",
            "none",
        ];
        args.extend_from_slice(flags);
        let o = common::isomesh(&dir.0, &args);
        let e = stderr(&o);
        assert!(!o.status.success(), "{flags:?} accepted");
        assert!(e.contains(what), "{flags:?}: {e}");
        assert!(
            !String::from_utf8_lossy(&o.stdout).contains("simplices/s"),
            "{flags:?}"
        );
        assert!(dir.files().is_empty(), "{flags:?}: {:?}", dir.files());
    }
}

/// f identically 0 on a region of the box: the run fails with a message naming a point,
/// and keeps its sample and report (no mesh is made of it).
#[test]
fn f_vanishing_on_a_region_fails_and_keeps_the_sample() {
    let dir = Scratch::new("zero-region");
    std::fs::write(
        dir.path("z.toml"),
        "ambient_dim = 3\nequations = [\"max(0.4 - x3, 0)\"]\nbox = [[-1, 1], [-1, 1], [-1, 1]]\n",
    )
    .unwrap();
    for scan in [false, true] {
        let mut args = vec![
            "trace", "z.toml", "-q", "--edge", "0.19", "--out", "s.csv", "--out", "m.ply",
            "--report", "r.json",
        ];
        if scan {
            args.push("--exhaustive");
        }
        let o = common::isomesh(&dir.0, &args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{e}");
        assert!(e.contains("identically 0 around"), "{e}");
        assert_eq!(dir.files(), ["r.json", "s.csv", "z.toml"], "{e}");
        let r = common::report(&dir.path("r.json"));
        assert_eq!(r["complete"], false, "{r}");
        assert!(
            r["error"].as_str().unwrap().contains("identically 0"),
            "{r}"
        );
        std::fs::remove_file(dir.path("s.csv")).unwrap();
        std::fs::remove_file(dir.path("r.json")).unwrap();
    }
}

/// A file replaced by a run keeps its permissions: a private (0600) output stays private.
#[cfg(unix)]
#[test]
fn a_replaced_output_keeps_its_permissions() {
    use std::os::unix::fs::PermissionsExt;
    let dir = Scratch::new("modes");
    for (name, mode) in [("s.csv", 0o600), ("r.json", 0o640), ("m.ply", 0o604)] {
        std::fs::write(dir.path(name), "old").unwrap();
        std::fs::set_permissions(dir.path(name), std::fs::Permissions::from_mode(mode)).unwrap();
    }
    let o = run(
        &dir,
        &["--out", "s.csv", "--out", "m.ply", "--report", "r.json"],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    for (name, mode) in [("s.csv", 0o600), ("r.json", 0o640), ("m.ply", 0o604)] {
        let m = std::fs::metadata(dir.path(name)).unwrap();
        assert!(m.len() > 3, "{name} was not replaced");
        assert_eq!(m.permissions().mode() & 0o777, mode, "{name}");
    }
}
