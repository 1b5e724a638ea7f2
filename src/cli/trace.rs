//! `isomesh trace`: flags -> [`Mesher`] -> [`Manifold`] -> printing. The library runs the
//! trace or scan, writes the outputs and assembles the report; this module turns flags into
//! a mesher and an output plan, shows progress, and prints the warnings and the summary.

use std::sync::Arc;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use isomesh::expr::{ImplicitFunction, Problem};
use isomesh::memory;
use isomesh::mesher::{Delivery, Job, OutputPlan, Warning};
use isomesh::trace::Progress;
use isomesh::triangulation::TriangulationKind;
use isomesh::{Error, Manifold, Mesher, Result};

use super::args::{box_from_flag, NumList, TraceArgs};
use super::outputs::plan_outputs;
use super::text::{num, say, shown, summary};
use super::{load, signals};

/// Runs `isomesh trace` with `args`.
pub fn run(args: &TraceArgs) -> Result<()> {
    // Parsing, differentiating and compiling the equations stop at the memory limit too.
    let limit = args.max_memory.unwrap_or_else(memory::default_limit);
    let mut problem = memory::within(limit, || {
        load(args.spec.clone(), args.preset.clone(), &args.params)
    })?;
    apply_flags(&mut problem, args)?;
    let plan = plan_outputs(args, &problem)?;
    if args.threads == Some(0) {
        return Err(Error::Usage("--threads must be at least 1".into()));
    }
    let threads = args.threads.unwrap_or_else(rayon::current_num_threads);
    let (d, k) = (problem.system.ambient_dim(), problem.system.codim());
    let cancel = signals::stop_flag();
    let bar = progress_bar(args.quiet);
    let mesher = mesher_of(problem, args, threads, &bar)?.cancel(cancel.clone());
    let phase = |what: &str| {
        if args.verbose {
            eprintln!("isomesh: {what}");
        }
    };
    let job = if args.exhaustive {
        phase("scan: evaluating f on the box's lattice, then deciding its simplices");
        Job::Scan
    } else {
        phase(&describe_trace(&mesher, args.search));
        Job::Trace
    };
    let manifold = mesher.run(job)?;
    bar.finish_and_clear();
    for w in manifold.warnings() {
        // The command line's name for an exhaustive scan.
        let flag = match w {
            Warning::SingularSeed { .. } | Warning::SingularCrossing(_) => " (--exhaustive)",
            _ => "",
        };
        match (w.is_note(), args.quiet) {
            (true, true) => {}
            (true, false) => eprintln!("note: {w}"),
            (false, _) => eprintln!("warning: {w}{flag}"),
        }
    }
    let delivery = manifold.deliver(&plan, &cancel, &phase);
    // The first error decides the exit status and the report's error; every other one is
    // named on standard error.
    for e in delivery.errors.iter().skip(1) {
        eprintln!("error: {e}");
    }
    let signal = signals::received();
    let report = manifold.final_report(&delivery, &plan.projection_name, signal.map(signals::name));
    let mut written = delivery.written.clone();
    if plan.report.is_some() {
        phase("writing the report");
        written.extend(plan.write_report(&report)?);
    }
    if !args.quiet {
        print_summary(&manifold, &delivery, &plan, &written, (d, k));
    }
    outcome(&manifold, delivery, signal, !written.is_empty())
}

/// The phase line of a trace: its seeds and its box search.
fn describe_trace(mesher: &Mesher, search: Option<usize>) -> String {
    let seeds = mesher.seed_count();
    let search = search.unwrap_or(if seeds == 0 {
        isomesh::trace::DEFAULT_SEARCH_SAMPLES
    } else {
        0
    });
    format!(
        "trace: from {seeds} seed{}{}",
        if seeds == 1 { "" } else { "s" },
        if search > 0 {
            format!(", then from {search} box points projected onto M")
        } else {
            String::new()
        }
    )
}

