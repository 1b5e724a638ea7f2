//! `isomesh bench`: the CPU oracle against the GPU oracle on the same batches (simplices per
//! second, where the GPU's time goes, whether the verdicts agree), then whole traces of the
//! reference cases on both backends (speed-up over the C++ library, whether S agrees); as
//! Markdown tables, and optionally a JSON file and a PNG plot.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use isomesh::bench::surfaces::{check_grid, crossover, measure_sizes, CHUNK, SURFACES};
use isomesh::bench::{scan_case, timed, trace_case, OracleBatch, ReferenceCase, SCAN_CASES};
use isomesh::export::plot::{write_charts, Chart, Series, PALETTE};
use isomesh::export::write_atomic;

use super::text::{say, shown};
use isomesh::export::safe::{check_target, FileId};
use isomesh::expr::ImplicitFunction;
use isomesh::gpu::calibration::{self, Calibration, Entry, Pick};
use isomesh::gpu::{Gpu, GpuOptions, GpuOracle, Precision};
use isomesh::mesher::Job;
use isomesh::trace::{CpuOracle, Oracle, TraceStats};
use isomesh::{Error, Result};
use serde_json::{json, Value};

use super::args::backend_parser;
use isomesh::Backend;

/// Which whole traces to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum TraceSet {
    /// No traces.
    None,
    /// The reference cases of at most 200,000 simplices.
    Quick,
    /// Every reference case (minutes on a small machine).
    All,
    /// Surfaces in R^3 (trace + complex + triangles) against the grid mesher
    /// fast-surface-nets (sampling + meshing) at matched vertex counts, on the CPU.
    Surfaces,
    /// Exhaustive scans of boxes on the CPU, on the GPU, and on the GPU with f's values
    /// from the device, with the split of vertex evaluations and decisions.
    Scans,
}

/// Flags of `isomesh bench`.
#[derive(Args, Clone, Debug)]
pub struct BenchArgs {
    /// Codimensions for the oracle alone: a list (1,2,3), a range (1-8), or 0 for none (which
    /// also skips the vertex-evaluation table).
    #[arg(long, default_value = "1-8", value_parser = parse_ks)]
    pub k: Ks,
    /// Simplices per oracle batch.
    #[arg(long, default_value_t = 200_000)]
    pub count: usize,
    /// Runs per measurement; the median is reported.
    #[arg(long, default_value_t = 3)]
    pub repeats: usize,
    /// Whole traces, a list: none, quick (reference cases up to 200,000 simplices), all
    /// (every reference case), surfaces (against a grid mesher, sizes from --grid), scans
    /// (exhaustive scans of boxes, with device values on a GPU).
    #[arg(long, value_enum, value_delimiter = ',', default_value = "quick")]
    pub traces: Vec<TraceSet>,
    /// Grid sizes (interior samples per axis, multiples of 64) for --traces surfaces.
    #[arg(long, value_delimiter = ',', default_value = "64,128,256,512,1024")]
    pub grid: Vec<u32>,
    /// cpu: the CPU only; gpu: a GPU is required; auto: the best adapter if any (software
    /// ones too, marked as such).
    #[arg(long, value_parser = backend_parser(), default_value = "auto")]
    pub backend: Backend,
    /// Worker threads for the CPU (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Write every figure as JSON.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Plot simplices per second against k, and the traces' speed-ups, into a PNG.
    #[arg(long)]
    pub png: Option<PathBuf>,
}

/// Refuses an oracle batch of `count` k-simplices that would not fit: vertex indices are
/// 32-bit, and the batch (its values, indices, both oracles' verdicts and lambda, the rows
/// packed for the device) must fit in memory.
fn check_count(count: usize, k: usize) -> Result<()> {
    if k == 0 {
        return Ok(());
    }
    let n = k + 1;
    if count.checked_mul(n).is_none_or(|v| v > u32::MAX as usize) {
        return Err(Error::Usage(format!(
            "--count {count}: a batch of {k}-simplices holds at most {} (32-bit vertex indices)",
            u32::MAX as usize / n
        )));
    }
    let per = (3 * n * k * 8 + 4 * n + 16 * n + 2) as u64;
    let bytes = (count as u64).saturating_mul(per);
    let limit = isomesh::memory::default_limit();
    if bytes > limit {
        return Err(Error::Usage(format!(
            "--count {count}: a batch of {k}-simplices needs about {} GB, over the memory \
             limit of {} GB",
            bytes / 1_000_000_000,
            limit / 1_000_000_000
        )));
    }
    Ok(())
}

