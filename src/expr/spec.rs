//! Spec files (TOML): the manifold, its seeds, box and triangulation. Unknown keys are errors.

use std::collections::BTreeMap;

use serde::Deserialize;

use super::parser::Scope;
use super::system::{newton_project, EquationSystem};
use crate::error::{check_finite_in, Error, Result};
use crate::triangulation::{check_dim, Offset, Triangulation, TriangulationKind};

/// ```
/// use isomesh::expr::Spec;
///
/// let spec = Spec::from_toml(
///     "variables = [\"u\", \"v\", \"w\"]\n\
///      equations = [\"u^2 + v^2 + w^2 - r^2\"]\n\
///      parameters = { r = 2.0 }\n\
///      seeds = [[2, 0, 0]]\n",
/// )?;
/// let p = spec.resolve("ball")?;
/// assert_eq!(p.dim(), 3);
/// assert_eq!(p.system.names(), ["u", "v", "w"]);
/// // A spec naming an unknown variable is an error that says where.
/// let bad = Spec::from_toml("ambient_dim = 2\nequations = [\"x1 + q\"]\n")?;
/// assert!(bad.resolve("bad").unwrap_err().to_string().contains("line 2"));
/// # Ok::<(), isomesh::Error>(())
/// ```
///
/// A spec file as written.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Spec {
    /// d; a spec file may leave it out when `variables` names the coordinates (it reads
    /// as [`INFER_DIM`]).
    #[serde(default = "infer_dim", deserialize_with = "written_dim")]
    pub ambient_dim: usize,
    /// Variable names (default x1..xd, plus x y z w when d <= 4).
    pub variables: Option<Vec<String>>,
    /// Named constants usable in equations.
    #[serde(default)]
    pub parameters: BTreeMap<String, f64>,
    /// f_1..f_k, with k < d.
    pub equations: Vec<String>,
    /// Inequalities g(x) >= 0 bounding the manifold.
    #[serde(default)]
    pub boundary: Vec<String>,
    /// Points near M (Newton-projected before use).
    #[serde(default)]
    pub seeds: Vec<Vec<f64>>,
    /// Per-coordinate [lo, hi] box, for seed search, scans and non-compact manifolds.
    #[serde(rename = "box", default, deserialize_with = "box_rows")]
    pub bbox: Option<Vec<[f64; 2]>>,
    /// Triangulation settings.
    pub triangulation: Option<TriangulationSpec>,
    /// Where each equation's text starts in the spec file (1-based line and column), when it
    /// is written without escapes; filled by [`Spec::from_toml`].
    #[serde(skip)]
    pub equation_at: Vec<Option<(usize, usize)>>,
    /// The same for the boundary inequalities.
    #[serde(skip)]
    pub boundary_at: Vec<Option<(usize, usize)>>,
}

/// The string literals of `equations` and `boundary`, with their places in the file.
#[derive(Deserialize)]
struct Literals {
    #[serde(default)]
    equations: Vec<toml::Spanned<String>>,
    #[serde(default)]
    boundary: Vec<toml::Spanned<String>>,
}

/// Line and column in `text` where the value of the string literal `lit` starts, when its
/// characters are the value's own (no escapes).
fn content_start(text: &str, lit: &toml::Spanned<String>) -> Option<(usize, usize)> {
    let span = lit.span();
    let raw = text.get(span.clone())?;
    let (open, close) = if raw.starts_with("\"\"\"") || raw.starts_with("'''") {
        let skip = if raw[3..].starts_with("\r\n") {
            5
        } else if raw[3..].starts_with('\n') {
            4
        } else {
            3
        };
        (skip, 3)
    } else {
        (1, 1)
    };
    let inner = raw.get(open..raw.len().checked_sub(close)?)?;
    if inner != lit.get_ref() {
        return None;
    }
    let before = &text[..span.start + open];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    Some((line, column))
}

