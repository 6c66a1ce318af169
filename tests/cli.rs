//! The real binary end to end: outputs, determinism across thread counts and seeds.

#[path = "common/mod.rs"]
mod common;

use std::path::Path;

use common::{path_str, relume, relume_ok, workspace};

fn render(cwd: &Path, out: &Path, threads: &str, seed: &str) {
    let root = workspace();
    relume_ok(
        cwd,
        &[
            "render",
            path_str(&root.join("scenes/cornell/scene.toml")),
            "--materials",
            path_str(&root.join("scenes/cornell/materials.toml")),
            "--out",
            path_str(out),
            "--spp",
            "4",
            "--seed",
            seed,
            "--threads",
            threads,
        ],
    );
}

#[test]
fn one_and_two_threads_give_identical_bytes() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("t1"), tmp.path().join("t2"));
    render(tmp.path(), &a, "1", "3");
    render(tmp.path(), &b, "2", "3");
    for view in ["px", "nx", "py", "ny", "pz", "nz"] {
        for ext in ["exr", "png"] {
            let name = format!("{view}.{ext}");
            let (x, y) = (
                std::fs::read(a.join(&name)).unwrap(),
                std::fs::read(b.join(&name)).unwrap(),
            );
            assert!(x == y, "{name} differs between 1 and 2 threads");
        }
    }
}

#[test]
fn another_seed_gives_another_image() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("s1"), tmp.path().join("s2"));
    render(tmp.path(), &a, "2", "1");
    render(tmp.path(), &b, "2", "2");
    let x = std::fs::read(a.join("px.exr")).unwrap();
    let y = std::fs::read(b.join("px.exr")).unwrap();
    assert_ne!(x, y, "the seed must change the Monte Carlo noise");
}

#[test]
fn render_writes_exr_png_and_summary_for_every_view() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    render(tmp.path(), &out, "2", "1");
    for view in ["px", "nx", "py", "ny", "pz", "nz"] {
        let img = relume::images::read_image(&out.join(format!("{view}.exr")), 1.0).unwrap();
        assert_eq!((img.width, img.height), (32, 32));
        assert!(img
            .pixels
            .iter()
            .flatten()
            .all(|v| v.is_finite() && *v >= 0.0));
        assert!(
            img.pixels.iter().flatten().any(|v| *v > 0.0),
            "{view} is black"
        );
        assert!(out.join(format!("{view}.png")).is_file());
    }
    let info: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("render.json")).unwrap()).unwrap();
    assert_eq!(info["spp"], 4);
    assert_eq!(info["samples"], 6 * 32 * 32 * 4);
    let mut views: Vec<&str> = info["views"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    views.sort();
    assert_eq!(views, ["nx", "ny", "nz", "px", "py", "pz"]);
    // Nothing but the outputs: no temp files left behind.
    let n = std::fs::read_dir(&out).unwrap().count();
    assert_eq!(n, 6 * 2 + 1);
}

#[test]
fn usage_errors_exit_with_code_2() {
    let tmp = tempfile::tempdir().unwrap();
    let out = relume(tmp.path(), &["render"]);
    assert_eq!(out.status.code(), Some(2));
    let out = relume(tmp.path(), &["frobnicate"]);
    assert_eq!(out.status.code(), Some(2));
}

