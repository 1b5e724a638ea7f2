//! isomesh: piecewise-linear meshes of implicit manifolds f^-1(0), f: R^d -> R^k, of any
//! dimension and codimension, traced on a Coxeter (or Freudenthal-Kuhn) triangulation that is
//! never stored.
//!
//! - [`triangulation`]: simplices as permutahedral representations, faces, cofaces, point
//!   location, compact keys.
//! - [`expr`]: the equation language: parser, derivatives, batch evaluation, WGSL emission,
//!   spec files and presets.
//! - [`trace`]: manifold tracing and the exhaustive scan, behind the [`trace::Oracle`] trait.
//! - [`gpu`]: the GPU oracle (wgpu, WGSL). [`complex`]: the cell complex and its topology.
//!   [`export`]: files and pictures. [`bench`](mod@bench): the measurements of `isomesh bench`.
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

pub mod bench;
pub mod complex;
pub mod cpu;
pub mod error;
pub mod export;
pub mod expr;
pub mod gpu;
pub mod linalg;
pub mod memory;
pub mod trace;
pub mod triangulation;

pub use error::{Error, Result};
