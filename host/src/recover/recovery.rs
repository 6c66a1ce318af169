//! The state of a recovery between stages ([`Recovery`]): the scene with the models found
//! so far, the panorama and its pure pixels, the thread pool, and the measurements every
//! stage asks of them: renders of a group's pixels, its transport cache, the bias-only
//! errors and the paired comparison of two models that the decisions rest on, and stage
//! 1's diffuse iteration.

use std::sync::Arc;
use std::time::Instant;

use indicatif::ProgressBar;
use relume_core::fit::{self, GroupFit};
use relume_core::geometry::View;
use relume_core::render::RenderSettings;
use relume_core::scene::Scene;
use relume_core::stages::diffuse;

use super::budget::{
    cache_pixel_spp, concentrated_spp, DIFFUSE_GROUP_PIXELS, MAX_CACHE_PIXELS,
    MEASURED_GROUP_PIXELS,
};
use super::model::GroupModel;
use super::pixels::{self, PurePixel};
use super::{cache, joint_step, refine, terms_memo, texture, DiffuseStep};
use crate::assemble::OwnedScene;
use crate::error::Error;
use crate::images::Image;

/// The state of a recovery between stages.
pub(super) struct Recovery {
    pub(super) owned: OwnedScene,
    pub(super) views: Vec<View>,
    pub(super) real: Vec<Image>,
    pub(super) pure: Vec<PurePixel>,
    pub(super) models: Vec<GroupModel>,
    /// Diffuse maps of textured groups (`GroupModel::Textured::map` indexes it).
    pub(super) maps: Vec<texture::RecoveredMap>,
    /// The workers, shared with `pipeline::run`, which runs the recovery on one of them.
    pub(super) pool: Arc<rayon::ThreadPool>,
    pub(super) seed: u64,
    /// The last paired measurements ([`Recovery::paired_terms`]).
    pub(super) terms_memo: terms_memo::TermsMemo,
    /// When the recovery began: the report's clock.
    pub(super) started: Instant,
}

/// What a run of the diffuse iteration ([`Recovery::diffuse_iteration`]) found.
pub(super) struct DiffuseIteration {
    /// The fits of its first render, of the colours it started from.
    pub(super) first: Vec<GroupFit>,
    /// Renders spent.
    pub(super) evaluations: u32,
    /// Each step's update.
    pub(super) steps: Vec<DiffuseStep>,
}

impl Recovery {
    pub(super) fn n_groups(&self) -> usize {
        self.models.len()
    }

    pub(super) fn apply_models(&mut self) {
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
    pub(super) fn with_scene<T>(
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
    pub(super) fn evaluate(
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
    pub(super) fn evaluate_with_lobe_part(
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
    pub(super) fn evaluate_pixels(
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
    pub(super) fn with_pixels<T>(
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
    pub(super) fn diffuse_subset(&self) -> Vec<PurePixel> {
        pixels::spread_subset(&self.pure, self.n_groups(), DIFFUSE_GROUP_PIXELS)
    }

    /// [`MEASURED_GROUP_PIXELS`] of group `g`'s pure pixels, spread evenly; `None` for a
    /// group of no more, to be measured on [`Recovery::pure`] as it is (whose sums then
    /// keep their bits).
    pub(super) fn measured_subset_of(&self, g: usize) -> Option<Vec<PurePixel>> {
        let of_g = pixels::of_group(&self.pure, g);
        (of_g.len() > MEASURED_GROUP_PIXELS)
            .then(|| pixels::spread_subset(&of_g, self.n_groups(), MEASURED_GROUP_PIXELS))
    }

    /// The bias-only fit of group `g` (see [`pixels::evaluate_cross`]).
    pub(super) fn evaluate_cross(
        &mut self,
        spp: u32,
        seed: u64,
        g: usize,
    ) -> Result<GroupFit, Error> {
        let n = self.n_groups();
        let fits = self.with_scene(spp, seed, |pool, scene, observed, settings| {
            pixels::evaluate_cross(pool, scene, observed, settings, n, &|h| h as usize == g)
        })?;
        Ok(fits[g])
    }

    /// The paired cross terms of `pixels` under the current models, at `spp` on `seed`
    /// (see [`pixels::paired_cross_terms`]).
    pub(super) fn paired_terms(
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
    pub(super) fn error_estimates(
        &mut self,
        spp: u32,
    ) -> Result<Vec<Option<fit::ErrorEstimate>>, Error> {
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
    pub(super) fn error_estimate(
        &mut self,
        g: usize,
        spp: u32,
        seed: u64,
    ) -> Result<Option<fit::ErrorEstimate>, Error> {
        let of_g = pixels::of_group(&self.pure, g);
        self.error_estimate_on(&of_g, spp, seed)
    }

    /// [`Recovery::error_estimate`] on `pixels` of one group.
    pub(super) fn error_estimate_on(
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
    pub(super) fn mean_pixels(&self, g: usize, spp: u32) -> (Option<Vec<PurePixel>>, u32) {
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
    pub(super) fn cache_samples(&self, g: usize, base_spp: u32) -> u64 {
        let pixels = self.cache_subset(g).len() as u32;
        pixels as u64 * cache_pixel_spp(base_spp, pixels) as u64
    }

    /// The pixels of group `g`'s transport cache: every k-th of the search's fixed subset
    /// (`refine::search_subset`), at most [`MAX_CACHE_PIXELS`].
    pub(super) fn cache_subset(&self, g: usize) -> Vec<PurePixel> {
        pixels::every_kth(refine::search_subset(&self.pure, g), MAX_CACHE_PIXELS)
    }

    /// The transport cache of group `g` under the current models: over
    /// [`Recovery::cache_subset`], at `base`'s samples per pixel or more, so that it holds
    /// at least `cache_min_samples` pixel samples ([`cache_pixel_spp`]).
    pub(super) fn group_cache(
        &mut self,
        g: usize,
        base: &RenderSettings,
    ) -> Result<cache::GroupCache, Error> {
        self.apply_models();
        let subset = self.cache_subset(g);
        let settings = RenderSettings {
            spp: cache_pixel_spp(base.spp, subset.len() as u32),
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
    pub(super) fn decision_seed(&self) -> u64 {
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
    pub(super) fn decision_pixels(&self, g: usize, spp: u32) -> (Vec<PurePixel>, u32) {
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
    /// comparison and its samples per pixel; `None` for a group without lit pixels. Adds
    /// to `evaluations` two for each round (one measurement of each model).
    pub(super) fn compare_models(
        &mut self,
        g: usize,
        (simple, complex): (GroupModel, GroupModel),
        spp: u32,
        evaluations: &mut u32,
    ) -> Result<Option<(fit::ModelComparison, u32)>, Error> {
        let (pixels, mut spp) = self.decision_pixels(g, spp);
        let mut round = 0;
        loop {
            let seed = self.decision_seed() ^ ((round as u64) << 32);
            *evaluations += 2;
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
    pub(super) fn compare_once(
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
    pub(super) fn diffuse_iteration(
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
pub(super) fn paired_comparison(
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
pub(super) fn error_estimate_of(terms: &[([f64; 2], f64)]) -> Option<fit::ErrorEstimate> {
    let sum_sq_real: f64 = terms.iter().map(|t| t.1).sum();
    fit::ErrorEstimate::from_cross_terms(terms.iter().map(|t| t.0), sum_sq_real)
}
