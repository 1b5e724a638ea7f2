// Index loops over lattice axes read as the coordinates they are.
#![allow(clippy::needless_range_loop)]
//! The lattice vertices of an exhaustive scan: which are near its box, f at each, and the sign
//! code that candidate generation reads (on the CPU, [`crate::trace::scan::candidates`]; on a GPU,
//! `shaders/scan.wgsl`).

use std::ops::Range;

use rayon::prelude::*;

use super::candidates::{sign_code, BASE};
use super::device_values::bounded_sign_code;
use super::MAX_SCAN_DIM;
use crate::error::{Error, Result};
use crate::trace::region::lattice_bounds;
use crate::trace::TraceContext;
use crate::triangulation::{Triangulation, MAX_DIM};

/// Vertices per evaluation step (between checks for Ctrl-C).
const EVAL_STEP: usize = 1 << 16;
/// Vertices a slab's own rows hold at least (the last slab's may hold fewer), for
/// [`Slabs::new`]: a window's values and codes then stay within the cache while it is
/// scanned.
pub(crate) const SLAB_VERTICES: usize = 1 << 20;
/// Vertices per parallel work item when listing a slab's coordinates.
const FILL: usize = 1 << 12;

/// The lattice vertices of an exhaustive scan (those within two edges of its box), with f and
/// a sign code at each.
///
/// Vertices lie in rows along lattice axis 0: the row with id r (its coordinates on axes
/// 1..d-1 are the digits of r in the mixed radix `n[1..]`, from `lo`) holds u_0 in
/// `start..start + len`, stored from `offset` on. Only rows that hold vertices are kept,
/// sorted by id. Build it with [`scan_grid`](crate::trace::scan_grid).
pub struct ScanGrid {
    lo: Vec<i64>,
    n: Vec<usize>,
    rows: Vec<Row>,
    total: usize,
    k: usize,
    values: Vec<f64>,
    bounds: Vec<f64>,
    codes: Vec<u32>,
}

/// The row [`ScanGrid::coords_at`] found last, and its coordinates on axes 1..d-1.
#[derive(Default)]
pub(crate) struct RowCursor {
    valid: bool,
    row: usize,
    coords: [i32; MAX_SCAN_DIM],
}

/// One row of a [`ScanGrid`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct Row {
    pub id: usize,
    pub start: i64,
    pub len: u32,
    pub offset: usize,
}

impl ScanGrid {
    /// Lattice vertices held.
    pub fn len(&self) -> usize {
        self.total
    }

    /// Whether no vertex is held.
    pub fn is_empty(&self) -> bool {
        self.total == 0
    }

    /// The ambient dimension d.
    pub fn dim(&self) -> usize {
        self.n.len()
    }

    /// The codimension k.
    pub fn codim(&self) -> usize {
        self.k
    }

    /// f at every vertex, rows of k: the CPU's values, or with an oracle that has
    /// [`device_values`](crate::trace::Scan::device_values), the device's.
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// The bounds of the device's [`values`](Self::values) (the CPU's values lie within
    /// them; infinite: unknown), or nothing when the values are the CPU's.
    pub fn bounds(&self) -> &[f64] {
        &self.bounds
    }

    /// The sign code of every vertex (`trace::scan::candidates::sign_code`, with `BASE` set
    /// on the vertices whose cube is scanned).
    pub fn codes(&self) -> &[u32] {
        &self.codes
    }

    /// The rows, sorted by id.
    pub(crate) fn rows(&self) -> &[Row] {
        &self.rows
    }

    /// Rows per unit step along lattice axis j (j >= 1) in row ids.
    pub(crate) fn stride(&self, j: usize) -> usize {
        self.n[1..j].iter().product()
    }

    /// The axes j >= 1 (as bit j - 1) on which row `id` is at the top of the grid.
    pub(crate) fn top_axes(&self, mut id: usize) -> u32 {
        let mut top = 0;
        for j in 1..self.n.len() {
            if id % self.n[j] == self.n[j] - 1 {
                top |= 1 << (j - 1);
            }
            id /= self.n[j];
        }
        top
    }

    /// The index of the row holding vertex `idx`.
    pub(crate) fn row_of(&self, idx: usize) -> usize {
        self.rows.partition_point(|row| row.offset <= idx) - 1
    }

    /// The index of the row with id `id`, if it is held.
    pub(crate) fn find_row(&self, id: usize) -> Option<usize> {
        self.rows.binary_search_by_key(&id, |row| row.id).ok()
    }

