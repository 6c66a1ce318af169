//! Output folders: made with an error that names the one that could not be, refused when
//! a file is in the way or no file can be made in them, and cleared of the temp files of
//! runs killed outright.

use std::fs::File;
use std::path::Path;

use crate::error::Error;

/// Creates `dir` and its parents.
pub fn create_dir(dir: &Path) -> Result<(), Error> {
    refuse_file_in_the_way(dir)?;
    make_folders(dir)
}

/// `create_dir_all`, whose error names the folder that could not be made: the outermost
/// missing one, where `create_dir_all` named the innermost asked for (`--out /proc/x`
/// read "/proc/x/views: No such file or directory", of a folder the user never named).
pub(super) fn make_folders(dir: &Path) -> Result<(), Error> {
    let Err(e) = std::fs::create_dir_all(dir) else {
        return Ok(());
    };
    match missing_folders(dir).last() {
        Some(d) if d != dir => {
            let why = std::io::Error::new(
                e.kind(),
                format!(
                    "cannot make this folder ({e}), where {} would go",
                    dir.display()
                ),
            );
            Err(Error::io(d, why))
        }
        _ => Err(Error::io(dir, e)),
    }
}

/// `dir` and those of its parents that do not exist yet, innermost first.
pub(super) fn missing_folders(dir: &Path) -> impl Iterator<Item = &Path> {
    dir.ancestors()
        .take_while(|d| !d.as_os_str().is_empty() && std::fs::symlink_metadata(d).is_err())
}

