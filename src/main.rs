//! The `isomesh` command line.

mod cli;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};
use cli::args::TraceArgs;
use cli::bench::BenchArgs;
use cli::text::say;
use isomesh::expr::PRESETS;
use isomesh::memory::CountingAlloc;

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

#[derive(Parser)]
#[command(
    name = "isomesh",
    version,
    about = "Meshes implicit manifolds f^-1(0) of any dimension and codimension",
    after_help = "With no command, isomesh traces the built-in torus and writes \
                  isomesh-out/torus.csv, .ply, .png and .json."
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Trace M = f^-1(0) from a spec or preset: the crossed k-simplices and a point of M on
    /// each.
    Trace(Box<TraceArgs>),
    /// Benchmark the CPU oracle against the GPU oracle on the same batches, and whole traces
    /// of the reference cases on both backends.
    Bench(Box<BenchArgs>),
    /// List the built-in manifolds and their parameters.
    Presets,
    /// List the GPU adapters wgpu finds, with their features.
    Info,
    /// Read a spec or preset, project its seeds onto M, locate them in the triangulation and
    /// check the WGSL emitted for f and its Jacobian.
    Check {
        /// A spec file (TOML).
        spec: Option<PathBuf>,
        /// A built-in manifold instead of a spec file.
        #[arg(long)]
        preset: Option<String>,
        /// Preset parameter, name=value (repeatable).
        #[arg(long = "param", value_parser = cli::parse_param)]
        params: Vec<(String, f64)>,
    },
}

fn main() -> ExitCode {
    // Silence a Mesa Vulkan layer that writes to stderr when no display is set; done first,
    // before any thread exists.
    if std::env::var_os("NODEVICE_SELECT").is_none() {
        std::env::set_var("NODEVICE_SELECT", "1");
    }
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Trace(args)) => cli::trace::run(&args),
        Some(Command::Bench(args)) => cli::bench::run(&args),
        Some(Command::Info) => {
            let list = isomesh::gpu::adapters();
            if list.is_empty() {
                say!(
                    "no GPU adapter: wgpu found no driver that runs compute shaders; \
                     --backend auto uses the CPU, --backend gpu fails"
                );
            }
            for (i, a) in list.iter().enumerate() {
                say!(
                    "{}{}: {} ({}, {}{}), driver {}, SHADER_F64 {}, storage binding {} MiB",
                    if i == 0 { "* " } else { "  " },
                    i,
                    a.name,
                    a.backend,
                    a.device_type,
                    if a.is_software() {
                        ", software: auto skips it"
                    } else {
                        ""
                    },
                    a.driver,
                    if a.shader_f64 { "yes" } else { "no" },
                    a.max_storage_binding >> 20
                );
            }
            if !list.is_empty() && std::env::var_os("WGPU_BACKEND").is_none() {
                say!(
                    "(GL is probed only where no Vulkan, Metal or Dx12 adapter runs compute; \
                     WGPU_BACKEND=gl lists its adapters)"
                );
            }
            Ok(())
        }
        Some(Command::Presets) => {
            for p in PRESETS {
                let params: Vec<String> =
                    p.params.iter().map(|(n, v)| format!("{n}={v}")).collect();
                say!("{:<15} {}  [{}]", p.name, p.about, params.join(", "));
            }
            Ok(())
        }
        Some(Command::Check {
            spec,
            preset,
            params,
        }) => isomesh::memory::within(isomesh::memory::default_limit(), || {
            cli::load(spec, preset, &params)
        })
        .and_then(|p| cli::check(&p)),
        None => {
            say!(
                "isomesh with no command traces the built-in torus (R = 1, r = 0.4) on a \
                 Coxeter triangulation (isomesh --help for more)."
            );
            let args = TraceArgs {
                preset: Some("torus".into()),
                out: vec![
                    "isomesh-out/torus.csv".into(),
                    "isomesh-out/torus.ply".into(),
                ],
                png: Some("isomesh-out/torus.png".into()),
                png_size: None,
                project: "auto".into(),
                report: Some("isomesh-out/torus.json".into()),
                ..TraceArgs::default()
            };
            cli::trace::run(&args)
        }
    };
    let signal = cli::signals::received();
    match result {
        Ok(()) if signal.is_none() => ExitCode::SUCCESS,
        Ok(()) => ExitCode::from(cli::signals::exit_status(signal.unwrap_or(2))),
        Err(e) => {
            eprintln!("error: {}", cli::text::shown(&e.to_string()));
            match signal {
                Some(sig) => ExitCode::from(cli::signals::exit_status(sig)),
                None => ExitCode::FAILURE,
            }
        }
    }
}
