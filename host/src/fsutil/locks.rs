//! The folder locks a commit holds, so that two runs into one folder commit one after the
//! other.

use std::fs::File;
use std::path::{Path, PathBuf};

/// Exclusive locks on each of `folders` (resolved, each once, in one order), released when
/// the files are dropped. Two runs into one `--out` each commit under them, so that their
/// commits follow one another and the folder holds one run's whole set, where their
/// renames interleaved and left views of both. A folder that cannot be locked (a file
/// system without locks) is committed into unlocked, as before.
pub(super) fn lock_folders<'a>(folders: impl Iterator<Item = &'a Path>) -> Vec<File> {
    let mut resolved: Vec<PathBuf> = folders
        .filter_map(|f| std::fs::canonicalize(f).ok())
        .collect();
    resolved.sort();
    resolved.dedup();
    lock_each(&resolved)
}

/// Locks each of `dirs` once: one folder under two paths (a bind mount of a folder into
/// itself, which resolving the paths does not undo) would be locked twice, and the second
/// lock wait on the first for ever.
fn lock_each(dirs: &[PathBuf]) -> Vec<File> {
    let mut held: Vec<(FolderId, File)> = Vec::new();
    for dir in dirs {
        let Ok(folder) = File::open(dir) else {
            continue;
        };
        let id = folder_id(&folder);
        if id.is_some() && held.iter().any(|(h, _)| *h == id) {
            continue;
        }
        if folder.lock().is_ok() {
            held.push((id, folder));
        }
    }
    held.into_iter().map(|(_, f)| f).collect()
}

/// A folder's device and inode, where the platform has them.
type FolderId = Option<(u64, u64)>;

fn folder_id(folder: &File) -> FolderId {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        folder.metadata().ok().map(|m| (m.dev(), m.ino()))
    }
    #[cfg(not(unix))]
    {
        let _ = folder;
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fsutil::OutputSet;

    /// A commit waits while another holds its folder (two runs into one `--out`): none of
    /// its files is in place until the other lets go, then all are.
    #[test]
    fn a_commit_waits_for_another_into_the_same_folder() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.txt"), dir.path().join("b.txt"));
        let mut set = OutputSet::default();
        set.add(&a, b"a").unwrap();
        set.add(&b, b"b").unwrap();
        let other_run = lock_folders([dir.path()].into_iter());
        assert_eq!(other_run.len(), 1, "this file system takes no locks");
        // One folder by two paths (here a link, not resolved; a bind mount alike) is
        // locked once: a second lock would wait on the first for ever.
        let other = tempfile::tempdir().unwrap();
        let link = other.path().join("again");
        std::os::unix::fs::symlink(other.path(), &link).unwrap();
        let (sent, got) = std::sync::mpsc::channel();
        let paths = [other.path().to_path_buf(), link];
        std::thread::spawn(move || sent.send(lock_each(&paths).len()));
        let locked = got.recv_timeout(std::time::Duration::from_secs(30));
        assert_eq!(locked, Ok(1), "one folder by two paths");
        let commit = std::thread::spawn(move || set.commit());
        std::thread::sleep(std::time::Duration::from_millis(300));
        assert!(!a.exists() && !b.exists(), "committed under another's lock");
        drop(other_run);
        commit.join().unwrap().unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"a");
        assert_eq!(std::fs::read(&b).unwrap(), b"b");
    }
}
