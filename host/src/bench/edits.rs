//! `relume bench edits`: how well a recovered model serves what users do with it.
//!
//! An edit is a scene.toml (other lights, another viewpoint, objects hidden or added) whose
//! view images are a reference render of that edit with the true materials. relume renders
//! each edit twice with the same seed, once with the recovered materials and once with the
//! true ones, and compares both with the reference over pure pixels. The true materials'
//! error is what relume's renderer itself leaves (its noise and its differences from the
//! reference renderer); the recovered model is judged by how much it adds to that, as the
//! ratio of the two errors against [`RATIO_GOAL`].
//!
//! Objects an edit puts in need materials no recovery gave: they come from the file
//! [`ADDED_MATERIALS`] beside the edit's scene.toml, given to both renders.

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::bench::{field, Csv};
use crate::compare::{self, ViewImages, ViewsReport};
use crate::error::Error;
use crate::fsutil::{self, OutputSet};
use crate::render_cmd::{self, RenderArgs};

/// The goal: an edit rendered from the recovered model is within 1.2x the error of
/// the same edit rendered with the true materials.
pub const RATIO_GOAL: f64 = 1.2;

/// The materials of objects an edit adds, beside its scene.toml.
pub const ADDED_MATERIALS: &str = "materials.toml";

pub struct EditsArgs {
    /// The edits' scene.toml files.
    pub edits: Vec<PathBuf>,
    /// The recovered materials.toml.
    pub recovered: PathBuf,
    /// The true materials (truth.toml).
    pub truth: PathBuf,
    pub out: PathBuf,
    pub spp: u32,
    pub seed: u64,
    pub threads: Option<usize>,
}

/// One render of an edit against its reference.
#[derive(Serialize, Clone, Debug)]
pub struct ArmError {
    /// RMS of the difference over all pure pixels, relative to the reference's mean.
    pub rel_rms: f64,
    /// Mean over the groups seen of |mean rendered - mean reference| / mean reference.
    pub group_mean_err: f64,
    /// The full comparison, group by group and view by view.
    pub views: ViewsReport,
}

impl ArmError {
    fn of(views: ViewsReport) -> ArmError {
        let seen: Vec<f64> = views
            .groups
            .iter()
            .filter(|g| g.pixels > 0 && g.rel_mean_diff.is_finite())
            .map(|g| g.rel_mean_diff.abs())
            .collect();
        ArmError {
            rel_rms: views.all.rel_rms,
            group_mean_err: seen.iter().sum::<f64>() / seen.len().max(1) as f64,
            views,
        }
    }
}

/// One edit: both renders' errors and their ratios.
#[derive(Serialize, Clone, Debug)]
pub struct EditOutcome {
    pub edit: String,
    pub scene: String,
    pub pixels: u64,
    pub recovered: ArmError,
    pub truth: ArmError,
    /// `recovered.rel_rms / truth.rel_rms`.
    pub rms_ratio: f64,
    /// `recovered.group_mean_err / truth.group_mean_err`.
    pub group_mean_ratio: f64,
    /// Both ratios within [`RATIO_GOAL`].
    pub within_goal: bool,
}

/// The edit's name: its folder when the file is `scene.toml`, else the file's stem.
fn edit_name(scene: &Path) -> String {
    let stem = scene.file_stem().and_then(|s| s.to_str()).unwrap_or("edit");
    if stem == "scene" {
        if let Some(dir) = scene
            .parent()
            .and_then(|d| d.file_name())
            .and_then(|d| d.to_str())
        {
            return dir.to_string();
        }
    }
    stem.to_string()
}

fn ratio(a: f64, b: f64) -> f64 {
    if b > 0.0 {
        a / b
    } else {
        f64::NAN
    }
}

/// Both ratios within the goal; an undefined ratio (no reference error) is not a pass.
fn meets_goal(rms_ratio: f64, group_mean_ratio: f64) -> bool {
    rms_ratio <= RATIO_GOAL && group_mean_ratio <= RATIO_GOAL
}

