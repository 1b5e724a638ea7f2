//! Where the lattice sits in R^d: Freudenthal-Kuhn, Coxeter A~d or a user matrix, with scale,
//! offset and an optional seeded rotation. A lattice point u in Z^d has the ambient position
//! x = b + s * R * Lambda * u; point location inverts this map and applies Lemma 10.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use super::simplex::{check_dim, Simplex};
use crate::error::{check_finite, check_finite_in, Error, Result};
use crate::linalg::{mat_mul, mat_vec, Lu};

/// Which triangulation of R^d.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TriangulationKind {
    /// Coxeter A~d: every d-simplex congruent, Delaunay, thick. The default.
    Coxeter,
    /// Freudenthal-Kuhn: the unit cubes of Z^d cut into d! simplices each.
    Freudenthal,
    /// Any CFK triangulation: vertex = matrix * v + offset for v in Z^d.
    Custom,
}

impl TriangulationKind {
    /// The name used in specs, flags and reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Coxeter => "coxeter",
            Self::Freudenthal => "freudenthal",
            Self::Custom => "custom",
        }
    }
}

impl std::str::FromStr for TriangulationKind {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "coxeter" => Ok(Self::Coxeter),
            "freudenthal" | "fk" | "kuhn" => Ok(Self::Freudenthal),
            "custom" => Ok(Self::Custom),
            other => Err(Error::Triangulation(format!(
                "unknown triangulation '{other}': expected coxeter, freudenthal or custom"
            ))),
        }
    }
}

/// How the lattice is translated.
#[derive(Clone, Debug, PartialEq)]
pub enum Offset {
    /// No translation.
    Zero,
    /// A uniformly random translation within one lattice cell, from this seed.
    Seeded(u64),
    /// This translation.
    Given(Vec<f64>),
}

/// The linear part of the map, with a fast path for the unrotated FK and Coxeter lattices.
#[derive(Clone, Debug)]
enum Linear {
    /// x = s * u.
    Identity,
    /// x = s * Lambda * u with the sparse Coxeter Lambda.
    Coxeter,
    /// x = A * u, A dense (rotation or custom matrix), with its factorisation.
    Dense { a: Vec<f64>, lu: Lu },
}

/// A triangulation of R^d: the permutahedral combinatorics of [`Simplex`] plus the geometry
/// that places lattice points in R^d. Never stored: every simplex is computed on demand.
///
/// ```
/// use isomesh::triangulation::Triangulation;
///
/// let t = Triangulation::coxeter(3).edge(0.1).build()?;
/// // Point location: the 3-simplex holding a point, then its faces and cofaces, computed
/// // from its permutahedral representation.
/// let s = t.locate(&[0.31, -0.2, 0.05])?;
/// assert_eq!(s.dim(), 3);
/// assert_eq!(s.facets().len(), 4);
/// let edge = &s.faces(1)?[0];
/// assert!(edge.cofaces(3)?.contains(&s));
/// # Ok::<(), isomesh::Error>(())
/// ```
#[derive(Clone, Debug)]
pub struct Triangulation {
    d: usize,
    kind: TriangulationKind,
    edge: f64,
    scale: f64,
    offset: Vec<f64>,
    linear: Linear,
    /// 1/sqrt(j^2 + j) for j = 1..d (Coxeter basis norms).
    coxeter_c: Vec<f64>,
}

/// The edge lengths a triangulation takes: far inside f64's range, so that lattice
/// coordinates, their inverses and squared lengths stay finite and normal.
pub const EDGE_RANGE: std::ops::RangeInclusive<f64> = 1e-100..=1e100;

/// Builds a [`Triangulation`]; start from [`Triangulation::coxeter`],
/// [`Triangulation::freudenthal`] or [`Triangulation::custom`].
#[derive(Clone, Debug)]
pub struct TriangulationBuilder {
    d: usize,
    kind: TriangulationKind,
    edge: Option<f64>,
    offset: Offset,
    rotation_seed: Option<u64>,
    matrix: Option<Vec<Vec<f64>>>,
}

/// Longest edge of a d-simplex for the lattice map `a` (row-major d x d): the longest A e_S
/// over non-empty S of {1..d} (every edge is +-A e_S); for d > 16, the upper bound
/// sum_j |A e_j|.
fn longest_edge_of(a: &[f64], d: usize) -> f64 {
    let col = |j: usize| -> Vec<f64> { (0..d).map(|i| a[i * d + j]).collect() };
    if d > 16 {
        return (0..d)
            .map(|j| col(j).iter().map(|v| v * v).sum::<f64>().sqrt())
            .sum();
    }
    let mut best: f64 = 0.0;
    for s in 1usize..(1 << d) {
        let mut len2 = 0.0;
        for i in 0..d {
            let x: f64 = (0..d)
                .filter(|j| s >> j & 1 == 1)
                .map(|j| a[i * d + j])
                .sum();
            len2 += x * x;
        }
        best = best.max(len2.sqrt());
    }
    best
}

