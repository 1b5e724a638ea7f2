//! isomesh: piecewise-linear meshes of implicit manifolds f^-1(0), f: R^d -> R^k, of any
//! dimension and codimension, traced on a Coxeter (or Freudenthal-Kuhn) triangulation that is
//! never stored (Boissonnat, Kachanovich and Wintraecken, "Tracing isomanifolds in R^d in time
//! polynomial in d using Coxeter-Freudenthal-Kuhn triangulations", 2021).
//!
//! Start with [`Mesher`]: it owns f (equations as text, a preset, or any
//! [`ImplicitFunction`](expr::ImplicitFunction)), the triangulation, the domain and the
//! backend; [`Mesher::trace`] and [`Mesher::scan`] return a [`Manifold`] that builds its cell
//! complex, reports and writes files:
//!
//! ```
//! use isomesh::Mesher;
//!
//! let sphere = Mesher::preset("sphere", &[])?.edge(0.2).trace()?;
//! let t = sphere.topology()?;
//! assert_eq!((t.euler_characteristic, t.closed), (2, true));
//! let dir = std::env::temp_dir().join(format!("isomesh-doc-{}", std::process::id()));
//! sphere.write(dir.join("sphere.ply"))?;
//! # std::fs::remove_dir_all(&dir).ok();
//! # Ok::<(), isomesh::Error>(())
//! ```
//!
//! The layers below stay public for callers who need them:
//! - [`triangulation`]: simplices as permutahedral representations, faces, cofaces, point
//!   location, compact keys.
//! - [`expr`]: the equation language: parser, derivatives, batch evaluation, spec files and
//!   presets.
//! - [`trace`]: manifold tracing and the exhaustive scan, behind the [`trace::Oracle`] trait.
//! - With the `internals` feature (for the crate's own tests, not a stable API): `cpu`, the
//!   CPU oracle's kernels and the a-posteriori certificate of its verdicts; `emulate`,
//!   device floats that round as adversarially as the WGSL and Vulkan specifications allow;
//!   `linalg`; `expr::certified`, certified evaluation; and the GPU oracle's test hooks.
//! - `gpu` (feature `gpu`): the GPU oracle (wgpu, WGSL). [`complex`]: the cell complex and its
//!   topology. [`export`]: files and pictures. [`report`]: the report's keys.
//!
//! Features: `gpu` (wgpu, naga) and `cli` (the `isomesh` binary), both on by default; with
//! `default-features = false` the library is CPU-only and pulls in neither wgpu nor clap.
//!
//! ```
//! use isomesh::expr::{preset, ImplicitFunction};
//! use isomesh::triangulation::Triangulation;
//!
//! // The built-in torus, its seed already projected onto f^-1(0).
//! let torus = preset("torus", &[]).unwrap();
//! let seed = &torus.seeds[0];
//! let mut f = [0.0];
//! torus.system.eval_batch(seed, &mut f);
//! assert!(f[0].abs() < 1e-12);
//!
//! // The Coxeter simplex holding the seed, and its facets.
//! let t = Triangulation::coxeter(3).edge(0.05).build().unwrap();
//! let s = t.locate(seed).unwrap();
//! assert_eq!(s.dim(), 3);
//! assert_eq!(s.facets().len(), 4);
//! ```

#[cfg(feature = "gpu")]
#[doc(hidden)]
pub mod bench;
pub mod complex;
#[cfg(feature = "internals")]
pub mod cpu;
#[cfg(not(feature = "internals"))]
pub(crate) mod cpu;
#[cfg(feature = "internals")]
pub mod emulate;
#[cfg(not(feature = "internals"))]
pub(crate) mod emulate;
pub mod error;
pub mod export;
pub mod expr;
#[cfg(feature = "gpu")]
pub mod gpu;
#[cfg(feature = "internals")]
pub mod linalg;
#[cfg(not(feature = "internals"))]
pub(crate) mod linalg;
pub mod memory;
pub mod mesher;
pub mod report;
pub mod shard;
pub(crate) mod threads;
pub mod trace;
pub mod triangulation;

pub use error::{Error, Result};

/// Largest ambient dimension: a simplex's ordered partition is held as 64-bit masks over the
/// d+1 elements.
pub const MAX_DIM: usize = 63;

/// README's Rust example, compiled as a doctest.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;
pub use mesher::{Backend, Manifold, Mesher, WriteOptions};
pub use report::Report;

/// A rayon pool of `threads` threads, for the tests that compare thread counts.
#[cfg(test)]
pub(crate) fn test_pool(threads: usize) -> rayon::ThreadPool {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a test's thread pool")
}
