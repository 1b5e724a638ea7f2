//! Simplices of a Freudenthal-Kuhn triangulation of Z^d as permutahedral representations.
//!
//! A simplex is `(v0, omega)`: a base vertex `v0` in Z^d and an ordered partition `omega` of
//! {1..d+1} into l+1 parts, where element j stands for the step e_j and e_{d+1} = -(e_1+...+e_d).
//! The vertices are v_i = v_{i-1} + sum_{j in omega_i} e_j (papers' Definition 13). Every simplex
//! here is kept in canonical form: d+1 lies in the last part, so v0 is its lexicographically
//! smallest vertex and two simplices are equal iff their representations are.
//!
//! Parts are bitmasks (bit j-1 for element j), so merging parts (faces) is an OR and refining
//! them (cofaces) is submask enumeration. Nothing here allocates per simplex: the `for_each_*`
//! methods hand out a reused scratch simplex.

use std::fmt;
use std::hash::{Hash, Hasher};

use crate::error::{Error, Result};

pub use crate::MAX_DIM;
const MAX_PARTS: usize = MAX_DIM + 1;

/// A simplex of the Freudenthal-Kuhn triangulation of Z^d, in canonical permutahedral form.
///
/// ```
/// use isomesh::triangulation::Simplex;
///
/// // A vertex of Z^3 and the 3-simplices around it: (d+1)! = 24 in Freudenthal-Kuhn.
/// let v = Simplex::vertex(&[1, 2, 3])?;
/// let around = v.cofaces(3)?;
/// assert_eq!(around.len(), 24);
/// assert!(around.iter().all(|s| s.vertices().contains(&vec![1, 2, 3])));
/// # Ok::<(), isomesh::Error>(())
/// ```
#[derive(Clone)]
pub struct Simplex {
    d: u8,
    n_parts: u8,
    v0: [i32; MAX_DIM],
    parts: [u64; MAX_PARTS],
}

/// The mask of all d+1 elements.
#[inline]
pub(crate) fn full_mask(d: usize) -> u64 {
    if d + 1 == 64 {
        u64::MAX
    } else {
        (1u64 << (d + 1)) - 1
    }
}

/// Adds sum_{j in mask} e_j to `v` (with e_{d+1} = -sum e_i), in O(popcount).
#[inline]
pub(crate) fn shift_by_mask(v: &mut [i32], mask: u64, d: usize) {
    let top = 1u64 << d;
    if mask & top != 0 {
        // sum_{j in mask} e_j = -sum_{i < d, i not in mask} e_i
        let mut rest = !mask & (top - 1);
        while rest != 0 {
            v[rest.trailing_zeros() as usize] -= 1;
            rest &= rest - 1;
        }
    } else {
        let mut m = mask;
        while m != 0 {
            v[m.trailing_zeros() as usize] += 1;
            m &= m - 1;
        }
    }
}

/// `dst[at..at + len] = src[from..from + len]`, for the short runs of a simplex's arrays:
/// a fixed block of 8 when it fits both (entries past a simplex's length are not part of
/// it, so overwriting them is harmless when runs are written in ascending order), which
/// compiles to a few moves instead of a call to memmove.
#[inline(always)]
fn copy_run<T: Copy>(dst: &mut [T], at: usize, src: &[T], from: usize, len: usize) {
    const BLOCK: usize = 8;
    if len <= BLOCK && at + BLOCK <= dst.len() && from + BLOCK <= src.len() {
        dst[at..at + BLOCK].copy_from_slice(&src[from..from + BLOCK]);
    } else {
        dst[at..at + len].copy_from_slice(&src[from..from + len]);
    }
}

/// Checks 1 <= d <= MAX_DIM.
pub(crate) fn check_dim(d: usize) -> Result<()> {
    if d == 0 || d > MAX_DIM {
        Err(Error::Dimension(d))
    } else {
        Ok(())
    }
}

impl Simplex {
    fn blank(d: usize, n_parts: usize) -> Self {
        Simplex {
            d: d as u8,
            n_parts: n_parts as u8,
            v0: [0; MAX_DIM],
            parts: [0; MAX_PARTS],
        }
    }