/// A list of codimensions.
#[derive(Clone, Debug)]
pub struct Ks(pub Vec<usize>);

fn parse_ks(s: &str) -> std::result::Result<Ks, String> {
    let bad = || format!("'{s}': expected k values such as 1,2,3 or 1-8 (each 1 to 16), or 0");
    if s.trim() == "0" {
        return Ok(Ks(Vec::new()));
    }
    let mut ks = Vec::new();
    for part in s.split(',') {
        let num = |t: &str| t.trim().parse::<usize>().map_err(|_| bad());
        match part.split_once('-') {
            Some((a, b)) => ks.extend(num(a)?..=num(b)?),
            None => ks.push(num(part)?),
        }
    }
    if ks.is_empty() || ks.iter().any(|&k| !(1..=16).contains(&k)) {
        return Err(bad());
    }
    ks.sort_unstable();
    ks.dedup();
    Ok(Ks(ks))
}

/// Runs the benchmark in a pool of the requested size.
pub fn run(args: &BenchArgs) -> Result<()> {
    if args.count == 0 || args.repeats == 0 {
        return Err(Error::Usage(
            "--count and --repeats must be at least 1".into(),
        ));
    }
    check_count(args.count, args.k.0.iter().copied().max().unwrap_or(0))?;
    check_outputs(args)?;
    let threads = args.threads.unwrap_or_else(rayon::current_num_threads);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads.max(1))
        .build()
        .map_err(|e| {
            Error::io(
                format!("cannot start {threads} threads"),
                std::io::Error::other(e),
            )
        })?;
    pool.install(|| run_in_pool(args, threads.max(1)))
}

/// `--json` and `--png`, checked before anything is measured: each absent or a regular file,
/// and not the same file.
fn check_outputs(args: &BenchArgs) -> Result<()> {
    let named: Vec<(&str, &std::path::Path)> = [("--json", &args.json), ("--png", &args.png)]
        .into_iter()
        .filter_map(|(flag, p)| p.as_deref().map(|p| (flag, p)))
        .collect();
    for (flag, path) in &named {
        check_target(path).map_err(|e| e.for_flag(flag))?;
    }
    if let [(_, a), (_, b)] = named[..] {
        if FileId::of(a)?.same(&FileId::of(b)?) {
            return Err(Error::Usage(format!(
                "--json {} and --png {} are the same file: give each output its own path",
                shown(&a.display().to_string()),
                shown(&b.display().to_string())
            )));
        }
    }
    Ok(())
}

