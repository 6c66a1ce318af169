//! Writing results atomically: a temp file in the same folder, then a rename, so a reader
//! never sees a partial or corrupted output file; and reading text inputs with errors that
//! say where they are not text.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use crate::error::Error;

/// The temp files of every [`OutputSet`] not yet committed or dropped, so that an
/// interrupted run can remove them ([`remove_staged_files_on_interrupt`]). Sets hold the
/// lock while they create a temp file and while they commit, so an interrupt waits for
/// either to finish: it never sees a file half registered nor a set half renamed.
static STAGED_FILES: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn staged_files() -> MutexGuard<'static, Vec<PathBuf>> {
    // A panic while the lock was held leaves the list as it was: still the files to remove.
    STAGED_FILES.lock().unwrap_or_else(|e| e.into_inner())
}

/// Exit status of a run ended by Ctrl-C or a termination signal (128 + SIGINT).
pub const INTERRUPTED_EXIT_CODE: i32 = 130;

/// Installs a handler for Ctrl-C (and SIGTERM, SIGHUP) that removes the temp files of
/// every output set not yet committed, says so, and exits with
/// [`INTERRUPTED_EXIT_CODE`]. Without it an interrupted run leaves hidden
/// `.<name>.tmp-<pid>` files beside its outputs. Called once, at the start of `main`.
pub fn remove_staged_files_on_interrupt() -> Result<(), String> {
    ctrlc::set_handler(|| {
        let removed = remove_staged_files(|_| true);
        // Files of sets committed before (a stability study's finished runs) stay.
        eprintln!("\nrelume: interrupted; {removed} unfinished output file(s) removed");
        // Exits holding the lock: no set can stage another file meanwhile.
        let _held = staged_files();
        std::process::exit(INTERRUPTED_EXIT_CODE);
    })
    .map_err(|e| e.to_string())
}

/// Removes the temp files of live output sets that `matching` selects (all of them on an
/// interrupt); returns how many. The sets' own `Drop` then finds nothing to remove.
fn remove_staged_files(matching: impl Fn(&Path) -> bool) -> usize {
    let mut staged = staged_files();
    let before = staged.len();
    staged.retain(|tmp| {
        if matching(tmp) {
            let _ = std::fs::remove_file(tmp);
            false
        } else {
            true
        }
    });
    before - staged.len()
}

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
        let mut registry = staged_files();
        if !registry.contains(&tmp) {
            registry.push(tmp.clone());
        }
        let written = (|| {
            let mut f = std::fs::File::create(&tmp)?;
            f.write_all(bytes)?;
            f.sync_all()
        })();
        if let Err(e) = written {
            let _ = std::fs::remove_file(&tmp);
            registry.retain(|t| *t != tmp);
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
        let mut registry = staged_files();
        let staged = std::mem::take(&mut self.staged);
        for (i, (tmp, target)) in staged.iter().enumerate() {
            if let Err(e) = std::fs::rename(tmp, target) {
                // This file and the ones not yet renamed are not outputs.
                for (rest, _) in &staged[i..] {
                    let _ = std::fs::remove_file(rest);
                    registry.retain(|t| t != rest);
                }
                return Err(Error::io(target, e));
            }
            registry.retain(|t| t != tmp);
        }
        Ok(())
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        let mut registry = staged_files();
        for (tmp, _) in &self.staged {
            let _ = std::fs::remove_file(tmp);
            registry.retain(|t| t != tmp);
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
    fn an_interrupt_removes_the_temp_files_of_sets_not_yet_committed() {
        let dir = tempfile::tempdir().unwrap();
        let in_dir = |p: &Path| p.starts_with(dir.path());
        let files = || {
            let mut names: Vec<String> = std::fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            names.sort();
            names
        };
        let mut done = OutputSet::default();
        done.add(&dir.path().join("done.txt"), b"done").unwrap();
        done.commit().unwrap();
        let mut live = OutputSet::default();
        live.add(&dir.path().join("a.txt"), b"a").unwrap();
        live.add(&dir.path().join("b.txt"), b"b").unwrap();
        let pid = std::process::id();
        assert_eq!(
            files(),
            [
                format!(".a.txt.tmp-{pid}"),
                format!(".b.txt.tmp-{pid}"),
                "done.txt".into()
            ]
        );
        assert_eq!(remove_staged_files(in_dir), 2);
        assert_eq!(files(), ["done.txt"]);
        // Nothing is left registered for this folder, and the set's drop is harmless.
        assert_eq!(remove_staged_files(in_dir), 0);
        drop(live);
        assert_eq!(files(), ["done.txt"]);
    }

    #[test]
    fn a_rename_that_fails_midway_leaves_no_temp_file() {
        let dir = tempfile::tempdir().unwrap();
        let mut set = OutputSet::default();
        for name in ["a.txt", "b.txt", "c.txt"] {
            set.add(&dir.path().join(name), name.as_bytes()).unwrap();
        }
        // b's temp file vanishes after staging: a is renamed, b fails, c must not stay.
        let pid = std::process::id();
        std::fs::remove_file(dir.path().join(format!(".b.txt.tmp-{pid}"))).unwrap();
        let e = set.commit().unwrap_err().to_string();
        assert!(e.contains("b.txt"), "{e}");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["a.txt"]);
        assert_eq!(remove_staged_files(|p| p.starts_with(dir.path())), 0);
    }

    #[test]
    fn missing_folder_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("no/such/a.txt");
        let e = write_atomic(&p, b"x").unwrap_err();
        assert!(e.to_string().contains("a.txt"), "{e}");
    }
}