/// `bench downsample` halves the panorama into a scene that loads and renders, and keeps
/// each view's mean radiance (a box average).
#[test]
fn downsample_makes_a_loadable_half_resolution_scene() {
    let root = workspace();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("half");
    relume_ok(
        tmp.path(),
        &[
            "bench",
            "downsample",
            path_str(&root.join("scenes/cornell/scene.toml")),
            "--factor",
            "2",
            "--out",
            path_str(&out),
        ],
    );
    let mean = |img: &relume::images::Image| -> f64 {
        img.pixels.iter().flatten().map(|&v| v as f64).sum::<f64>() / img.pixels.len() as f64
    };
    for view in ["px", "nx", "py", "ny", "pz", "nz"] {
        let full =
            relume::images::read_image(&root.join(format!("scenes/cornell/views/{view}.exr")), 1.0)
                .unwrap();
        let half = relume::images::read_image(&out.join(format!("views/{view}.exr")), 1.0).unwrap();
        assert_eq!((half.width, half.height), (full.width / 2, full.height / 2));
        let (a, b) = (mean(&full), mean(&half));
        assert!((a - b).abs() <= 1e-5 * a, "{view}: mean {a} became {b}");
    }
    relume_ok(
        tmp.path(),
        &[
            "render",
            path_str(&out.join("scene.toml")),
            "--materials",
            path_str(&root.join("scenes/cornell/materials.toml")),
            "--out",
            path_str(&tmp.path().join("render")),
            "--spp",
            "2",
        ],
    );
    let bad = relume(
        tmp.path(),
        &[
            "bench",
            "downsample",
            path_str(&root.join("scenes/cornell/scene.toml")),
            "--factor",
            "5",
            "--out",
            path_str(&tmp.path().join("bad")),
        ],
    );
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && err.contains("not a multiple of factor 5"),
        "{err}"
    );
}

/// A reader that closes the pipe before relume prints (`relume ... | head`) ends it as it
/// ends any Unix filter, by SIGPIPE, not by a panic on the broken pipe.
#[cfg(unix)]
#[test]
fn a_closed_stdout_ends_relume_quietly() {
    use std::os::unix::process::ExitStatusExt;
    use std::process::{Command, Stdio};
    let truth = workspace().join("scenes/cornell/materials.toml");
    // A copy: a file compared with itself is refused before anything is printed.
    let tmp = tempfile::tempdir().unwrap();
    let copy = tmp.path().join("materials.toml");
    std::fs::copy(&truth, &copy).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_relume"))
        .args(["compare", "materials", path_str(&truth), path_str(&copy)])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Closed before the process has started to print.
    drop(child.stdout.take());
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(
        output.status.success() || output.status.signal() == Some(libc::SIGPIPE),
        "{:?}",
        output.status
    );
}

