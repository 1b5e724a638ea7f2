//! A function f: R^d -> R^k as the library sees it: text equations compiled once (values,
//! Jacobian, boundary), or a Rust closure; Newton projection onto f^-1(0); combinators.

use std::sync::Arc;

use super::ast::Expr;
use super::parser::{check_counts, parse_expr_at, ParseError, Scope};
use crate::error::{check_finite_in, Error, Result};
use crate::expr::program::{Program, Scratch};
use crate::linalg::pow2_inverse;
use crate::linalg::Lu;
use crate::triangulation::{check_dim, random_rotation};

/// What the tracer needs of f: R^d -> R^k.
pub trait ImplicitFunction: Send + Sync {
    /// d.
    fn ambient_dim(&self) -> usize;
    /// k, the number of equations.
    fn codim(&self) -> usize;
    /// f at n points (`points`: n rows of d) into `out` (n rows of k).
    fn eval_batch(&self, points: &[f64], out: &mut [f64]);
    /// The k x d Jacobian at `x`, row-major (default: central differences).
    fn jacobian(&self, x: &[f64], out: &mut [f64]) {
        let (d, k) = (self.ambient_dim(), self.codim());
        let mut p = x.to_vec();
        let (mut fp, mut fm) = (vec![0.0; k], vec![0.0; k]);
        for c in 0..d {
            let h = 1e-6 * x[c].abs().max(1.0);
            p[c] = x[c] + h;
            self.eval_batch(&p, &mut fp);
            p[c] = x[c] - h;
            self.eval_batch(&p, &mut fm);
            p[c] = x[c];
            for r in 0..k {
                out[r * d + c] = (fp[r] - fm[r]) / (2.0 * h);
            }
        }
    }
    /// The Jacobians at n points (`points`: n rows of d) into `out` (n rows of k x d, each
    /// row-major); default: [`jacobian`](Self::jacobian) at each point.
    fn jacobian_batch(&self, points: &[f64], out: &mut [f64]) {
        let (d, k) = (self.ambient_dim(), self.codim());
        for (x, o) in points.chunks_exact(d).zip(out.chunks_exact_mut(k * d)) {
            self.jacobian(x, o);
        }
    }
    /// Whether calls of [`eval_batch`](Self::eval_batch) run one at a time whatever the
    /// thread (f behind a lock, such as a Python function under the GIL): the CPU oracle then
    /// gives it each batch whole instead of in parallel chunks.
    fn serial(&self) -> bool {
        false
    }
    /// The equations as text-derived trees, when f has them (needed by the GPU backend).
    fn system(&self) -> Option<&EquationSystem> {
        None
    }
    /// Number of boundary inequalities g_i(x) >= 0 that cut M (default: those of `system()`).
    fn boundary_count(&self) -> usize {
        self.system().map_or(0, |s| s.boundary().len())
    }
    /// The boundary functions g_i at `x` into `out` (`boundary_count()` values).
    fn eval_boundary(&self, x: &[f64], out: &mut [f64]) {
        if let Some(s) = self.system() {
            s.boundary_program().eval(x, out);
        }
    }
}

/// ```
/// use isomesh::expr::{EquationSystem, ImplicitFunction};
///
/// // The flat torus in R^4: two equations, f: R^4 -> R^2.
/// let f = EquationSystem::parse_simple(4, &["x1^2 + x2^2 - 1", "x3^2 + x4^2 - 1"])?;
/// assert_eq!((f.ambient_dim(), f.codim()), (4, 2));
/// let mut v = [0.0; 4];
/// f.eval_batch(&[1.0, 0.0, 0.0, 2.0, 0.0, 1.0, 1.0, 0.0], &mut v);
/// assert_eq!(v, [0.0, 3.0, 0.0, 0.0]);
/// // Its Jacobian comes from exact derivatives.
/// let mut j = [0.0; 8];
/// f.jacobian(&[1.0, 0.0, 0.0, 2.0], &mut j);
/// assert_eq!(j, [2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 4.0]);
/// # Ok::<(), isomesh::Error>(())
/// ```
/// A system of equations in the language, compiled for batch evaluation.
#[derive(Clone, Debug)]
pub struct EquationSystem {
    names: Vec<String>,
    equations: Vec<Expr>,
    boundary: Vec<Expr>,
    values: Arc<Program>,
    jacobian: Arc<Program>,
    boundary_values: Arc<Program>,
}

