//! Reading input of any kind (a file, a pipe, standard input, a FIFO, a
//! device) with bounded memory: a stream that never ends stops at
//! `--max-input` bytes, and text that is really binary data is refused in
//! its first kilobytes instead of being read to the end.
//!
//! Every reader of scene and model input goes through here, so one limit
//! and one set of messages cover them all.

use std::io::{self, Read};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// `--max-input`'s default: far above any real scene or model (the 2M
/// triangle grid is 683 MB of text), far below what a stream that never
/// ends would reach.
pub const DEFAULT_MAX_INPUT: u64 = 16 << 30;

static MAX_INPUT: AtomicU64 = AtomicU64::new(DEFAULT_MAX_INPUT);

/// Sets the most bytes any one input may have (`--max-input`).
pub fn set_max_input(bytes: u64) {
    MAX_INPUT.store(bytes.max(1), Ordering::Relaxed);
}

/// The most bytes any one input may have.
pub fn max_input() -> u64 {
    MAX_INPUT.load(Ordering::Relaxed)
}

/// How many bytes at the start of a text input are looked at before it is
/// taken for text: a NUL byte there means binary data.
pub const SNIFF: usize = 4096;

/// Why an input was not read to its end.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The input is longer than the limit.
    #[error(
        "the input goes on past --max-input ({}); if it is meant to be this long, raise \
         --max-input (bytes, or with K, M, G or T)",
        crate::units::human(*limit)
    )]
    TooLong {
        /// The limit, in bytes.
        limit: u64,
    },
    /// A NUL byte where text was expected.
    #[error(
        "byte {offset}: binary data (a NUL byte) where text was expected; this is not a {what} \
         (a wrong file, or a device such as /dev/zero?)"
    )]
    Binary {
        /// Where the NUL byte is.
        offset: u64,
        /// What the text should have been ("scene file", "OBJ file").
        what: &'static str,
    },
    /// Input that cannot be what it should be, found before it was read
    /// to its end.
    #[error("byte {offset}: {message}")]
    Refused {
        /// Where it was found.
        offset: u64,
        /// What is wrong.
        message: String,
    },
    /// Reading failed.
    #[error("{0}")]
    Io(#[from] io::Error),
}

impl InputError {
    /// The `InputError` inside an `io::Error` made by `into_io`, if any.
    pub fn from_io(e: io::Error) -> InputError {
        if e.get_ref().is_some_and(|inner| inner.is::<InputError>()) {
            match e.into_inner().map(|inner| inner.downcast::<InputError>()) {
                Some(Ok(inner)) => *inner,
                _ => InputError::Io(io::Error::other("unreadable input")),
            }
        } else {
            InputError::Io(e)
        }
    }

    /// The error as an `io::Error`, for readers whose callers only know
    /// those (the scene parser's `Read`).
    pub fn into_io(self) -> io::Error {
        match self {
            InputError::Io(e) => e,
            other => io::Error::new(io::ErrorKind::InvalidData, other),
        }
    }
}

/// A reader that fails once more than `limit` bytes have come through it.
pub struct Limited<R> {
    inner: R,
    read: u64,
    limit: u64,
}

impl<R: Read> Limited<R> {
    /// `inner`, which may yield at most `limit` bytes.
    pub fn new(inner: R, limit: u64) -> Limited<R> {
        Limited {
            inner,
            read: 0,
            limit,
        }
    }

    /// With the limit of `--max-input`.
    pub fn max(inner: R) -> Limited<R> {
        Limited::new(inner, max_input())
    }

    /// Bytes read so far.
    pub fn bytes_read(&self) -> u64 {
        self.read
    }
}

impl<R: Read> Read for Limited<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.read > self.limit {
            return Err(InputError::TooLong { limit: self.limit }.into_io());
        }
        // One byte past the limit is read, to tell "exactly the limit"
        // from "more".
        let room = (self.limit + 1 - self.read).min(buf.len() as u64) as usize;
        let n = self.inner.read(&mut buf[..room])?;
        self.read += n as u64;
        if self.read > self.limit {
            return Err(InputError::TooLong { limit: self.limit }.into_io());
        }
        Ok(n)
    }
}

