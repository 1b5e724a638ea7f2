//! What a trace level starts from and hands on (its frontier, the simplices it found, their
//! ways back, the oracle's verdicts), and the parallel helpers the level and the engine share.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use rayon::prelude::*;

use super::table::Key;
use crate::cpu::solve::Status;
use crate::error::Result;

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

/// Runs `f(state, range)` over `0..len` in ranges of `chunk` items, which the pool's threads
/// claim one after another until none is left: each thread works in a state of its own
/// (made by `start` when it claims its first range, handed to `finish` after its last), so
/// the threads stay busy to the end, and the work comes back in about one part per thread,
/// in no set order. On one thread, or for one range, one call of `f` on all the items. The
/// first error met stops the claims and is returned.
pub(crate) fn par_claim<S, T: Send>(
    len: usize,
    chunk: usize,
    start: impl Fn() -> S + Sync,
    f: impl Fn(&mut S, Range<usize>) -> Result<()> + Sync,
    finish: impl Fn(S) -> T + Sync,
) -> Result<Vec<T>> {
    let threads = crate::threads::threads();
    let chunk = chunk.max(1);
    if threads == 1 || len <= chunk {
        let mut state = start();
        f(&mut state, 0..len)?;
        return Ok(vec![finish(state)]);
    }
    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let parts: Vec<Result<Option<T>>> = (0..threads)
        .into_par_iter()
        .map(|_| {
            let mut state = None;
            while !failed.load(Ordering::Relaxed) {
                let at = next.fetch_add(chunk, Ordering::Relaxed);
                if at >= len {
                    break;
                }
                let s = state.get_or_insert_with(&start);
                if let Err(e) = f(s, at..(at + chunk).min(len)) {
                    failed.store(true, Ordering::Relaxed);
                    return Err(e);
                }
            }
            Ok(state.map(&finish))
        })
        .collect();
    let mut out = Vec::with_capacity(parts.len());
    for p in parts {
        out.extend(p?);
    }
    Ok(out)
}

/// Runs `f` on consecutive ranges covering `0..len`, about two per thread and at least
/// `min_chunk` items each, in parallel when there is more than one; returns the results in
/// order. On one thread, one range.
pub(crate) fn par_ranges<T: Send>(
    len: usize,
    min_chunk: usize,
    f: impl Fn(Range<usize>) -> T + Sync,
) -> Vec<T> {
    let threads = crate::threads::threads();
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;

    #[test]
    fn claimed_ranges_cover_every_item_once_in_about_a_part_per_thread() {
        for threads in [1, 2, 3, 8] {
            let p = crate::test_pool(threads);
            for (len, chunk) in [(0, 4), (1, 4), (4, 4), (5, 4), (1000, 7), (1000, 1)] {
                let parts = p
                    .install(|| {
                        par_claim(
                            len,
                            chunk,
                            Vec::new,
                            |seen: &mut Vec<usize>, r| {
                                assert!(threads == 1 || r.len() <= chunk);
                                assert!(!r.is_empty() || len == 0);
                                seen.extend(r);
                                Ok(())
                            },
                            |seen| seen,
                        )
                    })
                    .unwrap();
                assert!(
                    parts.len() <= threads.max(1),
                    "{threads} threads: {} parts",
                    parts.len()
                );
                let mut all: Vec<usize> = parts.concat();
                all.sort_unstable();
                assert!(
                    all == (0..len).collect::<Vec<_>>(),
                    "{threads} threads, {len} items"
                );
            }
        }
    }

    #[test]
    fn a_claimed_range_that_fails_stops_the_claims_with_its_error() {
        let p = crate::test_pool(3);
        let done = AtomicUsize::new(0);
        let out = p.install(|| {
            par_claim(
                10_000,
                10,
                || (),
                |_, r| {
                    done.fetch_add(1, Ordering::Relaxed);
                    if r.contains(&500) {
                        return Err(Error::Trace("at 500".into()));
                    }
                    Ok(())
                },
                |_| (),
            )
        });
        assert!(matches!(out, Err(Error::Trace(m)) if m == "at 500"));
        assert!(
            done.load(Ordering::Relaxed) < 1000,
            "claims went on after the error"
        );
    }
}
