//! The GPU side: WGSL emitted from the equation language and validated with naga, adapters
//! and devices through wgpu, and the GPU intersection oracle.

pub mod calibration;
pub mod context;
pub mod oracle;
pub mod wgsl;

pub use context::{adapters, AdapterSummary, Gpu};
pub use oracle::{GpuOptions, GpuOracle, GpuStats};
pub use wgsl::Precision;