fn run_in_pool(args: &BenchArgs, threads: usize) -> Result<()> {
    let gpu = match args.backend {
        Backend::Cpu => None,
        Backend::Gpu => Some(Gpu::open(true)?),
        Backend::Auto => match Gpu::open(true) {
            Ok(g) => Some(g),
            Err(e) => {
                eprintln!("note: {e}; the CPU only");
                None
            }
        },
    };
    let device = match &gpu {
        Some(g) => format!(
            "{} ({}, {}{})",
            g.adapter.name,
            g.adapter.backend,
            g.adapter.device_type,
            if g.adapter.is_software() {
                ", software: expect it slower than the CPU"
            } else {
                ""
            }
        ),
        None => "none".into(),
    };
    say!("CPU: {threads} threads; GPU: {device}\n");
    let mut precisions = Vec::new();
    if let Some(g) = &gpu {
        precisions.push(Precision::F32);
        if g.adapter.shader_f64 {
            precisions.push(Precision::F64);
        }
    }

    let oracle_rows = oracle_table(args, gpu.as_ref(), &precisions)?;
    let eval_rows = eval_table(args, gpu.as_ref(), &precisions)?;
    let trace_rows = trace_table(args, gpu.as_ref())?;
    let scan_rows = scan_table(args, gpu.as_ref())?;
    let (surface_rows, crossovers) = surface_table(args)?;
    if let Some(g) = &gpu {
        calibrate(g, threads, &trace_rows, &scan_rows);
    }

    // Each file is written, or fails, on its own: a picture that cannot be drawn does not
    // cost the JSON.
    let mut failed = None;
    if let Some(path) = &args.png {
        match plot(path, &oracle_rows, &trace_rows, &surface_rows, &precisions) {
            Ok(()) => say!("\nwrote {}", path.display()),
            Err(e) => failed = Some(e),
        }
    }
    if let Some(path) = &args.json {
        let report = json!({
            "threads": threads,
            "gpu": device,
            "count": args.count,
            "repeats": args.repeats,
            "oracle": oracle_rows,
            "vertex_eval": eval_rows,
            "traces": trace_rows,
            "scans": scan_rows,
            "surfaces": surface_rows,
            "crossover_vertices": crossovers,
        });
        write_atomic(path, |w| {
            serde_json::to_writer_pretty(&mut *w, &report).map_err(std::io::Error::other)
        })?;
        say!("wrote {}", path.display());
    }
    failed.map_or(Ok(()), Err)
}

/// The oracle alone: one row per k and backend.
fn oracle_table(
    args: &BenchArgs,
    gpu: Option<&Gpu>,
    precisions: &[Precision],
) -> Result<Vec<Value>> {
    let mut rows = Vec::new();
    if args.k.0.is_empty() {
        return Ok(rows);
    }
    say!(
        "Oracle alone: {} random k-simplices per batch, simplices per second (median of {})",
        args.count,
        args.repeats
    );
    say!("GPU time per simplex: host (filters, packing, CPU recheck), then upload, compute and readback, each timed alone in a separate run.\n");
    say!("| k | oracle | simplices/s | vs CPU | rechecked | host ns | upload ns | compute ns | readback ns | same verdicts |");
    say!("|---|---|---|---|---|---|---|---|---|---|");
    for &k in &args.k.0 {
        let batch = OracleBatch::random(k, args.count, k as u64)?;
        let cpu = CpuOracle::new(&batch.function);
        let (cpu_rate, cpu_status, cpu_lambda) = batch.time(&cpu, args.repeats)?;
        say!("| {k} | cpu | {cpu_rate:.3e} | 1 | | | | | | |");
        rows.push(json!({"k": k, "oracle": "cpu", "simplices_per_s": cpu_rate}));
        let Some(g) = gpu else { continue };
        for &p in precisions {
            let o = GpuOracle::new(g.clone(), &batch.function, Some(p))?;
            let (rate, status, lambda) = batch.time(&o, args.repeats)?;
            let st = o.stats();
            let recheck = st.rechecked as f64 / st.solved.max(1) as f64;
            // The same decisions, and in f64 the same crossing points up to rounding.
            let n = k + 1;
            let same = status == cpu_status
                && (0..batch.len()).filter(|&i| status[i].crossed()).all(|i| {
                    lambda[i * n..(i + 1) * n]
                        .iter()
                        .zip(&cpu_lambda[i * n..(i + 1) * n])
                        .all(|(a, b)| (a - b).abs() <= 1e-12 * (1.0 + b.abs()))
                });
            o.reset_stats();
            o.set_phased(true);
            batch.time(&o, 1)?;
            let ph = o.stats();
            let ns = |s: f64| s * 1e9 / batch.len() as f64;
            let name = format!("gpu {}", p.ty());
            say!(
                "| {k} | {name} | {rate:.3e} | {:.2} | {:.1}% | {:.1} | {:.1} | {:.1} | {:.1} | {} |",
                rate / cpu_rate,
                100.0 * recheck,
                ns(ph.host_s),
                ns(ph.upload_s),
                ns(ph.compute_s),
                ns(ph.readback_s),
                if same { "yes" } else { "NO" }
            );
            rows.push(json!({
                "k": k, "oracle": name, "simplices_per_s": rate, "recheck_share": recheck,
                "host_ns": ns(ph.host_s), "upload_ns": ns(ph.upload_s),
                "compute_ns": ns(ph.compute_s), "readback_ns": ns(ph.readback_s),
                "same_verdicts": same,
            }));
            if !same {
                return Err(Error::Gpu(format!(
                    "the GPU oracle ({}) disagrees with the CPU at k = {k}",
                    p.ty()
                )));
            }
        }
    }
    Ok(rows)
}

