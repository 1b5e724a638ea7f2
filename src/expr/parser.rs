//! Lexer and Pratt parser for the equation language. Every error names its kind, line and
//! column; nothing here panics on any input.

use std::fmt;

use super::ast::{Expr, Op1, Op2};

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
}

/// A parse error with its position (1-based line and column, in characters).
#[derive(Clone, Debug, PartialEq)]
pub struct ParseError {
    /// What went wrong.
    pub kind: ErrorKind,
    /// 1-based line.
    pub line: usize,
    /// 1-based column.
    pub column: usize,
    /// A sentence for people.
    pub message: String,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "line {}, column {}: {}",
            self.line, self.column, self.message
        )
    }
}

impl std::error::Error for ParseError {}

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Num(f64),
    Ident(String),
    Op(char),
    End,
}

#[derive(Clone, Debug)]
struct Token {
    tok: Tok,
    line: usize,
    column: usize,
}

fn err(kind: ErrorKind, line: usize, column: usize, message: impl Into<String>) -> ParseError {
    ParseError {
        kind,
        line,
        column,
        message: message.into(),
    }
}

/// Splits one equation into tokens; `line` is the line the text sits on.
fn lex(text: &str, line: usize) -> Result<Vec<Token>, ParseError> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let column = i + 1;
        if c.is_whitespace() {
            i += 1;
        } else if c.is_ascii_digit()
            || (c == '.' && chars.get(i + 1).is_some_and(|d| d.is_ascii_digit()))
        {
            let start = i;
            while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
                i += 1;
            }
            if i < chars.len() && (chars[i] == 'e' || chars[i] == 'E') {
                let mut j = i + 1;
                if j < chars.len() && (chars[j] == '+' || chars[j] == '-') {
                    j += 1;
                }
                if j < chars.len() && chars[j].is_ascii_digit() {
                    while j < chars.len() && chars[j].is_ascii_digit() {
                        j += 1;
                    }
                    i = j;
                } else {
                    return Err(err(
                        ErrorKind::BadNumber,
                        line,
                        column,
                        "malformed number: exponent without digits",
                    ));
                }
            }
            let s: String = chars[start..i].iter().collect();
            if i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                return Err(err(
                    ErrorKind::BadNumber,
                    line,
                    column,
                    format!(
                        "malformed number '{s}{}': a name cannot start with a digit",
                        chars[i]
                    ),
                ));
            }
            match s.parse::<f64>() {
                Ok(v) if v.is_finite() => out.push(Token {
                    tok: Tok::Num(v),
                    line,
                    column,
                }),
                _ => {
                    return Err(err(
                        ErrorKind::BadNumber,
                        line,
                        column,
                        format!("malformed number '{s}'"),
                    ))
                }
            }
        } else if c.is_alphabetic() || c == '_' {
            let start = i;
            while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                i += 1;
            }
            out.push(Token {
                tok: Tok::Ident(chars[start..i].iter().collect()),
                line,
                column,
            });
        } else if c == '*' && chars.get(i + 1) == Some(&'*') {
            out.push(Token {
                tok: Tok::Op('^'),
                line,
                column,
            });
            i += 2;
        } else if "+-*/^(),".contains(c) {
            out.push(Token {
                tok: Tok::Op(c),
                line,
                column,
            });
            i += 1;
        } else {
            return Err(err(
                ErrorKind::UnexpectedChar,
                line,
                column,
                format!("unexpected character '{c}'"),
            ));
        }
    }
    out.push(Token {
        tok: Tok::End,
        line,
        column: chars.len() + 1,
    });
    Ok(out)
}

/// Names an equation may use: variables (0-based index) and parameters (fixed values).
#[derive(Clone, Debug, Default)]
pub struct Scope {
    /// Ambient dimension d: x1..xd are always variables.
    pub dim: usize,
    /// Extra variable names (x, y, z, w by default when d <= 4, or declared ones).
    pub variables: Vec<(String, usize)>,
    /// Named parameters.
    pub parameters: Vec<(String, f64)>,
}

impl Scope {
    /// The default scope for R^d: x1..xd, plus x, y, z, w when d <= 4.
    pub fn new(dim: usize) -> Self {
        let variables = if dim <= 4 {
            ["x", "y", "z", "w"]
                .iter()
                .take(dim)
                .enumerate()
                .map(|(i, n)| (n.to_string(), i))
                .collect()
        } else {
            Vec::new()
        };
        Scope {
            dim,
            variables,
            parameters: Vec::new(),
        }
    }