/// Longest edge of a d-simplex of the unscaled lattice map.
fn unit_longest_edge(kind: TriangulationKind, d: usize) -> f64 {
    match kind {
        // Edge sum_{j in S} e_j has squared length |S|(d+1-|S|)/(d+1): largest at |S| = (d+1)/2.
        TriangulationKind::Coxeter => {
            let a = d.div_ceil(2);
            ((a * (d + 1 - a)) as f64 / (d + 1) as f64).sqrt()
        }
        // The main diagonal of the unit cube.
        TriangulationKind::Freudenthal => (d as f64).sqrt(),
        TriangulationKind::Custom => 1.0,
    }
}

/// A Haar-random orthogonal d x d matrix (row-major) from a seed: Gram-Schmidt on Gaussians.
pub fn random_rotation(d: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut q = vec![0.0; d * d];
    let mut row = vec![0.0; d];
    for r in 0..d {
        loop {
            for x in row.iter_mut() {
                *x = rng.sample(StandardNormal);
            }
            for p in 0..r {
                let dot: f64 = (0..d).map(|c| row[c] * q[p * d + c]).sum();
                for c in 0..d {
                    row[c] -= dot * q[p * d + c];
                }
            }
            let norm = row.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm > 1e-8 {
                for c in 0..d {
                    q[r * d + c] = row[c] / norm;
                }
                break;
            }
        }
    }
    q
}

impl TriangulationBuilder {
    /// Longest edge of a d-simplex, in ambient units (Coxeter and Freudenthal-Kuhn).
    pub fn edge(mut self, edge: f64) -> Self {
        self.edge = Some(edge);
        self
    }

    /// Translation by a uniformly random vector of one lattice cell, drawn from `seed`.
    pub fn offset_seed(mut self, seed: u64) -> Self {
        self.offset = Offset::Seeded(seed);
        self
    }

    /// Translation by `b`.
    pub fn offset(mut self, b: Vec<f64>) -> Self {
        self.offset = Offset::Given(b);
        self
    }

    /// The offset rule, whichever variant.
    pub fn offset_rule(mut self, offset: Offset) -> Self {
        self.offset = offset;
        self
    }

    /// Rotation by a random orthogonal matrix drawn from `seed`.
    pub fn rotation_seed(mut self, seed: u64) -> Self {
        self.rotation_seed = Some(seed);
        self
    }

    /// Builds the triangulation, checking every input.
    pub fn build(self) -> Result<Triangulation> {
        let d = self.d;
        check_dim(d)?;
        let kind = self.kind;
        let base_edge = unit_longest_edge(kind, d);
        let (edge, scale) = match (kind, self.edge) {
            (TriangulationKind::Custom, Some(_)) => {
                return Err(Error::Triangulation(
                    "a custom triangulation takes its scale from its matrix: no edge".into(),
                ))
            }
            (TriangulationKind::Custom, None) => (f64::NAN, 1.0),
            (_, e) => {
                let e = e.unwrap_or(1.0);
                if !EDGE_RANGE.contains(&e) {
                    return Err(Error::Triangulation(format!(
                        "edge {e:e} is out of range: the edge must be from {:e} to {:e}",
                        EDGE_RANGE.start(),
                        EDGE_RANGE.end()
                    )));
                }
                (e, e / base_edge)
            }
        };
        let rotation = self.rotation_seed.map(|s| random_rotation(d, s));
        let custom = match &self.matrix {
            Some(m) => {
                if m.len() != d || m.iter().any(|r| r.len() != d) {
                    return Err(Error::DimensionMismatch(format!(
                        "custom matrix must be {d} x {d}"
                    )));
                }
                let flat: Vec<f64> = m.iter().flatten().copied().collect();
                check_finite_in(&flat, "the custom matrix (row by row)")?;
                if let Some(x) = flat.iter().find(|x| x.abs() > *EDGE_RANGE.end()) {
                    return Err(Error::Triangulation(format!(
                        "custom matrix entry {x:e} is out of range: entries must be at most \
                         {:e} in size, as edges are",
                        EDGE_RANGE.end()
                    )));
                }
                Some(flat)
            }
            None => None,
        };
        let mut coxeter_c = vec![0.0; d + 1];
        for (j, c) in coxeter_c.iter_mut().enumerate().skip(1) {
            *c = 1.0 / ((j * j + j) as f64).sqrt();
        }
        let mut t = Triangulation {
            d,
            kind,
            edge,
            scale,
            offset: vec![0.0; d],
            linear: Linear::Identity,
            coxeter_c,
        };
        t.linear = match (kind, rotation, custom) {
            (TriangulationKind::Freudenthal, None, _) => Linear::Identity,
            (TriangulationKind::Coxeter, None, _) => Linear::Coxeter,
            (_, rot, custom) => {
                let lattice = match custom {
                    Some(m) => m,
                    None => t.lattice_matrix(),
                };
                let a = match rot {
                    Some(r) => mat_mul(&r, &lattice, d),
                    None => lattice,
                };
                let lu = Lu::new(&a, d).ok_or_else(|| {
                    Error::Triangulation("the triangulation matrix is singular".into())
                })?;
                Linear::Dense { a, lu }
            }
        };
        if let Linear::Dense { a, .. } = &t.linear {
            if kind == TriangulationKind::Custom {
                t.edge = longest_edge_of(a, d);
            }
        }
        t.offset = match self.offset {
            Offset::Zero => vec![0.0; d],
            Offset::Given(b) => {
                if b.len() != d {
                    return Err(Error::DimensionMismatch(format!(
                        "offset has {} coordinates, the triangulation has {d}",
                        b.len()
                    )));
                }
                check_finite_in(&b, "the offset")?;
                b
            }
            Offset::Seeded(seed) => {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                let u: Vec<f64> = (0..d).map(|_| rng.random::<f64>()).collect();
                let mut x = vec![0.0; d];
                t.apply_linear(&u, &mut x);
                x
            }
        };
        Ok(t)
    }
}