/// Vertex evaluation alone: f at lattice vertices, on the CPU (all threads) and in the GPU's
/// vertex shader, for a polynomial and a transcendental preset.
fn eval_table(args: &BenchArgs, gpu: Option<&Gpu>, precisions: &[Precision]) -> Result<Vec<Value>> {
    let mut rows = Vec::new();
    if args.k.0.is_empty() {
        return Ok(rows);
    }
    say!(
        "\nVertex evaluation alone: {} lattice vertices, vertices per second (median of {})\n",
        args.count,
        args.repeats
    );
    say!("| preset | d | k | evaluator | vertices/s | vs CPU | largest difference from the CPU |");
    say!("|---|---|---|---|---|---|---|");
    for name in ["3-torus", "bagel-klein"] {
        let p = isomesh::expr::preset(name, &[])?;
        let (d, k) = (p.dim(), p.system.codim());
        let tri = p.triangulation.build(d)?;
        let lattice: Vec<i32> = (0..args.count * d)
            .map(|i| ((i / d) as i32 % 97) - 48 + (i % d) as i32)
            .collect();
        let mut cpu_values = vec![0.0; args.count * k];
        let cpu = CpuOracle::new(&p.system);
        let (cpu_s, ()) = timed(args.repeats, || {
            cpu.values().eval_vertices(&tri, &lattice, &mut cpu_values)
        })?;
        let cpu_rate = args.count as f64 / cpu_s;
        say!("| {name} | {d} | {k} | cpu | {cpu_rate:.3e} | 1 | |");
        rows.push(json!({"preset": name, "evaluator": "cpu", "vertices_per_s": cpu_rate}));
        let Some(g) = gpu else { continue };
        for &prec in precisions {
            let o = GpuOracle::new(g.clone(), &p.system, Some(prec))?;
            let (s, values) = timed(args.repeats, || o.eval_vertices_stage(&tri, &lattice))?;
            let worst = values
                .iter()
                .zip(&cpu_values)
                .map(|(a, b)| (a - b).abs() / (1.0 + b.abs()))
                .fold(0.0, f64::max);
            let rate = args.count as f64 / s;
            let name_p = format!("gpu {}", prec.ty());
            say!(
                "| {name} | {d} | {k} | {name_p} | {rate:.3e} | {:.2} | {worst:.1e} |",
                rate / cpu_rate
            );
            rows.push(
                json!({"preset": name, "evaluator": name_p, "vertices_per_s": rate,
                "largest_relative_difference": worst}),
            );
            // With bounds: the share of values whose bound is usable, and the CPU's value
            // must lie within every such bound.
            let (s, pairs) = timed(args.repeats, || o.eval_certified_stage(&tri, &lattice))?;
            let acc = prec.accuracy();
            let mut known = 0usize;
            for (pair, c) in pairs.chunks_exact(2).zip(&cpu_values) {
                if pair[1] < acc.big && pair[0].abs() < acc.big {
                    known += 1;
                    if (c - pair[0]).abs() > pair[1] {
                        return Err(Error::Gpu(format!(
                            "{name}: the CPU's {c} lies outside the certified ({}, {})",
                            pair[0], pair[1]
                        )));
                    }
                }
            }
            let share = known as f64 / cpu_values.len().max(1) as f64;
            let rate = args.count as f64 / s;
            let name_c = format!("gpu {} certified", prec.ty());
            say!(
                "| {name} | {d} | {k} | {name_c} | {rate:.3e} | {:.2} | within bounds ({:.1}% certified) |",
                rate / cpu_rate,
                100.0 * share
            );
            rows.push(
                json!({"preset": name, "evaluator": name_c, "vertices_per_s": rate,
                "certified_share": share}),
            );
        }
    }
    Ok(rows)
}

