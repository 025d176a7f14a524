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
//! Optional extensions (never in the course's files; see the README):
//!
//! ```text
//! reflect: D   spp: N   shadow_samples: M   shutter: S   seed: K   fps: F
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

use std::fmt;
use std::io::Read;
use std::path::Path;

use glam::DVec3;

use super::{
    Bounds, CameraSpec, Effects, Light, LightShape, Material, MaterialIds, MeshInfo, Scene, Sphere,
    Triangle, Vertex,
};

/// A `mesh` block's placement step.
#[derive(Clone, Copy, Debug)]
enum Transform {
    Scale(f64),
    Translate(DVec3),
    Rotate(glam::DQuat),
}

impl Transform {
    fn point(&self, p: DVec3) -> DVec3 {
        match self {
            Transform::Scale(s) => p * *s,
            Transform::Translate(t) => p + *t,
            Transform::Rotate(q) => *q * p,
        }
    }

    /// Normals turn with rotations only (scales are uniform and positive).
    fn direction(&self, n: DVec3) -> DVec3 {
        match self {
            Transform::Rotate(q) => *q * n,
            _ => n,
        }
    }
}
use crate::Error;

/// A message tied to a place in a scene file, shown with the source line and
/// a caret under the offending token.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Diagnostic {
    pub path: String,
    /// 1-based line number.
    pub line: usize,
    /// 1-based column, in characters.
    pub col: usize,
    pub message: String,
    /// What to do about it, when there is something useful to say.
    pub hint: Option<String>,
    /// The part of the line shown, and where the caret goes in it.
    source_line: String,
    caret_col: usize,
    width: usize,
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
    pub fn diagnostic(&self) -> &Diagnostic {
        &self.0
    }
}

/// Reads and parses a scene file; `path` is also used in messages.
pub fn read_scene(path: &Path) -> Result<Scene, Error> {
    let file = std::fs::File::open(path).map_err(|error| Error::ReadScene {
        path: path.to_path_buf(),
        error,
    })?;
    parse_reader(file, path)
}

/// Parses classic-format scene text; `path` is only used in messages.
pub fn parse_scene(src: &[u8], path: &str) -> Result<Scene, ParseError> {
    let mut parser = Parser::new(src, 0, true, path, State::start());
    match parser.run()? {
        Some(_) => unreachable!("a parser that has the whole input never waits for more"),
        None => Ok(parser.state.scene),
    }
}

/// Bytes read at a time by `parse_reader`, for each thread that parses.
const CHUNK: usize = 1 << 20;
/// An object starts only with this much input after it (or the end of the
/// file), so one rarely straddles two reads; one that does (a block padded
/// with this much whitespace) is parsed again from its start with more.
const LOOKAHEAD: usize = 1 << 16;

/// How `parse_windows` reads: `chunk` bytes a thread at a time, starting
/// an object only with `lookahead` bytes after it, on `threads` threads
/// (tests try tiny windows and several threads).
#[derive(Clone, Copy, Debug)]
struct Windows {
    chunk: usize,
    lookahead: usize,
    threads: usize,
}

/// Parses a scene as it is read, holding a few megabytes of the text at a
/// time instead of the whole file: a 700 MB scene would otherwise be
/// resident beside everything parsed from it. Uses the threads of rayon's
/// pool (`--threads`): each window is cut at object starts into one part a
/// thread, and every part but the first is parsed ahead, then kept only
/// where the parse before it ends exactly at its start. The scene and every
/// message are those of `parse_scene` on the whole text; `path` names the
/// input in them.
pub fn parse_reader(reader: impl Read, path: &Path) -> Result<Scene, Error> {
    let windows = Windows {
        chunk: CHUNK,
        lookahead: LOOKAHEAD,
        threads: rayon::current_num_threads().clamp(1, MAX_PARSE_THREADS),
    };
    parse_windows(reader, path, windows)
}

/// More threads would hold more of the file at once for little gain:
/// parsing a window is already faster than reading most disks.
const MAX_PARSE_THREADS: usize = 8;

/// No object of a scene, whitespace around it included, is this long: a
/// window that grows past it without one being parsed holds something
/// that is not a scene (a file without line ends of endless garbage).
const MAX_OBJECT: usize = 16 << 20;

