//! `isomesh trace`: load a problem, apply the flags, trace (or scan), write the sample and
//! the JSON report, print a summary.

use std::io::Write;
use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use isomesh::complex::Complex;
use isomesh::export::picture::{Picture, SIDES};
use isomesh::export::{
    write_atomic, write_mesh_as, write_sample, write_sample_to, Encoding, Mesh,
    OutputFormat as Output,
};
use isomesh::expr::{ImplicitFunction, Problem};
use isomesh::gpu::{Gpu, GpuOracle, Precision};
use isomesh::memory;
use isomesh::report::{BackendInfo, ComplexReport, Report, RunInfo};
use isomesh::trace::{exhaustive, trace, CpuOracle, Oracle, Progress, TraceOptions};
use isomesh::triangulation::{TriangulationKind, EDGE_RANGE};
use isomesh::{Error, Result};

use super::checks::singular_seeds;
use super::outputs::{plan_outputs, report_to_stdout, Plan};
use super::text::{caption, num, say, shown, summary};
use super::{load, signals};

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

/// `--precision`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PrecisionArg {
    /// 32-bit shaders.
    F32,
    /// 64-bit shaders.
    F64,
    /// f64 where the adapter has it, else f32.
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
    #[arg(long, allow_hyphen_values = true, value_parser = parse_count::<u64>)]
    pub offset_seed: Option<u64>,
    /// Seed of the random rotation of the triangulation (default 1).
    #[arg(long, conflicts_with = "no_rotation", allow_hyphen_values = true, value_parser = parse_count::<u64>)]
    pub rotation_seed: Option<u64>,
    /// Keep the triangulation's lattice axis-aligned (no rotation).
    #[arg(long)]
    pub no_rotation: bool,
    /// Seed point x1,..,xd near M (repeatable; replaces the spec's seeds).
    #[arg(long = "seed", allow_hyphen_values = true)]
    pub seeds: Vec<NumList>,
    /// Longest edge of a d-simplex of the triangulation.
    #[arg(long, allow_hyphen_values = true, value_parser = parse_edge)]
    pub edge: Option<f64>,
    /// Scan every k-simplex in the box instead of tracing from seeds.
    #[arg(long)]
    pub exhaustive: bool,
    /// The box: LO,HI (the cube [LO,HI]^d) or lo1,hi1,...,lod,hid.
    #[arg(long = "box", allow_hyphen_values = true)]
    pub bbox: Option<NumList>,
    /// Random box points projected onto M to find components (default: 512 when there is no
    /// seed, else 0).
    #[arg(long, allow_hyphen_values = true, value_parser = parse_count::<usize>)]
    pub search: Option<usize>,
    /// Oracle backend [default: cpu]: gpu uses any adapter (software ones too); auto a
    /// hardware GPU when there is one, else the CPU.
    #[arg(long, value_enum)]
    pub backend: Option<Backend>,
    /// GPU shader precision: f64 (needs SHADER_F64), f32 (a filter; crossings are computed
    /// on the CPU), or auto (f64 where the adapter has it) [default: auto].
    #[arg(long, value_enum)]
    pub precision: Option<PrecisionArg>,
    /// GPU backend: frontier simplices per slice of a trace level; wider levels are decided
    /// slice by slice, the next slice named on the CPU meanwhile (for example 16384; default
    /// 0: whole levels). The result does not depend on it.
    #[arg(long, allow_hyphen_values = true, value_parser = parse_count::<usize>)]
    pub level_slice: Option<usize>,
    /// GPU backend, --exhaustive: evaluate f on the device with certified bounds and on the
    /// CPU only at the vertices of simplices the device found crossed or could not decide.
    /// The result does not depend on it.
    #[arg(long)]
    pub device_values: bool,
    /// Worker threads (default: all cores).
    #[arg(long, allow_hyphen_values = true, value_parser = parse_count::<usize>)]
    pub threads: Option<usize>,
    /// Memory limit, bytes or with a K/M/G suffix (default: 3/4 of RAM).
    #[arg(long, allow_hyphen_values = true, value_parser = parse_bytes)]
    pub max_memory: Option<u64>,
    /// Write the result (repeatable): the sample as .csv, .xyz or .txt; the mesh as .ply,
    /// .obj, .off, .stl (surfaces), .mesh (Medit), .vtu (ParaView) or .npz (NumPy). `-` is
    /// standard output, for the sample (CSV unless --format says xyz).
    #[arg(long)]
    pub out: Vec<PathBuf>,
    /// Output format for --out, overriding the file extension: csv, xyz, ply, obj, off, stl,
    /// mesh, vtu or npz.
    #[arg(long)]
    pub format: Option<String>,
    /// Draw the mesh into a PNG picture.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Size of the picture, WIDTHxHEIGHT (64 to 8192 pixels a side) [default: 1200x900].
    #[arg(long, value_parser = parse_size)]
    pub png_size: Option<(usize, usize)>,
    /// How R^d is seen in 3-D for files and pictures: auto (the coordinates up to d = 3,
    /// else pca), pca, or coordinates such as 1,2,4.
    #[arg(long, default_value = "auto")]
    pub project: String,
    /// Only the sample: no cell complex, no topology report, no mesh outputs.
    #[arg(long)]
    pub no_complex: bool,
    /// PLY and VTU files as text rather than binary (Medit `.mesh`, OBJ and OFF are text
    /// always, STL and NPZ binary always).
    #[arg(long)]
    pub ascii: bool,
    /// Write a JSON report.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// No progress bar and no summary.
    #[arg(long, short)]
    pub quiet: bool,
    /// Name each phase on standard error as it starts (grid, search, levels, complex,
    /// writing): a log for batch jobs.
    #[arg(long, short, conflicts_with = "quiet")]
    pub verbose: bool,
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
                    .map_err(|_| format!("'{}' is not a number", shown(t)))
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
        .map_err(|_| format!("'{}' is not a size (e.g. 2G, 512M, 1000000)", shown(s)))?;
    if !(v.is_finite() && v > 0.0) {
        return Err(format!("'{}' must be positive", shown(s)));
    }
    let bytes = v * mult as f64;
    if bytes < 1.0 {
        return Err(format!(
            "'{}' is less than one byte (sizes are bytes, or K, M, G, T)",
            shown(s)
        ));
    }
    Ok(bytes as u64)
}

