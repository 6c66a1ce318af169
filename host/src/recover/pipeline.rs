//! `relume recover`'s pipeline, step by step: the input read and inspected, stages 1 to
//! 5, the refinement under everything found, the final render, the uncertainties, the
//! warnings and the report, and the outputs written as one set. What passes between the
//! steps is named ([`Loaded`], [`Staged`], [`FinalRender`]).

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use glam::Vec3;
use relume_core::fit;
use relume_core::render::RenderSettings;
use relume_core::stages::texture as texture_stage;

use super::budget::{min_samples_spp, MAP_MIN_SPP, MAP_SPP_FACTOR, VIEW_MIN_SAMPLES};
use super::calibration::{self, LightReading, ViewReading};
use super::orientation::{self, OrientationReading};
use super::pixels::{self, PurePixel};
use super::recovery::Recovery;
use super::{
    inspect, output, polish, stage1, stage2, stage3, stage4, stage5, uncertainty, unseen, warnings,
    Budget, DiffuseStep, GroupModel, GroupReport, RecoverArgs, RecoverReport, StageReport,
    START_COLOR,
};
use crate::assemble::OwnedScene;
use crate::error::Error;
use crate::fsutil::OutputSet;
use crate::images::Image;
use crate::parallel;
use crate::scene_file::GroupKind;

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

/// Recovers every group's material: the input read and inspected, stages 1 to 5, the
/// refinement under everything found, the final render, the uncertainties, and the report
/// with the outputs written as one set.
pub fn run(args: &RecoverArgs) -> Result<RecoverReport, Error> {
    let start = Instant::now();
    let pool = Arc::new(parallel::thread_pool(args.threads)?);
    // The whole recovery runs on one of the pool's workers. Its thousands of parallel
    // steps (a render of a group's pixels, a fit on its cache) then start on the thread
    // that asks for them, and only the other workers are woken; from a thread outside
    // the pool, each step woke a worker to start it and woke the caller again to end it
    // (the living room at 64 px: 16,774 futex calls -> 1,111, 3-8% less wall time). Which
    // thread runs what changes no result.
    let worker_pool = Arc::clone(&pool);
    pool.install(move || run_on(args, worker_pool, start))
}

/// [`run`] on `pool`'s worker.
fn run_on(
    args: &RecoverArgs,
    pool: Arc<rayon::ThreadPool>,
    start: Instant,
) -> Result<RecoverReport, Error> {
    let Loaded {
        work,
        scene,
        inspected,
        mut warnings,
        output,
    } = load_and_inspect(args, pool)?;
    let mut rec = every_group_diffuse(work, args.seed, start);
    let (names, kinds) = (&scene.names, &scene.kinds);
    let mut reports: Vec<GroupReport> = (0..names.len())
        .map(|g| GroupReport::new(&names[g], &format!("{:?}", kinds[g]).to_lowercase()))
        .collect();

    let mut staged = stages_1_to_5(&mut rec, &mut reports, &scene, args, &mut warnings)?;
    refine_under_everything(
        &mut rec,
        &mut reports,
        &staged.textured,
        args.budget.loop_spp,
        &mut staged.stages,
    )?;
    let final_render = final_render(&mut rec, &mut reports, &scene, args, &mut warnings)?;
    staged.stages.push(final_render.report);
    staged.stages.push(uncertainty::run(
        &mut rec,
        &mut reports,
        &args.budget,
        &staged.cache_settings,
        args.seed,
    )?);

    warnings.extend(stability_warnings(
        &rec,
        &reports,
        &scene,
        staged.noise_bound,
        &args.budget,
    ));
    let report = recover_report(
        args,
        start,
        inspected,
        staged,
        final_render.view_readings,
        reports,
        warnings,
    );
    output::write_all(
        output,
        &args.out,
        &rec,
        &final_render.renders,
        &report,
        &scene.obj2rad,
    )?;
    Ok(report)
}

/// The input read and inspected, with the output folders made: what the recovery starts
/// from.
struct Loaded {
    work: RecoveryInput,
    scene: SceneFacts,
    inspected: Inspected,
    /// The input's warnings, to which each step adds its own.
    warnings: Vec<String>,
    output: OutputSet,
}