    /// A scope with declared variable names (replacing x, y, z, w).
    pub fn with_names(names: &[String]) -> Result<Self, ParseError> {
        let mut s = Scope {
            dim: names.len(),
            variables: Vec::new(),
            parameters: Vec::new(),
        };
        for (i, n) in names.iter().enumerate() {
            s.check_new_name(n)?;
            s.variables.push((n.clone(), i));
        }
        Ok(s)
    }

    fn check_new_name(&self, name: &str) -> Result<(), ParseError> {
        let valid = name
            .chars()
            .next()
            .is_some_and(|c| c.is_alphabetic() || c == '_')
            && name.chars().all(|c| c.is_alphanumeric() || c == '_');
        if !valid {
            return Err(err(
                ErrorKind::UnexpectedToken,
                1,
                1,
                format!("'{name}' is not a valid name"),
            ));
        }
        let taken = self.variables.iter().any(|(n, _)| n == name)
            || self.parameters.iter().any(|(n, _)| n == name)
            || FUNCTIONS.iter().any(|(n, _)| *n == name)
            || name == "pi"
            || name == "e";
        if taken {
            return Err(err(
                ErrorKind::DuplicateName,
                1,
                1,
                format!("the name '{name}' is already taken"),
            ));
        }
        Ok(())
    }

    /// Adds a parameter; names must be new and values finite.
    pub fn add_parameter(&mut self, name: &str, value: f64) -> Result<(), ParseError> {
        // A declared parameter may shadow a default single-letter variable name only if unused.
        self.check_new_name(name)?;
        if !value.is_finite() {
            return Err(err(
                ErrorKind::NonFinite,
                1,
                1,
                format!("parameter '{name}' = {value} is not finite"),
            ));
        }
        self.parameters.push((name.to_string(), value));
        Ok(())
    }

    /// What a bare name means.
    fn resolve(&self, name: &str) -> Option<Expr> {
        if let Some((_, i)) = self.variables.iter().find(|(n, _)| n == name) {
            return Some(Expr::Var(*i));
        }
        if let Some((_, v)) = self.parameters.iter().find(|(n, _)| n == name) {
            return Some(Expr::Num(*v));
        }
        match name {
            "pi" => Some(Expr::Num(std::f64::consts::PI)),
            "e" => Some(Expr::Num(std::f64::consts::E)),
            _ => None,
        }
    }
}

/// Built-in functions and their argument counts.
const FUNCTIONS: &[(&str, usize)] = &[
    ("sin", 1),
    ("cos", 1),
    ("tan", 1),
    ("asin", 1),
    ("acos", 1),
    ("atan", 1),
    ("atan2", 2),
    ("sinh", 1),
    ("cosh", 1),
    ("tanh", 1),
    ("exp", 1),
    ("ln", 1),
    ("log", 1),
    ("sqrt", 1),
    ("abs", 1),
    ("sign", 1),
    ("min", 2),
    ("max", 2),
    ("pow", 2),
];

struct Parser<'a> {
    toks: Vec<Token>,
    pos: usize,
    scope: &'a Scope,
}

