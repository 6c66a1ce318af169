//! Helpers shared by the integration tests: run the real binary, find the shared
//! reference scenes, print both sides in full on failure.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The workspace root (this folder's parent).
pub fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// The shared reference folder: `$RELUME_SHARED`, or `../shared` beside the workspace.
/// A missing folder fails the test: CI always has it.
pub fn shared() -> PathBuf {
    let dir = std::env::var_os("RELUME_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| workspace().join("../shared"));
    assert!(
        dir.join("bench").is_dir(),
        "reference scenes not found at {} (set RELUME_SHARED)",
        dir.display()
    );
    dir
}

/// Runs `relume` with `args` in `cwd`.
pub fn relume(cwd: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_relume"))
        .args(args)
        .current_dir(cwd)
        .output()
        .expect("the relume binary runs")
}

/// Runs `relume` and fails the test, printing stdout and stderr, unless it succeeds.
pub fn relume_ok(cwd: &Path, args: &[&str]) -> Output {
    let out = relume(cwd, args);
    assert!(
        out.status.success(),
        "relume {args:?} failed ({:?})\n--- stdout\n{}\n--- stderr\n{}",
        out.status,
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

pub fn path_str(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Every file under `dir` (recursively), sorted; none when `dir` does not exist.
pub fn files_in(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                out.extend(files_in(&p));
            } else {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// Every file under `dir` with its bytes, sorted by path: a snapshot to show that a
/// refused run changed nothing.
pub fn files_and_bytes(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    files_in(dir)
        .into_iter()
        .map(|f| (f.clone(), std::fs::read(&f).unwrap()))
        .collect()
}

/// The bundled scene's files (scene.toml, geometry.obj, materials.toml, views/) copied to
/// `to`, for a test to break one of them.
pub fn copy_cornell(to: &Path) {
    let cornell = workspace().join("scenes/cornell");
    std::fs::create_dir_all(to.join("views")).unwrap();
    for file in ["scene.toml", "geometry.obj", "materials.toml"] {
        std::fs::copy(cornell.join(file), to.join(file)).unwrap();
    }
    for view in ["px", "nx", "py", "ny", "pz", "nz"] {
        let file = format!("views/{view}.exr");
        std::fs::copy(cornell.join(&file), to.join(&file)).unwrap();
    }
}

/// Numbers separated by commas or spaces (an OBJ vertex's, a scene.toml position's), each
/// moved by its entry of `offset`, joined by ", ".
pub fn shifted(numbers: &str, offset: [f64; 3]) -> String {
    let moved: Vec<String> = numbers
        .split([',', ' '])
        .filter(|n| !n.is_empty())
        .zip(offset)
        .map(|(n, d)| format!("{:?}", n.parse::<f64>().unwrap() + d))
        .collect();
    moved.join(", ")
}

/// An OBJ's text with every vertex moved by `offset`.
pub fn shifted_obj(obj: &str, offset: [f64; 3]) -> String {
    let lines: Vec<String> = obj
        .lines()
        .map(|l| match l.strip_prefix("v ") {
            Some(xyz) => format!("v {}", shifted(xyz, offset).replace(',', "")),
            None => l.to_string(),
        })
        .collect();
    lines.join("\n")
}