    /// Lattice coordinates of axes 1..d-1 of row r.
    fn row_coords(&self, mut r: usize, out: &mut [i32]) {
        for j in 1..self.n.len() {
            out[j] = (self.lo[j] + (r % self.n[j]) as i64) as i32;
            r /= self.n[j];
        }
    }

    /// Lattice coordinates of the vertices `range` into `out` (d each), row by row.
    fn fill_coords(&self, range: Range<usize>, out: &mut [i32]) {
        // Rows of a fixed length copy as a few moves (a slice of d calls memcpy).
        match self.dim() {
            1 => self.fill_coords_of::<1>(range, out),
            2 => self.fill_coords_of::<2>(range, out),
            3 => self.fill_coords_of::<3>(range, out),
            4 => self.fill_coords_of::<4>(range, out),
            5 => self.fill_coords_of::<5>(range, out),
            6 => self.fill_coords_of::<6>(range, out),
            7 => self.fill_coords_of::<7>(range, out),
            8 => self.fill_coords_of::<8>(range, out),
            _ => self.fill_coords_of::<MAX_DIM>(range, out),
        }
    }

    /// [`ScanGrid::fill_coords`] for d <= N.
    fn fill_coords_of<const N: usize>(&self, range: Range<usize>, out: &mut [i32]) {
        let d = self.dim();
        if range.is_empty() {
            return;
        }
        let mut r = self.row_of(range.start);
        let mut v = [0i32; N];
        let mut idx = range.start;
        let mut slots = out.chunks_exact_mut(d);
        while idx < range.end {
            let row = self.rows[r];
            self.row_coords(row.id, &mut v[..d]);
            let end = (row.offset + row.len as usize).min(range.end);
            for i in idx..end {
                v[0] = (row.start + (i - row.offset) as i64) as i32;
                let slot = slots.next().expect("d coordinates per vertex");
                if N == d {
                    let slot: &mut [i32; N] = slot.try_into().expect("N coordinates");
                    *slot = v;
                } else {
                    slot.copy_from_slice(&v[..d]);
                }
            }
            idx = end;
            r += 1;
        }
    }

    /// Lattice coordinates of vertex `idx` into `out` (d of them), its row looked for from
    /// row `*r` on (at or before it; left at it): for vertices in increasing order.
    pub(crate) fn coords_from(&self, r: &mut usize, idx: usize, out: &mut [i32]) {
        while self.rows[*r].offset + self.rows[*r].len as usize <= idx {
            *r += 1;
        }
        let row = self.rows[*r];
        self.row_coords(row.id, out);
        out[0] = (row.start + (idx - row.offset) as i64) as i32;
    }

    /// Lattice coordinates of vertex `idx` into `out` (d of them), through `at`: fastest
    /// for vertices in increasing order (the row held or the next one is looked at before
    /// any search, and a row's coordinates are computed once).
    pub(crate) fn coords_at(&self, at: &mut RowCursor, idx: usize, out: &mut [i32]) {
        let d = self.dim();
        let holds = |r: usize| {
            self.rows
                .get(r)
                .is_some_and(|row| (row.offset..row.offset + row.len as usize).contains(&idx))
        };
        if !(at.valid && holds(at.row)) {
            at.row = if at.valid && holds(at.row + 1) {
                at.row + 1
            } else {
                self.row_of(idx)
            };
            at.valid = true;
            self.row_coords(self.rows[at.row].id, &mut at.coords[..d]);
        }
        let row = self.rows[at.row];
        out[1..d].copy_from_slice(&at.coords[1..d]);
        out[0] = (row.start + (idx - row.offset) as i64) as i32;
    }

    /// Lattice coordinates of vertex `idx` into `out` (d of them).
    pub fn coords(&self, idx: usize, out: &mut [i32]) {
        let r = self.row_of(idx);
        self.row_coords(self.rows[r].id, out);
        out[0] = (self.rows[r].start + (idx - self.rows[r].offset) as i64) as i32;
    }
}

/// Bytes per grid vertex: f's k values (and their bounds, with device values), the sign
/// code and the coordinates while they are evaluated.
fn vertex_bytes(ctx: &TraceContext, device: bool) -> u64 {
    let per_value = if device { 16 } else { 8 };
    ctx.k as u64 * per_value + 12
}

