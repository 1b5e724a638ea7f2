//! What the complex is, topologically: cell counts, Euler characteristic, manifoldness,
//! boundary, components, orientability (m = 2) and Betti numbers mod 2 (m <= 3).

use std::sync::atomic::{AtomicBool, Ordering};

use hashbrown::HashMap;
use serde::Serialize;

use super::{Complex, Surface};

/// Offenders listed by name in a report (all are counted).
pub const MAX_LISTED_OFFENDERS: usize = 20;

/// An (m-1)-cell without the right number of m-cells around it.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct Offender {
    /// Its index among the (m-1)-cells (a vertex index when m = 1).
    pub cell: usize,
    /// Whether it lies on the boundary (then it needs 1 coface, else 2).
    pub on_boundary: bool,
    /// The m-cells it has.
    pub cofaces: usize,
}

/// ```
/// let torus = isomesh::Mesher::preset("torus", &[])?.edge(0.1).trace()?;
/// let t = torus.topology()?;
/// assert!(t.manifold && t.closed);
/// assert_eq!(t.euler_characteristic, 0);
/// assert_eq!(t.betti_mod2, Some(vec![1, 2, 1]));
/// # Ok::<(), isomesh::Error>(())
/// ```
/// The topology report of a complex.
#[derive(Clone, Debug, Serialize)]
pub struct Topology {
    /// m.
    pub dim: usize,
    /// Cells per dimension 0..=m.
    pub cells: Vec<usize>,
    /// Alternating sum of `cells`.
    pub euler_characteristic: i64,
    /// Every (m-1)-cell has two m-cells around it (one on the boundary), and no edge was
    /// left out (`defects`).
    pub manifold: bool,
    /// Edges left out while building (see [`super::ComplexStats::defects`]).
    pub defects: usize,
    /// The first offenders of the manifold check.
    pub offenders: Vec<Offender>,
    /// How many offenders there are.
    pub offender_count: usize,
    /// No boundary cell.
    pub closed: bool,
    /// Boundary cells per dimension 0..m.
    pub boundary_cells: Vec<usize>,
    /// Euler characteristic of the boundary.
    pub boundary_euler_characteristic: i64,
    /// Connected components.
    pub components: usize,
    /// Components without boundary.
    pub closed_components: usize,
    /// For surfaces (m = 2): whether the polygons can be oriented consistently.
    pub orientable: Option<bool>,
    /// b_0..b_m over Z/2, for manifolds with m <= 3.
    pub betti_mod2: Option<Vec<usize>>,
}

fn euler(counts: &[usize]) -> i64 {
    counts
        .iter()
        .enumerate()
        .map(|(j, &c)| if j % 2 == 0 { c as i64 } else { -(c as i64) })
        .sum()
}

/// A union-find over 0..n with path halving.
pub(crate) struct UnionFind(Vec<u32>);

impl UnionFind {
    pub fn new(n: usize) -> Self {
        UnionFind((0..n as u32).collect())
    }
    pub fn find(&mut self, mut x: u32) -> u32 {
        while self.0[x as usize] != x {
            let p = self.0[self.0[x as usize] as usize];
            self.0[x as usize] = p;
            x = p;
        }
        x
    }
    /// Joins the classes of a and b; whether they were apart.
    pub fn union(&mut self, a: u32, b: u32) -> bool {
        let (a, b) = (self.find(a), self.find(b));
        if a == b {
            return false;
        }
        let (lo, hi) = if a < b { (a, b) } else { (b, a) };
        self.0[hi as usize] = lo;
        true
    }
}

/// Faces reduced between two looks at the cancel flag.
const CANCEL_EVERY: usize = 4096;

/// The topology of `c`; `None` once `cancel` is set (checked between stages and every
/// [`CANCEL_EVERY`] faces of the homology reduction).
pub(super) fn analyse(c: &Complex, cancel: &AtomicBool) -> Option<Topology> {
    let cancelled = || cancel.load(Ordering::Relaxed);
    let m = c.dim();
    let cells = c.counts();
    let boundary_cells = c.boundary_counts();
    let nv = c.vertex_count();

    // Manifold check: cofaces of the (m-1)-cells.
    let ridges = if m == 1 { nv } else { c.level(m - 1).len() };
    let ridge_on_boundary = |i: usize| {
        if m == 1 {
            i >= c.interior_vertex_count()
        } else {
            c.level(m - 1).on_boundary(i)
        }
    };
    let mut cofaces = vec![0u32; ridges];
    let top = c.level(m);
    for i in 0..top.len() {
        for &f in top.facets(i) {
            cofaces[f as usize] += 1;
        }
    }
    let mut offenders = Vec::new();
    let mut offender_count = 0;
    for (i, &n) in cofaces.iter().enumerate() {
        let b = ridge_on_boundary(i);
        if n != if b { 1 } else { 2 } {
            offender_count += 1;
            if offenders.len() < MAX_LISTED_OFFENDERS {
                offenders.push(Offender {
                    cell: i,
                    on_boundary: b,
                    cofaces: n as usize,
                });
            }
        }
    }
    let manifold = offender_count == 0 && c.stats.defects == 0;
    if cancelled() {
        return None;
    }

    // Components over the edges; those with a boundary vertex are not closed.
    let mut uf = UnionFind::new(nv);
    let edges = c.level(1);
    for i in 0..edges.len() {
        if let [a, b] = edges.facets(i) {
            uf.union(*a, *b);
        }
    }
    let roots: Vec<u32> = (0..nv as u32).map(|v| uf.find(v)).collect();
    let components = roots
        .iter()
        .enumerate()
        .filter(|(v, &r)| r == *v as u32)
        .count();
    let mut open = vec![false; nv];
    for &r in &roots[c.interior_vertex_count()..] {
        open[r as usize] = true;
    }
    let closed_components = roots
        .iter()
        .enumerate()
        .filter(|(v, &r)| r == *v as u32 && !open[r as usize])
        .count();

    if cancelled() {
        return None;
    }
    let orientable = (m == 2).then(|| Surface::new(c, None).orientable);
    let chi = euler(&cells);
    let betti_mod2 = if manifold && m <= 3 {
        let b0 = components;
        Some(match m {
            1 => vec![b0, (cells[1] + b0).saturating_sub(nv)],
            2 => vec![b0, h1_mod2(c, cancel)?, closed_components],
            _ => {
                let b1 = h1_mod2(c, cancel)?;
                let b3 = closed_components;
                let b2 = chi - b0 as i64 + b1 as i64 + b3 as i64;
                vec![b0, b1, b2.max(0) as usize, b3]
            }
        })
    } else {
        None
    };
    if cancelled() {
        return None;
    }
    Some(Topology {
        dim: m,
        euler_characteristic: chi,
        cells,
        manifold,
        defects: c.stats.defects,
        offenders,
        offender_count,
        closed: boundary_cells.iter().all(|&n| n == 0),
        boundary_euler_characteristic: euler(&boundary_cells),
        boundary_cells,
        components,
        closed_components,
        orientable,
        betti_mod2,
    })
}

