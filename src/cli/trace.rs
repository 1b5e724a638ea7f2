//! `isomesh trace`: load a problem, apply the flags, trace (or scan), write the sample and
//! the JSON report, print a summary.

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use isomesh::export::{write_atomic, write_sample, SampleFormat};
use isomesh::expr::{ImplicitFunction, Problem};
use isomesh::memory;
use isomesh::trace::{exhaustive, trace, CpuOracle, Progress, TraceOptions};
use isomesh::triangulation::TriangulationKind;
use isomesh::{Error, Result};
use serde_json::json;

use super::load;

/// Which oracle runs the intersection tests.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Backend {
    /// f64 on the CPU (the reference).
    Cpu,
    /// The GPU oracle.
    Gpu,
    /// A hardware GPU when there is one, else the CPU.
    Auto,
}

/// Flags of `isomesh trace`; they override the spec's values.
#[derive(Args, Clone, Debug, Default)]
pub struct TraceArgs {
    /// A spec file (TOML).
    pub spec: Option<PathBuf>,
    /// A built-in manifold instead of a spec file (`isomesh presets` lists them).
    #[arg(long)]
    pub preset: Option<String>,
    /// Preset parameter, name=value (repeatable).
    #[arg(long = "param", value_parser = super::parse_param)]
    pub params: Vec<(String, f64)>,
    /// Triangulation: coxeter or freudenthal.
    #[arg(long)]
    pub triangulation: Option<TriangulationKind>,
    /// Seed of the random offset of the triangulation.
    #[arg(long)]
    pub offset_seed: Option<u64>,
    /// Seed of the random rotation of the triangulation (default 1).
    #[arg(long, conflicts_with = "no_rotation")]
    pub rotation_seed: Option<u64>,
    /// Keep the triangulation's lattice axis-aligned (no rotation).
    #[arg(long)]
    pub no_rotation: bool,
    /// Seed point x1,..,xd near M (repeatable; replaces the spec's seeds).
    #[arg(long = "seed", allow_hyphen_values = true)]
    pub seeds: Vec<NumList>,
    /// Longest edge of a d-simplex of the triangulation.
    #[arg(long)]
    pub edge: Option<f64>,
    /// Scan every k-simplex in the box instead of tracing from seeds.
    #[arg(long)]
    pub exhaustive: bool,
    /// The box: LO,HI (the cube [LO,HI]^d) or lo1,hi1,...,lod,hid.
    #[arg(long = "box", allow_hyphen_values = true)]
    pub bbox: Option<NumList>,
    /// Random box points projected onto M to find components (default: 512 when there is no
    /// seed, else 0).
    #[arg(long)]
    pub search: Option<usize>,
    /// Oracle backend [default: cpu].
    #[arg(long, value_enum)]
    pub backend: Option<Backend>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Memory limit, bytes or with a K/M/G suffix (default: 3/4 of RAM).
    #[arg(long, value_parser = parse_bytes)]
    pub max_memory: Option<u64>,
    /// Write the sample (points on M-hat): .csv, .xyz or .txt.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write a JSON report.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// No progress bar and no summary.
    #[arg(long, short)]
    pub quiet: bool,
}

/// A comma-separated list of numbers, as a flag value.
#[derive(Clone, Debug, PartialEq)]
pub struct NumList(pub Vec<f64>);

impl std::str::FromStr for NumList {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        s.split(',')
            .map(|t| {
                t.trim()
                    .parse::<f64>()
                    .map_err(|_| format!("'{t}' is not a number"))
            })
            .collect::<std::result::Result<_, _>>()
            .map(NumList)
    }
}

/// Parses a byte count with an optional K, M, G or T suffix (powers of 1024).
pub fn parse_bytes(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim();
    let (num, mult) = match t.chars().last().map(|c| c.to_ascii_uppercase()) {
        Some('K') => (&t[..t.len() - 1], 1u64 << 10),
        Some('M') => (&t[..t.len() - 1], 1 << 20),
        Some('G') => (&t[..t.len() - 1], 1 << 30),
        Some('T') => (&t[..t.len() - 1], 1 << 40),
        _ => (t, 1),
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("'{s}' is not a size (e.g. 2G, 512M, 1000000)"))?;
    if !(v.is_finite() && v > 0.0) {
        return Err(format!("'{s}' must be positive"));
    }
    Ok((v * mult as f64) as u64)
}

