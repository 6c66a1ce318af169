//! `relume recover`: the staged recovery of every group's material from the panorama.
//!
//! The host's part: read the scene and the panorama, find each group's pure pixels, run
//! the renders and caches each stage asks for (in parallel, in a fixed partition, so results
//! do not depend on the thread count) and write the results atomically. The decisions and
//! the math are the core's (`relume_core::stages`, `relume_core::fit`).
//!
//! The stages, in order (each its own module here, its decisions in the core's):
//!
//! 1. `stage1`: every group diffuse, `rho_d <- rho_d mean(real) / mean(rendered)`; which
//!    groups are unseen, diffuse, or go on.
//! 2. `stage2`: an isotropic lobe per group that went on, worst-explained first (mirrors
//!    first, so that a mirror is found before it corrupts the others), proposed by its
//!    transport cache and refined on renders; kept only when a render shows it removes
//!    measurably more error than the diffuse model; the mirror test; `ladder` for weak lobes.
//! 3. `stage3`: is what the uniform model leaves a picture?
//! 4. `stage4`: an anisotropic lobe for the groups still poorly explained and for textured
//!    groups' stand-ins (`anisotropic`, `pattern`); then `polish`, the colours of the
//!    groups with a lobe.
//! 5. `texture`: the textured groups' diffuse maps. Diffuse groups are then refined again
//!    under everything found, the scene rendered once more and `output` writes the results
//!    with `report` and `uncertainty`.

mod anisotropic;
mod cache;
mod calibration;
mod inspect;
mod joint_step;
mod kind;
mod ladder;
mod model;
mod orientation;
mod output;
mod pattern;
mod pixels;
mod polish;
mod refine;
mod report;
mod seen_outside;
mod stage1;
mod stage2;
mod stage3;
mod stage4;
mod stage5;
mod terms_memo;
mod texture;
mod too_bright;
mod uncertainty;
mod unseen;
mod warnings;

use std::path::{Path, PathBuf};
use std::time::Instant;

use indicatif::ProgressBar;
use relume_core::fit::{self, GroupFit};
use relume_core::geometry::View;
use relume_core::material::Kind;
use relume_core::render::RenderSettings;
use relume_core::scene::Scene;
use relume_core::stages::diffuse;
use relume_core::stages::isotropic::{self, WardFit};
use relume_core::stages::texture as texture_stage;
use serde::Serialize;

use crate::assemble::OwnedScene;
use crate::error::Error;
use crate::images::Image;
use crate::parallel;
use crate::scene_file::GroupKind;
pub use calibration::NOT_CHECKED as CALIBRATION_NOT_CHECKED;
pub use inspect::{check, CheckReport, GroupSight};
pub use model::GroupModel;
pub use output::{output_files, UNSEEN_TOML};
use pixels::PurePixel;
use report::keep_rule;
pub use report::{ComparisonReport, DiffuseStep, GroupReport, RecoverReport, StageReport};
pub use warnings::FEW_PIXELS;

/// How much work the recovery may spend: samples per pixel of the renders and caches in
/// the loop, and of the final render that the report's errors come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Effort {
    Fast,
    Default,
    Thorough,
}

impl Effort {
    /// The knobs this effort level stands for.
    pub fn budget(self) -> Budget {
        let (loop_spp, cache_spp, anneal_levels, final_spp) = match self {
            Effort::Fast => (8, 16, 4, 32),
            Effort::Default => (32, 64, 8, 128),
            Effort::Thorough => (128, 256, 16, 512),
        };
        Budget {
            loop_spp,
            cache_spp,
            anneal_levels,
            final_spp,
            optimiser: Optimiser::Annealing,
        }
    }
}

/// The search that refines stage 2's proposal.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum Optimiser {
    /// Simulated annealing (the paper's global search).
    Annealing,
    /// Nelder-Mead from the same start (a local search, as Boivin & Gagalowicz used).
    NelderMead,
}

/// The knobs that trade time for accuracy. An [`Effort`] level names one setting of them;
/// `relume bench tradeoff` sweeps them one at a time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Budget {
    /// Samples per pixel of the renders inside the loops (stage 1, the searches).
    pub loop_spp: u32,
    /// Samples per pixel of a group's transport cache (stage 2's proposal).
    pub cache_spp: u32,
    /// Temperature levels of the annealing (10 proposals each); for Nelder-Mead, the same
    /// number of evaluations.
    pub anneal_levels: u32,
    /// Samples per pixel of the final render that the report's errors come from.
    pub final_spp: u32,
    pub optimiser: Optimiser,
}

pub struct RecoverArgs {
    pub scene: PathBuf,
    pub out: PathBuf,
    pub seed: u64,
    pub threads: Option<usize>,
    pub budget: Budget,
    /// Keep at most this many pure pixels of the named group (an even subset): for
    /// studying how recovery degrades as a group is seen in fewer pixels.
    pub limit_group_pixels: Option<(String, u32)>,
    /// Print the warnings about the input (calibration, a view's orientation, views that
    /// see no group) as soon as they are known, before the long work, so that a user can
    /// stop a run on a bad panorama: the command line does; the benches, which perturb the
    /// input on purpose, do not. [`RecoverReport::warnings_told`] counts them.
    pub tell_input_warnings: bool,
}

/// The state of a recovery between stages.
struct Recovery {
    owned: OwnedScene,
    views: Vec<View>,
    real: Vec<Image>,
    pure: Vec<PurePixel>,
    models: Vec<GroupModel>,
    /// Diffuse maps of textured groups (`GroupModel::Textured::map` indexes it).
    maps: Vec<texture::RecoveredMap>,
    pool: rayon::ThreadPool,
    seed: u64,
    /// The last paired measurements ([`Recovery::paired_terms`]).
    terms_memo: terms_memo::TermsMemo,
    /// When the recovery began: the report's clock.
    started: Instant,
}

/// What a run of the diffuse iteration ([`Recovery::diffuse_iteration`]) found.
struct DiffuseIteration {
    /// The fits of its first render, of the colours it started from.
    first: Vec<GroupFit>,
    /// Renders spent.
    evaluations: u32,
    /// Each step's update.
    steps: Vec<DiffuseStep>,
}

impl Recovery {
    fn n_groups(&self) -> usize {
        self.models.len()
    }

