//! Candidate generation of the exhaustive scan on the CPU, the twin of `shaders/scan.wgsl`.
//!
//! A k-simplex based at the lattice vertex v0 has the vertices v0 + e_S for a chain
//! {} = S_0 < S_1 < .. < S_k of subsets of the d axes: it lies in the unit cube at v0. It can
//! be crossed only where every component of f has a value <= 0 and a value >= 0 at its
//! vertices, and those are all the scan reads of f: a sign code per vertex, two bits per
//! component. The codes of a set of vertices are OR-ed, and the set passes when every
//! component has both bits. Integer operations only, so the GPU generates exactly these
//! candidates.
//!
//! Per cube: the storage index of each of its 2^d corners, the OR of the codes over the
//! supersets of every corner set (when the whole cube fails, nothing else is done), then the
//! chains depth first, in increasing order of (S_1, .., S_k), pruned where the chain so far
//! and every superset of its last set cannot pass together.

use std::ops::Range;

use rayon::prelude::*;

use super::ScanGrid;

/// The code bit of vertices whose cube is scanned (within one edge of the box).
pub const BASE: u32 = 1 << 31;
/// Largest k for sign codes (two bits per component, below [`BASE`]).
pub const MAX_CODE_COMPONENTS: usize = 15;

/// The sign code of f's values at one vertex: bit 2c when component c is <= 0, bit 2c + 1
/// when it is >= 0 (both at an exact zero, neither at NaN).
#[inline]
pub fn sign_code(values: &[f64]) -> u32 {
    values.iter().enumerate().fold(0, |code, (c, &v)| {
        code | ((v <= 0.0) as u32) << (2 * c) | ((v >= 0.0) as u32) << (2 * c + 1)
    })
}

/// The bits a passing OR of codes holds for k components.
#[inline]
pub fn pass_mask(k: usize) -> u32 {
    ((1u64 << (2 * k)) - 1) as u32
}

/// Candidate k-simplices: per candidate, k + 1 storage indices of grid vertices (the chain's
/// corners, base first) and the k corner sets S_1 < .. < S_k (bit j: axis j).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Candidates {
    /// Rows of k + 1 vertex indices.
    pub rows: Vec<u32>,
    /// Rows of k corner sets.
    pub chains: Vec<u32>,
}

impl Candidates {
    /// How many candidates there are, for codimension k.
    pub fn count(&self, k: usize) -> usize {
        self.rows.len() / (k + 1)
    }

    /// Appends `other`.
    pub fn append(&mut self, other: &mut Candidates) {
        self.rows.append(&mut other.rows);
        self.chains.append(&mut other.chains);
    }
}

/// The rows that hold a cube's corners, found once per grid row and kept for the next cubes
/// of that row (they share them: only the axis-0 position moves).
#[derive(Default)]
pub struct CornerRows {
    /// The grid row of the cubes' base vertices, and its vertex range (empty before the
    /// first lookup).
    own: usize,
    span: Range<usize>,
    /// Per subset t of axes 1..d-1, the row holding corners t << 1 and t << 1 | 1; empty
    /// when some corner row is missing (no cube of the row is whole).
    rows: Vec<usize>,
    /// Scratch for the corners' storage indices and the supersets' codes.
    scratch: Vec<u32>,
}

impl CornerRows {
    /// Looks up the corner rows of the cubes based in the grid row of vertex `cube`, unless
    /// they are the ones held.
    fn locate(&mut self, grid: &ScanGrid, cube: usize) {
        if self.span.contains(&cube) {
            return;
        }
        let d = grid.dim();
        let all = grid.rows();
        let r = grid.row_of(cube);
        let own = all[r];
        (self.own, self.span) = (r, own.offset..own.offset + own.len as usize);
        self.rows.clear();
        let top = grid.top_axes(own.id);
        for t in 0..1usize << (d - 1) {
            let id = own.id
                + (1..d)
                    .filter(|&j| t >> (j - 1) & 1 == 1)
                    .map(|j| grid.stride(j))
                    .sum::<usize>();
            match (t as u32 & top == 0).then(|| grid.find_row(id)).flatten() {
                Some(found) => self.rows.push(found),
                None => {
                    self.rows.clear();
                    return;
                }
            }
        }
    }
}

