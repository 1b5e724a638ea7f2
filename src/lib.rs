//! isomesh: piecewise-linear meshes of implicit manifolds f^-1(0), f: R^d -> R^k, of any
//! dimension and codimension, traced on a Coxeter (or Freudenthal-Kuhn) triangulation that is
//! never stored.
//!
//! - [`triangulation`]: simplices as permutahedral representations, faces, cofaces, point
//!   location, compact keys.
//! - [`expr`]: the equation language: parser, derivatives, batch evaluation, WGSL emission,
//!   spec files and presets.

pub mod cpu;
pub mod error;
pub mod expr;
pub mod gpu;
pub mod linalg;
pub mod triangulation;

pub use error::{Error, Result};
