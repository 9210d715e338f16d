//! Bounded reads of the files and streams raygun is given. A path from a user or from another
//! file may name anything — a device such as `/dev/zero`, a pipe, a folder, a sparse file of a
//! terabyte — so every read here first checks what it is reading and how much: files are read
//! only when they are regular files, and never past their size at the time they were opened or
//! past the limit the caller states; lines are read up to a stated length, and the rest of a
//! longer line is skipped without being held.
//!
//! Errors are [`std::io::Error`]s whose text says what was wrong ("is a character device, not a
//! file", "is 5.4 GB, more than the 67 MB a display model may have"); callers put the file's
//! name in front, as they do for every other I/O error.

use std::fs::File;
use std::io::{self, BufRead, Read};
use std::path::Path;

use crate::messages::bytes;

/// What kind of file system object `meta` describes, in words, for one that is not a regular
/// file.
fn kind_of(meta: &std::fs::Metadata) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = meta.file_type();
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_fifo() {
            return "a pipe";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    if meta.is_dir() {
        "a folder"
    } else {
        "not a regular file"
    }
}

/// A size for messages: its bytes exactly, and rounded for people where that differs.
fn size(n: u64) -> String {
    if n < 1000 {
        bytes(n)
    } else {
        format!("{} ({n} bytes)", bytes(n))
    }
}

fn invalid(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, message)
}

/// Opens `path` for reading if it is a regular file (after following links), with its size.
pub fn open_regular(path: &Path) -> io::Result<(File, u64)> {
    let file = File::open(path)?;
    // The open file's own metadata: the object that will be read, whatever the path names by
    // the time of the read.
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(invalid(format!("is {}, not a file", kind_of(&meta))));
    }
    Ok((file, meta.len()))
}

/// Reads exactly `len` bytes from `file` (fewer if it shrank meanwhile: an error).
fn read_len(file: File, len: u64) -> io::Result<Vec<u8>> {
    let cap = usize::try_from(len).map_err(|_| invalid(format!("{len} bytes do not fit")))?;
    let mut out = Vec::new();
    out.try_reserve_exact(cap).map_err(|_| {
        io::Error::new(
            io::ErrorKind::OutOfMemory,
            format!("cannot hold its {} in memory", bytes(len)),
        )
    })?;
    file.take(len).read_to_end(&mut out)?;
    if (out.len() as u64) < len {
        return Err(io::Error::new(
            io::ErrorKind::UnexpectedEof,
            format!(
                "ended after {} bytes of {len} (it shrank while read)",
                out.len()
            ),
        ));
    }
    Ok(out)
}

/// The whole of the regular file `path`, refused unread when it is larger than `max` bytes;
/// `what` names the kind of file in that message ("a display model").
pub fn read_file(path: &Path, max: u64, what: &str) -> io::Result<Vec<u8>> {
    let (file, len) = open_regular(path)?;
    if len > max {
        return Err(invalid(format!(
            "is {}, more than the {} {what} may have",
            size(len),
            size(max)
        )));
    }
    read_len(file, len)
}

/// [`read_file`] as UTF-8 text.
pub fn read_text(path: &Path, max: u64, what: &str) -> io::Result<String> {
    String::from_utf8(read_file(path, max, what)?).map_err(|e| {
        invalid(format!(
            "is not UTF-8 text (byte {})",
            e.utf8_error().valid_up_to()
        ))
    })
}

/// The first `len` bytes of the regular file `path`, which must have at least that many
/// (checked before anything is allocated, so a declared length is never trusted alone).
pub fn read_prefix(path: &Path, len: u64) -> io::Result<Vec<u8>> {
    let (file, size) = open_regular(path)?;
    if size < len {
        return Err(invalid(format!(
            "has {size} bytes, fewer than the {len} it is declared to have"
        )));
    }
    read_len(file, len)
}

/// What [`read_line`] found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Line {
    /// The end of the input: nothing was read.
    End,
    /// A line (in the buffer, with its `\n` if it had one).
    Line,
    /// A line longer than the limit; the buffer holds nothing and the rest of the line has
    /// been skipped (up to and including its `\n`, or to the end of the input).
    TooLong,
}

