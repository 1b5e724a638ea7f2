//! Sorting on all the pool's threads, for the arrays of a trace level: a few thousand
//! items, too few for rayon's parallel sorts to pay, sorted once or twice per level.
//!
//! The array is cut into chunks sorted in parallel; splitters sampled from the sorted
//! chunks then cut every chunk into pieces of the key range, and each piece of the output
//! gathers its part of every chunk and merges them, in parallel. The output is the sorted
//! array: for items whose order is total on their whole value (equal items are
//! identical), the same as a sequential sort's, whatever the threads.
//!
//! [`distinct_ranks`] finds a list's distinct values by hashing, and sorts only them.

use std::hash::{BuildHasher, Hash};

use foldhash::fast::FixedState;
use hashbrown::hash_table::{Entry, HashTable};
use rayon::prelude::*;

/// Below this length a sort runs on the calling thread.
const PAR_SORT_MIN: usize = 1 << 10;
/// Items sampled from each sorted chunk to choose the splitters.
const SAMPLES_PER_CHUNK: usize = 16;

/// Sorts `v`, on several threads when it pays.
pub(crate) fn sort<T: Ord + Copy + Send + Sync>(v: &mut Vec<T>) {
    match pieces(v.len()) {
        Some(p) => sort_in_pieces(v, p),
        None => v.sort_unstable(),
    }
}

/// Sorts `v`, a concatenation of sorted runs (merging them), on several threads when it
/// pays.
pub(crate) fn sort_runs<T: Ord + Copy + Send + Sync>(v: &mut Vec<T>) {
    match pieces(v.len()) {
        Some(p) => sort_in_pieces(v, p),
        // A stable sort finds the runs and merges them.
        None => v.sort(),
    }
}

/// The distinct values of `items` in increasing order, and for each item the position of
/// its value among them. A hash table finds the distinct values in one pass, so that only
/// they are sorted (a level's new vertices come about 2.5 times each).
pub(crate) fn distinct_ranks<K: Ord + Hash + Copy + Send + Sync>(
    items: &[K],
) -> (Vec<K>, Vec<u32>) {
    let hasher = FixedState::default();
    let mut table: HashTable<u32> = HashTable::with_capacity(items.len());
    // Each distinct value with its number in the order of first appearance.
    let mut firsts: Vec<(K, u32)> = Vec::new();
    let mut slots: Vec<u32> = Vec::with_capacity(items.len());
    for x in items {
        let h = hasher.hash_one(x);
        let at = |&j: &u32| hasher.hash_one(firsts[j as usize].0);
        let slot = match table.entry(h, |&j| firsts[j as usize].0 == *x, at) {
            Entry::Occupied(e) => *e.get(),
            Entry::Vacant(e) => {
                let j = firsts.len() as u32;
                e.insert(j);
                firsts.push((*x, j));
                j
            }
        };
        slots.push(slot);
    }
    drop(table);
    sort(&mut firsts);
    let mut rank = vec![0u32; firsts.len()];
    for (r, &(_, j)) in firsts.iter().enumerate() {
        rank[j as usize] = r as u32;
    }
    for s in &mut slots {
        *s = rank[*s as usize];
    }
    (firsts.into_iter().map(|(x, _)| x).collect(), slots)
}

/// How many chunks (and pieces) a sort of `len` items uses; `None` to sort on one thread.
fn pieces(len: usize) -> Option<usize> {
    let threads = crate::threads::threads();
    (threads > 1 && len >= PAR_SORT_MIN).then(|| (2 * threads).min(len / 64).max(2))
}

