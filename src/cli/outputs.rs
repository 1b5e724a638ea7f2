//! `isomesh trace`'s outputs, planned before anything is traced: each `--out` with its
//! format, the projection, and the paths checked (regular files only, no output the same file
//! as another or as the input spec).

use std::path::{Path, PathBuf};

use isomesh::export::safe::{check_target, FileId};
use isomesh::export::{OutputFormat as Output, Projection, SampleFormat};
use isomesh::expr::{ImplicitFunction, Problem};
use isomesh::{Error, Result};

use super::text::shown;
use super::trace::{Backend, TraceArgs};

/// `--report -`: the JSON report goes to standard output.
pub(super) fn report_to_stdout(args: &TraceArgs) -> bool {
    args.report.as_ref().is_some_and(|p| p.as_os_str() == "-")
}

/// One --out: where it goes and what it receives.
pub(super) struct Planned {
    pub path: PathBuf,
    pub kind: Output,
    /// `--out -`: standard output.
    pub stdout: bool,
}

/// The outputs and the projection, every output flag checked before anything is traced:
/// formats, the mesh dimension they hold, the projection, paths that must be regular files,
/// and no output the same file as another or as the input spec.
pub(super) struct Plan {
    pub outs: Vec<Planned>,
    pub projection: Projection,
}

pub(super) fn plan_outputs(args: &TraceArgs, p: &Problem) -> Result<Plan> {
    let (d, k) = (p.system.ambient_dim(), p.system.codim());
    if args.format.is_some() && args.out.is_empty() {
        return Err(Error::Usage(
            "--format sets the format of --out files: give --out too".into(),
        ));
    }
    let mut outs = Vec::new();
    for path in &args.out {
        let stdout = path.as_os_str() == "-";
        if !stdout {
            check_target(path).map_err(|e| e.for_flag("--out"))?;
        }
        let kind = match (stdout, args.format.as_deref()) {
            (true, None) => Output::Sample(SampleFormat::Csv),
            (_, format) => output_kind(path, format)?,
        };
        match &kind {
            Output::Mesh(_) if stdout => {
                return Err(Error::Usage(
                    "--out -: standard output takes the sample only (csv or xyz); write mesh \
                     files to a path"
                        .into(),
                ))
            }
            Output::Mesh(format) => format.check_holds(d - k, path)?,
            Output::Sample(_) => {}
        }
        outs.push(Planned {
            path: path.clone(),
            kind,
            stdout,
        });
    }
    if outs.iter().filter(|o| o.stdout).count() > 1 {
        return Err(Error::Usage("--out - is given twice".into()));
    }
    if (report_to_stdout(args) || outs.iter().any(|o| o.stdout)) && super::stdout_closed() {
        return Err(Error::Usage(format!(
            "{} -: standard output is closed; give a path",
            if report_to_stdout(args) {
                "--report"
            } else {
                "--out"
            }
        )));
    }
    if report_to_stdout(args) && outs.iter().any(|o| o.stdout) {
        return Err(Error::Usage(
            "--out - and --report - both ask for standard output: give one of them a path".into(),
        ));
    }
    if args.png.as_ref().is_some_and(|p| p.as_os_str() == "-") {
        return Err(Error::Usage(
            "--png -: a picture is written to a file; give a path".into(),
        ));
    }
    let projection = Projection::parse(&args.project, d)?;
    let wants_mesh = args.png.is_some() || outs.iter().any(|o| matches!(o.kind, Output::Mesh(_)));
    if args.no_complex && wants_mesh {
        return Err(Error::Usage(
            "--no-complex: mesh files and pictures need the cell complex".into(),
        ));
    }
    if args.backend.unwrap_or(Backend::Cpu) == Backend::Cpu {
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
    // Files: each absent or a regular file, and no two the same file.
    let mut files: Vec<(String, &Path, FileId)> = Vec::new();
    let named = outs
        .iter()
        .filter(|o| !o.stdout)
        .map(|o| ("--out", o.path.as_path()))
        .chain(args.png.iter().map(|p| ("--png", p.as_path())))
        .chain(
            args.report
                .iter()
                .filter(|_| !report_to_stdout(args))
                .map(|p| ("--report", p.as_path())),
        );
    for (flag, path) in named {
        check_target(path).map_err(|e| e.for_flag(flag))?;
        let id = FileId::of(path)?;
        if let Some((other, other_path, _)) = files.iter().find(|f| f.2.same(&id)) {
            return Err(Error::Usage(format!(
                "{flag} {} and {other} {} are the same file: give each output its own path",
                shown(&path.display().to_string()),
                shown(&other_path.display().to_string())
            )));
        }
        files.push((flag.to_string(), path, id));
    }
    if let Some(spec) = &args.spec {
        let id = FileId::of(spec)?;
        if let Some((flag, path, _)) = files.iter().find(|f| f.2.same(&id)) {
            return Err(Error::Usage(format!(
                "{flag} {} is the input spec: it would be overwritten; give another path",
                shown(&path.display().to_string())
            )));
        }
    }
    Ok(Plan { outs, projection })
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
