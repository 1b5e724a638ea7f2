//! Surfaces and 2-cells: the vertices of each 2-cell in cyclic order (from its edges), a
//! consistent orientation when one exists (in R^3, outward along the gradient of f), and
//! triangles.

use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use rayon::prelude::*;

use super::Complex;
use crate::expr::ImplicitFunction;

/// The 2-cells of a complex as oriented polygons.
#[derive(Clone, Debug)]
pub struct Surface {
    offsets: Vec<u32>,
    vertices: Vec<u32>,
    /// Whether the polygons are consistently oriented (only meaningful for m = 2: every
    /// edge shared by two polygons is walked in opposite directions by them).
    pub orientable: bool,
    /// 2-cells whose edges do not form one cycle (left empty).
    pub bad_cells: usize,
}

/// The 2-cells of a complex as polygons in cyclic order, with the flips that orient them
/// consistently and the components the flips were found in: [`Surface::new`] without f,
/// kept by the complex ([`Complex::polygons`]) so that it is built once.
#[derive(Clone, Debug, Default)]
pub(crate) struct Polygons {
    offsets: Vec<u32>,
    vertices: Vec<u32>,
    /// Whether the flips orient the polygons consistently (m = 2).
    pub orientable: bool,
    bad_cells: usize,
    /// Per polygon, whether it is reversed (empty unless orientable with m = 2).
    flip: Vec<bool>,
    /// The polygons component by component, and where each component starts there.
    order: Vec<u32>,
    starts: Vec<u32>,
}

impl Polygons {
    /// Orders the 2-cells of `c` (m >= 2); for m = 2 also orients them consistently when
    /// possible, each component by BFS over shared edges.
    pub(crate) fn of(c: &Complex) -> Self {
        let edges = c.level(1);
        let faces = c.level(2);
        // In chunks, each into flat arrays with reused scratch: no allocation per polygon.
        const CHUNK: usize = 2048;
        let chunks: Vec<(Vec<u32>, Vec<u32>, usize)> = (0..faces.len().div_ceil(CHUNK))
            .into_par_iter()
            .map(|k| {
                let range = k * CHUNK..((k + 1) * CHUNK).min(faces.len());
                let (mut ends, mut vertices, mut bad) = (Vec::new(), Vec::new(), 0);
                let (mut pairs, mut order) = (Vec::new(), Vec::new());
                for i in range {
                    let edges_of = faces.facets(i).iter().map(|&e| edges.facets(e as usize));
                    if cycle(edges_of, &mut pairs, &mut order) {
                        vertices.extend_from_slice(&order);
                    } else {
                        bad += 1;
                    }
                    ends.push(vertices.len() as u32);
                }
                (ends, vertices, bad)
            })
            .collect();
        let bad_cells = chunks.iter().map(|c| c.2).sum();
        let mut offsets = Vec::with_capacity(faces.len() + 1);
        let mut vertices = Vec::with_capacity(chunks.iter().map(|c| c.1.len()).sum());
        offsets.push(0);
        for (ends, verts, _) in &chunks {
            let base = vertices.len() as u32;
            offsets.extend(ends.iter().map(|e| base + e));
            vertices.extend_from_slice(verts);
        }
        let mut p = Polygons {
            offsets,
            vertices,
            orientable: bad_cells == 0,
            bad_cells,
            ..Polygons::default()
        };
        if c.dim() == 2 && p.orientable {
            p.orient(c);
        }
        p
    }

    /// Polygon `i`: vertex indices in cyclic order, before any flip.
    fn polygon(&self, i: usize) -> &[u32] {
        polygon_in(&self.offsets, &self.vertices, i)
    }

