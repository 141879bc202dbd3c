//! Reading the calc language into syntax trees: `{ }` comments (nested),
//! statements `name = e;`, `name : e;` and `f(a, b) = e;`, and expressions of
//! `+ - * / ^`, unary signs, numbers, names and calls. Precedence, lowest
//! first: `+ -`; `* /`; `^` (right-associative); unary `-` and `+`, which
//! bind tighter than `^` (so `-2^2` is 4, as Radiance reads it).

use super::CalcError;

/// Longest name kept (longer names are cut, as Radiance cuts them).
const MAX_NAME: usize = 127;
/// Deepest nesting of parentheses and calls an expression may have.
const MAX_NESTING: usize = 200;

/// A binary operator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Op {
    /// `+`
    Add,
    /// `-`
    Sub,
    /// `*`
    Mul,
    /// `/`
    Div,
    /// `^`
    Pow,
}

/// An expression as written.
#[derive(Clone, Debug, PartialEq)]
pub enum Expr {
    /// A number.
    Num(f64),
    /// A name: a variable, a parameter, or a function passed by name.
    Name(String),
    /// A call.
    Call(String, Vec<Expr>),
    /// Unary minus.
    Neg(Box<Expr>),
    /// A binary operation.
    Bin(Op, Box<Expr>, Box<Expr>),
}

/// One definition of a file.
#[derive(Clone, Debug, PartialEq)]
pub struct Definition {
    /// The name defined.
    pub name: String,
    /// Its parameters (empty for a variable).
    pub params: Vec<String>,
    /// Whether it is a function (written with parentheses, maybe none).
    pub function: bool,
    /// Its body.
    pub body: Expr,
    /// The line it starts on.
    pub line: usize,
}

#[derive(Clone, Debug, PartialEq)]
enum Token {
    Num(f64),
    Name(String),
    Sym(char),
}

/// Splits `text` into tokens with their line numbers.
fn tokens(text: &str, what: &str) -> Result<Vec<(Token, usize)>, CalcError> {
    let bytes = text.as_bytes();
    let mut out = Vec::new();
    let (mut i, mut line) = (0, 1);
    let err = |line: usize, message: String| CalcError::Syntax {
        what: what.to_string(),
        line,
        message,
    };
    while i < bytes.len() {
        let c = bytes[i];
        match c {
            b'\n' => {
                line += 1;
                i += 1;
            }
            c if c.is_ascii_whitespace() => i += 1,
            b'{' => {
                let start = line;
                let mut depth = 0usize;
                loop {
                    match bytes.get(i) {
                        None => return Err(err(start, "a comment opened here is never closed".into())),
                        Some(b'{') => depth += 1,
                        Some(b'}') => depth -= 1,
                        Some(b'\n') => line += 1,
                        Some(_) => {}
                    }
                    i += 1;
                    if depth == 0 {
                        break;
                    }
                }
            }
            b'0'..=b'9' | b'.' => {
                let start = i;
                while i < bytes.len() && bytes[i].is_ascii_digit() {
                    i += 1;
                }
                if bytes.get(i) == Some(&b'.') {
                    i += 1;
                    while i < bytes.len() && bytes[i].is_ascii_digit() {
                        i += 1;
                    }
                }
                if matches!(bytes.get(i), Some(b'e' | b'E')) {
                    i += 1;
                    if matches!(bytes.get(i), Some(b'+' | b'-')) {
                        i += 1;
                    }
                    if !bytes.get(i).is_some_and(u8::is_ascii_digit) {
                        return Err(err(line, "a number's exponent has no digits".into()));
                    }
                    while i < bytes.len() && bytes[i].is_ascii_digit() {
                        i += 1;
                    }
                }
                let s = &text[start..i];
                let v: f64 = s.parse().map_err(|_| err(line, format!("{s:?} is not a number")))?;
                out.push((Token::Num(v), line));
            }
            c if c.is_ascii_alphabetic() || c == b'`' => {
                let start = i;
                while i < bytes.len() && (bytes[i].is_ascii_alphanumeric() || matches!(bytes[i], b'_' | b'.' | b'`')) {
                    i += 1;
                }
                // Context marks (`name`context`) name Radiance's namespaces;
                // every file here has its own, so the mark is dropped.
                let name: String = text[start..i].trim_matches('`').chars().take(MAX_NAME).collect();
                let name = name.split('`').next().unwrap_or("").to_string();
                if name.is_empty() {
                    return Err(err(line, "a name is empty".into()));
                }
                out.push((Token::Name(name), line));
            }
            b'+' | b'-' | b'*' | b'/' | b'^' | b'(' | b')' | b',' | b';' | b'=' | b':' => {
                out.push((Token::Sym(c as char), line));
                i += 1;
            }
            _ => {
                let ch = text[i..].chars().next().unwrap_or('?');
                return Err(err(line, format!("unexpected {ch:?}")));
            }
        }
    }
    Ok(out)
}

/// A cursor over a token list.
struct Parser<'a> {
    tokens: Vec<(Token, usize)>,
    at: usize,
    what: &'a str,
    depth: usize,
}

