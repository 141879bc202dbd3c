//! Words of a Radiance file with their line numbers: white space separates
//! words, `#` starts a comment to the end of the line, quotes (`"` or `'`)
//! group a word with spaces in it, and a `!` line is one command (a trailing
//! backslash continues it on the next line). It knows nothing of primitives.

/// Longest word or command line read; longer ones are refused so that a file
/// without white space cannot make the reader collect it all in one string.
pub(super) const MAX_WORD: usize = 64 << 10;

/// A word too long to read.
#[derive(Debug)]
pub(super) struct TooLong;

/// Reads words from the bytes of one file.
pub(super) struct Lexer<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: u32,
}

impl<'a> Lexer<'a> {
    /// A lexer at the start of `bytes`.
    pub(super) fn new(bytes: &'a [u8]) -> Lexer<'a> {
        Lexer { bytes, pos: 0, line: 1 }
    }

    /// The line the lexer is on (1-based).
    pub(super) fn line(&self) -> u32 {
        self.line
    }

    /// Skips white space and comments; the next byte, not consumed (`None` at
    /// the end).
    pub(super) fn peek(&mut self) -> Option<u8> {
        while let Some(&c) = self.bytes.get(self.pos) {
            if c == b'#' {
                while let Some(&c) = self.bytes.get(self.pos) {
                    if c == b'\n' {
                        break;
                    }
                    self.pos += 1;
                }
            } else if c.is_ascii_whitespace() {
                self.advance();
            } else {
                return Some(c);
            }
        }
        None
    }

    /// The next word and the line it starts on, `None` at the end of the file.
    /// Quotes may open anywhere in a word and are dropped, as Radiance does.
    pub(super) fn word(&mut self) -> Result<Option<(String, u32)>, TooLong> {
        if self.peek().is_none() {
            return Ok(None);
        }
        let line = self.line;
        let mut out = Vec::new();
        let mut quote = None;
        while let Some(&c) = self.bytes.get(self.pos) {
            match quote {
                Some(q) if c == q => quote = None,
                None if c == b'"' || c == b'\'' => quote = Some(c),
                None if c.is_ascii_whitespace() => break,
                _ => {
                    if out.len() >= MAX_WORD {
                        return Err(TooLong);
                    }
                    out.push(c);
                }
            }
            self.advance();
        }
        Ok(Some((String::from_utf8_lossy(&out).into_owned(), line)))
    }

    /// The command of a `!` line (the lexer must be at the `!`): the text after
    /// it up to the end of the line, with backslash-newline continuations
    /// joined by a space, and the line it starts on.
    pub(super) fn command(&mut self) -> Result<(String, u32), TooLong> {
        let line = self.line;
        if self.bytes.get(self.pos) == Some(&b'!') {
            self.pos += 1;
        }
        let mut out = Vec::new();
        while let Some(&c) = self.bytes.get(self.pos) {
            if c == b'\n' {
                break;
            }
            if c == b'\\' && matches!(self.bytes.get(self.pos + 1), Some(b'\n')) {
                self.pos += 1;
                self.advance();
                out.push(b' ');
                continue;
            }
            if out.len() >= MAX_WORD {
                return Err(TooLong);
            }
            out.push(c);
            self.pos += 1;
        }
        Ok((String::from_utf8_lossy(&out).into_owned(), line))
    }

    /// Steps over one byte, counting lines.
    fn advance(&mut self) {
        if self.bytes.get(self.pos) == Some(&b'\n') {
            self.line = self.line.saturating_add(1);
        }
        self.pos += 1;
    }
}
