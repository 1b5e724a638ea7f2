//! Built-in manifolds, written in the equation language as [`Spec`]s, each with a seed on it.

use std::collections::BTreeMap;

use super::spec::{Problem, Spec, TriangulationSpec};
use crate::error::{Error, Result};

/// A preset's name, what it is, and its parameters with their defaults.
#[derive(Clone, Copy, Debug)]
pub struct PresetInfo {
    /// The name used by `--preset`.
    pub name: &'static str,
    /// One line for people.
    pub about: &'static str,
    /// Parameters and defaults (`d`, `m` are dimensions; the rest are lengths).
    pub params: &'static [(&'static str, f64)],
}

/// Every preset.
pub const PRESETS: &[PresetInfo] = &[
    PresetInfo {
        name: "circle",
        about: "circle of radius r in R^2",
        params: &[("r", 1.0), ("edge", 0.05)],
    },
    PresetInfo {
        name: "sphere",
        about: "sphere S^m of radius r in R^d (x_{m+2}..x_d = 0)",
        params: &[("m", 2.0), ("d", 3.0), ("r", 1.0), ("edge", 0.1)],
    },
    PresetInfo {
        name: "torus",
        about: "torus of radii R (centre circle) and r (tube) in R^3",
        params: &[("R", 1.0), ("r", 0.4), ("edge", 0.05)],
    },
    PresetInfo {
        name: "chair",
        about: "the genus-3 'chair' surface (Boissonnat, Kachanovich, Wintraecken 2019, Figure 6), embedded in R^d",
        params: &[("a", 0.8), ("b", 0.4), ("d", 3.0), ("edge", 0.0707)],
    },
    PresetInfo {
        name: "flat-torus",
        about: "flat torus S^1 x S^1 in R^4 (x1^2+x2^2 = 1, x3^2+x4^2 = 1), embedded in R^d",
        params: &[("d", 4.0), ("edge", 0.0775)],
    },
    PresetInfo {
        name: "3-torus",
        about: "3-torus S^1 x S^1 x S^1 in R^6 with radii a, b, c (Castelo et al., GCMH, 2022)",
        params: &[("a", 0.5), ("b", 1.0), ("c", 2.0), ("edge", 0.5555)],
    },
    PresetInfo {
        name: "complex-cosine",
        about: "the graph z = cos(w) in C^2 = R^4 (Castelo et al., GCMH, 2022), inside a box",
        params: &[("edge", 0.1)],
    },
    PresetInfo {
        name: "bagel-klein",
        about: "a disk cut from the Bagel Klein bottle in R^5 (Castelo et al., GCMH, 2022, Figure 1): a graph over (s, t) in a box, so it has a boundary",
        params: &[("a", 3.0), ("edge", 0.15)],
    },
    PresetInfo {
        name: "cut-flat-torus",
        about: "flat torus in R^4 cut by the ball (x1-1)^2+x2^2+(x3-1)^2+x4^2 <= 4 (Boissonnat, Kachanovich, Wintraecken 2019, Figure 8)",
        params: &[("edge", 0.15)],
    },
];

/// The names of all presets.
pub fn preset_names() -> Vec<&'static str> {
    PRESETS.iter().map(|p| p.name).collect()
}

fn dim_param(params: &BTreeMap<String, f64>, name: &str) -> Result<usize> {
    let v = params[name];
    if v.fract() != 0.0 || !(1.0..=63.0).contains(&v) {
        return Err(Error::Spec(format!(
            "parameter {name} = {v} must be an integer from 1 to 63"
        )));
    }
    Ok(v as usize)
}

/// `x_{from}..x_{to}` as equations x_i = 0.
fn zero_coords(from: usize, to: usize) -> Vec<String> {
    (from..=to).map(|i| format!("x{i}")).collect()
}

