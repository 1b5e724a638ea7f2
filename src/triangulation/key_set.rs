//! The one set of simplex and vertex keys: fixed-width keys of u64 words kept in insertion
//! order in a flat arena, indexed by a hash table of u32 positions (about `8 * words + 5..10`
//! bytes per key, no allocation per key).
//!
//! The table is split into [`SHARDS`] tables by bits of the hash, so that a batch of new
//! keys is indexed by several threads at once ([`KeySet::insert_new_batch`]).
//!
//! The width is known at run time ([`KeySet<usize>`], the public default) or at compile time
//! ([`KeySet<Words<W>>`], which the tracing loop uses: the comparisons and the hash of a key
//! unroll). Both hash a key the same way, so one seed and one overflow guard serve both.

use foldhash::fast::FixedState;
use hashbrown::hash_table::Entry;
use hashbrown::HashTable;
use rayon::prelude::*;
use std::hash::BuildHasher;
use std::ops::Range;

use crate::error::{Error, Result};

/// The number of u64 words in a key: a `usize` known at run time, or [`Words`] at compile
/// time.
pub trait Width: Copy + std::fmt::Debug {
    /// Words per key.
    fn words(self) -> usize;
}

impl Width for usize {
    #[inline]
    fn words(self) -> usize {
        self
    }
}

/// A key width of `W` words, known at compile time.
#[derive(Clone, Copy, Debug, Default)]
pub struct Words<const W: usize>;

impl<const W: usize> Width for Words<W> {
    #[inline]
    fn words(self) -> usize {
        W
    }
}

/// A set of fixed-width keys in insertion order: a flat arena of u64 words indexed by a hash
/// table of u32 positions, about `8 * words + 5..10` bytes per key. The width is a `usize`
/// (the default) or [`Words<W>`], known at compile time, which unrolls the comparisons.
#[derive(Clone, Debug)]
pub struct KeySet<N: Width = usize> {
    width: N,
    /// Most keys it may hold: 2^32, the positions its table stores (lowered in tests).
    max_keys: usize,
    arena: Vec<u64>,
    /// Positions in the arena, in the table [`shard`] of their key's hash names.
    tables: Vec<HashTable<u32>>,
    /// Keys `indexed..len()` are held but not in the tables yet ([`KeySet::push_unindexed`]).
    indexed: usize,
    hasher: FixedState,
}

const SEED: u64 = 0x1503_e5a1;
/// Tables a set is split into (a power of two).
pub const SHARDS: usize = 16;
/// Fewest keys a batch insertion indexes on several threads.
const PAR_BATCH: usize = 128;
/// Most keys [`KeySet::index_rest`] indexes at once.
const INDEX_PIECE: usize = 1 << 16;

/// The table of a key with hash `h`: bits the hash tables use for neither the bucket (low
/// bits) nor the control byte (the top seven).
#[inline]
fn shard(h: u64) -> usize {
    (h >> 48) as usize & (SHARDS - 1)
}

impl KeySet<usize> {
    /// An empty set of keys of `words` words.
    pub fn new(words: usize) -> Self {
        KeySet::with_width(words)
    }
}

impl<const W: usize> KeySet<Words<W>> {
    /// An empty set of keys of `W` words.
    pub fn fixed() -> Self {
        KeySet::with_width(Words)
    }

    /// The key at insertion index `i`, as an array.
    #[inline]
    pub fn key(&self, i: usize) -> &[u64; W] {
        self.get(i).try_into().expect("W words")
    }

    /// The same set with its width known at run time: both widths hash a key alike, so
    /// the tables move as they are, with no key hashed again.
    pub fn into_dynamic(self) -> KeySet<usize> {
        KeySet {
            width: W,
            max_keys: self.max_keys,
            arena: self.arena,
            tables: self.tables,
            indexed: self.indexed,
            hasher: self.hasher,
        }
    }
}

impl<N: Width> KeySet<N> {
    fn with_width(width: N) -> Self {
        assert!(width.words() > 0, "keys of no words");
        KeySet {
            width,
            max_keys: 1 << 32,
            arena: Vec::new(),
            tables: (0..SHARDS).map(|_| HashTable::new()).collect(),
            indexed: 0,
            hasher: FixedState::with_seed(SEED),
        }
    }

