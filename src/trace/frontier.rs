//! What a trace level starts from and hands on (its frontier, the simplices it found, their
//! ways back, the oracle's verdicts), and the parallel helpers the level and the engine share.

use std::ops::Range;

use rayon::prelude::*;

use super::table::Key;
use crate::cpu::solve::Status;

/// Oracle verdicts on a batch of candidates.
pub(crate) struct Verdicts {
    pub status: Vec<Status>,
    pub lambda: Vec<f64>,
}

/// The crossed simplices a level found, sorted by key, with their vertex-cache rows,
/// their points (none when not asked for) and their way back (see [`Frontier`]).
pub(crate) struct Found<const W: usize> {
    pub keys: Vec<Key<W>>,
    pub rows: Vec<u32>,
    pub points: Vec<f64>,
    pub back: Back,
}

/// For each simplex of a list, the cache indices of the new vertices of its cofacets known
/// to hold another crossed simplex of S already (the cofacets it was found through): the
/// pivot there would only name a known simplex, so they are skipped.
#[derive(Default)]
pub(crate) struct Back {
    /// `vertices[end[i - 1]..end[i]]` belong to simplex i.
    end: Vec<u32>,
    vertices: Vec<u32>,
}

impl Back {
    /// Room for `lists` lists of `vertices` vertices in all.
    pub(super) fn with_capacity(lists: usize, vertices: usize) -> Self {
        Back {
            end: Vec::with_capacity(lists),
            vertices: Vec::with_capacity(vertices),
        }
    }

    /// The number of vertices in all lists.
    pub(super) fn vertex_count(&self) -> usize {
        self.vertices.len()
    }

    /// The list of simplex i.
    pub(super) fn of(&self, i: usize) -> &[u32] {
        if self.end.is_empty() {
            return &[];
        }
        let start = if i == 0 { 0 } else { self.end[i - 1] as usize };
        &self.vertices[start..self.end[i] as usize]
    }

    /// Adds the next simplex's list.
    pub(super) fn push_list(&mut self, vertices: &[u32]) {
        self.vertices.extend_from_slice(vertices);
        self.end_list();
    }

    /// Adds a vertex to the list being built.
    pub(super) fn push_vertex(&mut self, v: u32) {
        self.vertices.push(v);
    }

    /// Ends the list being built.
    pub(super) fn end_list(&mut self) {
        self.end.push(self.vertices.len() as u32);
    }

    /// The lists of `parts`, one part after another.
    pub(super) fn concat(parts: impl Iterator<Item = Back>) -> Back {
        let mut out = Back::default();
        for p in parts {
            if out.end.is_empty() {
                out = p;
                continue;
            }
            let base = out.vertices.len() as u32;
            out.end.extend(p.end.iter().map(|e| e + base));
            out.vertices.extend_from_slice(&p.vertices);
        }
        out
    }

    /// Keeps simplex i's list (call in order).
    pub fn push_from(&mut self, other: &Back, i: usize) {
        self.vertices.extend_from_slice(other.of(i));
        self.end.push(self.vertices.len() as u32);
    }
}

/// The simplices a level starts from with their vertex-cache rows (k + 1 each) and their
/// way back.
pub(crate) struct Frontier {
    pub members: Members,
    pub rows: Vec<u32>,
    pub back: Back,
}

/// Which simplices of S a frontier holds.
pub(crate) enum Members {
    /// A range of S: a trace's last level.
    Range(Range<usize>),
    /// Listed by index in S: the scan's simplices near the domain's border.
    List(Vec<u32>),
}

impl Members {
    /// How many.
    pub fn len(&self) -> usize {
        match self {
            Members::Range(r) => r.len(),
            Members::List(l) => l.len(),
        }
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The index in S of member `i`.
    pub fn get(&self, i: usize) -> usize {
        match self {
            Members::Range(r) => r.start + i,
            Members::List(l) => l[i] as usize,
        }
    }

    /// The indices in S of every member, in order.
    pub fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        (0..self.len()).map(|i| self.get(i))
    }
}

/// Runs `f` on consecutive ranges covering `0..len`, about two per thread (enough to
/// even out the threads; each range's candidates are a sorted run that the level's ordering
/// merges, so more ranges cost more merging) and at least `min_chunk` items each, in
/// parallel when there is more than one; returns the results in order. On one thread, one
/// range.
pub(crate) fn par_ranges<T: Send>(
    len: usize,
    min_chunk: usize,
    f: impl Fn(Range<usize>) -> T + Sync,
) -> Vec<T> {
    let threads = rayon::current_num_threads();
    if threads == 1 {
        return vec![f(0..len)];
    }
    let chunk = len.div_ceil(2 * threads).max(min_chunk).max(1);
    let parts = len.div_ceil(chunk);
    if parts <= 1 {
        return vec![f(0..len)];
    }
    (0..parts)
        .into_par_iter()
        .map(|c| f(c * chunk..((c + 1) * chunk).min(len)))
        .collect()
}