    fn apply_models(&mut self) {
        for (m, model) in self.owned.materials.iter_mut().zip(&self.models) {
            *m = model.surface_material();
        }
        self.owned.texture_infos.clear();
        self.owned.texels.clear();
        for map in &self.maps {
            self.owned
                .texture_infos
                .push(relume_core::material::TextureInfo {
                    grid: map.grid(),
                    offset: self.owned.texels.len(),
                });
            self.owned.texels.extend_from_slice(&map.texels);
        }
    }

    /// Runs `measure` on the scene with the current models, the observed pixels and render
    /// settings of `spp` samples from `seed`: the one setup every evaluation shares.
    fn with_scene<T>(
        &mut self,
        spp: u32,
        seed: u64,
        measure: impl FnOnce(&rayon::ThreadPool, &Scene, pixels::Observed, &RenderSettings) -> T,
    ) -> Result<T, Error> {
        self.apply_models();
        let settings = RenderSettings {
            spp,
            seed,
            ..RenderSettings::default()
        };
        let scene = self.owned.build()?;
        let observed = pixels::Observed {
            views: &self.views,
            real: &self.real,
            pure: &self.pure,
        };
        Ok(measure(&self.pool, &scene, observed, &settings))
    }

    /// Renders the pure pixels of the groups `wanted` with the current models.
    fn evaluate(
        &mut self,
        spp: u32,
        seed: u64,
        wanted: &(dyn Fn(u16) -> bool + Sync),
    ) -> Result<Vec<GroupFit>, Error> {
        let pure = std::mem::take(&mut self.pure);
        let fits = self.evaluate_pixels(&pure, spp, seed, wanted);
        self.pure = pure;
        fits
    }

    /// [`Recovery::evaluate`], the same fits to the bit, and beside them the fits of the
    /// part the groups' lobes reflect, from the same samples (see
    /// [`pixels::evaluate_with_lobe_part`]).
    fn evaluate_with_lobe_part(
        &mut self,
        spp: u32,
        seed: u64,
        wanted: &(dyn Fn(u16) -> bool + Sync),
    ) -> Result<(Vec<GroupFit>, Vec<GroupFit>), Error> {
        let n = self.n_groups();
        self.with_scene(spp, seed, |pool, scene, observed, settings| {
            pixels::evaluate_with_lobe_part(pool, scene, observed, settings, n, wanted)
        })
    }

    /// Renders those of `pixels` (pure pixels, a subset of [`Recovery::pure`]) whose group
    /// is `wanted` with the current models.
    fn evaluate_pixels(
        &mut self,
        pixels: &[PurePixel],
        spp: u32,
        seed: u64,
        wanted: &(dyn Fn(u16) -> bool + Sync),
    ) -> Result<Vec<GroupFit>, Error> {
        let n = self.n_groups();
        self.with_pixels(pixels, spp, seed, |pool, scene, observed, settings| {
            pixels::evaluate(pool, scene, observed, settings, n, wanted)
        })
    }

    /// [`Recovery::with_scene`] with the observed pure pixels narrowed to `pixels` (a
    /// subset of [`Recovery::pure`]).
    fn with_pixels<T>(
        &mut self,
        pixels: &[PurePixel],
        spp: u32,
        seed: u64,
        measure: impl FnOnce(&rayon::ThreadPool, &Scene, pixels::Observed, &RenderSettings) -> T,
    ) -> Result<T, Error> {
        self.with_scene(spp, seed, |pool, scene, observed, settings| {
            let observed = pixels::Observed {
                pure: pixels,
                ..observed
            };
            measure(pool, scene, observed, settings)
        })
    }

    /// The pure pixels the diffuse iteration and its polish step render: at most
    /// [`DIFFUSE_GROUP_PIXELS`] per group, spread evenly over each group (see
    /// [`pixels::spread_subset`]).
    fn diffuse_subset(&self) -> Vec<PurePixel> {
        pixels::spread_subset(&self.pure, self.n_groups(), DIFFUSE_GROUP_PIXELS)
    }

    /// [`MEASURED_GROUP_PIXELS`] of group `g`'s pure pixels, spread evenly; `None` for a
    /// group of no more, to be measured on [`Recovery::pure`] as it is (whose sums then
    /// keep their bits).
    fn measured_subset_of(&self, g: usize) -> Option<Vec<PurePixel>> {
        let of_g = pixels::of_group(&self.pure, g);
        (of_g.len() > MEASURED_GROUP_PIXELS)
            .then(|| pixels::spread_subset(&of_g, self.n_groups(), MEASURED_GROUP_PIXELS))
    }

    /// The bias-only fit of group `g` (see [`pixels::evaluate_cross`]).
    fn evaluate_cross(&mut self, spp: u32, seed: u64, g: usize) -> Result<GroupFit, Error> {
        let n = self.n_groups();
        let fits = self.with_scene(spp, seed, |pool, scene, observed, settings| {
            pixels::evaluate_cross(pool, scene, observed, settings, n, &|h| h as usize == g)
        })?;
        Ok(fits[g])
    }

    /// The paired cross terms of `pixels` under the current models, at `spp` on `seed`
    /// (see [`pixels::paired_cross_terms`]).
    fn paired_terms(
        &mut self,
        pixels: &[PurePixel],
        spp: u32,
        seed: u64,
    ) -> Result<Vec<([f64; 2], f64)>, Error> {
        let key = terms_memo::MeasurementKey {
            models: self.models.clone(),
            maps: self.maps.clone(),
            pixels: pixels.to_vec(),
            spp,
            seed,
        };
        if let Some(terms) = self.terms_memo.get(&key) {
            return Ok(terms.to_vec());
        }
        let terms = self.with_scene(spp, seed, |pool, scene, observed, settings| {
            pixels::paired_cross_terms(pool, scene, observed, pixels, settings)
        })?;
        self.terms_memo.keep(key, terms.clone());
        Ok(terms)
    }

    /// Every group's bias-only error with its standard error, with the current models, on
    /// the decisions' seed (see [`fit::ErrorEstimate`]), over at most
    /// [`MEASURED_GROUP_PIXELS`] pure pixels of each group. `None` for a group without lit
    /// pure pixels.
    fn error_estimates(&mut self, spp: u32) -> Result<Vec<Option<fit::ErrorEstimate>>, Error> {
        let seed = self.decision_seed();
        let n = self.n_groups();
        let measured = pixels::spread_subset(&self.pure, n, MEASURED_GROUP_PIXELS);
        let population = pixels::group_counts(&self.pure, n);
        let mut by_group = vec![Vec::new(); n];
        self.with_scene(spp, seed, |pool, scene, observed, settings| {
            let terms = pixels::paired_cross_terms(pool, scene, observed, &measured, settings);
            for (p, t) in measured.iter().zip(terms) {
                by_group[p.group as usize].push(t);
            }
        })?;
        Ok(by_group
            .iter()
            .zip(population)
            .map(|(terms, all)| fit::ErrorEstimate::from_sampled_cross_terms(terms, all as usize))
            .collect())
    }

