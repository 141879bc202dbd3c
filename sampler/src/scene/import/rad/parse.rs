//! Primitives and `!` commands of one Radiance file, in file order. Each
//! primitive is `modifier type identifier` and three argument groups, `N
//! string...`, `N integer...`, `N real...` (an `alias` has one reference word
//! instead). This only reads: what a primitive means is decided elsewhere.

use std::path::Path;

use super::error::{Location, RadError, RadErrorKind};
use super::lexer::{Lexer, MAX_WORD};

/// Most string arguments one primitive may have.
pub(super) const MAX_STRINGS: u64 = 1 << 16;
/// Most integer arguments one primitive may have.
pub(super) const MAX_INTS: u64 = 1 << 16;
/// Most real arguments one primitive may have (a polygon of 5.6 million
/// vertices): counts are checked before anything is read, and memory grows
/// only with what the file really holds.
pub(super) const MAX_REALS: u64 = 1 << 24;

/// One primitive as written.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Primitive {
    /// The modifier's name (`void` for none).
    pub modifier: String,
    /// The type (`polygon`, `plastic`, ...).
    pub kind: String,
    /// The identifier.
    pub name: String,
    /// String arguments (for an `alias`, the name it refers to).
    pub strings: Vec<String>,
    /// Integer arguments.
    pub ints: Vec<i64>,
    /// Real arguments.
    pub reals: Vec<f64>,
    /// The line the primitive starts on.
    pub line: u32,
}

impl Primitive {
    /// `type "identifier"`, for messages.
    pub(super) fn what(&self) -> String {
        format!("{} {:?}", self.kind, self.name)
    }
}

/// What a file holds, one at a time.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Statement {
    /// A primitive.
    Primitive(Primitive),
    /// A `!` line: the command text after the `!`.
    Command {
        /// The command and its arguments.
        text: String,
        /// The line it starts on.
        line: u32,
    },
}

/// Reads the statements of one file.
pub(super) struct Parser<'a> {
    lex: Lexer<'a>,
    path: &'a Path,
}

impl<'a> Parser<'a> {
    /// A parser of `bytes`, the content of `path` (named in errors).
    pub(super) fn new(bytes: &'a [u8], path: &'a Path) -> Parser<'a> {
        Parser {
            lex: Lexer::new(bytes),
            path,
        }
    }

    /// The location of `line` in this file.
    pub(super) fn at(&self, line: u32) -> Location {
        Location {
            path: self.path.to_path_buf(),
            line,
        }
    }

    /// The next statement, `None` at the end of the file.
    pub(super) fn next_statement(&mut self) -> Result<Option<Statement>, RadError> {
        match self.lex.peek() {
            None => return Ok(None),
            Some(b'!') => {
                let (text, line) = self.lex.command().map_err(|_| self.too_long())?;
                return Ok(Some(Statement::Command { text, line }));
            }
            Some(_) => {}
        }
        let Some((modifier, line)) = self.word()? else {
            return Ok(None);
        };
        let truncated = |p: &Self, what: String| RadError::new(&p.at(p.lex.line()), RadErrorKind::Truncated { what });
        let Some((kind, _)) = self.word()? else {
            return Err(truncated(self, format!("the primitive starting at line {line}")));
        };
        let Some((name, _)) = self.word()? else {
            return Err(truncated(self, format!("the {kind} starting at line {line}")));
        };
        let mut p = Primitive {
            modifier,
            kind,
            name,
            strings: Vec::new(),
            ints: Vec::new(),
            reals: Vec::new(),
            line,
        };
        if p.kind == "alias" {
            let Some((target, _)) = self.word()? else {
                return Err(truncated(
                    self,
                    format!("alias {:?} (it names what it aliases)", p.name),
                ));
            };
            p.strings.push(target);
            return Ok(Some(Statement::Primitive(p)));
        }
        let what = p.what();
        let n = self.count(&what, "string", MAX_STRINGS)?;
        for _ in 0..n {
            p.strings.push(self.argument(&what)?.0);
        }
        let n = self.count(&what, "integer", MAX_INTS)?;
        for _ in 0..n {
            let (token, line) = self.argument(&what)?;
            let v = token.parse::<i64>().map_err(|_| {
                let what = what.clone();
                RadError::new(&self.at(line), RadErrorKind::NotAnInteger { token, what })
            })?;
            p.ints.push(v);
        }
        let n = self.count(&what, "real", MAX_REALS)?;
        p.reals.reserve(n.min(4096) as usize);
        for _ in 0..n {
            let (token, line) = self.argument(&what)?;
            match token.parse::<f64>() {
                Ok(v) if v.is_finite() => p.reals.push(v),
                _ => {
                    let what = what.clone();
                    return Err(RadError::new(&self.at(line), RadErrorKind::NotANumber { token, what }));
                }
            }
        }
        Ok(Some(Statement::Primitive(p)))
    }

    /// The next word, refusing one too long to be meant.
    fn word(&mut self) -> Result<Option<(String, u32)>, RadError> {
        self.lex.word().map_err(|_| self.too_long())
    }

    /// The next argument of `what`; the end of the file is an error.
    fn argument(&mut self, what: &str) -> Result<(String, u32), RadError> {
        self.word()?.ok_or_else(|| {
            RadError::new(
                &self.at(self.lex.line()),
                RadErrorKind::Truncated {
                    what: format!("the arguments of {what}"),
                },
            )
        })
    }

    /// An argument count of `group`, at most `max`.
    fn count(&mut self, what: &str, group: &'static str, max: u64) -> Result<u64, RadError> {
        let (token, line) = self.argument(what)?;
        let n = token.parse::<u64>().map_err(|_| {
            let what = what.to_string();
            RadError::new(&self.at(line), RadErrorKind::BadCount { token, what })
        })?;
        if n > max {
            let what = what.to_string();
            let kind = RadErrorKind::TooManyArguments {
                count: n,
                group,
                max,
                what,
            };
            return Err(RadError::new(&self.at(line), kind));
        }
        Ok(n)
    }

    /// The error for a word past [`MAX_WORD`].
    fn too_long(&self) -> RadError {
        RadError::new(&self.at(self.lex.line()), RadErrorKind::WordTooLong { max: MAX_WORD })
    }
}