impl Parser<'_> {
    fn peek(&self) -> Option<&Token> {
        self.tokens.get(self.at).map(|t| &t.0)
    }
    fn line(&self) -> usize {
        self.tokens.get(self.at).or(self.tokens.last()).map_or(1, |t| t.1)
    }
    fn err(&self, message: impl Into<String>) -> CalcError {
        CalcError::Syntax {
            what: self.what.to_string(),
            line: self.line(),
            message: message.into(),
        }
    }
    fn eat(&mut self, c: char) -> bool {
        if self.peek() == Some(&Token::Sym(c)) {
            self.at += 1;
            true
        } else {
            false
        }
    }
    fn expect(&mut self, c: char) -> Result<(), CalcError> {
        if self.eat(c) {
            Ok(())
        } else {
            Err(self.err(format!("expected {c:?}, found {}", self.found())))
        }
    }
    fn found(&self) -> String {
        match self.peek() {
            None => "the end".to_string(),
            Some(Token::Num(v)) => format!("the number {v}"),
            Some(Token::Name(n)) => format!("{n:?}"),
            Some(Token::Sym(c)) => format!("{c:?}"),
        }
    }

    /// `+` and `-`, left to right.
    fn sum(&mut self) -> Result<Expr, CalcError> {
        let mut e = self.product()?;
        loop {
            let op = if self.eat('+') {
                Op::Add
            } else if self.eat('-') {
                Op::Sub
            } else {
                return Ok(e);
            };
            e = Expr::Bin(op, Box::new(e), Box::new(self.product()?));
        }
    }
    /// `*` and `/`, left to right.
    fn product(&mut self) -> Result<Expr, CalcError> {
        let mut e = self.power()?;
        loop {
            let op = if self.eat('*') {
                Op::Mul
            } else if self.eat('/') {
                Op::Div
            } else {
                return Ok(e);
            };
            e = Expr::Bin(op, Box::new(e), Box::new(self.power()?));
        }
    }
    /// `^`, right to left.
    fn power(&mut self) -> Result<Expr, CalcError> {
        let base = self.unary()?;
        if self.eat('^') {
            self.nest()?;
            let exponent = self.power()?;
            self.depth -= 1;
            return Ok(Expr::Bin(Op::Pow, Box::new(base), Box::new(exponent)));
        }
        Ok(base)
    }
    /// A unary sign before a primary.
    fn unary(&mut self) -> Result<Expr, CalcError> {
        if self.eat('-') {
            self.nest()?;
            let e = self.unary()?;
            self.depth -= 1;
            return Ok(match e {
                Expr::Num(v) => Expr::Num(-v),
                e => Expr::Neg(Box::new(e)),
            });
        }
        if self.eat('+') {
            self.nest()?;
            let e = self.unary();
            self.depth -= 1;
            return e;
        }
        self.primary()
    }
    fn nest(&mut self) -> Result<(), CalcError> {
        self.depth += 1;
        if self.depth > MAX_NESTING {
            return Err(self.err(format!("nested more than {MAX_NESTING} deep")));
        }
        Ok(())
    }
    /// A number, a name, a call or a parenthesized expression.
    fn primary(&mut self) -> Result<Expr, CalcError> {
        match self.peek().cloned() {
            Some(Token::Num(v)) => {
                self.at += 1;
                Ok(Expr::Num(v))
            }
            Some(Token::Name(name)) => {
                self.at += 1;
                if !self.eat('(') {
                    return Ok(Expr::Name(name));
                }
                self.nest()?;
                let mut args = Vec::new();
                if !self.eat(')') {
                    loop {
                        args.push(self.sum()?);
                        if self.eat(')') {
                            break;
                        }
                        self.expect(',')?;
                    }
                }
                self.depth -= 1;
                Ok(Expr::Call(name, args))
            }
            Some(Token::Sym('(')) => {
                self.at += 1;
                self.nest()?;
                let e = self.sum()?;
                self.expect(')')?;
                self.depth -= 1;
                Ok(e)
            }
            _ => Err(self.err(format!("expected a number, a name or '(', found {}", self.found()))),
        }
    }
}

/// The definitions of a function file's text; `what` names it in errors.
pub fn definitions(text: &str, what: &str) -> Result<Vec<Definition>, CalcError> {
    let mut p = Parser {
        tokens: tokens(text, what)?,
        at: 0,
        what,
        depth: 0,
    };
    let mut out = Vec::new();
    while p.peek().is_some() {
        if p.eat(';') {
            continue;
        }
        let line = p.line();
        let name = match p.peek().cloned() {
            Some(Token::Name(n)) => {
                p.at += 1;
                n
            }
            _ => return Err(p.err(format!("expected a name to define, found {}", p.found()))),
        };
        let mut params = Vec::new();
        let function = p.eat('(');
        if function && !p.eat(')') {
            loop {
                match p.peek().cloned() {
                    Some(Token::Name(n)) => {
                        p.at += 1;
                        params.push(n);
                    }
                    _ => return Err(p.err(format!("expected a parameter name, found {}", p.found()))),
                }
                if p.eat(')') {
                    break;
                }
                p.expect(',')?;
            }
        }
        if !(p.eat('=') || p.eat(':')) {
            return Err(p.err(format!("expected '=' or ':' after {name:?}, found {}", p.found())));
        }
        let body = p.sum()?;
        if p.peek().is_some() {
            p.expect(';')?;
        }
        out.push(Definition {
            name,
            params,
            function,
            body,
            line,
        });
    }
    Ok(out)
}

/// One expression (a pattern's argument, such as `red` or `.5*foo(Px)`).
pub fn expression(text: &str, what: &str) -> Result<Expr, CalcError> {
    let mut p = Parser {
        tokens: tokens(text, what)?,
        at: 0,
        what,
        depth: 0,
    };
    let e = p.sum()?;
    if p.peek().is_some() {
        return Err(p.err(format!("unexpected {} after the expression", p.found())));
    }
    Ok(e)
}
