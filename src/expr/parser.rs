//! Lexer and recursive-descent parser for the equation language. Every error names its kind, line and
//! column; nothing here panics on any input.

use super::ast::{Expr, Op1, Op2};
pub use crate::error::{ErrorKind, ParseError};

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
        context: String::new(),
    }
}

/// Most tokens (numbers, names, operators) one equation may have: parsing keeps the whole tree
/// in memory (`isomesh check` peaked at about 35 bytes a token on a long sum), so the cap
/// bounds that memory to a few hundred MB.
pub const MAX_TOKENS: usize = 10_000_000;

/// Reads one equation token by token, so that no token list is held in memory.
struct Lexer<'a> {
    text: &'a str,
    /// Byte position of the next character.
    pos: usize,
    /// 1-based column (in characters) of the next character.
    column: usize,
    line: usize,
    count: usize,
}

impl Lexer<'_> {
    fn peek_char(&self, ahead: usize) -> Option<char> {
        self.text[self.pos..].chars().nth(ahead)
    }

    fn bump(&mut self) -> Option<char> {
        let c = self.text[self.pos..].chars().next()?;
        self.pos += c.len_utf8();
        if c == '\n' {
            self.line += 1;
            self.column = 1;
        } else {
            self.column += 1;
        }
        Some(c)
    }

    fn token(&self, tok: Tok, column: usize) -> Token {
        Token {
            tok,
            line: self.line,
            column,
        }
    }

    /// The next token (`Tok::End` at the end, again and again).
    fn next_token(&mut self) -> Result<Token, ParseError> {
        while self.peek_char(0).is_some_and(char::is_whitespace) {
            self.bump();
        }
        let (line, column) = (self.line, self.column);
        let Some(c) = self.peek_char(0) else {
            return Ok(self.token(Tok::End, column));
        };
        self.count += 1;
        if self.count > MAX_TOKENS {
            return Err(err(
                ErrorKind::TooLarge,
                line,
                column,
                format!(
                    "the equation has more than {MAX_TOKENS} tokens (numbers, names, operators): \
                     write it in fewer terms"
                ),
            ));
        }
        if self.count % 1024 == 0 {
            if let Some(limit) = crate::memory::over_limit() {
                return Err(err(
                    ErrorKind::TooLarge,
                    line,
                    column,
                    format!(
                        "parsing the equation passed the memory limit of {} at this token: \
                         raise the limit (--max-memory) or write it in fewer terms",
                        crate::memory::human_bytes(limit)
                    ),
                ));
            }
        }
        let start = self.pos;
        if c.is_ascii_digit() || (c == '.' && self.peek_char(1).is_some_and(|d| d.is_ascii_digit()))
        {
            while self
                .peek_char(0)
                .is_some_and(|c| c.is_ascii_digit() || c == '.')
            {
                self.bump();
            }
            if matches!(self.peek_char(0), Some('e' | 'E')) {
                let sign = usize::from(matches!(self.peek_char(1), Some('+' | '-')));
                if self.peek_char(1 + sign).is_some_and(|c| c.is_ascii_digit()) {
                    self.bump();
                    if sign == 1 {
                        self.bump();
                    }
                    while self.peek_char(0).is_some_and(|c| c.is_ascii_digit()) {
                        self.bump();
                    }
                } else {
                    return Err(err(
                        ErrorKind::BadNumber,
                        line,
                        column,
                        "malformed number: exponent without digits",
                    ));
                }
            }
            let s = &self.text[start..self.pos];
            if let Some(n) = self
                .peek_char(0)
                .filter(|n| n.is_alphanumeric() || *n == '_')
            {
                return Err(err(
                    ErrorKind::BadNumber,
                    line,
                    column,
                    format!("malformed number '{s}{n}': a name cannot start with a digit"),
                ));
            }
            return match s.parse::<f64>() {
                Ok(v) if v.is_finite() => Ok(self.token(Tok::Num(v), column)),
                _ => Err(err(
                    ErrorKind::BadNumber,
                    line,
                    column,
                    format!("malformed number '{s}'"),
                )),
            };
        }
        if c.is_alphabetic() || c == '_' {
            while self
                .peek_char(0)
                .is_some_and(|c| c.is_alphanumeric() || c == '_')
            {
                self.bump();
            }
            let name = self.text[start..self.pos].to_string();
            return Ok(self.token(Tok::Ident(name), column));
        }
        self.bump();
        if c == '*' && self.peek_char(0) == Some('*') {
            self.bump();
            return Ok(self.token(Tok::Op('^'), column));
        }
        if "+-*/^(),".contains(c) {
            return Ok(self.token(Tok::Op(c), column));
        }
        Err(err(
            ErrorKind::UnexpectedChar,
            line,
            column,
            format!("unexpected character '{c}'"),
        ))
    }
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
            // x1..xd always name the coordinates: a variable may be called xi only at place i.
            if coordinate_number(n) != Some(i + 1) {
                s.check_new_name(n)?;
            }
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
                0,
                0,
                format!("'{name}' is not a valid name"),
            ));
        }
        if let Some(i) = coordinate_number(name) {
            return Err(err(
                ErrorKind::DuplicateName,
                0,
                0,
                format!(
                    "the name '{name}' is taken: x1, x2, ... always name the coordinates \
                     (x{i} is coordinate {i}); choose another"
                ),
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
                0,
                0,
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
                0,
                0,
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

/// Most nested levels (parentheses, calls, unary minus, exponents) an equation may have.
pub const MAX_DEPTH: usize = 200;

/// Chains of more terms than this (a + b - c ..., a * b / c ...) are built as balanced trees
/// of left-to-right blocks of this many terms, so that a tree's depth grows with the log of
/// its size: nothing that walks it recursively can exhaust the stack.
const CHAIN_BLOCK: usize = 8;

struct Parser<'a> {
    lexer: Lexer<'a>,
    cur: Token,
    scope: &'a Scope,
}

/// A chain of operands joined by one precedence level's two operators: `inverse` marks the
/// second operator (`-` or `/`).
struct Chain {
    items: Vec<(bool, Expr)>,
    op: Op2,
    inverse: Op2,
}

impl Chain {
    /// The chain's value; `flip` swaps the operators (the first item is never inverted).
    fn build(mut items: Vec<(bool, Expr)>, op: Op2, inverse: Op2, flip: bool) -> Expr {
        if items.len() <= CHAIN_BLOCK {
            let mut it = items.into_iter();
            let Some((_, mut acc)) = it.next() else {
                return Expr::Num(0.0);
            };
            for (inv, e) in it {
                acc = Chain::join(if inv != flip { inverse } else { op }, acc, e);
            }
            return acc;
        }
        let right = items.split_off(items.len() / 2);
        let right_inverted = right[0].0 != flip;
        let lhs = Chain::build(items, op, inverse, flip);
        let rhs = Chain::build(right, op, inverse, flip != right_inverted);
        Chain::join(if right_inverted { inverse } else { op }, lhs, rhs)
    }

    /// Joins two operands of a chain, folding constants. Where folding two finite constants
    /// would overflow, they stay unfolded, to be evaluated as written: a long chain is
    /// regrouped (`x / 1.5 / 1.5 ...` multiplies its divisors first), and regrouping must not
    /// turn a valid equation into an invalid one. Division by zero still folds, and fails.
    fn join(op: Op2, lhs: Expr, rhs: Expr) -> Expr {
        if let (Some(a), Some(b)) = (lhs.as_num(), rhs.as_num()) {
            let overflow = a.is_finite() && b.is_finite() && !op.apply(a, b).is_finite();
            if overflow && !(op == Op2::Div && b == 0.0) {
                return Expr::Bin(op, Box::new(lhs), Box::new(rhs));
            }
        }
        Expr::bin(op, lhs, rhs)
    }

    fn finish(self) -> Expr {
        Chain::build(self.items, self.op, self.inverse, false)
    }
}

impl Parser<'_> {
    fn peek(&self) -> &Token {
        &self.cur
    }

    fn next(&mut self) -> Result<Token, ParseError> {
        let t = self.lexer.next_token()?;
        Ok(std::mem::replace(&mut self.cur, t))
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
        let t = self.next()?;
        if t.tok == Tok::Op(c) {
            Ok(())
        } else {
            Err(self.unexpected(&t, wanted))
        }
    }

    fn check_depth(&self, depth: usize) -> Result<(), ParseError> {
        if depth > MAX_DEPTH {
            let t = self.peek();
            return Err(err(
                ErrorKind::TooDeep,
                t.line,
                t.column,
                format!("expression nested too deeply (over {MAX_DEPTH} levels)"),
            ));
        }
        Ok(())
    }

    /// A sum or difference chain: terms joined by `+` and `-`.
    fn expr(&mut self, depth: usize) -> Result<Expr, ParseError> {
        self.check_depth(depth)?;
        let mut chain = Chain {
            items: vec![(false, self.product(depth)?)],
            op: Op2::Add,
            inverse: Op2::Sub,
        };
        while let Tok::Op(op @ ('+' | '-')) = self.peek().tok {
            self.next()?;
            chain.items.push((op == '-', self.product(depth)?));
        }
        Ok(chain.finish())
    }

    /// A product or quotient chain: factors joined by `*` and `/`.
    fn product(&mut self, depth: usize) -> Result<Expr, ParseError> {
        let mut chain = Chain {
            items: vec![(false, self.unary(depth)?)],
            op: Op2::Mul,
            inverse: Op2::Div,
        };
        while let Tok::Op(op @ ('*' | '/')) = self.peek().tok {
            self.next()?;
            chain.items.push((op == '/', self.unary(depth)?));
        }
        Ok(chain.finish())
    }

    /// Unary `-` and `+` (binding looser than `^`, tighter than `*`), then a power.
    fn unary(&mut self, depth: usize) -> Result<Expr, ParseError> {
        self.check_depth(depth)?;
        match self.peek().tok {
            Tok::Op('-') => {
                self.next()?;
                Ok(Expr::neg(self.unary(depth + 1)?))
            }
            Tok::Op('+') => {
                self.next()?;
                self.unary(depth + 1)
            }
            _ => {
                let base = self.primary(depth)?;
                if self.peek().tok == Tok::Op('^') {
                    self.next()?;
                    // Right-associative: a^b^c = a^(b^c), and a^-b is allowed.
                    let exponent = self.unary(depth + 1)?;
                    Ok(Expr::bin(Op2::Pow, base, exponent))
                } else {
                    Ok(base)
                }
            }
        }
    }

    fn primary(&mut self, depth: usize) -> Result<Expr, ParseError> {
        let t = self.next()?;
        match t.tok {
            Tok::Num(v) => Ok(Expr::Num(v)),
            Tok::Op('(') => {
                let e = self.expr(depth + 1)?;
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
                args.push(self.expr(depth + 1)?);
                let sep = self.next()?;
                match sep.tok {
                    Tok::Op(',') => continue,
                    Tok::Op(')') => break,
                    _ => return Err(self.unexpected(&sep, "',' or ')'")),
                }
            }
        } else {
            self.next()?;
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
    let mut lexer = Lexer {
        text,
        pos: 0,
        column: 1,
        line,
        count: 0,
    };
    let cur = lexer.next_token()?;
    if cur.tok == Tok::End {
        return Err(err(ErrorKind::UnexpectedEnd, line, 1, "empty equation"));
    }
    let mut p = Parser { lexer, cur, scope };
    let e = p.expr(0)?;
    let t = p.next()?;
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

/// ```
/// use isomesh::expr::{parse_expr, ErrorKind, Scope};
///
/// let e = parse_expr("sin(x) * y", &Scope::new(2))?;
/// assert_eq!(e.diff(0).to_string(), "(cos(x1) * x2)");
/// let err = parse_expr("x +* y", &Scope::new(2)).unwrap_err();
/// assert_eq!((err.kind, err.line, err.column), (ErrorKind::UnexpectedToken, 1, 4));
/// # Ok::<(), isomesh::expr::ParseError>(())
/// ```
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

/// `i` when `name` is `xi` (x followed by digits only, i >= 1): a coordinate's name.
fn coordinate_number(name: &str) -> Option<usize> {
    let digits = name.strip_prefix('x')?;
    if digits.is_empty() || !digits.chars().all(|c| c.is_ascii_digit()) {
        return None;
    }
    Some(digits.parse::<usize>().unwrap_or(usize::MAX)).filter(|&i| i >= 1)
}

/// Checks 1 <= k < d; `line` is the line of the text the error is put at (0: none, when the
/// equations were given one by one).
pub fn check_counts(k: usize, d: usize, line: usize) -> Result<(), ParseError> {
    let column = usize::from(line > 0);
    if k == 0 {
        return Err(err(
            ErrorKind::Dimensions,
            line,
            column,
            "no equation given",
        ));
    }
    if k >= d {
        return Err(err(
            ErrorKind::Dimensions,
            line,
            column,
            format!(
                "{k} equation{} in {d} variables: a manifold needs fewer equations than variables",
                if k == 1 { "" } else { "s" }
            ),
        ));
    }
    Ok(())
}