/// Box rows of exactly two numbers (serde alone would ignore extra ones).
fn box_rows<'de, D: serde::Deserializer<'de>>(
    de: D,
) -> std::result::Result<Option<Vec<[f64; 2]>>, D::Error> {
    let rows: Option<Vec<Vec<f64>>> = Deserialize::deserialize(de)?;
    rows.map(|rows| {
        rows.iter()
            .enumerate()
            .map(|(i, r)| match r[..] {
                [lo, hi] => Ok([lo, hi]),
                _ => Err(serde::de::Error::custom(format!(
                    "box row {} has {} numbers: give [lo, hi]",
                    i + 1,
                    r.len()
                ))),
            })
            .collect()
    })
    .transpose()
}

/// `ambient_dim` of a spec that leaves it out: the count of `variables`.
pub const INFER_DIM: usize = usize::MAX;

fn infer_dim() -> usize {
    INFER_DIM
}

/// `ambient_dim` as written; the one value that would read as left out (the sentinel
/// [`INFER_DIM`]) is refused here.
fn written_dim<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<usize, D::Error> {
    let v = u64::deserialize(d)?;
    match usize::try_from(v) {
        // Too large values are refused by `resolve` as such (`Error::Dimension`).
        Ok(n) if n != INFER_DIM => Ok(n),
        _ => Err(serde::de::Error::custom(format!(
            "ambient_dim = {v} is not supported: isomesh handles 1 to {}",
            crate::MAX_DIM
        ))),
    }
}

/// The `[triangulation]` table.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TriangulationSpec {
    /// "coxeter" (default), "freudenthal" or "custom".
    pub kind: Option<String>,
    /// Longest edge of a d-simplex.
    pub edge: Option<f64>,
    /// Seed of the random offset (default 1).
    pub offset_seed: Option<u64>,
    /// An explicit offset instead.
    pub offset: Option<Vec<f64>>,
    /// kind = "custom": vertex = matrix * v + offset.
    pub matrix: Option<Vec<Vec<f64>>>,
    /// Seed of the random rotation (default 1: the lattice is put in generic position, so
    /// that its structure does not line up with coordinate-aligned equations).
    pub rotation_seed: Option<u64>,
    /// `false` keeps the lattice unrotated (the default for kind = "custom").
    pub rotate: Option<bool>,
}

/// Default rotation seed for coxeter and freudenthal triangulations.
pub const DEFAULT_ROTATION_SEED: u64 = 1;

/// Default edge when neither spec nor flags give one.
pub const DEFAULT_EDGE: f64 = 0.1;

impl TriangulationSpec {
    /// Builds the triangulation of R^d this table describes.
    pub fn build(&self, d: usize) -> Result<Triangulation> {
        let kind: TriangulationKind = self.kind.as_deref().unwrap_or("coxeter").parse()?;
        let mut b = match (kind, &self.matrix) {
            (TriangulationKind::Custom, Some(m)) => Triangulation::custom(m.clone()),
            (TriangulationKind::Custom, None) => {
                return Err(Error::Spec("kind = \"custom\" needs a matrix".into()))
            }
            (_, Some(_)) => {
                return Err(Error::Spec(
                    "a matrix is only allowed with kind = \"custom\"".into(),
                ))
            }
            (k, None) => Triangulation::builder(d, k).edge(self.edge.unwrap_or(DEFAULT_EDGE)),
        };
        if kind == TriangulationKind::Custom && self.edge.is_some() {
            return Err(Error::Spec(
                "kind = \"custom\" takes its scale from the matrix: remove edge".into(),
            ));
        }
        b = match (&self.offset, self.offset_seed) {
            (Some(_), Some(_)) => {
                return Err(Error::Spec("give offset or offset_seed, not both".into()))
            }
            (Some(o), None) => b.offset(o.clone()),
            (None, Some(s)) => b.offset_seed(s),
            (None, None) if kind == TriangulationKind::Custom => b.offset_rule(Offset::Zero),
            (None, None) => b,
        };
        let rotate = self.rotate.unwrap_or(kind != TriangulationKind::Custom);
        match (rotate, self.rotation_seed) {
            (false, Some(_)) => {
                return Err(Error::Spec(
                    "rotate = false and a rotation_seed: give one or the other".into(),
                ))
            }
            (true, s) => b = b.rotation_seed(s.unwrap_or(DEFAULT_ROTATION_SEED)),
            (false, None) => {}
        }
        let t = b.build()?;
        if t.dim() != d {
            return Err(Error::DimensionMismatch(format!(
                "the triangulation matrix is {}-dimensional, ambient_dim is {d}",
                t.dim()
            )));
        }
        Ok(t)
    }
}