fn parse_windows(reader: impl Read, path: &Path, windows: Windows) -> Result<Scene, Error> {
    let Windows {
        chunk,
        lookahead,
        threads,
    } = windows;
    let mut reader = crate::input::Limited::max(reader);
    let name = path.display().to_string();
    let io_error = |error: std::io::Error| match crate::input::InputError::from_io(error) {
        crate::input::InputError::Io(error) => Error::ReadScene {
            path: path.to_path_buf(),
            error,
        },
        error => Error::Input {
            path: path.to_path_buf(),
            error,
        },
    };
    let refused = |error| Error::Input {
        path: path.to_path_buf(),
        error,
    };
    let mut checked = 0;
    let round = chunk * threads;
    let mut buf: Vec<u8> = Vec::with_capacity(round + lookahead);
    let mut base = 0;
    let mut want = round;
    let mut at_eof = false;
    let mut state = State::start();
    loop {
        while !at_eof && buf.len() < want {
            let room = (want - buf.len()) as u64;
            match (&mut reader).take(room).read_to_end(&mut buf) {
                Ok(0) => at_eof = true,
                Ok(_) => {}
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(io_error(e)),
            }
        }
        // Scene files are text: a NUL byte is binary data (a wrong file,
        // /dev/zero), refused where it is instead of parsed as tokens.
        if let Some(i) = buf[checked.min(buf.len())..].iter().position(|&b| b == 0) {
            return Err(refused(crate::input::InputError::Binary {
                offset: (base + checked + i) as u64,
                what: "scene file",
            }));
        }
        checked = buf.len();
        let limit = if at_eof {
            buf.len()
        } else {
            buf.len().saturating_sub(lookahead)
        };
        let splits = object_starts(&buf[..limit], chunk, threads);
        let mut ahead: Vec<Option<Ahead>> = splits.iter().map(|_| None).collect();
        let result = if splits.is_empty() {
            let mut parser = Parser::new(&buf, base, at_eof, &name, state);
            parser.lookahead = lookahead;
            parser.run().map(|r| (r, parser.state))
        } else {
            let (buf, name, splits) = (&buf[..], &name[..], &splits[..]);
            rayon::scope(|scope| {
                for (k, slot) in ahead.iter_mut().enumerate() {
                    let (from, stop) = (splits[k], splits.get(k + 1).copied());
                    scope.spawn(move |_| {
                        *slot = Some(parse_ahead(buf, from, stop, base, at_eof, lookahead, name));
                    });
                }
                let mut parser = Parser::new(buf, base, at_eof, name, state);
                parser.lookahead = lookahead;
                parser.stop_at = Some(splits[0]);
                parser.run().map(|r| (r, parser.state))
            })
        };
        let (mut resume, new_state) = result?;
        state = new_state;
        // Each part parsed ahead joins where the parse so far ended exactly
        // at its start; the first that does not is parsed again in order.
        for (ahead, &from) in ahead.into_iter().zip(&splits) {
            let Some(ahead) = ahead else { break };
            if resume != Some(from) || !state.join(ahead.state) {
                break;
            }
            resume = Some(from + ahead.end);
            #[cfg(test)]
            tests::JOINED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
        let Some(pos) = resume else {
            return Ok(state.scene);
        };
        if pos == 0 && !at_eof {
            if state.declared.is_none() && buf.len() >= crate::input::SNIFF {
                return Err(refused(crate::input::InputError::Refused {
                    offset: base as u64,
                    message: format!(
                        "its first {} KiB hold no object count and `amb:` line: this is not a \
                         scene file",
                        crate::input::SNIFF / 1024
                    ),
                }));
            }
            if buf.len() >= MAX_OBJECT {
                return Err(refused(crate::input::InputError::Refused {
                    offset: base as u64,
                    message: format!(
                        "no object is complete in the {} MiB from here (line {}): a token or \
                         a run of blanks this long is not a scene",
                        MAX_OBJECT >> 20,
                        state.line
                    ),
                }));
            }
        }
        // Where the current line began before `pos`, the characters of it
        // dropped with the consumed input still count in its columns.
        if state.line_start < base + pos {
            let from = state.line_start.saturating_sub(base);
            let dropped = String::from_utf8_lossy(&buf[from..pos]).chars().count();
            if state.line_start >= base {
                state.line_chars_before = dropped;
            } else {
                state.line_chars_before += dropped;
            }
        }
        buf.drain(..pos);
        base += pos;
        checked -= pos;
        // Nothing consumed from a full window: one object is longer than
        // it, so read on until it fits.
        want = if pos == 0 {
            2 * buf.len().max(round)
        } else {
            round
        };
    }
}

/// The objects a part parsed ahead may hold (`parse_ahead`), and so the
/// words a part may start at.
const SIMPLE_OBJECTS: [&str; 3] = ["sphere", "triangle", "light"];

/// Where the parts of a window after the first begin: for each thread but
/// the first, the first line at or after its share of `text` that starts
/// with `sphere`, `triangle` or `light`. Only a guess (such a word could
/// be a mesh file's name), which the parse of the part before confirms.
fn object_starts(text: &[u8], chunk: usize, threads: usize) -> Vec<usize> {
    let mut starts = Vec::new();
    let mut from = 0;
    for k in 1..threads {
        from = from.max(k * chunk);
        let Some(at) = next_object_line(text, from) else {
            break;
        };
        starts.push(at);
        from = at + 1;
    }
    starts
}

fn next_object_line(text: &[u8], from: usize) -> Option<usize> {
    let mut i = from;
    loop {
        i += text.get(i..)?.iter().position(|&b| b == b'\n')? + 1;
        let mut j = i;
        while j < text.len() && matches!(text[j], b' ' | b'\t' | b'\r') {
            j += 1;
        }
        let word_end = text[j..]
            .iter()
            .position(u8::is_ascii_whitespace)
            .map(|n| j + n)?;
        let word = &text[j..word_end];
        if SIMPLE_OBJECTS
            .iter()
            .any(|w| word.eq_ignore_ascii_case(w.as_bytes()))
        {
            return Some(j);
        }
    }
}

/// A part of a window parsed ahead of the parse before it.
struct Ahead {
    /// What it parsed, its lines counted from its start.
    state: State,
    /// Where it stopped, from its start.
    end: usize,
}

/// Parses `buf[from..]` ahead, as if an object began there, until `stop`:
/// spheres, triangles and lights only, each kept only if it parses without
/// an error or a warning. Whatever else comes first (a setting, a camera,
/// a mesh, a mistake) ends the part there, for the parse in order to do
/// with its own state and messages.
fn parse_ahead(
    buf: &[u8],
    from: usize,
    stop: Option<usize>,
    base: usize,
    at_eof: bool,
    lookahead: usize,
    path: &str,
) -> Ahead {
    let state = State {
        // Counted when joined.
        declared: Some(u64::MAX),
        line: 1,
        line_start: base + from,
        ..State::default()
    };
    let mut parser = Parser::new(&buf[from..], base + from, at_eof, path, state);
    parser.lookahead = lookahead;
    parser.stop_at = stop.map(|s| s - from);
    let end = parser.run_ahead();
    Ahead {
        state: parser.state,
        end,
    }
}

#[derive(Clone, Copy)]
struct Token<'a> {
    text: &'a [u8],
    offset: usize,
    line: usize,
    /// Byte offset of the token's line; the column is worked out only when a
    /// diagnostic needs it, so long lines cost nothing while parsing.
    line_start: usize,
}

