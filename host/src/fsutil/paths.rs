//! Which file a path names: its folder, resolved as a rename onto it sees it, the entries a
//! read of it goes through, and whether two paths name one file.

use std::path::{Path, PathBuf};

/// `path` with its folder resolved (links, `..`), not the file itself: what a rename onto
/// `path` replaces (a link there, not its target). `None` when the folder does not exist.
pub(super) fn resolved(path: &Path) -> Option<PathBuf> {
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
pub(super) fn entries_on_the_way(path: &Path) -> Vec<PathBuf> {
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
/// resolved when both exist, else its folder as
/// [`OutputSet::check_target`](super::OutputSet::check_target) resolves it (an output not
/// written yet). An input given twice would be counted twice, and two outputs of one name
/// would leave only the later.
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
pub(super) fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fsutil::OutputSet;

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
}
