//! Parser for the classic CSCI 420 scene format, exactly as the course's files
//! are written:
//!
//! ```text
//! <object count>
//! amb: r g b
//! sphere   pos: x y z  rad: r  dif: r g b  spe: r g b  shi: s
//! triangle (pos: x y z  nor: x y z  dif: r g b  spe: r g b  shi: s) x 3
//! light    pos: x y z  col: r g b
//! ```
//!
//! Optional extensions (never in the course's files; see docs/scene-format.md):
//!
//! ```text
//! reflect: D   spp: N   shadow_samples: M   shutter: S   seed: K   fps: F
//! sampler: sobol | stratified
//!              (settings, anywhere between objects; not counted as objects)
//! light ... col: r g b  [rad: r | edge_u: x y z edge_v: x y z]  [vel: x y z]
//! sphere ... shi: s  [vel: x y z]
//! triangle (...) x 3  [vel: x y z]
//! ```
//!
//! Tokens are separated by any whitespace; tags and keywords are
//! case-insensitive; numbers are anything Rust's `f64` parser accepts that is
//! finite (`1`, `.44`, `1e-16`). The object count counts spheres, triangles
//! and lights together and must match the blocks. The parser works on bytes,
//! never allocates by the declared count, and never panics: every failure is
//! a [`ParseError`] with file:line:col, the token found and what was expected.

use glam::DVec3;

use super::diagnostic::{Diagnostic, ParseError};
use super::model::{CameraSpec, MaterialIds, Scene};

/// An object starts only with this much input after it (or the end of the
/// file), so one rarely straddles two reads; one that does (a block padded
/// with this much whitespace) is parsed again from its start with more.
pub(super) const LOOKAHEAD: usize = 1 << 16;

/// The objects a part parsed ahead may hold (`parse_ahead`), and so the
/// words a part may start at.
pub(super) const SIMPLE_OBJECTS: [&str; 3] = ["sphere", "triangle", "light"];

#[derive(Clone, Copy)]
pub(super) struct Token<'a> {
    pub(super) text: &'a [u8],
    pub(super) offset: usize,
    pub(super) line: usize,
    /// Byte offset of the token's line; the column is worked out only when a
    /// diagnostic needs it, so long lines cost nothing while parsing.
    pub(super) line_start: usize,
}

impl Token<'_> {
    pub(super) fn show(&self) -> String {
        format!("`{}`", String::from_utf8_lossy(self.text).escape_debug())
    }

    pub(super) fn is(&self, word: &str) -> bool {
        self.text.eq_ignore_ascii_case(word.as_bytes())
    }
}

/// What a parse carries from one window of the input to the next.
#[derive(Default)]
pub(super) struct State {
    pub(super) scene: Scene,
    pub(super) material_ids: MaterialIds,
    /// Objects the first line declares; None before it is read.
    pub(super) declared: Option<u64>,
    pub(super) found: u64,
    pub(super) line: usize,
    /// Byte offset in the whole input where the current line begins.
    pub(super) line_start: usize,
    /// Characters of the current line before the window, when it began in
    /// input already dropped.
    pub(super) line_chars_before: usize,
    /// The first mesh block that brought no triangles: the error if the
    /// scene ends with nothing to render.
    pub(super) nothing_from_meshes: Option<Diagnostic>,
}

impl State {
    /// Before the first byte: line 1.
    pub(super) fn start() -> State {
        State {
            line: 1,
            ..State::default()
        }
    }

    /// Appends a part parsed ahead (`parse_ahead`) that begins where this
    /// state ends, as if parsed in order: its materials join the table in
    /// the order their corners name them, its lines follow these. False
    /// (and nothing joined) where its objects would pass the declared
    /// count, whose message the parse in order gives.
    pub(super) fn join(&mut self, ahead: State) -> bool {
        let declared = self.declared.unwrap_or(0);
        if self.found + ahead.found > declared {
            return false;
        }
        self.found += ahead.found;
        let Scene {
            spheres,
            mut triangles,
            materials,
            lights,
            ..
        } = ahead.scene;
        let mut ids: Vec<Option<u32>> = vec![None; materials.len()];
        for v in triangles.iter_mut().flat_map(|t| t.vertices.iter_mut()) {
            let local = v.material as usize;
            v.material = *ids[local].get_or_insert_with(|| {
                self.material_ids
                    .id(&mut self.scene.materials, materials[local])
            });
        }
        self.scene.spheres.extend(spheres);
        self.scene.triangles.extend(triangles);
        self.scene.lights.extend(lights);
        if ahead.line > 1 {
            self.line += ahead.line - 1;
            self.line_start = ahead.line_start;
        }
        true
    }
}

