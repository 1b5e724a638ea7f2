//! The command line's pieces: loading a problem, `check`, `trace`, `bench`.

pub mod bench;
pub mod trace;

use std::path::PathBuf;

use isomesh::expr::{preset, ImplicitFunction, Problem, Spec};
use isomesh::gpu::wgsl::{eval_shader, Precision};
use isomesh::Result;

/// Parses a `name=value` preset parameter.
pub fn parse_param(s: &str) -> std::result::Result<(String, f64), String> {
    let (n, v) = s
        .split_once('=')
        .ok_or_else(|| format!("'{s}': expected name=value"))?;
    let v: f64 = v
        .trim()
        .parse()
        .map_err(|_| format!("'{s}': '{v}' is not a number"))?;
    Ok((n.trim().to_string(), v))
}

/// The problem from a spec file or a preset (the torus when neither is given).
pub fn load(
    spec: Option<PathBuf>,
    name: Option<String>,
    params: &[(String, f64)],
) -> Result<Problem> {
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

/// `isomesh check`: what the problem is, where its seeds lie, and whether its WGSL validates.
pub fn check(p: &Problem) -> Result<()> {
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