/// The rows of lattice vertices whose position lies in `near` (a grown box).
fn near_rows(ctx: &TraceContext, near: &[[f64; 2]], device: bool) -> Result<ScanGrid> {
    let d = ctx.d;
    let (lo, hi) = lattice_bounds(ctx.tri, near);
    let n: Vec<usize> = lo
        .iter()
        .zip(&hi)
        .map(|(l, h)| h.saturating_sub(*l).saturating_add(2).max(0) as usize)
        .collect();
    let rows_total = n[1..].iter().try_fold(1usize, |a, &b| a.checked_mul(b));
    // Row ids must fit.
    if !matches!(rows_total, Some(r) if r < 1 << 40) {
        // Bounds beyond i64 saturate: then say so rather than print a product of them.
        let count = if n.iter().any(|&v| v as u64 >= 1 << 62) {
            "more than 10^18 lattice points along an axis".to_string()
        } else {
            format!(
                "{:.3e} lattice rows",
                n[1..].iter().map(|&v| v as f64).product::<f64>()
            )
        };
        return Err(Error::Trace(format!(
            "the exhaustive scan of this box needs {count}, over the memory limit: use a \
             smaller box or a larger edge"
        )));
    }
    // Refuse before enumerating: about vol(box) / |det A| vertices, each k values.
    let a = ctx.tri.matrix();
    // In logarithms: the volume and the determinant may each pass f64's range.
    let log_volume: f64 = near.iter().map(|[lo, hi]| (hi - lo).log10()).sum();
    let log_estimate =
        crate::linalg::Lu::new(&a, d).map_or(f64::INFINITY, |lu| log_volume - lu.abs_det().log10());
    let log_bytes = log_estimate + (vertex_bytes(ctx, device) as f64).log10();
    let estimate = 10f64.powf(log_estimate);
    if !(log_bytes <= (ctx.max_memory as f64).log10() && estimate < u32::MAX as f64) {
        let bytes = if log_bytes < 18.0 {
            crate::memory::human_bytes(10f64.powf(log_bytes) as u64)
        } else {
            format!("10^{} bytes", about_power(log_bytes))
        };
        let vertices = if log_estimate < 18.0 {
            format!("{estimate:.3e}")
        } else {
            format!("10^{}", about_power(log_estimate))
        };
        return Err(Error::Trace(format!(
            "the exhaustive scan of this box needs about {vertices} lattice vertices, about \
             {bytes}, over the memory limit of {} or the 2^32 vertex cap: use a smaller box or \
             a larger edge",
            crate::memory::human_bytes(ctx.max_memory)
        )));
    }
    let spans = row_spans(ctx.tri, near, &lo, &hi, &n);
    let total: usize = spans.iter().map(|s| s.2 as usize).sum();
    // On the CPU, a bit per vertex also marks the vertices of S.
    let marks = if device { 0 } else { total.div_ceil(8) as u64 };
    let need = total as u64 * vertex_bytes(ctx, device) + marks + spans.len() as u64 * 32;
    if need > ctx.max_memory {
        return Err(Error::Trace(format!(
            "the exhaustive scan of this box needs {total} lattice vertices, about {}, over \
             the memory limit of {}: use a smaller box or a larger edge",
            crate::memory::human_bytes(need),
            crate::memory::human_bytes(ctx.max_memory)
        )));
    }
    let mut offset = 0;
    let rows = spans
        .into_iter()
        .map(|(id, start, len)| {
            let row = Row {
                id,
                start,
                len,
                offset,
            };
            offset += len as usize;
            row
        })
        .collect();
    Ok(ScanGrid {
        lo,
        n,
        rows,
        total,
        k: ctx.k,
        values: Vec::new(),
        bounds: Vec::new(),
        codes: Vec::new(),
    })
}