    /// Makes this an l-simplex of R^d with `n_parts` = l + 1 parts, returning its base
    /// vertex and parts to fill in (canonical form is the caller's duty).
    pub(crate) fn reset(&mut self, d: usize, n_parts: usize) -> (&mut [i32], &mut [u64]) {
        self.d = d as u8;
        self.n_parts = n_parts as u8;
        (&mut self.v0[..d], &mut self.parts[..n_parts])
    }

    /// The vertex `v` as a 0-simplex.
    pub fn vertex(v: &[i32]) -> Result<Self> {
        let d = v.len();
        check_dim(d)?;
        let mut s = Self::blank(d, 1);
        s.v0[..d].copy_from_slice(v);
        s.parts[0] = full_mask(d);
        Ok(s)
    }

    /// A simplex from a base vertex and an ordered partition given as bitmasks (bit j-1 for
    /// element j); any cyclic shift is accepted and brought to canonical form.
    pub fn from_masks(v0: &[i32], parts: &[u64]) -> Result<Self> {
        let d = v0.len();
        check_dim(d)?;
        if parts.is_empty() || parts.len() > d + 1 {
            return Err(Error::InvalidSimplex(format!(
                "{} parts: an ordered partition of {{1..{}}} has 1 to {} parts",
                parts.len(),
                d + 1,
                d + 1
            )));
        }
        let mut seen = 0u64;
        for (i, &p) in parts.iter().enumerate() {
            if p == 0 {
                return Err(Error::InvalidSimplex(format!("part {} is empty", i + 1)));
            }
            if p & !full_mask(d) != 0 {
                return Err(Error::InvalidSimplex(format!(
                    "part {} holds an element above {}",
                    i + 1,
                    d + 1
                )));
            }
            if p & seen != 0 {
                return Err(Error::InvalidSimplex(format!(
                    "part {} repeats an element",
                    i + 1
                )));
            }
            seen |= p;
        }
        if seen != full_mask(d) {
            return Err(Error::InvalidSimplex(format!(
                "the parts do not cover {{1..{}}}",
                d + 1
            )));
        }
        let mut s = Self::blank(d, parts.len());
        s.v0[..d].copy_from_slice(v0);
        s.parts[..parts.len()].copy_from_slice(parts);
        s.canonicalize();
        Ok(s)
    }

    /// A simplex from a base vertex and parts listed as 1-based elements, e.g. `[[1, 3], [2]]`.
    pub fn from_parts<P: AsRef<[usize]>>(v0: &[i32], parts: &[P]) -> Result<Self> {
        let d = v0.len();
        check_dim(d)?;
        let mut masks = Vec::with_capacity(parts.len());
        for p in parts {
            let mut m = 0u64;
            for &e in p.as_ref() {
                if e == 0 || e > d + 1 {
                    return Err(Error::InvalidSimplex(format!(
                        "element {e} is outside 1..={}",
                        d + 1
                    )));
                }
                if m & (1 << (e - 1)) != 0 {
                    return Err(Error::InvalidSimplex(format!("element {e} repeated")));
                }
                m |= 1 << (e - 1);
            }
            masks.push(m);
        }
        Self::from_masks(v0, &masks)
    }

    /// The ambient dimension d.
    #[inline]
    pub fn ambient_dim(&self) -> usize {
        self.d as usize
    }

    /// The dimension l of the simplex (its number of parts minus one).
    #[inline]
    pub fn dim(&self) -> usize {
        self.n_parts as usize - 1
    }

    /// The base vertex v0, the lexicographically smallest vertex.
    #[inline]
    pub fn base(&self) -> &[i32] {
        &self.v0[..self.d as usize]
    }

    /// The ordered partition as bitmasks (bit j-1 for element j); d+1 is in the last part.
    #[inline]
    pub fn parts(&self) -> &[u64] {
        &self.parts[..self.n_parts as usize]
    }

    /// The 1-based elements of part `i`, in increasing order.
    pub fn part_elements(&self, i: usize) -> impl Iterator<Item = usize> {
        let mut m = self.parts[i];
        std::iter::from_fn(move || {
            (m != 0).then(|| {
                let e = m.trailing_zeros() as usize + 1;
                m &= m - 1;
                e
            })
        })
    }

