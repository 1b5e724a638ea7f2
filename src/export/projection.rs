//! Views of R^d in R^3 for files and pictures: chosen coordinates, or the three principal
//! axes of the vertices (PCA). The choice is written into every file that uses it.

use crate::error::{Error, Result};

/// How to map R^d to R^3.
#[derive(Clone, Debug, PartialEq, Default)]
pub enum Projection {
    /// The coordinates themselves for d <= 3 (padded with zeros), PCA above.
    #[default]
    Auto,
    /// These coordinates (0-based; up to 3, missing ones are 0).
    Axes(Vec<usize>),
    /// The three principal axes of the points, centred on their mean.
    Pca,
}

impl Projection {
    /// Parses `pca`, `auto`, or a list of 1-based coordinates such as `1,2,4` or `x1,x2,x4`.
    pub fn parse(s: &str, d: usize) -> Result<Self> {
        if s.len() > 64 || s.chars().any(char::is_control) {
            return Err(Error::Spec(format!(
                "projection {:?}...: expected pca, auto, or up to 3 coordinates such as 1,2,3",
                s.chars().take(24).collect::<String>()
            )));
        }
        match s.trim() {
            "auto" => return Ok(Projection::Auto),
            "pca" => return Ok(Projection::Pca),
            _ => {}
        }
        let axes = s
            .split(',')
            .map(|t| {
                let t = t.trim();
                let t = t.strip_prefix('x').unwrap_or(t);
                match t.parse::<usize>() {
                    Ok(i) if (1..=d).contains(&i) => Ok(i - 1),
                    _ => Err(Error::Spec(format!(
                        "projection '{s}': expected pca, auto, or up to 3 coordinates from 1 to \
                         {d} such as 1,2,3"
                    ))),
                }
            })
            .collect::<Result<Vec<_>>>()?;
        if axes.is_empty() || axes.len() > 3 {
            return Err(Error::Spec(format!(
                "projection '{s}': give 1 to 3 coordinates"
            )));
        }
        if (1..axes.len()).any(|i| axes[..i].contains(&axes[i])) {
            return Err(Error::Spec(format!(
                "projection '{s}': a coordinate is repeated; give distinct ones such as 1,2,3"
            )));
        }
        Ok(Projection::Axes(axes))
    }
}

/// A projection fixed for one set of points: x -> A (x - c), A being 3 x d.
#[derive(Clone, Debug)]
pub struct View {
    /// d.
    pub dim: usize,
    /// The 3 x d matrix, row-major.
    pub matrix: Vec<f64>,
    /// The centre c.
    pub centre: Vec<f64>,
    /// A one-line description, written into files.
    pub description: String,
}

impl View {
    /// The view of `points` (d per point) for `p`.
    pub fn new(p: &Projection, points: &[f64], d: usize) -> Self {
        let axes = |ax: &[usize]| {
            let mut matrix = vec![0.0; 3 * d];
            for (r, &a) in ax.iter().enumerate() {
                matrix[r * d + a] = 1.0;
            }
            let names: Vec<String> = ax.iter().map(|a| format!("x{}", a + 1)).collect();
            View {
                dim: d,
                matrix,
                centre: vec![0.0; d],
                description: format!("coordinates {}", names.join(", ")),
            }
        };
        match p {
            Projection::Auto if d <= 3 => axes(&(0..d).collect::<Vec<_>>()),
            Projection::Axes(ax) => axes(ax),
            _ => pca(points, d),
        }
    }

    /// The image of `x` in R^3.
    pub fn apply(&self, x: &[f64]) -> [f64; 3] {
        let mut out = [0.0; 3];
        for (r, o) in out.iter_mut().enumerate() {
            *o = (0..self.dim)
                .map(|i| self.matrix[r * self.dim + i] * (x[i] - self.centre[i]))
                .sum();
        }
        out
    }

    /// The images of all `points` (d each), 3 per point.
    pub fn apply_all(&self, points: &[f64]) -> Vec<f64> {
        points
            .chunks_exact(self.dim.max(1))
            .flat_map(|x| self.apply(x))
            .collect()
    }
}

fn pca(points: &[f64], d: usize) -> View {
    let (centre, vectors) = super::section::principal_axes(points, d);
    let mut matrix = vec![0.0; 3 * d];
    for r in 0..3.min(d) {
        let row = &vectors[r * d..(r + 1) * d];
        // Sign convention: the largest entry is positive (the same view every run).
        let big = row
            .iter()
            .copied()
            .max_by(|a, b| a.abs().total_cmp(&b.abs()))
            .unwrap_or(1.0);
        let s = if big < 0.0 { -1.0 } else { 1.0 };
        for i in 0..d {
            matrix[r * d + i] = s * row[i];
        }
    }
    let fmt = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:.6}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    let description = format!(
        "pca: centre [{}], axes [{}] [{}] [{}]",
        fmt(&centre),
        fmt(&matrix[..d]),
        fmt(&matrix[d..2 * d]),
        fmt(&matrix[2 * d..])
    );
    View {
        dim: d,
        matrix,
        centre,
        description,
    }
}
