//! Inserting an object into a recovered scene, as the README's example does
//! (`scenes/cornell-insert/`): the inserted vase gets its material from a second materials
//! file, its pixels take that material's colour, the rest of the image barely changes, and a
//! group left with no material, or given two, is an input error that names it.

#[path = "common/mod.rs"]
mod common;

use std::path::{Path, PathBuf};

use common::{path_str, relume, relume_ok, workspace};
use relume::assemble::{self, MaterialSource};
use relume::images::{read_image, Image};
use relume_core::geometry::Surface;
use relume_core::render::pixel_surface;

/// Samples per pixel of the test renders: enough for means over hundreds of pixels.
const SPP: &str = "16";

fn example() -> PathBuf {
    workspace().join("scenes/cornell-insert")
}

/// The materials every render here starts from: the bundled scene's (the truth stands in
/// for a recovered materials.toml; both name every group of scenes/cornell/scene.toml).
fn room_materials() -> PathBuf {
    workspace().join("scenes/cornell/materials.toml")
}

/// Renders the `front` view of `scene` with `materials` into `out` and reads it back.
fn render_front(scene: &Path, materials: &[&Path], out: &Path) -> Image {
    let mut args = vec!["render", path_str(scene)];
    for m in materials {
        args.extend(["--materials", path_str(m)]);
    }
    args.extend(["--out", path_str(out), "--spp", SPP, "--view", "front"]);
    relume_ok(out.parent().unwrap(), &args);
    read_image(&out.join("front.exr"), 1.0).unwrap()
}

/// The group name seen by the whole footprint of each pixel of the `front` view (`None` on
/// silhouettes and lights), from the geometry alone.
fn front_labels(scene: &Path) -> Vec<Option<String>> {
    let mut owned = assemble::load_and_assemble(scene, MaterialSource::GeometryOnly).unwrap();
    let vi = owned.desc.views.iter().position(|v| v.name == "front");
    let view = owned.views[vi.expect("a view named front")];
    let names = owned.group_names.clone();
    let scene = owned.build().unwrap();
    let mut labels = Vec::new();
    for y in 0..view.height {
        for x in 0..view.width {
            labels.push(match pixel_surface(&scene, &view, x, y, 4) {
                Some(Surface::Group(g)) => Some(names[g as usize].clone()),
                _ => None,
            });
        }
    }
    labels
}

/// Per-channel mean over the pixels labelled `group`, and their count.
fn group_mean(img: &Image, labels: &[Option<String>], group: &str) -> ([f64; 3], usize) {
    let mut sum = [0.0f64; 3];
    let mut n = 0;
    for (p, l) in img.pixels.iter().zip(labels) {
        if l.as_deref() == Some(group) {
            for c in 0..3 {
                sum[c] += p[c] as f64;
            }
            n += 1;
        }
    }
    (sum.map(|s| s / n.max(1) as f64), n)
}