/// The box from `--box` for dimension d.
fn box_from_flag(v: &[f64], d: usize) -> Result<Vec<[f64; 2]>> {
    match v.len() {
        2 => Ok(vec![[v[0], v[1]]; d]),
        n if n == 2 * d => Ok(v.chunks_exact(2).map(|c| [c[0], c[1]]).collect()),
        n => Err(Error::DimensionMismatch(format!(
            "--box has {n} numbers: give LO,HI or {} numbers lo1,hi1,...,lo{d},hi{d}",
            2 * d
        ))),
    }
}

/// The Ctrl-C flag, installed once.
fn interrupt_flag() -> Arc<AtomicBool> {
    static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
    FLAG.get_or_init(|| {
        let flag = Arc::new(AtomicBool::new(false));
        let f = flag.clone();
        // If the handler cannot be installed, Ctrl-C keeps its default meaning.
        let _ = ctrlc::set_handler(move || f.store(true, Ordering::Relaxed));
        flag
    })
    .clone()
}

/// Runs `isomesh trace` with `args`.
pub fn run(args: &TraceArgs) -> Result<()> {
    let mut problem = load(args.spec.clone(), args.preset.clone(), &args.params)?;
    apply_flags(&mut problem, args)?;
    let threads = args.threads.unwrap_or_else(rayon::current_num_threads);
    if threads == 0 {
        return Err(Error::Spec("--threads must be at least 1".into()));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| Error::Io(format!("cannot start {threads} threads: {e}")))?;
    pool.install(|| run_in_pool(&problem, args, threads))
}

fn apply_flags(p: &mut Problem, args: &TraceArgs) -> Result<()> {
    let d = p.dim();
    if let Some(kind) = args.triangulation {
        if kind == TriangulationKind::Custom {
            return Err(Error::Spec(
                "--triangulation custom needs a matrix: set it in a spec file".into(),
            ));
        }
        p.triangulation.kind = Some(kind.name().to_string());
    }
    if let Some(s) = args.offset_seed {
        p.triangulation.offset_seed = Some(s);
        p.triangulation.offset = None;
    }
    if let Some(s) = args.rotation_seed {
        p.triangulation.rotation_seed = Some(s);
        p.triangulation.rotate = Some(true);
    }
    if args.no_rotation {
        p.triangulation.rotation_seed = None;
        p.triangulation.rotate = Some(false);
    }
    if let Some(e) = args.edge {
        p.triangulation.edge = Some(e);
    }
    if let Some(b) = &args.bbox {
        p.bbox = Some(box_from_flag(&b.0, d)?);
    }
    if !args.seeds.is_empty() {
        for NumList(s) in &args.seeds {
            if s.len() != d {
                return Err(Error::DimensionMismatch(format!(
                    "--seed has {} coordinates, the ambient dimension is {d}",
                    s.len()
                )));
            }
        }
        p.seeds = args.seeds.iter().map(|s| s.0.clone()).collect();
    }
    Ok(())
}

