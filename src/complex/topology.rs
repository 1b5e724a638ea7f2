//! What the complex is, topologically: cell counts, Euler characteristic, manifoldness,
//! boundary, components, orientability (m = 2) and Betti numbers mod 2 (m <= 3).

use std::sync::atomic::{AtomicBool, Ordering};

use hashbrown::HashMap;
use serde::Serialize;

use super::Complex;

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

    // The polygons' orientation (m = 2) does not depend on the components and H_1: the two
    // run side by side.
    let chi = euler(&cells);
    let (orientable, rest) = rayon::join(
        || (m == 2).then(|| c.polygons().orientable),
        || {
            // Components over the edges; those with a boundary vertex are not closed.
            let mut forest = Forest::of(c);
            let roots: Vec<u32> = (0..nv as u32).map(|v| forest.classes.find(v)).collect();
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
            let betti_mod2 = if manifold && m <= 3 {
                let b0 = components;
                Some(match m {
                    1 => vec![b0, (cells[1] + b0).saturating_sub(nv)],
                    2 => vec![b0, h1_mod2(c, &forest, cancel)?, closed_components],
                    _ => {
                        let b1 = h1_mod2(c, &forest, cancel)?;
                        let b3 = closed_components;
                        let b2 = chi - b0 as i64 + b1 as i64 + b3 as i64;
                        vec![b0, b1, b2.max(0) as usize, b3]
                    }
                })
            } else {
                None
            };
            Some((components, closed_components, betti_mod2))
        },
    );
    let (components, closed_components, betti_mod2) = rest?;
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

/// A spanning forest of the complex's edges, taken in order: the components of the vertices,
/// and the edges off the forest (each closes a cycle), numbered in order.
struct Forest {
    /// The vertices' components.
    classes: UnionFind,
    /// Per edge, its number among the edges off the forest, or [`Forest::TREE`].
    generator: Vec<u32>,
    /// How many edges are off the forest.
    generators: u32,
}

impl Forest {
    /// The number of an edge of the forest.
    const TREE: u32 = u32::MAX;

    fn of(c: &Complex) -> Self {
        let edges = c.level(1);
        let mut classes = UnionFind::new(c.vertex_count());
        let mut generator = vec![Self::TREE; edges.len()];
        let mut g = 0u32;
        for (i, gen) in generator.iter_mut().enumerate() {
            if let [a, b] = edges.facets(i) {
                if !classes.union(*a, *b) {
                    *gen = g;
                    g += 1;
                }
            }
        }
        Forest {
            classes,
            generator,
            generators: g,
        }
    }
}

/// dim H_1(M-hat; Z/2), from the 2-skeleton: the edges off a spanning forest (`forest`, of
/// `c`) generate, the 2-cells relate. Relations with one or two live generators kill or
/// identify them (this collapses most of the complex); the rest are reduced by sparse
/// elimination. `None` once `cancel` is set.
fn h1_mod2(c: &Complex, forest: &Forest, cancel: &AtomicBool) -> Option<usize> {
    h1_mod2_counted(c, forest, cancel).map(|(b1, _)| b1)
}

/// [`h1_mod2`], and how many faces the collapse left to the elimination.
fn h1_mod2_counted(c: &Complex, forest: &Forest, cancel: &AtomicBool) -> Option<(usize, usize)> {
    let mut seen = 0usize;
    let mut cancelled = || {
        seen += 1;
        seen % CANCEL_EVERY == 0 && cancel.load(Ordering::Relaxed)
    };
    const TREE: u32 = Forest::TREE;
    let (generator, g) = (&forest.generator, forest.generators);
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
    collapse(&mut pending, &mut classes, zero, &reduce, &mut cancelled)?;
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
    Some((generators - rank, pending.len()))
}