/// Removes the temp files `.<name>.tmp-<pid>` in `dir` that a run killed outright (no
/// chance to clean up: SIGKILL, a power cut) left, where `/proc` tells its process is gone.
/// A live run's, or any where that cannot be told, are left alone.
pub(super) fn remove_temp_files_of_dead_runs(dir: &Path, name: &str) {
    let proc_fs = Path::new("/proc/self");
    if !proc_fs.exists() {
        return;
    }
    let prefix = format!(".{name}.tmp-");
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let file_name = entry.file_name();
        let Some(pid) = file_name
            .to_str()
            .and_then(|f| f.strip_prefix(&prefix))
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if pid != std::process::id() && !Path::new("/proc").join(pid.to_string()).exists() {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// An error when no file can be made in the folder `dir` (no write permission, a
/// read-only mount): found by making one and removing it, before the work, where `render`
/// into a folder it could not write to failed after its first view.
pub(super) fn refuse_unwritable(dir: &Path) -> Result<(), Error> {
    let probe = dir.join(format!(".relume-probe-{}", std::process::id()));
    File::create(&probe).map_err(|e| Error::io(dir, e))?;
    std::fs::remove_file(&probe).map_err(|e| Error::io(&probe, e))
}

/// An error when the nearest existing one of `dir` and its parents is not a folder: an
/// `--out` naming a file gave the system's bare "File exists" or "Not a directory".
pub(super) fn refuse_file_in_the_way(dir: &Path) -> Result<(), Error> {
    // A link to nothing is neither a folder to go into nor one to make: it read "File
    // exists (os error 17)", and sent the user looking for a file that is not there.
    let dangling = dir
        .ancestors()
        .filter(|d| !d.as_os_str().is_empty())
        .find(|d| std::fs::symlink_metadata(d).is_ok_and(|m| m.is_symlink()) && !d.exists());
    if let Some(link) = dangling {
        let target = std::fs::read_link(link).unwrap_or_default();
        return Err(Error::input(
            link,
            format!(
                "is a link to {}, which does not exist: outputs (--out) go into a folder",
                target.display()
            ),
        ));
    }
    let existing = dir
        .ancestors()
        .filter(|d| !d.as_os_str().is_empty())
        .find_map(|d| Some((d, std::fs::metadata(d).ok()?)));
    match existing {
        Some((d, meta)) if !meta.is_dir() => Err(Error::input(
            d,
            "is a file, not a folder: outputs (--out) go into a folder",
        )),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fsutil::{write_atomic, OutputSet};

    /// A folder that cannot be made is the one the error names, not the deepest one asked
    /// for: a name longer than a file system takes stands in for a place where no folder
    /// can be made (root makes folders anywhere else).
    #[test]
    fn the_error_names_the_folder_that_could_not_be_made() {
        let dir = tempfile::tempdir().unwrap();
        let too_long = dir.path().join("x".repeat(300));
        let views = too_long.join("views");
        for e in [
            OutputSet::default().create_dir(&views).unwrap_err(),
            create_dir(&views).unwrap_err(),
        ] {
            let Error::Io { file, source } = &e else {
                panic!("{e}");
            };
            assert_eq!(file, &too_long, "{e}");
            assert!(
                source.to_string().contains("cannot make this folder"),
                "{e}"
            );
            assert!(e.to_string().contains(&views.display().to_string()), "{e}");
        }
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
        // A missing folder the error is about is the one asked for: named as before.
        let e = create_dir(&too_long).unwrap_err();
        assert!(
            matches!(&e, Error::Io { file, .. } if file == &too_long),
            "{e}"
        );
        assert!(!e.to_string().contains("cannot make this folder"), "{e}");
    }

    /// A folder where no file can be made is refused when the set makes it, before the
    /// work; /proc, where even root makes no file, stands in for a folder without write
    /// permission or on a read-only mount.
    #[test]
    fn a_folder_no_file_can_be_made_in_is_refused_at_once() {
        let proc_self = Path::new("/proc/self");
        if !proc_self.is_dir() {
            return; // not Linux
        }
        let e = OutputSet::default().create_dir(proc_self).unwrap_err();
        assert!(matches!(e, Error::Io { .. }), "{e}");
        assert!(e.to_string().starts_with("/proc/self"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        OutputSet::default().create_dir(dir.path()).unwrap();
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }

    /// A run killed outright left its temp file; the next run that writes the same file
    /// removes it, and leaves a live run's alone.
    #[test]
    fn a_killed_runs_temp_file_goes_with_the_next_write() {
        if !Path::new("/proc/self").exists() {
            return;
        }
        let dir = tempfile::tempdir().unwrap();
        // No process has pid 4194304 or above (Linux's largest pid is 2^22).
        let dead = dir.path().join(".px.exr.tmp-4194305");
        let live = dir.path().join(".px.exr.tmp-1");
        let other = dir.path().join(".nx.exr.tmp-4194305");
        for f in [&dead, &live, &other] {
            std::fs::write(f, "partial").unwrap();
        }
        write_atomic(&dir.path().join("px.exr"), b"px").unwrap();
        assert!(!dead.exists());
        assert!(live.exists() && other.exists());
    }

    #[cfg(unix)]
    #[test]
    fn an_output_folder_that_is_a_link_to_nothing_is_named_as_such() {
        let dir = tempfile::tempdir().unwrap();
        let link = dir.path().join("dang");
        std::os::unix::fs::symlink(dir.path().join("gone"), &link).unwrap();
        for target in [link.clone(), link.join("views")] {
            let e = OutputSet::default().create_dir(&target).unwrap_err();
            assert!(matches!(e, Error::Input { .. }), "{e}");
            assert!(e.to_string().contains("dang: is a link to"), "{e}");
            assert!(e.to_string().contains("gone, which does not exist"), "{e}");
        }
        assert!(!dir.path().join("gone").exists());
    }

    #[test]
    fn an_output_folder_that_is_a_file_is_named_as_such_before_any_write() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("afile");
        std::fs::write(&file, b"keep").unwrap();
        let set = OutputSet::default();
        for target in [file.join("px.exr"), file.join("views/px.exr")] {
            let e = set.check_target(&target).unwrap_err();
            assert_eq!(e.exit_code(), 3, "{e}");
            assert!(
                e.to_string().contains("afile: is a file, not a folder"),
                "{e}"
            );
        }
        let e = create_dir(&file.join("views")).unwrap_err();
        assert!(e.to_string().contains("is a file, not a folder"), "{e}");
        assert!(OutputSet::default().create_dir(&file).is_err());
        assert_eq!(std::fs::read(&file).unwrap(), b"keep");
        // A folder, present or not yet made, is fine.
        assert!(set.check_target(&dir.path().join("new/px.exr")).is_ok());
        assert!(set.check_target(&dir.path().join("px.exr")).is_ok());
    }
}
