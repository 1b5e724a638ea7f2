//! The ambient triangulation, never stored: simplices are permutahedral representations
//! ([`Simplex`]), placed in R^d by a [`Triangulation`], hashed through compact keys
//! ([`KeyCodec`], [`KeySet`]).

mod geometry;
mod key;
mod key_set;
mod simplex;
#[cfg(test)]
pub(crate) mod test_support;

pub use geometry::{
    random_rotation, Offset, Triangulation, TriangulationBuilder, TriangulationKind, EDGE_RANGE,
};
pub use key::KeyCodec;
pub use key_set::{KeySet, Width, Words};
pub(crate) use simplex::check_dim;
pub(crate) use simplex::{copy_run, shift_by_mask, RUN_BLOCK};
pub use simplex::{Simplex, MAX_DIM};