/// Sorts `v` as the module says, in `parts` chunks and pieces.
fn sort_in_pieces<T: Ord + Copy + Send + Sync>(v: &mut Vec<T>, parts: usize) {
    let chunk = v.len().div_ceil(parts);
    // Stable: a chunk that holds sorted runs is merged, not sorted again.
    v.par_chunks_mut(chunk).for_each(|c| c.sort());
    let chunks: Vec<&[T]> = v.chunks(chunk).collect();
    let mut sample: Vec<T> = chunks
        .iter()
        .flat_map(|c| (0..SAMPLES_PER_CHUNK).map(move |i| c[i * c.len() / SAMPLES_PER_CHUNK]))
        .collect();
    sample.sort_unstable();
    let splitters: Vec<T> = (1..parts)
        .map(|j| sample[j * sample.len() / parts])
        .collect();
    // Piece j holds the items in [splitter j - 1, splitter j): `bounds[j][c]` is where it
    // starts in chunk c.
    let bounds: Vec<Vec<usize>> = (0..=parts)
        .map(|j| {
            chunks
                .iter()
                .map(|c| match j {
                    0 => 0,
                    j if j == parts => c.len(),
                    j => c.partition_point(|x| *x < splitters[j - 1]),
                })
                .collect()
        })
        .collect();
    let mut out = v.clone();
    let mut rest: &mut [T] = &mut out;
    let mut slots = Vec::with_capacity(parts);
    for j in 0..parts {
        let size = (0..chunks.len())
            .map(|c| bounds[j + 1][c] - bounds[j][c])
            .sum();
        let (slot, tail) = rest.split_at_mut(size);
        slots.push(slot);
        rest = tail;
    }
    slots.into_par_iter().enumerate().for_each(|(j, slot)| {
        let mut at = 0;
        for (c, run) in chunks.iter().enumerate() {
            let part = &run[bounds[j][c]..bounds[j + 1][c]];
            slot[at..at + part.len()].copy_from_slice(part);
            at += part.len();
        }
        // The sorted parts are runs: a stable sort merges them.
        slot.sort();
    });
    *v = out;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random sequence (xorshift).
    fn noise(n: usize, seed: u64, modulo: u64) -> Vec<u64> {
        let mut x = seed;
        (0..n)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                x % modulo
            })
            .collect()
    }

    #[test]
    fn the_same_order_as_a_sequential_sort_at_every_thread_count() {
        for threads in [1, 2, 3, 8, 16] {
            let p = crate::test_pool(threads);
            for (n, modulo) in [
                (0, 10),
                (5, 10),
                (1023, 1 << 40),
                (1024, 3),
                (5000, 1 << 40),
            ] {
                for (n, modulo) in [(n, modulo), (n * 7 + 13, modulo), (n * 7 + 13, 2)] {
                    // Pairs with a tag: equal keys, distinct items.
                    let v: Vec<(u64, u32)> = noise(n, 0x9e37_79b9 + n as u64, modulo)
                        .into_iter()
                        .zip(0..)
                        .collect();
                    let mut want = v.clone();
                    want.sort_unstable();
                    let mut got = v.clone();
                    p.install(|| sort(&mut got));
                    assert!(got == want, "sort: {threads} threads, {n} items < {modulo}");
                    // Sorted runs of uneven lengths, as naming's parts give them.
                    let mut runs = v.clone();
                    let mut at = 0;
                    for (i, len) in noise(64, 7, 700).into_iter().enumerate() {
                        let end = (at + len as usize + i).min(runs.len());
                        runs[at..end].sort_unstable();
                        at = end;
                    }
                    let mut got = runs;
                    p.install(|| sort_runs(&mut got));
                    assert!(got == want, "runs: {threads} threads, {n} items < {modulo}");
                }
            }
        }
    }

    #[test]
    fn distinct_values_in_order_and_each_items_rank_among_them() {
        for threads in [1, 2, 3] {
            let p = crate::test_pool(threads);
            for (n, modulo) in [(0, 10), (1, 10), (700, 5), (5000, 1 << 40), (9001, 3000)] {
                let items: Vec<[u64; 2]> = noise(n, 0x2545 + n as u64, modulo)
                    .into_iter()
                    .map(|x| [x % 7, x])
                    .collect();
                let mut want = items.clone();
                want.sort_unstable();
                want.dedup();
                let (distinct, ranks) = p.install(|| distinct_ranks(&items));
                assert!(distinct == want, "{threads} threads, {n} items < {modulo}");
                assert_eq!(ranks.len(), n);
                for (x, &r) in items.iter().zip(&ranks) {
                    assert_eq!(distinct[r as usize], *x, "{threads} threads, {n} items");
                }
            }
        }
    }

    #[test]
    fn identical_items_and_one_value_throughout() {
        let p = crate::test_pool(4);
        let mut same = vec![(3u64, 1u32); 4000];
        p.install(|| sort(&mut same));
        assert!(same.iter().all(|x| *x == (3, 1)) && same.len() == 4000);
        let mut two: Vec<u64> = (0..5000).map(|i| u64::from(i % 2 == 0)).collect();
        p.install(|| sort_runs(&mut two));
        assert_eq!(two.iter().filter(|&&x| x == 0).count(), 2500);
        assert!(two.windows(2).all(|w| w[0] <= w[1]));
    }
}
