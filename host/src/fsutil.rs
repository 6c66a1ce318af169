//! Writing results atomically: a temp file in the same folder, then a rename, so a reader
//! never sees a partial or corrupted output file; and reading text inputs with errors that
//! say where they are not text.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::Error;

/// Writes `bytes` to `path` atomically (temp file beside it, fsync, rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    let mut set = OutputSet::default();
    set.add(path, bytes)?;
    set.commit()
}

/// Files that belong together (a recovery's materials, report, views and maps), written so
/// that a failure on any of them leaves none: each is written and synced to a temp file
/// beside its target as it is added, and only [`OutputSet::commit`] renames them into
/// place, after checking that every rename can succeed. A set dropped before its commit
/// (an error on the way) removes its temp files and leaves the previous outputs as they were.
#[derive(Default)]
pub struct OutputSet {
    /// (temp file, target) in the order added.
    staged: Vec<(PathBuf, PathBuf)>,
}

impl OutputSet {
    /// Writes `bytes` to a synced temp file beside `path`; a path added twice keeps the
    /// later bytes.
    pub fn add(&mut self, path: &Path, bytes: &[u8]) -> Result<(), Error> {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
        let tmp = dir.join(format!(".{name}.tmp-{}", std::process::id()));
        let written = (|| {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(bytes)?;
            f.sync_all()
        })();
        if let Err(e) = written {
            let _ = std::fs::remove_file(&tmp);
            return Err(Error::io(path, e));
        }
        if !self.staged.iter().any(|(t, _)| *t == tmp) {
            self.staged.push((tmp, path.to_path_buf()));
        }
        Ok(())
    }

    /// Renames every file into place. A target that a file cannot replace (a folder) is
    /// found before the first rename, so that case too leaves no part of the set.
    pub fn commit(mut self) -> Result<(), Error> {
        for (_, target) in &self.staged {
            if std::fs::symlink_metadata(target).is_ok_and(|m| m.is_dir()) {
                return Err(Error::io(
                    target,
                    std::io::Error::other("a folder is in the way of this output file"),
                ));
            }
        }
        for (tmp, target) in std::mem::take(&mut self.staged) {
            std::fs::rename(&tmp, &target).map_err(|e| {
                let _ = std::fs::remove_file(&tmp);
                Error::io(&target, e)
            })?;
        }
        Ok(())
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        for (tmp, _) in &self.staged {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Reads a text input (OBJ, TOML, JSON): UTF-8, with a leading byte order mark dropped (an
/// editor's, invisible in an error message). Bytes that are not UTF-8 are an error at
/// their line and byte.
pub fn read_text(path: &Path) -> Result<String, Error> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    match String::from_utf8(bytes) {
        Ok(text) => Ok(match text.strip_prefix('\u{feff}') {
            Some(rest) => rest.to_string(),
            None => text,
        }),
        Err(e) => {
            let bytes = e.as_bytes();
            let at = e.utf8_error().valid_up_to();
            let line = 1 + bytes[..at].iter().filter(|&&b| b == b'\n').count();
            Err(Error::at_line(
                path,
                line,
                format!("byte 0x{:02x} is not UTF-8 text", bytes[at]),
            ))
        }
    }
}

/// Creates `dir` and its parents.
pub fn create_dir(dir: &Path) -> Result<(), Error> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_inputs_drop_a_byte_order_mark_and_name_the_line_of_a_non_utf8_byte() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a.obj");
        std::fs::write(&path, "\u{feff}o quad\nv 0 0 0\n").unwrap();
        assert_eq!(read_text(&path).unwrap(), "o quad\nv 0 0 0\n");
        std::fs::write(&path, b"o quad\nv 0 0 0\nv 1 \xff 0\n").unwrap();
        let err = read_text(&path).unwrap_err().to_string();
        assert!(err.contains("a.obj:3") && err.contains("0xff"), "{err}");
    }

    #[test]
    fn writes_and_replaces_without_leaving_temp_files() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn a_set_that_fails_on_one_file_leaves_the_previous_outputs_and_no_temp_files() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.txt"), dir.path().join("b.txt"));
        std::fs::write(&a, "old a").unwrap();
        // A folder where b.txt should go: found at the commit, before a.txt is replaced.
        std::fs::create_dir(&b).unwrap();
        let mut set = OutputSet::default();
        set.add(&a, b"new a").unwrap();
        set.add(&b, b"new b").unwrap();
        let e = set.commit().unwrap_err().to_string();
        assert!(e.contains("b.txt") && e.contains("folder"), "{e}");
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
        // An error while adding: the set is dropped, its temp files go with it.
        let mut set = OutputSet::default();
        set.add(&a, b"new a").unwrap();
        assert!(set.add(&dir.path().join("no/such/c.txt"), b"c").is_err());
        drop(set);
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
        // A set that commits replaces every file.
        std::fs::remove_dir(&b).unwrap();
        let mut set = OutputSet::default();
        set.add(&a, b"new a").unwrap();
        set.add(&b, b"new b").unwrap();
        set.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "new a");
        assert_eq!(std::fs::read_to_string(&b).unwrap(), "new b");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    #[test]
    fn missing_folder_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("no/such/a.txt");
        let e = write_atomic(&p, b"x").unwrap_err();
        assert!(e.to_string().contains("a.txt"), "{e}");
    }
}