    /// Group `g`'s bias-only error with its standard error, with the current models, at
    /// `spp` on `seed` (see [`fit::ErrorEstimate`]).
    fn error_estimate(
        &mut self,
        g: usize,
        spp: u32,
        seed: u64,
    ) -> Result<Option<fit::ErrorEstimate>, Error> {
        let of_g = pixels::of_group(&self.pure, g);
        self.error_estimate_on(&of_g, spp, seed)
    }

    /// [`Recovery::error_estimate`] on `pixels` of one group.
    fn error_estimate_on(
        &mut self,
        pixels: &[PurePixel],
        spp: u32,
        seed: u64,
    ) -> Result<Option<fit::ErrorEstimate>, Error> {
        Ok(error_estimate_of(&self.paired_terms(pixels, spp, seed)?))
    }

    /// The pixels a measurement of group `g`'s mean colour or error renders for `spp`
    /// samples on each of its pixels, and their samples per pixel: all of them (`None`)
    /// for a group of at most `refine::MAX_SEARCH_PIXELS`, else its decision subset with
    /// as many samples in all within `fit::DECISION_MAX_SAMPLES`
    /// ([`Recovery::decision_pixels`]). A mean needs samples, not pixels: stage 4's
    /// gate rendered every pixel of a wall at 64 spp, twice (glossy's floor at 256 px, 7.4
    /// of the stage's 8.2 s; at 512 px the living room's ceiling, walls and accent wall).
    fn mean_pixels(&self, g: usize, spp: u32) -> (Option<Vec<PurePixel>>, u32) {
        let all = pixels::of_group(&self.pure, g).len();
        let (subset, concentrated) = self.decision_pixels(g, spp);
        if subset.len() < all {
            (Some(subset), concentrated)
        } else {
            (None, spp)
        }
    }

    /// The pixel samples in all of group `g`'s transport cache at `base_spp` (see
    /// [`Recovery::group_cache`]): what its lobe's estimate saw.
    fn cache_samples(&self, g: usize, base_spp: u32) -> u64 {
        let pixels = self.cache_subset(g).len() as u32;
        pixels as u64 * min_samples_spp(base_spp, pixels, CACHE_MIN_SAMPLES) as u64
    }

    /// The pixels of group `g`'s transport cache: every k-th of the search's fixed subset
    /// (`refine::search_subset`), at most [`MAX_CACHE_PIXELS`].
    fn cache_subset(&self, g: usize) -> Vec<PurePixel> {
        pixels::every_kth(refine::search_subset(&self.pure, g), MAX_CACHE_PIXELS)
    }

    /// The transport cache of group `g` under the current models: over
    /// [`Recovery::cache_subset`], at `base`'s samples per pixel or more, so that it holds
    /// at least [`CACHE_MIN_SAMPLES`] pixel samples.
    fn group_cache(&mut self, g: usize, base: &RenderSettings) -> Result<cache::GroupCache, Error> {
        self.apply_models();
        let subset = self.cache_subset(g);
        let settings = RenderSettings {
            spp: min_samples_spp(base.spp, subset.len() as u32, CACHE_MIN_SAMPLES),
            ..*base
        };
        let scene = self.owned.build()?;
        Ok(cache::build(
            &self.pool,
            &scene,
            &self.views,
            &subset,
            &self.real,
            g as u16,
            &settings,
        ))
    }

    /// The seed of every keep-or-reject measurement.
    fn decision_seed(&self) -> u64 {
        self.seed ^ 0x5E1F
    }

    /// The pixels a decision about group `g` renders and their samples per pixel, for
    /// `spp` samples per pixel of the whole group: a large group's fixed search subset
    /// (`refine::search_subset`, at most `MAX_SEARCH_PIXELS`) with as many pixel samples
    /// in all, concentrated on fewer pixels. Much of a comparison's noise is a product of
    /// two renders' noises per pixel, whose variance falls with the square of the samples
    /// per pixel, so at the same cost a subset reads steadier: on glossy at 256 px the
    /// steel box (6472 pixels) read its lobe against a perfect mirror as -0.064 +- 0.073
    /// at 32 spp on all its pixels (seed 1) and became a mirror by default; the same lobe
    /// against the diffuse model read 0.193 +- 0.0056 on all of them and 0.187 +- 0.0032
    /// at 224 spp on 925 (seed 3).
    ///
    /// Concentrated, the samples stay within `fit::DECISION_MAX_SAMPLES` per model, as a
    /// decision's further rounds do, but never below `spp` on each pixel measured. Without
    /// the cap a wall's measurements grew with its size: at 256 px the living room's floor
    /// (99,451 pixels) was tested at 3136 spp on 1015 pixels, at z -24 where it needed 3,
    /// and the ceiling's ladder took 19 s; at 512 px a diffuse ceiling's tests ran at
    /// 13,592 spp.
    fn decision_pixels(&self, g: usize, spp: u32) -> (Vec<PurePixel>, u32) {
        let all = pixels::of_group(&self.pure, g).len();
        let subset = refine::search_subset(&self.pure, g);
        let spp = concentrated_spp(all, subset.len(), spp);
        (subset, spp)
    }