pub(super) struct Parser<'a> {
    /// The window of the input held now; `base` is its offset in the whole.
    pub(super) src: &'a [u8],
    pub(super) base: usize,
    /// Whether the window reaches the end of the input.
    pub(super) at_eof: bool,
    /// A token ran into the end of a window that does not reach the end of
    /// the input: whatever was parsed since the object began is redone
    /// with more input.
    pub(super) starved: bool,
    /// Input an object needs after its start before it is begun, when the
    /// window does not reach the end.
    pub(super) lookahead: usize,
    /// Where the next part of the window begins (parsed by another thread):
    /// no object is begun at or past it.
    pub(super) stop_at: Option<usize>,
    /// A warning was given: a part parsed ahead (`run_ahead`) drops the
    /// object, whose warning the parse in order gives.
    pub(super) warned: bool,
    pub(super) path: &'a str,
    pub(super) pos: usize,
    /// Also the line position (`State::line`, `State::line_start`).
    pub(super) state: State,
}

pub(super) type PResult<T> = Result<T, ParseError>;

/// How much of `Scene` an object may have added, to undo it.
pub(super) struct Mark {
    pub(super) at: (usize, usize, usize),
    pub(super) lens: [usize; 5],
    pub(super) more_warnings: usize,
    pub(super) camera: Option<CameraSpec>,
    pub(super) found: u64,
}

impl<'a> Parser<'a> {
    pub(super) fn new(
        src: &'a [u8],
        base: usize,
        at_eof: bool,
        path: &'a str,
        state: State,
    ) -> Self {
        Parser {
            src,
            base,
            at_eof,
            starved: false,
            lookahead: LOOKAHEAD,
            stop_at: None,
            warned: false,
            path,
            pos: 0,
            state,
        }
    }

    /// Parses what the window holds: None when the input is done, or the
    /// window offset from which the next window must start.
    pub(super) fn run(&mut self) -> PResult<Option<usize>> {
        if self.state.declared.is_none() {
            match self.resumable(Self::header)? {
                Some(declared) => self.state.declared = Some(declared),
                None => return Ok(Some(self.pos)),
            }
        }
        loop {
            if self.at_stop() {
                return Ok(Some(self.pos));
            }
            if !self.at_eof && self.src.len() - self.pos < self.lookahead {
                return Ok(Some(self.pos));
            }
            match self.resumable(Self::object)? {
                Some(true) => {}
                Some(false) => break,
                None => return Ok(Some(self.pos)),
            }
        }
        let (declared, found) = (self.state.declared.unwrap_or(0), self.state.found);
        if found < declared {
            let end = self.end_token();
            return Err(self.error_at(
                &end,
                format!(
                    "the file declares {declared} object(s) on its first line, \
                     but ends after {found}"
                ),
                Some("the file may be truncated; otherwise fix the count on the first line"),
            ));
        }
        if let Some(d) = &self.state.nothing_from_meshes {
            if self.state.scene.primitive_count() == 0 {
                return Err(ParseError(Box::new(d.clone())));
            }
        }
        Ok(None)
    }

    /// Whether the next token is at or past `stop_at`.
    pub(super) fn at_stop(&mut self) -> bool {
        let Some(stop) = self.stop_at else {
            return false;
        };
        self.skip_space();
        self.pos >= stop
    }

