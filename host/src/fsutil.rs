//! Writing results atomically: a temp file in the same folder, then a rename, so a reader
//! never sees a partial or corrupted output file; and reading text inputs with errors that
//! say where they are not text.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

use crate::error::Error;

/// What the [`OutputSet`]s not yet committed or dropped have put on disk, so that an
/// interrupted run can remove it ([`remove_staged_files_on_interrupt`]). Sets hold the
/// lock while they register and create a temp file or folder and while they commit, so an
/// interrupt never sees a file half registered nor a set half renamed.
struct Staged {
    /// Temp files.
    files: Vec<PathBuf>,
    /// Folders the sets created for their files, parents before children.
    dirs: Vec<PathBuf>,
}

static STAGED: Mutex<Staged> = Mutex::new(Staged {
    files: Vec::new(),
    dirs: Vec::new(),
});

fn staged() -> MutexGuard<'static, Staged> {
    // A panic while the lock was held leaves the lists as they were: still what to remove.
    STAGED.lock().unwrap_or_else(|e| e.into_inner())
}

impl Staged {
    /// Removes the temp file `tmp` and forgets it.
    fn remove_file(&mut self, tmp: &Path) {
        let _ = std::fs::remove_file(tmp);
        self.files.retain(|t| t != tmp);
    }

    /// Removes the folders of `dirs` (a set's, parents first) that are empty, children
    /// first, and forgets them all. A folder that holds anything else stays.
    fn remove_dirs(&mut self, dirs: &[PathBuf]) {
        for dir in dirs.iter().rev() {
            let _ = std::fs::remove_dir(dir);
            self.forget_dir(dir);
        }
    }

