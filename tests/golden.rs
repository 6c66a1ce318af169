//! Golden images: the bundled scene rendered at a fixed seed must equal the committed
//! images bit for bit. A mismatch writes `<view>.new.exr` beside the golden and prints the
//! update command; a missing golden is a failure. Goldens change only through
//! `RELUME_UPDATE_GOLDEN=1 cargo test --test golden`, and the commit says why.

#[path = "common/mod.rs"]
mod common;

use common::{path_str, relume_ok, workspace};
use relume::images::read_image;

const VIEWS: [&str; 6] = ["px", "nx", "py", "ny", "pz", "nz"];

#[test]
fn cornell_matches_the_golden_images_bit_for_bit() {
    let root = workspace();
    let golden_dir = root.join("tests/golden/cornell");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("render");
    relume_ok(
        tmp.path(),
        &[
            "render",
            path_str(&root.join("scenes/cornell/scene.toml")),
            "--materials",
            path_str(&root.join("scenes/cornell/materials.toml")),
            "--out",
            path_str(&out),
            "--spp",
            "8",
            "--seed",
            "7",
        ],
    );
    let update = std::env::var_os("RELUME_UPDATE_GOLDEN").is_some();
    let mut failures = Vec::new();
    for view in VIEWS {
        let rendered = out.join(format!("{view}.exr"));
        let golden = golden_dir.join(format!("{view}.exr"));
        if update {
            std::fs::create_dir_all(&golden_dir).unwrap();
            std::fs::copy(&rendered, &golden).unwrap();
            continue;
        }
        if !golden.exists() {
            failures.push(format!("missing golden {}", golden.display()));
            continue;
        }
        let a = read_image(&golden, 1.0).unwrap();
        let b = read_image(&rendered, 1.0).unwrap();
        let bits = |img: &relume::images::Image| -> Vec<u32> {
            img.pixels.iter().flatten().map(|v| v.to_bits()).collect()
        };
        if (a.width, a.height) != (b.width, b.height) || bits(&a) != bits(&b) {
            let new = golden_dir.join(format!("{view}.new.exr"));
            std::fs::copy(&rendered, &new).unwrap();
            failures.push(format!(
                "{view}: differs from {} (new image: {})",
                golden.display(),
                new.display()
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{}\nIf the change is intended, update with: RELUME_UPDATE_GOLDEN=1 cargo test --test golden\nand explain it in the commit.",
        failures.join("\n")
    );
}