impl EquationSystem {
    /// Parses `equations` (and `boundary` inequalities g >= 0) in `scope`; an error's line and
    /// column are within its text, and its context says "equation i" or "boundary inequality i".
    pub fn parse(scope: &Scope, equations: &[&str], boundary: &[&str]) -> Result<Self> {
        Self::parse_with(scope, equations, boundary, |e, what, i| {
            e.within(format!("{what} {}", i + 1))
        })
    }

    /// [`EquationSystem::parse`], with `relocate(error, what, i)` applied to an error in
    /// text i, where `what` is "equation" or "boundary inequality" (a spec file moves the
    /// position to its own lines and columns).
    pub fn parse_with(
        scope: &Scope,
        equations: &[&str],
        boundary: &[&str],
        relocate: impl Fn(ParseError, &str, usize) -> ParseError,
    ) -> Result<Self> {
        let parse_all = |texts: &[&str], what: &str| {
            texts
                .iter()
                .enumerate()
                .map(|(i, t)| parse_expr_at(t, scope, 1).map_err(|e| relocate(e, what, i)))
                .collect::<Result<Vec<_>, ParseError>>()
        };
        let eqs = parse_all(equations, "equation")?;
        check_counts(eqs.len(), scope.dim, 0)?;
        let bnd = parse_all(boundary, "boundary inequality")?;
        Self::from_exprs(default_names(scope), eqs, bnd)
    }

    /// Parses equations in x1..xd (and x, y, z, w when d <= 4).
    pub fn parse_simple(dim: usize, equations: &[&str]) -> Result<Self> {
        Self::parse(&Scope::new(dim), equations, &[])
    }

    /// Builds from trees; `names` gives d.
    pub fn from_exprs(
        names: Vec<String>,
        equations: Vec<Expr>,
        boundary: Vec<Expr>,
    ) -> Result<Self> {
        let d = names.len();
        check_dim(d)?;
        check_counts(equations.len(), d, 0)?;
        if let Some(e) = equations.iter().chain(&boundary).find(|e| e.arity() > d) {
            return Err(Error::DimensionMismatch(format!(
                "an equation uses x{} in R^{d}",
                e.arity()
            )));
        }
        // Derivatives and programs can be many times an equation's size: they stop at the
        // memory limit of `memory::within`, where one is set.
        let mut jac = Vec::with_capacity(equations.len() * d);
        for e in &equations {
            for v in 0..d {
                jac.push(e.diff_within_limit(v)?);
            }
        }
        Ok(EquationSystem {
            values: Arc::new(Program::compile_within_limit(&equations, d)?),
            jacobian: Arc::new(Program::compile_within_limit(&jac, d)?),
            boundary_values: Arc::new(Program::compile_within_limit(&boundary, d)?),
            names,
            equations,
            boundary,
        })
    }

    /// Variable names, one per coordinate.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The equations f_1..f_k.
    pub fn equations(&self) -> &[Expr] {
        &self.equations
    }

    /// Boundary inequalities g_i(x) >= 0.
    pub fn boundary(&self) -> &[Expr] {
        &self.boundary
    }

    /// The compiled f.
    pub fn values(&self) -> &Program {
        &self.values
    }

    /// The compiled Jacobian (k x d outputs, row-major).
    pub fn jacobian_program(&self) -> &Program {
        &self.jacobian
    }

    /// The compiled boundary functions.
    pub fn boundary_program(&self) -> &Program {
        &self.boundary_values
    }