    /// Brings the representation to canonical form (d+1 in the last part) by a cyclic shift.
    #[inline]
    pub(crate) fn canonicalize(&mut self) {
        let d = self.d as usize;
        let n = self.n_parts as usize;
        let top = 1u64 << d;
        if self.parts[n - 1] & top != 0 {
            return;
        }
        let mut mask = 0;
        let mut c = 0;
        while self.parts[c] & top == 0 {
            mask |= self.parts[c];
            c += 1;
        }
        mask |= self.parts[c];
        shift_by_mask(&mut self.v0[..d], mask, d);
        self.parts[..n].rotate_left(c + 1);
    }

    /// Vertex `i` (0..=l) written into `out` (length d).
    pub fn vertex_into(&self, i: usize, out: &mut [i32]) {
        let d = self.d as usize;
        out[..d].copy_from_slice(self.base());
        let mask = self.parts[..i].iter().fold(0, |a, p| a | p);
        shift_by_mask(&mut out[..d], mask, d);
    }

    /// Calls `f(i, v_i)` for every vertex in order, in O(d + l) total beyond the calls.
    pub fn for_each_vertex(&self, mut f: impl FnMut(usize, &[i32])) {
        let d = self.d as usize;
        let mut v = self.v0;
        f(0, &v[..d]);
        for i in 1..=self.dim() {
            shift_by_mask(&mut v[..d], self.parts[i - 1], d);
            f(i, &v[..d]);
        }
    }

    /// All vertices, in order v_0..v_l.
    pub fn vertices(&self) -> Vec<Vec<i32>> {
        let mut out = Vec::with_capacity(self.n_parts as usize);
        self.for_each_vertex(|_, v| out.push(v.to_vec()));
        out
    }

    /// Calls `f` on every j-face, in lexicographic order of the vertex subsets it keeps;
    /// C(l+1, j+1) calls, O(d) work each.
    pub fn for_each_face(&self, j: usize, mut f: impl FnMut(&Simplex)) -> Result<()> {
        let l = self.dim();
        if j > l {
            return Err(Error::InvalidSimplex(format!(
                "a {l}-simplex has no faces of dimension {j}"
            )));
        }
        let d = self.d as usize;
        let n = l + 1;
        // prefix[m] = union of parts 0..m, so parts a..b is prefix[b] ^ prefix[a].
        let mut prefix = [0u64; MAX_PARTS + 1];
        for i in 0..n {
            prefix[i + 1] = prefix[i] | self.parts[i];
        }
        let full = prefix[n];
        let mut idx = [0usize; MAX_PARTS];
        for (i, x) in idx.iter_mut().enumerate().take(j + 1) {
            *x = i;
        }
        let mut out = Self::blank(d, j + 1);
        let mut base_of = usize::MAX;
        loop {
            if idx[0] != base_of {
                base_of = idx[0];
                out.v0[..d].copy_from_slice(&self.v0[..d]);
                shift_by_mask(&mut out.v0[..d], prefix[base_of], d);
            }
            for i in 0..j {
                out.parts[i] = prefix[idx[i + 1]] ^ prefix[idx[i]];
            }
            out.parts[j] = full & !(prefix[idx[j]] ^ prefix[idx[0]]);
            f(&out);
            // Next (j+1)-subset of 0..n in lexicographic order.
            let mut i = j as isize;
            while i >= 0 && idx[i as usize] == n - (j + 1) + i as usize {
                i -= 1;
            }
            if i < 0 {
                return Ok(());
            }
            let i = i as usize;
            idx[i] += 1;
            for t in i + 1..=j {
                idx[t] = idx[t - 1] + 1;
            }
        }
    }

    /// All j-faces (see [`Simplex::for_each_face`]).
    pub fn faces(&self, j: usize) -> Result<Vec<Simplex>> {
        let mut out = Vec::new();
        self.for_each_face(j, |s| out.push(s.clone()))?;
        Ok(out)
    }