/// The spec of preset `name`, with parameters overridden by `overrides`.
pub fn preset_spec(name: &str, overrides: &[(String, f64)]) -> Result<Spec> {
    let info = PRESETS.iter().find(|p| p.name == name).ok_or_else(|| {
        Error::Spec(format!(
            "unknown preset '{name}': the presets are {}",
            preset_names().join(", ")
        ))
    })?;
    let mut params: BTreeMap<String, f64> = info
        .params
        .iter()
        .map(|(n, v)| (n.to_string(), *v))
        .collect();
    for (n, v) in overrides {
        if !params.contains_key(n) {
            return Err(Error::Usage(format!(
                "preset '{name}' has no parameter '{n}' (it has {})",
                info.params
                    .iter()
                    .map(|p| p.0)
                    .collect::<Vec<_>>()
                    .join(", ")
            )));
        }
        if !v.is_finite() {
            return Err(Error::Spec(format!("parameter {n} = {v} is not finite")));
        }
        params.insert(n.clone(), *v);
    }
    let edge = params.remove("edge");
    let mut spec = Spec {
        triangulation: Some(TriangulationSpec {
            edge,
            ..Default::default()
        }),
        ..Default::default()
    };
    let lengths = |keys: &[&str]| -> BTreeMap<String, f64> {
        keys.iter().map(|k| (k.to_string(), params[*k])).collect()
    };
    match name {
        "circle" => {
            spec.ambient_dim = 2;
            spec.parameters = lengths(&["r"]);
            spec.equations = vec!["x^2 + y^2 - r^2".into()];
            spec.seeds = vec![vec![params["r"], 0.0]];
        }
        "sphere" => {
            let (m, d) = (dim_param(&params, "m")?, dim_param(&params, "d")?);
            if m >= d {
                return Err(Error::Spec(format!(
                    "sphere: m = {m} must be below d = {d}"
                )));
            }
            spec.ambient_dim = d;
            spec.variables = Some((1..=d).map(|i| format!("x{i}")).collect());
            spec.parameters = lengths(&["r"]);
            let sum: Vec<String> = (1..=m + 1).map(|i| format!("x{i}^2")).collect();
            spec.equations = vec![format!("{} - r^2", sum.join(" + "))];
            spec.equations.extend(zero_coords(m + 2, d));
            let mut seed = vec![0.0; d];
            seed[0] = params["r"];
            spec.seeds = vec![seed];
        }
        "torus" => {
            spec.ambient_dim = 3;
            spec.parameters = lengths(&["R", "r"]);
            spec.equations = vec!["(sqrt(x^2 + y^2) - R)^2 + z^2 - r^2".into()];
            spec.seeds = vec![vec![params["R"] + params["r"], 0.0, 0.0]];
        }
        "chair" => {
            let d = dim_param(&params, "d")?;
            if d < 3 {
                return Err(Error::Spec("chair: d must be at least 3".into()));
            }
            spec.ambient_dim = d;
            spec.variables = Some((1..=d).map(|i| format!("x{i}")).collect());
            spec.parameters = lengths(&["a", "b"]);
            spec.equations = vec![
                "(x1^2 + x2^2 + x3^2 - a)^2 - b*((x3 - 1)^2 - 2*x1^2)*((x3 + 1)^2 - 2*x2^2)".into(),
            ];
            spec.equations.extend(zero_coords(4, d));
            let mut seed = vec![0.0; d];
            seed[2] = 0.675;
            spec.seeds = vec![seed];
        }
        "flat-torus" => {
            let d = dim_param(&params, "d")?;
            if d < 4 {
                return Err(Error::Spec("flat-torus: d must be at least 4".into()));
            }
            spec.ambient_dim = d;
            spec.variables = Some((1..=d).map(|i| format!("x{i}")).collect());
            spec.equations = vec!["x1^2 + x2^2 - 1".into(), "x3^2 + x4^2 - 1".into()];
            spec.equations.extend(zero_coords(5, d));
            let mut seed = vec![0.0; d];
            seed[0] = 1.0;
            seed[2] = 1.0;
            spec.seeds = vec![seed];
        }
        "3-torus" => {
            spec.ambient_dim = 6;
            spec.parameters = lengths(&["a", "b", "c"]);
            spec.equations = vec![
                "x1^2 + x2^2 - a^2".into(),
                "x3^2 + x4^2 - b^2".into(),
                "x5^2 + x6^2 - c^2".into(),
            ];
            spec.seeds = vec![vec![params["a"], 0.0, params["b"], 0.0, params["c"], 0.0]];
        }
        "complex-cosine" => {
            // z = x1 + i x2, w = x3 + i x4; cos(w) = cos x3 cosh x4 - i sin x3 sinh x4.
            spec.ambient_dim = 4;
            spec.equations = vec![
                "x1 - cos(x3)*cosh(x4)".into(),
                "x2 + sin(x3)*sinh(x4)".into(),
            ];
            spec.bbox = Some(vec![[-2.0, 2.0], [-2.0, 2.0], [-3.0, 3.0], [-1.0, 1.0]]);
            spec.seeds = vec![vec![1.0, 0.0, 0.0, 0.0]];
        }
        "bagel-klein" => {
            spec.ambient_dim = 5;
            spec.variables = Some(["x", "y", "z", "s", "t"].map(String::from).to_vec());
            spec.parameters = lengths(&["a"]);
            let ring = "(a + cos(s/2)*sin(t) - sin(s/2)*sin(2*t))";
            spec.equations = vec![
                format!("cos(s)*{ring} - x"),
                format!("sin(s)*{ring} - y"),
                "sin(s/2)*sin(t) + cos(s/2)*sin(2*t) - z".into(),
            ];
            let a = params["a"];
            spec.bbox = Some(vec![
                [-a - 1.5, a + 1.5],
                [-a - 1.5, a + 1.5],
                [-1.5, 1.5],
                [-3.0, 3.0],
                [-3.0, 3.0],
            ]);
            spec.seeds = vec![vec![a, 0.0, 0.0, 0.0, 0.0]];
        }
        "cut-flat-torus" => {
            spec.ambient_dim = 4;
            spec.equations = vec!["x1^2 + x2^2 - 1".into(), "x3^2 + x4^2 - 1".into()];
            spec.boundary = vec!["4 - (x1 - 1)^2 - x2^2 - (x3 - 1)^2 - x4^2".into()];
            spec.seeds = vec![vec![1.0, 0.0, 1.0, 0.0]];
        }
        _ => unreachable!("every name in PRESETS has a case"),
    }
    Ok(spec)
}

/// Preset `name` resolved: equations compiled, seed projected onto M.
pub fn preset(name: &str, overrides: &[(String, f64)]) -> Result<Problem> {
    preset_spec(name, overrides)?.resolve(name)
}
