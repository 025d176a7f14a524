//! Reading a scene as it arrives, a few megabytes at a time and in
//! parallel: a 700 MB scene is never resident beside what was parsed from
//! it, and a stream that is not a scene (binary data, a line without end)
//! is refused early instead of read to its end.

use std::io::Read;
use std::path::Path;

use super::diagnostic::ParseError;
use super::model::Scene;
use super::parse::{Parser, State, LOOKAHEAD, SIMPLE_OBJECTS};
use crate::Error;

/// Reads and parses a scene file; `path` is also used in messages. A model
/// file (by its extension: `mesh::EXTENSIONS`) is read as a scene of that
/// model alone, framed (`model_scene` with `MODEL_MATERIAL`).
pub fn read_scene(path: &Path) -> Result<Scene, Error> {
    if crate::mesh::Format::of(path).is_some() {
        return Ok(super::framed::model_scene(
            path,
            super::framed::MODEL_MATERIAL,
        )?);
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
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