    /// Cartesian product: f(x) = 0 and g(y) = 0 on R^{d1 + d2}.
    pub fn product(&self, other: &EquationSystem) -> Result<Self> {
        let d1 = self.names.len();
        let shift: Vec<Expr> = (0..other.names.len()).map(|i| Expr::Var(d1 + i)).collect();
        let mut eqs = self.equations.clone();
        eqs.extend(other.equations.iter().map(|e| e.substitute(&shift)));
        let mut bnd = self.boundary.clone();
        bnd.extend(other.boundary.iter().map(|e| e.substitute(&shift)));
        Self::from_exprs(indexed_names(d1 + other.names.len()), eqs, bnd)
    }

    /// Embedding in R^d (d >= current): the extra coordinates are set to zero.
    pub fn embed(&self, d: usize) -> Result<Self> {
        let d0 = self.names.len();
        if d < d0 {
            return Err(Error::DimensionMismatch(format!(
                "cannot embed R^{d0} in R^{d}"
            )));
        }
        let mut eqs = self.equations.clone();
        eqs.extend((d0..d).map(Expr::Var));
        Self::from_exprs(indexed_names(d), eqs, self.boundary.clone())
    }

    /// The image under x -> R x for the seeded random rotation R: f'(x) = f(R^T x).
    pub fn rotate(&self, seed: u64) -> Result<(Self, Vec<f64>)> {
        let d = self.names.len();
        let r = random_rotation(d, seed);
        // (R^T x)_i = sum_j R[j][i] x_j
        let subs: Vec<Expr> = (0..d)
            .map(|i| {
                (0..d).fold(Expr::Num(0.0), |acc, j| {
                    Expr::add(acc, Expr::mul(Expr::Num(r[j * d + i]), Expr::Var(j)))
                })
            })
            .collect();
        let sys = Self::from_exprs(
            self.names.clone(),
            self.equations.iter().map(|e| e.substitute(&subs)).collect(),
            self.boundary.iter().map(|e| e.substitute(&subs)).collect(),
        )?;
        Ok((sys, r))
    }

    /// The image under x -> x + t: f'(x) = f(x - t).
    pub fn translate(&self, t: &[f64]) -> Result<Self> {
        let d = self.names.len();
        if t.len() != d {
            return Err(Error::DimensionMismatch(format!(
                "translation has {} coordinates, the system {d}",
                t.len()
            )));
        }
        check_finite_in(t, "the translation")?;
        let subs: Vec<Expr> = (0..d)
            .map(|i| Expr::sub(Expr::Var(i), Expr::Num(t[i])))
            .collect();
        Self::from_exprs(
            self.names.clone(),
            self.equations.iter().map(|e| e.substitute(&subs)).collect(),
            self.boundary.iter().map(|e| e.substitute(&subs)).collect(),
        )
    }

    /// Whether `x` satisfies every boundary inequality g_i(x) >= 0.
    pub fn inside_boundary(&self, x: &[f64]) -> bool {
        if self.boundary.is_empty() {
            return true;
        }
        let mut g = vec![0.0; self.boundary.len()];
        self.boundary_values.eval(x, &mut g);
        g.iter().all(|&v| v >= 0.0)
    }
}

fn indexed_names(d: usize) -> Vec<String> {
    (1..=d).map(|i| format!("x{i}")).collect()
}

/// x1..xd, with the scope's names (x y z w, or declared ones) where it has them.
fn default_names(scope: &Scope) -> Vec<String> {
    let mut names = indexed_names(scope.dim);
    for (n, i) in &scope.variables {
        names[*i] = n.clone();
    }
    names
}

