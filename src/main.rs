//! The `isomesh` command line.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use isomesh::expr::{preset, ImplicitFunction, Problem, Spec, PRESETS};
use isomesh::gpu::wgsl::{eval_shader, Precision};
use isomesh::Result;

#[derive(Parser)]
#[command(
    name = "isomesh",
    version,
    about = "Meshes implicit manifolds f^-1(0) of any dimension and codimension"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// List the built-in manifolds and their parameters.
    Presets,
    /// Read a spec or preset, project its seeds onto M, locate them in the triangulation and
    /// check the WGSL emitted for f and its Jacobian.
    Check {
        /// A spec file (TOML).
        spec: Option<PathBuf>,
        /// A built-in manifold instead of a spec file.
        #[arg(long)]
        preset: Option<String>,
        /// Preset parameter, name=value (repeatable).
        #[arg(long = "param", value_parser = parse_param)]
        params: Vec<(String, f64)>,
    },
}

fn parse_param(s: &str) -> std::result::Result<(String, f64), String> {
    let (n, v) = s
        .split_once('=')
        .ok_or_else(|| format!("'{s}': expected name=value"))?;
    let v: f64 = v
        .trim()
        .parse()
        .map_err(|_| format!("'{s}': '{v}' is not a number"))?;
    Ok((n.trim().to_string(), v))
}

fn load(spec: Option<PathBuf>, name: Option<String>, params: &[(String, f64)]) -> Result<Problem> {
    match (spec, name) {
        (Some(path), None) => {
            let stem = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            Spec::from_file(&path)?.resolve(&stem)
        }
        (None, Some(n)) => preset(&n, params),
        (None, None) => preset("torus", params),
        (Some(_), Some(_)) => Err(isomesh::Error::Spec(
            "give a spec file or --preset, not both".into(),
        )),
    }
}

fn check(p: &Problem) -> Result<()> {
    let sys = &p.system;
    let (d, k) = (sys.ambient_dim(), sys.codim());
    println!("{}: f: R^{d} -> R^{k}, a {}-manifold", p.name, d - k);
    for (i, e) in sys.equations().iter().enumerate() {
        println!("  f{} = {e}", i + 1);
    }
    for g in sys.boundary() {
        println!("  boundary: {g} >= 0");
    }
    let t = p.triangulation.build(d)?;
    println!(
        "triangulation: {} in R^{d}, longest edge {}",
        t.kind().name(),
        t.edge()
    );
    for s in &p.seeds {
        let mut f = vec![0.0; k];
        sys.eval_batch(s, &mut f);
        let norm = f.iter().map(|v| v * v).sum::<f64>().sqrt();
        let simplex = t.locate(s)?;
        println!(
            "seed {s:?}: |f| = {norm:.1e}, in the {}-simplex {simplex}",
            simplex.dim()
        );
    }
    for (what, prog) in [("f", sys.values()), ("Jacobian", sys.jacobian_program())] {
        for prec in [Precision::F32, Precision::F64] {
            let src = eval_shader(prog, prec)?;
            println!(
                "WGSL for {what} ({}): {} lines, validated by naga",
                prec.ty(),
                src.lines().count()
            );
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Presets) => {
            for p in PRESETS {
                let params: Vec<String> =
                    p.params.iter().map(|(n, v)| format!("{n}={v}")).collect();
                println!("{:<15} {}  [{}]", p.name, p.about, params.join(", "));
            }
            Ok(())
        }
        Some(Command::Check {
            spec,
            preset,
            params,
        }) => load(spec, preset, &params).and_then(|p| check(&p)),
        None => {
            println!(
                "isomesh with no arguments checks the built-in torus (isomesh --help for more).\n"
            );
            load(None, None, &[]).and_then(|p| check(&p))
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
