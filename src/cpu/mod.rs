//! The CPU side: batch evaluation of compiled expressions, the intersection test, and the
//! twin of the GPU's vertex shader.

pub mod decide;
pub mod program;
pub mod vertices;