/// The rows of lattice vertices whose position lies in `near`: per row, its id (the
/// coordinates on axes 1..d-1 in the mixed radix `n[1..]` from `lo`), the first u_0 and the
/// count, sorted by id. `lo..=hi` bounds the lattice coordinates of those vertices.
pub(crate) fn row_spans(
    tri: &Triangulation,
    near: &[[f64; 2]],
    lo: &[i64],
    hi: &[i64],
    n: &[usize],
) -> Vec<(usize, i64, u32)> {
    let d = tri.dim();
    let step = axis0_step(tri);
    // Per row, the u_0 interval where the vertex lies in the grown box.
    let span = |r: usize, x: &[f64]| -> Option<(usize, i64, u32)> {
        let (s, e) = axis0_span(x, &step, near, (lo[0], hi[0] + 1))?;
        Some((r, s, (e - s + 1) as u32))
    };
    let walk = RowWalk::new(tri, tri.matrix(), lo, n, near);
    if d == 1 {
        let mut origin = [0.0];
        tri.vertex_coords(&[0], &mut origin);
        return span(0, &origin).into_iter().collect();
    }
    // The values of the top axis in parallel, each walked depth first: rows come out sorted
    // by id.
    let mut s = [0.0; MAX_DIM];
    s[..d].copy_from_slice(tri.offset());
    let (first, last) = walk.values(d - 1, &s).unwrap_or((1, 0));
    (first..=last)
        .into_par_iter()
        .flat_map_iter(|t| {
            let mut u = [0i64; MAX_DIM];
            u[d - 1] = t;
            let mut out = Vec::new();
            walk.rows(d - 1, &mut u, &s, &mut |id, x| out.extend(span(id, x)));
            out
        })
        .collect()
}

/// The step in R^d of one unit along lattice axis 0.
fn axis0_step(tri: &Triangulation) -> Vec<f64> {
    let d = tri.dim();
    let mut v = vec![0i32; d];
    let mut origin = vec![0.0; d];
    tri.vertex_coords(&v, &mut origin);
    v[0] = 1;
    let mut step = vec![0.0; d];
    tri.vertex_coords(&v, &mut step);
    for (s, o) in step.iter_mut().zip(&origin) {
        *s -= o;
    }
    step
}

/// The integers u_0 in `from..=to` with `x + u_0 step` in `bbox` (as an interval), if any.
fn axis0_span(
    x: &[f64],
    step: &[f64],
    bbox: &[[f64; 2]],
    (from, to): (i64, i64),
) -> Option<(i64, i64)> {
    let (mut t0, mut t1) = (from as f64, to as f64);
    for ((&[a, b], &xi), &si) in bbox.iter().zip(x).zip(step) {
        if si == 0.0 {
            if xi < a || xi > b {
                return None;
            }
        } else {
            let (p, q) = ((a - xi) / si, (b - xi) / si);
            t0 = t0.max(p.min(q));
            t1 = t1.min(p.max(q));
        }
    }
    let (s, e) = (t0.ceil() as i64, t1.floor() as i64);
    (e >= s).then_some((s, e))
}

/// Sets [`BASE`] on the vertices within `near` (the box grown by an edge): an interval of
/// each row. `near` is padded against rounding: a few more cubes are scanned, none fewer.
fn mark_bases(tri: &Triangulation, grid: &mut ScanGrid, near: &[[f64; 2]]) {
    let d = grid.dim();
    let scale = near
        .iter()
        .map(|[l, h]| l.abs().max(h.abs()))
        .fold(tri.edge(), f64::max);
    let pad = 1e-9 * scale;
    let near: Vec<[f64; 2]> = near.iter().map(|[l, h]| [l - pad, h + pad]).collect();
    let step = axis0_step(tri);
    let mut codes = std::mem::take(&mut grid.codes);
    let mut rows = Vec::with_capacity(grid.rows.len());
    let mut rest = &mut codes[..];
    for row in &grid.rows {
        let (own, next) = rest.split_at_mut(row.len as usize);
        rows.push((*row, own));
        rest = next;
    }
    rows.into_par_iter().for_each(|(row, codes)| {
        let mut v = [0i32; MAX_DIM];
        grid.row_coords(row.id, &mut v[..d]);
        v[0] = 0;
        let mut x = [0.0; MAX_DIM];
        tri.vertex_coords(&v[..d], &mut x[..d]);
        let last = row.start + row.len as i64 - 1;
        if let Some((s, e)) = axis0_span(&x[..d], &step, &near, (row.start, last)) {
            for code in &mut codes[(s - row.start) as usize..=(e - row.start) as usize] {
                *code |= BASE;
            }
        }
    });
    grid.codes = codes;
}