/// What a [`Recovery`] is made of: the scene assembled, the panorama, its pure pixels
/// (limited on request) and the threads.
struct RecoveryInput {
    owned: OwnedScene,
    real: Vec<Image>,
    pure: Vec<PurePixel>,
    pool: Arc<rayon::ThreadPool>,
}

/// What the scene says of its groups and views that the stages and the report read.
struct SceneFacts {
    names: Vec<String>,
    kinds: Vec<GroupKind>,
    mapped: Vec<bool>,
    unfit_for_a_map: Vec<Option<String>>,
    overlapping_uv: Vec<Option<String>>,
    view_names: Vec<String>,
    header_divisors: Vec<Option<[f64; 3]>>,
    obj2rad: output::Obj2radNames,
}

/// What the inspection found before any stage, for the report.
struct Inspected {
    light_readings: Vec<LightReading>,
    orientation_readings: Vec<OrientationReading>,
    /// How many of the input's warnings were told as soon as known.
    warnings_told: usize,
}

/// Reads the scene and its panorama, checks `--limit-group-pixels`, makes the output
/// folders and inspects the input, telling its warnings if asked: all before any stage,
/// so that a bad input fails in a moment.
fn load_and_inspect(args: &RecoverArgs, pool: Arc<rayon::ThreadPool>) -> Result<Loaded, Error> {
    let mut input = inspect::read(&args.scene)?;
    // Checked with the scene read, not after the inspection's renders.
    let limited_group = match &args.limit_group_pixels {
        Some((name, _)) => Some(group_named(&args.scene, &input.owned.group_names, name)?),
        None => None,
    };
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
    Ok(Loaded {
        work: RecoveryInput {
            owned,
            real,
            pure,
            pool,
        },
        scene: SceneFacts {
            names,
            kinds,
            mapped,
            unfit_for_a_map,
            overlapping_uv,
            view_names,
            header_divisors,
            obj2rad,
        },
        inspected: Inspected {
            light_readings,
            orientation_readings,
            warnings_told,
        },
        warnings,
        output,
    })
}

/// The recovery's state before stage 1: every group diffuse at [`START_COLOR`].
fn every_group_diffuse(work: RecoveryInput, seed: u64, start: Instant) -> Recovery {
    let RecoveryInput {
        owned,
        real,
        pure,
        pool,
    } = work;
    let views = owned.views.clone();
    let n_groups = owned.group_names.len();
    Recovery {
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
        seed,
        terms_memo: Default::default(),
        started: start,
    }
}

/// What stages 1 to 5 hand on to the refinement, the final render and the report.
struct Staged {
    stages: Vec<StageReport>,
    diffuse_steps: Vec<DiffuseStep>,
    textured: Vec<bool>,
    noise_bound: f64,
    cache_settings: RenderSettings,
}