/// `relume check` on the bundled scene, as it is and with its `px` face mirrored left to
/// right (a cube face in another convention): the pure pixels it counts are those recover
/// works on, the mirrored face is told, and nothing is written but the JSON asked for.
#[test]
fn check_counts_each_groups_pixels_and_tells_a_mirrored_view() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("cornell");
    common::copy_cornell(&scene);
    let scene_toml = scene.join("scene.toml");
    let before = common::files_and_bytes(&scene);

    let out = relume_ok(tmp.path(), &["check", path_str(&scene_toml)]);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(!stderr.contains("warning"), "{stderr}");
    assert!(stdout.contains("0 warnings"), "{stdout}");
    // The plate is seen by px alone, the mirror by py alone; ny and pz see too few
    // boundaries to be read.
    let row = |group: &str| -> Vec<u32> {
        let line = stdout
            .lines()
            .find(|l| l.split_whitespace().next() == Some(group))
            .unwrap_or_else(|| panic!("no row for {group}: {stdout}"));
        // The total and one count per view; the first diffuse colour follows.
        line.split_whitespace()
            .skip(2)
            .take(7)
            .map(|n| n.parse().unwrap())
            .collect()
    };
    let plate = row("plate");
    assert!(plate[0] > 0 && plate[0] == plate[1], "{plate:?}");
    assert!(plate[2..].iter().all(|&n| n == 0), "{plate:?}");
    for group in ["floor", "walls_white", "box", "mirror"] {
        let counts = row(group);
        assert_eq!(
            counts[0],
            counts[1..].iter().sum::<u32>(),
            "{group}: {counts:?}"
        );
    }
    // The groups under 256 pure pixels are named, each with its count from the table.
    let few: Vec<String> = [
        "floor",
        "ceiling",
        "wall_red",
        "wall_green",
        "walls_white",
        "box",
        "sphere",
        "plate",
        "mirror",
    ]
    .iter()
    .filter(|g| row(g)[0] < 256)
    .map(|g| format!("{g} {}", row(g)[0]))
    .collect();
    assert!(few.len() >= 3, "{few:?}");
    assert!(
        stdout.contains(&format!("few pixels: {} (fewer than 256", few.join(", "))),
        "{stdout}"
    );
    assert!(stdout.contains("calibration: light 'light' in view 'pz' reads 1.000 1.000 1.000"));
    assert!(
        stdout.contains("orientation: view 'ny' not read"),
        "{stdout}"
    );
    assert!(stdout.contains("orientation: view 'px' shows"), "{stdout}");

    // px mirrored left to right: told, naming the reading that undoes it.
    let px = scene.join("views/px.exr");
    let image = relume::images::read_image(&px, 1.0).unwrap();
    let w = image.width as usize;
    let mirrored = relume::images::Image {
        pixels: (0..image.pixels.len())
            .map(|i| image.pixels[i - i % w + (w - 1 - i % w)])
            .collect(),
        ..image
    };
    relume::images::write_exr(&px, &mirrored).unwrap();
    let json = tmp.path().join("check.json");
    let out = relume_ok(
        tmp.path(),
        &["check", path_str(&scene_toml), "--json", path_str(&json)],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    let told: Vec<&str> = stderr.lines().filter(|l| l.contains("warning")).collect();
    assert_eq!(told.len(), 1, "{stderr}");
    assert!(
        told[0].contains("view 'px'") && told[0].contains("far better mirrored left to right"),
        "{stderr}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["warnings"].as_array().unwrap().len(), 1);
    assert_eq!(report["groups"].as_array().unwrap().len(), 9);
    // Nothing but the JSON was written, and no input changed but the one the test wrote.
    let after = common::files_and_bytes(&scene);
    assert_eq!(before.len(), after.len());
    for ((path, a), (_, b)) in before.iter().zip(&after) {
        assert!(
            a == b || path.ends_with("views/px.exr"),
            "{}",
            path.display()
        );
    }
    assert_eq!(common::files_in(tmp.path()).len(), before.len() + 1);
}

/// `relume check`'s preview of stage 1: the bundled scene's diffuse groups read near their
/// true colours; with the light declared a tenth as bright, every group would need a colour
/// above white, and check says so (beside the calibration's reading of the light itself).
#[test]
fn check_reads_a_first_diffuse_colour_and_tells_a_light_too_dim_for_the_panorama() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("cornell");
    common::copy_cornell(&scene);
    let truth = relume::materials_file::load_materials(&scene.join("materials.toml"))
        .unwrap()
        .materials;
    let colour_of = |report: &serde_json::Value, group: &str| -> Vec<f64> {
        let g = report["groups"]
            .as_array()
            .unwrap()
            .iter()
            .find(|g| g["group"] == group)
            .unwrap();
        let c = g["preview_colour"].as_array().unwrap();
        c.iter().map(|v| v.as_f64().unwrap()).collect()
    };
    let check = |json: &str| -> (serde_json::Value, String) {
        let out = relume_ok(&scene, &["check", "scene.toml", "--json", json]);
        let report =
            serde_json::from_str(&std::fs::read_to_string(scene.join(json)).unwrap()).unwrap();
        (report, String::from_utf8_lossy(&out.stderr).into_owned())
    };
    let (report, stderr) = check("check.json");
    assert!(!stderr.contains("warning"), "{stderr}");
    for group in ["floor", "ceiling", "wall_red", "wall_green", "walls_white"] {
        let t = truth
            .iter()
            .find(|m| m.group == group)
            .unwrap()
            .color
            .unwrap();
        let c = colour_of(&report, group);
        for k in 0..3 {
            assert!(
                (c[k] / t[k] as f64 - 1.0).abs() < 0.1,
                "{group}: {c:?} against the truth {t:?}"
            );
        }
    }

    let text = std::fs::read_to_string(scene.join("scene.toml")).unwrap();
    let dim = text.replace(
        "radiance = [30.0, 28.0, 24.0]",
        "radiance = [3.0, 2.8, 2.4]",
    );
    assert_ne!(dim, text);
    std::fs::write(scene.join("scene.toml"), dim).unwrap();
    let (report, stderr) = check("dim.json");
    let told: Vec<&str> = stderr.lines().filter(|l| l.contains("warning")).collect();
    let brighter: Vec<&&str> = told
        .iter()
        .filter(|l| l.contains("brighter in the panorama than any diffuse colour renders"))
        .collect();
    assert_eq!(brighter.len(), 1, "{stderr}");
    for group in ["floor", "ceiling", "wall_red", "wall_green", "walls_white"] {
        assert!(brighter[0].contains(&format!("'{group}'")), "{stderr}");
        assert!(colour_of(&report, group).contains(&0.99), "{group}");
    }
    assert!(
        told.iter().any(|l| l.contains("light 'light'")),
        "the calibration tells it too: {stderr}"
    );
}