/// The shortcut of [`h1_mod2`]: relations (faces) with no live generator are dropped, with one
/// kill it, with two identify them, until none is left to do; the faces left in `pending`
/// are for the elimination. Skipping it would change no result, only the elimination's work.
/// `None` once `cancelled` says so.
fn collapse(
    pending: &mut Vec<u32>,
    classes: &mut UnionFind,
    zero: u32,
    reduce: &impl Fn(&mut UnionFind, usize, &mut Vec<u32>),
    cancelled: &mut impl FnMut() -> bool,
) -> Option<()> {
    let mut live = Vec::new();
    loop {
        let mut changed = false;
        let mut stop = false;
        pending.retain(|&face| {
            if stop || cancelled() {
                stop = true;
                return true;
            }
            reduce(classes, face as usize, &mut live);
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
            return Some(());
        }
    }
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

#[cfg(test)]
mod tests {
    use std::collections::{BTreeSet, HashMap as StdMap};

    use super::super::{ComplexStats, Level};
    use super::*;

    /// A complex from its cells given as vertex sets, `cells[j]` the j-cells for j = 1..=m
    /// (`cells[0]` is unused): facets are the (j-1)-cells inside each j-cell, an (m-1)-cell
    /// in one m-cell and every face of one is on the boundary; interior cells and vertices
    /// are numbered first, as the builder does.
    fn complex(nv: usize, cells: Vec<Vec<BTreeSet<u32>>>, defects: usize) -> Complex {
        let m = cells.len() - 1;
        // Boundary: (m-1)-cells with one coface, then their faces.
        let mut boundary: Vec<Vec<bool>> = cells.iter().map(|l| vec![false; l.len()]).collect();
        let mut vertex_on_boundary = vec![false; nv];
        let ridge_sets: Vec<BTreeSet<u32>> = if m == 1 {
            (0..nv as u32).map(|v| BTreeSet::from([v])).collect()
        } else {
            cells[m - 1].clone()
        };
        for (r, ridge) in ridge_sets.iter().enumerate() {
            let n = cells[m].iter().filter(|c| c.is_superset(ridge)).count();
            if n == 1 {
                for &v in ridge {
                    vertex_on_boundary[v as usize] = true;
                }
                if m > 1 {
                    boundary[m - 1][r] = true;
                }
            }
        }
        for j in 1..m.saturating_sub(1) {
            for i in 0..cells[j].len() {
                boundary[j][i] = ridge_sets
                    .iter()
                    .enumerate()
                    .any(|(r, s)| boundary[m - 1][r] && s.is_superset(&cells[j][i]));
            }
        }
        // Interior first.
        let mut vorder: Vec<u32> = (0..nv as u32).collect();
        vorder.sort_by_key(|&v| vertex_on_boundary[v as usize]);
        let vnew: StdMap<u32, u32> = vorder
            .iter()
            .enumerate()
            .map(|(i, &v)| (v, i as u32))
            .collect();
        let interior_vertices = vertex_on_boundary.iter().filter(|&&b| !b).count();
        let mut levels = Vec::new();
        let mut below: Vec<BTreeSet<u32>> = (0..nv as u32).map(|v| BTreeSet::from([v])).collect();
        let mut below_index: Vec<u32> = vnew.iter().fold(vec![0; nv], |mut a, (&v, &i)| {
            a[v as usize] = i;
            a
        });
        for j in 1..=m {
            let mut order: Vec<usize> = (0..cells[j].len()).collect();
            order.sort_by_key(|&i| boundary[j][i]);
            let (mut offsets, mut facets) = (vec![0u32], Vec::new());
            for &i in &order {
                for (f, s) in below.iter().enumerate() {
                    if cells[j][i].is_superset(s) && (j > 1 || s.len() == 1) {
                        facets.push(below_index[f]);
                    }
                }
                offsets.push(facets.len() as u32);
            }
            let interior = order.iter().filter(|&&i| !boundary[j][i]).count();
            levels.push(Level::from_lists(offsets, facets, interior));
            below = cells[j].clone();
            below_index = vec![0; order.len()];
            for (new, &old) in order.iter().enumerate() {
                below_index[old] = new as u32;
            }
        }
        Complex::from_parts(
            3,
            vec![0.0; 3 * nv],
            interior_vertices,
            levels,
            ComplexStats {
                defects,
                elapsed_s: 0.0,
            },
        )
    }

    /// The cubical complex of an n_1 x ... x n_m grid of unit cubes, each axis either a
    /// circle of n cubes (`wrap`), an interval of n cubes, or (`twist`, for axis 1 of 2) a
    /// circle along which axis 0 is reflected: tori, cylinders, balls, Klein bottles.
    fn grid(n: &[usize], wrap: &[bool], twist: bool) -> Complex {
        let m = n.len();
        let size: Vec<usize> = (0..m).map(|a| n[a] + usize::from(!wrap[a])).collect();
        let id = |p: &[i64]| -> u32 {
            let mut p = p.to_vec();
            if twist && p[1] >= n[1] as i64 {
                p[1] -= n[1] as i64;
                p[0] = -p[0];
            }
            let mut k = 0;
            for a in (0..m).rev() {
                let x = if wrap[a] {
                    p[a].rem_euclid(n[a] as i64)
                } else {
                    p[a]
                };
                k = k * size[a] + x as usize;
            }
            k as u32
        };
        let nv: usize = size.iter().product();
        let mut cells: Vec<Vec<BTreeSet<u32>>> = vec![Vec::new(); m + 1];
        // A j-cube: a corner and j axes; corners range over cube positions.
        for corner in 0..n.iter().map(|x| x + 1).product::<usize>() {
            let mut c = corner;
            let p: Vec<i64> = (0..m)
                .map(|a| {
                    let x = (c % (n[a] + 1)) as i64;
                    c /= n[a] + 1;
                    x
                })
                .collect();
            for axes in 1u32..1 << m {
                let ok = (0..m).all(|a| {
                    let along = axes >> a & 1 == 1;
                    let limit = if wrap[a] || along { n[a] - 1 } else { n[a] };
                    (p[a] as usize) <= limit
                });
                if !ok {
                    continue;
                }
                let j = axes.count_ones() as usize;
                let mut set = BTreeSet::new();
                for sub in 0u32..1 << m {
                    if sub & !axes == 0 {
                        let q: Vec<i64> = (0..m).map(|a| p[a] + (sub >> a & 1) as i64).collect();
                        set.insert(id(&q));
                    }
                }
                if !cells[j].contains(&set) {
                    cells[j].push(set);
                }
            }
        }
        complex(nv, cells, 0)
    }

    /// The triangles of the 6-vertex projective plane.
    fn projective_plane() -> Complex {
        let t = [
            [0, 1, 2],
            [0, 2, 3],
            [0, 3, 4],
            [0, 4, 5],
            [0, 5, 1],
            [1, 2, 4],
            [2, 3, 5],
            [3, 4, 1],
            [4, 5, 2],
            [5, 1, 3],
        ];
        let tris: Vec<BTreeSet<u32>> = t.iter().map(|t| t.iter().copied().collect()).collect();
        let mut edges = BTreeSet::new();
        for t in &t {
            for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[0], t[2])] {
                edges.insert(BTreeSet::from([a.min(b), a.max(b)]));
            }
        }
        complex(6, vec![vec![], edges.into_iter().collect(), tris], 0)
    }

    /// x_0 - x_1 + x_2 - ..., written out here rather than through `euler`.
    fn alternating(x: &[usize]) -> i64 {
        let (even, odd) = x.iter().enumerate().fold((0, 0), |(e, o), (j, &v)| {
            if j % 2 == 0 {
                (e + v as i64, o)
            } else {
                (e, o + v as i64)
            }
        });
        even - odd
    }

    fn topo(c: &Complex) -> Topology {
        analyse(c, &AtomicBool::new(false)).expect("not cancelled")
    }

    /// A grid (sizes, wrapped axes, twist) with its Betti numbers mod 2 and closed components.
    type Case = (
        &'static [usize],
        &'static [bool],
        bool,
        &'static [usize],
        usize,
    );

    #[test]
    fn grids_have_the_topology_of_what_they_are() {
        let cases: &[Case] = &[
            (&[5], &[true], false, &[1, 1], 1),
            (&[4], &[false], false, &[1, 0], 0),
            (&[3, 4], &[true, true], false, &[1, 2, 1], 1),
            (&[4, 3], &[true, false], false, &[1, 1, 0], 0),
            (&[3, 3], &[false, false], false, &[1, 0, 0], 0),
            (&[4, 3], &[true, true], true, &[1, 2, 1], 1),
            (&[3, 3, 3], &[true, true, true], false, &[1, 3, 3, 1], 1),
            (&[3, 3, 2], &[true, true, false], false, &[1, 2, 1, 0], 0),
            (&[2, 2, 2], &[false, false, false], false, &[1, 0, 0, 0], 0),
            (&[3, 2, 2], &[true, false, false], false, &[1, 1, 0, 0], 0),
        ];
        for &(n, wrap, twist, betti, closed) in cases {
            let c = grid(n, wrap, twist);
            let t = topo(&c);
            let what = format!("{n:?} {wrap:?} twist={twist}");
            assert!(t.manifold, "{what}: {:?}", t.offenders);
            assert_eq!(t.betti_mod2.as_deref(), Some(betti), "{what}");
            assert_eq!((t.components, t.closed_components), (1, closed), "{what}");
            assert_eq!(t.closed, closed == 1, "{what}");
            assert_eq!(t.dim, n.len());
            // chi from the counts; by Euler-Poincare it is also the alternating sum of the
            // expected Betti numbers (a check of the case table against the complex).
            let chi = alternating(&t.cells);
            assert_eq!(t.euler_characteristic, chi, "{what}");
            assert_eq!(chi, alternating(betti), "{what}");
            assert_eq!(t.cells, c.counts());
            assert_eq!(t.boundary_cells, c.boundary_counts());
            let bchi = alternating(&t.boundary_cells);
            assert_eq!(t.boundary_euler_characteristic, bchi);
            if n.len() == 2 {
                assert_eq!(t.orientable, Some(!twist), "{what}");
            } else {
                assert_eq!(t.orientable, None);
            }
            assert!(t.offenders.is_empty() && t.offender_count == 0 && t.defects == 0);
        }
        // The ball's boundary is a sphere; the solid torus's a torus; the cylinder's two circles.
        assert_eq!(
            topo(&grid(&[2, 2, 2], &[false; 3], false)).boundary_euler_characteristic,
            2
        );
        assert_eq!(
            topo(&grid(&[3, 2, 2], &[true, false, false], false)).boundary_euler_characteristic,
            0
        );
        assert_eq!(
            topo(&grid(&[3, 2], &[false, false], false)).boundary_cells,
            vec![10, 10]
        );
    }

    #[test]
    fn the_projective_plane_is_one_sided_with_h1_of_rank_one() {
        let t = topo(&projective_plane());
        assert_eq!(t.cells, vec![6, 15, 10]);
        assert_eq!(t.euler_characteristic, 1);
        assert!(t.manifold && t.closed);
        assert_eq!(t.orientable, Some(false));
        assert_eq!(t.betti_mod2, Some(vec![1, 1, 1]));
    }

    #[test]
    fn components_are_counted_and_closed_ones_told_apart() {
        // A circle of 3 edges, a path of 2 and a lone vertex: 3 components, 2 closed (the
        // circle, and the vertex, which has no boundary either).
        let e = |a: u32, b: u32| BTreeSet::from([a, b]);
        let c = complex(
            7,
            vec![vec![], vec![e(0, 1), e(1, 2), e(2, 0), e(3, 4), e(4, 5)]],
            0,
        );
        let t = topo(&c);
        assert_eq!((t.components, t.closed_components), (3, 2));
        // The lone vertex 6 has no edge: as a ridge of m = 1 it is an offender.
        assert!(!t.manifold && t.betti_mod2.is_none());
        assert_eq!(t.offender_count, 1);
        let c = complex(
            6,
            vec![vec![], vec![e(0, 1), e(1, 2), e(2, 0), e(3, 4), e(4, 5)]],
            0,
        );
        let t = topo(&c);
        assert!(t.manifold && !t.closed);
        assert_eq!((t.components, t.closed_components), (2, 1));
        assert_eq!(t.betti_mod2, Some(vec![2, 1]));
        assert_eq!(t.boundary_cells, vec![2]);
        // A torus and a sphere (the boundary of a cube) side by side: b = 2, 2, 2.
        let torus = grid(&[3, 3], &[true, true], false);
        let sphere = grid(&[1, 1, 1], &[false; 3], false);
        let t = topo(&disjoint(&torus, &boundary_surface(&sphere)));
        assert_eq!(t.betti_mod2, Some(vec![2, 2, 2]));
        assert_eq!((t.components, t.closed_components), (2, 2));
        assert_eq!(t.euler_characteristic, 2);
    }

    /// The boundary of a 3-dimensional complex as a closed surface (its 2- and 1-cells).
    fn boundary_surface(c: &Complex) -> Complex {
        let faces = c.level(2);
        let edges = c.level(1);
        let mut cells: Vec<Vec<BTreeSet<u32>>> = vec![vec![], vec![], vec![]];
        for i in faces.interior()..faces.len() {
            let mut s = BTreeSet::new();
            for &e in faces.facets(i) {
                s.extend(edges.facets(e as usize).iter().copied());
            }
            cells[2].push(s);
        }
        for i in edges.interior()..edges.len() {
            cells[1].push(edges.facets(i).iter().copied().collect());
        }
        complex(c.vertex_count(), cells, 0)
    }

    /// Two surfaces side by side (vertex sets re-read from their edges).
    fn disjoint(a: &Complex, b: &Complex) -> Complex {
        let mut cells: Vec<Vec<BTreeSet<u32>>> = vec![vec![], vec![], vec![]];
        for (c, shift) in [(a, 0u32), (b, a.vertex_count() as u32)] {
            let edges = c.level(1);
            let faces = c.level(2);
            for i in 0..edges.len() {
                cells[1].push(edges.facets(i).iter().map(|v| v + shift).collect());
            }
            for i in 0..faces.len() {
                let mut s = BTreeSet::new();
                for &e in faces.facets(i) {
                    s.extend(edges.facets(e as usize).iter().map(|v| v + shift));
                }
                cells[2].push(s);
            }
        }
        complex(a.vertex_count() + b.vertex_count(), cells, 0)
    }

    #[test]
    fn a_non_manifold_complex_names_its_offenders() {
        // Three squares on one edge, then 30 such fins: every shared edge is an offender.
        let mut cells: Vec<Vec<BTreeSet<u32>>> = vec![vec![], vec![], vec![]];
        let mut nv = 0u32;
        for _ in 0..30 {
            let (a, b) = (nv, nv + 1);
            cells[1].push(BTreeSet::from([a, b]));
            for f in 0..3 {
                let (p, q) = (nv + 2 + 2 * f, nv + 3 + 2 * f);
                cells[1].extend([
                    BTreeSet::from([a, p]),
                    BTreeSet::from([p, q]),
                    BTreeSet::from([q, b]),
                ]);
                cells[2].push(BTreeSet::from([a, b, p, q]));
            }
            nv += 8;
        }
        let t = topo(&complex(nv as usize, cells, 0));
        assert!(!t.manifold && t.betti_mod2.is_none());
        assert_eq!(t.offender_count, 30);
        assert_eq!(t.offenders.len(), MAX_LISTED_OFFENDERS);
        assert!(t.offenders.iter().all(|o| o.cofaces == 3 && !o.on_boundary));
        // Edges left out while building make a complex non-manifold too.
        let mut c = grid(&[3, 3], &[true, true], false);
        c.stats.defects = 2;
        let t = topo(&c);
        assert!(!t.manifold && t.offender_count == 0 && t.defects == 2 && t.betti_mod2.is_none());
    }

    /// The n x n square torus, its levels written directly (too big for `complex`): vertex
    /// i + n j, horizontal edges i + n j, vertical ones n^2 + i + n j.
    fn big_torus(n: u32, reversed: bool) -> Complex {
        let v = |i: u32, j: u32| i % n + n * (j % n);
        let (mut eo, mut ef) = (vec![0u32], Vec::new());
        for (di, dj) in [(1, 0), (0, 1)] {
            for j in 0..n {
                for i in 0..n {
                    ef.extend([v(i, j), v(i + di, j + dj)]);
                    eo.push(ef.len() as u32);
                }
            }
        }
        let (mut fo, mut ff) = (vec![0u32], Vec::new());
        for f in 0..n * n {
            let f = if reversed { n * n - 1 - f } else { f };
            let (i, j) = (f % n, f / n);
            ff.extend([v(i, j), v(i, j + 1), n * n + v(i, j), n * n + v(i + 1, j)]);
            fo.push(ff.len() as u32);
        }
        let (nv, ne, nf) = ((n * n) as usize, 2 * (n * n) as usize, (n * n) as usize);
        let levels = vec![Level::from_lists(eo, ef, ne), Level::from_lists(fo, ff, nf)];
        Complex::from_parts(3, vec![0.0; 3 * nv], nv, levels, ComplexStats::default())
    }

    #[test]
    fn a_cancelled_analysis_returns_nothing() {
        let c = grid(&[3, 3, 3], &[true, true, true], false);
        assert!(analyse(&c, &AtomicBool::new(true)).is_none());
        assert!(c.topology_cancellable(&AtomicBool::new(false)).is_some());
        // H_1 looks at the flag every CANCEL_EVERY faces: a torus of 4,900 squares stops,
        // 9 squares finish (and the flag's absence stops nothing).
        let big = big_torus(70, false);
        assert!(big.level(2).len() > CANCEL_EVERY);
        let forest = Forest::of(&big);
        assert_eq!(h1_mod2(&big, &forest, &AtomicBool::new(true)), None);
        assert_eq!(h1_mod2(&big, &forest, &AtomicBool::new(false)), Some(2));
        assert_eq!(topo(&big).betti_mod2, Some(vec![1, 2, 1]));
        let small = grid(&[3, 3], &[true, true], false);
        let forest = Forest::of(&small);
        assert_eq!(h1_mod2(&small, &forest, &AtomicBool::new(true)), Some(2));
    }

    #[test]
    fn the_collapse_leaves_nothing_to_eliminate_on_a_torus() {
        let big = big_torus(70, false);
        // On a torus the collapse does all the work: no face is left to eliminate.
        // Faces in the reverse order need several passes.
        for big in [big, big_torus(70, true)] {
            let forest = Forest::of(&big);
            let (b1, left) = h1_mod2_counted(&big, &forest, &AtomicBool::new(false)).unwrap();
            assert_eq!(b1, 2);
            assert_eq!(left, 0, "{left} of 4,900 faces left to the elimination");
        }
    }

    #[test]
    fn pairs_cancel_and_differences_are_symmetric() {
        let mut v = vec![1, 1, 2, 3, 3, 3, 4];
        cancel_pairs(&mut v);
        assert_eq!(v, [2, 3, 4]);
        let mut v = vec![5, 5];
        cancel_pairs(&mut v);
        assert!(v.is_empty());
        assert_eq!(
            symmetric_difference(&[1, 3, 5, 9], &[2, 3, 9, 10]),
            [1, 2, 5, 10]
        );
        assert_eq!(
            symmetric_difference(&[2, 3, 9, 10], &[1, 3, 5, 9]),
            [1, 2, 5, 10]
        );
        assert_eq!(symmetric_difference(&[], &[4]), [4]);
        assert_eq!(symmetric_difference(&[4, 6], &[]), [4, 6]);
        assert_eq!(euler(&[7, 9, 4]), 2);
        let mut uf = UnionFind::new(5);
        assert!(uf.union(3, 1) && uf.union(1, 4) && !uf.union(4, 3));
        assert_eq!(uf.find(4), 1);
        assert_ne!(uf.find(0), uf.find(2));
    }
}
