//! The GPU side: WGSL emitted from the equation language and validated with naga.

pub mod wgsl;
