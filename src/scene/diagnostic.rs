//! What is wrong in a scene file, and where: file:line:col, the line with
//! a caret under the token, and a hint, as compilers print them.

use std::fmt;

/// A message tied to a place in a scene file, shown with the source line and
/// a caret under the offending token.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Diagnostic {
    /// The scene file, as the user named it.
    pub path: String,
    /// 1-based line number.
    pub line: usize,
    /// 1-based column, in characters.
    pub col: usize,
    /// What is wrong.
    pub message: String,
    /// What to do about it, when there is something useful to say.
    pub hint: Option<String>,
    /// The part of the line shown, and where the caret goes in it.
    pub(crate) source_line: String,
    pub(crate) caret_col: usize,
    pub(crate) width: usize,
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}:{}:{}: {}",
            self.path, self.line, self.col, self.message
        )?;
        let gutter = self.line.to_string().len();
        writeln!(f, "{:gutter$} |", "")?;
        writeln!(f, "{} | {}", self.line, self.source_line)?;
        write!(
            f,
            "{:gutter$} | {}{}",
            "",
            " ".repeat(self.caret_col.saturating_sub(1)),
            "^".repeat(self.width.max(1))
        )?;
        if let Some(hint) = &self.hint {
            write!(f, "\n{:gutter$} = help: {hint}", "")?;
        }
        Ok(())
    }
}

/// The scene file is not valid classic-format input.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct ParseError(pub Box<Diagnostic>);

impl ParseError {
    /// Where and what.
    pub fn diagnostic(&self) -> &Diagnostic {
        &self.0
    }
}