/// The depth-first walk over the rows that can hold vertices in a box: on each axis from d - 1
/// down to 1, exactly the values of u_j for which some real u_0..u_{j-1} put x = b + A u in
/// the box (padded against rounding).
///
/// With u_j..u_{d-1} fixed, x sweeps the affine subspace s + V_j, V_j spanned by the columns
/// A_0..A_{j-1}; it meets the box B iff the projection of s along V_j lies in the projection
/// of B, a zonotope. Its facets have the normals n orthogonal to V_j and to d - 1 - j of the
/// coordinate axes, so the test is n . s in [min n . B, max n . B] for each such n: a slab.
struct RowWalk<'a> {
    tri: &'a Triangulation,
    a: Vec<f64>,
    lo: &'a [i64],
    n: &'a [usize],
    /// Per axis j >= 1, the slabs of its facet normals.
    slabs: Vec<Vec<Slab>>,
}

/// n . x in [lo, hi] for x in the padded box; `along` is n . A_j, for the axis j chosen
/// (0 where A_j is parallel to the facet).
#[derive(Clone, Copy)]
struct Slab {
    n: [f64; MAX_DIM],
    along: f64,
    lo: f64,
    hi: f64,
}

impl<'a> RowWalk<'a> {
    /// The walk for x = b + A u (`a`: A, row-major) over the axis ranges `lo`, `n`.
    fn new(
        tri: &'a Triangulation,
        a: Vec<f64>,
        lo: &'a [i64],
        n: &'a [usize],
        near: &'a [[f64; 2]],
    ) -> Self {
        let d = tri.dim();
        let scale = near
            .iter()
            .chain(std::iter::once(&[tri.edge(), 0.0]))
            .map(|[l, h]| l.abs().max(h.abs()))
            .fold(1.0, f64::max);
        let pad = 1e-9 * scale;
        let column = |i: usize| -> Vec<f64> { (0..d).map(|r| a[r * d + i]).collect() };
        let slabs = (0..d)
            .map(|j| {
                let span: Vec<Vec<f64>> = (0..j).map(column).collect();
                let aj = column(j);
                facet_normals(&span, d)
                    .into_iter()
                    .map(|v| {
                        let mut n = [0.0; MAX_DIM];
                        n[..d].copy_from_slice(&v);
                        let (mut lo, mut hi) = (0.0, 0.0);
                        for (r, [l, h]) in near.iter().enumerate() {
                            let (p, q) = (n[r] * (l - pad), n[r] * (h + pad));
                            lo += p.min(q);
                            hi += p.max(q);
                        }
                        // n is a unit vector: A_j nearly orthogonal to it counts as
                        // parallel to the facet.
                        let along: f64 = v.iter().zip(&aj).map(|(x, y)| x * y).sum();
                        let along = if along.abs() <= 1e-12 * norm(&aj) {
                            0.0
                        } else {
                            along
                        };
                        Slab { n, along, lo, hi }
                    })
                    .collect()
            })
            .collect();
        RowWalk {
            tri,
            a,
            lo,
            n,
            slabs,
        }
    }

    /// The values of u_j (j >= 1) from which the box can be reached, where `s` is b plus the
    /// contribution of the axes above j.
    fn values(&self, j: usize, s: &[f64]) -> Option<(i64, i64)> {
        let d = self.tri.dim();
        let (mut t0, mut t1) = (
            self.lo[j] as f64,
            (self.lo[j] + self.n[j] as i64 - 1) as f64,
        );
        for slab in &self.slabs[j] {
            let ns: f64 = slab.n[..d].iter().zip(&s[..d]).map(|(x, y)| x * y).sum();
            let (below, above) = (slab.lo - ns, slab.hi - ns);
            if slab.along == 0.0 {
                if below > 0.0 || above < 0.0 {
                    return None;
                }
            } else {
                let (p, q) = (below / slab.along, above / slab.along);
                t0 = t0.max(p.min(q));
                t1 = t1.min(p.max(q));
            }
        }
        let (first, last) = (t0.ceil() as i64, t1.floor() as i64);
        (last >= first).then_some((first, last))
    }

