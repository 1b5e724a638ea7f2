//! The vertices cached in the last few levels of a breadth-first trace, in a small
//! set-associative table per thread: naming looks a cofacet's new vertex up in its thread's
//! table, in one cache line that this core wrote, instead of in the whole vertex cache,
//! whose lookups miss the core's caches (and, with several threads, read lines that
//! another core wrote).
//!
//! It is a cache of the cache: it may forget a vertex (an older one is overwritten when a
//! bucket is full), never gives a wrong one, and a vertex it does not hold is looked up in
//! the whole cache later. Nothing it holds or forgets changes the trace's output.

use std::hash::BuildHasher;
use std::ops::Range;
use std::sync::{Mutex, MutexGuard};

use foldhash::fast::FixedState;

use super::table::{Key, Table};

/// Entries per bucket: a bucket of one-word keys fills most of a 64-byte line.
const WAYS: usize = 4;
/// Marks an empty entry.
const EMPTY: u32 = u32::MAX;
/// Fewest buckets.
const MIN_BUCKETS: usize = 1 << 8;

#[derive(Clone, Copy)]
struct Bucket<const W: usize> {
    keys: [Key<W>; WAYS],
    index: [u32; WAYS],
}

impl<const W: usize> Bucket<W> {
    const EMPTY: Self = Bucket {
        keys: [[0; W]; WAYS],
        index: [EMPTY; WAYS],
    };
}

/// Vertex keys with their cache indices, the newest kept where a bucket overflows.
pub(crate) struct RecentVertices<const W: usize> {
    buckets: Vec<Bucket<W>>,
    hasher: FixedState,
    /// The vertices before this one have been added.
    synced: usize,
}

impl<const W: usize> RecentVertices<W> {
    pub fn new() -> Self {
        RecentVertices {
            buckets: vec![Bucket::EMPTY; MIN_BUCKETS],
            hasher: FixedState::with_seed(0x6c62_272e_07bb_0142),
            synced: 0,
        }
    }

    #[inline]
    fn bucket(&self, key: &Key<W>) -> usize {
        // Buckets are a power of two.
        (self.hasher.hash_one(key) as usize) & (self.buckets.len() - 1)
    }

    /// The cache index of `key`, if held.
    #[inline]
    pub fn get(&self, key: &Key<W>) -> Option<u32> {
        let b = &self.buckets[self.bucket(key)];
        (0..WAYS)
            .find(|&w| b.index[w] != EMPTY && b.keys[w] == *key)
            .map(|w| b.index[w])
    }

    /// Holds vertex `index` of `verts`, in place of its bucket's oldest (smallest index)
    /// entry when the bucket is full.
    fn insert(&mut self, verts: &Table<W>, index: usize) {
        let key = verts.key(index);
        let at = self.bucket(key);
        let b = &mut self.buckets[at];
        let w = (0..WAYS)
            .min_by_key(|&w| match b.index[w] {
                EMPTY => (0, 0),
                i => (1, i),
            })
            .unwrap_or(0);
        b.keys[w] = *key;
        b.index[w] = index as u32;
    }

    /// Adds the vertices of `verts` not added yet, and holds those of `window` (a range of
    /// `verts`'s indices that ends at its end): when the window outgrows a quarter of the
    /// table, the table grows to four entries per vertex of the window and is refilled.
    fn sync(&mut self, verts: &Table<W>, window: Range<usize>) {
        let want = window.len().next_power_of_two().max(MIN_BUCKETS);
        let from = if want > self.buckets.len() {
            self.buckets = vec![Bucket::EMPTY; want];
            window.start
        } else {
            self.synced.max(window.start)
        };
        for i in from..window.end {
            self.insert(verts, i);
        }
        self.synced = window.end;
    }
}

/// A value alone in its cache lines (two, for the adjacent-line prefetcher).
#[repr(align(128))]
struct Padded<T>(T);

/// One [`RecentVertices`] per thread of the pool.
pub(crate) struct Replicas<const W: usize> {
    tables: Vec<Padded<Mutex<RecentVertices<W>>>>,
}

impl<const W: usize> Replicas<W> {
    /// A table for each thread of the current pool.
    pub fn new() -> Self {
        Replicas {
            tables: (0..rayon::current_num_threads())
                .map(|_| Padded(Mutex::new(RecentVertices::new())))
                .collect(),
        }
    }

    /// The calling thread's table, holding the vertices of `verts` in `from..` (the last
    /// levels'). Locking it does not wait: no other thread takes it while this one holds it.
    pub fn mine(&self, verts: &Table<W>, from: usize) -> MutexGuard<'_, RecentVertices<W>> {
        let i = rayon::current_thread_index().unwrap_or(0) % self.tables.len();
        let mut t = self.tables[i]
            .0
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        if t.synced != verts.len() {
            t.sync(verts, from.min(verts.len())..verts.len());
        }
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A vertex cache of `n` distinct one-word keys.
    fn cache(n: usize) -> Table<1> {
        let mut t = Table::fixed();
        for i in 0..n as u64 {
            t.insert_new(&[i.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0x55])
                .unwrap();
        }
        t
    }

    #[test]
    fn a_vertex_is_found_with_its_index_or_not_at_all() {
        let verts = cache(20_000);
        let mut r = RecentVertices::<1>::new();
        // A window of 1,000 vertices moving over the cache, 500 at a time.
        let mut found_in_window = 0;
        let mut in_window = 0;
        for end in (1_000..=20_000).step_by(500) {
            r.sync(&verts, end - 1_000..end);
            assert_eq!(r.synced, end);
            for i in 0..20_000 {
                let got = r.get(verts.key(i));
                if let Some(j) = got {
                    assert_eq!(j as usize, i, "a wrong index");
                    assert!(i < end, "a vertex not added yet");
                }
                if (end - 1_000..end).contains(&i) {
                    in_window += 1;
                    found_in_window += got.is_some() as usize;
                }
            }
            // The newest vertex is always held.
            assert_eq!(r.get(verts.key(end - 1)), Some(end as u32 - 1));
        }
        // Four entries per vertex of the window: nearly all of it is held.
        assert!(
            found_in_window * 100 >= in_window * 99,
            "{found_in_window} of {in_window}"
        );
        // A key never added is not found.
        assert_eq!(r.get(&[1]), None);
    }

    #[test]
    fn a_growing_window_grows_the_table_and_keeps_the_window() {
        let verts = cache(50_000);
        let mut r = RecentVertices::<1>::new();
        r.sync(&verts, 0..100);
        let small = r.buckets.len();
        assert!(small >= 100);
        r.sync(&verts, 10_000..50_000);
        assert!(r.buckets.len() >= 40_000, "{} buckets", r.buckets.len());
        let held = (10_000..50_000)
            .filter(|&i| r.get(verts.key(i)) == Some(i as u32))
            .count();
        assert!(held * 100 >= 40_000 * 99, "{held} of 40000");
        // Refilled from the window's start: the vertices before it are gone.
        assert!((100..10_000).all(|i| r.get(verts.key(i)).is_none()));
    }
}