/// `relume panorama` against the bundled scene's own cube faces: they are laid out as an
/// equirectangular image here (each texel from the face its direction falls in, by the
/// views' definition in scene-format.md, not by the code under test), split back into
/// faces, and put in a scene in place of the originals. The faces that share the
/// originals' frame match them, and `relume check` reads the new scene the right way
/// round, its light at its declared radiance.
#[test]
fn a_panorama_split_into_faces_gives_back_the_cube_it_was_laid_out_from() {
    use glam::Vec3;
    let root = workspace();
    let cornell = root.join("scenes/cornell/scene.toml");
    let desc = relume::scene_file::load_scene(&cornell).unwrap();
    let faces: Vec<(Vec3, Vec3, Vec3, relume::images::Image)> = desc
        .views
        .iter()
        .map(|v| {
            let f = Vec3::from(v.direction).normalize();
            let r = f.cross(Vec3::from(v.up)).normalize();
            let image = relume::images::read_image(v.image.as_ref().unwrap(), 1.0).unwrap();
            (f, r, r.cross(f), image)
        })
        .collect();
    // Forward +X, up +Z: the right is -Y. Column 0 is straight behind, turning right.
    let (w, h) = (512u32, 256u32);
    let mut pixels = Vec::new();
    for j in 0..h {
        for i in 0..w {
            let azimuth = ((i as f64 + 0.5) / w as f64 - 0.5) * std::f64::consts::TAU;
            let elevation = (0.5 - (j as f64 + 0.5) / h as f64) * std::f64::consts::PI;
            let d = Vec3::new(
                (libm::cos(elevation) * libm::cos(azimuth)) as f32,
                (-libm::cos(elevation) * libm::sin(azimuth)) as f32,
                libm::sin(elevation) as f32,
            );
            let (f, r, u, image) = faces
                .iter()
                .max_by(|a, b| d.dot(a.0).total_cmp(&d.dot(b.0)))
                .unwrap();
            // x = (i + 0.5) / W - 0.5 along the right span 2 tan(45) = 2.
            let (sx, sy) = (d.dot(*r) / d.dot(*f) / 2.0, d.dot(*u) / d.dot(*f) / 2.0);
            let n = image.width as f32;
            let px = (((sx + 0.5) * n) as u32).min(image.width - 1);
            let py = (((0.5 - sy) * n) as u32).min(image.height - 1);
            pixels.push(image.pixels[(py * image.width + px) as usize]);
        }
    }
    let tmp = tempfile::tempdir().unwrap();
    let equirect = tmp.path().join("equirect.exr");
    relume::images::write_exr(
        &equirect,
        &relume::images::Image {
            width: w,
            height: h,
            pixels,
        },
    )
    .unwrap();
    let out = tmp.path().join("scene");
    let run = relume_ok(
        tmp.path(),
        &[
            "panorama",
            "split",
            path_str(&equirect),
            "--position",
            "1.5,0.9,1.3",
            "--size",
            "32",
            "--scene",
            path_str(&cornell),
            "--out",
            path_str(&out),
        ],
    );
    assert!(
        run.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );

    // The four faces about the up axis are the originals' frames under other names, and
    // come back as they were: each face pixel is the mean of the texels wholly inside it,
    // which were laid out from that one pixel.
    for (face, original) in [
        ("front", "px"),
        ("right", "ny"),
        ("back", "nx"),
        ("left", "py"),
    ] {
        let got = relume::images::read_image(&out.join(format!("views/{face}.exr")), 1.0).unwrap();
        let want = &faces[desc.views.iter().position(|v| v.name == original).unwrap()].3;
        for (i, (a, b)) in got.pixels.iter().zip(&want.pixels).enumerate() {
            let (a, b) = (Vec3::from(*a), Vec3::from(*b));
            assert!(
                (a - b).abs().max_element() <= 1e-5 * b.max_element().max(1.0),
                "{face} against {original}, pixel {i}: {a} against {b}"
            );
        }
    }

    // In a scene: the geometry, lights and groups of the bundled one, the new faces as its
    // views, written by split (--scene) and, as a user would, pasted from views.toml.
    let text = std::fs::read_to_string(&cornell).unwrap();
    let (head, rest) = text.split_at(text.find("[[view]]").unwrap());
    let tail = &rest[rest.find("[[light]]").unwrap()..];
    let views = std::fs::read_to_string(out.join("views.toml")).unwrap();
    assert_eq!(views.matches("[[view]]").count(), 6);
    std::fs::write(out.join("pasted.toml"), format!("{head}{views}\n{tail}")).unwrap();
    std::fs::copy(
        root.join("scenes/cornell/geometry.obj"),
        out.join("geometry.obj"),
    )
    .unwrap();
    let check = |scene: &str| {
        let run = relume_ok(tmp.path(), &["check", path_str(&out.join(scene))]);
        let stdout = String::from_utf8_lossy(&run.stdout).to_string();
        let stderr = String::from_utf8_lossy(&run.stderr).to_string();
        // All but the closing line, which has the time.
        let findings: Vec<String> = stdout
            .lines()
            .map(str::to_string)
            .filter(|l| !l.starts_with("checked in"))
            .collect();
        (stdout, stderr, findings)
    };
    let (stdout, stderr, findings) = check("scene.toml");
    assert_eq!(check("pasted.toml").2, findings);
    assert!(
        stderr.is_empty() && stdout.contains("0 warnings"),
        "{stdout}{stderr}"
    );
    assert!(
        stdout.contains("calibration: light 'light' in view 'up' reads"),
        "{stdout}"
    );
    for view in ["front", "right", "back", "left", "down"] {
        assert!(
            stdout.contains(&format!("orientation: view '{view}' shows"))
                || stdout.contains(&format!("orientation: view '{view}' not read")),
            "{stdout}"
        );
    }

    // And back: the faces joined into an equirectangular image of the first one's size
    // match it but where a texel spans the edge between two face pixels, which the first
    // image took from one of them and the joined one mixes: 90% of texels within 2%, 96%
    // within 5%.
    let joined = tmp.path().join("joined.exr");
    relume_ok(
        tmp.path(),
        &[
            "panorama",
            "join",
            path_str(&out.join("scene.toml")),
            path_str(&out.join("views")),
            "--out",
            path_str(&joined),
            "--width",
            "512",
        ],
    );
    let original = relume::images::read_image(&equirect, 1.0).unwrap();
    let back = relume::images::read_image(&joined, 1.0).unwrap();
    assert_eq!((back.width, back.height), (512, 256));
    let lum = |p: &[f32; 3]| (p[0] + p[1] + p[2]) as f64;
    let mean = |img: &relume::images::Image| {
        img.pixels.iter().map(lum).sum::<f64>() / img.pixels.len() as f64
    };
    assert!((mean(&back) / mean(&original) - 1.0).abs() < 0.01);
    let close = back
        .pixels
        .iter()
        .zip(&original.pixels)
        .filter(|(a, b)| (lum(a) - lum(b)).abs() <= 0.05 * lum(b).max(1e-3))
        .count();
    assert!(
        close * 10 >= back.pixels.len() * 9,
        "{close} of {} texels within 5%",
        back.pixels.len()
    );
}

