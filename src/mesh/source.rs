//! A model file's bytes, read with bounded memory whatever it is (a file,
//! a FIFO, a device): text formats are refused at their first NUL byte,
//! binary formats whose header gives their length (binary STL, GLB) are
//! read to that length and no further, and everything stops at
//! `--max-input`. Text in UTF-16 is decoded and a byte-order mark skipped,
//! each with a warning.

use std::io::Read;
use std::path::{Path, PathBuf};

use super::report::{Report, Tolerance};
use super::{Format, MeshError};
use crate::input::{self, InputError, Kind, Limited};

/// A model file's bytes, ready for its parser, and the format they hold
/// (a `.gltf` that is really GLB, an STL's encoding).
pub struct Source {
    pub bytes: Vec<u8>,
    pub format: Format,
    pub report: Report,
}

fn error(path: &Path, at: Option<String>, message: impl Into<String>) -> MeshError {
    MeshError {
        path: path.to_path_buf(),
        at,
        message: message.into(),
    }
}

fn input_error(path: &Path, e: InputError) -> MeshError {
    match e {
        InputError::Io(e) => error(path, None, format!("cannot read it: {e}")),
        InputError::Binary { offset, what } => error(
            path,
            Some(format!("byte {offset}")),
            format!(
                "binary data (a NUL byte) where {what} text was expected; is it the file you \
                 meant?"
            ),
        ),
        InputError::Refused { offset, message } => {
            error(path, Some(format!("byte {offset}")), message)
        }
        e @ InputError::TooLong { .. } => error(path, None, e.to_string()),
    }
}

/// Reads `path` for `format` (chosen by extension).
pub fn read(path: &Path, format: Format) -> Result<Source, MeshError> {
    let file = std::fs::File::open(path).map_err(|e| input_error(path, e.into()))?;
    // A regular file's length, so its bytes land in one buffer of the
    // right size (a pipe or device says 0 and grows as it comes).
    let len = file
        .metadata()
        .map_or(0, |m| m.len())
        .min(input::max_input());
    read_sized(file, path, format, usize::try_from(len).unwrap_or(0))
}

/// `read` from any reader; `path` names it in messages.
pub fn read_from(reader: impl Read, path: &Path, format: Format) -> Result<Source, MeshError> {
    read_sized(reader, path, format, 0)
}

fn read_sized(
    reader: impl Read,
    path: &Path,
    format: Format,
    len: usize,
) -> Result<Source, MeshError> {
    let mut r = Limited::max(reader);
    let mut head = Vec::with_capacity(len.saturating_add(1));
    input::fill(&mut r, &mut head, 84).map_err(|e| input_error(path, e.into()))?;
    let mut report = Report::default();
    // A GLB named .gltf (or the other way round) is read for what it is.
    let format = match format {
        Format::Gltf | Format::Glb if head.starts_with(b"glTF") => Format::Glb,
        Format::Glb if !head.starts_with(b"glTF") => Format::Gltf,
        f => f,
    };
    let format = match format {
        Format::Stl if is_ascii_stl(&head) => Format::StlAscii,
        f => f,
    };
    let bytes = match format {
        Format::Glb => read_glb(r, head, path)?,
        Format::Stl => read_binary_stl(r, head, path, &mut report)?,
        Format::Ply => {
            if !head.starts_with(b"ply") {
                return Err(error(
                    path,
                    Some("line 1".into()),
                    "this is not a PLY file: it does not begin with `ply`",
                ));
            }
            rest(r, head, Kind::Binary, path)?
        }
        _ => read_text(r, head, path, format, &mut report)?,
    };
    Ok(Source {
        bytes,
        format,
        report,
    })
}

/// `head` and the rest of the input.
fn rest(r: impl Read, head: Vec<u8>, kind: Kind, path: &Path) -> Result<Vec<u8>, MeshError> {
    if let Kind::Text { what } = kind {
        if let Some(i) = head.iter().position(|&b| b == 0) {
            return Err(input_error(
                path,
                InputError::Binary {
                    offset: i as u64,
                    what,
                },
            ));
        }
    }
    input::read_rest(r, kind, head).map_err(|e| input_error(path, e))
}

fn read_text(
    r: impl Read,
    head: Vec<u8>,
    path: &Path,
    format: Format,
    report: &mut Report,
) -> Result<Vec<u8>, MeshError> {
    let what = format.name();
    let utf16 = match head.get(..2) {
        Some([0xFF, 0xFE]) => Some(false),
        Some([0xFE, 0xFF]) => Some(true),
        _ => None,
    };
    let Some(big_endian) = utf16 else {
        let mut bytes = rest(r, head, Kind::Text { what }, path)?;
        if bytes.starts_with(b"\xEF\xBB\xBF") {
            bytes.drain(..3);
            report.warn(
                Tolerance::Encoding,
                path,
                None,
                "a UTF-8 byte-order mark at the start was skipped",
            );
        }
        return Ok(bytes);
    };
    let raw = rest(r, head, Kind::Binary, path)?;
    let units = raw[2..].chunks_exact(2).map(|b| {
        if big_endian {
            u16::from_be_bytes([b[0], b[1]])
        } else {
            u16::from_le_bytes([b[0], b[1]])
        }
    });
    let text: String = char::decode_utf16(units)
        .enumerate()
        .map(|(i, c)| {
            c.map_err(|_| {
                error(
                    path,
                    Some(format!("byte {}", 2 + 2 * i)),
                    "UTF-16 text with a broken surrogate pair; save the file as UTF-8",
                )
            })
        })
        .collect::<Result<_, _>>()?;
    if let Some(i) = text.bytes().position(|b| b == 0) {
        return Err(error(
            path,
            None,
            format!("character {i} of the decoded UTF-16 text is NUL: this is not {what} text"),
        ));
    }
    report.warn(
        Tolerance::Encoding,
        path,
        None,
        format!(
            "UTF-16 ({}) text was decoded; glint reads UTF-8 and ASCII",
            if big_endian {
                "big-endian"
            } else {
                "little-endian"
            }
        ),
    );
    Ok(text.into_bytes())
}

