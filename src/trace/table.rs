//! A hash set of fixed-width keys `[u64; W]` in insertion order: a flat arena of words plus
//! a table of u32 positions, about 8 W + 5..10 bytes per key.

use foldhash::fast::FixedState;
use hashbrown::HashTable;
use std::hash::BuildHasher;

use crate::error::{Error, Result};

/// A simplex or vertex key.
pub(crate) type Key<const W: usize> = [u64; W];

pub(crate) struct Table<const W: usize> {
    words: Vec<u64>,
    index: HashTable<u32>,
    hasher: FixedState,
}

impl<const W: usize> Table<W> {
    pub fn new() -> Self {
        Table {
            words: Vec::new(),
            index: HashTable::new(),
            hasher: FixedState::with_seed(0x5eed_150e),
        }
    }

    #[inline]
    pub fn len(&self) -> usize {
        self.words.len() / W
    }

    #[inline]
    pub fn key(&self, i: usize) -> &Key<W> {
        self.words[i * W..(i + 1) * W].try_into().expect("W words")
    }

    #[inline]
    pub fn find(&self, key: &Key<W>) -> Option<u32> {
        let h = self.hasher.hash_one(key);
        self.index
            .find(h, |&i| self.key(i as usize) == key)
            .copied()
    }

    /// Inserts `key`; its position and whether it is new.
    pub fn insert(&mut self, key: &Key<W>) -> Result<(u32, bool)> {
        let h = self.hasher.hash_one(key);
        match self.index.find(h, |&i| self.key(i as usize) == key) {
            Some(&i) => Ok((i, false)),
            None => Ok((self.insert_hashed(h, key)?, true)),
        }
    }

    /// Inserts `key`, known not to be in the table (one probe less than [`Table::insert`]);
    /// returns its position.
    pub fn insert_new(&mut self, key: &Key<W>) -> Result<u32> {
        debug_assert!(self.find(key).is_none());
        self.insert_hashed(self.hasher.hash_one(key), key)
    }

    /// Appends `key`, absent, whose hash is `h`.
    fn insert_hashed(&mut self, h: u64, key: &Key<W>) -> Result<u32> {
        let Table {
            words,
            index,
            hasher,
        } = self;
        let i =
            u32::try_from(words.len() / W).map_err(|_| Error::Io("more than 2^32 keys".into()))?;
        index.insert_unique(h, i, |&j| {
            hasher.hash_one(
                <&Key<W>>::try_from(&words[j as usize * W..(j as usize + 1) * W]).unwrap(),
            )
        });
        words.extend_from_slice(key);
        Ok(i)
    }

    /// Bytes that inserting `extra` more keys may allocate on top of [`Table::bytes`] (the
    /// arena and the index grow by doubling, the old index live while the new one fills).
    pub fn growth_bytes(&self, extra: usize) -> usize {
        let len = self.len() + extra;
        let mut grow = 0;
        if len * W > self.words.capacity() {
            grow += (len * W).max(2 * self.words.capacity()) * 8;
        }
        if len > self.index.capacity() {
            let ratio = len
                .div_ceil(self.index.capacity().max(1))
                .next_power_of_two();
            // A bucket: its u32 and a control byte, at 7/8 load.
            grow += (self.index.allocation_size().max(len * 5 * 8 / 7)) * ratio.max(2);
        }
        grow
    }

    /// Bytes held (arena and table).
    pub fn bytes(&self) -> usize {
        self.words.capacity() * 8 + self.index.allocation_size()
    }

    /// The arena: keys one after another.
    pub fn into_words(self) -> Vec<u64> {
        self.words
    }
}
