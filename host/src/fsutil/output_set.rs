//! An [`OutputSet`]: files written together, each to a synced temp file beside its target,
//! then renamed into place at the commit or removed with the set; never over one of the
//! run's inputs.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use super::folders::{
    make_folders, missing_folders, refuse_file_in_the_way, refuse_unwritable,
    remove_temp_files_of_dead_runs,
};
use super::locks::lock_folders;
use super::paths::{entries_on_the_way, folder_of, resolved};
use super::staged::staged;
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
    /// The folders [`OutputSet::create_dir`] created, parents first.
    dirs: Vec<PathBuf>,
    /// Files the run reads (canonical path, what each is), which no output may replace.
    inputs: Vec<(PathBuf, String)>,
    /// Earlier outputs that this set's files make stale, removed at its commit.
    stale: Vec<PathBuf>,
    /// Folders whose files of these extensions that the set does not write are stale,
    /// found at the commit ([`OutputSet::remove_unwritten_on_commit`]).
    unwritten_in: Vec<(PathBuf, &'static [&'static str])>,
}

impl OutputSet {
    /// A set that refuses to replace any of `inputs`, the files its run reads (path, and
    /// what it is, for the error). An output folder is easily the input's own: a recovery
    /// written into its scene's folder put its re-rendered views over the panorama.
    pub fn keeping(inputs: Vec<(PathBuf, String)>) -> OutputSet {
        OutputSet {
            staged: Vec::new(),
            dirs: Vec::new(),
            stale: Vec::new(),
            unwritten_in: Vec::new(),
            inputs: inputs
                .into_iter()
                .flat_map(|(path, what)| {
                    let entries = entries_on_the_way(&path);
                    entries.into_iter().map(move |entry| (entry, what.clone()))
                })
                .collect(),
        }
    }