    /// Calls `row(id, x)` for every row reached below axis j, where u holds the axes above
    /// and at j and `s` is b plus the contribution of the axes above j; x is the row's vertex
    /// with u_0 = 0.
    fn rows(
        &self,
        j: usize,
        u: &mut [i64; MAX_DIM],
        s: &[f64],
        row: &mut dyn FnMut(usize, &[f64]),
    ) {
        let d = self.tri.dim();
        let mut t_s = [0.0; MAX_DIM];
        for r in 0..d {
            t_s[r] = s[r] + self.a[r * d + j] * u[j] as f64;
        }
        if j == 1 {
            let mut v = [0i32; MAX_DIM];
            let mut id = 0;
            let mut stride = 1;
            for i in 1..d {
                v[i] = u[i] as i32;
                id += (u[i] - self.lo[i]) as usize * stride;
                stride *= self.n[i];
            }
            let mut x = [0.0; MAX_DIM];
            self.tri.vertex_coords(&v[..d], &mut x[..d]);
            row(id, &x[..d]);
            return;
        }
        if let Some((first, last)) = self.values(j - 1, &t_s) {
            for t in first..=last {
                u[j - 1] = t;
                self.rows(j - 1, u, &t_s, row);
            }
        }
    }
}

/// The scan's grid for `bbox`: vertices within two edges of it, f at each (through the
/// oracle), and sign codes, with [`BASE`] on the vertices within one edge of it (every
/// k-simplex that can meet the box is based at one of those, and its cube's corners lie in
/// the grid).
pub(crate) fn build(ctx: &TraceContext, bbox: &[[f64; 2]]) -> Result<ScanGrid> {
    build_with(ctx, bbox, ctx.oracle.scans().device_values())
}

/// The scan's grid for `bbox` with the CPU's values of f, whatever the oracle.
pub(crate) fn build_on_cpu(ctx: &TraceContext, bbox: &[[f64; 2]]) -> Result<ScanGrid> {
    build_with(ctx, bbox, None)
}

fn build_with(
    ctx: &TraceContext,
    bbox: &[[f64; 2]],
    device: Option<&dyn crate::trace::DeviceValues>,
) -> Result<ScanGrid> {
    let (mut grid, near_base) = plan_rows(ctx, bbox, device.is_some())?;
    let (total, k) = (grid.total, ctx.k);
    grid.values = vec![0.0; total * k];
    if device.is_some() {
        grid.bounds = vec![0.0; total * k];
    }
    grid.codes = vec![0; total];
    evaluate(ctx, &mut grid, 0..total, device).map_err(|(_, e)| e)?;
    mark_bases(ctx.tri, &mut grid, &near_base);
    Ok(grid)
}

/// The rows of the scan's grid for `bbox` (vertices within two edges of it; no values yet),
/// and the box grown by an edge (where the scanned cubes are based).
fn plan_rows(
    ctx: &TraceContext,
    bbox: &[[f64; 2]],
    device: bool,
) -> Result<(ScanGrid, Vec<[f64; 2]>)> {
    let d = ctx.d;
    if d > MAX_SCAN_DIM {
        return Err(Error::Trace(format!(
            "the exhaustive scan handles d <= {MAX_SCAN_DIM} (d = {d}); trace from seeds instead"
        )));
    }
    let edge = ctx.tri.edge();
    let grown =
        |r: f64| -> Vec<[f64; 2]> { bbox.iter().map(|[lo, hi]| [lo - r, hi + r]).collect() };
    let grid = near_rows(ctx, &grown(2.0 * edge + 1e-9 * (1.0 + edge)), device)?;
    let total = grid.total;
    if total >= u32::MAX as usize {
        return Err(Error::Trace(format!(
            "the exhaustive scan of this box needs {total} lattice vertices (> 2^32): use a \
             smaller box or a larger edge"
        )));
    }
    Ok((grid, grown(edge)))
}

/// f (through the oracle, or certified values from `device`) and the sign codes at the
/// vertices `range` of `grid`, whose arrays already have room for them. An error comes with
/// how many of them were done.
fn evaluate(
    ctx: &TraceContext,
    grid: &mut ScanGrid,
    range: Range<usize>,
    device: Option<&dyn crate::trace::DeviceValues>,
) -> std::result::Result<(), (usize, Error)> {
    let (d, k) = (ctx.d, ctx.k);
    let mut pairs = Vec::new();
    for start in range.clone().step_by(EVAL_STEP) {
        let done = |e| (start - range.start, e);
        super::cancelled(ctx).map_err(done)?;
        let end = (start + EVAL_STEP).min(range.end);
        let mut lattice = vec![0i32; (end - start) * d];
        lattice
            .par_chunks_mut(FILL * d)
            .enumerate()
            .for_each(|(c, v)| {
                let from = start + c * FILL;
                grid.fill_coords(from..from + v.len() / d, v)
            });
        let values = &mut grid.values[start * k..end * k];
        if let Some(device) = device {
            pairs.resize(2 * (end - start) * k, 0.0);
            device
                .eval_certified(ctx.tri, &lattice, &mut pairs)
                .map_err(done)?;
            let bounds = &mut grid.bounds[start * k..end * k];
            values
                .par_iter_mut()
                .zip(bounds.par_iter_mut())
                .zip(pairs.par_chunks(2))
                .for_each(|((v, e), p)| (*v, *e) = (p[0], p[1]));
            grid.codes[start..end]
                .par_iter_mut()
                .zip(values.par_chunks(k).zip(bounds.par_chunks(k)))
                .for_each(|(code, (f, e))| *code = bounded_sign_code(f, e));
        } else {
            ctx.oracle
                .values()
                .eval_vertices(ctx.tri, &lattice, values)
                .map_err(done)?;
            grid.codes[start..end]
                .par_iter_mut()
                .zip(values.par_chunks(k))
                .for_each(|(code, f)| *code = sign_code(f));
        }
    }
    Ok(())
}