/// Stages 1 to 5 in order, each on what the ones before found.
fn stages_1_to_5(
    rec: &mut Recovery,
    reports: &mut [GroupReport],
    scene: &SceneFacts,
    args: &RecoverArgs,
    warnings: &mut Vec<String>,
) -> Result<Staged, Error> {
    let (names, kinds) = (&scene.names, &scene.kinds);
    let spp = args.budget.loop_spp;
    let stage1::Stage1 {
        report: stage1_report,
        mut candidates,
        steps: diffuse_steps,
    } = stage1::run(rec, reports, names, spp, warnings)?;
    let mut stages = vec![stage1_report];
    // The groups no view sees whole pass on light too: their stand-ins, measured under
    // stage 1's colours now, and again below under their neighbours' final models.
    stages.extend(unseen::measure_stand_ins(rec, reports, spp, 0x05EE_0001)?);

    let cache_settings = RenderSettings {
        spp: args.budget.cache_spp,
        seed: args.seed ^ 0x1507,
        ..RenderSettings::default()
    };
    let verify_spp = args.budget.loop_spp;
    stages.push(stage2::run(
        rec,
        reports,
        &mut candidates,
        kinds,
        &args.budget,
        &cache_settings,
    )?);

    // Stage 3's textured groups get their maps in stage 5, after stage 4, which may give
    // the untextured stand-in an anisotropic lobe.
    let stage3::Stage3 {
        report: stage3_report,
        mut textured,
        noise_bound,
        warnings: texture_warnings,
    } = stage3::run(
        rec,
        reports,
        kinds,
        &stage3::Coordinates {
            mapped: &scene.mapped,
            unfit_for_a_map: &scene.unfit_for_a_map,
            overlapping: &scene.overlapping_uv,
        },
        verify_spp,
        args.seed,
    )?;
    stages.push(stage3_report);
    warnings.extend(texture_warnings);

    let after_stage2 = rec.models.clone();
    stages.push(stage4::run(
        rec,
        reports,
        &textured,
        kinds,
        &args.budget,
        &cache_settings,
    )?);
    // A uniform anisotropic panel reads as a texture under stage 2's isotropic lobe: stage
    // 3 tests again under stage 4's anisotropic one, and stage 4 fits a group found
    // untextured there again as an untextured group.
    let (untextured, again) = stage3::test_again_under_anisotropic_lobes(
        rec,
        reports,
        &mut textured,
        noise_bound,
        verify_spp,
        args.seed,
    )?;
    stages.extend(again);
    stages.extend(stage4::again_untextured(
        rec,
        reports,
        &untextured,
        &after_stage2,
        (&textured, kinds),
        &args.budget,
        &cache_settings,
    )?);
    stages.push(polish::polish_colours(
        rec,
        reports,
        &textured,
        spp,
        polish::Pass::First,
    )?);

    stages.push(stage5::run(
        rec,
        reports,
        &textured,
        &stage5::MapSettings {
            map_spp: (MAP_SPP_FACTOR * args.budget.final_spp).max(MAP_MIN_SPP),
            seed: args.seed,
            cache_settings: &cache_settings,
            budget: &args.budget,
        },
    )?);
    Ok(Staged {
        stages,
        diffuse_steps,
        textured,
        noise_bound,
        cache_settings,
    })
}

/// The diffuse groups refined again under everything found, the unseen groups' stand-ins
/// measured again and the lobes' colours polished once more.
fn refine_under_everything(
    rec: &mut Recovery,
    reports: &mut [GroupReport],
    textured: &[bool],
    spp: u32,
    stages: &mut Vec<StageReport>,
) -> Result<(), Error> {
    stages.push(stage1::refine_diffuse_groups(rec, reports, spp)?);
    // An unseen group's stand-in and its neighbours' colours depend on each other: the
    // stand-in is measured again under the neighbours' final models, and the diffuse
    // colours refined once more under it (box-diffuse at 64 px with walls_ew withheld:
    // its stand-in 6.3% off in red under stage 1's neighbours, within 1.3% after this).
    if let Some(report) = unseen::measure_stand_ins(rec, reports, spp, 0x05EE_0002)? {
        stages.push(report);
        stages.push(stage1::refine_diffuse_groups(rec, reports, spp)?);
    }
    // The lobes' colours once more, under the maps and diffuse colours now final.
    if polish::any_to_polish(rec, reports, textured) {
        stages.push(polish::polish_colours(
            rec,
            reports,
            textured,
            spp,
            polish::Pass::Final,
        )?);
    }
    Ok(())
}

/// What the final render hands on: the views it wrote and its readings.
struct FinalRender {
    /// Per view, the mean of the two halves: the views and error images written.
    renders: Vec<Vec<Vec3>>,
    view_readings: Vec<ViewReading>,
    report: StageReport,
}

