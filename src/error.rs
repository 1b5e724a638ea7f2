//! The crate's error type.

use std::fmt::Write as _;

use crate::MAX_DIM;

/// Everything that can go wrong in isomesh, as one typed error.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// An ambient dimension outside 1..=MAX_DIM.
    #[error("ambient dimension {0} is not supported: isomesh handles 1 to {MAX_DIM}")]
    Dimension(usize),
    /// Two things that must have the same dimension do not.
    #[error("dimension mismatch: {0}")]
    DimensionMismatch(String),
    /// A simplex that is not well formed, or whose dimension does not fit the request.
    #[error("invalid simplex: {0}")]
    InvalidSimplex(String),
    /// A NaN or infinite value where a finite number is required.
    #[error("non-finite value {value} in {what}, coordinate {} (counting from 1)", index + 1)]
    NonFinite {
        /// What holds it ("seed 2", "the offset"...).
        what: String,
        /// Index of the offending coordinate (from 0).
        index: usize,
        /// The value itself.
        value: f64,
    },
    /// A triangulation that cannot be built as asked (singular matrix, bad edge length...).
    #[error("invalid triangulation: {0}")]
    Triangulation(String),
    /// A lattice coordinate too large for the compact key.
    #[error(
        "a point lies {} lattice steps from the origin, more than a {bits}-bit key field holds: \
         use a larger edge, a smaller box, or seeds nearer the origin",
        if value.unsigned_abs() >= 1 << 62 { "too many".to_string() } else { value.to_string() }
    )]
    KeyOverflow {
        /// The coordinate.
        value: i64,
        /// Bits per coordinate in the key.
        bits: u32,
    },
    /// A malformed equation, with its position.
    #[error(transparent)]
    Parse(#[from] ParseError),
    /// A malformed or inconsistent spec file.
    #[error("spec: {0}")]
    Spec(String),
    /// Command-line flags or call arguments that cannot be used together or as given (the
    /// message names them).
    #[error("{0}")]
    Usage(String),
    /// WGSL that naga rejects (a bug in the emitter: the message is naga's).
    #[error("generated WGSL does not validate:\n{0}")]
    Wgsl(String),
    /// A trace or scan that cannot run as asked (no seed, seed off M, box too large...).
    #[error("trace: {0}")]
    Trace(String),
    /// Work stopped by the cancel flag (Ctrl-C, a signal); the message says what stopped
    /// and what was kept.
    #[error("{0}")]
    Interrupted(String),
    /// The device certified a verdict that the CPU's exact arithmetic contradicts: a bound
    /// on the device's floats did not hold, so none of its verdicts can be trusted (a bug
    /// to report, or a device that does not round as its specification allows).
    #[error("a device bound does not hold: {0}")]
    DeviceBound(String),
    /// No usable GPU, or a GPU operation that failed.
    #[error("gpu: {0}")]
    Gpu(String),
    /// Work that stopped (or did not start) because the heap would pass the memory limit.
    #[error(
        "{what} needs more than the memory limit of {}: raise the limit (--max-memory) or \
         {advice}",
        crate::memory::human_bytes(*limit)
    )]
    MemoryLimit {
        /// What stopped ("parsing equation 1"...).
        what: String,
        /// The limit, bytes.
        limit: u64,
        /// What else would help ("write smaller equations"...).
        advice: String,
    },
    /// An input/output failure: what was read or written (a path, "standard output") and
    /// the system's error, kept as the source.
    #[error("{context}: {source}")]
    Io {
        /// The path or stream involved, with the flag that named it where there is one.
        context: String,
        /// The system's error.
        #[source]
        source: std::io::Error,
    },
    /// An output that cannot be written as asked: an unknown format, a format that cannot
    /// hold the manifold, a target that is not a regular file, a picture size out of range.
    #[error("{0}")]
    Output(String),
}

impl Error {
    /// An [`Error::Io`] on `context` (a path, "standard output"...).
    pub fn io(context: impl std::fmt::Display, source: std::io::Error) -> Error {
        Error::Io {
            context: context.to_string(),
            source,
        }
    }

    /// The same error, its path or message prefixed by the flag that named it ("--out").
    pub fn for_flag(self, flag: &str) -> Error {
        match self {
            Error::Io { context, source } => Error::Io {
                context: format!("{flag} {context}"),
                source,
            },
            Error::Output(m) => Error::Output(format!("{flag} {m}")),
            e => e,
        }
    }
}

/// Shorthand for results carrying [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Checks that every value is finite, naming the first that is not.
pub fn check_finite(values: &[f64]) -> Result<()> {
    check_finite_in(values, "a point")
}