/// Renders and judges every edit; writes `edits.csv`, `edits.json` and the renders under
/// `<out>/<edit>/{recovered,truth}/`.
pub fn run(args: &EditsArgs) -> Result<Vec<EditOutcome>, Error> {
    if args.edits.is_empty() {
        return Err(Error::Usage("give at least one edit's scene.toml".into()));
    }
    let mut names: Vec<String> = args.edits.iter().map(|e| edit_name(e)).collect();
    names.sort();
    if let Some(w) = names.windows(2).find(|w| w[0] == w[1]) {
        return Err(Error::Usage(format!(
            "two edits are named '{}': their outputs would share a folder",
            w[0]
        )));
    }
    fsutil::create_dir(&args.out)?;
    let mut outcomes = Vec::new();
    for scene in &args.edits {
        let name = edit_name(scene);
        let added = scene
            .parent()
            .map(|d| d.join(ADDED_MATERIALS))
            .filter(|p| p.is_file() && p != scene);
        let arm = |materials: &Path, label: &str| -> Result<ArmError, Error> {
            let out = args.out.join(&name).join(label);
            eprintln!("{name}: rendering with the {label} materials");
            render_cmd::run(&RenderArgs {
                scene: scene.clone(),
                materials: std::iter::once(materials.to_path_buf())
                    .chain(added.clone())
                    .collect(),
                out: out.clone(),
                spp: args.spp,
                seed: args.seed,
                threads: args.threads,
                views: Vec::new(),
            })?;
            let views = compare::views_report_of(
                scene,
                ViewImages::Scene,
                ViewImages::Folder(&out),
                args.threads,
            )?;
            Ok(ArmError::of(views))
        };
        let recovered = arm(&args.recovered, "recovered")?;
        let truth = arm(&args.truth, "truth")?;
        let rms_ratio = ratio(recovered.rel_rms, truth.rel_rms);
        let group_mean_ratio = ratio(recovered.group_mean_err, truth.group_mean_err);
        outcomes.push(EditOutcome {
            edit: name,
            scene: scene.display().to_string(),
            pixels: truth.views.all.pixels,
            within_goal: meets_goal(rms_ratio, group_mean_ratio),
            recovered,
            truth,
            rms_ratio,
            group_mean_ratio,
        });
    }
    write_outputs(&args.out, &outcomes)?;
    Ok(outcomes)
}

fn write_outputs(out: &Path, outcomes: &[EditOutcome]) -> Result<(), Error> {
    let mut csv = Csv::new(&[
        "edit",
        "pixels",
        "rel_rms_recovered",
        "rel_rms_truth",
        "rms_ratio",
        "group_mean_err_recovered",
        "group_mean_err_truth",
        "group_mean_ratio",
        "within_goal",
    ]);
    for o in outcomes {
        csv.push(vec![
            o.edit.clone(),
            o.pixels.to_string(),
            field(Some(o.recovered.rel_rms)),
            field(Some(o.truth.rel_rms)),
            field(Some(o.rms_ratio)),
            field(Some(o.recovered.group_mean_err)),
            field(Some(o.truth.group_mean_err)),
            field(Some(o.group_mean_ratio)),
            o.within_goal.to_string(),
        ]);
    }
    let mut set = OutputSet::default();
    set.add(&out.join("edits.csv"), csv.to_text().as_bytes())?;
    let json = serde_json::to_string_pretty(outcomes).map_err(|e| Error::Usage(e.to_string()))?;
    set.add(&out.join("edits.json"), json.as_bytes())?;
    set.commit()
}

/// The table a person reads: one line per edit, then the groups where the recovered model
/// adds the most error.
pub fn print_table(outcomes: &[EditOutcome]) {
    println!(
        "{:<12} {:>7} {:>22} {:>7} {:>24} {:>7}  goal {RATIO_GOAL}x",
        "edit", "pixels", "rel RMS rec / truth", "ratio", "group mean rec / truth", "ratio"
    );
    for o in outcomes {
        println!(
            "{:<12} {:>7} {:>10.2}% / {:>6.2}% {:>7.2} {:>11.2}% / {:>7.2}% {:>7.2}  {}",
            o.edit,
            o.pixels,
            100.0 * o.recovered.rel_rms,
            100.0 * o.truth.rel_rms,
            o.rms_ratio,
            100.0 * o.recovered.group_mean_err,
            100.0 * o.truth.group_mean_err,
            o.group_mean_ratio,
            if o.within_goal { "met" } else { "missed" }
        );
    }
    for o in outcomes {
        let mut added: Vec<(String, f64, f64)> = o
            .recovered
            .views
            .groups
            .iter()
            .zip(&o.truth.views.groups)
            .filter(|(r, _)| r.pixels > 0)
            .map(|(r, t)| (r.name.clone(), r.rel_mean_diff, t.rel_mean_diff))
            .collect();
        added.sort_by(|a, b| (b.1.abs() - b.2.abs()).total_cmp(&(a.1.abs() - a.2.abs())));
        let worst: Vec<String> = added
            .iter()
            .take(3)
            .map(|(g, r, t)| format!("{g} {:+.1}% (truth {:+.1}%)", 100.0 * r, 100.0 * t))
            .collect();
        println!("  {}: most added error in {}", o.edit, worst.join(", "));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_edit_is_named_by_its_folder_or_its_file() {
        assert_eq!(edit_name(Path::new("edits/relit/scene.toml")), "relit");
        assert_eq!(edit_name(Path::new("edits/relit.toml")), "relit");
    }

    #[test]
    fn a_ratio_against_nothing_is_not_a_pass() {
        assert!(ratio(0.1, 0.0).is_nan());
        assert!(!meets_goal(ratio(0.1, 0.0), 1.0));
        assert!(meets_goal(1.2, 0.5));
        assert!(!meets_goal(1.0, 1.21));
    }
}