    /// Finds the flips that make neighbours agree, component by component; clears
    /// `orientable` (and keeps no flip) on a conflict. The polygons at each edge and
    /// whether they walk it the same way are found in parallel first; a union-find then
    /// reads one entry per edge.
    fn orient(&mut self, c: &Complex) {
        let edges = c.level(1);
        let faces = c.level(2);
        const NONE: u32 = u32::MAX;
        // The (up to two) polygons at each edge, in any order, each as 2 p + 1 where p walks
        // the edge from its first end to its second, else 2 p (a polygon has 3 vertices or
        // more and their count fits 32 bits, so 2 p + 1 < NONE); a third one at an edge
        // ends the orientation.
        let at: Vec<[AtomicU32; 2]> = (0..edges.len())
            .into_par_iter()
            .map(|_| [AtomicU32::new(NONE), AtomicU32::new(NONE)])
            .collect();
        let crowded = AtomicBool::new(false);
        (0..faces.len())
            .into_par_iter()
            .with_min_len(1 << 12)
            .for_each(|p| {
                for &e in faces.facets(p) {
                    let ab = <[u32; 2]>::try_from(edges.facets(e as usize)).expect("2 ends");
                    let walk = 2 * p as u32 + u32::from(self.walks(p, ab));
                    let [a, b] = &at[e as usize];
                    let put = |s: &AtomicU32| {
                        s.compare_exchange(NONE, walk, Ordering::Relaxed, Ordering::Relaxed)
                            .is_ok()
                    };
                    if !put(a) && !put(b) {
                        crowded.store(true, Ordering::Relaxed);
                    }
                }
            });
        if crowded.into_inner() {
            self.orientable = false;
            return;
        }
        // Per edge: its polygons (the lower first) and whether they walk it the same way.
        let links: Vec<(u32, u32, bool)> = at
            .into_par_iter()
            .map(|[a, b]| {
                let (a, b) = (a.into_inner(), b.into_inner());
                let (u, v) = if b != NONE && b < a { (b, a) } else { (a, b) };
                if v == NONE {
                    return (u / 2, NONE, false);
                }
                (u / 2, v / 2, u % 2 == v % 2)
            })
            .collect();
        // Relative flips by a union-find over the polygons: each link joins its two
        // polygons' classes with the parity it asks for, and a link whose polygons are in one
        // class already must agree with the parity between them.
        let mut classes = Parities::new(faces.len());
        for &(u, v, same) in &links {
            if v != NONE && !classes.join(u, v, same) {
                self.orientable = false;
                return;
            }
        }
        // Each class's root is its lowest polygon (which keeps its walk), and every other
        // polygon's parent is lower than itself: one pass in order settles the flips, and a
        // counting pass lists the components, lowest first, each in order.
        let n = faces.len();
        let mut flip = vec![false; n];
        let mut root = vec![0u32; n];
        let mut size = vec![0u32; n];
        for p in 0..n {
            let (up, parity) = classes.link(p);
            if up == p {
                root[p] = p as u32;
            } else {
                root[p] = root[up];
                flip[p] = parity != flip[up];
            }
            size[root[p] as usize] += 1;
        }
        // Where each component's next polygon goes in `order`, at its root.
        let mut next = vec![0u32; n];
        for p in 0..n {
            if root[p] == p as u32 {
                self.starts.push(self.order.len() as u32);
                next[p] = self.order.len() as u32;
                self.order
                    .resize(self.order.len() + size[p] as usize, u32::MAX);
            }
            let slot = &mut next[root[p] as usize];
            self.order[*slot as usize] = p as u32;
            *slot += 1;
        }
        self.flip = flip;
    }

    /// Whether polygon `p` walks from `ab[0]` to `ab[1]`.
    fn walks(&self, p: usize, ab: [u32; 2]) -> bool {
        let poly = self.polygon(p);
        let i = poly
            .iter()
            .position(|&v| v == ab[0])
            .expect("edge of the polygon");
        poly[(i + 1) % poly.len()] == ab[1]
    }
}

impl Surface {
    /// Orders the 2-cells of `c` (m >= 2). For m = 2 it also orients them consistently when
    /// possible, each component by BFS over shared edges; with `f` and d = 3, each component
    /// then faces along the gradient of f. The polygons and their consistent orientation
    /// are the complex's (built once and kept with it); only the gradient's turn is
    /// computed here.
    pub fn new(c: &Complex, f: Option<&dyn ImplicitFunction>) -> Self {
        let p = c.polygons();
        let mut s = Surface {
            offsets: p.offsets.clone(),
            vertices: p.vertices.clone(),
            orientable: p.orientable,
            bad_cells: p.bad_cells,
        };
        if p.flip.is_empty() {
            return s;
        }
        let mut flip = p.flip.clone();
        if let (Some(f), 3) = (f, c.ambient_dim()) {
            let ends = p.starts.iter().skip(1).map(|&e| e as usize);
            for (start, end) in p.starts.iter().zip(ends.chain([p.order.len()])) {
                let component = &p.order[*start as usize..end];
                if s.against_gradient(c, f, component, &flip) {
                    for &q in component {
                        flip[q as usize] = !flip[q as usize];
                    }
                }
            }
        }
        for (q, fl) in flip.iter().enumerate() {
            if *fl {
                let (a, b) = (s.offsets[q] as usize, s.offsets[q + 1] as usize);
                s.vertices[a..b].reverse();
            }
        }
        s
    }