impl ImplicitFunction for EquationSystem {
    fn ambient_dim(&self) -> usize {
        self.names.len()
    }
    fn codim(&self) -> usize {
        self.equations.len()
    }
    fn eval_batch(&self, points: &[f64], out: &mut [f64]) {
        SCRATCH.with(|s| self.values.eval_batch(points, out, &mut s.borrow_mut()));
    }
    fn jacobian(&self, x: &[f64], out: &mut [f64]) {
        SCRATCH.with(|s| self.jacobian.eval_batch(x, out, &mut s.borrow_mut()));
    }
    fn jacobian_batch(&self, points: &[f64], out: &mut [f64]) {
        SCRATCH.with(|s| self.jacobian.eval_batch(points, out, &mut s.borrow_mut()));
    }
    fn system(&self) -> Option<&EquationSystem> {
        Some(self)
    }
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// The signature of a closure usable as f: writes f(x) (k values) for one point x.
pub type PointFn = dyn Fn(&[f64], &mut [f64]) + Send + Sync;

/// ```
/// use isomesh::expr::{ClosureFunction, ImplicitFunction};
///
/// let sphere = ClosureFunction::new(3, 1, |x, out| {
///     out[0] = x.iter().map(|v| v * v).sum::<f64>() - 1.0;
/// })?;
/// let mut v = [0.0; 2];
/// sphere.eval_batch(&[1.0, 0.0, 0.0, 0.0, 2.0, 0.0], &mut v);
/// assert_eq!(v, [0.0, 3.0]);
/// # Ok::<(), isomesh::Error>(())
/// ```
/// f given as a Rust closure (CPU backend only: the GPU needs the equation language).
pub struct ClosureFunction {
    d: usize,
    k: usize,
    f: Box<PointFn>,
    boundary: Option<(usize, Box<PointFn>)>,
}

impl ClosureFunction {
    /// Wraps `f`, which maps a point of R^d to k values.
    pub fn new(
        d: usize,
        k: usize,
        f: impl Fn(&[f64], &mut [f64]) + Send + Sync + 'static,
    ) -> Result<Self> {
        check_dim(d)?;
        check_counts(k, d, 0)?;
        Ok(ClosureFunction {
            d,
            k,
            f: Box::new(f),
            boundary: None,
        })
    }