/// A scene far from its origin renders as the same scene at it: cornell moved by
/// (1e6, -2e6, 5e5), its vertices and views (a room in site or map coordinates), against
/// cornell as it is at 16 spp on the same seed, over every pure pixel, in the image mean
/// and pixel by pixel. In 32-bit floats a ray's offset from the surface it leaves grows
/// with the coordinates: moved by a hundredth of this, the room read 13% off until the scene
/// was moved to its centre before rendering (`assemble::far_scene_centre`). While the
/// vertices and then the views' positions were still read in 32 bits it read 0.3% off in
/// the mean and 20% pixel by pixel (a view's rounding at 2e6 is up to 0.06 units); both are now
/// read in 64 bits and rounded after the move, and the two renders differ by the room's
/// own rounding, a few parts in a million.
#[test]
fn a_scene_far_from_its_origin_renders_as_at_it() {
    let root = workspace();
    let cornell = root.join("scenes/cornell");
    let tmp = tempfile::tempdir().unwrap();
    let far = tmp.path().join("far");
    std::fs::create_dir(&far).unwrap();
    let offset = [1e6f64, -2e6, 5e5];
    let moved = |numbers: &str| common::shifted(numbers, offset);
    let obj = std::fs::read_to_string(cornell.join("geometry.obj")).unwrap();
    std::fs::write(far.join("geometry.obj"), common::shifted_obj(&obj, offset)).unwrap();
    let scene = std::fs::read_to_string(cornell.join("scene.toml")).unwrap();
    let scene: Vec<String> = scene
        .lines()
        .map(|l| match l.strip_prefix("position = [") {
            Some(rest) => format!("position = [{}]", moved(rest.trim_end_matches(']'))),
            None => l.replace("\"views/", &format!("\"{}/views/", path_str(&cornell))),
        })
        .collect();
    std::fs::write(far.join("scene.toml"), scene.join("\n")).unwrap();
    let materials = cornell.join("materials.toml");
    for (scene, out) in [
        (cornell.join("scene.toml"), "here"),
        (far.join("scene.toml"), "far"),
    ] {
        let args = [
            "render",
            path_str(&scene),
            "--materials",
            path_str(&materials),
        ];
        let more = ["--out", out, "--spp", "16", "--seed", "1"];
        relume_ok(tmp.path(), &[&args[..], &more[..]].concat());
    }
    let cornell_scene = cornell.join("scene.toml");
    let compare = ["compare", "views", path_str(&cornell_scene), "here", "far"];
    relume_ok(tmp.path(), &[&compare[..], &["--json", "c.json"]].concat());
    let json = std::fs::read_to_string(tmp.path().join("c.json")).unwrap();
    let table: serde_json::Value = serde_json::from_str(&json).unwrap();
    let mean = table["all"]["rel_mean_diff"].as_f64().unwrap();
    let rms = table["all"]["rel_rms"].as_f64().unwrap();
    assert!(
        mean.abs() < 1e-4 && rms < 1e-3,
        "the far room's image mean is {:+.3}% off, its pixels {:.3}% (relative RMS)",
        100.0 * mean,
        100.0 * rms
    );
}

