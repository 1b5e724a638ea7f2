//! The CPU side: batch evaluation of compiled expressions.

pub mod program;
