//! The key types of the tracing loop: keys of a width `W` fixed at compile time.

use crate::triangulation::{KeySet, Words};

/// A simplex or vertex key.
pub(crate) type Key<const W: usize> = [u64; W];

/// A set of `W`-word keys in insertion order.
pub(crate) type Table<const W: usize> = KeySet<Words<W>>;
