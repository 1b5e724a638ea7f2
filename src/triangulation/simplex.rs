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

/// The fixed block that short runs of a simplex's arrays are copied or cleared as.
pub(crate) const RUN_BLOCK: usize = 8;

/// `dst[at..at + len] = src[from..from + len]`, for the short runs of a simplex's arrays:
/// a fixed block of [`RUN_BLOCK`] when it fits both (entries past a simplex's length are not
/// part of it, so overwriting them is harmless when runs are written in ascending order),
/// which compiles to a few moves instead of a call to memmove.
#[inline(always)]
pub(crate) fn copy_run<T: Copy>(dst: &mut [T], at: usize, src: &[T], from: usize, len: usize) {
    if len <= RUN_BLOCK && at + RUN_BLOCK <= dst.len() && from + RUN_BLOCK <= src.len() {
        dst[at..at + RUN_BLOCK].copy_from_slice(&src[from..from + RUN_BLOCK]);
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

    /// [`Simplex::reset`] with the parts cleared (a fixed block of [`RUN_BLOCK`] where they
    /// fit, which compiles to a few stores instead of a call to memset).
    #[inline]
    pub(crate) fn reset_clear(&mut self, d: usize, n_parts: usize) -> (&mut [i32], &mut [u64]) {
        if n_parts <= RUN_BLOCK {
            self.parts[..RUN_BLOCK].fill(0);
        } else {
            self.parts[..n_parts].fill(0);
        }
        self.reset(d, n_parts)
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
        // A buffer no larger than needed: copying all MAX_DIM coordinates cost more than
        // the walk itself in low dimensions.
        fn with<const N: usize>(s: &Simplex, f: &mut impl FnMut(usize, &[i32])) {
            let d = s.d as usize;
            let mut v = [0i32; N];
            v[..d].copy_from_slice(s.base());
            f(0, &v[..d]);
            for i in 1..=s.dim() {
                shift_by_mask(&mut v[..d], s.parts[i - 1], d);
                f(i, &v[..d]);
            }
        }
        match self.d {
            0..=4 => with::<4>(self, &mut f),
            5..=8 => with::<8>(self, &mut f),
            9..=16 => with::<16>(self, &mut f),
            _ => with::<MAX_DIM>(self, &mut f),
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
        let mut out = Self::blank(self.d as usize, 0); // scratch: cofacet_into sets its length
        self.for_each_split(|i, s| {
            let p = self.cofacet_into(i, s, &mut out);
            f(&out, p, (i, s));
        });
    }

    /// Calls `f(i, s)` for the split of every cofacet, in the order of
    /// [`Simplex::for_each_cofacet_split`], without building the cofacets: part i split
    /// into s (a non-empty proper subset of it, listed from the largest down) and the rest.
    /// The cofacet's new vertex is vertex i moved by s.
    pub(crate) fn for_each_split(&self, mut f: impl FnMut(usize, u64)) {
        let n = self.n_parts as usize;
        if n == self.d as usize + 1 {
            return;
        }
        for i in 0..n {
            let m = self.parts[i];
            if m.count_ones() < 2 {
                continue;
            }
            let mut s = (m - 1) & m;
            while s != 0 {
                f(i, s);
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
            work: Self::blank(d, 0), // scratch: only its arrays are used
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
            if fr >= 1.0 - eps {
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

#[cfg(test)]
mod tests {
    use std::collections::hash_map::DefaultHasher;
    use std::collections::HashSet;

    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::super::test_support::{
        random_partition, random_simplex, simplex_from_vertices, simplices_near,
        vertices_by_definition,
    };
    use super::*;

    fn hash_of(s: &Simplex) -> u64 {
        let mut h = DefaultHasher::new();
        s.hash(&mut h);
        h.finish()
    }

    /// The (j+1)-subsets of 0..n in lexicographic order.
    fn subsets(n: usize, size: usize) -> Vec<Vec<usize>> {
        let mut out = Vec::new();
        for bits in 0u32..1 << n {
            if bits.count_ones() as usize == size {
                out.push((0..n).filter(|&i| bits >> i & 1 == 1).collect::<Vec<_>>());
            }
        }
        out.sort();
        out
    }

    fn vertex_set(s: &Simplex) -> HashSet<Vec<i32>> {
        vertices_by_definition(s.base(), s.parts())
            .into_iter()
            .collect()
    }

    #[test]
    fn vertices_follow_the_definition_and_the_base_is_the_smallest() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for round in 0..600 {
            let d = if round % 10 == 0 {
                MAX_DIM
            } else {
                1 + round % 9
            };
            let l = rng.random_range(0..=d);
            let v0: Vec<i32> = (0..d).map(|_| rng.random_range(-5..=5)).collect();
            let parts = random_partition(&mut rng, d, l);
            let s = Simplex::from_masks(&v0, &parts).unwrap();
            // Any cyclic position of the partition is the same simplex: the same vertices.
            let given: HashSet<_> = vertices_by_definition(&v0, &parts).into_iter().collect();
            assert_eq!(vertex_set(&s), given, "{s}");
            assert_eq!((s.ambient_dim(), s.dim(), s.parts().len()), (d, l, l + 1));
            assert_eq!(s.parts()[l] >> d & 1, 1, "d+1 not in the last part: {s}");
            let vs = s.vertices();
            assert_eq!(vs, vertices_by_definition(s.base(), s.parts()));
            assert_eq!(&vs[0][..], s.base());
            assert!(
                vs.iter().all(|v| v >= &vs[0]),
                "the base is not the smallest: {s}"
            );
            let mut out = vec![0; d];
            let mut seen = 0;
            s.for_each_vertex(|i, v| {
                assert_eq!((i, v), (seen, &vs[i][..]));
                seen += 1;
            });
            assert_eq!(seen, l + 1);
            for (i, v) in vs.iter().enumerate() {
                s.vertex_into(i, &mut out);
                assert_eq!(&out, v);
            }
            for (i, &p) in s.parts().iter().enumerate() {
                let elems: Vec<usize> = s.part_elements(i).collect();
                let want: Vec<usize> = (1..=d + 1).filter(|&e| p >> (e - 1) & 1 == 1).collect();
                assert_eq!(elems, want);
            }
        }
    }

    #[test]
    fn faces_are_the_vertex_subsets_in_order() {
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        for round in 0..200 {
            let d = 1 + round % 6;
            let l = rng.random_range(0..=d);
            let s = random_simplex(&mut rng, d, l, 4);
            let vs = s.vertices();
            for j in 0..=l {
                let faces = s.faces(j).unwrap();
                let want = subsets(l + 1, j + 1);
                assert_eq!(faces.len(), want.len(), "{s} j={j}");
                for (f, keep) in faces.iter().zip(&want) {
                    let kept: Vec<_> = keep.iter().map(|&i| vs[i].clone()).collect();
                    assert_eq!(f.vertices(), kept, "{s} j={j}");
                    assert_eq!(f, &simplex_from_vertices(&kept), "{s} j={j}");
                    assert_eq!(f.vertices(), vertices_by_definition(f.base(), f.parts()));
                    assert!(s.contains(f) && f.dim() == j);
                }
            }
            assert!(s.faces(l + 1).is_err());
        }
        // The largest simplex: 64 vertices, 64 facets.
        let s = random_simplex(&mut rng, MAX_DIM, MAX_DIM, 2);
        let vs = s.vertices();
        let points = s.faces(0).unwrap();
        assert_eq!(points.len(), MAX_DIM + 1);
        for (p, v) in points.iter().zip(&vs) {
            assert_eq!(p, &Simplex::vertex(v).unwrap());
        }
        assert_eq!(s.faces(MAX_DIM - 1).unwrap().len(), MAX_DIM + 1);
    }

    #[test]
    fn facets_drop_one_vertex_each_in_order() {
        let mut rng = ChaCha8Rng::seed_from_u64(13);
        for round in 0..400 {
            let d = if round % 8 == 0 {
                20 + round % 40
            } else {
                1 + round % 7
            };
            let l = rng.random_range(0..=d);
            let s = random_simplex(&mut rng, d, l, 4);
            let vs = s.vertices();
            let facets = s.facets();
            if l == 0 {
                assert!(facets.is_empty());
                continue;
            }
            assert_eq!(facets.len(), l + 1);
            let mut out = Simplex::vertex(&[9; 3]).unwrap();
            for (q, f) in facets.iter().enumerate() {
                let mut want = vs.clone();
                want.remove(q);
                assert_eq!(f.vertices(), want, "{s} q={q}");
                assert_eq!(f, &simplex_from_vertices(&want), "{s} q={q}");
                assert_eq!(f.vertices(), vertices_by_definition(f.base(), f.parts()));
                assert_eq!(f.parts()[l - 1] >> d & 1, 1, "facet not canonical");
                s.facet_into(q, &mut out);
                assert_eq!(&out, f, "facet_into({q}) of {s}");
                // Into a scratch holding the simplex itself: nothing of its parts may stay
                // (in increasing q, the previous facet's parts are already the right ones).
                let mut fresh = s.clone();
                s.facet_into(q, &mut fresh);
                assert_eq!(&fresh, f, "facet_into({q}) of {s} over itself");
            }
        }
    }

    #[test]
    fn cofacets_and_cofaces_are_every_simplex_around() {
        let mut rng = ChaCha8Rng::seed_from_u64(14);
        for round in 0..60 {
            let d = 1 + round % 4;
            let k = rng.random_range(0..=d);
            let s = random_simplex(&mut rng, d, k, 3);
            let mine = vertex_set(&s);
            for l in k..=d {
                // Brute force: every l-simplex whose base is within 1 of s's and holds its vertices.
                let want: HashSet<Simplex> = simplices_near(s.base(), l, 1)
                    .into_iter()
                    .filter(|c| vertex_set(c).is_superset(&mine))
                    .collect();
                let got = s.cofaces(l).unwrap();
                assert_eq!(
                    got.len(),
                    want.len(),
                    "{s} l={l}: a coface twice or missing"
                );
                assert_eq!(
                    got.iter().cloned().collect::<HashSet<_>>(),
                    want,
                    "{s} l={l}"
                );
                for c in &got {
                    assert_eq!(c.parts()[l] >> d & 1, 1, "coface not canonical");
                    assert!(c.contains(&s));
                }
                if l == k + 1 {
                    let cofacets = s.cofacets();
                    assert_eq!(cofacets.len(), want.len());
                    assert_eq!(cofacets.into_iter().collect::<HashSet<_>>(), want, "{s}");
                    assert_eq!(s.cofacet_count(), want.len() as u64);
                }
            }
            assert!(s.cofaces(d + 1).is_err());
            if k > 0 {
                assert!(s.cofaces(k - 1).is_err());
            }
            // The apex and the split of each cofacet.
            let vs = s.vertices();
            let mut n = 0;
            let mut out = Simplex::vertex(&[0]).unwrap();
            s.for_each_cofacet_split(|c, p, (i, sub)| {
                let mut cv = c.vertices();
                let apex = cv.remove(p);
                assert_eq!(cv, vs, "{c}: apex {p}");
                assert!(!vs.contains(&apex));
                assert_eq!(s.cofacet_into(i, sub, &mut out), p);
                assert_eq!(&out, c);
                assert_eq!(
                    c,
                    &simplex_from_vertices(&c.vertices()),
                    "{c} not canonical"
                );
                n += 1;
            });
            assert_eq!(n as u64, s.cofacet_count());
            let mut m = 0;
            s.for_each_cofacet_apex(|c, p| {
                let mut cv = c.vertices();
                cv.remove(p);
                assert_eq!(cv, vs);
                m += 1;
            });
            assert_eq!(m, n);
        }
    }

    #[test]
    fn cofaces_in_higher_dimensions_have_the_right_count() {
        // The l-cofaces of an l'-simplex: ordered refinements of each part, counted by
        // ordered set partitions (Fubini numbers), with no repeats.
        let mut rng = ChaCha8Rng::seed_from_u64(15);
        for d in [7usize, 9, 12] {
            let v = Simplex::vertex(&vec![2; d]).unwrap();
            let cofacets = v.cofacets();
            assert_eq!(cofacets.len() as u64, (1u64 << (d + 1)) - 2);
            assert_eq!(v.cofacet_count(), (1u64 << (d + 1)) - 2);
            let s = random_simplex(&mut rng, d, d - 2, 3);
            let got = s.cofaces(d).unwrap();
            let distinct: HashSet<_> = got.iter().cloned().collect();
            assert_eq!(distinct.len(), got.len());
            // Parts of sizes a_i refine into singletons in prod a_i! ways.
            let want: u64 = s
                .parts()
                .iter()
                .map(|p| (1..=p.count_ones() as u64).product::<u64>())
                .product();
            assert_eq!(got.len() as u64, want, "{s}");
            assert!(got.iter().all(|c| c.contains(&s) && c.dim() == d));
        }
        // The largest cofacets: a 62-simplex of R^63 whose first part has two elements.
        let mut parts = vec![0b11u64];
        parts.extend((2..=MAX_DIM).map(|e| 1u64 << e));
        let s = Simplex::from_masks(&[0; MAX_DIM], &parts).unwrap();
        let cofacets = s.cofacets();
        assert_eq!(cofacets.len(), 2);
        for c in &cofacets {
            assert_eq!(c, &simplex_from_vertices(&c.vertices()));
            assert!(c.contains(&s) && c.dim() == MAX_DIM);
        }
        let full = random_simplex(&mut rng, 5, 5, 2);
        assert!(full.cofacets().is_empty() && full.cofacet_count() == 0);
    }

    #[test]
    fn contains_compares_vertex_sets() {
        let mut rng = ChaCha8Rng::seed_from_u64(16);
        for _ in 0..300 {
            let d = rng.random_range(1..=5);
            let (la, lb) = (rng.random_range(0..=d), rng.random_range(0..=d));
            let a = random_simplex(&mut rng, d, la, 1);
            let b = random_simplex(&mut rng, d, lb, 1);
            assert_eq!(a.contains(&b), vertex_set(&a).is_superset(&vertex_set(&b)));
            assert!(a.contains(&a));
        }
        let a = Simplex::vertex(&[0, 0]).unwrap();
        let b = Simplex::vertex(&[0, 0, 0]).unwrap();
        assert!(!a.contains(&b) && !b.contains(&a));
    }

    #[test]
    fn a_point_inside_a_simplex_locates_it() {
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        for round in 0..1500 {
            let d = if round % 50 == 0 {
                MAX_DIM
            } else {
                1 + round % 8
            };
            let l = rng.random_range(0..=d);
            let s = random_simplex(&mut rng, d, l, 1000);
            // Weights of at least 1/(4(l+1)), so no two fractional parts come near each other.
            let w: Vec<f64> = (0..=l).map(|_| rng.random_range(1.0..4.0)).collect();
            let total: f64 = w.iter().sum();
            let mut u = vec![0.0; d];
            for (v, wi) in s.vertices().iter().zip(&w) {
                for (x, &c) in u.iter_mut().zip(v) {
                    *x += wi / total * c as f64;
                }
            }
            let found = Simplex::locate_lattice(&u, 1e-9).unwrap();
            assert_eq!(found, s, "{u:?}");
            // Within eps of a vertex is the vertex.
            let v = &s.vertices()[rng.random_range(0..=l)];
            let near: Vec<f64> = v
                .iter()
                .map(|&c| c as f64 + rng.random_range(-1e-10..1e-10))
                .collect();
            assert_eq!(
                Simplex::locate_lattice(&near, 1e-9).unwrap(),
                Simplex::vertex(v).unwrap()
            );
        }
        assert!(Simplex::locate_lattice(&[], 1e-9).is_err());
        assert!(Simplex::locate_lattice(&[0.5, f64::NAN], 1e-9).is_err());
        assert!(matches!(
            Simplex::locate_lattice(&[0.5, 3e9], 1e-9),
            Err(Error::KeyOverflow { bits: 32, .. })
        ));
        assert!(matches!(
            Simplex::locate_lattice(&[-3e9, 0.0], 1e-9),
            Err(Error::KeyOverflow { bits: 32, .. })
        ));
        let edge = Simplex::locate_lattice(&[2147483647.5, 0.0], 1e-9).unwrap();
        assert_eq!(edge.base(), &[i32::MAX, 0]);
        // Within eps of an integer, both ways and eps included, is the integer.
        let at = |u: &[f64], eps: f64| Simplex::locate_lattice(u, eps).unwrap();
        assert_eq!(at(&[0.75, 0.0], 0.25), Simplex::vertex(&[1, 0]).unwrap());
        assert_eq!(at(&[0.25, 0.0], 0.25), Simplex::vertex(&[0, 0]).unwrap());
        assert_eq!(at(&[0.5, 0.0], 0.25).dim(), 1);
        // Fractional parts within eps of each other are one part.
        let s = Simplex::locate_lattice(&[0.3, 0.3 + 1e-12, 0.7], 1e-9).unwrap();
        assert_eq!(s.dim(), 2);
        assert_eq!(s.parts(), &[0b100, 0b011, 0b1000]);
    }

    #[test]
    fn bad_partitions_are_errors() {
        let v = [0, 0];
        for parts in [
            &[][..],
            &[0b111, 0][..],
            &[0b1, 0b10, 0b100, 0b1000][..],
            &[0b1011][..],
            &[0b011, 0b110][..],
            &[0b001, 0b100][..],
        ] {
            assert!(Simplex::from_masks(&v, parts).is_err(), "{parts:?}");
        }
        assert!(Simplex::from_masks(&[], &[1]).is_err());
        assert!(Simplex::from_masks(&[0; MAX_DIM + 1], &[u64::MAX]).is_err());
        assert!(Simplex::vertex(&[]).is_err());
        assert!(Simplex::from_parts(&v, &[vec![0usize, 1, 2]]).is_err());
        assert!(Simplex::from_parts(&v, &[vec![1usize, 2, 4]]).is_err());
        assert!(Simplex::from_parts(&v, &[vec![1usize, 1], vec![2, 3]]).is_err());
        assert!(Simplex::from_parts(&v, &[vec![2usize, 2], vec![1, 3]]).is_err());
        // The messages name what is wrong.
        let message = |parts: &[u64]| Simplex::from_masks(&v, parts).unwrap_err().to_string();
        assert!(message(&[]).contains("0 parts"), "{}", message(&[]));
        assert!(
            message(&[1, 2, 4, 8]).contains("4 parts"),
            "{}",
            message(&[1, 2, 4, 8])
        );
        assert!(message(&[0b111, 0]).contains("part 2 is empty"));
        assert!(message(&[0b1011]).contains("above 3"));
        assert!(message(&[0b011, 0b110]).contains("repeats"));
        assert!(message(&[0b001, 0b100]).contains("do not cover"));
        let s = Simplex::from_parts(&[1, 2], &[vec![2usize], vec![1, 3]]).unwrap();
        assert_eq!(s.parts(), &[0b010, 0b101]);
        assert_eq!(s.to_string(), "([1, 2]; {2}{1,3})");
        assert_eq!(format!("{s:?}"), "([1, 2]; {2}{1,3})");
        let full = Simplex::vertex(&[0; MAX_DIM]).unwrap();
        assert_eq!(full.parts(), &[u64::MAX]);
    }

    #[test]
    fn equal_simplices_hash_alike_and_different_ones_differ() {
        let a = Simplex::from_parts(&[1, 2], &[vec![2usize], vec![1, 3]]).unwrap();
        // The same simplex from another cyclic position: base [1, 2] + e_2 = [1, 3].
        let b = Simplex::from_parts(&[1, 3], &[vec![1usize, 3], vec![2]]).unwrap();
        assert_eq!(a, b);
        assert_eq!(hash_of(&a), hash_of(&b));
        let other_base = Simplex::from_parts(&[1, 1], &[vec![2usize], vec![1, 3]]).unwrap();
        let other_parts = Simplex::from_parts(&[1, 2], &[vec![1usize], vec![2, 3]]).unwrap();
        let other_d = Simplex::from_parts(&[1, 2, 0], &[vec![2usize], vec![1, 3, 4]]).unwrap();
        for c in [&other_base, &other_parts, &other_d] {
            assert_ne!(&a, c);
            assert_ne!(hash_of(&a), hash_of(c));
        }
        // Storage past the simplex's length does not count.
        let mut long = Simplex::vertex(&[1, 2, 7, 7]).unwrap();
        let (v0, parts) = long.reset(2, 2);
        v0.copy_from_slice(&[1, 2]);
        parts.copy_from_slice(&[0b010, 0b101]);
        assert_eq!(long, a);
        assert_eq!(hash_of(&long), hash_of(&a));
    }

    #[test]
    fn storage_past_a_simplex_is_not_part_of_it() {
        // A 2-simplex of R^3 leaves parts[2] = {3, 4} (with d+1) behind; the edge written
        // over it is not in canonical form and must be canonicalized by its own parts.
        let mut s = Simplex::from_masks(&[0, 0, 0], &[0b0001, 0b0010, 0b1100]).unwrap();
        let (v0, parts) = s.reset(3, 2);
        v0.copy_from_slice(&[0, 0, 0]);
        parts.copy_from_slice(&[0b1001, 0b0110]);
        s.canonicalize();
        assert_eq!(
            s,
            Simplex::from_masks(&[0, 0, 0], &[0b1001, 0b0110]).unwrap()
        );
        assert_eq!(s.parts()[1] >> 3 & 1, 1);
    }

    #[test]
    fn steps_and_masks_at_the_largest_dimension() {
        assert_eq!(full_mask(MAX_DIM), u64::MAX);
        assert_eq!(full_mask(3), 0b1111);
        let mut v = vec![0; MAX_DIM];
        shift_by_mask(&mut v, 1 << MAX_DIM, MAX_DIM);
        assert!(v.iter().all(|&x| x == -1));
        let mut v = vec![0; 4];
        shift_by_mask(&mut v, 0b10101, 4);
        assert_eq!(v, [0, -1, 0, -1]);
        shift_by_mask(&mut v, 0b01010, 4);
        assert_eq!(v, [0, 0, 0, 0]);
        assert!(check_dim(0).is_err() && check_dim(MAX_DIM + 1).is_err());
        assert!(check_dim(1).is_ok() && check_dim(MAX_DIM).is_ok());
        let mut dst = [0u8; 12];
        copy_run(&mut dst, 2, &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12], 1, 3);
        assert_eq!(&dst[2..5], &[2, 3, 4]);
        let mut dst = [0u8; 12];
        copy_run(&mut dst, 1, &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12], 0, 10);
        assert_eq!(&dst[1..11], &[1, 2, 3, 4, 5, 6, 7, 8, 9, 10]);
        // Runs that end near the end of either array take the exact copy (a block of 8
        // would run past it).
        let src: Vec<u8> = (1..=12).collect();
        for (dst_len, at, src_len, from) in
            [(8, 1, 12, 0), (12, 0, 8, 1), (12, 6, 12, 0), (12, 0, 12, 6)]
        {
            let mut dst = vec![0u8; dst_len];
            copy_run(&mut dst, at, &src[..src_len], from, 3);
            assert_eq!(&dst[at..at + 3], &src[from..from + 3]);
        }
    }
}