    /// Words per key.
    #[inline]
    pub fn words(&self) -> usize {
        self.width.words()
    }

    /// Number of keys.
    #[inline]
    pub fn len(&self) -> usize {
        self.arena.len() / self.words()
    }

    /// Whether the set is empty.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.arena.is_empty()
    }

    /// The key at insertion index `i`.
    #[inline]
    pub fn get(&self, i: usize) -> &[u64] {
        let w = self.words();
        &self.arena[i * w..(i + 1) * w]
    }

    /// The insertion index of `key`, if present: looked up in the table, and keys pushed
    /// unindexed ([`KeySet::push_unindexed`]) and not indexed since scanned one by one.
    #[inline]
    pub fn find(&self, key: &[u64]) -> Option<usize> {
        let h = self.hasher.hash_one(key);
        let (arena, w) = (&self.arena, self.words());
        self.tables[shard(h)]
            .find(h, |&i| &arena[i as usize * w..(i as usize + 1) * w] == key)
            .map(|&i| i as usize)
            .or_else(|| self.scan_unindexed(key))
    }

    /// Where the unindexed keys hold `key` (none, but for [`KeySet::push_unindexed`]).
    fn scan_unindexed(&self, key: &[u64]) -> Option<usize> {
        let w = self.words();
        self.arena[self.indexed * w..]
            .chunks_exact(w)
            .position(|k| k == key)
            .map(|i| self.indexed + i)
    }

    /// Keys pushed by [`KeySet::push_unindexed`] and not indexed yet.
    #[inline]
    pub fn unindexed(&self) -> usize {
        self.len() - self.indexed
    }

    /// Inserts `key`; returns its index and whether it was new. An error, and the set
    /// unchanged, when a new key would need an index past u32 (2^32 keys held already).
    #[inline]
    pub fn insert(&mut self, key: &[u64]) -> Result<(usize, bool)> {
        debug_assert_eq!(key.len(), self.words());
        self.index_rest();
        let h = self.hasher.hash_one(key);
        let w = self.words();
        let i = self.len();
        let fits = self.position(i);
        let KeySet {
            arena,
            tables,
            indexed,
            hasher,
            ..
        } = self;
        let entry = tables[shard(h)].entry(
            h,
            |&i| &arena[i as usize * w..(i as usize + 1) * w] == key,
            |&i| hasher.hash_one(&arena[i as usize * w..(i as usize + 1) * w]),
        );
        match entry {
            Entry::Occupied(e) => Ok((*e.get() as usize, false)),
            Entry::Vacant(e) => {
                e.insert(fits?);
                arena.extend_from_slice(key);
                *indexed += 1;
                Ok((i, true))
            }
        }
    }

    /// Inserts `key`, known not to be in the set (one probe less than [`KeySet::insert`]);
    /// returns its index.
    #[inline]
    pub fn insert_new(&mut self, key: &[u64]) -> Result<usize> {
        debug_assert_eq!(key.len(), self.words());
        self.index_rest();
        debug_assert!(self.find(key).is_none());
        let i = self.len();
        let pos = self.position(i)?;
        let h = self.hasher.hash_one(key);
        let (arena, w, hasher) = (&self.arena, self.words(), &self.hasher);
        self.tables[shard(h)].insert_unique(h, pos, |&j| {
            hasher.hash_one(&arena[j as usize * w..(j as usize + 1) * w])
        });
        self.arena.extend_from_slice(key);
        self.indexed += 1;
        Ok(i)
    }

    /// Inserts the keys `keys` (one after another, [`KeySet::words`] each), distinct and
    /// known not to be in the set, in order; returns their indices. A large batch is indexed
    /// by several threads, one table each. An error, and the set unchanged, when they would
    /// need an index past u32.
    pub fn insert_new_batch(&mut self, keys: &[u64]) -> Result<Range<usize>> {
        self.index_rest();
        let added = self.push_unindexed(keys)?;
        self.index_rest();
        Ok(added)
    }

    /// Appends the keys `keys` (as [`KeySet::insert_new_batch`] takes them, distinct and
    /// not in the set) without indexing them: [`KeySet::get`] reads them at once,
    /// [`KeySet::find`] scans them one by one until [`KeySet::index_rest`] (or an insertion)
    /// indexes them. For a set mostly read by index, whose lookups are few and late. Returns their indices; an error, and the set
    /// unchanged, when they would need an index past u32.
    pub fn push_unindexed(&mut self, keys: &[u64]) -> Result<Range<usize>> {
        let w = self.words();
        debug_assert_eq!(keys.len() % w, 0);
        let (start, count) = (self.len(), keys.len() / w);
        if count > 0 {
            self.position(start + count - 1)?;
        }
        self.arena.extend_from_slice(keys);
        Ok(start..start + count)
    }

    /// Indexes the keys pushed by [`KeySet::push_unindexed`] and not indexed yet: a large
    /// batch on several threads, one table each, in pieces of 2^16 keys (their
    /// hashes are held meanwhile).
    pub fn index_rest(&mut self) {
        while self.indexed < self.len() {
            let count = (self.len() - self.indexed).min(INDEX_PIECE);
            self.index_piece(count);
        }
    }

    /// Indexes the next `count` keys not indexed yet.
    fn index_piece(&mut self, count: usize) {
        let (start, w) = (self.indexed, self.words());
        self.indexed += count;
        let (arena, hasher) = (&self.arena, &self.hasher);
        let rehash = |&j: &u32| hasher.hash_one(&arena[j as usize * w..(j as usize + 1) * w]);
        let keys = &arena[start * w..(start + count) * w];
        if count < PAR_BATCH || crate::threads::threads() == 1 {
            for (i, key) in keys.chunks_exact(w).enumerate() {
                let h = hasher.hash_one(key);
                // Positions were checked when the keys were pushed.
                self.tables[shard(h)].insert_unique(h, (start + i) as u32, rehash);
            }
            return;
        }
        let hashes: Vec<u64> = keys
            .par_chunks_exact(w)
            .with_min_len(PAR_BATCH)
            .map(|k| hasher.hash_one(k))
            .collect();
        // The piece's positions bucketed by table (a counting sort, in order), so that each
        // table's thread reads only its own keys and grows its table once.
        // Table t's positions are order[bounds[t]..bounds[t + 1]].
        let mut bounds = [0usize; SHARDS + 1];
        for &h in &hashes {
            bounds[shard(h) + 1] += 1;
        }
        for t in 0..SHARDS {
            bounds[t + 1] += bounds[t];
        }
        let mut next = bounds;
        let mut order = vec![0u32; count];
        for (i, &h) in hashes.iter().enumerate() {
            let t = shard(h);
            order[next[t]] = i as u32;
            next[t] += 1;
        }
        self.tables
            .par_iter_mut()
            .enumerate()
            .for_each(|(t, table)| {
                let own = &order[bounds[t]..bounds[t + 1]];
                table.reserve(own.len(), rehash);
                for &i in own {
                    table.insert_unique(hashes[i as usize], start as u32 + i, rehash);
                }
            });
    }

    /// The table position of the key at index `i`, or the overflow error.
    #[inline]
    fn position(&self, i: usize) -> Result<u32> {
        u32::try_from(i)
            .ok()
            .filter(|_| i < self.max_keys)
            .ok_or_else(|| Error::Trace(format!("more than {} keys", self.max_keys)))
    }

    /// Reserves room for `additional` more keys.
    pub fn reserve(&mut self, additional: usize) {
        let w = self.words();
        self.arena.reserve(additional * w);
        let (arena, hasher) = (&self.arena, &self.hasher);
        // Keys spread evenly over the tables, give or take a few.
        let each = additional / SHARDS + additional.div_ceil(SHARDS).isqrt() * 4;
        for table in &mut self.tables {
            table.reserve(each, |&i| {
                hasher.hash_one(&arena[i as usize * w..(i as usize + 1) * w])
            });
        }
    }

    /// Keys in insertion order.
    pub fn iter(&self) -> impl Iterator<Item = &[u64]> {
        self.arena.chunks_exact(self.words())
    }

    /// Bytes held by the arena and the table.
    pub fn memory_bytes(&self) -> usize {
        self.arena.capacity() * 8
            + self
                .tables
                .iter()
                .map(HashTable::allocation_size)
                .sum::<usize>()
    }

    /// Bytes that inserting `extra` more keys may allocate on top of
    /// [`KeySet::memory_bytes`] (the arena and the table grow by doubling, the old table live
    /// while the new one fills).
    pub fn growth_bytes(&self, extra: usize) -> usize {
        let (len, w) = (self.len() + extra, self.words());
        let mut grow = 0;
        if len * w > self.arena.capacity() {
            grow += (len * w).max(2 * self.arena.capacity()) * 8;
        }
        // The tables grow one by one; counted as if they were one (more than they need),
        // holding every key (those pushed unindexed are indexed at the next lookup).
        let capacity: usize = self.tables.iter().map(HashTable::capacity).sum();
        if len > capacity {
            let size: usize = self.tables.iter().map(HashTable::allocation_size).sum();
            // A bucket: its u32 and a control byte, at 7/8 load, in a power of two.
            grow += (len * 8 / 7).next_power_of_two() * 5 + size;
        }
        grow
    }

    /// The arena: the keys one after another, in insertion order.
    pub fn into_words(self) -> Vec<u64> {
        self.arena
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_key_set_refuses_a_key_past_its_last_index() {
        let mut set = KeySet::new(2);
        set.max_keys = 3;
        for i in 0..3u64 {
            assert_eq!(set.insert(&[i, 7]).unwrap(), (i as usize, true));
        }
        // Known keys are still found; a new one is refused and leaves the set as it was.
        assert_eq!(set.insert(&[1, 7]).unwrap(), (1, false));
        for e in [
            set.insert(&[9, 9]).unwrap_err(),
            set.insert_new(&[9, 9]).unwrap_err(),
        ] {
            assert!(e.to_string().contains("more than 3 keys"), "{e}");
        }
        assert_eq!(set.len(), 3);
        assert_eq!(set.find(&[9, 9]), None);
        assert_eq!(set.find(&[2, 7]), Some(2));
    }

    #[test]
    fn a_fixed_width_set_keeps_its_keys_when_its_width_moves_to_run_time() {
        let mut fixed = KeySet::<Words<3>>::fixed();
        let keys: Vec<u64> = (0..3000u64).flat_map(|i| [i * 7919, i, !i]).collect();
        fixed.insert_new_batch(&keys).unwrap();
        let set = fixed.into_dynamic();
        assert_eq!(set.words(), 3);
        for (i, key) in keys.chunks_exact(3).enumerate() {
            assert_eq!(set.find(key), Some(i));
        }
        assert_eq!(set.find(&[1, 2, 3]), None);
        let mut set = set;
        assert_eq!(set.insert(&[1, 2, 3]).unwrap(), (3000, true));
        assert_eq!(set.insert(&keys[..3]).unwrap(), (0, false));
    }

    #[test]
    fn keys_pushed_unindexed_are_read_at_once_and_found_once_indexed() {
        // Small and large pieces, pushed one after another, then indexed together; an
        // insertion or a second push indexes what is pending first.
        let mut set = KeySet::new(2);
        let mut all = Vec::new();
        for (n, count) in [(0u64, 3usize), (1, PAR_BATCH + 7), (2, 0), (3, 2)] {
            let keys: Vec<u64> = (0..count as u64).flat_map(|i| [i * 7919, n]).collect();
            assert_eq!(
                set.push_unindexed(&keys).unwrap(),
                all.len() / 2..(all.len() + keys.len()) / 2
            );
            all.extend_from_slice(&keys);
            for (i, key) in all.chunks_exact(2).enumerate() {
                assert_eq!(set.get(i), key);
            }
        }
        // Found by a scan while unindexed, then in the table.
        assert_eq!(set.unindexed(), all.len() / 2);
        for indexed in [false, true] {
            if indexed {
                set.index_rest();
                assert_eq!(set.unindexed(), 0);
            }
            for (i, key) in all.chunks_exact(2).enumerate() {
                assert_eq!(set.find(key), Some(i));
            }
            assert_eq!(set.find(&[1, 9]), None);
        }
        set.push_unindexed(&[5, 9]).unwrap();
        assert_eq!(set.insert(&[5, 9]).unwrap(), (all.len() / 2, false));
        set.push_unindexed(&[6, 9]).unwrap();
        assert_eq!(set.insert_new(&[7, 9]).unwrap(), all.len() / 2 + 2);
        assert_eq!(set.find(&[6, 9]), Some(all.len() / 2 + 1));
        // Past the last index: refused, the set unchanged.
        set.max_keys = set.len() + 1;
        assert!(set.push_unindexed(&[1, 1, 2, 2]).is_err());
        assert_eq!(set.len(), all.len() / 2 + 3);
    }

    #[test]
    fn a_batch_is_indexed_as_one_key_at_a_time() {
        for count in [0, 1, PAR_BATCH - 1, PAR_BATCH, 5000] {
            let keys: Vec<u64> = (0..count as u64)
                .flat_map(|i| [i * 7919 % 100_003, i])
                .collect();
            let mut one = KeySet::new(2);
            let mut batch = KeySet::new(2);
            one.insert(&[u64::MAX, 0]).unwrap();
            batch.insert(&[u64::MAX, 0]).unwrap();
            for key in keys.chunks_exact(2) {
                one.insert_new(key).unwrap();
            }
            assert_eq!(batch.insert_new_batch(&keys).unwrap(), 1..count + 1);
            assert_eq!(batch.len(), one.len());
            for (i, key) in keys.chunks_exact(2).enumerate() {
                assert_eq!(batch.find(key), Some(i + 1), "{count} keys");
                assert_eq!(batch.get(i + 1), key);
            }
            assert_eq!(batch.find(&[u64::MAX, 0]), Some(0));
            assert_eq!(batch.find(&[3, u64::MAX]), None);
            // Every table holds keys, and only its own.
            if count >= 5000 {
                for (t, table) in batch.tables.iter().enumerate() {
                    assert!(
                        table.len() > count / SHARDS / 2,
                        "table {t}: {}",
                        table.len()
                    );
                    for &j in table {
                        assert_eq!(shard(batch.hasher.hash_one(batch.get(j as usize))), t);
                    }
                }
            }
        }
        // Past the last index: refused, the set unchanged.
        let mut set = KeySet::new(1);
        set.max_keys = PAR_BATCH + 1;
        set.insert(&[u64::MAX]).unwrap();
        let keys: Vec<u64> = (0..PAR_BATCH as u64 + 1).collect();
        assert!(set.insert_new_batch(&keys).is_err());
        assert_eq!((set.len(), set.find(&[0])), (1, None));
        assert_eq!(set.insert_new_batch(&keys[1..]).unwrap(), 1..PAR_BATCH + 1);
    }

    #[test]
    fn both_widths_hash_alike_and_keep_insertion_order() {
        let mut fixed = KeySet::<Words<3>>::fixed();
        let mut dynamic = KeySet::new(3);
        for i in 0..1000u64 {
            let key = [i * 7919 % 1000, i, u64::MAX - i];
            assert_eq!(fixed.insert_new(&key).unwrap(), i as usize);
            assert_eq!(dynamic.insert(&key).unwrap(), (i as usize, true));
        }
        for i in (0..1000).rev() {
            let key = *fixed.key(i);
            assert_eq!(fixed.find(&key), Some(i));
            assert_eq!(dynamic.find(&key), Some(i));
            assert_eq!(
                fixed.hasher.hash_one(key),
                dynamic.hasher.hash_one(dynamic.get(i))
            );
        }
        assert_eq!(fixed.find(&[1, 2, 3]), None);
        assert_eq!(
            fixed.into_words(),
            dynamic.iter().flatten().copied().collect::<Vec<_>>()
        );
    }
}