/// ASCII STL begins with `solid` and holds only text; binary STL files
/// often begin with `solid` too, so the next bytes decide: a binary
/// header is followed by a little-endian count and 50-byte triangles,
/// which are rarely all printable.
pub fn is_ascii_stl(bytes: &[u8]) -> bool {
    let start = bytes.trim_ascii_start();
    if !start
        .get(..5)
        .is_some_and(|s| s.eq_ignore_ascii_case(b"solid"))
    {
        return false;
    }
    let window = &bytes[..bytes.len().min(input::SNIFF)];
    let text = window
        .iter()
        .all(|&b| b.is_ascii_graphic() || b.is_ascii_whitespace());
    let keyword = window
        .windows(5)
        .any(|w| w.eq_ignore_ascii_case(b"facet") || w.eq_ignore_ascii_case(b"endso"));
    text && (keyword || bytes.len() < 84 || window.len() < input::SNIFF)
}

/// Binary STL: an 80-byte header, a triangle count, 50 bytes a triangle.
/// Read to the count's end and no further; a longer input is reported.
fn read_binary_stl(
    mut r: impl Read,
    mut head: Vec<u8>,
    path: &Path,
    report: &mut Report,
) -> Result<Vec<u8>, MeshError> {
    if head.len() < 84 {
        return Err(error(
            path,
            None,
            format!(
                "{} bytes: too short for binary STL (an 80-byte header and a triangle \
                 count), and not ASCII STL (which begins with `solid`)",
                head.len()
            ),
        ));
    }
    let count = u32::from_le_bytes([head[80], head[81], head[82], head[83]]);
    let want = 84 + 50 * u64::from(count);
    if want > input::max_input() {
        return Err(error(
            path,
            Some("byte 80".into()),
            format!(
                "the header claims {count} triangles ({want} bytes), more than --max-input ({})",
                crate::units::human(input::max_input())
            ),
        ));
    }
    let complete =
        input::fill(&mut r, &mut head, want as usize).map_err(|e| input_error(path, e.into()))?;
    if !complete && (head.len() as u64) < want {
        let whole = (head.len() - 84) / 50;
        return Err(error(
            path,
            Some(format!("byte {}", head.len())),
            format!(
                "the file ends inside triangle {} of the {count} its header claims",
                whole + 1
            ),
        ));
    }
    let mut probe = [0u8; 1];
    if matches!(r.read(&mut probe), Ok(1)) {
        report.warn(
            Tolerance::TrailingData,
            path,
            Some(format!("byte {want}")),
            format!("data after the {count} triangles the header claims was not read"),
        );
    }
    Ok(head)
}

/// GLB: a 12-byte header whose third word is the whole length; read to it.
fn read_glb(mut r: impl Read, mut head: Vec<u8>, path: &Path) -> Result<Vec<u8>, MeshError> {
    if head.len() < 12 {
        return Err(error(path, None, "too short for a GLB header (12 bytes)"));
    }
    let word = |i: usize| u32::from_le_bytes([head[i], head[i + 1], head[i + 2], head[i + 3]]);
    let (version, length) = (word(4), u64::from(word(8)));
    if version != 2 {
        return Err(error(
            path,
            Some("byte 4".into()),
            format!("GLB version {version}; glint reads glTF 2.0"),
        ));
    }
    if length > input::max_input() {
        return Err(error(
            path,
            Some("byte 8".into()),
            format!(
                "the header claims {length} bytes, more than --max-input ({})",
                crate::units::human(input::max_input())
            ),
        ));
    }
    head.truncate(head.len().min(length as usize));
    input::fill(&mut r, &mut head, length as usize).map_err(|e| input_error(path, e.into()))?;
    if (head.len() as u64) < length {
        return Err(error(
            path,
            Some(format!("byte {}", head.len())),
            format!("the file ends before the {length} bytes its header claims"),
        ));
    }
    Ok(head)
}

/// A file a model refers to (an MTL library, a glTF buffer), read the same
/// bounded way; tried, it is one of the files the model came from
/// (`referenced_during`), whether or not it was there.
pub fn read_referenced(path: &Path, kind: Kind) -> Result<Vec<u8>, InputError> {
    REFERENCED.with(|r| r.borrow_mut().push(path.to_path_buf()));
    input::read_path(path, kind)
}

thread_local! {
    /// The files `read_referenced` tried on this thread during the
    /// innermost `referenced_during`.
    static REFERENCED: std::cell::RefCell<Vec<PathBuf>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// `f()`, and the files a model refers to that it tried to read: what
/// the scene cache checks besides the model file. A model is parsed on
/// the thread that loads it, so every such read is this thread's.
pub(crate) fn referenced_during<T>(f: impl FnOnce() -> T) -> (T, Vec<PathBuf>) {
    let outer = REFERENCED.with(|r| std::mem::take(&mut *r.borrow_mut()));
    let out = f();
    let tried = REFERENCED.with(|r| std::mem::replace(&mut *r.borrow_mut(), outer));
    (out, tried)
}