/// Reads one line of at most `max` bytes (its `\n` included) into `buf` (cleared first). A
/// longer line is skipped in pieces of the reader's buffer, so memory stays bounded by `max`
/// whatever the input holds.
pub fn read_line(input: &mut impl BufRead, buf: &mut Vec<u8>, max: usize) -> io::Result<Line> {
    buf.clear();
    let n = (&mut *input).take(max as u64).read_until(b'\n', buf)?;
    if n == 0 {
        return Ok(Line::End);
    }
    if buf.last() == Some(&b'\n') {
        return Ok(Line::Line);
    }
    // No newline within `max` bytes: either the input ended (a last line without `\n`) or the
    // line goes on.
    if input.fill_buf()?.is_empty() {
        return Ok(Line::Line);
    }
    buf.clear();
    loop {
        let chunk = input.fill_buf()?;
        if chunk.is_empty() {
            return Ok(Line::TooLong);
        }
        if let Some(i) = chunk.iter().position(|&b| b == b'\n') {
            input.consume(i + 1);
            return Ok(Line::TooLong);
        }
        let n = chunk.len();
        input.consume(n);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir() -> std::path::PathBuf {
        let d = std::env::temp_dir().join(format!("raygun-input-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn devices_folders_and_pipes_are_refused_unread() {
        let e = read_file(Path::new("/dev/zero"), 1 << 20, "a test file").unwrap_err();
        assert!(
            e.to_string().contains("a character device, not a file"),
            "{e}"
        );
        let e = read_prefix(Path::new("/dev/zero"), 16).unwrap_err();
        assert!(e.to_string().contains("character device"), "{e}");
        let e = read_file(Path::new("/"), 1 << 20, "a test file").unwrap_err();
        assert!(e.to_string().contains("a folder, not a file"), "{e}");
    }

    #[test]
    fn files_over_their_limit_are_refused_with_both_sizes() {
        let d = dir();
        let p = d.join("limit.txt");
        std::fs::write(&p, b"0123456789").unwrap();
        assert_eq!(read_file(&p, 10, "x").unwrap(), b"0123456789");
        let e = read_file(&p, 9, "a calibration").unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("is 10 bytes, more than the 9 bytes a calibration may have"),
            "{text}"
        );
        assert_eq!(read_prefix(&p, 4).unwrap(), b"0123");
        let e = read_prefix(&p, 11).unwrap_err();
        assert!(
            e.to_string().contains("has 10 bytes, fewer than the 11"),
            "{e}"
        );
        // A declared length far beyond the file is refused before anything is allocated.
        assert!(read_prefix(&p, u64::MAX).is_err());
        std::fs::write(&p, [0xff, 0xfe]).unwrap();
        assert!(
            read_text(&p, 10, "x")
                .unwrap_err()
                .to_string()
                .contains("UTF-8")
        );
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn lines_are_capped_and_the_rest_of_a_long_line_is_skipped() {
        let text = b"short\n0123456789abcdef\nnext\nlast";
        // A reader buffer smaller than the long line, so the skip takes several pieces.
        let mut r = io::BufReader::with_capacity(4, &text[..]);
        let mut buf = Vec::new();
        assert_eq!(read_line(&mut r, &mut buf, 8).unwrap(), Line::Line);
        assert_eq!(buf, b"short\n");
        assert_eq!(read_line(&mut r, &mut buf, 8).unwrap(), Line::TooLong);
        assert!(buf.is_empty());
        assert_eq!(read_line(&mut r, &mut buf, 8).unwrap(), Line::Line);
        assert_eq!(buf, b"next\n");
        assert_eq!(read_line(&mut r, &mut buf, 8).unwrap(), Line::Line);
        assert_eq!(buf, b"last");
        assert_eq!(read_line(&mut r, &mut buf, 8).unwrap(), Line::End);
        // Exactly the limit, newline included, is a line; one more byte is not.
        let mut r = io::BufReader::new(&b"1234567\n12345678\n"[..]);
        assert_eq!(read_line(&mut r, &mut buf, 8).unwrap(), Line::Line);
        assert_eq!(read_line(&mut r, &mut buf, 8).unwrap(), Line::TooLong);
        assert_eq!(read_line(&mut r, &mut buf, 8).unwrap(), Line::End);
    }

    #[test]
    fn an_endless_line_is_read_with_bounded_memory() {
        // 64 MiB of zeros without a newline, read through a 1 KiB limit: the buffer never
        // grows past the limit.
        let mut r = io::BufReader::new(io::repeat(0).take(64 << 20));
        let mut buf = Vec::new();
        assert_eq!(read_line(&mut r, &mut buf, 1024).unwrap(), Line::TooLong);
        assert!(buf.capacity() <= 2048, "{}", buf.capacity());
        assert_eq!(read_line(&mut r, &mut buf, 1024).unwrap(), Line::End);
    }
}