/// Parses WIDTHxHEIGHT.
fn parse_size(s: &str) -> std::result::Result<(usize, usize), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT (e.g. 1200x900)"))?;
    let p = |t: &str| match t.trim().parse::<usize>() {
        Ok(n) if SIDES.contains(&n) => Ok(n),
        Ok(_) => Err(format!(
            "'{}': each side must be {} to {} pixels",
            shown(s),
            SIDES.start(),
            SIDES.end()
        )),
        Err(_) => Err(format!(
            "'{}' is not WIDTHxHEIGHT (e.g. 1200x900)",
            shown(s)
        )),
    };
    Ok((p(w)?, p(h)?))
}

/// The size of a picture when --png-size is not given.
pub const DEFAULT_PNG_SIZE: (usize, usize) = (1200, 900);

/// Parses an edge length within [`EDGE_RANGE`].
fn parse_edge(s: &str) -> std::result::Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if EDGE_RANGE.contains(&v) => Ok(v),
        Ok(v) if v.is_finite() && v > 0.0 => Err(format!(
            "{} is out of range: the edge must be from {:e} to {:e}",
            num(v),
            EDGE_RANGE.start(),
            EDGE_RANGE.end()
        )),
        Ok(v) => Err(format!(
            "{} is not a length: the edge must be positive and finite",
            num(v)
        )),
        Err(_) => Err(format!("'{}' is not a number", shown(s))),
    }
}