fn luminance(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// A materials file giving the vase alone a diffuse `color`.
fn vase_diffuse(dir: &Path, name: &str, color: [f64; 3]) -> PathBuf {
    let path = dir.join(name);
    let text = format!(
        "format = 1\n\n[[material]]\ngroup = \"vase\"\nmodel = \"diffuse\"\ncolor = [{}, {}, {}]\n",
        color[0], color[1], color[2]
    );
    std::fs::write(&path, text).unwrap();
    path
}

/// The README's before/after pair: the vase's pixels turn orange, the floor and the box
/// beside it darken, and the surfaces away from it keep their mean radiance (same seed, so
/// the paths that never meet the vase are the same in both renders).
#[test]
fn the_vase_appears_and_the_rest_of_the_room_stays() {
    let tmp = tempfile::tempdir().unwrap();
    let room = room_materials();
    let before = render_front(
        &example().join("before.toml"),
        &[&room],
        &tmp.path().join("before"),
    );
    let after = render_front(
        &example().join("insert.toml"),
        &[&room, &example().join("inserted-materials.toml")],
        &tmp.path().join("after"),
    );
    let labels = front_labels(&example().join("insert.toml"));

    let (vase_after, n_vase) = group_mean(&after, &labels, "vase");
    let (vase_before, _) = group_mean(&before, &labels, "vase");
    println!("vase: {n_vase} pixels, before {vase_before:?}, after {vase_after:?}");
    assert!(n_vase >= 500, "the vase covers only {n_vase} pure pixels");
    // The orange plastic: red well above green, green above blue; the floor it hides is
    // a much less saturated beige.
    assert!(
        vase_after[0] > 1.5 * vase_after[1] && vase_after[1] > 2.0 * vase_after[2],
        "vase pixels are not orange: {vase_after:?}"
    );
    let hidden_rb = vase_before[0] / vase_before[2];
    let vase_rb = vase_after[0] / vase_after[2];
    assert!(
        vase_rb > 2.0 * hidden_rb,
        "R/B of the vase {vase_rb:.2} vs the floor behind it {hidden_rb:.2}"
    );

    for group in [
        "floor",
        "box",
        "wall_red",
        "walls_white",
        "sphere",
        "mirror",
    ] {
        let (a, n) = group_mean(&before, &labels, group);
        let (b, _) = group_mean(&after, &labels, group);
        let rel = (luminance(b) - luminance(a)) / luminance(a);
        println!("{group:<12} {n:>6} pixels  {:+.3}%", 100.0 * rel);
        assert!(n >= 100, "{group}: only {n} pure pixels in the front view");
        match group {
            // The vase's shadow on the floor, and the floor light it keeps from the box.
            "floor" => assert!(rel < -0.01, "{group}: no shadow, {rel:+.4}"),
            "box" => assert!(rel < -0.005, "{group}: not darker, {rel:+.4}"),
            _ => assert!(rel.abs() < 0.005, "{group}: changed by {rel:+.4}"),
        }
    }
}

/// The vase's pixels take the colour of the material the second file gives it: a diffuse
/// colour `c` against grey `g` scales them by `c / g` per channel (up to the light the vase
/// sends back to itself via the room, a few per cent).
#[test]
fn the_inserted_material_sets_the_vase_colour() {
    let tmp = tempfile::tempdir().unwrap();
    let room = room_materials();
    let scene = example().join("insert.toml");
    let color = [0.85, 0.42, 0.1];
    let grey = 0.5;
    let c = vase_diffuse(tmp.path(), "c.toml", color);
    let g = vase_diffuse(tmp.path(), "g.toml", [grey; 3]);
    let with_c = render_front(&scene, &[&room, &c], &tmp.path().join("c"));
    let with_g = render_front(&scene, &[&room, &g], &tmp.path().join("g"));
    let labels = front_labels(&scene);
    let (mc, n) = group_mean(&with_c, &labels, "vase");
    let (mg, _) = group_mean(&with_g, &labels, "vase");
    for ch in 0..3 {
        let ratio = mc[ch] / mg[ch];
        let expected = color[ch] / grey;
        println!("channel {ch}: ratio {ratio:.4}, expected {expected:.4} ({n} pixels)");
        assert!(
            (ratio / expected - 1.0).abs() < 0.03,
            "channel {ch}: vase pixels scaled by {ratio:.4}, expected {expected:.4}"
        );
    }
}

/// Runs a render expected to fail with exit code 3 and no output; returns stderr.
fn fails(cwd: &Path, scene: &Path, materials: &[&Path]) -> String {
    let out = cwd.join("out");
    let mut args = vec!["render", path_str(scene)];
    for m in materials {
        args.extend(["--materials", path_str(m)]);
    }
    args.extend(["--out", path_str(&out), "--spp", "1"]);
    let run = relume(cwd, &args);
    let stderr = String::from_utf8_lossy(&run.stderr).to_string();
    assert_eq!(run.status.code(), Some(3), "exit code; stderr:\n{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!out.exists(), "output left behind; stderr:\n{stderr}");
    stderr
}

/// Forgetting the inserted object's file, or giving its group twice, is an input error that
/// names the group and the files; a group that recovery left out (unseen in the panorama) is
/// the same error, fixed by giving it a material in a file of one's own.
#[test]
fn a_group_with_no_material_or_two_is_an_input_error() {
    let tmp = tempfile::tempdir().unwrap();
    let room = room_materials();
    let scene = example().join("insert.toml");
    let vase = example().join("inserted-materials.toml");

    let err = fails(tmp.path(), &scene, &[&room]);
    // The line of the group's name in insert.toml.
    let vase_line = 1 + std::fs::read_to_string(&scene)
        .unwrap()
        .lines()
        .position(|l| l.trim() == "name = \"vase\"")
        .expect("insert.toml names the vase group");
    assert!(
        err.contains(&format!("insert.toml:{vase_line}"))
            && err.contains("group 'vase' has no material in")
            && err.contains("scenes/cornell/materials.toml"),
        "{err}"
    );

    let again = vase_diffuse(tmp.path(), "again.toml", [0.5; 3]);
    let err = fails(tmp.path(), &scene, &[&room, &vase, &again]);
    assert!(
        err.contains("again.toml:3")
            && err.contains("group 'vase' has two materials: here and at")
            && err.contains("inserted-materials.toml:5"),
        "{err}"
    );

    // A recovered materials.toml without the mirror (as when no pixel of it is seen).
    let text = std::fs::read_to_string(&room).unwrap();
    let start = text.find("[[material]]\ngroup = \"mirror\"").unwrap();
    let recovered = tmp.path().join("recovered.toml");
    std::fs::write(&recovered, &text[..start]).unwrap();
    let err = fails(tmp.path(), &scene, &[&recovered, &vase]);
    assert!(
        err.contains("group 'mirror' has no material in")
            && err.contains("recovered.toml")
            && err.contains("inserted-materials.toml"),
        "{err}"
    );
    let mirror = tmp.path().join("mirror.toml");
    std::fs::write(
        &mirror,
        "format = 1\n\n[[material]]\ngroup = \"mirror\"\nmodel = \"mirror\"\ncolor = [0.9, 0.9, 0.9]\n",
    )
    .unwrap();
    relume_ok(
        tmp.path(),
        &[
            "render",
            path_str(&scene),
            "--materials",
            path_str(&recovered),
            "--materials",
            path_str(&vase),
            "--materials",
            path_str(&mirror),
            "--out",
            path_str(&tmp.path().join("fixed")),
            "--spp",
            "1",
        ],
    );
    assert!(tmp.path().join("fixed/front.exr").is_file());
}