/// A resolved problem: the function, where to start, where to look, how to triangulate.
#[derive(Clone, Debug)]
pub struct Problem {
    /// A short name (preset name or spec file stem).
    pub name: String,
    /// f (and boundary).
    pub system: EquationSystem,
    /// Seeds on M (already projected).
    pub seeds: Vec<Vec<f64>>,
    /// The box, if any.
    pub bbox: Option<Vec<[f64; 2]>>,
    /// Triangulation settings.
    pub triangulation: TriangulationSpec,
}

impl Problem {
    /// Ambient dimension.
    pub fn dim(&self) -> usize {
        self.system.names().len()
    }
}

/// Checks a box: d rows, finite, lo < hi, and a width that is a finite number too.
pub fn check_box(bbox: &[[f64; 2]], d: usize) -> Result<()> {
    if bbox.len() != d {
        return Err(Error::DimensionMismatch(format!(
            "the box has {} rows, the ambient dimension is {d}",
            bbox.len()
        )));
    }
    for (i, [lo, hi]) in bbox.iter().enumerate() {
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(Error::Spec(format!(
                "box row {}: [{lo}, {hi}] must be finite with lo < hi",
                i + 1
            )));
        }
        if !(hi - lo).is_finite() {
            return Err(Error::Spec(format!(
                "box row {}: [{lo:e}, {hi:e}] is wider than the largest number (about 1.8e308)",
                i + 1
            )));
        }
    }
    Ok(())
}

/// The longest spec file read: far beyond any system of equations written by hand or by a
/// program (a sum of 10^6 terms takes about 20 MiB).
pub const MAX_SPEC_BYTES: u64 = 64 << 20;

/// Heap the TOML reader needs at its peak: about 8 bytes per byte of text (measured on a spec
/// holding one long equation), plus about 380 per value in an array (200,000 seed points in
/// 5.6 MB of text took 307 MB: each number becomes a value with its span); a little more is
/// asked for. Values are counted by their separators, `[` and `,`.
const TOML_BYTES_PER_BYTE: u64 = 10;
/// See [`TOML_BYTES_PER_BYTE`].
const TOML_BYTES_PER_VALUE: u64 = 400;

/// The heap [`Spec::from_toml`] asks for before it reads `text`: the separators of values
/// are counted outside strings (an equation's commas are text, not values).
fn toml_bytes(text: &str) -> (u64, u64) {
    let (mut quote, mut escaped, mut values) = (None, false, 0u64);
    for b in text.bytes() {
        match quote {
            Some(_) if escaped => escaped = false,
            Some(q) if b == b'\\' && q == b'"' => escaped = true,
            Some(q) if b == q => quote = None,
            Some(_) => {}
            None if b == b'"' || b == b'\'' => quote = Some(b),
            None => values += (b == b',' || b == b'[') as u64,
        }
    }
    (
        TOML_BYTES_PER_BYTE * text.len() as u64 + TOML_BYTES_PER_VALUE * values,
        values,
    )
}

impl Spec {
    /// Parses TOML text.
    pub fn from_toml(text: &str) -> Result<Spec> {
        let (bytes, values) = toml_bytes(text);
        // Mostly array values: seed points (or a box, a matrix) rather than equations.
        let advice = if values * TOML_BYTES_PER_VALUE > bytes / 2 {
            "give fewer seed points (each number in a spec's arrays takes about 400 bytes \
             while it is read)"
        } else {
            "write smaller equations"
        };
        crate::memory::ensure_room("reading the spec", bytes, advice)?;
        let mut spec: Spec = toml::from_str(text).map_err(|e| Error::Spec(e.to_string()))?;
        if let Ok(lits) = toml::from_str::<Literals>(text) {
            let at =
                |l: &[toml::Spanned<String>]| l.iter().map(|s| content_start(text, s)).collect();
            spec.equation_at = at(&lits.equations);
            spec.boundary_at = at(&lits.boundary);
        }
        Ok(spec)
    }