    /// Calls `f` on every facet: the one opposite vertex 0 first, then opposite v_1..v_l.
    pub fn for_each_facet(&self, mut f: impl FnMut(&Simplex)) {
        let l = self.dim();
        if l == 0 {
            return;
        }
        let d = self.d as usize;
        let n = l + 1;
        let mut out = Self::blank(d, l);
        // Opposite v_0: merge the first part into the last, base moves to v_1.
        out.v0[..d].copy_from_slice(&self.v0[..d]);
        shift_by_mask(&mut out.v0[..d], self.parts[0], d);
        out.parts[..l - 1].copy_from_slice(&self.parts[1..l]);
        out.parts[l - 1] = self.parts[l] | self.parts[0];
        f(&out);
        // Opposite v_r: merge parts r-1 and r.
        out.v0[..d].copy_from_slice(&self.v0[..d]);
        out.parts[..l].copy_from_slice(&self.parts[1..n]);
        for r in 1..n {
            // out.parts = parts[0..r-1], parts[r-1]|parts[r], parts[r+1..n]
            out.parts[r - 1] = self.parts[r - 1] | self.parts[r];
            f(&out);
            out.parts[r - 1] = self.parts[r - 1];
        }
    }

    /// Writes the facet opposite vertex `q` (0..=l) into `out`, in O(d + l): its vertices are
    /// this simplex's in order, without v_q.
    pub fn facet_into(&self, q: usize, out: &mut Simplex) {
        let l = self.dim();
        debug_assert!(l > 0 && q <= l);
        let d = self.d as usize;
        out.d = self.d;
        out.n_parts = l as u8;
        copy_run(&mut out.v0, 0, &self.v0, 0, d);
        if q == 0 {
            shift_by_mask(&mut out.v0[..d], self.parts[0], d);
            copy_run(&mut out.parts, 0, &self.parts, 1, l - 1);
            out.parts[l - 1] = self.parts[l] | self.parts[0];
        } else {
            copy_run(&mut out.parts, 0, &self.parts, 0, q - 1);
            out.parts[q - 1] = self.parts[q - 1] | self.parts[q];
            copy_run(&mut out.parts, q, &self.parts, q + 1, l - q);
        }
    }

    /// All facets (see [`Simplex::for_each_facet`]).
    pub fn facets(&self) -> Vec<Simplex> {
        let mut out = Vec::with_capacity(self.n_parts as usize);
        self.for_each_facet(|s| out.push(s.clone()));
        out
    }

    /// Number of cofacets: sum over parts of 2^{|part|} - 2.
    pub fn cofacet_count(&self) -> u64 {
        self.parts()
            .iter()
            .map(|p| (1u64 << p.count_ones()).wrapping_sub(2))
            .sum()
    }

    /// Calls `f` on every cofacet (each part split into two ordered non-empty sub-parts), in
    /// O(d) per cofacet.
    pub fn for_each_cofacet(&self, mut f: impl FnMut(&Simplex)) {
        self.for_each_cofacet_apex(|c, _| f(c));
    }

    /// Like [`Simplex::for_each_cofacet`], with the position `p` of the new vertex in the
    /// cofacet: its vertices are this simplex's in order with the new one inserted at `p`.
    pub fn for_each_cofacet_apex(&self, mut f: impl FnMut(&Simplex, usize)) {
        self.for_each_cofacet_split(|c, p, _| f(c, p));
    }

    /// Like [`Simplex::for_each_cofacet_apex`], with the split `(i, s)` that makes each
    /// cofacet (part i split into s and the rest), for [`Simplex::cofacet_into`].
    pub(crate) fn for_each_cofacet_split(&self, mut f: impl FnMut(&Simplex, usize, (usize, u64))) {
        let d = self.d as usize;
        let n = self.n_parts as usize;
        if n == d + 1 {
            return;
        }
        let mut out = Self::blank(d, n + 1);
        for i in 0..n {
            let m = self.parts[i];
            if m.count_ones() < 2 {
                continue;
            }
            let mut s = (m - 1) & m;
            while s != 0 {
                let p = self.cofacet_into(i, s, &mut out);
                f(&out, p, (i, s));
                s = (s - 1) & m;
            }
        }
    }