    /// What a stage decides on for group `g`: the `simple` model against the `complex` one
    /// on the group's pure pixels ([`Recovery::decision_pixels`], at `spp` samples per
    /// pixel of the whole group), both with bias-only errors (see
    /// [`pixels::evaluate_cross`]) on the decisions' own seed, paired pixel by pixel
    /// ([`fit::ModelComparison`]), from `spp` samples per pixel up while the comparison is
    /// promising or unresolved, or a first look's marginal pass
    /// ([`fit::ModelComparison::next_look_cap`], [`fit::next_decision_spp`]). A subtracted variance
    /// estimate would favour the model whose sampling is noisier (any Ward lobe, however
    /// weak), not the better model. Leaves the group's model as it was. Returns the last
    /// comparison and its samples per pixel; `None` for a group without lit pixels.
    fn compare_models(
        &mut self,
        g: usize,
        simple: GroupModel,
        complex: GroupModel,
        spp: u32,
    ) -> Result<Option<(fit::ModelComparison, u32)>, Error> {
        let (pixels, mut spp) = self.decision_pixels(g, spp);
        let mut round = 0;
        loop {
            let seed = self.decision_seed() ^ ((round as u64) << 32);
            let Some(c) = self.compare_once(g, simple, complex, &pixels, spp, seed)? else {
                return Ok(None);
            };
            let next_spp = c
                .next_look_cap(round)
                .and_then(|cap| fit::next_decision_spp(spp, pixels.len(), cap));
            let Some(next_spp) = next_spp.filter(|_| round < fit::DECISION_MAX_ROUNDS) else {
                return Ok(Some((c, spp)));
            };
            spp = next_spp;
            round += 1;
        }
    }

    /// One measurement of [`Recovery::compare_models`].
    fn compare_once(
        &mut self,
        g: usize,
        simple: GroupModel,
        complex: GroupModel,
        pixels: &[PurePixel],
        spp: u32,
        seed: u64,
    ) -> Result<Option<fit::ModelComparison>, Error> {
        let before = self.models[g];
        let terms_of = |rec: &mut Recovery, model: GroupModel| {
            rec.models[g] = model;
            rec.paired_terms(pixels, spp, seed)
        };
        let simple_terms = terms_of(self, simple);
        let complex_terms = terms_of(self, complex);
        self.models[g] = before;
        Ok(paired_comparison(&simple_terms?, &complex_terms?))
    }

    /// Stage 1 (and its refinement): the diffuse update for the groups `active`, the others
    /// held fixed, until converged, every render on [`Recovery::diffuse_subset`] (the
    /// update needs each group's mean, not every pixel). The first fits are on that
    /// subset. The step that finds the change converged has already applied its update; no
    /// render follows it (what stage 1 decides on is measured afterwards by
    /// [`Recovery::error_estimates`]).
    fn diffuse_iteration(
        &mut self,
        spp: u32,
        active: &[bool],
        bar: &ProgressBar,
    ) -> Result<DiffuseIteration, Error> {
        let seed = self.seed;
        let wanted = |g: u16| active[g as usize];
        let subset = self.diffuse_subset();
        let mut first = None;
        let mut evaluations = 0;
        let mut steps = Vec::new();
        let mut previous_change = f64::INFINITY;
        let mut joint = joint_step::JointStep::new(self.n_groups());
        // The colours before the last step, from which `converged` sees a step turn back.
        let mut before: Vec<Option<[f64; 3]>> = vec![None; self.n_groups()];
        loop {
            let fits = self.evaluate_pixels(&subset, spp, seed, &wanted)?;
            evaluations += 1;
            bar.inc(1);
            if first.is_none() {
                first = Some(fits.clone());
            }
            let mut colours: Vec<Option<[f64; 3]>> = (0..self.n_groups())
                .map(|g| match (active[g], self.models[g]) {
                    (true, GroupModel::Diffuse { color }) => Some(color),
                    _ => None,
                })
                .collect();
            let now = colours.clone();
            let max_change = joint.step(&mut colours, &fits);
            // How far the colours end from those before the step before (`converged`).
            let back = colours
                .iter()
                .zip(&before)
                .map(|(next, earlier)| match (next, earlier) {
                    (Some(next), Some(earlier)) => diffuse::relative_distance(*next, *earlier),
                    (Some(_), None) => f64::INFINITY,
                    _ => 0.0,
                })
                .fold(0.0, f64::max);
            before = now;
            for (model, colour) in self.models.iter_mut().zip(&colours) {
                if let Some(color) = colour {
                    *model = GroupModel::Diffuse { color: *color };
                }
            }
            steps.push(DiffuseStep {
                seconds: self.started.elapsed().as_secs_f64(),
                largest_change: max_change,
                reflectances: colours,
            });
            if diffuse::converged(evaluations, max_change, previous_change, back) {
                return Ok(DiffuseIteration {
                    first: first.unwrap_or_default(),
                    evaluations,
                    steps,
                });
            }
            previous_change = max_change;
        }
    }
}

/// The comparison of two models from their paired terms on the same pixels and samples
/// (`None` without lit pixels).
fn paired_comparison(
    simple_terms: &[([f64; 2], f64)],
    complex_terms: &[([f64; 2], f64)],
) -> Option<fit::ModelComparison> {
    let sum_sq_real: f64 = simple_terms.iter().map(|t| t.1).sum();
    fit::ModelComparison::from_cross_terms(
        simple_terms
            .iter()
            .zip(complex_terms)
            .map(|(s, c)| fit::PairedTerms {
                simple: s.0,
                complex: c.0,
            }),
        sum_sq_real,
    )
}

/// The error estimate of one group's paired cross terms (see [`fit::ErrorEstimate`]).
fn error_estimate_of(terms: &[([f64; 2], f64)]) -> Option<fit::ErrorEstimate> {
    let sum_sq_real: f64 = terms.iter().map(|t| t.1).sum();
    fit::ErrorEstimate::from_cross_terms(terms.iter().map(|t| t.0), sum_sq_real)
}

fn progress_bar(len: u64, what: &str) -> ProgressBar {
    crate::progress::bar(len, what, "")
}

/// The best isotropic Ward fit of a group's cache for one kind: roughness searched
/// globally, reflectances in closed form.
fn fit_ward(
    pool: &rayon::ThreadPool,
    cache: &cache::GroupCache,
    kind: Kind,
) -> (WardFit, f64, u32) {
    fit_ward_by(|alpha| cache::isotropic_fit(pool, cache, kind, alpha))
}

/// [`fit_ward`] with the reflectances at each roughness from `fit_at`.
fn fit_ward_by(mut fit_at: impl FnMut(f64) -> WardFit) -> (WardFit, f64, u32) {
    let mut evaluations = 0;
    let mut best: Option<(WardFit, f64)> = None;
    let mut solve = |alpha: f64| {
        evaluations += 1;
        let fit = fit_at(alpha);
        let sse = fit.sse;
        if best.as_ref().is_none_or(|(b, _)| sse < b.sse) {
            best = Some((fit, alpha));
        }
        sse
    };
    isotropic::minimise_1d(
        &mut solve,
        isotropic::ROUGHNESS_MIN,
        isotropic::ROUGHNESS_MAX,
        isotropic::ROUGHNESS_GRID,
        isotropic::ROUGHNESS_REFINE_STEPS,
        true,
    );
    let (fit, alpha) = best.unwrap_or((
        isotropic::solve_diffuse(&relume_core::stages::isotropic::LinearSums::default()),
        isotropic::ROUGHNESS_MAX,
    ));
    (fit, alpha, evaluations)
}