impl Token<'_> {
    fn show(&self) -> String {
        format!("`{}`", String::from_utf8_lossy(self.text).escape_debug())
    }

    fn is(&self, word: &str) -> bool {
        self.text.eq_ignore_ascii_case(word.as_bytes())
    }
}

/// What a parse carries from one window of the input to the next.
#[derive(Default)]
struct State {
    scene: Scene,
    material_ids: MaterialIds,
    /// Objects the first line declares; None before it is read.
    declared: Option<u64>,
    found: u64,
    line: usize,
    /// Byte offset in the whole input where the current line begins.
    line_start: usize,
    /// Characters of the current line before the window, when it began in
    /// input already dropped.
    line_chars_before: usize,
    /// The first mesh block that brought no triangles: the error if the
    /// scene ends with nothing to render.
    nothing_from_meshes: Option<Diagnostic>,
}

impl State {
    /// Before the first byte: line 1.
    fn start() -> State {
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
    fn join(&mut self, ahead: State) -> bool {
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

struct Parser<'a> {
    /// The window of the input held now; `base` is its offset in the whole.
    src: &'a [u8],
    base: usize,
    /// Whether the window reaches the end of the input.
    at_eof: bool,
    /// A token ran into the end of a window that does not reach the end of
    /// the input: whatever was parsed since the object began is redone
    /// with more input.
    starved: bool,
    /// Input an object needs after its start before it is begun, when the
    /// window does not reach the end.
    lookahead: usize,
    /// Where the next part of the window begins (parsed by another thread):
    /// no object is begun at or past it.
    stop_at: Option<usize>,
    /// A warning was given: a part parsed ahead (`run_ahead`) drops the
    /// object, whose warning the parse in order gives.
    warned: bool,
    path: &'a str,
    pos: usize,
    /// Also the line position (`State::line`, `State::line_start`).
    state: State,
}

type PResult<T> = Result<T, ParseError>;

/// How much of `Scene` an object may have added, to undo it.
struct Mark {
    at: (usize, usize, usize),
    lens: [usize; 5],
    more_warnings: usize,
    camera: Option<CameraSpec>,
    found: u64,
}

impl<'a> Parser<'a> {
    fn new(src: &'a [u8], base: usize, at_eof: bool, path: &'a str, state: State) -> Self {
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
    fn run(&mut self) -> PResult<Option<usize>> {
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
    fn at_stop(&mut self) -> bool {
        let Some(stop) = self.stop_at else {
            return false;
        };
        self.skip_space();
        self.pos >= stop
    }

    /// `run` for a part parsed ahead (`parse_ahead`): where it stopped.
    fn run_ahead(&mut self) -> usize {
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
    fn at(&self) -> (usize, usize, usize) {
        (self.pos, self.state.line, self.state.line_start)
    }

    /// Back to a place `at` gave.
    fn go(&mut self, at: (usize, usize, usize)) {
        (self.pos, self.state.line, self.state.line_start) = at;
    }

    /// Runs one step of the parse; if it ran out of window, undoes it and
    /// returns None (the position is back where the step began).
    fn resumable<T>(&mut self, step: fn(&mut Self) -> PResult<T>) -> PResult<Option<T>> {
        let mark = self.mark();
        let result = step(self);
        if self.starved {
            self.undo(mark);
            self.starved = false;
            return Ok(None);
        }
        result.map(Some)
    }

    fn mark(&self) -> Mark {
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

    fn undo(&mut self, m: Mark) {
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
    fn header(&mut self) -> PResult<u64> {
        let declared = self.object_count()?;
        self.tag("amb:")?;
        self.state.scene.ambient = self.vec3("the ambient colour")?;
        Ok(declared)
    }

    /// The next object or setting; false at the end of the input.
    fn object(&mut self) -> PResult<bool> {
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
                 `spp:`, `shadow_samples:`, `shutter:`, `seed:`, `fps:`)",
            ));
        }
        Ok(true)
    }

    fn object_count(&mut self) -> PResult<u64> {
        let tok = self.require("the object count")?;
        std::str::from_utf8(tok.text)
            .ok()
            .and_then(|s| s.parse::<u64>().ok())
            .ok_or_else(|| {
                self.expected(&tok, "the object count (a whole number) as the first token")
            })
    }

    fn sphere(&mut self) -> PResult<Sphere> {
        self.tag("pos:")?;
        let center = self.vec3("the sphere centre")?;
        self.tag("rad:")?;
        let (radius, tok) = self.number("the sphere radius")?;
        if radius <= 0.0 {
            return Err(self.error_at(
                &tok,
                format!("sphere radius must be positive, found {}", tok.show()),
                None,
            ));
        }
        let material = self.material()?;
        let velocity = self.velocity()?;
        Ok(Sphere {
            center,
            radius,
            material,
            velocity,
        })
    }

    fn triangle(&mut self) -> PResult<Triangle> {
        // The classic files' normals are unit to within 2e-5; anything
        // further off was not meant to be interpolated as written.
        const NORMAL_LENGTH_TOLERANCE: f64 = 1e-3;
        let mut vertices = [Vertex {
            position: DVec3::ZERO,
            normal: DVec3::ZERO,
            material: 0,
        }; 3];
        for v in &mut vertices {
            self.tag("pos:")?;
            v.position = self.vec3("the vertex position")?;
            let nor = self.tag("nor:")?;
            v.normal = self.vec3("the vertex normal")?;
            if v.normal == DVec3::ZERO {
                let d = self.diagnostic(
                    &nor,
                    "zero-length vertex normal: it adds nothing to the interpolated normal"
                        .to_string(),
                    Some("where all three are zero the flat (geometric) normal is used"),
                );
                self.warn(d);
            } else if (v.normal.length() - 1.0).abs() > NORMAL_LENGTH_TOLERANCE
                || !v.normal.length().is_finite()
            {
                // Interpolating unnormalized normals would weight the corners
                // by their lengths; a 1e30 normal would also overflow f32.
                let d = self.diagnostic(
                    &nor,
                    format!(
                        "vertex normal has length {:e}, not 1: glint renormalizes it",
                        v.normal.length()
                    ),
                    Some("write unit normals to silence this warning"),
                );
                self.warn(d);
                // Scaled first so that even 1e300 has a finite length.
                v.normal = (v.normal / v.normal.abs().max_element()).normalize();
            }
            let m = self.material()?;
            let state = &mut self.state;
            v.material = state.material_ids.id(&mut state.scene.materials, m);
        }
        let velocity = self.velocity()?;
        Ok(Triangle { vertices, velocity })
    }

    fn light(&mut self) -> PResult<Light> {
        self.tag("pos:")?;
        let position = self.vec3("the light position")?;
        self.tag("col:")?;
        let color = self.vec3("the light colour")?;
        let mut shape = LightShape::Point;
        if self.optional_tag("rad:") {
            let (radius, tok) = self.number("the light radius")?;
            if radius < 0.0 {
                return Err(self.error_at(
                    &tok,
                    format!("light radius must be zero or more, found {}", tok.show()),
                    Some("rad: 0 (or no rad:) makes a point light"),
                ));
            }
            if radius > 0.0 {
                shape = LightShape::Sphere { radius };
            }
        } else if self.optional_tag("edge_u:") {
            let edge_u = self.vec3("the rectangle light's first edge")?;
            self.tag("edge_v:")?;
            let edge_v = self.vec3("the rectangle light's second edge")?;
            shape = LightShape::Rect { edge_u, edge_v };
        }
        let velocity = self.velocity()?;
        Ok(Light {
            position,
            color,
            shape,
            velocity,
        })
    }

    /// `camera` with `eye:`, `look:`, `up:`, `fov:` in any order, each
    /// optional (the classic camera's values where left out); at most one.
    fn camera(&mut self, tok: &Token<'a>) -> PResult<()> {
        if self.state.scene.camera.is_some() {
            return Err(self.error_at(
                tok,
                "a second `camera` block; a scene has at most one".into(),
                None,
            ));
        }
        let mut cam = CameraSpec::CLASSIC;
        loop {
            if self.optional_tag("eye:") {
                cam.eye = self.vec3("the camera position")?;
            } else if self.optional_tag("look:") {
                cam.look = self.vec3("the point the camera looks at")?;
            } else if self.optional_tag("up:") {
                cam.up = self.vec3("the camera's up direction")?;
            } else if self.optional_tag("fov:") {
                let (fov, t) = self.number("the vertical field of view in degrees")?;
                if !(fov > 0.0 && fov < 180.0) {
                    return Err(self.expected(&t, "a field of view above 0 and below 180 degrees"));
                }
                cam.fov = fov;
            } else {
                break;
            }
        }
        if cam.basis().is_none() {
            return Err(self.error_at(
                tok,
                "this camera has no view: `look:` is its `eye:`, or `up:` points along the view"
                    .into(),
                Some("look at a point other than the eye, with an up direction across the view"),
            ));
        }
        self.state.scene.camera = Some(cam);
        Ok(())
    }

    /// `mesh` with `file:` (relative to the scene file), an optional
    /// material, and `scale:`, `translate:`, `rotate:` applied in the order
    /// written; its triangles join the scene's.
    fn mesh(&mut self) -> PResult<()> {
        let file_tag = self.tag("file:")?;
        let name_tok = self.require("a model file name (.obj, .ply or .off)")?;
        let name = String::from_utf8_lossy(name_tok.text).into_owned();
        let mut material = None;
        let mut transforms: Vec<Transform> = Vec::new();
        loop {
            let saved = self.at();
            if self.optional_tag("dif:") {
                self.go(saved);
                material = Some(self.material()?);
            } else if self.optional_tag("scale:") {
                let (s, t) = self.number("the mesh's scale factor")?;
                if s <= 0.0 {
                    return Err(self.expected(&t, "a scale above 0"));
                }
                transforms.push(Transform::Scale(s));
            } else if self.optional_tag("translate:") {
                transforms.push(Transform::Translate(self.vec3("the mesh's translation")?));
            } else if self.optional_tag("rotate:") {
                let axis = self.vec3("the rotation axis")?;
                let (degrees, _) = self.number("the rotation angle in degrees")?;
                let Some(axis) = axis.try_normalize() else {
                    return Err(self.error_at(
                        &name_tok,
                        "the rotation axis of this mesh has no direction (0 0 0)".into(),
                        None,
                    ));
                };
                transforms.push(Transform::Rotate(glam::DQuat::from_axis_angle(
                    axis,
                    degrees.to_radians(),
                )));
            } else {
                break;
            }
        }
        let start = std::time::Instant::now();
        let file = self.base_dir().join(&name);
        let mesh = crate::mesh::load(&file).map_err(|e| {
            self.error_at(
                &name_tok,
                format!("cannot load this mesh: {e}"),
                Some("the path is relative to the scene file"),
            )
        })?;
        if material.is_none() && mesh.missing_material() && !mesh.faces.is_empty() {
            let what = if mesh.materials.is_empty() {
                format!("{name} brings no materials, and this mesh block gives none")
            } else {
                format!(
                    "some faces of {name} have no material (no `usemtl` before them, or one \
                     no library defines), and this mesh block gives none"
                )
            };
            let d = crate::mesh::DEFAULT_MATERIAL;
            let diagnostic = self.diagnostic(
                &file_tag,
                format!(
                    "{what}: they take the default material (dif: {} {} {} spe: 0 0 0 shi: {})",
                    d.kd.x, d.kd.y, d.kd.z, d.shininess
                ),
                Some("add `dif: r g b  spe: r g b  shi: s` after the file name"),
            );
            self.warn(diagnostic);
        }
        if mesh.faces.is_empty() {
            let diagnostic = self.diagnostic(
                &name_tok,
                format!("{name} holds no triangles (points, lines or nothing): it adds nothing"),
                Some("check the file: glint renders surfaces (faces, triangles)"),
            );
            self.warn(diagnostic);
        }
        let state = &mut self.state;
        let triangles = mesh.triangles(
            material,
            |p| transforms.iter().fold(p, |p, t| t.point(p)),
            |n| transforms.iter().fold(n, |n, t| t.direction(n)),
            |m| state.material_ids.id(&mut state.scene.materials, m),
        );
        let bounds = triangles
            .iter()
            .map(Triangle::bounds)
            .fold(Bounds::EMPTY, Bounds::union);
        let before = self.state.scene.triangles.len();
        self.state.scene.triangles.extend(triangles);
        let count = self.state.scene.triangles.len() - before;
        if self.state.nothing_from_meshes.is_none() && count == 0 {
            self.state.nothing_from_meshes = Some(self.diagnostic(
                &name_tok,
                format!(
                    "nothing to render: the scene has no spheres or triangles, and {name} \
                     brought none"
                ),
                Some("check the model file, or add objects to the scene"),
            ));
        }
        self.state.scene.meshes.push(MeshInfo {
            file: name,
            triangles: count,
            bounds,
            load_time: start.elapsed(),
            report: mesh.report,
        });
        Ok(())
    }

    /// The directory `mesh` file names are relative to.
    fn base_dir(&self) -> std::path::PathBuf {
        match Path::new(self.path).parent() {
            Some(d) if self.path != "<stdin>" => d.to_path_buf(),
            _ => std::path::PathBuf::from("."),
        }
    }

    /// An optional `vel: x y z` (scene units per second).
    fn velocity(&mut self) -> PResult<DVec3> {
        if self.optional_tag("vel:") {
            self.vec3("the velocity")
        } else {
            Ok(DVec3::ZERO)
        }
    }

    /// Consumes the next token if it is `tag`.
    fn optional_tag(&mut self, tag: &str) -> bool {
        let saved = self.at();
        match self.next_token() {
            Some(tok) if tok.is(tag) => true,
            _ => {
                self.go(saved);
                false
            }
        }
    }

    /// Parses a setting directive if `tok` starts one.
    fn setting(&mut self, tok: &Token<'a>) -> PResult<bool> {
        if tok.is("reflect:") {
            let v = self.integer("the reflection depth", 0, Effects::MAX_REFLECT)?;
            self.state.scene.settings.reflect = Some(v);
        } else if tok.is("spp:") {
            let v = self.integer("samples per pixel", 1, Effects::MAX_SPP)?;
            self.state.scene.settings.spp = Some(v);
        } else if tok.is("shadow_samples:") {
            let what = "shadow samples per area light";
            let v = self.integer(what, 1, Effects::MAX_SHADOW_SAMPLES)?;
            self.state.scene.settings.shadow_samples = Some(v);
        } else if tok.is("seed:") {
            let v = self.integer("the random seed", 0, u32::MAX)?;
            self.state.scene.settings.seed = Some(v);
        } else if tok.is("shutter:") {
            let (v, t) = self.number("the shutter, a fraction of the frame interval")?;
            if !(0.0..=1.0).contains(&v) {
                return Err(self.expected(&t, "a shutter between 0 (no blur) and 1"));
            }
            self.state.scene.settings.shutter = Some(v);
        } else if tok.is("fps:") {
            let (v, t) = self.number("frames per second")?;
            if v <= 0.0 {
                return Err(self.expected(&t, "a positive number of frames per second"));
            }
            self.state.scene.settings.fps = Some(v);
        } else {
            return Ok(false);
        }
        Ok(true)
    }

    fn integer(&mut self, what: &str, min: u32, max: u32) -> PResult<u32> {
        let (v, tok) = self.number(what)?;
        if v.fract() != 0.0 || v < f64::from(min) || v > f64::from(max) {
            return Err(self.expected(
                &tok,
                &format!("a whole number from {min} to {max} ({what})"),
            ));
        }
        Ok(v as u32)
    }

    fn material(&mut self) -> PResult<Material> {
        self.tag("dif:")?;
        let kd = self.vec3("the diffuse colour")?;
        self.tag("spe:")?;
        let ks = self.vec3("the specular colour")?;
        self.tag("shi:")?;
        let (shininess, tok) = self.number("the shininess")?;
        if shininess < 0.0 {
            return Err(self.error_at(
                &tok,
                format!("shininess must be zero or more, found {}", tok.show()),
                None,
            ));
        }
        Ok(Material { kd, ks, shininess })
    }

    fn tag(&mut self, tag: &str) -> PResult<Token<'a>> {
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

    fn vec3(&mut self, what: &str) -> PResult<DVec3> {
        let (x, _) = self.number(what)?;
        let (y, _) = self.number(what)?;
        let (z, _) = self.number(what)?;
        Ok(DVec3::new(x, y, z))
    }

    fn number(&mut self, what: &str) -> PResult<(f64, Token<'a>)> {
        // The fast path reads most numbers in place; what it cannot read,
        // or a number not followed by whitespace, goes the long way (which
        // also gives the messages).
        self.skip_space();
        let rest = &self.src[self.pos..];
        if let Some((value, n)) = super::number::parse_prefix(rest) {
            let ends = rest.get(n).map_or(self.at_eof, u8::is_ascii_whitespace);
            if ends && value.abs() <= f64::from(f32::MAX) {
                let tok = self.token_at(n);
                self.pos += n;
                return Ok((value, tok));
            }
        }
        let tok = self.require_with(|| format!("a number ({what})"))?;
        let value = super::number::parse_f64(tok.text);
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
    fn require(&mut self, what: &str) -> PResult<Token<'a>> {
        self.require_with(|| what.to_string())
    }

    /// As `require`, with `what` worked out only for the error: every
    /// token of a file passes here, and a message per token would cost an
    /// allocation each (most of the parse time on big files).
    fn require_with(&mut self, what: impl FnOnce() -> String) -> PResult<Token<'a>> {
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

    fn skip_space(&mut self) {
        while self.pos < self.src.len() && self.src[self.pos].is_ascii_whitespace() {
            if self.src[self.pos] == b'\n' {
                self.state.line += 1;
                self.state.line_start = self.base + self.pos + 1;
            }
            self.pos += 1;
        }
    }

    fn next_token(&mut self) -> Option<Token<'a>> {
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
    fn token_at(&self, len: usize) -> Token<'a> {
        Token {
            text: &self.src[self.pos..self.pos + len],
            offset: self.pos,
            line: self.state.line,
            line_start: self.state.line_start,
        }
    }

    /// A zero-width token at the end of the input, for end-of-file errors.
    fn end_token(&mut self) -> Token<'a> {
        while self.next_token().is_some() {}
        Token {
            text: &[],
            offset: self.src.len(),
            line: self.state.line,
            line_start: self.state.line_start,
        }
    }

    fn expected(&self, tok: &Token<'_>, what: &str) -> ParseError {
        self.error_at(tok, format!("expected {what}, found {}", tok.show()), None)
    }

    /// Keeps the first few warnings of each kind (told apart by their hint)
    /// and counts the rest, so a file that repeats one mistake a million
    /// times costs a counter, not a million diagnostics.
    fn warn(&mut self, d: Diagnostic) {
        self.warned = true;
        let same = self
            .state
            .scene
            .warnings
            .iter()
            .filter(|w| w.hint == d.hint)
            .count();
        if same < super::WARNINGS_KEPT {
            self.state.scene.warnings.push(d);
        } else {
            self.state.scene.more_warnings += 1;
        }
    }

    fn error_at(&self, tok: &Token<'_>, message: String, hint: Option<&str>) -> ParseError {
        ParseError(Box::new(self.diagnostic(tok, message, hint)))
    }

    fn diagnostic(&self, tok: &Token<'_>, message: String, hint: Option<&str>) -> Diagnostic {
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
const SOURCE_WINDOW: usize = 60;

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    /// Parts parsed ahead and joined, over all tests.
    pub(super) static JOINED: AtomicUsize = AtomicUsize::new(0);

    /// A scene whose parts parsed ahead meet everything that ends one: a
    /// setting, warnings, materials first named in a later part, objects on
    /// one line and on many, mixed case.
    fn mixed_scene(objects: usize) -> Vec<u8> {
        let mut text = format!("{objects}\namb: .1 .1 .1\n");
        for i in 0..objects {
            if i == objects / 2 {
                text += "reflect: 2\n";
            }
            let m = |k: usize| format!("dif: .{} .5 .5 spe: 0 0 0 shi: {}", (i + k) % 7, i % 3);
            let normal = if i % 37 == 5 { "0 0 0" } else { "0 0 1" };
            match i % 5 {
                0 => text += &format!("sphere pos: {i} 0 -3 rad: .5 {}\n", m(0)),
                1 => text += &format!("LIGHT\npos: 0 {i} 0\ncol: 1 1 1\n"),
                _ => {
                    text += if i % 2 == 0 {
                        "triangle\n"
                    } else {
                        "Triangle "
                    };
                    for k in 0..3 {
                        text += &format!("pos: {i} {k} -5 nor: {normal} {}\n", m(k));
                    }
                }
            }
        }
        text.into_bytes()
    }

    #[test]
    fn parts_parsed_ahead_join_as_the_parse_in_order_reads_them() {
        let before = JOINED.load(Ordering::Relaxed);
        let src = mixed_scene(400);
        let whole = parse_scene(&src, "t").unwrap();
        assert!(whole.more_warnings > 0 && whole.settings.reflect == Some(2));
        for threads in 2..=4 {
            for (chunk, lookahead) in [(512, 128), (2000, 300), (97, 0)] {
                let windows = Windows {
                    chunk,
                    lookahead,
                    threads,
                };
                let windowed = parse_windows(&src[..], Path::new("t"), windows).unwrap();
                assert_eq!(whole, windowed, "{windows:?}");
            }
        }
        // Counted across tests running at once: at least this one's.
        assert!(JOINED.load(Ordering::Relaxed) > before + 100);
    }

    #[test]
    fn accepts_course_number_forms_and_mixed_case_tags() {
        let src = b"2\nAMB: .1 1 1e-16\nSphere pos: 0 0 -3 RAD: 1 dif: .44 0 0 spe: 0 0 0 shi: 1\nLIGHT pos: 0 0 0 col: 1 1 1\n";
        let scene = parse_scene(src, "t").unwrap();
        assert_eq!(scene.ambient, DVec3::new(0.1, 1.0, 1e-16));
        assert_eq!(scene.spheres[0].material.kd.x, 0.44);
        assert_eq!(scene.lights.len(), 1);
    }

    /// The project's scenes, a one-line scene (its columns run across
    /// windows) and the classic ones where present.
    fn sources() -> Vec<Vec<u8>> {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let mut out = Vec::new();
        for dir in ["scenes/effects", "scenes", "../shared/scenes/classic"] {
            let Ok(entries) = std::fs::read_dir(root.join(dir)) else {
                continue;
            };
            for e in entries.flatten() {
                if e.path().extension().is_some_and(|x| x == "scene") {
                    out.push(std::fs::read(e.path()).expect("readable scene"));
                }
            }
        }
        assert!(out.len() >= 6, "the project's scenes are missing");
        let one_line: Vec<u8> = out[0]
            .iter()
            .map(|&b| if b == b'\n' { b' ' } else { b })
            .collect();
        out.push(one_line);
        out
    }

    /// A parse error as the user reads it: where, what, and the hint.
    fn summary(text: &str) -> (&str, &str) {
        let first = text.lines().next().unwrap_or_default();
        let hint = text.lines().last().unwrap_or_default();
        (first, hint)
    }

    #[test]
    fn reading_in_windows_parses_as_the_whole_text_does() {
        // Tiny windows, and several threads, each parsing a part ahead.
        let sizes = [
            (1, 0),
            (7, 3),
            (64, 16),
            (300, 100),
            (4096, 1024),
            (4096, 1024),
        ];
        for src in sources() {
            let mut corrupt = vec![src.clone()];
            // Truncated mid-way, and a bad token in the middle and near
            // the end, so errors are found in later windows.
            corrupt.push(src[..src.len() * 2 / 3].to_vec());
            for at in [src.len() / 2, src.len() - src.len() / 10] {
                let mut bad = src.clone();
                let end = at
                    + bad[at..]
                        .iter()
                        .position(u8::is_ascii_whitespace)
                        .unwrap_or(0);
                bad.splice(end..end, " bogus\u{e9}".bytes());
                corrupt.push(bad);
            }
            for (k, text) in corrupt.iter().enumerate() {
                let whole = parse_scene(text, "t").map_err(|e| e.to_string());
                for ((chunk, lookahead), threads) in sizes.into_iter().zip([1, 2, 3, 4, 1, 2]) {
                    let windows = Windows {
                        chunk,
                        lookahead,
                        threads,
                    };
                    let windowed = parse_windows(&text[..], Path::new("t"), windows);
                    match (&whole, &windowed) {
                        (Ok(a), Ok(b)) => assert_eq!(a, b, "{windows:?}"),
                        (Err(a), Err(b)) => {
                            let b = b.to_string();
                            assert_eq!(summary(a), summary(&b), "{windows:?}, case {k}");
                        }
                        _ => panic!("{windows:?}, case {k}: {whole:?} but {windowed:?}"),
                    }
                }
            }
        }
    }

    /// A read that fails part way is an error naming the input, never a
    /// scene made of what was read before it.
    #[test]
    fn a_failed_read_is_an_error_not_a_shorter_scene() {
        /// The first `limit` bytes of a valid scene, a few at a time, then
        /// an error.
        struct Failing {
            at: usize,
            limit: usize,
        }
        impl Read for Failing {
            fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
                let text = b"2 amb: 0 0 0 light pos: 0 0 0 col: 1 1 1 light pos: 1 1 1 col: 1 1 1";
                if self.at == self.limit {
                    return Err(std::io::Error::other("disk gone"));
                }
                let n = (self.limit - self.at).min(buf.len()).min(3);
                buf[..n].copy_from_slice(&text[self.at..self.at + n]);
                self.at += n;
                Ok(n)
            }
        }
        let failing = Failing { at: 0, limit: 45 };
        let windows = Windows {
            chunk: 4,
            lookahead: 2,
            threads: 2,
        };
        let err = parse_windows(failing, Path::new("s.scene"), windows).unwrap_err();
        assert!(matches!(err, Error::ReadScene { .. }), "{err}");
        assert!(err.to_string().contains("s.scene"), "{err}");
    }

    #[test]
    fn caret_points_at_the_token() {
        let err = parse_scene(
            b"1\namb: 0 0 0\nsphere\npos: 0 0 -3\nradius: 1\n",
            "s.scene",
        )
        .unwrap_err();
        let text = err.to_string();
        assert!(
            text.starts_with("s.scene:5:1: expected `rad:`, found `radius:`"),
            "{text}"
        );
        assert!(text.contains("5 | radius: 1\n  | ^^^^^^^"), "{text}");
    }
}