    /// `run` for a part parsed ahead (`parse_ahead`): where it stopped.
    pub(super) fn run_ahead(&mut self) -> usize {
        loop {
            if self.at_stop() || (!self.at_eof && self.src.len() - self.pos < self.lookahead) {
                return self.pos;
            }
            let saved = self.at();
            let simple = self
                .next_token()
                .is_some_and(|t| SIMPLE_OBJECTS.iter().any(|w| t.is(w)));
            self.go(saved);
            self.starved = false;
            if !simple {
                return self.pos;
            }
            let mark = self.mark();
            match self.resumable(Self::object) {
                Ok(Some(true)) if !self.warned => {}
                _ => {
                    self.undo(mark);
                    return self.pos;
                }
            }
        }
    }

    /// Where the parse is: window offset, line and its absolute start.
    pub(super) fn at(&self) -> (usize, usize, usize) {
        (self.pos, self.state.line, self.state.line_start)
    }

    /// Back to a place `at` gave.
    pub(super) fn go(&mut self, at: (usize, usize, usize)) {
        (self.pos, self.state.line, self.state.line_start) = at;
    }

    /// Runs one step of the parse; if it ran out of window, undoes it and
    /// returns None (the position is back where the step began).
    pub(super) fn resumable<T>(&mut self, step: fn(&mut Self) -> PResult<T>) -> PResult<Option<T>> {
        let mark = self.mark();
        let result = step(self);
        if self.starved {
            self.undo(mark);
            self.starved = false;
            return Ok(None);
        }
        result.map(Some)
    }

    pub(super) fn mark(&self) -> Mark {
        let s = &self.state.scene;
        Mark {
            at: self.at(),
            lens: [
                s.spheres.len(),
                s.triangles.len(),
                s.lights.len(),
                s.meshes.len(),
                s.warnings.len(),
            ],
            more_warnings: s.more_warnings,
            camera: s.camera,
            found: self.state.found,
        }
    }

    pub(super) fn undo(&mut self, m: Mark) {
        self.go(m.at);
        let s = &mut self.state.scene;
        s.spheres.truncate(m.lens[0]);
        s.triangles.truncate(m.lens[1]);
        s.lights.truncate(m.lens[2]);
        s.meshes.truncate(m.lens[3]);
        s.warnings.truncate(m.lens[4]);
        s.more_warnings = m.more_warnings;
        s.camera = m.camera;
        self.state.found = m.found;
    }

    /// The object count and the ambient colour.
    pub(super) fn header(&mut self) -> PResult<u64> {
        let declared = self.object_count()?;
        self.tag("amb:")?;
        self.state.scene.ambient = self.vec3("the ambient colour")?;
        Ok(declared)
    }

    /// The next object or setting; false at the end of the input.
    pub(super) fn object(&mut self) -> PResult<bool> {
        let Some(tok) = self.next_token() else {
            return Ok(false);
        };
        if self.setting(&tok)? {
            return Ok(true);
        }
        if tok.is("camera") {
            // Like the settings, not counted as an object.
            self.camera(&tok)?;
            return Ok(true);
        }
        self.state.found += 1;
        let (declared, found) = (self.state.declared.unwrap_or(0), self.state.found);
        if found > declared {
            return Err(self.error_at(
                &tok,
                format!(
                    "the file declares {declared} object(s) on its first line, \
                     but object {found} starts here"
                ),
                Some("make the count on the first line match the number of sphere, triangle, light and mesh blocks"),
            ));
        }
        if tok.is("sphere") {
            let sphere = self.sphere()?;
            self.state.scene.spheres.push(sphere);
        } else if tok.is("triangle") {
            let triangle = self.triangle()?;
            self.state.scene.triangles.push(triangle);
        } else if tok.is("light") {
            let light = self.light()?;
            self.state.scene.lights.push(light);
        } else if tok.is("mesh") {
            self.mesh()?;
        } else {
            return Err(self.expected(
                &tok,
                "`sphere`, `triangle`, `light`, `mesh`, `camera` or a setting (`reflect:`, \
                 `spp:`, `shadow_samples:`, `shutter:`, `seed:`, `fps:`, `sampler:`)",
            ));
        }
        Ok(true)
    }