/// Storage index of every corner of the cube based at vertex `cube` (corner set s, bit j: +1
/// on axis j) into `corner`; false when a corner is not in the grid. Rows are looked up once
/// per grid row and subset of axes 1..d-1 (`rows` keeps them); the axis-0 step is the next
/// vertex of a row.
pub fn cube_corners(
    grid: &ScanGrid,
    cube: usize,
    rows: &mut CornerRows,
    corner: &mut [u32],
) -> bool {
    rows.locate(grid, cube);
    if rows.rows.is_empty() {
        return false;
    }
    let all = grid.rows();
    let own = all[rows.own];
    let u0 = own.start + (cube - own.offset) as i64;
    for (t, &r) in rows.rows.iter().enumerate() {
        let row = all[r];
        for b in 0..2 {
            let u = u0 + b as i64;
            if u < row.start || u >= row.start + row.len as i64 {
                return false;
            }
            corner[t << 1 | b] = (row.offset as i64 + u - row.start) as u32;
        }
    }
    true
}

/// Appends the candidates of the cube based at vertex `cube` to `out`; `rows` is reused
/// across calls (fastest over consecutive cubes).
pub fn cube_candidates(grid: &ScanGrid, cube: usize, rows: &mut CornerRows, out: &mut Candidates) {
    let codes = grid.codes();
    if codes[cube] & BASE == 0 {
        return;
    }
    let (d, k) = (grid.dim(), grid.codim());
    let corners = 1usize << d;
    let mut scratch = std::mem::take(&mut rows.scratch);
    scratch.resize(2 * corners, 0);
    let (corner, sup) = scratch.split_at_mut(corners);
    if cube_corners(grid, cube, rows, corner) {
        chains(codes, k, corner, sup, out);
    }
    rows.scratch = scratch;
}

/// The passing chains of one cube whose corners' storage indices are `corner`; `sup` is
/// scratch of the same length.
pub(crate) fn chains(
    codes: &[u32],
    k: usize,
    corner: &[u32],
    sup: &mut [u32],
    out: &mut Candidates,
) {
    let corners = corner.len();
    let d = corners.trailing_zeros() as usize;
    let mask = pass_mask(k);
    // The whole cube first: most fail, and the OR over supersets is d times the work.
    let mut any = 0;
    for s in 0..corners {
        sup[s] = codes[corner[s] as usize];
        any |= sup[s];
    }
    if any & mask != mask {
        return;
    }
    for j in 0..d {
        for s in 0..corners {
            if s & (1 << j) == 0 {
                sup[s] |= sup[s | 1 << j];
            }
        }
    }
    // Depth first over chains; at depth i the chain holds sets[0..=i] and their codes' OR.
    let full = (corners - 1) as u32;
    let code = |s: u32| codes[corner[s as usize] as usize];
    let mut sets = [0u32; MAX_CODE_COMPONENTS + 1];
    let mut run = [0u32; MAX_CODE_COMPONENTS + 1];
    let mut add = [0u32; MAX_CODE_COMPONENTS + 1];
    run[0] = code(0);
    let mut depth = 0;
    let mut descend = true;
    loop {
        if descend {
            let s = sets[depth];
            let free = full & !s;
            if depth == k {
                if run[k] & mask == mask {
                    out.rows
                        .extend(sets[..=k].iter().map(|&s| corner[s as usize]));
                    out.chains.extend_from_slice(&sets[1..=k]);
                }
            } else if (run[depth] | sup[s as usize]) & mask == mask
                && free.count_ones() as usize >= k - depth
            {
                add[depth] = free & free.wrapping_neg();
                sets[depth + 1] = s | add[depth];
                run[depth + 1] = run[depth] | code(sets[depth + 1]);
                depth += 1;
                continue;
            }
            descend = false;
        }
        // Back up to the deepest set that has a next superset, in increasing order.
        if depth == 0 {
            return;
        }
        depth -= 1;
        let s = sets[depth];
        let free = full & !s;
        if add[depth] == free {
            continue;
        }
        add[depth] = add[depth].wrapping_sub(free) & free;
        sets[depth + 1] = s | add[depth];
        run[depth + 1] = run[depth] | code(sets[depth + 1]);
        depth += 1;
        descend = true;
    }
}