/// Whole traces of the reference cases on the CPU and, when there is one, the GPU.
fn trace_table(args: &BenchArgs, gpu: Option<&Gpu>) -> Result<Vec<Value>> {
    let mut rows = Vec::new();
    let limit = if args.traces.contains(&TraceSet::All) {
        u64::MAX
    } else if args.traces.contains(&TraceSet::Quick) {
        200_000
    } else {
        return Ok(rows);
    };
    say!(
        "\nTraces of the reference cases (C++: GUDHI, one thread), median of {}\n",
        args.repeats
    );
    say!("| case | d | k | simplices | C++ | CPU | CPU speed-up | GPU | GPU speed-up | decided on the GPU | same S |");
    say!("|---|---|---|---|---|---|---|---|---|---|---|");
    let cases = ReferenceCase::parse_all(include_str!("../../benches/reference.toml"))?;
    for case in cases.iter().filter(|c| c.simplices <= limit) {
        let p = case.problem()?;
        let cpu_oracle = CpuOracle::new(&p.system);
        let (cpu_s, cpu) = timed(args.repeats, || trace_case(&p, &cpu_oracle))?;
        let n = cpu.len();
        let mut row = json!({
            "case": case.label, "d": p.dim(), "k": p.system.codim(), "simplices": n,
            "reference_simplices": case.simplices, "reference_s": case.seconds,
            "cpu_s": cpu_s, "cpu_speedup": case.speedup(n, cpu_s),
        });
        let mut gpu_cols = ("-".to_string(), "-".to_string(), "-".to_string(), "-");
        if let Some(g) = gpu {
            let o = GpuOracle::new(g.clone(), &p.system, None)?;
            let (gpu_s, s) = timed(args.repeats, || trace_case(&p, &o))?;
            let same = s.sorted_keys() == cpu.sorted_keys();
            gpu_cols = (
                format!("{gpu_s:.3} s"),
                format!("{:.1}x", case.speedup(s.len(), gpu_s)),
                device_share(&s.stats),
                if same { "yes" } else { "NO" },
            );
            split_keys(&mut row, &s.stats);
            row["gpu_s"] = json!(gpu_s);
            row["gpu_speedup"] = json!(case.speedup(s.len(), gpu_s));
            row["gpu_precision"] = json!(o.precision().ty());
            row["same_sample"] = json!(same);
            if !same {
                return Err(Error::Gpu(format!(
                    "{}: the GPU trace differs from the CPU's",
                    case.label
                )));
            }
        }
        say!(
            "| {} | {} | {} | {n} | {} s | {cpu_s:.3} s | {:.1}x | {} | {} | {} | {} |",
            case.label,
            p.dim(),
            p.system.codim(),
            case.seconds,
            case.speedup(n, cpu_s),
            gpu_cols.0,
            gpu_cols.1,
            gpu_cols.2,
            gpu_cols.3
        );
        row["short"] = json!(case.short);
        rows.push(row);
    }
    Ok(rows)
}

/// Records in the calibration file what the traces and scans measured on a hardware
/// adapter, for `--backend auto` ([`calibration`]), and says where auto now runs each job.
/// A file that cannot be written costs the bench nothing but a note.
fn calibrate(g: &Gpu, threads: usize, traces: &[Value], scans: &[Value]) {
    let Some(entry) = Entry::from_bench(&g.adapter, threads, traces, scans) else {
        return;
    };
    let Some(path) = calibration::default_path() else {
        say!("\nnote: no cache directory to keep the calibration for --backend auto in (set ISOMESH_CALIBRATION)");
        return;
    };
    let mut c = Calibration::load(&path).unwrap_or_else(|e| {
        say!("\nnote: {e}; it is replaced");
        Calibration::default()
    });
    c.record(entry);
    if let Err(e) = c.save(&path) {
        say!("\nnote: the calibration for --backend auto was not saved: {e}");
        return;
    }
    say!(
        "\n--backend auto on {} (saved in {}):",
        g.adapter.name,
        path.display()
    );
    for job in [Job::Trace, Job::Scan] {
        let name = if job == Job::Trace { "traces" } else { "scans" };
        match c.pick(&g.adapter, job) {
            Pick::Gpu { device_values } => say!(
                "- {name}: the GPU{}",
                if device_values {
                    " with device values"
                } else {
                    ""
                }
            ),
            Pick::Cpu(why) => say!("- {name}: the CPU ({why})"),
        }
    }
}