    pub(super) fn object_count(&mut self) -> PResult<u64> {
        let tok = self.require("the object count")?;
        std::str::from_utf8(tok.text)
            .ok()
            .and_then(|s| s.parse::<u64>().ok())
            .ok_or_else(|| {
                self.expected(&tok, "the object count (a whole number) as the first token")
            })
    }

    pub(super) fn tag(&mut self, tag: &str) -> PResult<Token<'a>> {
        // Most tags are as expected: compared in place, without finding
        // the token's end first.
        self.skip_space();
        let rest = &self.src[self.pos..];
        let n = tag.len();
        if rest.len() > n
            && rest[n].is_ascii_whitespace()
            && rest[..n].eq_ignore_ascii_case(tag.as_bytes())
        {
            let tok = self.token_at(n);
            self.pos += n;
            return Ok(tok);
        }
        let tok = self.require_with(|| format!("`{tag}`"))?;
        if tok.is(tag) {
            Ok(tok)
        } else {
            Err(self.expected(&tok, &format!("`{tag}`")))
        }
    }

    pub(super) fn vec3(&mut self, what: &str) -> PResult<DVec3> {
        let (x, _) = self.number(what)?;
        let (y, _) = self.number(what)?;
        let (z, _) = self.number(what)?;
        Ok(DVec3::new(x, y, z))
    }

    pub(super) fn number(&mut self, what: &str) -> PResult<(f64, Token<'a>)> {
        // The fast path reads most numbers in place; what it cannot read,
        // or a number not followed by whitespace, goes the long way (which
        // also gives the messages).
        self.skip_space();
        let rest = &self.src[self.pos..];
        if let Some((value, n)) = crate::number::parse_prefix(rest) {
            let ends = rest.get(n).map_or(self.at_eof, u8::is_ascii_whitespace);
            if ends && value.abs() <= f64::from(f32::MAX) {
                let tok = self.token_at(n);
                self.pos += n;
                return Ok((value, tok));
            }
        }
        let tok = self.require_with(|| format!("a number ({what})"))?;
        let value = crate::number::parse_f64(tok.text);
        match value {
            // The GPU computes in f32: a larger value would arrive there as
            // infinity.
            Some(v) if v.is_finite() && v.abs() > f64::from(f32::MAX) => Err(self.expected(
                &tok,
                &format!("a number of magnitude at most 3.4e38, the f32 limit ({what})"),
            )),
            Some(v) if v.is_finite() => Ok((v, tok)),
            Some(_) => Err(self.expected(&tok, &format!("a finite number ({what})"))),
            None => Err(self.expected(&tok, &format!("a number ({what})"))),
        }
    }

    /// The next token, or an "unexpected end of file" error naming `what`.
    pub(super) fn require(&mut self, what: &str) -> PResult<Token<'a>> {
        self.require_with(|| what.to_string())
    }

    /// As `require`, with `what` worked out only for the error: every
    /// token of a file passes here, and a message per token would cost an
    /// allocation each (most of the parse time on big files).
    pub(super) fn require_with(&mut self, what: impl FnOnce() -> String) -> PResult<Token<'a>> {
        match self.next_token() {
            Some(tok) => Ok(tok),
            None => {
                let end = self.end_token();
                Err(self.error_at(
                    &end,
                    format!("expected {}, found end of file", what()),
                    Some("the file looks truncated"),
                ))
            }
        }
    }

    pub(super) fn skip_space(&mut self) {
        while self.pos < self.src.len() && self.src[self.pos].is_ascii_whitespace() {
            if self.src[self.pos] == b'\n' {
                self.state.line += 1;
                self.state.line_start = self.base + self.pos + 1;
            }
            self.pos += 1;
        }
    }

    pub(super) fn next_token(&mut self) -> Option<Token<'a>> {
        self.skip_space();
        let start = self.pos;
        while self.pos < self.src.len() && !self.src[self.pos].is_ascii_whitespace() {
            self.pos += 1;
        }
        if self.pos == self.src.len() && !self.at_eof {
            // The token may go on in input not read yet.
            self.starved = true;
            self.pos = start;
            return None;
        }
        if start == self.pos {
            return None;
        }
        Some(Token {
            text: &self.src[start..self.pos],
            offset: start,
            line: self.state.line,
            line_start: self.state.line_start,
        })
    }

    /// The token of `len` bytes at the parse position.
    pub(super) fn token_at(&self, len: usize) -> Token<'a> {
        Token {
            text: &self.src[self.pos..self.pos + len],
            offset: self.pos,
            line: self.state.line,
            line_start: self.state.line_start,
        }
    }

    /// A zero-width token at the end of the input, for end-of-file errors.
    pub(super) fn end_token(&mut self) -> Token<'a> {
        while self.next_token().is_some() {}
        Token {
            text: &[],
            offset: self.src.len(),
            line: self.state.line,
            line_start: self.state.line_start,
        }
    }

    pub(super) fn expected(&self, tok: &Token<'_>, what: &str) -> ParseError {
        self.error_at(tok, format!("expected {what}, found {}", tok.show()), None)
    }

    /// Keeps the first few warnings of each kind (told apart by their hint)
    /// and counts the rest, so a file that repeats one mistake a million
    /// times costs a counter, not a million diagnostics.
    pub(super) fn warn(&mut self, d: Diagnostic) {
        self.warned = true;
        let same = self
            .state
            .scene
            .warnings
            .iter()
            .filter(|w| w.hint == d.hint)
            .count();
        if same < super::model::WARNINGS_KEPT {
            self.state.scene.warnings.push(d);
        } else {
            self.state.scene.more_warnings += 1;
        }
    }

    pub(super) fn error_at(
        &self,
        tok: &Token<'_>,
        message: String,
        hint: Option<&str>,
    ) -> ParseError {
        ParseError(Box::new(self.diagnostic(tok, message, hint)))
    }

    pub(super) fn diagnostic(
        &self,
        tok: &Token<'_>,
        message: String,
        hint: Option<&str>,
    ) -> Diagnostic {
        // The token's line may have begun in input already dropped (see
        // `parse_reader`); its characters there still count.
        let (line_start, chars_before) = match tok.line_start.checked_sub(self.base) {
            Some(start) => (start, 0),
            None => (0, self.state.line_chars_before),
        };
        let chars = |bytes: &[u8]| String::from_utf8_lossy(bytes).chars().count();
        let line_end = self.src[tok.offset..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(self.src.len(), |i| tok.offset + i);
        // Line breaks are optional in this format: a whole scene can be one
        // line. Show a window of the line around the token, so a diagnostic
        // costs the same whatever the line's length.
        let token_end = (tok.offset + tok.text.len()).min(line_end);
        let mut from = tok.offset.saturating_sub(SOURCE_WINDOW).max(line_start);
        let mut to = (token_end + SOURCE_WINDOW).min(line_end);
        // Whole UTF-8 characters only.
        while from > line_start && (self.src[from] & 0xC0) == 0x80 {
            from -= 1;
        }
        while to < line_end && (self.src[to] & 0xC0) == 0x80 {
            to += 1;
        }
        let lead = if from > line_start || chars_before > 0 {
            "..."
        } else {
            ""
        };
        let tail = if to < line_end || (to == self.src.len() && !self.at_eof) {
            "..."
        } else {
            ""
        };
        // Tabs shown as one space keep the caret under the token.
        let source_line = format!(
            "{lead}{}{tail}",
            String::from_utf8_lossy(&self.src[from..to])
                .trim_end()
                .replace('\t', " ")
        );
        let width = chars(&self.src[tok.offset..token_end]);
        Diagnostic {
            path: self.path.to_string(),
            line: tok.line,
            col: chars_before + chars(&self.src[line_start..tok.offset]) + 1,
            message,
            hint: hint.map(str::to_string),
            source_line,
            caret_col: lead.len() + chars(&self.src[from..tok.offset]) + 1,
            width: width.min(2 * SOURCE_WINDOW),
        }
    }
}

/// Bytes of the source line shown on each side of a diagnostic's token.
pub(super) const SOURCE_WINDOW: usize = 60;