/// Final render: the views, their error images and every group's final error, from two
/// independent halves of at least VIEW_MIN_SAMPLES per view.
fn final_render(
    rec: &mut Recovery,
    reports: &mut [GroupReport],
    scene: &SceneFacts,
    args: &RecoverArgs,
    warnings: &mut Vec<String>,
) -> Result<FinalRender, Error> {
    let (names, view_names) = (&scene.names, &scene.view_names);
    let n_groups = names.len();
    let stage_start = Instant::now();
    let final_spp = args.budget.final_spp;
    let final_seed = args.seed ^ 0xF1A1;
    let smallest_view = rec
        .views
        .iter()
        .map(|v| v.width.saturating_mul(v.height))
        .min();
    let view_spp = min_samples_spp(final_spp, smallest_view.unwrap_or(1), VIEW_MIN_SAMPLES);
    let final_renders = output::render_views(rec, view_spp, final_seed)?;
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
    let view_readings = calibration::read_views(&rec.pure, &rec.real, &renders, view_names);
    warnings.extend(calibration::view_warnings(
        &view_readings,
        calibration::ImageHeaders {
            views: view_names,
            divisors: &scene.header_divisors,
        },
    ));
    record_texture_features(rec, reports, &renders);
    let report = StageReport {
        stage: "final render".into(),
        evaluations: 1,
        samples_per_pixel: spp_per_half.saturating_mul(2),
        seconds: stage_start.elapsed().as_secs_f64(),
        notes: vec![
            format!("every view rendered twice with independent samples, {} spp each (at least the effort's {final_spp} and VIEW_MIN_SAMPLES {VIEW_MIN_SAMPLES} per view in all): the views, error images and view readings are their mean; error_final is each group's bias-only error from the two", spp_per_half),
        ],
    };
    Ok(FinalRender {
        renders,
        view_readings,
        report,
    })
}

/// The paper's own texture feature, on the final render's difference image: reported
/// beside the statistic stage 3 decides on, since on our references it does not
/// separate the classes (docs/recovery.md).
fn record_texture_features(rec: &Recovery, reports: &mut [GroupReport], renders: &[Vec<Vec3>]) {
    let n_groups = reports.len();
    let differences = pixels::step_differences(
        pixels::Observed {
            views: &rec.views,
            real: &rec.real,
            pure: &rec.pure,
        },
        renders,
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
}

/// Where the stability study saw recovery fail, said of this run's groups.
fn stability_warnings(
    rec: &Recovery,
    reports: &[GroupReport],
    scene: &SceneFacts,
    noise_bound: f64,
    budget: &Budget,
) -> Vec<String> {
    warnings::stability_warnings(&warnings::Inputs {
        groups: reports,
        models: &rec.models,
        panorama_noise_bound: noise_bound,
        view_sides: &scene
            .view_names
            .iter()
            .cloned()
            .zip(rec.views.iter().map(|v| v.width.min(v.height)))
            .collect::<Vec<_>>(),
        budget,
        mapped: &scene.mapped,
    })
}

/// What report.json holds of the run.
fn recover_report(
    args: &RecoverArgs,
    start: Instant,
    inspected: Inspected,
    staged: Staged,
    view_readings: Vec<ViewReading>,
    reports: Vec<GroupReport>,
    warnings: Vec<String>,
) -> RecoverReport {
    let Inspected {
        light_readings,
        orientation_readings,
        warnings_told,
    } = inspected;
    RecoverReport {
        scene: args.scene.display().to_string(),
        seed: args.seed,
        budget: args.budget,
        error_definition: "relative error over the group's pure pixels, RGB pooled (relume_core::fit): error_diffuse, error_decided, error_final and every comparison are bias-only, sqrt(max(0, sum (A-T).(B-T)) / sum |T|^2) with A, B two renders with independent samples; error_initial is sqrt(max(0, sum |R-T|^2 - sum var(R)) / sum |T|^2) of one render",
        thresholds: thresholds(),
        panorama_noise_bound: staged.noise_bound,
        light_readings,
        view_readings,
        orientation_readings,
        stages: staged.stages,
        diffuse_steps: staged.diffuse_steps,
        groups: reports,
        warnings,
        warnings_told,
        seconds: start.elapsed().as_secs_f64(),
    }
}

/// Every threshold the recovery decides by, under its name in the code, for report.json.
fn thresholds() -> serde_json::Value {
    serde_json::json!({
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
    })
}