/// `panorama join` of the scene's own panorama folder reads each face with its view's
/// exposure, as check and recover read the panorama (it was read at 1: a capture of
/// exposure 2 joined at half its radiance); a folder of renders is read at 1.
#[test]
fn panorama_join_reads_the_scenes_own_faces_with_their_exposure() {
    let tmp = tempfile::tempdir().unwrap();
    let c = tmp.path().join("c");
    common::copy_cornell(&c);
    let scene = c.join("scene.toml");
    let text = std::fs::read_to_string(&scene).unwrap();
    std::fs::write(&scene, text.replace("exposure = 1.0", "exposure = 2.0")).unwrap();
    let renders = tmp.path().join("renders");
    std::fs::create_dir(&renders).unwrap();
    for view in ["px", "nx", "py", "ny", "pz", "nz"] {
        let file = format!("{view}.exr");
        std::fs::copy(c.join("views").join(&file), renders.join(&file)).unwrap();
    }
    let join = |dir: &Path, out: &str| {
        relume_ok(
            tmp.path(),
            &[
                "panorama",
                "join",
                path_str(&scene),
                path_str(dir),
                "--out",
                out,
                "--width",
                "64",
            ],
        );
        relume::images::read_image(&tmp.path().join(out), 1.0).unwrap()
    };
    let own = join(&c.join("views"), "own.exr");
    let rendered = join(&renders, "rendered.exr");
    let sum =
        |i: &relume::images::Image| -> f64 { i.pixels.iter().flatten().map(|&v| v as f64).sum() };
    assert!(sum(&rendered) > 0.0);
    let ratio = sum(&own) / sum(&rendered);
    assert!((ratio - 2.0).abs() < 1e-4, "{ratio}");
}