impl Parser<'_> {
    fn peek(&self) -> &Token {
        &self.toks[self.pos]
    }

    fn next(&mut self) -> Token {
        let t = self.toks[self.pos].clone();
        if self.pos + 1 < self.toks.len() {
            self.pos += 1;
        }
        t
    }

    fn unexpected(&self, t: &Token, wanted: &str) -> ParseError {
        match &t.tok {
            Tok::End => err(
                ErrorKind::UnexpectedEnd,
                t.line,
                t.column,
                format!("the equation ends where {wanted} was expected"),
            ),
            Tok::Num(v) => err(
                ErrorKind::UnexpectedToken,
                t.line,
                t.column,
                format!("unexpected number {v} where {wanted} was expected"),
            ),
            Tok::Ident(n) => err(
                ErrorKind::UnexpectedToken,
                t.line,
                t.column,
                format!("unexpected name '{n}' where {wanted} was expected"),
            ),
            Tok::Op(c) => err(
                ErrorKind::UnexpectedToken,
                t.line,
                t.column,
                format!("unexpected '{c}' where {wanted} was expected"),
            ),
        }
    }

    fn expect(&mut self, c: char, wanted: &str) -> Result<(), ParseError> {
        let t = self.next();
        if t.tok == Tok::Op(c) {
            Ok(())
        } else {
            Err(self.unexpected(&t, wanted))
        }
    }

    /// Pratt loop: binding powers + - : 1/2, * / : 3/4, unary - : 5, ^ : 7/6 (right).
    fn expr(&mut self, min_bp: u8, depth: usize) -> Result<Expr, ParseError> {
        if depth > 200 {
            let t = self.peek();
            return Err(err(
                ErrorKind::UnexpectedToken,
                t.line,
                t.column,
                "expression nested too deeply (over 200 levels)",
            ));
        }
        let mut lhs = self.prefix(depth)?;
        while let Tok::Op(op @ ('+' | '-' | '*' | '/' | '^')) = self.peek().tok {
            let (lbp, rbp) = match op {
                '+' | '-' => (1, 2),
                '*' | '/' => (3, 4),
                _ => (7, 6),
            };
            if lbp < min_bp {
                break;
            }
            self.next();
            let rhs = self.expr(rbp, depth + 1)?;
            lhs = match op {
                '+' => Expr::add(lhs, rhs),
                '-' => Expr::sub(lhs, rhs),
                '*' => Expr::mul(lhs, rhs),
                '/' => Expr::div(lhs, rhs),
                _ => Expr::bin(Op2::Pow, lhs, rhs),
            };
        }
        Ok(lhs)
    }

    fn prefix(&mut self, depth: usize) -> Result<Expr, ParseError> {
        let t = self.next();
        match t.tok {
            Tok::Num(v) => Ok(Expr::Num(v)),
            Tok::Op('-') => Ok(Expr::neg(self.expr(5, depth + 1)?)),
            Tok::Op('+') => self.expr(5, depth + 1),
            Tok::Op('(') => {
                let e = self.expr(0, depth + 1)?;
                self.expect(')', "')'")?;
                Ok(e)
            }
            Tok::Ident(ref name) => {
                if self.peek().tok == Tok::Op('(') {
                    self.call(name, &t, depth)
                } else {
                    self.name(name, &t)
                }
            }
            _ => Err(self.unexpected(&t, "a number, a name or '('")),
        }
    }

    fn name(&self, name: &str, t: &Token) -> Result<Expr, ParseError> {
        if let Some(e) = self.scope.resolve(name) {
            return Ok(e);
        }
        // x1..xd
        if let Some(rest) = name.strip_prefix('x') {
            if !rest.is_empty() && rest.chars().all(|c| c.is_ascii_digit()) {
                let i: usize = rest.parse().unwrap_or(usize::MAX);
                if i >= 1 && i <= self.scope.dim {
                    return Ok(Expr::Var(i - 1));
                }
                return Err(err(
                    ErrorKind::VariableIndex,
                    t.line,
                    t.column,
                    format!(
                        "variable '{name}' is outside x1..x{} (the ambient dimension is {})",
                        self.scope.dim, self.scope.dim
                    ),
                ));
            }
        }
        if FUNCTIONS.iter().any(|(n, _)| *n == name) {
            return Err(err(
                ErrorKind::UnexpectedToken,
                t.line,
                t.column,
                format!("'{name}' is a function: call it as {name}(...)"),
            ));
        }
        Err(err(
            ErrorKind::UnknownName,
            t.line,
            t.column,
            format!("unknown name '{name}'"),
        ))
    }

    fn call(&mut self, name: &str, t: &Token, depth: usize) -> Result<Expr, ParseError> {
        let Some(&(_, arity)) = FUNCTIONS.iter().find(|(n, _)| *n == name) else {
            let what = if self.scope.resolve(name).is_some() {
                format!("'{name}' is not a function")
            } else {
                format!("unknown function '{name}'")
            };
            return Err(err(ErrorKind::UnknownFunction, t.line, t.column, what));
        };
        self.expect('(', "'('")?;
        let mut args = Vec::new();
        if self.peek().tok != Tok::Op(')') {
            loop {
                args.push(self.expr(0, depth + 1)?);
                let sep = self.next();
                match sep.tok {
                    Tok::Op(',') => continue,
                    Tok::Op(')') => break,
                    _ => return Err(self.unexpected(&sep, "',' or ')'")),
                }
            }
        } else {
            self.next();
        }
        if args.len() != arity {
            return Err(err(
                ErrorKind::WrongArity,
                t.line,
                t.column,
                format!(
                    "{name} takes {arity} argument{}, got {}",
                    if arity == 1 { "" } else { "s" },
                    args.len()
                ),
            ));
        }
        let mut args = args.into_iter();
        let mut a = || args.next().unwrap_or(Expr::Num(0.0));
        Ok(match name {
            "atan2" => Expr::bin(Op2::Atan2, a(), a()),
            "min" => Expr::bin(Op2::Min, a(), a()),
            "max" => Expr::bin(Op2::Max, a(), a()),
            "pow" => Expr::bin(Op2::Pow, a(), a()),
            "sin" => Expr::un(Op1::Sin, a()),
            "cos" => Expr::un(Op1::Cos, a()),
            "tan" => Expr::un(Op1::Tan, a()),
            "asin" => Expr::un(Op1::Asin, a()),
            "acos" => Expr::un(Op1::Acos, a()),
            "atan" => Expr::un(Op1::Atan, a()),
            "sinh" => Expr::un(Op1::Sinh, a()),
            "cosh" => Expr::un(Op1::Cosh, a()),
            "tanh" => Expr::un(Op1::Tanh, a()),
            "exp" => Expr::un(Op1::Exp, a()),
            "ln" | "log" => Expr::un(Op1::Ln, a()),
            "sqrt" => Expr::un(Op1::Sqrt, a()),
            "abs" => Expr::un(Op1::Abs, a()),
            _ => Expr::un(Op1::Sign, a()),
        })
    }
}