/// The scan's grid in slabs along the top lattice axis, with the CPU's values: each slab's
/// window holds its own rows (whole layers of equal top coordinate, at least a given number
/// of vertices) and the next layer, whose vertices are corners of its top
/// cubes. Only the cubes based in a slab's own rows are scanned in it, so every cube is
/// scanned once, and f is evaluated once per vertex: the next window starts with the layer
/// the last one ended with, copied. Memory holds one window, not the grid.
pub(crate) struct Slabs<'c, 'a> {
    ctx: &'c TraceContext<'a>,
    /// Every row (no values).
    whole: ScanGrid,
    /// The box grown by an edge: where the scanned cubes are based.
    near_base: Vec<[f64; 2]>,
    /// Per slab: its first row, the end of its own rows, the end of its window's rows.
    plan: Vec<(usize, usize, usize)>,
}

/// A slab's window: a grid of its own (vertex indices from the slab's first vertex), whose
/// first `own` vertices are the slab's own, whose first `kept` were copied from the last
/// window, and at how many of whose vertices f was evaluated.
pub(crate) struct Window {
    pub grid: ScanGrid,
    pub own: usize,
    pub kept: usize,
    pub evaluated: usize,
}

impl<'c, 'a> Slabs<'c, 'a> {
    /// The slabs of the scan of `bbox`, each holding at least `vertices` (but the last).
    pub(crate) fn new(
        ctx: &'c TraceContext<'a>,
        bbox: &[[f64; 2]],
        vertices: usize,
    ) -> Result<Self> {
        let (whole, near_base) = plan_rows(ctx, bbox, false)?;
        let rows = &whole.rows;
        let d = whole.dim();
        let layer_stride = if d >= 2 {
            whole.stride(d - 1)
        } else {
            usize::MAX
        };
        let top = |r: usize| rows[r].id.checked_div(layer_stride).unwrap_or(0);
        let layer_end = |mut r: usize| {
            let t = top(r);
            while r < rows.len() && top(r) == t {
                r += 1;
            }
            r
        };
        let mut plan = Vec::new();
        let mut a = 0;
        while a < rows.len() {
            let mut b = layer_end(a);
            while b < rows.len() && rows[b].offset - rows[a].offset < vertices {
                b = layer_end(b);
            }
            let c = if b < rows.len() && top(b) == top(b - 1) + 1 {
                layer_end(b)
            } else {
                b
            };
            plan.push((a, b, c));
            a = b;
        }
        Ok(Slabs {
            ctx,
            whole,
            near_base,
            plan,
        })
    }

    /// How many slabs there are.
    pub(crate) fn len(&self) -> usize {
        self.plan.len()
    }

    /// The storage offset of row `r` of the whole grid (its total past the last row).
    fn offset(&self, r: usize) -> usize {
        self.whole
            .rows
            .get(r)
            .map_or(self.whole.total, |row| row.offset)
    }

