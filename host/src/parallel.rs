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

/// A pool of `threads` workers (all cores when `None`).
pub fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, Error> {
    let mut builder = rayon::ThreadPoolBuilder::new();
    if let Some(n) = threads {
        if n == 0 {
            return Err(Error::Usage("--threads must be at least 1".into()));
        }
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
    let width = view.width;
    pool.install(|| {
        (0..view.n_pixels())
            .into_par_iter()
            .with_min_len(width as usize * ROWS_PER_BAND)
            .map(|i| f(i as u32 % width, i as u32 / width))
            .collect()
    })
}
