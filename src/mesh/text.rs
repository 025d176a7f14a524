//! A cursor over a text model file (OBJ, MTL, OFF, ASCII PLY and STL):
//! whitespace-separated tokens, `#` comments to the end of the line, line
//! numbers for messages.

use std::path::Path;

use super::MeshError;

/// A cursor over a text model file: whitespace-separated tokens, `#`
/// comments to the end of the line, line numbers for messages.
pub(crate) struct Text<'a> {
    src: &'a [u8],
    pos: usize,
    line: usize,
    path: &'a Path,
}

impl<'a> Text<'a> {
    pub fn new(src: &'a [u8], path: &'a Path) -> Text<'a> {
        Text {
            src,
            pos: 0,
            line: 1,
            path,
        }
    }

    pub fn error(&self, message: impl Into<String>) -> MeshError {
        MeshError {
            path: self.path.to_path_buf(),
            at: Some(format!("line {}", self.line)),
            message: message.into(),
        }
    }

    /// The next token, crossing line ends; None at the end of the file.
    pub fn token(&mut self) -> Option<&'a [u8]> {
        loop {
            self.skip_blanks();
            match self.src.get(self.pos) {
                None => return None,
                Some(b'\n') => {
                    self.pos += 1;
                    self.line += 1;
                }
                Some(_) => return self.word(),
            }
        }
    }

    /// The next token on this line; None at its end (the line end is not
    /// consumed).
    pub fn token_on_line(&mut self) -> Option<&'a [u8]> {
        self.skip_blanks();
        match self.src.get(self.pos) {
            None | Some(b'\n') => None,
            Some(_) => self.word(),
        }
    }

    /// Moves past the end of the current line.
    pub fn next_line(&mut self) {
        while let Some(&c) = self.src.get(self.pos) {
            self.pos += 1;
            if c == b'\n' {
                self.line += 1;
                return;
            }
        }
    }

    /// Where the cursor is, in bytes (binary PLY data starts here).
    pub fn offset(&self) -> usize {
        self.pos
    }

    /// The rest of the line, trimmed (for names with spaces).
    pub fn rest_of_line(&mut self) -> &'a [u8] {
        let start = self.pos;
        while let Some(&c) = self.src.get(self.pos) {
            if c == b'\n' || c == b'#' {
                break;
            }
            self.pos += 1;
        }
        self.src[start..self.pos].trim_ascii()
    }

    fn skip_blanks(&mut self) {
        while let Some(&c) = self.src.get(self.pos) {
            match c {
                b' ' | b'\t' | b'\r' | b'\x0c' | b'\x0b' => self.pos += 1,
                b'#' => {
                    while self.src.get(self.pos).is_some_and(|&c| c != b'\n') {
                        self.pos += 1;
                    }
                }
                _ => return,
            }
        }
    }

    fn word(&mut self) -> Option<&'a [u8]> {
        let start = self.pos;
        self.pos = word_end(self.src, start);
        Some(&self.src[start..self.pos])
    }

    /// The line the next token is on (blank lines and comments skipped).
    pub fn next_token_line(&mut self) -> usize {
        loop {
            self.skip_blanks();
            match self.src.get(self.pos) {
                Some(b'\n') => {
                    self.pos += 1;
                    self.line += 1;
                }
                _ => return self.line,
            }
        }
    }

    /// The line the cursor is on, from 1.
    pub fn line(&self) -> usize {
        self.line
    }

    /// "line 12", for warnings.
    pub fn at(&self) -> Option<String> {
        Some(format!("line {}", self.line))
    }

    /// A number token that may be anything, for values that are repaired
    /// rather than refused (normals): NaN where it is not a number.
    pub fn number_or_nan(tok: Option<&[u8]>) -> f64 {
        tok.and_then(crate::number::parse_f64).unwrap_or(f64::NAN)
    }

    /// A finite number token, or an error saying what was expected.
    pub fn number(&mut self, tok: Option<&[u8]>, what: &str) -> Result<f64, MeshError> {
        let Some(t) = tok else {
            return Err(self.error(format!("expected {what}, found the end of the line")));
        };
        match crate::number::parse_f64(t) {
            Some(v) if v.is_finite() && v.abs() <= f64::from(f32::MAX) => Ok(v),
            _ => Err(self.error(format!("expected {what}, found {}", show(t)))),
        }
    }

    /// As `number`, but a malformed number (`3.1+e2`, as some exporters
    /// write) is read as the longest number it begins with, the way
    /// mainstream importers read it; true when it was cut short, for the
    /// caller's warning.
    pub fn number_lenient(
        &mut self,
        tok: Option<&[u8]>,
        what: &str,
    ) -> Result<(f64, bool), MeshError> {
        let Some(t) = tok else {
            return self.number(tok, what).map(|v| (v, false));
        };
        if let Ok(v) = self.number(Some(t), what) {
            return Ok((v, false));
        }
        let ok = |v: f64| v.is_finite() && v.abs() <= f64::from(f32::MAX);
        let prefix = (1..t.len().min(64))
            .rev()
            .find_map(|n| crate::number::parse_f64(&t[..n]).filter(|&v| ok(v)));
        match prefix {
            Some(v) => Ok((v, true)),
            None => self.number(Some(t), what).map(|v| (v, false)),
        }
    }

    /// A whole number token.
    pub fn integer(&mut self, tok: Option<&[u8]>, what: &str) -> Result<i64, MeshError> {
        let Some(t) = tok else {
            return Err(self.error(format!("expected {what}, found the end of the file")));
        };
        std::str::from_utf8(t)
            .ok()
            .and_then(|s| s.parse::<i64>().ok())
            .ok_or_else(|| self.error(format!("expected {what}, found {}", show(t))))
    }
}

/// Where the word at `start` ends: at whitespace, a `#` or the end.
pub(crate) fn word_end(src: &[u8], start: usize) -> usize {
    src[start..]
        .iter()
        .position(|&c| c.is_ascii_whitespace() || c == b'#')
        .map_or(src.len(), |n| start + n)
}

/// A token for a message: quoted, escaped, and cut short when long (a
/// binary file's "token" can be megabytes).
pub fn show(t: &[u8]) -> String {
    const MAX: usize = 40;
    let text = String::from_utf8_lossy(&t[..t.len().min(MAX)]);
    let more = if t.len() > MAX { "..." } else { "" };
    format!("`{}{more}`", text.escape_debug())
}