fn first_non_finite(e: &Expr) -> bool {
    match e {
        Expr::Num(v) => !v.is_finite(),
        Expr::Var(_) => false,
        Expr::Un(_, a) | Expr::PowI(a, _) => first_non_finite(a),
        Expr::Bin(_, a, b) => first_non_finite(a) || first_non_finite(b),
    }
}

/// Parses one expression written on line `line` of its source.
pub fn parse_expr_at(text: &str, scope: &Scope, line: usize) -> Result<Expr, ParseError> {
    let toks = lex(text, line)?;
    if toks.len() == 1 {
        return Err(err(ErrorKind::UnexpectedEnd, line, 1, "empty equation"));
    }
    let mut p = Parser {
        toks,
        pos: 0,
        scope,
    };
    let e = p.expr(0, 0)?;
    let t = p.next();
    if t.tok != Tok::End {
        return Err(p.unexpected(&t, "an operator or the end of the equation"));
    }
    if first_non_finite(&e) {
        return Err(err(
            ErrorKind::NonFinite,
            line,
            1,
            "a constant part of this equation is not finite (division by zero, sqrt of a negative...)",
        ));
    }
    Ok(e)
}

/// Parses one expression (line 1).
pub fn parse_expr(text: &str, scope: &Scope) -> Result<Expr, ParseError> {
    parse_expr_at(text, scope, 1)
}

/// Parses a system: one equation per non-blank line (or separated by ';'), with k < d.
pub fn parse_system(text: &str, scope: &Scope) -> Result<Vec<Expr>, ParseError> {
    let mut eqs = Vec::new();
    let mut last_line = 1;
    for (ln, line) in text.lines().enumerate() {
        last_line = ln + 1;
        let mut offset = 0;
        for piece in line.split(';') {
            if !piece.trim().is_empty() {
                let e = parse_expr_at(piece, scope, ln + 1).map_err(|mut e| {
                    e.column += offset;
                    e
                })?;
                eqs.push(e);
            }
            offset += piece.chars().count() + 1;
        }
    }
    check_counts(eqs.len(), scope.dim, last_line)?;
    Ok(eqs)
}

/// Checks 1 <= k < d.
pub fn check_counts(k: usize, d: usize, line: usize) -> Result<(), ParseError> {
    if k == 0 {
        return Err(err(ErrorKind::Dimensions, line, 1, "no equation given"));
    }
    if k >= d {
        return Err(err(
            ErrorKind::Dimensions,
            line,
            1,
            format!(
                "{k} equation{} in {d} variables: a manifold needs fewer equations than variables",
                if k == 1 { "" } else { "s" }
            ),
        ));
    }
    Ok(())
}