fn run_in_pool(p: &Problem, args: &TraceArgs, threads: usize) -> Result<()> {
    let sys = &p.system;
    let (d, k) = (sys.ambient_dim(), sys.codim());
    let tri = p.triangulation.build(d)?;
    let backend = match args.backend.unwrap_or(Backend::Cpu) {
        Backend::Cpu => "cpu".to_string(),
        Backend::Auto => {
            if !args.quiet {
                eprintln!("note: this build has no GPU oracle yet; using the CPU");
            }
            "cpu".to_string()
        }
        Backend::Gpu => {
            return Err(Error::Trace(
                "this build has no GPU oracle yet: use --backend cpu".into(),
            ))
        }
    };
    let oracle = CpuOracle::new(sys);
    let cancel = interrupt_flag();
    cancel.store(false, Ordering::Relaxed);
    let bar = progress_bar(args.quiet);
    let started = Instant::now();
    let report_progress = |pr: &Progress| {
        if started.elapsed() > Duration::from_secs(1) {
            if bar.is_hidden() && !args.quiet {
                bar.set_draw_target(ProgressDrawTarget::stderr());
            }
            bar.set_message(format!(
                "{} simplices, level {}, {} vertices",
                pr.simplices, pr.level, pr.vertices
            ));
            bar.tick();
        }
    };
    let opts = TraceOptions {
        bbox: p.bbox.clone(),
        seeds: p.seeds.clone(),
        search_samples: args.search,
        max_memory: args.max_memory.unwrap_or_else(memory::default_limit),
        cancel: Some(cancel.clone()),
        progress: Some(&report_progress),
        ..TraceOptions::default()
    };
    memory::reset_peak();
    let base = memory::live_bytes();
    let sample = if args.exhaustive {
        exhaustive(sys, &tri, &oracle, &opts)?
    } else {
        trace(sys, &tri, &oracle, &opts)?
    };
    let peak = memory::peak_bytes().saturating_sub(base);
    bar.finish_and_clear();

    let mut written = Vec::new();
    if let Some(path) = &args.out {
        write_sample(path, &sample, SampleFormat::from_path(path)?)?;
        written.push(path.clone());
    }
    let st = &sample.stats;
    let n = sample.len();
    let per_s = if st.elapsed_s > 0.0 {
        n as f64 / st.elapsed_s
    } else {
        0.0
    };
    if let Some(path) = &args.report {
        let report = json!({
            "name": p.name,
            "mode": if args.exhaustive { "exhaustive" } else { "trace" },
            "ambient_dim": d,
            "codim": k,
            "manifold_dim": d - k,
            "triangulation": tri.kind().name(),
            "edge": tri.edge(),
            "offset": tri.offset(),
            "box": p.bbox,
            "simplex_count": n,
            "components": st.components,
            "backend": backend,
            "threads": threads,
            "elapsed_s": st.elapsed_s,
            "simplices_per_s": per_s,
            "peak_memory_bytes": peak,
            "bytes_per_simplex": if n > 0 { peak as f64 / n as f64 } else { 0.0 },
            "levels": st.levels,
            "oracle_calls": st.oracle_calls,
            "exact_decisions": st.exact_decisions,
            "degenerate": st.degenerate,
            "non_finite": st.non_finite,
            "vertices_evaluated": st.vertices,
            "seed_points": st.seed_points,
            "complete": st.stopped.is_none(),
            "stopped": st.stopped.as_ref().map(|s| s.to_string()),
        });
        write_atomic(path, |w| {
            serde_json::to_writer_pretty(&mut *w, &report).map_err(std::io::Error::other)?;
            writeln!(w)
        })?;
        written.push(path.clone());
    }
    if !args.quiet {
        let m = d - k;
        println!(
            "{}: {n} crossed {k}-simplices ({m}-manifold in R^{d}, {}, edge {}), {} component{}, \
             in {:.3} s ({:.0} simplices/s, {threads} thread{}), peak {:.1} MiB ({:.0} B/simplex)",
            p.name,
            tri.kind().name(),
            tri.edge(),
            st.components,
            if st.components == 1 { "" } else { "s" },
            st.elapsed_s,
            per_s,
            if threads == 1 { "" } else { "s" },
            peak as f64 / (1 << 20) as f64,
            if n > 0 { peak as f64 / n as f64 } else { 0.0 },
        );
        for f in &written {
            println!("wrote {}", f.display());
        }
    }
    if let Some(stop) = &st.stopped {
        return Err(Error::Trace(format!(
            "{stop}; the {n} simplices found so far were kept{}",
            if written.is_empty() {
                ""
            } else {
                " and written"
            }
        )));
    }
    Ok(())
}

fn progress_bar(quiet: bool) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    if !quiet {
        bar.set_style(
            ProgressStyle::with_template("{spinner} {elapsed} {msg}").expect("a valid template"),
        );
    }
    bar
}