    /// Adds `count` boundary inequalities g_i(x) >= 0: `g` writes the g_i at one point.
    pub fn with_boundary(
        mut self,
        count: usize,
        g: impl Fn(&[f64], &mut [f64]) + Send + Sync + 'static,
    ) -> Self {
        self.boundary = Some((count, Box::new(g)));
        self
    }
}

impl ImplicitFunction for ClosureFunction {
    fn ambient_dim(&self) -> usize {
        self.d
    }
    fn codim(&self) -> usize {
        self.k
    }
    fn eval_batch(&self, points: &[f64], out: &mut [f64]) {
        for (p, o) in points
            .chunks_exact(self.d)
            .zip(out.chunks_exact_mut(self.k))
        {
            (self.f)(p, o);
        }
    }
    fn boundary_count(&self) -> usize {
        self.boundary.as_ref().map_or(0, |b| b.0)
    }
    fn eval_boundary(&self, x: &[f64], out: &mut [f64]) {
        if let Some((_, g)) = &self.boundary {
            g(x, out);
        }
    }
}

/// Projects `x0` onto f^-1(0) by Gauss-Newton steps x <- x - J^T (J J^T)^-1 f(x) (the
/// nearest-point step for a full-rank Jacobian); errors if it does not reach |f| <= tol, or
/// for an f too large or too small in scale for that, a first-order distance to each
/// equation's zero set (|f_r| / |grad f_r|) of at most tol.
pub fn newton_project(f: &dyn ImplicitFunction, x0: &[f64], tol: f64) -> Result<Vec<f64>> {
    let (d, k) = (f.ambient_dim(), f.codim());
    if x0.len() != d {
        return Err(Error::DimensionMismatch(format!(
            "seed has {} coordinates, f takes {d}",
            x0.len()
        )));
    }
    check_finite_in(x0, "the seed")?;
    let mut x = x0.to_vec();
    let mut fx = vec![0.0; k];
    let mut j = vec![0.0; k * d];
    let mut jjt = vec![0.0; k * k];
    for _ in 0..60 {
        f.eval_batch(&x, &mut fx);
        if fx.iter().any(|v| !v.is_finite()) {
            break;
        }
        let norm = fx.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm <= tol {
            return Ok(x);
        }
        f.jacobian(&x, &mut j);
        if j.iter().any(|v| !v.is_finite()) {
            break;
        }
        // Rows of a scale whose products would overflow or underflow are brought to [1, 2)
        // by a power of two (the step does not change; other rows are left as they are).
        for r in 0..k {
            let m = j[r * d..(r + 1) * d]
                .iter()
                .fold(0.0f64, |a, v| a.max(v.abs()));
            if m > 0.0 && !(2f64.powi(-100)..=2f64.powi(100)).contains(&m) {
                let s = pow2_inverse(m);
                j[r * d..(r + 1) * d].iter_mut().for_each(|v| *v *= s);
                fx[r] *= s;
            }
        }
        for r in 0..k {
            for c in 0..k {
                jjt[r * k + c] = (0..d).map(|t| j[r * d + t] * j[c * d + t]).sum();
            }
        }
        let Some(lu) = Lu::new(&jjt, k) else { break };
        let mut y = fx.clone();
        lu.solve(&mut y);
        // x -= J^T y
        for (c, xc) in x.iter_mut().enumerate() {
            *xc -= (0..k).map(|r| j[r * d + c] * y[r]).sum::<f64>();
        }
    }
    if within_distance(f, &x, tol) {
        return Ok(x);
    }
    Err(Error::Spec(format!(
        "Newton projection from {x0:?} did not converge to |f| <= {tol:e}: the seed is too far \
         from the manifold or the Jacobian is singular there"
    )))
}

/// Whether every equation's first-order distance |f_r(x)| / |grad f_r(x)| to its zero set is
/// at most `tol`: |f| <= tol for an f whose scale is far from 1 (1e300 f, 1e-300 f).
fn within_distance(f: &dyn ImplicitFunction, x: &[f64], tol: f64) -> bool {
    values_and_slopes(f, x)
        .iter()
        .all(|&(v, g)| g > 0.0 && g.is_finite() && v.is_finite() && v.abs() <= tol * g)
}

/// Whether a Newton step from `x` moves it by at most `h` for every equation: |f_r(x)| is
/// finite and at most `h` times the norm of its gradient (a zero gradient where f_r is 0
/// too, as at a crossing of branches, passes). Unlike [`within_distance`], a point where an
/// equation is flat passes: it serves to tell a point near M from the crossing of a simplex
/// too coarse for a steep f, far from M.
pub(crate) fn newton_step_within(f: &dyn ImplicitFunction, x: &[f64], h: f64) -> bool {
    values_and_slopes(f, x)
        .iter()
        .all(|&(v, g)| v.is_finite() && v.abs() <= h * g)
}

/// Each equation's value at `x` and the norm of its gradient there.
fn values_and_slopes(f: &dyn ImplicitFunction, x: &[f64]) -> Vec<(f64, f64)> {
    let (d, k) = (f.ambient_dim(), f.codim());
    let (mut fx, mut j) = (vec![0.0; k], vec![0.0; k * d]);
    f.eval_batch(x, &mut fx);
    f.jacobian(x, &mut j);
    fx.into_iter()
        .zip(j.chunks_exact(d).map(scaled_norm))
        .collect()
}

/// The Euclidean norm of `v`, with no overflow or underflow on the way.
fn scaled_norm(v: &[f64]) -> f64 {
    let m = v.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    if m == 0.0 || !m.is_finite() {
        return m;
    }
    m * v.iter().map(|x| (x / m) * (x / m)).sum::<f64>().sqrt()
}

/// Whether the Jacobian of `f` is rank-deficient at `x`: some row, made orthogonal to the
/// rows before it, is shorter than 1e-6 times that equation's own slope about `x`: the
/// median of its Jacobian row's norm at the 2 d points `x` +- `h` e_i (a median, so that a
/// steep f, whose slope a step away is many times its slope at `x`, is not taken for a
/// singular one; per equation, so that equations of different scales are not either).
/// Tracing from such a point (a crossing of branches, a cusp) follows one branch at most. A
/// Jacobian that is not finite at `x` tells nothing: false.
pub fn is_singular_at(f: &dyn ImplicitFunction, x: &[f64], h: f64) -> bool {
    rank_ratio(f, x, h).is_some_and(|r| r <= 1e-6)
}

/// How close the Jacobian of `f` at `x` is to losing rank, against f's slope about `x`:
/// the least, over the equations, of its row made orthogonal to the rows before it over the
/// equation's slope that [`is_singular_at`] takes (the median of the row's norm at `x` +- `h`
/// e_i).
/// Near a point where branches cross (or a cusp) at distance r, with `h` several times r,
/// it is about r / h; on a smooth M it is about 1. `None` where the Jacobian at `x` is not
/// finite.
pub fn rank_ratio(f: &dyn ImplicitFunction, x: &[f64], h: f64) -> Option<f64> {
    let (d, k) = (f.ambient_dim(), f.codim());
    let mut j = vec![0.0; k * d];
    // Each row's norm at the 2 d points about x, row by row.
    let mut around = vec![Vec::with_capacity(2 * d); k];
    let mut p = x.to_vec();
    for c in 0..d {
        for step in [h, -h] {
            p[c] = x[c] + step;
            f.jacobian(&p, &mut j);
            for (a, row) in around.iter_mut().zip(j.chunks_exact(d)) {
                let n = scaled_norm(row);
                if !n.is_nan() {
                    a.push(n);
                }
            }
        }
        p[c] = x[c];
    }
    f.jacobian(x, &mut j);
    if j.iter().any(|v| !v.is_finite()) {
        return None;
    }
    // Each row's slope: its median about x, or its norm at x if larger. Each row is then
    // scaled by a power of two near 1 / slope (exact; the rows' span is unchanged), so that
    // their products neither overflow nor underflow where it matters.
    let mut slopes = Vec::with_capacity(k);
    for (a, row) in around.iter_mut().zip(j.chunks_exact_mut(d)) {
        a.sort_by(f64::total_cmp);
        let at_x = scaled_norm(row);
        let slope = match a.get(a.len() / 2) {
            Some(&m) if m.is_finite() => m.max(at_x),
            _ => at_x,
        };
        if slope == 0.0 {
            return Some(0.0);
        }
        let s = pow2_inverse(slope);
        row.iter_mut().for_each(|v| *v *= s);
        slopes.push(slope * s);
    }
    // Modified Gram-Schmidt over the rows.
    let mut ratio = f64::INFINITY;
    for r in 0..k {
        for q in 0..r {
            let (done, rest) = j.split_at_mut(r * d);
            let (qrow, row) = (&done[q * d..(q + 1) * d], &mut rest[..d]);
            let qq: f64 = qrow.iter().map(|v| v * v).sum();
            if qq > 0.0 {
                let t = qrow.iter().zip(row.iter()).map(|(a, b)| a * b).sum::<f64>() / qq;
                row.iter_mut().zip(qrow).for_each(|(b, a)| *b -= t * a);
            }
        }
        ratio = ratio.min(scaled_norm(&j[r * d..(r + 1) * d]) / slopes[r]);
    }
    Some(ratio)
}

/// The first equation (0-based) that is exactly 0 at every one of `points` (n rows of d),
/// if any: f is then identically 0 there, and f^-1(0) is no manifold.
pub fn zero_equation_at(f: &dyn ImplicitFunction, points: &[f64]) -> Option<usize> {
    let (d, k) = (f.ambient_dim(), f.codim());
    let n = points.len() / d.max(1);
    if n == 0 {
        return None;
    }
    let mut out = vec![0.0; n * k];
    f.eval_batch(&points[..n * d], &mut out);
    (0..k).find(|&i| out.chunks_exact(k).all(|v| v[i] == 0.0))
}