    /// Writes into `out` the cofacet that splits part `i` into `s` (a non-empty proper
    /// subset of it) followed by the rest; returns the position of its new vertex.
    pub(crate) fn cofacet_into(&self, i: usize, s: u64, out: &mut Simplex) -> usize {
        let d = self.d as usize;
        let n = self.n_parts as usize;
        let top = 1u64 << d;
        let rest = self.parts[i] & !s;
        out.d = self.d;
        out.n_parts = (n + 1) as u8;
        copy_run(&mut out.v0, 0, &self.v0, 0, d);
        if i == n - 1 && s & top != 0 {
            // d+1 moved to the second-to-last part: rotate it to the end.
            shift_by_mask(&mut out.v0[..d], full_mask(d) ^ rest, d);
            out.parts[0] = rest;
            copy_run(&mut out.parts, 1, &self.parts, 0, n - 1);
            out.parts[n] = s;
            0
        } else {
            copy_run(&mut out.parts, 0, &self.parts, 0, i);
            out.parts[i] = s;
            out.parts[i + 1] = rest;
            copy_run(&mut out.parts, i + 2, &self.parts, i + 1, n - 1 - i);
            i + 1
        }
    }

    /// All cofacets (see [`Simplex::for_each_cofacet`]).
    pub fn cofacets(&self) -> Vec<Simplex> {
        let mut out = Vec::new();
        self.for_each_cofacet(|s| out.push(s.clone()));
        out
    }

    /// Calls `f` on every l-coface: every refinement of the partition into l+1 parts, brought
    /// to canonical form. Output-sensitive: every branch of the enumeration yields a coface.
    pub fn for_each_coface(&self, l: usize, f: impl FnMut(&Simplex)) -> Result<()> {
        let d = self.d as usize;
        let k = self.dim();
        if l < k || l > d {
            return Err(Error::InvalidSimplex(format!(
                "a {k}-simplex in R^{d} has no cofaces of dimension {l}"
            )));
        }
        let n = k + 1;
        let mut suffix = [0usize; MAX_PARTS + 1];
        for i in (0..n).rev() {
            suffix[i] = suffix[i + 1] + self.parts[i].count_ones() as usize;
        }
        let mut gen = CofaceGen {
            src: self,
            suffix,
            work: Self::blank(d, l + 1),
            emit: Self::blank(d, l + 1),
            f,
        };
        gen.work.v0 = self.v0;
        gen.refine(0, 0, l + 1);
        Ok(())
    }

    /// All l-cofaces (see [`Simplex::for_each_coface`]).
    pub fn cofaces(&self, l: usize) -> Result<Vec<Simplex>> {
        let mut out = Vec::new();
        self.for_each_coface(l, |s| out.push(s.clone()))?;
        Ok(out)
    }

    /// Whether every vertex of `other` is a vertex of `self`.
    pub fn contains(&self, other: &Simplex) -> bool {
        if other.d != self.d || other.dim() > self.dim() {
            return false;
        }
        let mine = self.vertices();
        let mut all = true;
        other.for_each_vertex(|_, v| all &= mine.iter().any(|w| w == v));
        all
    }

    /// The simplex whose relative interior holds the lattice point `u` (Lemma 10). Fractional
    /// parts within `eps` of each other, or of an integer, are treated as equal, so a point
    /// within `eps` of a lower-dimensional face is located on that face.
    pub fn locate_lattice(u: &[f64], eps: f64) -> Result<Self> {
        let d = u.len();
        check_dim(d)?;
        crate::error::check_finite_in(u, "the lattice point")?;
        let mut s = Self::blank(d, 0);
        let mut z = [(0.0f64, 0u8); MAX_PARTS];
        for (i, &x) in u.iter().enumerate() {
            let mut fl = x.floor();
            let mut fr = x - fl;
            if fr > 1.0 - eps {
                fl += 1.0;
                fr = 0.0;
            } else if fr <= eps {
                fr = 0.0;
            }
            if fl.abs() > i32::MAX as f64 {
                return Err(Error::KeyOverflow {
                    value: fl as i64,
                    bits: 32,
                });
            }
            s.v0[i] = fl as i32;
            z[i] = (fr, i as u8);
        }
        z[d] = (0.0, d as u8);
        // Decreasing fractional part; ties by index, so d+1 ends the zero group, which is last.
        z[..=d].sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut n = 0;
        let mut i = 0;
        while i <= d {
            let lead = z[i].0;
            let mut mask = 0u64;
            while i <= d && lead - z[i].0 <= eps {
                mask |= 1 << z[i].1;
                i += 1;
            }
            s.parts[n] = mask;
            n += 1;
        }
        s.n_parts = n as u8;
        s.canonicalize();
        Ok(s)
    }
}