    /// Reads and parses a spec file of at most [`MAX_SPEC_BYTES`] (a device or a pipe that
    /// never ends, such as /dev/zero, is read only that far).
    pub fn from_file(path: &std::path::Path) -> Result<Spec> {
        use std::io::Read;
        let io = |e| Error::io(path.display(), e);
        if let Ok(meta) = std::fs::metadata(path) {
            crate::memory::ensure_room(
                "reading the spec file",
                meta.len().min(MAX_SPEC_BYTES),
                "write a shorter spec",
            )?;
        }
        let mut bytes = Vec::new();
        std::fs::File::open(path)
            .map_err(io)?
            .take(MAX_SPEC_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(io)?;
        if bytes.len() as u64 > MAX_SPEC_BYTES {
            return Err(Error::Spec(format!(
                "{}: more than {} MiB; a spec file is at most that long",
                path.display(),
                MAX_SPEC_BYTES >> 20
            )));
        }
        let text = String::from_utf8(bytes)
            .map_err(|_| Error::Spec(format!("{}: not UTF-8 text", path.display())))?;
        Self::from_toml(&text)
    }

    /// Validates everything and compiles the equations; seeds are Newton-projected.
    pub fn resolve(&self, name: &str) -> Result<Problem> {
        let d = match (self.ambient_dim, &self.variables) {
            (INFER_DIM, Some(names)) => names.len(),
            (INFER_DIM, None) => {
                return Err(Error::Spec(
                    "ambient_dim is missing: give it, or name the coordinates in `variables`"
                        .into(),
                ))
            }
            (d, _) => d,
        };
        check_dim(d)?;
        let mut scope = match &self.variables {
            Some(names) => {
                if names.len() != d {
                    return Err(Error::DimensionMismatch(format!(
                        "{} variable names for ambient_dim = {d}",
                        names.len()
                    )));
                }
                Scope::with_names(names)?
            }
            None => Scope::new(d),
        };
        for (n, v) in &self.parameters {
            scope.add_parameter(n, *v)?;
        }
        let eqs: Vec<&str> = self.equations.iter().map(String::as_str).collect();
        let bnd: Vec<&str> = self.boundary.iter().map(String::as_str).collect();
        let system = EquationSystem::parse_with(&scope, &eqs, &bnd, |mut e, what, i| {
            let at = if what == "equation" {
                &self.equation_at
            } else {
                &self.boundary_at
            };
            match at.get(i).copied().flatten() {
                Some((line, column)) if e.line > 0 => {
                    if e.line == 1 {
                        e.column += column - 1;
                    }
                    e.line += line - 1;
                    e.within(format!("{what} {} of the spec file", i + 1))
                }
                Some(_) => e.within(format!("{what} {} of the spec file", i + 1)),
                None => e.within(format!("{what} {}, counted within its text", i + 1)),
            }
        })?;
        if let Some(b) = &self.bbox {
            check_box(b, d)?;
        }
        let mut seeds = Vec::new();
        for (i, s) in self.seeds.iter().enumerate() {
            if s.len() != d {
                return Err(Error::DimensionMismatch(format!(
                    "seed {} has {} coordinates, ambient_dim is {d}",
                    i + 1,
                    s.len()
                )));
            }
            check_finite_in(s, &format!("seed {}", i + 1))?;
            seeds.push(newton_project(&system, s, 1e-12)?);
        }
        let triangulation = self.triangulation.clone().unwrap_or_default();
        triangulation.build(d)?;
        Ok(Problem {
            name: name.to_string(),
            system,
            seeds,
            bbox: self.bbox.clone(),
            triangulation,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_reading_estimate_counts_values_outside_strings() {
        let text = |body: &str| 10 * body.len() as u64;
        // Commas of an equation (and an escaped quote before them) are text.
        let eq = r#"equations = ["max(x1, x2) - \"a, b\""]"#;
        assert_eq!(toml_bytes(eq), (text(eq) + 400, 1));
        let lit = "equations = ['atan2(x1, x2)', 'x3']";
        assert_eq!(toml_bytes(lit), (text(lit) + 2 * 400, 2));
        // A seed point: its array and two commas, and the list's comma and bracket.
        let seeds = "seeds = [[1, 0, 0],]";
        assert_eq!(toml_bytes(seeds), (text(seeds) + 5 * 400, 5));
    }
}