/// The mesher `args` ask for on `p`, its progress shown on `bar`.
fn mesher_of(p: Problem, args: &TraceArgs, threads: usize, bar: &ProgressBar) -> Result<Mesher> {
    let started = Instant::now();
    let (verbose, quiet, bar) = (args.verbose, args.quiet, bar.clone());
    let progress = move |pr: &Progress| {
        if verbose {
            eprintln!(
                "isomesh: level {}, {} simplices, {} vertices",
                pr.level, pr.simplices, pr.vertices
            );
        }
        if started.elapsed() > Duration::from_secs(1) {
            if bar.is_hidden() && !quiet {
                bar.set_draw_target(ProgressDrawTarget::stderr());
            }
            bar.set_message(format!(
                "{} simplices, level {}, {} vertices",
                pr.simplices, pr.level, pr.vertices
            ));
            bar.tick();
        }
    };
    let mut m = Mesher::from_problem(p)
        .backend(args.backend.unwrap_or_default())
        .precision(args.shader_precision())
        .level_slice(args.level_slice)
        .device_values(args.device_values)
        .threads(threads)
        .max_memory(args.max_memory.unwrap_or_else(memory::default_limit))
        .progress(Arc::new(progress))
        .warm(true);
    if let Some(n) = args.search {
        m = m.search(n);
    }
    Ok(m)
}

/// The summary: what was found, the complex, the files written.
fn print_summary(
    m: &Manifold,
    delivery: &Delivery,
    plan: &OutputPlan,
    written: &[std::path::PathBuf],
    (d, k): (usize, usize),
) {
    // With the sample or the report on standard output, the summary goes to standard error.
    let to_stderr = plan.uses_stdout();
    let line = |text: String| {
        if to_stderr {
            eprintln!("{text}");
        } else {
            say!("{text}");
        }
    };
    let st = &m.sample().stats;
    let r = m.report();
    let n = m.len();
    let tri = m.sample().triangulation();
    let threads = r.threads;
    line(format!(
        "{}: {n} crossed {k}-simplices ({}-manifold in R^{d}, {}, edge {}), {} component{}, \
         in {:.3} s ({:.0} simplices/s, {threads} thread{}), peak {} ({:.0} B/simplex)",
        shown(&r.name),
        d - k,
        tri.kind().name(),
        num(tri.edge()),
        st.components,
        if st.components == 1 { "" } else { "s" },
        st.elapsed_s,
        r.simplices_per_s,
        if threads == 1 { "" } else { "s" },
        memory::human_bytes(r.peak_memory_bytes),
        r.bytes_per_simplex,
    ));
    if let (Some(topo_s), Ok(c), Ok(t)) = (delivery.topology_s, m.complex(), m.topology()) {
        line(summary(t, c.stats.elapsed_s + topo_s));
    }
    for f in written {
        line(format!("wrote {}", shown(&f.display().to_string())));
    }
}

/// The exit status: a signal, nothing found, a failure or an early stop is an error that
/// says what was kept.
fn outcome(
    m: &Manifold,
    mut delivery: Delivery,
    signal: Option<i32>,
    wrote_any: bool,
) -> Result<()> {
    let n = m.len();
    let not_written = &delivery.not_written;
    let unwritten = if not_written.is_empty() {
        String::new()
    } else {
        format!("; not written: {}", not_written.join(", "))
    };
    let kept = |n: usize| {
        format!(
            "the {n} simplices found were kept{}{unwritten}",
            if wrote_any { " and written" } else { "" }
        )
    };
    let stopped = &m.sample().stats.stopped;
    if let Some(sig) = signal {
        return Err(Error::Interrupted(format!(
            "stopped by {}; {}, the report says complete: false",
            signals::name(sig),
            kept(n)
        )));
    }
    if let Some(why) = m.nothing_found() {
        return Err(Error::Trace(format!("{why}{unwritten}")));
    }
    if !delivery.errors.is_empty() && stopped.is_none() {
        if !not_written.is_empty() {
            eprintln!("not written: {}", not_written.join(", "));
        }
        return Err(delivery.errors.remove(0));
    }
    if let Some(stop) = stopped {
        return Err(Error::Trace(format!("{stop}; {}", kept(n))));
    }
    Ok(())
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

fn progress_bar(quiet: bool) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    if !quiet {
        bar.set_style(
            ProgressStyle::with_template("{spinner} {elapsed} {msg}").expect("a valid template"),
        );
    }
    bar
}