/// Recursive refinement for [`Simplex::for_each_coface`].
struct CofaceGen<'a, F> {
    src: &'a Simplex,
    /// suffix[i] = number of elements in parts i.. of the source.
    suffix: [usize; MAX_PARTS + 1],
    work: Simplex,
    emit: Simplex,
    f: F,
}

impl<F: FnMut(&Simplex)> CofaceGen<'_, F> {
    /// Refines source parts `part..` into `remaining` parts written from `out_len` on.
    fn refine(&mut self, part: usize, out_len: usize, remaining: usize) {
        let n = self.src.n_parts as usize;
        if part == n {
            let d = self.src.d as usize;
            self.emit.v0[..d].copy_from_slice(&self.work.v0[..d]);
            self.emit.parts[..out_len].copy_from_slice(&self.work.parts[..out_len]);
            self.emit.canonicalize();
            (self.f)(&self.emit);
            return;
        }
        if remaining == n - part {
            // Every remaining part stays whole: copy them and emit, without recursing.
            self.work.parts[out_len..out_len + remaining].copy_from_slice(&self.src.parts[part..n]);
            return self.refine(n, out_len + remaining, 0);
        }
        let m = self.src.parts[part];
        let size = m.count_ones() as usize;
        let later_parts = n - part - 1;
        let later_elems = self.suffix[part + 1];
        let lo = remaining.saturating_sub(later_elems).max(1);
        let hi = size.min(remaining - later_parts);
        for a in lo..=hi {
            self.split(m, a, part, out_len, remaining - a);
        }
    }

    /// Writes every ordered partition of mask `m` into `a` parts, then refines the next part.
    fn split(&mut self, m: u64, a: usize, part: usize, out_len: usize, rem_after: usize) {
        if a == 1 {
            self.work.parts[out_len] = m;
            self.refine(part + 1, out_len + 1, rem_after);
            return;
        }
        let size = m.count_ones() as usize;
        let mut elems = [0u8; 64];
        let mut t = m;
        for e in elems.iter_mut().take(size) {
            *e = t.trailing_zeros() as u8;
            t &= t - 1;
        }
        // The first sub-part takes c elements, leaving at least a-1 for the others.
        for c in 1..=size - (a - 1) {
            // Gosper's hack over c-subsets of 0..size (u128 so that size = 64 cannot overflow).
            let mut comb: u128 = (1u128 << c) - 1;
            let limit: u128 = 1u128 << size;
            while comb < limit {
                let mut s = 0u64;
                let mut x = comb;
                while x != 0 {
                    s |= 1 << elems[x.trailing_zeros() as usize];
                    x &= x - 1;
                }
                self.work.parts[out_len] = s;
                self.split(m & !s, a - 1, part, out_len + 1, rem_after);
                let low = comb & comb.wrapping_neg();
                let r = comb + low;
                comb = (((r ^ comb) >> 2) / low) | r;
            }
        }
    }
}

impl PartialEq for Simplex {
    fn eq(&self, other: &Self) -> bool {
        self.d == other.d && self.parts() == other.parts() && self.base() == other.base()
    }
}

impl Eq for Simplex {}

impl Hash for Simplex {
    fn hash<H: Hasher>(&self, state: &mut H) {
        self.d.hash(state);
        self.base().hash(state);
        self.parts().hash(state);
    }
}

impl fmt::Debug for Simplex {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{self}")
    }
}

impl fmt::Display for Simplex {
    /// `(v0; {1,3}{2})`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "({:?}; ", self.base())?;
        for i in 0..self.n_parts as usize {
            write!(f, "{{")?;
            for (t, e) in self.part_elements(i).enumerate() {
                if t > 0 {
                    write!(f, ",")?;
                }
                write!(f, "{e}")?;
            }
            write!(f, "}}")?;
        }
        write!(f, ")")
    }
}
