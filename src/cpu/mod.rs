//! The CPU side: batch evaluation of compiled expressions, the intersection test, the
//! door-in/door-out pivot of tracing, and the twin of the GPU's vertex shader.

pub mod decide;
pub mod pivot;
pub mod program;
pub mod vertices;
