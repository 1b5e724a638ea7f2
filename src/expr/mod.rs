//! The equation language.
/// placeholder
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("parse")]
pub struct ParseError;