/// Every group's diffuse colour before stage 1's first step, in each channel. A channel
/// no light of the scene emits in keeps it (`too_bright::unlit_channel_warnings`).
pub(super) const START_COLOR: f64 = 0.5;

/// Stage 5 renders the irradiance at this many times the final render's samples, and at
/// least [`MAP_MIN_SPP`]: a map takes the render's noise into its texels (T = I / E, pixel
/// by pixel), where the final render averages it away; textured groups are small, so this
/// costs little.
const MAP_SPP_FACTOR: u32 = 8;

/// The fewest samples per pixel of stage 5's renders. At effort fast (8 x 32 = 256 spp)
/// the irradiance's noise cost the textured scene's maps at 256 px up to 0.6 dB of PSNR;
/// this costs 6 s there (docs/recovery.md, "Map PSNR"). Default and thorough render at
/// least as many already.
const MAP_MIN_SPP: u32 = 1024;

/// The diffuse refinement's last step renders at this many times the loop's samples.
const POLISH_SPP_FACTOR: u32 = 8;

/// Both polishes set each colour from at least this many samples in all (more per pixel
/// for small groups). A mirror's pixels carry the heavy-tailed noise of the light paths it
/// reflects: the living room's 192-pixel mirror took 10-15% colour errors from the
/// search's renders without it, and +1.9, -1.7, +0.2, -0.9% (seeds 1-4, 64 px) at 2^16
/// samples; at 2^19 +1.1, -0.6, -0.1, -0.3%, for about 0.4 s per small group. A small
/// diffuse group under a metal is as noisy (the living room's pedestal, 138 pixels).
const POLISH_MIN_SAMPLES: u64 = 1 << 19;

/// The final views are rendered with at least this many samples per view. The view check
/// (`calibration::view_warnings`) holds each view's mean residual against the others', and
/// at 32 spp a 64-px view's mean carries heavy-tailed noise that the spread of its pixels
/// underestimates: the living room's view px (seed 8, effort fast) read +2.0% +- 0.8%, a
/// false warning, where 256-spp renders of the same model read -0.4% to +0.5%. Over 8
/// seeds that view's mean spreads by 0.75% at 32 spp and 0.4% at 2^19 samples (128 spp).
/// The error images show more of the fit and less of the noise too. At 256 px the
/// effort's samples are already more; about 1 s at 64 px.
const VIEW_MIN_SAMPLES: u64 = 1 << 19;

/// The diffuse refinement's last step is a Newton step: besides its render at
/// [`POLISH_SPP_FACTOR`] times the samples, it renders once at the loop's samples with
/// every pixel's derivative with respect to every diffuse group's log colour
/// (`render::radiance_with_colour_gradient`), for the matrix of how every group's mean
/// responds to every colour (`stage1::newton_steps`). The plain ratio step treats each
/// group alone, but groups light each other: on textured at 256 px the iteration ended
/// with the floor, walls and ceiling all 0.1-0.3% bright, each of their renders moved
/// 1.7-2.7 times as much as the colours did together, and the ratio step left them
/// 0.2-0.6% dark (every view of the final render 0.15-0.5% dark, 4-6 standard errors;
/// docs/recovery.md, "The diffuse polish"). The matrix took a render per group, each
/// colour raised 5% on the same samples, before "Colour gradients in one render".
///
/// The most diffuse groups the polish takes a Newton step for: past them, the ratio step.
/// The matrix has a row and a column per group, each measured on the group's share of the
/// polish's pixels; the references have 4-7 diffuse groups, and larger matrices were
/// measured only by finite differences, when a render per group made them costly.
const POLISH_NEWTON_MAX_GROUPS: usize = 32;

/// Pure pixels per group that the renders of the diffuse iteration and its polish step
/// take at most: a larger group is rendered on that many, spread evenly over it
/// (`pixels::spread_subset`), at the effort's samples per pixel.
///
/// The update `rho <- rho * mean(real) / mean(rendered)` needs the group's mean, and the
/// mean of `N` pixel samples whose relative deviation per sample is `sigma` has a relative
/// standard error of `sigma / sqrt(N)`. The renders of box-diffuse's groups measured
/// `sigma` 0.33-0.87 at effort fast (a pixel's variance times its samples, over its mean).
/// At `sigma = 1` and effort fast (8 samples per pixel, 2^17 per step) this gives each step
/// of the iteration 0.28% and the polish, from which the colours come (2^20 samples), 0.10%:
/// a third of the 0.3% asked of box-diffuse, and less than its smallest group at 256 px
/// (8407 pixels, under the cap) gets from all its pixels (0.14%); a higher effort takes
/// more samples per pixel on the same pixels. The panorama's own noise averages over the
/// 16384 pixels.
///
/// Groups of up to 16384 pixels (box-diffuse's at 64 px per face have at most 7865) keep
/// every pixel, and their sums keep their bits; at 256 px, where its walls and floor have
/// 60000-130000 pixels, a step costs about a quarter.
const DIFFUSE_GROUP_PIXELS: usize = 1 << 14;

/// Pure pixels per group that a measurement of a whole group renders at most, spread
/// evenly over a larger group (`pixels::spread_subset`): stage 1's bias-only errors
/// ([`Recovery::error_estimates`]) and stage 2's re-fit of a diffuse alternative's colour
/// (`stage2::refit_diffuse`). Without a cap their cost grew with the panorama: at 512 px a
/// face the living room's floor, ceiling, walls and accent wall (213,479-434,499 pixels)
/// made half of stage 1's 40 s, and at 1024 px the re-fit took 25 s for the floor alone.
///
/// Stage 1's error is a ratio of sums over the group's pixels. Spread over 131072 of
/// their pixels, those four groups' errors moved by 0.5-1.6% of themselves (0.0502 to
/// 0.0508 on the floor), a few of the render noise's standard errors; the estimate's
/// standard error counts that part too (`fit::ErrorEstimate::from_sampled_cross_terms`).
/// The re-fit needs a mean, which far fewer pixels would give, as the diffuse iteration's
/// [`DIFFUSE_GROUP_PIXELS`] do; but on those the walls' colours moved enough during stage
/// 2 to turn glossy's white sphere, a weak lobe at the 1% rule, diffuse at 256 px (effort
/// default, seed 1). Every group of the references at 256 px but textured's walls
/// (193,735 pixels, diffuse after stage 1) is under this cap and keeps its bits
/// (docs/recovery.md, "Stage 1's gate on large groups").
const MEASURED_GROUP_PIXELS: usize = 1 << 17;

