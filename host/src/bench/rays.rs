//! `relume bench rays`: the tracer timed on a fixed ray file (shared/bench/rays format),
//! with its hits checked against a reference tracer's. Figures are Mrays/s of closest-hit
//! queries, best of several runs after a warm-up, on one thread and on all threads.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;
use relume_core::geometry::Ray;
use relume_core::scene::Scene;

use crate::error::Error;
use crate::fsutil;
use crate::parallel;

/// Rays handed to one worker at a time: large enough that scheduling costs nothing.
const RAYS_PER_CHUNK: usize = 4096;

/// Two hits agree when their distances agree to this relative tolerance (rays/README.md).
pub const T_AGREEMENT: f32 = 1e-4;

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

fn read_all(path: &Path) -> Result<Vec<u8>, Error> {
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|mut f| f.read_to_end(&mut bytes))
        .map_err(|e| Error::io(path, e))?;
    Ok(bytes)
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
    let bytes = read_all(path)?;
    let (count, body) = records(path, &bytes, 24)?;
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
        if direction.length_squared() == 0.0 {
            return Err(Error::input(path, format!("ray {i} has a zero direction")));
        }
        rays.push(Ray::new(Vec3::new(v[0], v[1], v[2]), direction));
    }
    Ok(rays)
}

/// Reads a hit file: `u64 count`, then `count x (f32 t, i32 triangle)`.
pub fn read_hits(path: &Path) -> Result<Vec<FileHit>, Error> {
    let bytes = read_all(path)?;
    let (_, body) = records(path, &bytes, 8)?;
    Ok(body
        .chunks_exact(8)
        .map(|h| FileHit {
            t: f32_at(h, 0),
            triangle: i32::from_le_bytes([h[4], h[5], h[6], h[7]]),
        })
        .collect())
}

/// Writes hits in the reference format, atomically.
pub fn write_hits(path: &Path, hits: &[FileHit]) -> Result<(), Error> {
    let mut bytes = Vec::with_capacity(8 + 8 * hits.len());
    bytes.extend_from_slice(&(hits.len() as u64).to_le_bytes());
    for h in hits {
        bytes.extend_from_slice(&h.t.to_le_bytes());
        bytes.extend_from_slice(&h.triangle.to_le_bytes());
    }
    fsutil::write_atomic(path, &bytes)
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

/// Best time in seconds over `repeats` runs after one warm-up.
fn best_of(repeats: usize, mut run: impl FnMut()) -> f64 {
    run();
    (0..repeats.max(1))
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

/// Runs the benchmark, prints the figures and writes the requested files.
pub fn bench_rays(args: &BenchRaysArgs, scene: &Scene) -> Result<BenchRaysResult, Error> {
    let rays = read_rays(&args.rays)?;
    let mut hits = vec![FileHit::MISS; rays.len()];

    let one = parallel::thread_pool(Some(1))?;
    let seconds_1 = one.install(|| best_of(args.repeats, || trace(scene, &rays, &mut hits)));

    let all = parallel::thread_pool(args.threads)?;
    let threads_all = all.current_num_threads();
    let seconds_all = all.install(|| {
        best_of(args.repeats, || {
            rays.par_chunks(RAYS_PER_CHUNK)
                .zip(hits.par_chunks_mut(RAYS_PER_CHUNK))
                .for_each(|(r, h)| trace(scene, r, h));
        })
    });

    let reference_path = args
        .reference_hits
        .clone()
        .unwrap_or_else(|| args.rays.with_extension("hits"));
    let agreement = if args.reference_hits.is_some() || reference_path.is_file() {
        let reference = read_hits(&reference_path)?;
        Some((
            agreement(&reference_path, &hits, &reference)?,
            reference.len(),
        ))
    } else {
        None
    };

    let mrays = |s: f64| rays.len() as f64 / s.max(1e-12) / 1e6;
    let result = BenchRaysResult {
        rays: rays.len(),
        mrays_1: mrays(seconds_1),
        threads_all,
        mrays_all: mrays(seconds_all),
        agreement,
    };

    println!("{}: {} rays", args.rays.display(), result.rays);
    println!("  1 thread:  {:8.3} Mrays/s", result.mrays_1);
    println!(
        "  {} threads: {:8.3} Mrays/s",
        threads_all, result.mrays_all
    );
    if let Some((agree, n)) = result.agreement {
        println!(
            "  hits agree with {}: {agree}/{n} ({:.4}%)",
            reference_path.display(),
            100.0 * agree as f64 / n.max(1) as f64
        );
    }

    if let Some(path) = &args.hits_out {
        write_hits(path, &hits)?;
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
        let text = serde_json::to_string_pretty(&json).expect("JSON of numbers");
        fsutil::write_atomic(path, text.as_bytes())?;
    }
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
    }
}