    /// Slab `i`'s window, not evaluated yet ([`Slabs::evaluate`]). `prev` is slab i - 1's
    /// window, whose buffers it reuses and whose last layer (its first) it copies instead of
    /// evaluating f there again.
    pub(crate) fn window(&self, i: usize, prev: Option<Window>) -> Window {
        let (a, b, c) = self.plan[i];
        let base = self.offset(a);
        let (len, own) = (self.offset(c) - base, self.offset(b) - base);
        let k = self.whole.k;
        let (mut values, mut codes, kept) = match prev {
            Some(Window {
                grid, own: last, ..
            }) => {
                let (mut values, mut codes) = (grid.values, grid.codes);
                // Slab i - 1's window ends with slab i's first layer, or with its own rows.
                let kept = if self.plan[i - 1].2 > a {
                    values.copy_within(last * k.., 0);
                    codes.copy_within(last.., 0);
                    grid.total - last
                } else {
                    0
                };
                (values, codes, kept)
            }
            None => (Vec::new(), Vec::new(), 0),
        };
        values.resize(len * k, 0.0);
        codes.resize(len, 0);
        let grid = ScanGrid {
            lo: self.whole.lo.clone(),
            n: self.whole.n.clone(),
            rows: self.whole.rows[a..c]
                .iter()
                .map(|row| Row {
                    offset: row.offset - base,
                    ..*row
                })
                .collect(),
            total: len,
            k,
            values,
            bounds: Vec::new(),
            codes,
        };
        Window {
            grid,
            own,
            kept,
            evaluated: 0,
        }
    }

    /// f and the sign codes at the vertices of `window` that its last one did not hold.
    /// Interrupted (Ctrl-C), an error, and the window holds f's values at its first `kept`
    /// vertices only.
    pub(crate) fn evaluate(&self, window: &mut Window) -> Result<()> {
        let range = window.kept..window.grid.total;
        let done = evaluate(self.ctx, &mut window.grid, range.clone(), None);
        window.evaluated = done.as_ref().map_or_else(|(n, _)| *n, |()| range.len());
        done.map_err(|(_, e)| e)?;
        mark_bases(self.ctx.tri, &mut window.grid, &self.near_base);
        Ok(())
    }
}

/// A power of ten to print: `log10` rounded, "more than 308" past f64's range.
fn about_power(log10: f64) -> String {
    if log10.is_finite() && log10 < 308.0 {
        format!("{:.0}", log10)
    } else {
        "308 or more".into()
    }
}

/// Unit normals n (one per sign pair) orthogonal to the vectors `span` (j of them, in R^d)
/// and to d - 1 - j coordinate axes: the facet normals of the projection of a box along
/// span. Subsets of axes that leave more than one direction free give none.
fn facet_normals(span: &[Vec<f64>], d: usize) -> Vec<Vec<f64>> {
    let j = span.len();
    let mut out = Vec::new();
    // The axes a normal may use: j + 1 of the d, the others are orthogonal to it.
    for mask in 0u32..1 << d {
        if mask.count_ones() as usize != j + 1 {
            continue;
        }
        let q: Vec<usize> = (0..d).filter(|&r| mask >> r & 1 == 1).collect();
        // An orthonormal basis of the span restricted to those axes.
        let mut basis: Vec<Vec<f64>> = Vec::new();
        for v in span {
            let mut w: Vec<f64> = q.iter().map(|&r| v[r]).collect();
            let before = norm(&w);
            orthogonalize(&mut w, &basis);
            let after = norm(&w);
            if after <= 1e-10 * before.max(f64::MIN_POSITIVE) {
                break;
            }
            basis.push(w.iter().map(|x| x / after).collect());
        }
        if basis.len() < j {
            continue;
        }
        // The direction left: the axis vector with the largest residual, projected.
        let (size, w) = (0..=j)
            .map(|t| {
                let mut w = vec![0.0; j + 1];
                w[t] = 1.0;
                orthogonalize(&mut w, &basis);
                (norm(&w), w)
            })
            .fold((f64::NEG_INFINITY, Vec::new()), |best, c| {
                if c.0 > best.0 {
                    c
                } else {
                    best
                }
            });
        let mut n = vec![0.0; d];
        for (&r, x) in q.iter().zip(&w) {
            n[r] = x / size;
        }
        out.push(n);
    }
    out
}

/// Removes from `w` its components along the orthonormal `basis` (modified Gram-Schmidt,
/// twice for accuracy).
fn orthogonalize(w: &mut [f64], basis: &[Vec<f64>]) {
    for _ in 0..2 {
        for b in basis {
            let dot: f64 = w.iter().zip(b).map(|(x, y)| x * y).sum();
            w.iter_mut().zip(b).for_each(|(x, y)| *x -= dot * y);
        }
    }
}

/// The Euclidean norm.
fn norm(w: &[f64]) -> f64 {
    w.iter().map(|x| x * x).sum::<f64>().sqrt()
}
