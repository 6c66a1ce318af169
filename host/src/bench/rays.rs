//! `relume bench rays`: the tracer timed on a fixed ray file (shared/bench/rays format),
//! with its hits checked against a reference tracer's. Figures are Mrays/s of closest-hit
//! queries, best of several runs after a warm-up, on one thread and on all threads.

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;
use relume_core::geometry::Ray;
use relume_core::scene::Scene;

use crate::assemble::{self, MaterialSource};
use crate::error::Error;
use crate::fsutil::{self, OutputSet};
use crate::parallel;
use crate::scene_file;

/// Rays handed to one worker at a time: large enough that scheduling costs nothing.
const RAYS_PER_CHUNK: usize = 4096;

/// Two hits agree when their distances agree to this relative tolerance (rays/README.md).
pub const T_AGREEMENT: f32 = 1e-4;

/// How far from 1 a ray's direction may be in length: f32 rounding of a unit vector, with
/// room to spare (the reference sets are within 1e-7).
pub const UNIT_TOLERANCE: f64 = 1e-3;

pub struct BenchRaysArgs {
    pub scene: PathBuf,
    pub rays: PathBuf,
    pub hits_out: Option<PathBuf>,
    pub json_out: Option<PathBuf>,
    pub reference_hits: Option<PathBuf>,
    pub threads: Option<usize>,
    pub repeats: usize,
}

/// A closest hit in the file format: `t = +inf, triangle = -1` for a miss.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FileHit {
    pub t: f32,
    pub triangle: i32,
}

impl FileHit {
    pub const MISS: FileHit = FileHit {
        t: f32::INFINITY,
        triangle: -1,
    };

    /// Same triangle, or distances within [`T_AGREEMENT`] (two triangles sharing an edge).
    pub fn agrees_with(&self, other: &FileHit) -> bool {
        if self.triangle == other.triangle {
            return true;
        }
        if self.triangle < 0 || other.triangle < 0 {
            return false;
        }
        (self.t - other.t).abs() <= T_AGREEMENT * self.t.abs().max(other.t.abs())
    }
}

pub struct BenchRaysResult {
    pub rays: usize,
    pub mrays_1: f64,
    pub threads_all: usize,
    pub mrays_all: f64,
    /// Agreeing hits and reference hits compared, when a reference was found.
    pub agreement: Option<(usize, usize)>,
}

/// The `u64` count at the start of a file and the records after it, checking the size.
fn records<'a>(path: &Path, bytes: &'a [u8], record: usize) -> Result<(usize, &'a [u8]), Error> {
    let Some((head, body)) = bytes.split_first_chunk::<8>() else {
        return Err(Error::input(path, "shorter than its 8-byte count"));
    };
    let count = u64::from_le_bytes(*head);
    let expected = usize::try_from(count)
        .ok()
        .and_then(|c| c.checked_mul(record))
        .filter(|&n| n == body.len());
    match expected {
        Some(_) => Ok((count as usize, body)),
        None => Err(Error::input(
            path,
            format!(
                "header says {count} records of {record} bytes, but {} bytes follow",
                body.len()
            ),
        )),
    }
}

fn f32_at(b: &[u8], i: usize) -> f32 {
    f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]])
}

/// Reads a ray file: `u64 count`, then `count x (ox oy oz dx dy dz)` as f32.
pub fn read_rays(path: &Path) -> Result<Vec<Ray>, Error> {
    let bytes = fsutil::read_bytes(path)?;
    let (count, body) = records(path, &bytes, 24)?;
    // No ray timed gave "0.000 Mrays/s" as a figure.
    if count == 0 {
        return Err(Error::input(
            path,
            "holds no ray (its count is 0): nothing to trace",
        ));
    }
    let mut rays = Vec::with_capacity(count);
    for (i, r) in body.chunks_exact(24).enumerate() {
        let v: [f32; 6] = core::array::from_fn(|k| f32_at(r, 4 * k));
        if v.iter().any(|x| !x.is_finite()) {
            return Err(Error::input(
                path,
                format!("ray {i} has a non-finite component"),
            ));
        }
        let direction = Vec3::new(v[3], v[4], v[5]);
        // A hit's t is a distance only along a unit direction: another length gives t's
        // that cannot agree with the reference's, and figures for other rays.
        let length = v[3..]
            .iter()
            .map(|&c| c as f64 * c as f64)
            .sum::<f64>()
            .sqrt();
        if (length - 1.0).abs() > UNIT_TOLERANCE {
            return Err(Error::input(
                path,
                format!(
                    "ray {i} has a direction of length {length}, not 1: the format gives unit directions"
                ),
            ));
        }
        rays.push(Ray::new(Vec3::new(v[0], v[1], v[2]), direction));
    }
    Ok(rays)
}