    /// Removes the temp files of live output sets that `matching` selects (all of them on
    /// an interrupt), then the folders they created that `matching` selects and are left
    /// empty; returns how many files. The sets' own `Drop` then finds nothing to remove.
    fn remove_matching(&mut self, matching: impl Fn(&Path) -> bool) -> usize {
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

    fn forget_dir(&mut self, dir: &Path) {
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

/// Exclusive locks on each of `folders` (resolved, each once, in one order), released when
/// the files are dropped. Two runs into one `--out` each commit under them, so that their
/// commits follow one another and the folder holds one run's whole set, where their
/// renames interleaved and left views of both. A folder that cannot be locked (a file
/// system without locks) is committed into unlocked, as before.
fn lock_folders<'a>(folders: impl Iterator<Item = &'a Path>) -> Vec<File> {
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

/// `path` with its folder resolved (links, `..`), not the file itself: what a rename onto
/// `path` replaces (a link there, not its target). `None` when the folder does not exist.
fn resolved(path: &Path) -> Option<PathBuf> {
    let name = path.file_name()?;
    std::fs::canonicalize(folder_of(path))
        .ok()
        .map(|d| d.join(name))
}

/// Every folder entry a read of `path` goes through, resolved as [`resolved`] does: the
/// entry `path` names and, where that is a symbolic link, the entries it leads to, down to
/// the file itself. A rename onto any of them would change what `path` reads; onto the
/// last it removes the input's content (an image given by a link into the output folder
/// was replaced by its re-render).
fn entries_on_the_way(path: &Path) -> Vec<PathBuf> {
    /// As the kernel's own limit on links followed in one lookup.
    const MAX_LINKS: usize = 40;
    let mut entries = Vec::new();
    let mut next = resolved(path);
    while let Some(entry) = next.take() {
        let link = std::fs::symlink_metadata(&entry).is_ok_and(|m| m.file_type().is_symlink());
        if link && entries.len() < MAX_LINKS {
            // A relative target is relative to the link's folder.
            next = std::fs::read_link(&entry)
                .ok()
                .and_then(|target| resolved(&folder_of(&entry).join(target)));
        }
        entries.push(entry);
    }
    entries
}

/// Whether `a` and `b` name the same file by any spelling (links, `..`): the file itself
/// resolved when both exist, else its folder as [`OutputSet::check_target`] resolves it
/// (an output not written yet). An input given twice would be counted twice, and two
/// outputs of one name would leave only the later.
pub fn same_file(a: &Path, b: &Path) -> bool {
    if let (Ok(ca), Ok(cb)) = (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
        return ca == cb || same_inode(a, b);
    }
    matches!((resolved(a), resolved(b)), (Some(a), Some(b)) if a == b)
}

/// Whether `a` and `b` are one file under two names (hard links): a materials file given
/// twice that way was read as two files that both give every group a material.
#[cfg(unix)]
fn same_inode(a: &Path, b: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
        _ => false,
    }
}

#[cfg(not(unix))]
fn same_inode(_: &Path, _: &Path) -> bool {
    false
}

/// The first of `paths` that names, by any spelling ([`same_file`]), a file an earlier
/// one names, with that earlier one: `(again, first)`. For the commands that take a list
/// of inputs, where one given twice would be counted twice.
pub fn given_twice(paths: &[PathBuf]) -> Option<(&PathBuf, &PathBuf)> {
    paths.iter().enumerate().find_map(|(i, again)| {
        paths[..i]
            .iter()
            .find(|first| same_file(first, again))
            .map(|first| (again, first))
    })
}

/// The folder a file at `path` is in (`.` for a bare file name).
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
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
    refuse_file_in_the_way(dir)?;
    make_folders(dir)
}

/// `create_dir_all`, whose error names the folder that could not be made: the outermost
/// missing one, where `create_dir_all` named the innermost asked for (`--out /proc/x`
/// read "/proc/x/views: No such file or directory", of a folder the user never named).
fn make_folders(dir: &Path) -> Result<(), Error> {
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
fn missing_folders(dir: &Path) -> impl Iterator<Item = &Path> {
    dir.ancestors()
        .take_while(|d| !d.as_os_str().is_empty() && std::fs::symlink_metadata(d).is_err())
}

/// Removes the temp files `.<name>.tmp-<pid>` in `dir` that a run killed outright (no
/// chance to clean up: SIGKILL, a power cut) left, where `/proc` tells its process is gone.
/// A live run's, or any where that cannot be told, are left alone.
fn remove_temp_files_of_dead_runs(dir: &Path, name: &str) {
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
fn refuse_unwritable(dir: &Path) -> Result<(), Error> {
    let probe = dir.join(format!(".relume-probe-{}", std::process::id()));
    File::create(&probe).map_err(|e| Error::io(dir, e))?;
    std::fs::remove_file(&probe).map_err(|e| Error::io(&probe, e))
}

/// An error when the nearest existing one of `dir` and its parents is not a folder: an
/// `--out` naming a file gave the system's bare "File exists" or "Not a directory".
fn refuse_file_in_the_way(dir: &Path) -> Result<(), Error> {
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
    }

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
    fn a_set_refuses_to_replace_an_input_by_any_path_to_it() {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("views").join("px.exr");
        std::fs::create_dir(input.parent().unwrap()).unwrap();
        std::fs::write(&input, b"panorama").unwrap();
        let mut set = OutputSet::keeping(vec![(input.clone(), "view 'px''s image".into())]);
        // The same file by another spelling of its folder.
        let other = dir
            .path()
            .join("views")
            .join("..")
            .join("views")
            .join("px.exr");
        let e = set.add(&other, b"render").unwrap_err().to_string();
        assert!(
            e.contains("would replace view 'px''s image, an input of this run"),
            "{e}"
        );
        assert!(e.contains("px.exr"), "{e}");
        assert_eq!(std::fs::read(&input).unwrap(), b"panorama");
        // Beside it, in a folder not made yet, and a set that keeps nothing: all fine.
        set.add(&dir.path().join("views").join("nx.exr"), b"render")
            .unwrap();
        set.check_target(&dir.path().join("new").join("px.exr"))
            .unwrap();
        set.commit().unwrap();
        let mut free = OutputSet::default();
        free.add(&input, b"render").unwrap();
        free.commit().unwrap();
        assert_eq!(std::fs::read(&input).unwrap(), b"render");
        let leftovers: Vec<_> = std::fs::read_dir(dir.path().join("views"))
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(leftovers.len(), 2, "{leftovers:?}");
    }

    #[cfg(unix)]
    #[test]
    fn a_set_refuses_to_replace_an_input_it_reaches_through_links() {
        use std::os::unix::fs::symlink;
        let dir = tempfile::tempdir().unwrap();
        let (views, out) = (dir.path().join("views"), dir.path().join("out"));
        std::fs::create_dir(&views).unwrap();
        std::fs::create_dir(&out).unwrap();
        // views/px.exr -> ../out/link.exr -> px.exr (out/px.exr, the file itself).
        let file = out.join("px.exr");
        std::fs::write(&file, b"panorama").unwrap();
        symlink("px.exr", out.join("link.exr")).unwrap();
        symlink("../out/link.exr", views.join("px.exr")).unwrap();
        let input = views.join("px.exr");
        let set = OutputSet::keeping(vec![(input.clone(), "view 'px''s image".into())]);
        for target in [&file, &out.join("link.exr"), &input] {
            let e = set.check_target(target).unwrap_err().to_string();
            assert!(e.contains("would replace view 'px''s image"), "{e}");
        }
        set.check_target(&out.join("nx.exr")).unwrap();
        // A link to the file as an output replaces the link, not the file: allowed, and
        // the input keeps its content.
        let mut beside = OutputSet::keeping(vec![(input.clone(), "view 'px''s image".into())]);
        symlink("px.exr", out.join("other.exr")).unwrap();
        beside.add(&out.join("other.exr"), b"render").unwrap();
        beside.commit().unwrap();
        assert_eq!(std::fs::read(&input).unwrap(), b"panorama");
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

    #[test]
    fn one_file_under_two_hard_links_is_the_same_file() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b, c) = (
            dir.path().join("a.toml"),
            dir.path().join("b.toml"),
            dir.path().join("c.toml"),
        );
        std::fs::write(&a, "x").unwrap();
        std::fs::write(&c, "x").unwrap();
        std::fs::hard_link(&a, &b).unwrap();
        assert!(same_file(&a, &b) && same_file(&a, &dir.path().join("./a.toml")));
        assert!(!same_file(&a, &c), "the same bytes are not the same file");
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