/// dim H_1(M-hat; Z/2), from the 2-skeleton: the edges off a spanning forest generate, the
/// 2-cells relate. Relations with one or two live generators kill or identify them (this
/// collapses most of the complex); the rest are reduced by sparse elimination. `None` once
/// `cancel` is set.
fn h1_mod2(c: &Complex, cancel: &AtomicBool) -> Option<usize> {
    let mut seen = 0usize;
    let mut cancelled = || {
        seen += 1;
        seen % CANCEL_EVERY == 0 && cancel.load(Ordering::Relaxed)
    };
    let nv = c.vertex_count();
    let edges = c.level(1);
    let mut forest = UnionFind::new(nv);
    const TREE: u32 = u32::MAX;
    let mut generator = vec![TREE; edges.len()];
    let mut g = 0u32;
    for (i, gen) in generator.iter_mut().enumerate() {
        if let [a, b] = edges.facets(i) {
            if !forest.union(*a, *b) {
                *gen = g;
                g += 1;
            }
        }
    }
    let zero = g;
    let mut classes = UnionFind::new(g as usize + 1);
    let faces = c.level(2);
    let mut pending: Vec<u32> = (0..faces.len() as u32).collect();
    let mut live = Vec::new();
    let reduce = |classes: &mut UnionFind, face: usize, live: &mut Vec<u32>| {
        live.clear();
        for &e in faces.facets(face) {
            let gen = generator[e as usize];
            if gen != TREE {
                let r = classes.find(gen);
                if r != classes.find(zero) {
                    live.push(r);
                }
            }
        }
        live.sort_unstable();
        cancel_pairs(live);
    };
    loop {
        let mut changed = false;
        let mut stop = false;
        pending.retain(|&face| {
            if stop || cancelled() {
                stop = true;
                return true;
            }
            reduce(&mut classes, face as usize, &mut live);
            match live.len() {
                0 => false,
                1 => {
                    classes.union(live[0], zero);
                    changed = true;
                    false
                }
                2 => {
                    classes.union(live[0], live[1]);
                    changed = true;
                    false
                }
                _ => true,
            }
        });
        if stop {
            return None;
        }
        if !changed {
            break;
        }
    }
    let zero_root = classes.find(zero);
    let generators = (0..g)
        .filter(|&x| classes.find(x) == x && x != zero_root)
        .count();
    // Sparse elimination of what is left, pivoting on the largest class.
    let mut pivots: HashMap<u32, Vec<u32>> = HashMap::new();
    let mut rank = 0;
    for &face in &pending {
        if cancelled() {
            return None;
        }
        reduce(&mut classes, face as usize, &mut live);
        let mut col = live.clone();
        while let Some(&p) = col.last() {
            match pivots.get(&p) {
                Some(other) => col = symmetric_difference(&col, other),
                None => break,
            }
        }
        if let Some(&p) = col.last() {
            pivots.insert(p, col);
            rank += 1;
        }
    }
    Some(generators - rank)
}

/// Removes equal neighbours two by two from a sorted list (x + x = 0 over Z/2).
fn cancel_pairs(v: &mut Vec<u32>) {
    let mut out = 0;
    let mut i = 0;
    while i < v.len() {
        if i + 1 < v.len() && v[i] == v[i + 1] {
            i += 2;
        } else {
            v[out] = v[i];
            out += 1;
            i += 1;
        }
    }
    v.truncate(out);
}

fn symmetric_difference(a: &[u32], b: &[u32]) -> Vec<u32> {
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => {
                out.push(a[i]);
                i += 1;
            }
            std::cmp::Ordering::Greater => {
                out.push(b[j]);
                j += 1;
            }
            std::cmp::Ordering::Equal => {
                i += 1;
                j += 1;
            }
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out
}