    /// An error when a file written at `path` would replace one of the set's inputs. Every
    /// file added is checked; a command calls this before its work for the files it will
    /// write, so that it fails at once rather than at the end.
    pub fn check_target(&self, path: &Path) -> Result<(), Error> {
        // `--json out/` names a folder: its write failed ("Not a directory") after the work.
        if path.as_os_str().as_encoded_bytes().ends_with(b"/") || path.file_name().is_none() {
            return Err(Error::io(
                path,
                std::io::Error::other("names a folder (it ends in '/'), not a file: name a file"),
            ));
        }
        refuse_file_in_the_way(folder_of(path))?;
        // As the commit would find it, but before the work (a `--json` naming a folder
        // was refused after the whole comparison or bench).
        if std::fs::symlink_metadata(path).is_ok_and(|m| m.is_dir()) {
            return Err(Error::io(
                path,
                std::io::Error::other("a folder is in the way of this output file"),
            ));
        }
        // An output is renamed into place: `--json /dev/stdout` or `/dev/null` replaced
        // the device's entry (run as root) or failed after the work, and a pipe or socket
        // was replaced by a file no reader of it sees.
        if std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
            return Err(Error::io(
                path,
                std::io::Error::other(
                    "is a device, a pipe or a socket, not a file: outputs are written beside their name and renamed into place, which would replace it; name a file",
                ),
            ));
        }
        let Some(target) = resolved(path) else {
            return Ok(()); // a folder not made yet holds no input
        };
        match self.inputs.iter().find(|(input, _)| *input == target) {
            Some((_, what)) => Err(Error::input(
                path,
                format!("this output would replace {what}, an input of this run: write to another folder"),
            )),
            None => Ok(()),
        }
    }

    /// [`OutputSet::check_target`] for each of `paths`.
    pub fn check_targets(&self, paths: impl IntoIterator<Item = PathBuf>) -> Result<(), Error> {
        paths.into_iter().try_for_each(|p| self.check_target(&p))
    }

    /// Writes `bytes` to a synced temp file beside `path`; a path added twice keeps the
    /// later bytes.
    pub fn add(&mut self, path: &Path, bytes: &[u8]) -> Result<(), Error> {
        self.add_written(path, |file| {
            file.write_all(bytes).map_err(|e| Error::io(path, e))
        })
    }

    /// Like [`OutputSet::add`], with the file's content written by `write` straight into
    /// the (buffered) temp file: a large image need not be held in memory a second time as
    /// its encoded bytes.
    pub fn add_written(
        &mut self,
        path: &Path,
        write: impl FnOnce(&mut BufWriter<File>) -> Result<(), Error>,
    ) -> Result<(), Error> {
        let dir = folder_of(path);
        self.check_target(path)?;
        // A `--json` into a folder not made yet: made as `--out`'s is (and removed again
        // if the run fails), where the write failed after the whole comparison or bench.
        if std::fs::symlink_metadata(dir).is_err() {
            self.create_dir(dir)?;
        }
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("out");
        remove_temp_files_of_dead_runs(dir, name);
        let tmp = dir.join(format!(".{name}.tmp-{}", std::process::id()));
        // Registered and created under the lock; written outside it, so that an interrupt
        // does not wait for a long encode: it removes the file (the writer goes on into
        // an unlinked file until the process exits).
        let created = {
            let mut registry = staged();
            if !registry.files.contains(&tmp) {
                registry.files.push(tmp.clone());
            }
            File::create(&tmp).map_err(|e| Error::io(path, e))
        };
        let written = created.and_then(|file| {
            let mut file = BufWriter::new(file);
            write(&mut file)?;
            let file = file
                .into_inner()
                .map_err(|e| Error::io(path, e.into_error()))?;
            file.sync_all().map_err(|e| Error::io(path, e))
        });
        if let Err(e) = written {
            // A path this set staged before lost its earlier content with the file.
            staged().remove_file(&tmp);
            self.staged.retain(|(t, _)| *t != tmp);
            return Err(e);
        }
        if !self.staged.iter().any(|(t, _)| *t == tmp) {
            self.staged.push((tmp, path.to_path_buf()));
        }
        Ok(())
    }

    /// Whether a file for `path` is staged in this set.
    pub fn stages(&self, path: &Path) -> bool {
        self.staged.iter().any(|(_, target)| target == path)
    }

    /// Removes the file at `path` when the set commits (an earlier run's output that this
    /// one does not write again, so that a folder never mixes two runs); not if the set
    /// fails. An input of the run is refused, as for a file written.
    pub fn remove_on_commit(&mut self, path: &Path) -> Result<(), Error> {
        self.check_target(path)?;
        self.stale.push(path.to_path_buf());
        Ok(())
    }

    /// Removes, when the set commits, the files of folder `dir` with one of `extensions`
    /// that the set does not write (an earlier run's renders of views this one lacks, its
    /// maps of groups this one did not map), other than the run's inputs. They are found
    /// at the commit, under its lock: found before it, another run's commit in between
    /// could leave its files beside this set.
    pub fn remove_unwritten_on_commit(&mut self, dir: &Path, extensions: &'static [&'static str]) {
        self.unwritten_in.push((dir.to_path_buf(), extensions));
    }

    /// The files of `dir` with one of `extensions` that the set does not write, and that
    /// are no input of the run, in name order.
    fn unwritten_files(&self, dir: &Path, extensions: &[&str]) -> Vec<PathBuf> {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return Vec::new();
        };
        let mut found: Vec<PathBuf> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|p| {
                p.extension()
                    .and_then(|e| e.to_str())
                    .is_some_and(|e| extensions.contains(&e))
            })
            // An input of this run (a panorama kept there under other names) stays.
            .filter(|p| p.is_file() && !self.stages(p) && self.check_target(p).is_ok())
            .collect();
        found.sort();
        found
    }

    /// Renames every file into place, then removes the stale ones. A target that a file
    /// cannot replace (a folder) is found before the first rename, so that case too leaves
    /// no part of the set.
    pub fn commit(mut self) -> Result<(), Error> {
        let folders = (self.staged.iter().map(|(_, target)| folder_of(target)))
            .chain(self.unwritten_in.iter().map(|(dir, _)| dir.as_path()));
        let _locks = lock_folders(folders);
        let unwritten: Vec<PathBuf> = (self.unwritten_in.iter())
            .flat_map(|(dir, extensions)| self.unwritten_files(dir, extensions))
            .collect();
        self.stale.extend(unwritten);
        for (_, target) in &self.staged {
            if std::fs::symlink_metadata(target).is_ok_and(|m| m.is_dir()) {
                return Err(Error::io(
                    target,
                    std::io::Error::other("a folder is in the way of this output file"),
                ));
            }
        }
        let mut registry = staged();
        let staged = std::mem::take(&mut self.staged);
        for (i, (tmp, target)) in staged.iter().enumerate() {
            if let Err(e) = std::fs::rename(tmp, target) {
                // This file and the ones not yet renamed are not outputs (and `Drop`
                // removes the set's folders that are left empty).
                for (rest, _) in &staged[i..] {
                    registry.remove_file(rest);
                }
                return Err(Error::io(target, e));
            }
            registry.files.retain(|t| t != tmp);
        }
        for dir in std::mem::take(&mut self.dirs) {
            registry.forget_dir(&dir);
        }
        drop(registry);
        for path in std::mem::take(&mut self.stale) {
            match std::fs::remove_file(&path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                    return Err(Error::io(&path, e))
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Creates the folder `dir` (and its missing parents) for files of this set. The
    /// folders it creates are removed again, if empty, when the set is dropped without
    /// its commit or the run is interrupted: a failed run leaves no empty output folder.
    pub fn create_dir(&mut self, dir: &Path) -> Result<(), Error> {
        let mut missing: Vec<PathBuf> = missing_folders(dir).map(Path::to_path_buf).collect();
        missing.reverse();
        refuse_file_in_the_way(dir)?;
        {
            let mut registry = staged();
            registry.dirs.extend(missing.iter().cloned());
            self.dirs.extend(missing);
            make_folders(dir)?;
        }
        refuse_unwritable(dir)
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        let mut registry = staged();
        for (tmp, _) in &self.staged {
            registry.remove_file(tmp);
        }
        registry.remove_dirs(&self.dirs);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
        // A folder where b.txt should go: found when b.txt is added (as a command checks
        // its targets before its work), and at the commit where it appeared since, in
        // either case before a.txt is replaced.
        std::fs::create_dir(&b).unwrap();
        let mut set = OutputSet::default();
        set.add(&a, b"new a").unwrap();
        let e = set.add(&b, b"new b").unwrap_err().to_string();
        assert!(e.contains("b.txt") && e.contains("folder"), "{e}");
        drop(set);
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
        std::fs::remove_dir(&b).unwrap();
        let mut set = OutputSet::default();
        set.add(&a, b"new a").unwrap();
        set.add(&b, b"new b").unwrap();
        std::fs::create_dir(&b).unwrap();
        let e = set.commit().unwrap_err().to_string();
        assert!(e.contains("b.txt") && e.contains("folder"), "{e}");
        assert_eq!(std::fs::read_to_string(&a).unwrap(), "old a");
        // An error while adding: the set is dropped, its temp files go with it.
        let mut set = OutputSet::default();
        set.add(&a, b"new a").unwrap();
        assert!(set.add(&a.join("c.txt"), b"c").is_err());
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
    fn a_writer_that_fails_midway_leaves_no_temp_file() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.exr");
        let mut set = OutputSet::default();
        set.add_written(&a, |file| {
            file.write_all(b"the first half").unwrap();
            Err(Error::input(&a, "cannot encode"))
        })
        .expect_err("the writer's error");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        let tmp_of_a = |t: &Path| t.starts_with(dir.path());
        assert_eq!(
            staged().remove_matching(tmp_of_a),
            0,
            "nothing left registered"
        );
        // A writer that succeeds: the same bytes as `add`.
        set.add_written(&a, |file| {
            file.write_all(b"whole").map_err(|e| Error::io(&a, e))
        })
        .unwrap();
        set.commit().unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"whole");
    }

    /// A socket stands in for a device (`--json /dev/null`), which a test run as root
    /// would replace were the check missing.
    #[test]
    fn an_output_that_is_a_device_pipe_or_socket_is_refused_before_the_work() {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().unwrap();
        let socket = dir.path().join("out.json");
        let _listener = std::os::unix::net::UnixListener::bind(&socket).unwrap();
        let link = dir.path().join("link.json");
        std::os::unix::fs::symlink(&socket, &link).unwrap();
        let mut set = OutputSet::keeping(Vec::new());
        for path in [&socket, &link] {
            let e = set.check_target(path).unwrap_err();
            assert_eq!(e.exit_code(), 4, "{e}");
            assert!(
                e.to_string()
                    .contains("is a device, a pipe or a socket, not a file"),
                "{e}"
            );
            assert!(set.add(path, b"{}").is_err());
        }
        assert!(std::fs::symlink_metadata(&socket)
            .unwrap()
            .file_type()
            .is_socket());
        assert!(std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        set.check_target(&dir.path().join("new.json")).unwrap();
    }

    /// A path that ends in '/' names a folder: refused before the work, where the write
    /// failed after it with "Not a directory".
    #[test]
    fn an_output_named_as_a_folder_is_refused_before_the_work() {
        let dir = tempfile::tempdir().unwrap();
        let set = OutputSet::keeping(Vec::new());
        let slash = PathBuf::from(format!("{}/", dir.path().join("nothere").display()));
        for path in [slash, dir.path().join("..")] {
            let e = set.check_target(&path).unwrap_err();
            assert_eq!(e.exit_code(), 4, "{e}");
            assert!(e.to_string().contains("names a folder"), "{e}");
        }
        set.check_target(&dir.path().join("nothere")).unwrap();
    }

    #[test]
    fn stale_files_go_only_when_the_set_commits() {
        let dir = tempfile::tempdir().unwrap();
        let (old, new) = (dir.path().join("old.exr"), dir.path().join("new.exr"));
        std::fs::write(&old, b"earlier run").unwrap();
        let mut failed = OutputSet::default();
        failed.add(&new, b"this run").unwrap();
        failed.remove_on_commit(&old).unwrap();
        assert!(failed.stages(&new) && !failed.stages(&old));
        drop(failed);
        assert!(
            old.exists() && !new.exists(),
            "a set that fails removes nothing"
        );
        let mut set = OutputSet::default();
        set.add(&new, b"this run").unwrap();
        set.remove_on_commit(&old).unwrap();
        set.remove_on_commit(&dir.path().join("never-there.exr"))
            .unwrap();
        set.commit().unwrap();
        assert!(!old.exists() && new.exists());
        // An input is not removed.
        std::fs::write(&old, b"input").unwrap();
        let mut keeping = OutputSet::keeping(vec![(old.clone(), "an input".into())]);
        assert!(keeping.remove_on_commit(&old).is_err());
    }

    #[test]
    fn the_folders_a_set_creates_go_with_it_unless_it_commits() {
        let dir = tempfile::tempdir().unwrap();
        let (out, views) = (dir.path().join("out"), dir.path().join("out/views"));
        let entries = |d: &Path| std::fs::read_dir(d).unwrap().count();
        // Dropped: the file and both folders go.
        let mut set = OutputSet::default();
        set.create_dir(&views).unwrap();
        set.add(&views.join("px.exr"), b"px").unwrap();
        drop(set);
        assert!(!out.exists());
        // Interrupted: the same, through the registry.
        let mut set = OutputSet::default();
        set.create_dir(&views).unwrap();
        set.add(&views.join("px.exr"), b"px").unwrap();
        assert_eq!(staged().remove_matching(|p| p.starts_with(dir.path())), 1);
        assert!(!out.exists());
        drop(set);
        // Committed: the folders stay, and a later failed set leaves them.
        let mut set = OutputSet::default();
        set.create_dir(&views).unwrap();
        set.add(&views.join("px.exr"), b"px").unwrap();
        set.commit().unwrap();
        let mut set = OutputSet::default();
        set.create_dir(&views).unwrap();
        set.create_dir(&out.join("errors")).unwrap();
        set.add(&views.join("nx.exr"), b"nx").unwrap();
        drop(set);
        assert_eq!(std::fs::read(views.join("px.exr")).unwrap(), b"px");
        assert_eq!((entries(&out), entries(&views)), (1, 1));
        // A folder the set created holds a file of someone else's: it stays.
        let mut set = OutputSet::default();
        set.create_dir(&out.join("maps")).unwrap();
        std::fs::write(out.join("maps/mine.txt"), "mine").unwrap();
        drop(set);
        assert!(out.join("maps/mine.txt").exists());
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
        assert_eq!(staged().remove_matching(|p| p.starts_with(dir.path())), 0);
    }

    #[test]
    fn a_file_into_a_folder_not_made_yet_makes_it_unless_the_set_fails() {
        // A `--json no/such/a.json` failed with "No such file or directory" only when it
        // was written, after the work.
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("no/such/a.txt");
        write_atomic(&p, b"x").unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"x");
        // A set that fails takes the folders it made with it.
        let q = dir.path().join("not/yet/b.txt");
        let mut set = OutputSet::default();
        set.add(&q, b"y").unwrap();
        assert!(dir.path().join("not/yet").is_dir());
        drop(set);
        assert!(!dir.path().join("not").exists());
        // A file in the way of the folder is still named as such.
        std::fs::write(dir.path().join("file"), "f").unwrap();
        let e = write_atomic(&dir.path().join("file/c.txt"), b"z").unwrap_err();
        assert!(e.to_string().contains("file"), "{e}");
    }
}