/// Parses a non-negative whole number, naming a negative one as such.
fn parse_count<T: std::str::FromStr>(s: &str) -> std::result::Result<T, String> {
    let t = s.trim();
    t.parse::<T>().map_err(|_| {
        if t.starts_with('-') && t[1..].parse::<f64>().is_ok() {
            format!("{} is negative: give a whole number from 0 up", shown(t))
        } else {
            format!("'{}' is not a whole number", shown(t))
        }
    })
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

/// Runs `isomesh trace` with `args`.
pub fn run(args: &TraceArgs) -> Result<()> {
    // Parsing, differentiating and compiling the equations stop at the memory limit too.
    let limit = args.max_memory.unwrap_or_else(memory::default_limit);
    let mut problem = memory::within(limit, || {
        load(args.spec.clone(), args.preset.clone(), &args.params)
    })?;
    apply_flags(&mut problem, args)?;
    let plan = plan_outputs(args, &problem)?;
    let mut threads = args.threads.unwrap_or_else(rayon::current_num_threads);
    if threads == 0 {
        return Err(Error::Usage("--threads must be at least 1".into()));
    }
    let cap = isomesh::mesher::max_threads();
    if threads > cap {
        eprintln!(
            "warning: --threads {threads}: {}",
            isomesh::mesher::too_many_threads(cap)
        );
        threads = cap;
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| {
            Error::io(
                format!("cannot start {threads} threads"),
                std::io::Error::other(e),
            )
        })?;
    pool.install(|| run_in_pool(&problem, args, &plan, threads))
}

fn apply_flags(p: &mut Problem, args: &TraceArgs) -> Result<()> {
    let d = p.dim();
    if let Some(kind) = args.triangulation {
        if kind == TriangulationKind::Custom {
            return Err(Error::Usage(
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
        if p.triangulation.matrix.is_some() {
            return Err(Error::Usage(
                "--edge: this spec's triangulation is custom and takes its scale from its \
                 matrix; scale the matrix instead, or leave --edge out"
                    .into(),
            ));
        }
        p.triangulation.edge = Some(e);
    }
    if let Some(b) = &args.bbox {
        let b = box_from_flag(&b.0, d)?;
        isomesh::expr::spec::check_box(&b, d).map_err(|e| match e {
            Error::Spec(m) => Error::Usage(format!("--box: {m}")),
            e => e,
        })?;
        p.bbox = Some(b);
    }
    if !args.seeds.is_empty() {
        for NumList(s) in &args.seeds {
            if s.len() != d {
                return Err(Error::DimensionMismatch(format!(
                    "--seed has {} coordinates, the ambient dimension is {d}",
                    s.len()
                )));
            }
            isomesh::error::check_finite_in(s, "--seed")?;
        }
        p.seeds = args.seeds.iter().map(|s| s.0.clone()).collect();
    }
    Ok(())
}

fn run_in_pool(p: &Problem, args: &TraceArgs, plan: &Plan, threads: usize) -> Result<()> {
    let sys = &p.system;
    let (d, k) = (sys.ambient_dim(), sys.codim());
    let tri = p.triangulation.build(d)?;
    let precision = match args.precision.unwrap_or(PrecisionArg::Auto) {
        PrecisionArg::F32 => Some(Precision::F32),
        PrecisionArg::F64 => Some(Precision::F64),
        PrecisionArg::Auto => None,
    };
    let gpu = match args.backend.unwrap_or(Backend::Cpu) {
        Backend::Cpu => None,
        Backend::Gpu => Some(Gpu::open(true)?),
        Backend::Auto => match Gpu::open(false) {
            Ok(g) => Some(g),
            Err(e) => {
                if !args.quiet {
                    eprintln!("note: {e}; using the CPU");
                    if args.precision.is_some() || args.level_slice.is_some() || args.device_values
                    {
                        eprintln!(
                            "note: --precision, --level-slice and --device-values do not apply \
                             on the CPU"
                        );
                    }
                }
                None
            }
        },
    };
    let cpu_oracle = CpuOracle::new(sys);
    let gpu_oracle = match gpu {
        Some(g) => Some(GpuOracle::new(g, sys, precision)?),
        None => None,
    };
    if let (Some(o), Some(slice)) = (&gpu_oracle, args.level_slice) {
        o.set_level_slice(slice);
    }
    if let Some(o) = &gpu_oracle {
        o.set_device_values(args.device_values);
    }
    let oracle: &dyn Oracle = match &gpu_oracle {
        Some(o) => o,
        None => &cpu_oracle,
    };
    let cancel = signals::stop_flag();
    let stopping = || cancel.load(Ordering::SeqCst);
    let bar = progress_bar(args.quiet);
    let started = Instant::now();
    let phase = |what: &str| {
        if args.verbose {
            eprintln!("isomesh: {what}");
        }
    };
    let report_progress = |pr: &Progress| {
        if args.verbose {
            eprintln!(
                "isomesh: level {}, {} simplices, {} vertices",
                pr.level, pr.simplices, pr.vertices
            );
        }
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
        warm: true,
        ..TraceOptions::default()
    };
    let limit = opts.max_memory;
    isomesh::trace::checks::check_not_zero(&p.system, p.bbox.as_deref(), &p.seeds, tri.edge())?;
    let singular_seeds = singular_seeds(p, tri.edge(), args.quiet);
    let base = memory::live_bytes();
    let sample = if args.exhaustive {
        phase("scan: evaluating f on the box's lattice, then deciding its simplices");
        exhaustive(sys, &tri, oracle, &opts)?
    } else {
        let search = args.search.unwrap_or(if p.seeds.is_empty() {
            isomesh::trace::DEFAULT_SEARCH_SAMPLES
        } else {
            0
        });
        phase(&format!(
            "trace: from {} seed{}{}",
            p.seeds.len(),
            if p.seeds.len() == 1 { "" } else { "s" },
            if search > 0 {
                format!(", then from {search} box points projected onto M")
            } else {
                String::new()
            }
        ));
        trace(sys, &tri, oracle, &opts)?
    };
    let trace_peak = memory::peak_bytes().saturating_sub(base);
    bar.finish_and_clear();
    let checks = sample.check_crossings(sys);
    let suspect = checks.suspect;
    let singular_crossings = if args.exhaustive {
        // A scan finds every branch.
        Vec::new()
    } else {
        checks.singular
    };
    if let Some(x) = singular_crossings.first().filter(|_| !args.quiet) {
        eprintln!(
            "warning: the trace passed near a point where the Jacobian of f is \
             rank-deficient, about {x:?} (branches of M may cross there, or a cusp): it \
             follows only the branches it reaches from its seeds; --exhaustive finds all of \
             them in the box"
        );
    }
    if suspect > 0 {
        eprintln!(
            "warning: at {suspect} of {} crossings |f| is more than half the spread of its \
             values at the simplex's vertices: f may have a pole or a jump there (the mesh \
             then shows a sign change, not a zero), or the edge is too coarse for f",
            sample.len()
        );
    }

    let projection = &plan.projection;
    let wants_mesh =
        args.png.is_some() || plan.outs.iter().any(|o| matches!(o.kind, Output::Mesh(_)));
    let mut written = Vec::new();
    // Each output is written, or fails, on its own: one that cannot be written (a full disk,
    // a bad path) is reported and the others, and the report, are still written.
    let mut failed: Vec<Error> = Vec::new();
    let mut stdout_failed = false;
    let mut attempt = |result: Result<()>| match result {
        Ok(()) => true,
        Err(e) => {
            failed.push(e);
            false
        }
    };
    // The sample first: whatever happens next, it is on disk.
    for o in &plan.outs {
        if let Output::Sample(format) = o.kind {
            if o.stdout {
                let mut out = std::io::stdout().lock();
                let result = write_sample_to(&mut out, &sample, format)
                    .and_then(|()| out.flush())
                    .map_err(|e| Error::io("standard output", e));
                stdout_failed = !attempt(result);
            } else {
                phase(&format!("writing {}", shown(&o.path.display().to_string())));
                let result = write_sample(&o.path, &sample, format);
                if attempt(result) {
                    written.push(o.path.clone());
                }
            }
        }
    }
    // A failure past this point still leaves the sample and the report on disk. f vanishing
    // on a region is one: the sample is kept, no mesh of it is made.
    let mut failure: Option<Error> = sample
        .stats
        .zero_region
        .as_ref()
        .map(|(i, x)| isomesh::trace::checks::region_error(*i, x));
    let complex = if args.no_complex || sample.is_empty() || stopping() || failure.is_some() {
        None
    } else {
        phase("complex: building the cell complex");
        match Complex::build_cancellable(&sample, sys, p.bbox.as_deref(), limit, &cancel) {
            Ok(c) => {
                phase("complex: topology");
                let t0 = Instant::now();
                // Stopped by a signal: the report says so, with no complex.
                c.topology_cancellable(&cancel)
                    .map(|topo| (c, topo, t0.elapsed().as_secs_f64()))
            }
            // Stopped by a signal: the report says so.
            Err(_) if stopping() => None,
            Err(e) => {
                failure = Some(e);
                None
            }
        }
    };
    if let (Some((c, topo, _)), true) = (&complex, wants_mesh) {
        let encoding = if args.ascii {
            Encoding::Ascii
        } else {
            Encoding::Binary
        };
        // Vertices in R^3 and the polygons as triangles, generously.
        let cells: usize = topo.cells.iter().sum();
        match check_memory("the mesh", 48 * topo.cells[0] + 64 * cells, limit) {
            Err(e) => failure = Some(e),
            Ok(()) => {
                let mesh = Mesh::new(c, Some(sys), projection, &p.name);
                // A signal lets the file being written finish, and skips the rest.
                for o in &plan.outs {
                    if let (Output::Mesh(format), false) = (&o.kind, stopping()) {
                        phase(&format!("writing {}", shown(&o.path.display().to_string())));
                        let result = write_mesh_as(&o.path, &mesh, *format, encoding);
                        if attempt(result) {
                            written.push(o.path.clone());
                        }
                    }
                }
                if let (Some(path), false) = (&args.png, stopping()) {
                    phase(&format!("writing {}", shown(&path.display().to_string())));
                    let (w, h) = args.png_size.unwrap_or(DEFAULT_PNG_SIZE);
                    let result =
                        check_memory("the picture", w.saturating_mul(h).saturating_mul(16), limit)
                            .and_then(|()| Picture::render(&mesh, w, h, &caption(&p.name, d, topo)))
                            .and_then(|pic| pic.write_png(path));
                    if attempt(result) {
                        written.push(path.clone());
                    }
                }
            }
        }
    }
    // The first error decides the exit status and the report's error; every failed output is
    // named on standard error.
    for e in failed.iter().skip(usize::from(failure.is_none())) {
        eprintln!("error: {e}");
    }
    if failure.is_none() && !failed.is_empty() {
        failure = Some(failed.remove(0));
    }
    let st = &sample.stats;
    let n = sample.len();
    let peak = memory::peak_bytes();
    let empty = (n == 0 && st.stopped.is_none())
        .then(|| st.why_nothing_found(args.exhaustive, !p.seeds.is_empty()));
    let mut not_written: Vec<String> = args
        .out
        .iter()
        .chain(&args.png)
        .filter(|f| f.as_os_str() != "-" && !written.contains(f))
        .map(|f| f.display().to_string())
        .collect();
    if stdout_failed {
        not_written.push("standard output".into());
    }
    let per_s = if st.elapsed_s > 0.0 {
        n as f64 / st.elapsed_s
    } else {
        0.0
    };
    let signal = signals::received();
    if let Some(path) = &args.report {
        let backend = match &gpu_oracle {
            Some(o) => BackendInfo::of_gpu(o),
            None => BackendInfo::cpu(),
        };
        let run = RunInfo {
            name: p.name.clone(),
            exhaustive: args.exhaustive,
            bbox: p.bbox.clone(),
            backend,
            threads,
            peak_memory_bytes: peak as u64,
            max_memory_bytes: limit,
            suspect_crossings: suspect,
            singular_seeds,
            singular_crossings,
        };
        let mut report = Report::new(&sample, run);
        report.error = failure
            .as_ref()
            .map(|e| e.to_string())
            .or_else(|| empty.clone());
        report.complete &= failure.is_none() && empty.is_none();
        report.not_written = not_written.clone();
        if let Some(sig) = signal {
            report.complete = false;
            report.stopped.get_or_insert_with(|| "interrupted".into());
            report.signal = Some(signals::name(sig));
        }
        if let Some((c, t, topo_s)) = &complex {
            report = report.with_complex(
                ComplexReport::new(c, t, *topo_s, &args.project),
                t.components,
            );
        }
        if report_to_stdout(args) {
            let mut out = std::io::stdout().lock();
            writeln!(out, "{}", report.to_json())
                .and_then(|()| out.flush())
                .map_err(|e| Error::io("standard output", e))?;
        } else {
            phase(&format!("writing {}", shown(&path.display().to_string())));
            write_atomic(path, |w| writeln!(w, "{}", report.to_json()))?;
            written.push(path.clone());
        }
    }
    if !args.quiet {
        // With the sample or the report on standard output, the summary goes to standard
        // error.
        let to_stderr = plan.outs.iter().any(|o| o.stdout) || report_to_stdout(args);
        let line = |text: String| {
            if to_stderr {
                eprintln!("{text}");
            } else {
                say!("{text}");
            }
        };
        let m = d - k;
        line(format!(
            "{}: {n} crossed {k}-simplices ({m}-manifold in R^{d}, {}, edge {}), {} component{}, \
             in {:.3} s ({:.0} simplices/s, {threads} thread{}), peak {} ({:.0} B/simplex)",
            shown(&p.name),
            tri.kind().name(),
            num(tri.edge()),
            st.components,
            if st.components == 1 { "" } else { "s" },
            st.elapsed_s,
            per_s,
            if threads == 1 { "" } else { "s" },
            memory::human_bytes(trace_peak as u64),
            if n > 0 {
                trace_peak as f64 / n as f64
            } else {
                0.0
            },
        ));
        if let Some((c, t, topo_s)) = &complex {
            line(summary(t, c.stats.elapsed_s + topo_s));
        }
        for f in &written {
            line(format!("wrote {}", shown(&f.display().to_string())));
        }
    }
    let unwritten = if not_written.is_empty() {
        String::new()
    } else {
        format!("; not written: {}", not_written.join(", "))
    };
    let kept = |n: usize| {
        format!(
            "the {n} simplices found were kept{}{unwritten}",
            if written.is_empty() {
                ""
            } else {
                " and written"
            }
        )
    };
    if let Some(sig) = signal {
        return Err(Error::Trace(format!(
            "stopped by {}; {}, the report says complete: false",
            signals::name(sig),
            kept(n)
        )));
    }
    if let Some(why) = empty {
        return Err(Error::Trace(format!("{why}{unwritten}")));
    }
    if let (Some(e), None) = (failure, &st.stopped) {
        if !not_written.is_empty() {
            eprintln!("not written: {}", not_written.join(", "));
        }
        return Err(e);
    }
    if let Some(stop) = &st.stopped {
        return Err(Error::Trace(format!("{stop}; {}", kept(n))));
    }
    Ok(())
}

/// Fails when `extra` more heap bytes would pass `limit`.
fn check_memory(what: &str, extra: usize, limit: u64) -> Result<()> {
    let live = memory::in_use(0);
    let need = live.saturating_add(extra as u64);
    if need > limit {
        return Err(Error::Trace(format!(
            "{what} needs about {:.1} MiB on top of {:.1} MiB in use, over the memory limit of \
             {:.1} MiB (raise --max-memory, or use a larger edge)",
            extra as f64 / (1u64 << 20) as f64,
            live as f64 / (1u64 << 20) as f64,
            limit as f64 / (1u64 << 20) as f64
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