impl Triangulation {
    /// Coxeter triangulation of type A~d of R^d.
    pub fn coxeter(d: usize) -> TriangulationBuilder {
        Self::builder(d, TriangulationKind::Coxeter)
    }

    /// Freudenthal-Kuhn triangulation of R^d.
    pub fn freudenthal(d: usize) -> TriangulationBuilder {
        Self::builder(d, TriangulationKind::Freudenthal)
    }

    /// A builder for `kind` in R^d (custom needs [`Triangulation::custom`]).
    pub fn builder(d: usize, kind: TriangulationKind) -> TriangulationBuilder {
        TriangulationBuilder {
            d,
            kind,
            edge: None,
            offset: Offset::Seeded(1),
            rotation_seed: None,
            matrix: None,
        }
    }

    /// The CFK triangulation with vertex = matrix * v + offset (rows of `matrix` given), in the
    /// papers' lattice convention, so another implementation's matrix reproduces its simplices.
    pub fn custom(matrix: Vec<Vec<f64>>) -> TriangulationBuilder {
        TriangulationBuilder {
            d: matrix.len(),
            kind: TriangulationKind::Custom,
            edge: None,
            offset: Offset::Zero,
            rotation_seed: None,
            matrix: Some(matrix),
        }
    }

    /// Ambient dimension d.
    #[inline]
    pub fn dim(&self) -> usize {
        self.d
    }

    /// Which triangulation.
    pub fn kind(&self) -> TriangulationKind {
        self.kind
    }

    /// Longest edge of a d-simplex (for a custom matrix with d > 16, an upper bound).
    pub fn edge(&self) -> f64 {
        self.edge
    }

    /// The translation b.
    pub fn offset(&self) -> &[f64] {
        &self.offset
    }

    /// The full linear part A (row-major), x = b + A u.
    pub fn matrix(&self) -> Vec<f64> {
        match &self.linear {
            Linear::Dense { a, .. } => a.clone(),
            _ => self.lattice_matrix(),
        }
    }

    /// s * Lambda (dense) for the FK and Coxeter maps.
    fn lattice_matrix(&self) -> Vec<f64> {
        let d = self.d;
        let mut m = vec![0.0; d * d];
        let mut e = vec![0.0; d];
        let mut col = vec![0.0; d];
        for c in 0..d {
            e.fill(0.0);
            e[c] = 1.0;
            self.apply_unrotated(&e, &mut col);
            for r in 0..d {
                m[r * d + c] = col[r];
            }
        }
        m
    }