/// A group's transport cache holds at least this many pixel samples: a small group's
/// lobe is seen in a few pixels, and a cache of the effort level's samples per pixel
/// alone (16 at fast) cannot tell its specularity and shape from noise (the living
/// room's 20-pixel statue: specularity 0.85 and roughness 0.15 against a true 0.9 and
/// 0.1; 0.92 and 0.10 at this many samples).
const CACHE_MIN_SAMPLES: u64 = 1 << 16;

/// A group's transport cache holds at most this many of its pixels, so that its
/// [`CACHE_MIN_SAMPLES`] are at least 128 per pixel. The cache's fits are least squares
/// through the origin on each pixel's estimated parts, and a part's sampling noise biases
/// them (a noisy regressor's coefficient comes out scaled by about `1 / (1 + var / D^2)`):
/// on 1024 pixels at 64 spp, at 256 px per face, glossy's metals were proposed 7-13% off
/// in specularity and the living room's floor, walls and ceiling came out 2.5-8% dark. At
/// 512 pixels and 128 spp the metals are 3-4% off; at 256 pixels and 256 spp 1-2%, but a
/// quarter of the pixels loses what only some of them show (the textured checker's
/// anisotropy at 256 px, the steel box's roughness at 64 px). docs/recovery.md, "The
/// cache on fewer pixels".
const MAX_CACHE_PIXELS: usize = 512;

/// The kinds of lobe a group of `kind` is fitted with, simpler first.
fn lobe_kinds(kind: GroupKind) -> &'static [Kind] {
    match kind {
        GroupKind::Plastic => &[Kind::Plastic],
        GroupKind::Metal => &[Kind::Metal],
        GroupKind::Auto => &[Kind::Plastic, Kind::Metal],
    }
}

/// Samples per pixel on `subset` of a group's `all` pixels for as many samples in all as
/// `spp` on every pixel, within `fit::DECISION_MAX_SAMPLES` ([`Recovery::decision_pixels`])
/// and never below `spp`.
fn concentrated_spp(all: usize, subset: usize, spp: u32) -> u32 {
    let samples = (all as u64)
        .saturating_mul(spp as u64)
        .min(fit::DECISION_MAX_SAMPLES);
    samples
        .div_ceil(subset.max(1) as u64)
        .clamp(spp as u64, u32::MAX as u64) as u32
}

/// Samples per pixel for a group of `pixels`: `spp`, or more so that the group gets at
/// least `min_samples` pixel samples.
pub(super) fn min_samples_spp(spp: u32, pixels: u32, min_samples: u64) -> u32 {
    (spp as u64)
        .max(min_samples.div_ceil(pixels.max(1) as u64))
        .min(u32::MAX as u64) as u32
}

/// The paper's mirror test on an isotropic model: specular part above
/// `MIRROR_SPECULAR_FRACTION` of the reflectance, a sharp lobe, and a reflected colour close
/// to the incident one (an untinted specular reflectance).
fn mirror_test(model: &GroupModel) -> Option<String> {
    let GroupModel::Isotropic { roughness, .. } = *model else {
        return None;
    };
    let (rho_d, rho_s) = model.reflectances();
    let total: f64 = (0..3).map(|c| rho_d[c] + rho_s[c]).sum();
    let spec: f64 = rho_s.iter().sum();
    let fraction = if total > 0.0 { spec / total } else { 0.0 };
    let tint = model::tint(rho_s);
    if fraction > fit::MIRROR_SPECULAR_FRACTION
        && roughness <= fit::MIRROR_MAX_ROUGHNESS
        && tint <= fit::MIRROR_MAX_TINT
    {
        Some(format!(
            "mirror: specular fraction {fraction:.3} > MIRROR_SPECULAR_FRACTION {}, roughness {roughness:.4} <= MIRROR_MAX_ROUGHNESS {}, tint {tint:.3} <= MIRROR_MAX_TINT {}",
            fit::MIRROR_SPECULAR_FRACTION,
            fit::MIRROR_MAX_ROUGHNESS,
            fit::MIRROR_MAX_TINT
        ))
    } else {
        None
    }
}

/// The index of group `name` among the scene's `groups`, for `--limit-group-pixels`; an
/// input error naming the scene file and its groups if it has none of that name.
fn group_named(scene: &Path, groups: &[String], name: &str) -> Result<usize, Error> {
    groups.iter().position(|n| n == name).ok_or_else(|| {
        const LISTED: usize = 20;
        let mut listed: Vec<String> = groups
            .iter()
            .take(LISTED)
            .map(|n| format!("'{n}'"))
            .collect();
        if groups.len() > LISTED {
            listed.push(format!("... ({} in all)", groups.len()));
        }
        Error::input(
            scene,
            format!(
                "--limit-group-pixels names group '{name}', which the scene does not have (its groups: {})",
                listed.join(", ")
            ),
        )
    })
}