/// Reads a hit file: `u64 count`, then `count x (f32 t, i32 triangle)`, each record a
/// miss (`t = +inf, triangle = -1`) or a hit (finite `t >= 0`, `triangle >= 0`). A record
/// that is neither is an error naming it: compared as it stands it would only count as a
/// disagreement, and a corrupted reference would pass for a tracer's mistake.
pub fn read_hits(path: &Path) -> Result<Vec<FileHit>, Error> {
    let bytes = fsutil::read_bytes(path)?;
    let (_, body) = records(path, &bytes, 8)?;
    body.chunks_exact(8)
        .enumerate()
        .map(|(i, h)| {
            let hit = FileHit {
                t: f32_at(h, 0),
                triangle: i32::from_le_bytes([h[4], h[5], h[6], h[7]]),
            };
            let valid = match hit.triangle {
                -1 => hit.t == f32::INFINITY,
                triangle => triangle >= 0 && hit.t.is_finite() && hit.t >= 0.0,
            };
            if valid {
                Ok(hit)
            } else {
                Err(Error::input(
                    path,
                    format!(
                        "hit {i} has t {} and triangle {}: a miss is t = inf with triangle -1, a hit a finite t >= 0 with a triangle >= 0",
                        hit.t, hit.triangle
                    ),
                ))
            }
        })
        .collect()
}

/// Checks that every reference hit names a triangle of the scene (`triangles` of them, in
/// file order, as the ray sets count them).
fn check_triangles(path: &Path, hits: &[FileHit], triangles: usize) -> Result<(), Error> {
    match hits
        .iter()
        .enumerate()
        .find(|(_, h)| h.triangle >= 0 && h.triangle as usize >= triangles)
    {
        Some((i, h)) => Err(Error::input(
            path,
            format!(
                "hit {i} names triangle {}, but the scene has {triangles} triangles",
                h.triangle
            ),
        )),
        None => Ok(()),
    }
}

/// Hits in the reference format.
fn hits_bytes(hits: &[FileHit]) -> Vec<u8> {
    let mut bytes = Vec::with_capacity(8 + 8 * hits.len());
    bytes.extend_from_slice(&(hits.len() as u64).to_le_bytes());
    for h in hits {
        bytes.extend_from_slice(&h.t.to_le_bytes());
        bytes.extend_from_slice(&h.triangle.to_le_bytes());
    }
    bytes
}

/// Writes hits in the reference format, atomically.
pub fn write_hits(path: &Path, hits: &[FileHit]) -> Result<(), Error> {
    fsutil::write_atomic(path, &hits_bytes(hits))
}

fn trace(scene: &Scene, rays: &[Ray], out: &mut [FileHit]) {
    for (ray, hit) in rays.iter().zip(out) {
        *hit = match scene.intersect(ray, f32::INFINITY) {
            Some(h) => FileHit {
                t: h.t,
                triangle: h.triangle as i32,
            },
            None => FileHit::MISS,
        };
    }
}