    /// s * Lambda * u for the FK or Coxeter lattice, ignoring rotation (O(d)).
    fn apply_unrotated(&self, u: &[f64], x: &mut [f64]) {
        let s = self.scale;
        match self.kind {
            TriangulationKind::Coxeter => {
                // x_j = (u_1 + ... + u_j - j u_{j+1}) / sqrt(j^2 + j), u_{d+1} = 0.
                let mut prefix = 0.0;
                for j in 1..=self.d {
                    prefix += u[j - 1];
                    let next = if j < self.d { u[j] } else { 0.0 };
                    x[j - 1] = s * (prefix - j as f64 * next) * self.coxeter_c[j];
                }
            }
            _ => {
                for (xi, ui) in x.iter_mut().zip(u) {
                    *xi = s * ui;
                }
            }
        }
    }

    /// A u (no offset).
    fn apply_linear(&self, u: &[f64], x: &mut [f64]) {
        match &self.linear {
            Linear::Dense { a, .. } => mat_vec(a, u, x),
            _ => self.apply_unrotated(u, x),
        }
    }

    /// The map from lattice to ambient coordinates as a dense affine map x = A u + b:
    /// (A row-major, d x d; b). The GPU's vertex shader uses it; for unrotated FK and
    /// Coxeter lattices [`Triangulation::vertex_coords`] computes the same map more cheaply,
    /// so the two may differ in the last bits.
    pub fn affine_map(&self) -> (Vec<f64>, Vec<f64>) {
        let d = self.d;
        let a = match &self.linear {
            Linear::Dense { a, .. } => a.clone(),
            _ => {
                let mut a = vec![0.0; d * d];
                let mut u = vec![0.0; d];
                let mut col = vec![0.0; d];
                for c in 0..d {
                    u.fill(0.0);
                    u[c] = 1.0;
                    self.apply_unrotated(&u, &mut col);
                    for r in 0..d {
                        a[r * d + c] = col[r];
                    }
                }
                a
            }
        };
        (a, self.offset.clone())
    }

    /// Ambient coordinates of the lattice vertex `v`, into `x` (length d).
    #[inline]
    pub fn vertex_coords(&self, v: &[i32], x: &mut [f64]) {
        // A buffer no larger than needed: zeroing MAX_DIM entries per vertex cost more than
        // the map itself in low dimensions.
        fn with<const N: usize>(t: &Triangulation, v: &[i32], x: &mut [f64]) {
            let mut u = [0.0f64; N];
            for (ui, &vi) in u.iter_mut().zip(&v[..t.d]) {
                *ui = vi as f64;
            }
            t.point_from_lattice(&u[..t.d], x);
        }
        match self.d {
            0..=4 => with::<4>(self, v, x),
            5..=8 => with::<8>(self, v, x),
            9..=16 => with::<16>(self, v, x),
            _ => with::<{ super::MAX_DIM }>(self, v, x),
        }
    }

    /// [`Triangulation::vertex_coords`] of many vertices: `lattice` holds rows of d, `x` gets
    /// rows of d, bit for bit the same. With a dense map in up to 8 dimensions each row is
    /// one unrolled pass, its d sums independent of one another (the same operations in the
    /// same order as the dense product's, which starts each sum at -0.0: a no-op).
    pub fn vertices_coords(&self, lattice: &[i32], x: &mut [f64]) {
        fn dense<const D: usize>(a: &[f64], b: &[f64], lattice: &[i32], x: &mut [f64]) {
            let a: &[f64; 64] = &std::array::from_fn(|i| a.get(i).copied().unwrap_or(0.0));
            for (v, out) in lattice.chunks_exact(D).zip(x.chunks_exact_mut(D)) {
                let u: [f64; D] = std::array::from_fn(|j| v[j] as f64);
                for r in 0..D {
                    let mut acc = a[r * D] * u[0];
                    for j in 1..D {
                        acc += a[r * D + j] * u[j];
                    }
                    out[r] = acc + b[r];
                }
            }
        }
        let d = self.d;
        match (&self.linear, d) {
            (Linear::Dense { a, .. }, 2) => dense::<2>(a, &self.offset, lattice, x),
            (Linear::Dense { a, .. }, 3) => dense::<3>(a, &self.offset, lattice, x),
            (Linear::Dense { a, .. }, 4) => dense::<4>(a, &self.offset, lattice, x),
            (Linear::Dense { a, .. }, 5) => dense::<5>(a, &self.offset, lattice, x),
            (Linear::Dense { a, .. }, 6) => dense::<6>(a, &self.offset, lattice, x),
            (Linear::Dense { a, .. }, 7) => dense::<7>(a, &self.offset, lattice, x),
            (Linear::Dense { a, .. }, 8) => dense::<8>(a, &self.offset, lattice, x),
            _ => {
                for (v, out) in lattice.chunks_exact(d).zip(x.chunks_exact_mut(d)) {
                    self.vertex_coords(v, out);
                }
            }
        }
    }