    /// Number of polygons (2-cells).
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }
    /// Whether there is no polygon.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Polygon `i`: vertex indices in cyclic order.
    pub fn polygon(&self, i: usize) -> &[u32] {
        polygon_in(&self.offsets, &self.vertices, i)
    }
    /// Fan triangles of every polygon, with the polygons' orientation.
    pub fn triangles(&self) -> Vec<[u32; 3]> {
        let mut t = Vec::with_capacity(self.vertices.len());
        for i in 0..self.len() {
            let p = self.polygon(i);
            for w in 1..p.len().saturating_sub(1) {
                t.push([p[0], p[w], p[w + 1]]);
            }
        }
        t
    }

    /// Whether the component, with its flips, faces against the gradient of f overall: the
    /// sum over its polygons of their normal (flipped where they are) dotted with the
    /// gradient at their centre, the gradients taken in batches. The batches' sums are added
    /// in order, so that the sign does not depend on the threads.
    fn against_gradient(
        &self,
        c: &Complex,
        f: &dyn ImplicitFunction,
        component: &[u32],
        flip: &[bool],
    ) -> bool {
        /// Polygons per batch of gradients.
        const BATCH: usize = 256;
        let sums: Vec<f64> = component
            .par_chunks(BATCH)
            .map(|chunk| {
                let mut normals = vec![0.0; chunk.len() * 3];
                let mut centres = vec![0.0; chunk.len() * 3];
                for ((&p, n), centre) in chunk
                    .iter()
                    .zip(normals.chunks_exact_mut(3))
                    .zip(centres.chunks_exact_mut(3))
                {
                    let poly = self.polygon(p as usize);
                    let x0 = c.point(poly[0] as usize);
                    for w in 0..poly.len() {
                        let x = c.point(poly[w] as usize);
                        for i in 0..3 {
                            centre[i] += x[i] / poly.len() as f64;
                        }
                        if w >= 1 && w + 1 < poly.len() {
                            let (a, b) = (c.point(poly[w] as usize), c.point(poly[w + 1] as usize));
                            let u = [a[0] - x0[0], a[1] - x0[1], a[2] - x0[2]];
                            let v = [b[0] - x0[0], b[1] - x0[1], b[2] - x0[2]];
                            n[0] += u[1] * v[2] - u[2] * v[1];
                            n[1] += u[2] * v[0] - u[0] * v[2];
                            n[2] += u[0] * v[1] - u[1] * v[0];
                        }
                    }
                }
                let mut g = vec![0.0; chunk.len() * 3];
                f.jacobian_batch(&centres, &mut g);
                chunk
                    .iter()
                    .zip(normals.chunks_exact(3).zip(g.chunks_exact(3)))
                    .map(|(&p, (n, g))| {
                        let s = n[0] * g[0] + n[1] * g[1] + n[2] * g[2];
                        if flip[p as usize] {
                            -s
                        } else {
                            s
                        }
                    })
                    .sum::<f64>()
            })
            .collect();
        sums.iter().sum::<f64>() < 0.0
    }
}

/// A union-find over polygons that keeps, with each polygon, whether it is flipped relative
/// to its parent; the root of a class is its lowest polygon.
struct Parities {
    parent: Vec<u32>,
    flipped: Vec<bool>,
}

impl Parities {
    fn new(n: usize) -> Self {
        Parities {
            parent: (0..n as u32).collect(),
            flipped: vec![false; n],
        }
    }

