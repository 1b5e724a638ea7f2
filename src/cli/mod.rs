//! The command line's pieces: loading a problem, `check`, `trace`, `bench`.

pub mod args;
pub mod bench;
mod outputs;
pub mod signals;
pub mod text;
pub mod trace;

use std::path::PathBuf;

use isomesh::expr::{preset, ImplicitFunction, Problem, Spec};
use isomesh::gpu::wgsl::{eval_shader, Precision};
use isomesh::Result;
use text::{num, say, shown};

/// Whether standard output was closed by the caller (`>&-`): `--out -` and `--report -` are
/// refused then, their bytes would go nowhere.
///
/// The Rust runtime reopens a closed standard stream on /dev/null before `main`, read and
/// write; a shell's `>/dev/null` opens it write-only. So a standard output that is /dev/null
/// opened for reading and writing was closed.
pub fn stdout_closed() -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        // SAFETY: fcntl and fstat on descriptor 1 read its state and change nothing; `st` is
        // a plain C struct that fstat fills.
        let (flags, rdev) = unsafe {
            let mut st: libc::stat = std::mem::zeroed();
            let flags = libc::fcntl(1, libc::F_GETFL);
            if flags < 0 || libc::fstat(1, &mut st) != 0 {
                return true;
            }
            (flags, st.st_rdev)
        };
        let null = std::fs::metadata("/dev/null").map(|m| m.rdev());
        flags & libc::O_ACCMODE == libc::O_RDWR && null.is_ok_and(|n| n == rdev)
    }
    #[cfg(not(unix))]
    {
        false
    }
}

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
            let mut spec = Spec::from_file(&path)?;
            // --param overrides the spec's `parameters`; it cannot add new names.
            for (n, v) in params {
                match spec.parameters.get_mut(n) {
                    Some(slot) if v.is_finite() => *slot = *v,
                    Some(_) => {
                        return Err(isomesh::Error::Usage(format!(
                            "--param {}: the value is not finite",
                            shown(n)
                        )))
                    }
                    None => {
                        let names: Vec<&str> = spec.parameters.keys().map(String::as_str).collect();
                        return Err(isomesh::Error::Usage(format!(
                            "--param {}: {} has no such parameter ({})",
                            shown(n),
                            path.display(),
                            if names.is_empty() {
                                "it has none".to_string()
                            } else {
                                format!("it has {}", names.join(", "))
                            }
                        )));
                    }
                }
            }
            spec.resolve(&stem)
        }
        (None, Some(n)) => preset(&n, params),
        (None, None) => preset("torus", params),
        (Some(_), Some(_)) => Err(isomesh::Error::Usage(
            "give a spec file or --preset, not both".into(),
        )),
    }
}

/// `isomesh check`: what the problem is, where its seeds lie, and whether its WGSL validates.
pub fn check(p: &Problem) -> Result<()> {
    let sys = &p.system;
    let (d, k) = (sys.ambient_dim(), sys.codim());
    say!(
        "{}: f: R^{d} -> R^{k}, a {}-manifold",
        shown(&p.name),
        d - k
    );
    let names = sys.names();
    say!("  variables: {}", shown(&names.join(", ")));
    for (i, e) in sys.equations().iter().enumerate() {
        say!("  f{} = {}", i + 1, shown(&e.with_names(names).to_string()));
    }
    for g in sys.boundary() {
        say!(
            "  boundary: {} >= 0",
            shown(&g.with_names(names).to_string())
        );
    }
    let t = p.triangulation.build(d)?;
    say!(
        "triangulation: {} in R^{d}, longest edge {}",
        t.kind().name(),
        num(t.edge())
    );
    for s in &p.seeds {
        let mut f = vec![0.0; k];
        sys.eval_batch(s, &mut f);
        let norm = f.iter().map(|v| v * v).sum::<f64>().sqrt();
        let simplex = t.locate(s)?;
        say!(
            "seed {s:?}: |f| = {norm:.1e}, in the {}-simplex {simplex}",
            simplex.dim()
        );
    }
    for (what, prog) in [("f", sys.values()), ("Jacobian", sys.jacobian_program())] {
        for prec in [Precision::F32, Precision::F64] {
            let src = eval_shader(prog, prec)?;
            say!(
                "WGSL for {what} ({}): {} lines, validated by naga",
                prec.ty(),
                src.lines().count()
            );
        }
    }
    Ok(())
}