/// The share of a run's decisions the device made, as a percentage.
fn device_share(st: &TraceStats) -> String {
    let all = st.device_decisions + st.cpu_decisions;
    format!(
        "{:.1}%",
        100.0 * st.device_decisions as f64 / all.max(1) as f64
    )
}

/// The split of a run's work between device and CPU, under the report's keys.
fn split_keys(row: &mut Value, st: &TraceStats) {
    row["device_vertex_evaluations"] = json!(st.device_vertex_evaluations);
    row["cpu_vertex_evaluations"] = json!(st.cpu_vertex_evaluations);
    row["device_decisions"] = json!(st.device_decisions);
    row["cpu_decisions"] = json!(st.cpu_decisions);
}

/// Exhaustive scans of boxes: the CPU, the GPU deciding from the CPU's values, and the GPU
/// with f's values (certified) from the device, with the split of the work.
fn scan_table(args: &BenchArgs, gpu: Option<&Gpu>) -> Result<Vec<Value>> {
    let mut rows = Vec::new();
    if !args.traces.contains(&TraceSet::Scans) {
        return Ok(rows);
    }
    say!("\nExhaustive scans, median of {}; vertices and decisions: device / CPU, with device values\n", args.repeats);
    say!("| case | vertices | simplices | CPU | GPU | GPU, device values | vertices | decisions | bytes per vertex, GPU / device values | same S |");
    say!("|---|---|---|---|---|---|---|---|---|---|");
    for case in SCAN_CASES {
        let p = case.problem()?;
        let cpu_oracle = CpuOracle::new(&p.system);
        let (cpu_s, cpu) = timed(args.repeats, || {
            scan_case(&p, &case.bbox(p.dim()), &cpu_oracle)
        })?;
        let mut row = json!({
            "case": case.label, "d": p.dim(), "k": p.system.codim(), "simplices": cpu.len(),
            "vertices": cpu.stats.vertices, "cpu_s": cpu_s,
        });
        let mut cols = [
            "-".to_string(),
            "-".into(),
            "-".into(),
            "-".into(),
            "-".into(),
            "-".into(),
        ];
        if let Some(g) = gpu {
            let bbox = case.bbox(p.dim());
            let vertices = cpu.stats.vertices.max(1) as f64;
            let o = GpuOracle::new(g.clone(), &p.system, None)?;
            let (gpu_s, plain) = timed(args.repeats, || scan_case(&p, &bbox, &o))?;
            let plain_moved = moved_per_run(&o, args.repeats, vertices, &mut row, "gpu");
            let with_values = GpuOptions {
                device_values: true,
                ..GpuOptions::default()
            };
            let o = GpuOracle::with_options(g.clone(), &p.system, with_values)?;
            let (values_s, dev) = timed(args.repeats, || scan_case(&p, &bbox, &o))?;
            let dev_moved = moved_per_run(&o, args.repeats, vertices, &mut row, "device_values");
            let st = &dev.stats;
            let same =
                plain.sorted_keys() == cpu.sorted_keys() && dev.sorted_keys() == cpu.sorted_keys();
            cols = [
                format!("{gpu_s:.3} s"),
                format!("{values_s:.3} s"),
                format!(
                    "{} / {}",
                    st.device_vertex_evaluations, st.cpu_vertex_evaluations
                ),
                format!("{} / {}", st.device_decisions, st.cpu_decisions),
                format!("{plain_moved:.1} / {dev_moved:.1}"),
                if same { "yes" } else { "NO" }.into(),
            ];
            row["gpu_s"] = json!(gpu_s);
            row["device_values_s"] = json!(values_s);
            row["gpu_vertices_per_s"] = json!(vertices / gpu_s);
            row["device_values_vertices_per_s"] = json!(vertices / values_s);
            row["gpu_precision"] = json!(o.precision().ty());
            split_keys(&mut row, st);
            row["same_sample"] = json!(same);
            if !same {
                return Err(Error::Gpu(format!(
                    "{}: a GPU scan differs from the CPU's",
                    case.label
                )));
            }
        }
        say!(
            "| {} | {} | {} | {cpu_s:.3} s | {} | {} | {} | {} | {} | {} |",
            case.label,
            cpu.stats.vertices,
            cpu.len(),
            cols[0],
            cols[1],
            cols[2],
            cols[3],
            cols[4],
            cols[5]
        );
        rows.push(row);
    }
    Ok(rows)
}

