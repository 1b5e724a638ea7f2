//! The CPU side: batch evaluation of compiled expressions and the intersection test.

pub mod decide;
pub mod program;