/// Best time in seconds over `repeats` (at least 1) runs after one warm-up.
fn best_of(repeats: usize, mut run: impl FnMut()) -> f64 {
    run();
    (0..repeats)
        .map(|_| {
            let start = Instant::now();
            run();
            start.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Counts reference hits that agree; a count mismatch is an input error.
pub fn agreement(path: &Path, ours: &[FileHit], reference: &[FileHit]) -> Result<usize, Error> {
    if ours.len() != reference.len() {
        return Err(Error::input(
            path,
            format!("{} reference hits for {} rays", reference.len(), ours.len()),
        ));
    }
    Ok(ours
        .iter()
        .zip(reference)
        .filter(|(a, b)| a.agrees_with(b))
        .count())
}

/// The output set of a run, with every check that needs no work made: at least one timed
/// run, and no output that would replace an input (the scene's files, the rays, the
/// reference hits read) or the other output.
fn prepare(args: &BenchRaysArgs, reference: Option<&Path>) -> Result<OutputSet, Error> {
    if args.repeats == 0 {
        return Err(Error::Usage("--repeats must be at least 1".into()));
    }
    let desc = scene_file::load_scene(&args.scene)?;
    // The ray sets name a hit's triangle by its index in the OBJ files, in file order,
    // which the scene's triangles keep only when none is left out: with objects hidden,
    // the hits written and those compared named other triangles, without a word.
    if !desc.hide.is_empty() {
        let hidden: Vec<String> = desc.hide.iter().map(|h| format!("'{h}'")).collect();
        return Err(scene_file::hide_error(
            &args.scene,
            format!(
                "hides {}: bench rays names a hit's triangle by its index in the OBJ files, which hidden objects would shift; give it the scene with `hide = []`",
                hidden.join(", ")
            ),
        ));
    }
    let mut inputs = desc.input_files();
    inputs.push((args.rays.clone(), "the ray file".into()));
    inputs.extend(reference.map(|r| (r.to_path_buf(), "the reference hits".into())));
    let set = OutputSet::keeping(inputs);
    set.check_targets(args.hits_out.iter().chain(&args.json_out).cloned())?;
    if let (Some(hits), Some(json)) = (&args.hits_out, &args.json_out) {
        if fsutil::same_file(hits, json) {
            return Err(Error::Usage(format!(
                "--hits and --json both name {}: the JSON would replace the hits",
                json.display()
            )));
        }
    }
    Ok(set)
}

/// Runs the benchmark, prints the figures and writes the requested files as one set. Every
/// input is read and checked before the timing: the rays, the reference hits (given, or
/// the .hits beside the .rays when there is one) and the scene.
pub fn run(args: &BenchRaysArgs) -> Result<BenchRaysResult, Error> {
    // The .hits beside the .rays when there is one by that name: one that is no file (a
    // folder, a broken link) is named as a given one is, where the run went on without a
    // word of the check it had left out.
    let reference_path = match &args.reference_hits {
        Some(path) => Some(path.clone()),
        None => {
            let beside = args.rays.with_extension("hits");
            std::fs::symlink_metadata(&beside).is_ok().then_some(beside)
        }
    };
    let mut set = prepare(args, reference_path.as_deref())?;
    let rays = read_rays(&args.rays)?;
    let reference = match &reference_path {
        Some(path) => {
            let hits = read_hits(path)?;
            if hits.len() != rays.len() {
                return Err(Error::input(
                    path,
                    format!("{} reference hits for {} rays", hits.len(), rays.len()),
                ));
            }
            Some((path, hits))
        }
        None => None,
    };
    let mut owned = assemble::load_and_assemble(&args.scene, MaterialSource::GeometryOnly)?;
    // The rays are in the scene's own coordinates; the geometry may have been moved.
    let origin = Vec3::from(owned.origin.map(|c| c as f32));
    let rays: Vec<Ray> = rays
        .into_iter()
        .map(|r| Ray::new(r.origin - origin, r.direction))
        .collect();
    let scene = owned.build()?;
    if let Some((path, hits)) = &reference {
        check_triangles(path, hits, scene.triangles.len())?;
    }
    let mut hits = vec![FileHit::MISS; rays.len()];

    let one = parallel::thread_pool(Some(1))?;
    let seconds_1 = one.install(|| best_of(args.repeats, || trace(&scene, &rays, &mut hits)));

    let all = parallel::thread_pool(args.threads)?;
    let threads_all = all.current_num_threads();
    let seconds_all = all.install(|| {
        best_of(args.repeats, || {
            rays.par_chunks(RAYS_PER_CHUNK)
                .zip(hits.par_chunks_mut(RAYS_PER_CHUNK))
                .for_each(|(r, h)| trace(&scene, r, h));
        })
    });

    let agreement = match &reference {
        Some((path, reference)) => Some((agreement(path, &hits, reference)?, reference.len())),
        None => None,
    };

    let mrays = |s: f64| rays.len() as f64 / s.max(1e-12) / 1e6;
    let result = BenchRaysResult {
        rays: rays.len(),
        mrays_1: mrays(seconds_1),
        threads_all,
        mrays_all: mrays(seconds_all),
        agreement,
    };

    println!(
        "{}: {}",
        args.rays.display(),
        crate::text::counted(result.rays as u64, "ray")
    );
    println!("  1 thread:  {:8.3} Mrays/s", result.mrays_1);
    // With one thread in all, the second timing is of the same work: not printed twice.
    if threads_all > 1 {
        println!(
            "  {} threads: {:8.3} Mrays/s",
            threads_all, result.mrays_all
        );
    }
    if let (Some((agree, n)), Some((path, _))) = (result.agreement, &reference) {
        println!(
            "  hits agree with {}: {agree}/{n} ({:.4}%)",
            path.display(),
            100.0 * agree as f64 / n.max(1) as f64
        );
    }

    if let Some(path) = &args.hits_out {
        set.add(path, &hits_bytes(&hits))?;
    }
    if let Some(path) = &args.json_out {
        let mut json = serde_json::json!({
            "rays": result.rays,
            "threads_1": { "mrays_per_s": result.mrays_1 },
            "threads_all": { "threads": threads_all, "mrays_per_s": result.mrays_all },
        });
        if let Some((agree, n)) = result.agreement {
            json["agreement"] = serde_json::json!({ "agreeing": agree, "compared": n });
        }
        let text = serde_json::to_string_pretty(&json).map_err(|e| Error::Usage(e.to_string()))?;
        set.add(path, text.as_bytes())?;
    }
    set.commit()?;
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_agree_by_triangle_or_distance() {
        let a = FileHit {
            t: 2.0,
            triangle: 3,
        };
        assert!(a.agrees_with(&FileHit {
            t: 5.0,
            triangle: 3
        }));
        assert!(a.agrees_with(&FileHit {
            t: 2.0001,
            triangle: 4
        }));
        assert!(!a.agrees_with(&FileHit {
            t: 2.01,
            triangle: 4
        }));
        assert!(!a.agrees_with(&FileHit::MISS));
        assert!(FileHit::MISS.agrees_with(&FileHit::MISS));
    }

    #[test]
    fn hit_files_round_trip_and_bad_sizes_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.hits");
        let hits = [
            FileHit {
                t: 1.5,
                triangle: 7,
            },
            FileHit::MISS,
        ];
        write_hits(&path, &hits).unwrap();
        assert_eq!(read_hits(&path).unwrap(), hits);

        std::fs::write(&path, [1u8, 0, 0, 0, 0, 0, 0, 0, 9]).unwrap();
        let e = read_hits(&path).unwrap_err().to_string();
        assert!(e.contains("x.hits") && e.contains("1 records"), "{e}");
        let e = read_rays(&dir.path().join("missing.rays"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing.rays"), "{e}");
        // A folder where the file goes is bad input (exit 3), as for every input.
        let e = read_rays(dir.path()).unwrap_err();
        assert_eq!(e.exit_code(), 3, "{e}");
        assert!(e.to_string().contains("is a folder, not a file"), "{e}");
    }

    #[test]
    fn a_hit_record_that_is_neither_a_hit_nor_a_miss_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.hits");
        let good = FileHit {
            t: 1.5,
            triangle: 7,
        };
        for (bad, what) in [
            (
                FileHit {
                    t: f32::NAN,
                    ..good
                },
                "t NaN and triangle 7",
            ),
            (FileHit { t: -2.0, ..good }, "t -2 and triangle 7"),
            (
                FileHit {
                    t: f32::INFINITY,
                    ..good
                },
                "t inf and triangle 7",
            ),
            (
                FileHit {
                    t: 3.0,
                    triangle: -1,
                },
                "t 3 and triangle -1",
            ),
            (
                FileHit {
                    t: 3.0,
                    triangle: -7,
                },
                "t 3 and triangle -7",
            ),
        ] {
            write_hits(&path, &[good, FileHit::MISS, bad]).unwrap();
            let e = read_hits(&path).unwrap_err().to_string();
            assert!(
                e.contains("x.hits") && e.contains(&format!("hit 2 has {what}")),
                "{e}"
            );
        }
        let hits = [good, FileHit::MISS];
        assert!(check_triangles(&path, &hits, 8).is_ok());
        let e = check_triangles(&path, &hits, 7).unwrap_err().to_string();
        assert!(
            e.contains("x.hits")
                && e.contains("hit 0 names triangle 7, but the scene has 7 triangles"),
            "{e}"
        );
    }

    /// A ray file of `directions`, all from the origin.
    fn ray_file(path: &Path, directions: &[[f32; 3]]) {
        let mut bytes = (directions.len() as u64).to_le_bytes().to_vec();
        for d in directions {
            for v in [0.0, 0.0, 0.0, d[0], d[1], d[2]] {
                bytes.extend_from_slice(&f32::to_le_bytes(v));
            }
        }
        std::fs::write(path, bytes).unwrap();
    }

    #[test]
    fn directions_must_be_unit_length_within_the_tolerance() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.rays");
        let s = std::f32::consts::FRAC_1_SQRT_2;
        ray_file(&path, &[[1.0, 0.0, 0.0], [0.0, s, s], [0.0, 0.0, -1.0005]]);
        assert_eq!(read_rays(&path).unwrap().len(), 3);
        ray_file(&path, &[[1.0, 0.0, 0.0], [0.0, 2.0, 0.0]]);
        let e = read_rays(&path).unwrap_err().to_string();
        assert!(
            e.contains("x.rays") && e.contains("ray 1 has a direction of length 2, not 1"),
            "{e}"
        );
        ray_file(&path, &[[0.0, 0.0, 0.0]]);
        let e = read_rays(&path).unwrap_err().to_string();
        assert!(e.contains("ray 0 has a direction of length 0"), "{e}");
    }

    #[test]
    fn a_scene_that_hides_objects_is_refused_at_its_hide_line() {
        let dir = tempfile::tempdir().unwrap();
        let rays = dir.path().join("x.rays");
        ray_file(&rays, &[[1.0, 0.0, 0.0]]);
        let cornell_dir = cornell().parent().unwrap().to_path_buf();
        let text = std::fs::read_to_string(cornell())
            .unwrap()
            .replace("hide = []", "hide = [\"box\"]")
            .replace(
                "\"geometry.obj\"",
                &format!("{:?}", cornell_dir.join("geometry.obj")),
            );
        let scene = dir.path().join("scene.toml");
        std::fs::write(&scene, &text).unwrap();
        let args = BenchRaysArgs {
            scene: scene.clone(),
            rays,
            hits_out: Some(dir.path().join("x.hits")),
            json_out: None,
            reference_hits: None,
            threads: Some(1),
            repeats: 1,
        };
        let e = run(&args).err().unwrap();
        assert_eq!(e.exit_code(), 3, "{e}");
        let line = text.lines().position(|l| l.starts_with("hide")).unwrap() + 1;
        assert!(
            e.to_string().contains(&format!("scene.toml:{line}"))
                && e.to_string().contains("hides 'box'"),
            "{e}"
        );
        assert!(!dir.path().join("x.hits").exists());
    }

    #[test]
    fn hits_beside_the_rays_that_are_no_file_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let rays = dir.path().join("x.rays");
        ray_file(&rays, &[[1.0, 0.0, 0.0]]);
        let args = BenchRaysArgs {
            scene: cornell(),
            rays: rays.clone(),
            hits_out: None,
            json_out: None,
            reference_hits: None,
            threads: Some(1),
            repeats: 1,
        };
        let beside = dir.path().join("x.hits");
        std::fs::create_dir(&beside).unwrap();
        let e = run(&args).err().unwrap();
        assert_eq!(e.exit_code(), 3, "{e}");
        assert!(
            e.to_string().contains("x.hits") && e.to_string().contains("is a folder"),
            "{e}"
        );
        std::fs::remove_dir(&beside).unwrap();
        std::os::unix::fs::symlink(dir.path().join("gone.hits"), &beside).unwrap();
        let e = run(&args).err().unwrap().to_string();
        assert!(e.contains("x.hits"), "{e}");
        // No entry of that name: no reference, and no error.
        std::fs::remove_file(&beside).unwrap();
        assert_eq!(run(&args).unwrap().agreement, None);
    }

    fn cornell() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell/scene.toml")
    }

    #[test]
    fn no_repeats_and_outputs_over_inputs_are_refused_before_the_timing() {
        let dir = tempfile::tempdir().unwrap();
        let rays = dir.path().join("x.rays");
        ray_file(&rays, &[[1.0, 0.0, 0.0]]);
        let before = std::fs::read(&rays).unwrap();
        let args = |hits: Option<&str>, json: Option<&str>, repeats| BenchRaysArgs {
            scene: cornell(),
            rays: rays.clone(),
            hits_out: hits.map(|h| dir.path().join(h)),
            json_out: json.map(|j| dir.path().join(j)),
            reference_hits: None,
            threads: Some(1),
            repeats,
        };
        let e = run(&args(None, None, 0)).err().unwrap();
        assert!(
            e.to_string().contains("--repeats") && e.exit_code() == 2,
            "{e}"
        );
        for (hits, json) in [(Some("x.rays"), None), (None, Some("x.rays"))] {
            let e = run(&args(hits, json, 1)).err().unwrap().to_string();
            assert!(e.contains("would replace the ray file"), "{e}");
        }
        let e = run(&args(Some("o.bin"), Some("o.bin"), 1)).err().unwrap();
        assert!(e.to_string().contains("--hits and --json both name"), "{e}");
        assert_eq!(std::fs::read(&rays).unwrap(), before);
        // The hits written become the reference beside the rays, which a later run keeps.
        let result = run(&args(Some("x.hits"), Some("x.json"), 1)).unwrap();
        assert_eq!(result.agreement, None);
        let e = run(&args(Some("x.hits"), None, 1))
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("would replace the reference hits"), "{e}");
        let result = run(&args(None, None, 1)).unwrap();
        assert_eq!(result.agreement, Some((1, 1)));
    }
}
