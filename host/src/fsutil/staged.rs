//! The registry of what the live output sets have staged (temp files, the folders made
//! for them), and the removal of it all when a run is interrupted.

use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

/// What the [`OutputSet`](super::OutputSet)s not yet committed or dropped have put on
/// disk, so that an interrupted run can remove it ([`remove_staged_files_on_interrupt`]).
/// Sets hold the lock while they register and create a temp file or folder and while they
/// commit, so an interrupt never sees a file half registered nor a set half renamed.
pub(super) struct Staged {
    /// Temp files.
    pub(super) files: Vec<PathBuf>,
    /// Folders the sets created for their files, parents before children.
    pub(super) dirs: Vec<PathBuf>,
}

static STAGED: Mutex<Staged> = Mutex::new(Staged {
    files: Vec::new(),
    dirs: Vec::new(),
});

pub(super) fn staged() -> MutexGuard<'static, Staged> {
    // A panic while the lock was held leaves the lists as they were: still what to remove.
    STAGED.lock().unwrap_or_else(|e| e.into_inner())
}

impl Staged {
    /// Removes the temp file `tmp` and forgets it.
    pub(super) fn remove_file(&mut self, tmp: &Path) {
        let _ = std::fs::remove_file(tmp);
        self.files.retain(|t| t != tmp);
    }

    /// Removes the folders of `dirs` (a set's, parents first) that are empty, children
    /// first, and forgets them all. A folder that holds anything else stays.
    pub(super) fn remove_dirs(&mut self, dirs: &[PathBuf]) {
        for dir in dirs.iter().rev() {
            let _ = std::fs::remove_dir(dir);
            self.forget_dir(dir);
        }
    }

    /// Removes the temp files of live output sets that `matching` selects (all of them on
    /// an interrupt), then the folders they created that `matching` selects and are left
    /// empty; returns how many files. The sets' own `Drop` then finds nothing to remove.
    pub(super) fn remove_matching(&mut self, matching: impl Fn(&Path) -> bool) -> usize {
        let selected = |paths: &[PathBuf]| -> Vec<PathBuf> {
            paths.iter().filter(|p| matching(p)).cloned().collect()
        };
        let files = selected(&self.files);
        for tmp in &files {
            self.remove_file(tmp);
        }
        let dirs = selected(&self.dirs);
        self.remove_dirs(&dirs);
        files.len()
    }

    pub(super) fn forget_dir(&mut self, dir: &Path) {
        if let Some(i) = self.dirs.iter().rposition(|d| d == dir) {
            self.dirs.remove(i);
        }
    }
}

/// Exit status of a run ended by Ctrl-C or a termination signal (128 + SIGINT).
pub const INTERRUPTED_EXIT_CODE: i32 = 130;

/// Installs a handler for Ctrl-C (and SIGTERM, SIGHUP) that removes the temp files of
/// every output set not yet committed, says so, and exits with
/// [`INTERRUPTED_EXIT_CODE`]. Without it an interrupted run leaves hidden
/// `.<name>.tmp-<pid>` files beside its outputs. Called once, at the start of `main`.
pub fn remove_staged_files_on_interrupt() -> Result<(), String> {
    ctrlc::set_handler(|| {
        // Files of sets committed before (a stability study's finished runs) stay.
        remove_staged_then(
            |_| true,
            |removed| {
                eprintln!("\nrelume: interrupted; {removed} unfinished output file(s) removed");
                std::process::exit(INTERRUPTED_EXIT_CODE)
            },
        )
    })
    .map_err(|e| e.to_string())
}

/// Removes what the live output sets staged that `matching` selects, then calls `and_then`
/// with how many files, the registry's lock held all the while: a set that staged a file
/// or made a folder between the removal and an exit would leave it behind (the output
/// folder of a render interrupted just before it was made, seen in CI).
fn remove_staged_then<T>(matching: impl Fn(&Path) -> bool, and_then: impl FnOnce(usize) -> T) -> T {
    let mut registry = staged();
    let removed = registry.remove_matching(matching);
    and_then(removed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fsutil::OutputSet;

    /// The interrupt's exit runs under the same hold of the lock as its removal: no set
    /// can make a folder or stage a file after the one and before the other.
    #[test]
    fn an_interrupt_exits_holding_the_lock_it_removed_under() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        let mut set = OutputSet::default();
        set.create_dir(&out).unwrap();
        set.add(&out.join("a.txt"), b"a").unwrap();
        let locked_at_exit = remove_staged_then(
            |p| p.starts_with(dir.path()),
            |removed| {
                assert_eq!(removed, 1);
                assert!(!out.exists(), "the file and the folder it was made for go");
                STAGED.try_lock().is_err()
            },
        );
        assert!(locked_at_exit, "the lock was let go before the exit");
        drop(set);
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
        assert_eq!(staged().remove_matching(in_dir), 2);
        assert_eq!(files(), ["done.txt"]);
        // Nothing is left registered for this folder, and the set's drop is harmless.
        assert_eq!(staged().remove_matching(in_dir), 0);
        drop(live);
        assert_eq!(files(), ["done.txt"]);
    }
}