/// Bytes uploaded and read back per lattice vertex in one of `repeats` runs of oracle `o`
/// (whose counters then restart), with the run's counts and host seconds under `prefix`
/// in `row`.
fn moved_per_run(
    o: &GpuOracle,
    repeats: usize,
    vertices: f64,
    row: &mut Value,
    prefix: &str,
) -> f64 {
    let st = o.stats();
    let runs = repeats.max(1) as u64;
    let (up, back) = (st.upload_bytes / runs, st.readback_bytes / runs);
    row[format!("{prefix}_upload_bytes")] = json!(up);
    row[format!("{prefix}_readback_bytes")] = json!(back);
    row[format!("{prefix}_host_s")] = json!(st.host_s / runs as f64);
    o.reset_stats();
    (up + back) as f64 / vertices
}

/// Surfaces in R^3 against the grid mesher: a row per surface and size, and each surface's
/// crossover (the vertex count from which isomesh is faster; null if it is nowhere).
fn surface_table(args: &BenchArgs) -> Result<(Vec<Value>, serde_json::Map<String, Value>)> {
    let (mut out, mut crossovers) = (Vec::new(), serde_json::Map::new());
    if !args.traces.contains(&TraceSet::Surfaces) {
        return Ok((out, crossovers));
    }
    // Every size is checked before anything is measured.
    for &n in &args.grid {
        check_grid(n)?;
    }
    let mut sizes = args.grid.clone();
    sizes.sort_unstable();
    sizes.dedup();
    say!(
        "\nSurfaces in R^3: isomesh (trace + complex + triangles) against fast-surface-nets (f sampled in f32 + meshing, in {CHUNK}^3 chunks), {} threads, median of {}\n",
        rayon::current_num_threads(),
        args.repeats
    );
    say!("| surface | grid | grid vertices | isomesh vertices | grid ms | isomesh ms (trace + complex + triangles) | isomesh / grid |");
    say!("|---|---|---|---|---|---|---|");
    for s in &SURFACES {
        let rows = measure_sizes(s, &sizes, args.repeats, |r| {
            let ms = |x: f64| x * 1e3;
            say!(
                "| {} | {}^3 | {} | {} | {:.1} | {:.1} + {:.1} + {:.1} = {:.1} | {:.2} |",
                s.preset,
                r.n,
                r.grid.vertices,
                r.isomesh.vertices,
                ms(r.grid_s),
                ms(r.stages.trace_s),
                ms(r.stages.complex_s),
                ms(r.stages.triangles_s),
                ms(r.stages.total()),
                r.ratio()
            );
            out.push(json!({
                "surface": s.preset, "n": r.n, "grid_vertices": r.grid.vertices,
                "grid_triangles": r.grid.triangles, "grid_s": r.grid_s, "edge": r.edge,
                "isomesh_vertices": r.isomesh.vertices, "isomesh_triangles": r.isomesh.triangles,
                "trace_s": r.stages.trace_s, "complex_s": r.stages.complex_s,
                "triangles_s": r.stages.triangles_s, "isomesh_s": r.stages.total(),
                "ratio": r.ratio(),
            }));
        })?;
        crossovers.insert(s.preset.into(), json!(crossover(&rows)));
    }
    say!("");
    for (name, c) in &crossovers {
        match c.as_f64() {
            Some(v) => say!("{name}: isomesh is faster from about {v:.3e} vertices up"),
            None => say!("{name}: isomesh is slower at every size measured"),
        }
    }
    Ok((out, crossovers))
}