/// Reads until `buf` holds `want` bytes or the input ends; false at the end.
pub fn fill(reader: &mut impl Read, buf: &mut Vec<u8>, want: usize) -> io::Result<bool> {
    while buf.len() < want {
        let room = (want - buf.len()) as u64;
        match reader.take(room).read_to_end(buf) {
            Ok(0) => return Ok(false),
            Ok(_) => {}
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(true)
}

/// What kind of bytes a model file holds, for `read_all`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Text throughout: a NUL byte anywhere is binary data, refused there.
    Text {
        /// What the text should be, for the message ("OBJ file").
        what: &'static str,
    },
    /// Anything goes (binary formats, or a text header before binary data).
    Binary,
}

/// Reads a whole input under `--max-input`, a chunk at a time. Text is
/// checked as it arrives, so a device or pipe of binary data is refused at
/// its first NUL byte, never read to the end.
pub fn read_all(reader: impl Read, kind: Kind) -> Result<Vec<u8>, InputError> {
    read_rest(reader, kind, Vec::new())
}

/// `read_all` after `buf`'s bytes (checked already), appending to it: a
/// caller that knows the length reserves it, and the bytes are never
/// copied to grow the buffer.
pub fn read_rest(
    mut reader: impl Read,
    kind: Kind,
    mut buf: Vec<u8>,
) -> Result<Vec<u8>, InputError> {
    const CHUNK: usize = 1 << 16;
    let limit = max_input();
    loop {
        let start = buf.len();
        let more = fill(&mut reader, &mut buf, start + CHUNK)?;
        if let Kind::Text { what } = kind {
            if let Some(i) = memchr_nul(&buf[start..]) {
                return Err(InputError::Binary {
                    offset: (start + i) as u64,
                    what,
                });
            }
        }
        if buf.len() as u64 > limit {
            return Err(InputError::TooLong { limit });
        }
        if !more {
            return Ok(buf);
        }
    }
}

/// Opens and reads a file (or FIFO, or device) as `read_all` does.
pub fn read_path(path: &Path, kind: Kind) -> Result<Vec<u8>, InputError> {
    let file = std::fs::File::open(path)?;
    read_all(file, kind)
}

fn memchr_nul(bytes: &[u8]) -> Option<usize> {
    memchr::memchr(0, bytes)
}

/// Parses a byte count: a whole number with an optional K, M, G or T
/// (powers of 1024, `B` and `iB` optional): `--max-input 64G`.
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let upper = t.to_ascii_uppercase();
    let digits_end = upper
        .find(|c: char| !c.is_ascii_digit())
        .unwrap_or(upper.len());
    let (num, unit) = upper.split_at(digits_end);
    let shift = match unit.trim_end_matches("IB").trim_end_matches('B') {
        "" => 0,
        "K" => 10,
        "M" => 20,
        "G" => 30,
        "T" => 40,
        _ => return Err(format!("expected a size such as 64G or 500M, found `{s}`")),
    };
    let n: u64 = num
        .parse()
        .map_err(|_| format!("expected a size such as 64G or 500M, found `{s}`"))?;
    n.checked_mul(1 << shift)
        .filter(|&v| v > 0)
        .ok_or_else(|| format!("`{s}` is not a size from 1 byte to 16 EiB"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_units() {
        assert_eq!(parse_size("16G"), Ok(16 << 30));
        assert_eq!(parse_size("500m"), Ok(500 << 20));
        assert_eq!(parse_size("1KiB"), Ok(1024));
        assert_eq!(parse_size("42"), Ok(42));
        assert!(parse_size("0").is_err());
        assert!(parse_size("1X").is_err());
        assert!(parse_size("99999999999T").is_err());
    }

    #[test]
    fn limited_ends_a_stream_one_byte_past_the_limit() {
        let mut r = Limited::new(io::repeat(b'a'), 1000);
        let mut v = Vec::new();
        let e = r.read_to_end(&mut v).expect_err("endless");
        assert!(e.to_string().contains("--max-input"), "{e}");
        assert!(v.len() <= 1001);
        let mut r = Limited::new(&[7u8; 1000][..], 1000);
        let mut v = Vec::new();
        assert_eq!(r.read_to_end(&mut v).expect("exactly the limit"), 1000);
    }

    #[test]
    fn text_of_nul_bytes_is_refused_in_its_first_chunk() {
        let e = read_all(io::repeat(0), Kind::Text { what: "model" }).expect_err("zeros");
        assert!(matches!(e, InputError::Binary { offset: 0, .. }), "{e}");
        let mut bytes = b"v 1 2 3\n".repeat(100_000);
        bytes[700_001] = 0;
        let e = read_all(&bytes[..], Kind::Text { what: "model" }).expect_err("a NUL");
        assert!(
            matches!(
                e,
                InputError::Binary {
                    offset: 700_001,
                    ..
                }
            ),
            "{e}"
        );
    }
}