pub fn run(args: &RecoverArgs) -> Result<RecoverReport, Error> {
    let start = Instant::now();
    let mut input = inspect::read(&args.scene)?;
    // Checked with the scene read, not after the inspection's renders.
    let limited_group = match &args.limit_group_pixels {
        Some((name, _)) => Some(group_named(&args.scene, &input.owned.group_names, name)?),
        None => None,
    };
    let pool = parallel::thread_pool(args.threads)?;
    let output = output::prepare(
        &args.out,
        std::mem::take(&mut input.inputs),
        &input.view_names,
        &input.owned.group_names,
    )?;
    let inspect::Inspection {
        pure,
        light_readings,
        orientation_readings,
        mut warnings,
    } = inspect::inspect(&args.scene, &pool, &mut input)?;
    let inspect::Input {
        owned,
        real,
        view_names,
        header_divisors,
        kinds,
        mapped,
        unfit_for_a_map,
        overlapping_uv,
        obj2rad,
        ..
    } = input;
    let views = owned.views.clone();
    let n_groups = owned.group_names.len();
    let names = owned.group_names.clone();
    let pure = match (&args.limit_group_pixels, limited_group) {
        (Some((name, limit)), Some(g)) => {
            warnings.push(format!(
                "group '{name}': limited to {limit} pure pixels on request (--limit-group-pixels)"
            ));
            pixels::limit_group(pure, g as u16, *limit as usize)
        }
        _ => pure,
    };
    let warnings_told = if args.tell_input_warnings {
        for w in &warnings {
            eprintln!("relume: warning: {w}");
        }
        warnings.len()
    } else {
        0
    };
    let mut rec = Recovery {
        owned,
        views,
        real,
        pure,
        models: vec![
            GroupModel::Diffuse {
                color: [START_COLOR; 3]
            };
            n_groups
        ],
        maps: Vec::new(),
        pool,
        seed: args.seed,
        terms_memo: Default::default(),
        started: start,
    };
    let mut reports: Vec<GroupReport> = (0..n_groups)
        .map(|g| GroupReport::new(&names[g], &format!("{:?}", kinds[g]).to_lowercase()))
        .collect();

    let spp = args.budget.loop_spp;
    let stage1::Stage1 {
        report: stage1_report,
        mut candidates,
        steps: diffuse_steps,
    } = stage1::run(&mut rec, &mut reports, &names, spp, &mut warnings)?;
    let mut stages = vec![stage1_report];
    // The groups no view sees whole pass on light too: their stand-ins, measured under
    // stage 1's colours now, and again below under their neighbours' final models.
    stages.extend(unseen::measure_stand_ins(
        &mut rec,
        &mut reports,
        spp,
        0x05EE_0001,
    )?);

    let cache_settings = RenderSettings {
        spp: args.budget.cache_spp,
        seed: args.seed ^ 0x1507,
        ..RenderSettings::default()
    };
    let verify_spp = args.budget.loop_spp;
    stages.push(stage2::run(
        &mut rec,
        &mut reports,
        &mut candidates,
        &kinds,
        &args.budget,
        &cache_settings,
    )?);

    // Stage 3's textured groups get their maps in stage 5, after stage 4, which may give
    // the untextured stand-in an anisotropic lobe.
    let stage3::Stage3 {
        report: stage3_report,
        textured,
        noise_bound,
        warnings: texture_warnings,
    } = stage3::run(
        &mut rec,
        &mut reports,
        &kinds,
        &stage3::Coordinates {
            mapped: &mapped,
            unfit_for_a_map: &unfit_for_a_map,
            overlapping: &overlapping_uv,
        },
        verify_spp,
        args.seed,
    )?;
    stages.push(stage3_report);
    warnings.extend(texture_warnings);

    stages.push(stage4::run(
        &mut rec,
        &mut reports,
        &textured,
        &kinds,
        &args.budget,
        &cache_settings,
    )?);
    stages.push(polish::polish_colours(
        &mut rec,
        &mut reports,
        &textured,
        spp,
        polish::Pass::First,
    )?);

    stages.push(stage5::run(
        &mut rec,
        &mut reports,
        &textured,
        &stage5::MapSettings {
            map_spp: (MAP_SPP_FACTOR * args.budget.final_spp).max(MAP_MIN_SPP),
            seed: args.seed,
            cache_settings: &cache_settings,
            budget: &args.budget,
        },
    )?);

    stages.push(stage1::refine_diffuse_groups(&mut rec, &mut reports, spp)?);
    // An unseen group's stand-in and its neighbours' colours depend on each other: the
    // stand-in is measured again under the neighbours' final models, and the diffuse
    // colours refined once more under it (box-diffuse at 64 px with walls_ew withheld:
    // its stand-in 6.3% off in red under stage 1's neighbours, within 1.3% after this).
    if let Some(report) = unseen::measure_stand_ins(&mut rec, &mut reports, spp, 0x05EE_0002)? {
        stages.push(report);
        stages.push(stage1::refine_diffuse_groups(&mut rec, &mut reports, spp)?);
    }
    // The lobes' colours once more, under the maps and diffuse colours now final.
    if polish::any_to_polish(&rec, &reports, &textured) {
        stages.push(polish::polish_colours(
            &mut rec,
            &mut reports,
            &textured,
            spp,
            polish::Pass::Final,
        )?);
    }

    // Final render: the views, their error images and every group's final error, from two
    // independent halves of at least VIEW_MIN_SAMPLES per view.
    let stage_start = Instant::now();
    let final_spp = args.budget.final_spp;
    let final_seed = args.seed ^ 0xF1A1;
    let smallest_view = rec
        .views
        .iter()
        .map(|v| v.width.saturating_mul(v.height))
        .min();
    let view_spp = min_samples_spp(final_spp, smallest_view.unwrap_or(1), VIEW_MIN_SAMPLES);
    let final_renders = output::render_views(&mut rec, view_spp, final_seed)?;
    let final_fits = pixels::fits_of_halves(
        pixels::Observed {
            views: &rec.views,
            real: &rec.real,
            pure: &rec.pure,
        },
        [&final_renders.halves[0], &final_renders.halves[1]],
        n_groups,
    );
    for (g, r) in reports.iter_mut().enumerate() {
        r.error_final = final_fits[g].bias_only_error();
        r.model = rec.models[g].name().into();
        warnings.extend(warnings::brighter_than_lit(
            &names[g],
            &rec.models[g],
            &final_fits[g],
        ));
        warnings.extend(warnings::darker_than_any_material(
            &names[g],
            &rec.models[g],
        ));
        warnings.extend(warnings::plastic_lobe_at_bound(&names[g], &rec.models[g]));
    }
    let spp_per_half = final_renders.spp_per_half;
    let renders = final_renders.mean;
    let view_readings = calibration::read_views(&rec.pure, &rec.real, &renders, &view_names);
    warnings.extend(calibration::view_warnings(
        &view_readings,
        calibration::ImageHeaders {
            views: &view_names,
            divisors: &header_divisors,
        },
    ));

    // The paper's own texture feature, on the final render's difference image: reported
    // beside the statistic stage 3 decides on, since on our references it does not
    // separate the classes (docs/recovery.md).
    let differences = pixels::step_differences(
        pixels::Observed {
            views: &rec.views,
            real: &rec.real,
            pure: &rec.pure,
        },
        &renders,
        n_groups,
        fit::TEXTURE_STEP,
        |real, rendered| {
            relume_core::math::luminance(real) - relume_core::math::luminance(rendered)
        },
    );
    for (g, r) in reports.iter_mut().enumerate() {
        if r.pure_pixels >= fit::MIN_PIXELS_FOR_TEXTURE {
            r.texture_feature = texture_stage::texture_feature(&differences[g]);
        }
    }
    stages.push(StageReport {
        stage: "final render".into(),
        evaluations: 1,
        samples_per_pixel: spp_per_half.saturating_mul(2),
        seconds: stage_start.elapsed().as_secs_f64(),
        notes: vec![
            format!("every view rendered twice with independent samples, {} spp each (at least the effort's {final_spp} and VIEW_MIN_SAMPLES {VIEW_MIN_SAMPLES} per view in all): the views, error images and view readings are their mean; error_final is each group's bias-only error from the two", spp_per_half),
        ],
    });

    stages.push(uncertainty::run(
        &mut rec,
        &mut reports,
        &args.budget,
        &cache_settings,
        args.seed,
    )?);

    warnings.extend(warnings::stability_warnings(&warnings::Inputs {
        groups: &reports,
        models: &rec.models,
        panorama_noise_bound: noise_bound,
        view_sides: &view_names
            .iter()
            .cloned()
            .zip(rec.views.iter().map(|v| v.width.min(v.height)))
            .collect::<Vec<_>>(),
        budget: &args.budget,
        mapped: &mapped,
    }));
    let report = RecoverReport {
        scene: args.scene.display().to_string(),
        seed: args.seed,
        budget: args.budget,
        error_definition: "relative error over the group's pure pixels, RGB pooled (relume_core::fit): error_diffuse, error_decided, error_final and every comparison are bias-only, sqrt(max(0, sum (A-T).(B-T)) / sum |T|^2) with A, B two renders with independent samples; error_initial is sqrt(max(0, sum |R-T|^2 - sum var(R)) / sum |T|^2) of one render",
        thresholds: serde_json::json!({
            "DIFFUSE_THRESHOLD": fit::DIFFUSE_THRESHOLD,
            "DIFFUSE_CONVERGED": fit::DIFFUSE_CONVERGED,
            "SPECULAR_GAIN_THRESHOLD": fit::SPECULAR_GAIN_THRESHOLD,
            "GAIN_SIGNIFICANCE": fit::GAIN_SIGNIFICANCE,
            "DECISION_SPP_GROWTH": fit::DECISION_SPP_GROWTH,
            "DECISION_MAX_ROUNDS": fit::DECISION_MAX_ROUNDS,
            "DECISION_MAX_SAMPLES": fit::DECISION_MAX_SAMPLES,
            "DECISION_MIN_GROWTH": fit::DECISION_MIN_GROWTH,
            "MIRROR_SPECULAR_FRACTION": fit::MIRROR_SPECULAR_FRACTION,
            "MIRROR_MAX_ROUGHNESS": fit::MIRROR_MAX_ROUGHNESS,
            "MIRROR_MAX_TINT": fit::MIRROR_MAX_TINT,
            "MIN_PIXELS_FOR_MODEL_CHOICE": fit::MIN_PIXELS_FOR_MODEL_CHOICE,
            "MIN_PIXELS_FOR_TEXTURE": fit::MIN_PIXELS_FOR_TEXTURE,
            "TEXTURE_STEP": fit::TEXTURE_STEP,
            "TEXTURE_FLOOR": fit::TEXTURE_FLOOR,
            "TEXTURE_THRESHOLD": fit::TEXTURE_THRESHOLD,
            "TEXTURE_CONTRAST_THRESHOLD": fit::TEXTURE_CONTRAST_THRESHOLD,
            "NOISE_BOUND_SIGNIFICANCE": fit::NOISE_BOUND_SIGNIFICANCE,
            "EXCEEDS_SIGMAS": fit::EXCEEDS_SIGMAS,
            "HIGHLIGHT_FRACTION": fit::HIGHLIGHT_FRACTION,
            "SHADOW_FRACTION": fit::SHADOW_FRACTION,
            "CALIBRATION_TOLERANCE": calibration::CALIBRATION_TOLERANCE,
            "DARK_LIGHT_LIT": calibration::DARK_LIGHT_LIT,
            "VIEW_AGREEMENT": calibration::VIEW_AGREEMENT,
            "VIEW_SIGMAS": calibration::VIEW_SIGMAS,
            "MIN_VIEW_PIXELS": calibration::MIN_VIEW_PIXELS,
            "ORIENTATION_MARGIN": orientation::ORIENTATION_MARGIN,
            "PAIR_STEP": orientation::PAIR_STEP,
            "EDGE_QUANTILE": orientation::EDGE_QUANTILE,
            "MIN_BOUNDARY_PAIRS": orientation::MIN_BOUNDARY_PAIRS,
        }),
        panorama_noise_bound: noise_bound,
        light_readings,
        view_readings,
        orientation_readings,
        stages,
        diffuse_steps,
        groups: reports,
        warnings,
        warnings_told,
        seconds: start.elapsed().as_secs_f64(),
    };
    output::write_all(output, &args.out, &rec, &renders, &report, &obj2rad)?;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_decisions_samples_are_concentrated_on_its_subset_within_the_cap() {
        // A group of up to 1024 pixels is its own subset: its samples as asked, even past
        // the cap (a small group at a ladder's or a late round's samples).
        assert_eq!(concentrated_spp(938, 938, 32), 32);
        assert_eq!(concentrated_spp(1024, 1024, 4096), 4096);
        // Glossy's steel box at 256 px: 6472 pixels at 32 spp, on 925 of them.
        assert_eq!(concentrated_spp(6472, 925, 32), 224);
        // A wall of 112,446 pixels, on 1023: 3518 spp before the cap, now within it.
        let spp = concentrated_spp(112_446, 1023, 32);
        assert_eq!(spp, 1026);
        assert!(spp as u64 * 1023 <= fit::DECISION_MAX_SAMPLES + 1023);
        // Never fewer than asked per pixel, and no overflow or division by zero.
        assert_eq!(concentrated_spp(5_000_000, 1000, 2048), 2048);
        assert_eq!(concentrated_spp(0, 0, 8), 8);
        assert_eq!(concentrated_spp(usize::MAX / 2, 1, u32::MAX), u32::MAX);
    }
}