/// Cubes per block of [`range_candidates`]' first pass.
const BLOCK: usize = 256;

/// Appends the candidates of the cubes based at the vertices `cubes` to `out`, as
/// [`cube_candidates`] over each in turn does. Per grid row, a first pass ORs the codes of
/// every cube's corners over whole slices of its corner rows (straight-line code the compiler
/// vectorises); only the cubes that pass it and are scanned are walked.
fn range_candidates(
    grid: &ScanGrid,
    cubes: Range<usize>,
    rows: &mut CornerRows,
    out: &mut Candidates,
) {
    let codes = grid.codes();
    let mask = pass_mask(grid.codim());
    let all = grid.rows();
    let mut any = [0u32; BLOCK];
    let mut cube = cubes.start;
    while cube < cubes.end {
        rows.locate(grid, cube);
        let row_end = rows.span.end.min(cubes.end);
        if !rows.rows.is_empty() {
            // The cubes whose corners all lie in their rows: u_0 in lo..hi.
            let own = all[rows.own];
            let (mut lo, mut hi) = (i64::MIN, i64::MAX);
            for &r in &rows.rows {
                lo = lo.max(all[r].start);
                hi = hi.min(all[r].start + all[r].len as i64 - 1);
            }
            let index =
                |u: i64| (own.offset as i64 + u - own.start).clamp(cube as i64, row_end as i64);
            let (first, last) = (index(lo) as usize, index(hi) as usize);
            for block in (first..last).step_by(BLOCK) {
                let n = BLOCK.min(last - block);
                let u = own.start + (block - own.offset) as i64;
                any[..n].fill(0);
                for &r in &rows.rows {
                    let at = (all[r].offset as i64 + u - all[r].start) as usize;
                    let c = &codes[at..at + n + 1];
                    for i in 0..n {
                        any[i] |= c[i] | c[i + 1];
                    }
                }
                for (i, (&a, &base)) in any[..n].iter().zip(&codes[block..block + n]).enumerate() {
                    if a & mask == mask && base & BASE != 0 {
                        cube_candidates(grid, block + i, rows, out);
                    }
                }
            }
        }
        cube = row_end;
    }
}

/// The candidates of the cubes based at the vertices `cubes`, in order of base, then of
/// (S_1, .., S_k); in parallel.
pub fn candidates(grid: &ScanGrid, cubes: Range<usize>) -> Candidates {
    let chunk = cubes
        .len()
        .div_ceil(8 * rayon::current_num_threads())
        .max(256);
    let end = cubes.end;
    let parts: Vec<Candidates> = (cubes.start..end)
        .step_by(chunk)
        .collect::<Vec<_>>()
        .into_par_iter()
        .map(|start| {
            let mut rows = CornerRows::default();
            let mut out = Candidates::default();
            range_candidates(grid, start..(start + chunk).min(end), &mut rows, &mut out);
            out
        })
        .collect();
    let mut all = Candidates {
        rows: Vec::with_capacity(parts.iter().map(|p| p.rows.len()).sum()),
        chains: Vec::with_capacity(parts.iter().map(|p| p.chains.len()).sum()),
    };
    for mut p in parts {
        all.append(&mut p);
    }
    all
}