    /// The point with barycentric coordinates `lambda` in the simplex whose lattice vertices
    /// `vertex(i, out)` writes: u = v_0 + sum_i lambda_i (v_i - v_0) (exact integer
    /// differences), then x = b + A u.
    pub fn barycentric_point(
        &self,
        lambda: &[f64],
        mut vertex: impl FnMut(usize, &mut [i32]),
        x: &mut [f64],
    ) {
        // Buffers no larger than needed (as in `vertex_coords`).
        fn with<const N: usize>(
            t: &Triangulation,
            lambda: &[f64],
            vertex: &mut impl FnMut(usize, &mut [i32]),
            x: &mut [f64],
        ) {
            let d = t.d;
            let (mut v0, mut v) = ([0i32; N], [0i32; N]);
            let mut u = [0.0f64; N];
            vertex(0, &mut v0[..d]);
            for (i, &l) in lambda.iter().enumerate().skip(1) {
                vertex(i, &mut v[..d]);
                for c in 0..d {
                    u[c] += l * (v[c] - v0[c]) as f64;
                }
            }
            for c in 0..d {
                u[c] += v0[c] as f64;
            }
            t.point_from_lattice(&u[..d], x);
        }
        match self.d {
            0..=4 => with::<4>(self, lambda, &mut vertex, x),
            5..=8 => with::<8>(self, lambda, &mut vertex, x),
            9..=16 => with::<16>(self, lambda, &mut vertex, x),
            _ => with::<{ super::MAX_DIM }>(self, lambda, &mut vertex, x),
        }
    }

    /// Ambient coordinates of a (real) lattice point u: x = b + A u.
    #[inline]
    pub fn point_from_lattice(&self, u: &[f64], x: &mut [f64]) {
        self.apply_linear(u, x);
        for (xi, bi) in x.iter_mut().zip(&self.offset) {
            *xi += bi;
        }
    }

    /// Lattice coordinates of the ambient point x: u = A^-1 (x - b); O(d) for unrotated FK and
    /// Coxeter, a triangular solve otherwise.
    pub fn point_to_lattice(&self, x: &[f64], u: &mut [f64]) {
        let d = self.d;
        for i in 0..d {
            u[i] = x[i] - self.offset[i];
        }
        match &self.linear {
            Linear::Identity => {
                for ui in u.iter_mut().take(d) {
                    *ui /= self.scale;
                }
            }
            Linear::Coxeter => {
                // p = sum_j x_j b_j in R^{d+1}; u_i = p_i - p_{d+1}.
                let c = &self.coxeter_c;
                let mut w = [0.0f64; super::MAX_DIM];
                for i in 0..d {
                    w[i] = u[i] / self.scale;
                }
                let p_last = -(d as f64) * c[d] * w[d - 1];
                let mut suffix = 0.0;
                for i in (1..=d).rev() {
                    suffix += w[i - 1] * c[i];
                    let below = if i >= 2 {
                        (i - 1) as f64 * c[i - 1] * w[i - 2]
                    } else {
                        0.0
                    };
                    u[i - 1] = suffix - below - p_last;
                }
            }
            Linear::Dense { lu, .. } => lu.solve(&mut u[..d]),
        }
    }

    /// The simplex (of any dimension) whose relative interior holds `x`.
    pub fn locate(&self, x: &[f64]) -> Result<Simplex> {
        self.locate_with_tolerance(x, 0.0)
    }

    /// Like [`Triangulation::locate`], but lattice coordinates within `eps` (in lattice units)
    /// of a face put the point on that face: for points meant to lie on lower-dimensional faces.
    pub fn locate_with_tolerance(&self, x: &[f64], eps: f64) -> Result<Simplex> {
        if x.len() != self.d {
            return Err(Error::DimensionMismatch(format!(
                "point has {} coordinates, the triangulation has {}",
                x.len(),
                self.d
            )));
        }
        check_finite(x)?;
        let mut u = [0.0f64; super::MAX_DIM];
        self.point_to_lattice(x, &mut u[..self.d]);
        Simplex::locate_lattice(&u[..self.d], eps)
    }

    /// Ambient coordinates of all vertices of `s`, row after row (l+1 rows of d).
    pub fn simplex_coords(&self, s: &Simplex) -> Vec<f64> {
        let d = self.d;
        let mut out = vec![0.0; (s.dim() + 1) * d];
        s.for_each_vertex(|i, v| self.vertex_coords(v, &mut out[i * d..(i + 1) * d]));
        out
    }
}
