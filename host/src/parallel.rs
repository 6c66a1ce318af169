//! Parallelism that does not change results: work is cut into fixed bands of rows whose
//! pixels are independent (each sample has its own random stream), and every band writes
//! into its own place of the output. Thread count and scheduling change speed only.

use glam::Vec3;
use indicatif::ProgressBar;
use rayon::prelude::*;
use relume_core::geometry::View;
use relume_core::render::{self, RenderSettings};
use relume_core::scene::Scene;

use crate::error::Error;

/// Rows in one unit of parallel work.
const ROWS_PER_BAND: usize = 4;

/// The most worker threads `--threads` may ask for: the time to start and join them
/// grows faster than linearly (a 4-spp cornell render took 0.02 s on 64 threads, 1 s on
/// 1000, 7 s on 4000 and over a minute on 100000).
pub const MAX_THREADS: usize = 1024;

/// Whether `--threads` asks for a count [`thread_pool`] starts: at least 1, at most
/// [`MAX_THREADS`].
pub fn check_threads(threads: Option<usize>) -> Result<(), Error> {
    match threads {
        Some(0) => Err(Error::Usage("--threads must be at least 1".into())),
        Some(n) if n > MAX_THREADS => Err(Error::Usage(format!(
            "--threads {n} is more than {MAX_THREADS}: each thread takes work in fixed bands, and thousands of threads spend their time starting and waiting"
        ))),
        _ => Ok(()),
    }
}

/// Past this many workers a core, `--threads` is warned of.
pub const THREADS_PER_CORE_WARNED: usize = 4;

/// A warning when `threads` workers are far more than the machine's `cores`: idle workers
/// spin waiting for work, so that `check` of the living room took 10.7 s on 1000 threads
/// against 0.7 s on 2, and a recovery 14x as long, to the same bytes.
pub fn oversubscribed_warning(threads: Option<usize>, cores: usize) -> Option<String> {
    let n = threads?;
    (n > THREADS_PER_CORE_WARNED * cores.max(1)).then(|| {
        format!(
            "--threads {n} is more than {THREADS_PER_CORE_WARNED} a core for the {cores} cores here: idle workers spin waiting for work and slow the run (the results are the same on any count); leave --threads out to use every core"
        )
    })
}

/// A worker's stack: the main thread's usual 8 MiB rather than a spawned thread's 2 MiB,
/// since a recovery runs whole on one of its workers (`recover::pipeline::run`).
const WORKER_STACK_BYTES: usize = 8 << 20;

/// A pool of `threads` workers (all cores when `None`).
pub fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, Error> {
    check_threads(threads)?;
    static WARNED: std::sync::Once = std::sync::Once::new();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    if let Some(w) = oversubscribed_warning(threads, cores) {
        WARNED.call_once(|| eprintln!("relume: warning: {w}"));
    }
    let mut builder = rayon::ThreadPoolBuilder::new().stack_size(WORKER_STACK_BYTES);
    if let Some(n) = threads {
        builder = builder.num_threads(n);
    }
    builder
        .build()
        .map_err(|e| Error::Usage(format!("cannot start {threads:?} threads: {e}")))
}

/// Renders one view, band by band, on `pool`; `progress` advances by one per row.
pub fn render_view(
    pool: &rayon::ThreadPool,
    scene: &Scene,
    view: &View,
    view_index: u32,
    settings: &RenderSettings,
    progress: &ProgressBar,
) -> Vec<Vec3> {
    let width = view.width as usize;
    let mut pixels = vec![Vec3::ZERO; view.n_pixels()];
    pool.install(|| {
        pixels
            .par_chunks_mut(width * ROWS_PER_BAND)
            .enumerate()
            .for_each(|(band, out)| {
                let first = (band * ROWS_PER_BAND) as u32;
                let rows = (out.len() / width) as u32;
                render::render_rows(scene, view, view_index, first..first + rows, settings, out);
                progress.inc(rows as u64);
            });
    });
    pixels
}

/// Applies `f` to every pixel of a view in parallel, in fixed bands, collecting in order.
pub fn map_pixels<T, F>(pool: &rayon::ThreadPool, view: &View, f: F) -> Vec<T>
where
    T: Send,
    F: Fn(u32, u32) -> T + Sync,
{
    map_grid(pool, view.width, view.height, f)
}

/// [`map_pixels`] over a `width x height` grid that is no view (an equirectangular image).
pub fn map_grid<T, F>(pool: &rayon::ThreadPool, width: u32, height: u32, f: F) -> Vec<T>
where
    T: Send,
    F: Fn(u32, u32) -> T + Sync,
{
    pool.install(|| {
        (0..width as usize * height as usize)
            .into_par_iter()
            .with_min_len(width as usize * ROWS_PER_BAND)
            .map(|i| f(i as u32 % width, i as u32 / width))
            .collect()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn threads_far_above_the_cores_are_warned_of() {
        assert_eq!(oversubscribed_warning(None, 2), None);
        assert_eq!(oversubscribed_warning(Some(8), 2), None);
        let w = oversubscribed_warning(Some(1000), 2).unwrap();
        assert!(
            w.starts_with("--threads 1000 is more than 4 a core for the 2 cores here"),
            "{w}"
        );
        assert!(oversubscribed_warning(Some(5), 1).is_some());
    }

    #[test]
    fn thread_counts_outside_1_to_max_threads_are_usage_errors() {
        for n in [0, MAX_THREADS + 1] {
            let err = thread_pool(Some(n)).expect_err("an error");
            assert!(matches!(err, Error::Usage(_)), "{err}");
            assert!(err.to_string().contains("--threads"), "{err}");
        }
        assert_eq!(thread_pool(Some(3)).unwrap().current_num_threads(), 3);
    }
}