fn plot(
    path: &std::path::Path,
    oracle: &[Value],
    traces: &[Value],
    surfaces: &[Value],
    precisions: &[Precision],
) -> Result<()> {
    let mut names = vec!["cpu".to_string()];
    names.extend(precisions.iter().map(|p| format!("gpu {}", p.ty())));
    let series = |rows: &[Value], x: &dyn Fn(usize, &Value) -> f64, key: &str, name: &str| {
        rows.iter()
            .enumerate()
            .filter(|(_, r)| r["oracle"].as_str().is_none_or(|o| o == name))
            .filter_map(|(i, r)| Some((x(i, r), r[key].as_f64()?)))
            .collect::<Vec<_>>()
    };
    let mut charts = Vec::new();
    if !oracle.is_empty() {
        charts.push(Chart {
            title: "Intersection oracle alone".into(),
            x_label: "codimension k".into(),
            y_label: "simplices per second".into(),
            series: names
                .iter()
                .enumerate()
                .map(|(i, name)| Series {
                    name: name.clone(),
                    color: PALETTE[i % PALETTE.len()],
                    points: series(
                        oracle,
                        &|_, r| r["k"].as_f64().unwrap_or(0.0),
                        "simplices_per_s",
                        name,
                    ),
                })
                .collect(),
            x_ticks: Vec::new(),
        });
    }
    if !traces.is_empty() {
        let at = |i: usize, _: &Value| i as f64;
        charts.push(Chart {
            title: "Whole traces against the C++ library".into(),
            x_label: "reference case".into(),
            y_label: "speed-up (throughput)".into(),
            series: [("cpu", "cpu_speedup"), ("gpu", "gpu_speedup")]
                .iter()
                .enumerate()
                .map(|(i, (name, key))| Series {
                    name: name.to_string(),
                    color: PALETTE[i],
                    points: series(traces, &at, key, name),
                })
                .filter(|s| !s.points.is_empty())
                .collect(),
            x_ticks: traces
                .iter()
                .enumerate()
                .map(|(i, r)| (i as f64, r["short"].as_str().unwrap_or("?").to_string()))
                .collect(),
        });
    }
    if !surfaces.is_empty() {
        // isomesh in the palette's blue, green and orange; the grid mesher in red, purple, brown.
        const GRID_COLORS: [[u8; 3]; 3] = [PALETTE[1], PALETTE[3], [140, 86, 75]];
        let mut series = Vec::new();
        for (i, s) in SURFACES.iter().enumerate() {
            for (method, key, color) in [
                ("isomesh", "isomesh_s", PALETTE[2 * i % PALETTE.len()]),
                ("surface nets", "grid_s", GRID_COLORS[i]),
            ] {
                let points = surfaces
                    .iter()
                    .filter(|r| r["surface"] == s.preset)
                    .filter_map(|r| {
                        let v = r["grid_vertices"].as_f64()?;
                        Some((v.log10(), r[key].as_f64()? * 1e3))
                    })
                    .collect();
                series.push(Series {
                    name: format!("{} {method}", s.preset),
                    color,
                    points,
                });
            }
        }
        // Powers of ten of the vertex counts on the (linear in log10) x axis.
        let logs = surfaces.iter().filter_map(|r| r["grid_vertices"].as_f64());
        let (lo, hi) = logs.fold((f64::MAX, 0.0f64), |(a, b), v| {
            (a.min(v.log10()), b.max(v.log10()))
        });
        let x_ticks = (lo.ceil() as i32..=hi.floor() as i32)
            .map(|e| (f64::from(e), format!("1e{e}")))
            .collect();
        charts.push(Chart {
            title: "Surfaces in R^3 against surface nets".into(),
            x_label: "vertices".into(),
            y_label: "milliseconds".into(),
            series,
            x_ticks,
        });
    }
    if charts.is_empty() {
        return Err(Error::Usage(
            "--png: nothing was measured (--k 0 and --traces none)".into(),
        ));
    }
    write_charts(path, &charts, (700, 480))
}
