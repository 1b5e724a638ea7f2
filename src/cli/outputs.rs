//! `isomesh trace`'s outputs, planned before anything is traced: each `--out` with its
//! format, the projection, and the paths checked (regular files only, no output the same file
//! as another or as the input spec).

use isomesh::export::safe::check_target;
use isomesh::export::{OutputFormat as Output, SampleFormat};
use isomesh::expr::{ImplicitFunction, Problem};
use isomesh::mesher::{OutputPlan, Target};
use isomesh::{Backend, Error, Result};

use super::args::{TraceArgs, DEFAULT_PNG_SIZE};
use super::text::shown;

/// The outputs of `args`, every output flag checked before anything is traced: formats, the
/// mesh dimension they hold, the projection, paths that must be regular files, no output the
/// same file as another or as the input spec, and no flag that would be ignored.
pub(super) fn plan_outputs(args: &TraceArgs, p: &Problem) -> Result<OutputPlan> {
    let (d, k) = (p.system.ambient_dim(), p.system.codim());
    if args.format.is_some() && args.out.is_empty() {
        return Err(Error::Usage(
            "--format sets the format of --out files: give --out too".into(),
        ));
    }
    let mut plan = OutputPlan::new(d, &args.project)?;
    for path in &args.out {
        let target = Target::from_path(path);
        if target != Target::Stdout {
            check_target(path).map_err(|e| e.for_flag("--out"))?;
        }
        let kind = match (&target, args.format.as_deref()) {
            (Target::Stdout, None) => Output::Sample(SampleFormat::Csv),
            (_, format) => output_kind(path, format)?,
        };
        plan.add("--out", target, kind, d - k)?;
    }
    let out_stdout = plan.uses_stdout();
    if (args.report_to_stdout() || out_stdout) && super::stdout_closed() {
        return Err(Error::Usage(format!(
            "{} -: standard output is closed; give a path",
            if args.report_to_stdout() {
                "--report"
            } else {
                "--out"
            }
        )));
    }
    if args.report_to_stdout() && out_stdout {
        return Err(Error::Usage(
            "--out - and --report - both ask for standard output: give one of them a path".into(),
        ));
    }
    if args.png.as_ref().is_some_and(|p| p.as_os_str() == "-") {
        return Err(Error::Usage(
            "--png -: a picture is written to a file; give a path".into(),
        ));
    }
    plan.report = args.report.as_deref().map(Target::from_path);
    plan.picture = args.png.clone().map(|path| {
        let (w, h) = args.png_size.unwrap_or(DEFAULT_PNG_SIZE);
        (path, w, h)
    });
    plan.complex = !args.no_complex;
    if args.ascii {
        plan.encoding = isomesh::export::Encoding::Ascii;
    }
    if args.no_complex && plan.wants_mesh() {
        return Err(Error::Usage(
            "--no-complex: mesh files and pictures need the cell complex".into(),
        ));
    }
    if args.backend.unwrap_or_default() == Backend::Cpu {
        for (set, flag) in [
            (args.precision.is_some(), "--precision"),
            (args.level_slice.is_some(), "--level-slice"),
            (args.device_values, "--device-values"),
        ] {
            if set {
                return Err(Error::Usage(format!(
                    "{flag} sets the GPU oracle; the CPU backend (the default) has no use for \
                     it: add --backend gpu or --backend auto, or leave {flag} out"
                )));
            }
        }
    }
    // Flags that would be ignored are refused: the run would not be the one asked for.
    if args.png_size.is_some() && args.png.is_none() {
        return Err(Error::Usage(
            "--png-size sets the size of the --png picture: give --png too".into(),
        ));
    }
    if args.exhaustive {
        for (set, flag) in [
            (!args.seeds.is_empty(), "--seed"),
            (args.search.is_some(), "--search"),
        ] {
            if set {
                return Err(Error::Usage(format!(
                    "{flag} starts a trace; --exhaustive scans the whole box and has no use \
                     for it: leave one of them out"
                )));
            }
        }
    }
    if args.device_values && !args.exhaustive {
        return Err(Error::Usage(
            "--device-values applies to exhaustive scans (a trace takes f's values from the \
             CPU): add --exhaustive, or leave --device-values out"
                .into(),
        ));
    }
    plan.check_files("--png", "--report", args.spec.as_deref())?;
    Ok(plan)
}

/// The format of `path`: `--format` when given, else its extension.
fn output_kind(path: &std::path::Path, format: Option<&str>) -> Result<Output> {
    match format {
        Some(f) => Output::from_name(f).ok_or_else(|| {
            Error::Usage(format!(
                "--format {}: use {}",
                shown(f),
                isomesh::export::FORMAT_NAMES
            ))
        }),
        None => Output::for_path(path, None),
    }
}
