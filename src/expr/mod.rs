//! The equation language: one text form for f, parsed once into trees that evaluate on the
//! CPU in batches ([`program`]), differentiate symbolically, and emit WGSL
//! (the GPU module's `wgsl`); spec files and presets are written in it.

pub mod ast;
#[cfg(feature = "internals")]
pub mod certified;
#[cfg(not(feature = "internals"))]
pub(crate) mod certified;
pub mod parser;
pub mod presets;
pub mod program;
pub mod spec;
pub mod system;

pub use ast::{Expr, Op1, Op2};
pub use parser::{parse_expr, parse_system, ErrorKind, ParseError, Scope};
pub use presets::{preset, preset_names, preset_spec, PresetInfo, PRESETS};
pub use spec::{Problem, Spec, TriangulationSpec};
pub use system::{
    is_singular_at, newton_project, rank_ratio, zero_equation_at, ClosureFunction, EquationSystem,
    ImplicitFunction,
};