/// [`check_finite`], saying the values are those of `what` ("seed 2", "the offset"...).
pub fn check_finite_in(values: &[f64], what: &str) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(Error::NonFinite {
            what: what.to_string(),
            index,
            value: values[index],
        }),
        None => Ok(()),
    }
}

/// What went wrong while reading an equation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ErrorKind {
    /// A character that starts no token.
    UnexpectedChar,
    /// A token where another was expected.
    UnexpectedToken,
    /// The input ended in the middle of an expression.
    UnexpectedEnd,
    /// A malformed number such as `1e` or `1.2.3`.
    BadNumber,
    /// A name that is no variable, parameter or constant.
    UnknownName,
    /// A call of something that is not a function.
    UnknownFunction,
    /// A function called with the wrong number of arguments.
    WrongArity,
    /// A variable x_i with i outside 1..=d.
    VariableIndex,
    /// k equations for d variables with k >= d, or no equation at all.
    Dimensions,
    /// A name declared twice (variables and parameters share one namespace).
    DuplicateName,
    /// A constant sub-expression that is NaN or infinite (such as `1/0` or `sqrt(-1)`).
    NonFinite,
    /// More tokens in one equation than the parser's cap (ten million), or more heap than
    /// the memory limit (see [`crate::memory::within`]).
    TooLarge,
    /// More nested levels than the parser's cap.
    TooDeep,
}

/// A parse error with its position (1-based line and column, in characters).
#[derive(Clone, Debug, PartialEq)]
pub struct ParseError {
    /// What went wrong.
    pub kind: ErrorKind,
    /// 1-based line; 0 when the error is not at a place in the text (a declared name, the
    /// number of equations).
    pub line: usize,
    /// 1-based column (0 with line 0).
    pub column: usize,
    /// A sentence for people.
    pub message: String,
    /// Which text it is in ("equation 2", "boundary inequality 1", "equation 2 of the spec
    /// file", where line and column are then the file's); empty when not known.
    pub context: String,
}

impl ParseError {
    /// The same error, said to be in `context`.
    pub fn within(mut self, context: impl Into<String>) -> Self {
        self.context = context.into();
        self
    }
}

impl std::fmt::Display for ParseError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match (self.line, self.context.is_empty()) {
            (0, true) => {}
            (0, false) => write!(f, "{}: ", self.context)?,
            (line, true) => write!(f, "line {line}, column {}: ", self.column)?,
            (line, false) => write!(
                f,
                "line {line}, column {} ({}): ",
                self.column, self.context
            )?,
        }
        write!(f, "{}", self.message)
    }
}

impl std::error::Error for ParseError {}

/// Longest run of non-space characters echoed whole.
const MAX_WORD: usize = 64;
/// Longest message echoed whole, in characters.
const MAX_MESSAGE: usize = 4000;

/// `s` fit to print: control characters (but newlines) and NUL escaped, runs of more than
/// 64 non-space characters cut in the middle, the whole cut after 4000 characters.
pub fn shown(s: &str) -> String {
    let mut out = String::with_capacity(s.len().min(MAX_MESSAGE + 64));
    for (li, line) in s.split('\n').enumerate() {
        if li > 0 {
            out.push('\n');
        }
        let mut word = String::new();
        let mut word_len = 0;
        for c in line.chars() {
            if c == ' ' {
                flush_word(&mut out, &word, word_len);
                word.clear();
                word_len = 0;
                out.push(' ');
            } else {
                word_len += 1;
                if word_len > MAX_WORD {
                    // Only the ends of a long word are shown: keep its last few characters.
                    if word.chars().count() > 2 * MAX_WORD {
                        let head: String = word.chars().take(24).collect();
                        let tail: Vec<char> = word.chars().rev().take(8).collect();
                        word = head + &tail.into_iter().rev().collect::<String>();
                    }
                }
                if c.is_control() {
                    word.extend(c.escape_debug());
                } else {
                    word.push(c);
                }
            }
        }
        flush_word(&mut out, &word, word_len);
    }
    let n = out.chars().count();
    if n > MAX_MESSAGE {
        let mut cut: String = out.chars().take(MAX_MESSAGE).collect();
        let _ = write!(cut, " ... ({} more characters)", n - MAX_MESSAGE);
        return cut;
    }
    out
}

fn flush_word(out: &mut String, word: &str, len: usize) {
    if len <= MAX_WORD {
        out.push_str(word);
        return;
    }
    let chars: Vec<char> = word.chars().collect();
    out.extend(&chars[..24]);
    let _ = write!(out, "...[{len} characters]...");
    out.extend(&chars[chars.len() - 8..]);
}