    /// The root of `x`'s class and whether `x` is flipped relative to it (path halving).
    fn find(&mut self, mut x: u32) -> (u32, bool) {
        let mut flipped = false;
        loop {
            let p = self.parent[x as usize];
            if p == x {
                return (x, flipped);
            }
            let g = self.parent[p as usize];
            let to_g = self.flipped[x as usize] != self.flipped[p as usize];
            self.parent[x as usize] = g;
            self.flipped[x as usize] = to_g;
            flipped ^= to_g;
            x = g;
        }
    }

    /// Makes `u` and `v` flipped relative to each other exactly when `flipped`; false when
    /// their classes already say otherwise.
    fn join(&mut self, u: u32, v: u32, flipped: bool) -> bool {
        let ((ru, fu), (rv, fv)) = (self.find(u), self.find(v));
        let rel = fu != fv;
        if ru == rv {
            return rel == flipped;
        }
        let (lo, hi) = if ru < rv { (ru, rv) } else { (rv, ru) };
        self.parent[hi as usize] = lo;
        self.flipped[hi as usize] = rel != flipped;
        true
    }

    /// Polygon `p`'s parent (lower than `p` unless `p` is a root) and whether `p` is
    /// flipped relative to it.
    fn link(&self, p: usize) -> (usize, bool) {
        (self.parent[p] as usize, self.flipped[p])
    }
}

/// Polygon `i` of polygons stored one after another in `vertices`, polygon i ending at
/// `offsets[i + 1]`.
fn polygon_in<'a>(offsets: &[u32], vertices: &'a [u32], i: usize) -> &'a [u32] {
    &vertices[offsets[i] as usize..offsets[i + 1] as usize]
}

/// The vertices of a polygon in cyclic order from its edges (pairs of vertex indices), into
/// `order`; false when the edges do not form one cycle. `pairs` is scratch.
fn cycle<'a>(
    edges: impl Iterator<Item = &'a [u32]>,
    pairs: &mut Vec<[u32; 2]>,
    order: &mut Vec<u32>,
) -> bool {
    pairs.clear();
    order.clear();
    for e in edges {
        match <[u32; 2]>::try_from(e) {
            Ok(e) => pairs.push(e),
            Err(_) => return false,
        }
    }
    if pairs.len() < 3 {
        return false;
    }
    let first = pairs.swap_remove(0);
    order.extend_from_slice(&first);
    while !pairs.is_empty() {
        let last = *order.last().expect("non-empty");
        let Some(i) = pairs.iter().position(|e| e.contains(&last)) else {
            return false;
        };
        let e = pairs.swap_remove(i);
        let next = if e[0] == last { e[1] } else { e[0] };
        if pairs.is_empty() {
            return next == order[0];
        }
        order.push(next);
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::complex::{ComplexStats, Level};

    /// The first `pages` of three triangles on the edge from vertex 0 to vertex 1 (the
    /// pages of a book, the edge its spine), in R^3.
    fn book(pages: usize) -> Complex {
        let edges: [[u32; 2]; 7] = [[0, 1], [0, 2], [1, 2], [0, 3], [1, 3], [0, 4], [1, 4]];
        // The second page walks the spine the other way: were the third page left out of
        // the spine's polygons, the flips would find no conflict.
        let faces: [[u32; 3]; 3] = [[0, 1, 2], [3, 0, 4], [0, 5, 6]];
        let ne = 1 + 2 * pages;
        let lists = |cells: &[u32], n: usize| {
            let offsets = (0..=cells.len() / n).map(|i| (i * n) as u32).collect();
            Level::from_lists(offsets, cells.to_vec(), cells.len() / n)
        };
        let levels = vec![
            lists(edges[..ne].as_flattened(), 2),
            lists(faces[..pages].as_flattened(), 3),
        ];
        let nv = 2 + pages;
        Complex::from_parts(3, vec![0.0; 3 * nv], nv, levels, ComplexStats::default())
    }

    #[test]
    fn three_polygons_at_one_edge_have_no_orientation() {
        let two = book(2);
        assert!(two.polygons().orientable);
        assert!(Surface::new(&two, None).orientable);
        let three = book(3);
        assert!(!three.polygons().orientable);
        let s = Surface::new(&three, None);
        assert!(!s.orientable);
        // The polygons are kept, in the order of their edges, unflipped.
        assert_eq!(s.len(), 3);
        assert_eq!(s.polygon(2), &[0, 1, 4]);
    }
}
