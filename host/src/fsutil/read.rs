//! Reading input files: whole, as text with errors that say where it is not text, and why
//! a path an input names is no file to read.

use std::fs::File;
use std::path::Path;

use crate::error::Error;

/// Reads an input file whole. A folder in its place is bad input (a path that names the
/// wrong thing): the system's "Is a directory (os error 21)" reads as a fault of the
/// machine. A missing file stays an I/O error naming it.
pub fn read_bytes(path: &Path) -> Result<Vec<u8>, Error> {
    if path.is_dir() {
        return Err(Error::input(path, "is a folder, not a file"));
    }
    std::fs::read(path).map_err(|e| Error::io(path, e))
}

/// Why `path`, which an input file names as `a_what` ("an image"), is no file to read, or
/// `None` when it is one. Said at the line that names it.
pub fn not_a_file(path: &Path, a_what: &str) -> Option<String> {
    let why = match std::fs::metadata(path) {
        // Opened, not only looked at: a file without read permission was passed here and
        // failed later, as an I/O error naming no line.
        Ok(m) if m.is_file() => match File::open(path) {
            Ok(_) => return None,
            Err(e) => format!("cannot be read: {e}"),
        },
        Ok(m) if m.is_dir() => format!("is a folder, not {a_what}"),
        Ok(_) => format!("is not a regular file (a device, pipe or socket), not {a_what}"),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => "does not exist".to_string(),
        // A folder on the way that may not be entered, a NUL in the name: the file may
        // well be there, and "does not exist" sent the user looking for it.
        Err(e) => format!("cannot be reached: {e}"),
    };
    // A control character (a NUL) printed raw garbled the terminal.
    let shown: String = path
        .display()
        .to_string()
        .chars()
        .flat_map(|c| match c.is_control() {
            true => c.escape_debug().collect::<Vec<_>>(),
            false => vec![c],
        })
        .collect();
    Some(format!("{shown} {why}"))
}

/// Reads a text input (OBJ, TOML, JSON): UTF-8, with a leading byte order mark dropped (an
/// editor's, invisible in an error message). Bytes that are not UTF-8 are an error at
/// their line and byte.
pub fn read_text(path: &Path) -> Result<String, Error> {
    let bytes = read_bytes(path)?;
    match String::from_utf8(bytes) {
        Ok(text) => Ok(match text.strip_prefix('\u{feff}') {
            Some(rest) => rest.to_string(),
            None => text,
        }),
        Err(e) => {
            let bytes = e.as_bytes();
            let at = e.utf8_error().valid_up_to();
            // Lines end in LF (or CRLF); a file of CR alone (classic Mac OS) has its lines
            // counted by CR, as the OBJ reader reads them (it said line 1 for any byte).
            let cr_only = bytes.contains(&b'\r') && !bytes.contains(&b'\n');
            let end = if cr_only { b'\r' } else { b'\n' };
            let line = 1 + bytes[..at].iter().filter(|&&b| b == end).count();
            Err(Error::at_line(
                path,
                line,
                format!("byte 0x{:02x} is not UTF-8 text", bytes[at]),
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Only a file that is not there "does not exist": a NUL in a name (or a folder on the
    /// way that may not be entered) cannot be reached, and is said so, the NUL escaped.
    #[test]
    fn a_file_that_cannot_be_reached_is_not_said_to_be_missing() {
        let dir = tempfile::tempdir().unwrap();
        let missing = not_a_file(&dir.path().join("no.obj"), "an OBJ").unwrap();
        assert!(missing.ends_with("no.obj does not exist"), "{missing}");
        let nul = not_a_file(&dir.path().join("a\0b.obj"), "an OBJ").unwrap();
        assert!(
            nul.ends_with(
                "a\\0b.obj cannot be reached: file name contained an unexpected NUL byte"
            ),
            "{nul}"
        );
        std::fs::write(dir.path().join("here.obj"), "").unwrap();
        assert_eq!(not_a_file(&dir.path().join("here.obj"), "an OBJ"), None);
        assert!(not_a_file(dir.path(), "an OBJ")
            .unwrap()
            .ends_with("is a folder, not an OBJ"));
    }

    #[test]
    fn text_inputs_drop_a_byte_order_mark_and_name_the_line_of_a_non_utf8_byte() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.obj");
        std::fs::write(&path, "\u{feff}o quad\nv 0 0 0\n").unwrap();
        assert_eq!(read_text(&path).unwrap(), "o quad\nv 0 0 0\n");
        std::fs::write(&path, b"o quad\nv 0 0 0\nv 1 \xff 0\n").unwrap();
        let err = read_text(&path).unwrap_err().to_string();
        assert!(err.contains("a.obj:3") && err.contains("0xff"), "{err}");
        std::fs::write(&path, b"o quad\rv 0 0 0\rv 1 \xff 0\r").unwrap();
        let err = read_text(&path).unwrap_err().to_string();
        assert!(err.contains("a.obj:3") && err.contains("0xff"), "{err}");
    }
}
