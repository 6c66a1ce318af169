//! `relume bench edits`: how well a recovered model serves what users do with it.
//!
//! An edit is a scene.toml (other lights, another viewpoint, objects hidden or added) whose
//! view images are a reference render of that edit with the true materials. relume renders
//! each edit with the same seed, once with the recovered materials and once with the true
//! ones, and compares both with the reference over pure pixels. The true materials' error
//! is what relume's renderer itself leaves (its noise and its differences from the
//! reference renderer); the recovered model is judged by how much it adds to that, as the
//! ratio of the two errors against [`RATIO_GOAL`].
//!
//! Each is rendered once more on the next seed, so that both errors are also given with
//! the render noise taken out (`compare views --independent`). Render noise adds to both
//! errors alike and pulls their ratio towards 1 where it dominates, or away from it where
//! one model renders noisier than the other (a sharper lobe that catches a light); without
//! it, the ratio weighs the models' misfits alone.
//!
//! Objects an edit puts in need materials no recovery gave: they come from the file
//! [`ADDED_MATERIALS`] beside the edit's scene.toml, given to both renders.

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::assemble::{self, MaterialSource};
use crate::bench::{field, Csv};
use crate::compare::{self, Groups, ViewImages, ViewsReport};
use crate::error::Error;
use crate::fsutil::{self, OutputSet};
use crate::materials_file::{self, MaterialsDesc};
use crate::parallel;
use crate::render_cmd::{self, RenderArgs};
use crate::scene_file;

/// The goal: an edit rendered from the recovered model is within 1.2x the error of
/// the same edit rendered with the true materials.
pub const RATIO_GOAL: f64 = 1.2;

/// The materials of objects an edit adds, beside its scene.toml.
pub const ADDED_MATERIALS: &str = "materials.toml";

#[derive(clap::Args)]
pub struct EditsArgs {
    /// The edits' scene.toml files; their view images are the references.
    #[arg(required = true, num_args = 1..)]
    pub edits: Vec<PathBuf>,
    /// The recovered materials.toml, and with it any more files the recovered model
    /// is rendered with (its unseen.toml: the stand-ins of groups not recovered).
    #[arg(long, required = true, num_args = 1..)]
    pub recovered: Vec<PathBuf>,
    /// The true materials (truth.toml).
    #[arg(long)]
    pub truth: PathBuf,
    /// Output folder: the renders, the CSV and the JSON.
    #[arg(long)]
    pub out: PathBuf,
    /// Samples per pixel of every render (relume's noise is in both errors as they are:
    /// enough that it does not hide the recovered model's own).
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..))]
    pub spp: u32,
    /// Seed of each model's first render; its second, for the errors with the render
    /// noise taken out, is on the next seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads (default: all cores); the figures do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
}

/// One render of an edit against its reference.
#[derive(Serialize, Clone, Debug)]
pub struct ArmError {
    /// RMS of the difference over all pure pixels, relative to the reference's mean.
    pub rel_rms: f64,
    /// Mean over the groups seen of |mean rendered - mean reference| / mean reference.
    pub group_mean_err: f64,
    /// `rel_rms` with the render noise taken out: the misfit over all pure pixels
    /// ([`compare::ViewsRow::rel_misfit`], from the render on the next seed).
    pub misfit: f64,
    /// `group_mean_err` with the render noise taken out: the mean over the groups seen of
    /// |[`compare::ViewsRow::rel_mean_bias`]|.
    pub group_mean_bias: f64,
    /// The full comparison, group by group and view by view.
    pub views: ViewsReport,
}

impl ArmError {
    fn of(views: ViewsReport) -> ArmError {
        let seen: Vec<&compare::ViewsRow> = views
            .groups
            .iter()
            .filter(|g| g.pixels > 0 && g.rel_mean_diff.is_finite())
            .collect();
        let mean_over_seen = |f: fn(&compare::ViewsRow) -> f64| {
            seen.iter().map(|g| f(g).abs()).sum::<f64>() / seen.len().max(1) as f64
        };
        ArmError {
            rel_rms: views.all.rel_rms,
            group_mean_err: mean_over_seen(|g| g.rel_mean_diff),
            misfit: views.all.rel_misfit.unwrap_or(f64::NAN),
            group_mean_bias: mean_over_seen(|g| g.rel_mean_bias.unwrap_or(f64::NAN)),
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
    /// `recovered.misfit / truth.misfit`.
    pub misfit_ratio: f64,
    /// `recovered.group_mean_bias / truth.group_mean_bias`.
    pub group_mean_bias_ratio: f64,
    /// Both ratios with the render noise taken out within [`RATIO_GOAL`].
    pub within_goal_noise_out: bool,
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
    let set = prepare(args)?;
    // Before the folder is made: a bad --threads left it behind, empty.
    parallel::check_threads(args.threads)?;
    fsutil::create_dir(&args.out)?;
    let mut outcomes = Vec::new();
    for scene in &args.edits {
        let name = edit_name(scene);
        let added = added_materials(scene);
        let arm = |materials: &[PathBuf], label: &str| -> Result<ArmError, Error> {
            let [out, independent] = arm_folders(&args.out.join(&name), label);
            eprintln!("{name}: rendering with the {label} materials, twice");
            for (out, seed) in [
                (&out, args.seed),
                (&independent, independent_seed(args.seed)),
            ] {
                render_cmd::run(&RenderArgs {
                    scene: scene.clone(),
                    materials: materials.iter().cloned().chain(added.clone()).collect(),
                    out: out.clone(),
                    spp: args.spp,
                    seed,
                    threads: args.threads,
                    views: Vec::new(),
                })?;
            }
            let views = compare::views_report_of(
                scene,
                ViewImages::Scene,
                ViewImages::Folder(&out),
                Some(ViewImages::Folder(&independent)),
                &[],
                args.threads,
            )?;
            Ok(ArmError::of(views))
        };
        let recovered = arm(&args.recovered, "recovered")?;
        let truth = arm(std::slice::from_ref(&args.truth), "truth")?;
        let rms_ratio = ratio(recovered.rel_rms, truth.rel_rms);
        let group_mean_ratio = ratio(recovered.group_mean_err, truth.group_mean_err);
        let misfit_ratio = ratio(recovered.misfit, truth.misfit);
        let group_mean_bias_ratio = ratio(recovered.group_mean_bias, truth.group_mean_bias);
        outcomes.push(EditOutcome {
            edit: name,
            scene: scene.display().to_string(),
            pixels: truth.views.all.pixels,
            within_goal: meets_goal(rms_ratio, group_mean_ratio),
            within_goal_noise_out: meets_goal(misfit_ratio, group_mean_bias_ratio),
            recovered,
            truth,
            rms_ratio,
            group_mean_ratio,
            misfit_ratio,
            group_mean_bias_ratio,
        });
    }
    write_outputs(set, &args.out, &outcomes)?;
    Ok(outcomes)
}

/// An arm's two render folders under an edit's: `<label>` on the seed given and
/// `<label>-independent` on [`independent_seed`].
fn arm_folders(edit_out: &Path, label: &str) -> [PathBuf; 2] {
    [label.to_string(), format!("{label}-independent")].map(|l| edit_out.join(l))
}

/// The seed of an arm's second render: the next one, so that `relume render --seed S+1`
/// gives the same image.
fn independent_seed(seed: u64) -> u64 {
    seed.wrapping_add(1)
}

/// The files' paths as one, for a message about their groups together: `a.toml` or
/// `a.toml + b.toml`.
fn files_label(files: &[MaterialsDesc]) -> PathBuf {
    let names: Vec<String> = files.iter().map(|f| f.path.display().to_string()).collect();
    PathBuf::from(names.join(" + "))
}

/// The materials file beside an edit's scene.toml, for the objects it adds, if any.
fn added_materials(scene: &Path) -> Option<PathBuf> {
    scene
        .parent()
        .map(|d| d.join(ADDED_MATERIALS))
        .filter(|p| p.is_file() && p != scene)
}

/// The checks made before the first render, which otherwise met a truth of another scene
/// or a missing reference image only after minutes of rendering: each edit's groups get
/// their materials from the recovered and the true file (and its added materials),
/// exactly (a group-set mismatch names the groups on each side); each edit renders with
/// both (every other error of a material); its views name reference images that exist;
/// and no output replaces an input. Returns the set for the CSV and the JSON.
fn prepare(args: &EditsArgs) -> Result<OutputSet, Error> {
    if args.recovered.is_empty() {
        return Err(Error::Usage(
            "give --recovered the recovered materials.toml".into(),
        ));
    }
    if let Some((m, first)) = fsutil::given_twice(&args.recovered) {
        return Err(Error::Usage(format!(
            "{} is given twice to --recovered (also as {}): each of its groups would have two materials",
            m.display(),
            first.display()
        )));
    }
    let recovered = args
        .recovered
        .iter()
        .map(|path| materials_file::load_materials(path))
        .collect::<Result<Vec<_>, Error>>()?;
    let truth = materials_file::load_materials(&args.truth)?;
    let mut inputs = truth.input_files();
    inputs.extend(recovered.iter().flat_map(|r| r.input_files()));
    let mut outputs = Vec::new();
    let hint = format!(
        "a file of another scene? A group only the edit has takes its material from {ADDED_MATERIALS} beside its scene.toml"
    );
    // A recovery writes the stand-ins of the groups it could not recover apart.
    let unseen_hint = |first: &Path| {
        let unseen = first.with_file_name(crate::recover::UNSEEN_TOML);
        let given = args.recovered.iter().any(|r| fsutil::same_file(r, &unseen));
        if unseen.is_file() && !given {
            format!("{hint}; a group the recovery could not recover has its stand-in in {}: give it to --recovered too", unseen.display())
        } else {
            hint.clone()
        }
    };
    for scene in &args.edits {
        let desc = scene_file::load_scene(scene)?;
        let added = match added_materials(scene) {
            Some(path) => {
                // Given as well as --recovered or --truth, its groups would have two
                // materials, or the whole file would look like one of another scene.
                let given = args.recovered.iter().map(|r| ("--recovered", r));
                for (flag, given) in given.chain([("--truth", &args.truth)]) {
                    if fsutil::same_file(&path, given) {
                        return Err(Error::Usage(format!(
                            "{flag} {} is also {}, which gives the materials of the objects edit {} adds (read from beside its scene.toml): give {flag} a file of its own",
                            given.display(),
                            path.display(),
                            scene.display()
                        )));
                    }
                }
                Some(materials_file::load_materials(&path)?)
            }
            None => None,
        };
        let added_groups: Vec<&str> = added
            .iter()
            .flat_map(|a| a.materials.iter().map(|m| m.group.as_str()))
            .collect();
        let own: Vec<&str> = desc
            .groups
            .iter()
            .map(|g| g.name.as_str())
            .filter(|g| !added_groups.contains(g))
            .collect();
        for (files, hint) in [
            (std::slice::from_ref(&truth), hint.clone()),
            (&recovered[..], unseen_hint(&recovered[0].path)),
        ] {
            let groups: Vec<&str> = files
                .iter()
                .flat_map(|f| f.materials.iter().map(|m| m.group.as_str()))
                .collect();
            compare::check_groups(
                &files_label(files),
                &groups,
                "the edit",
                scene,
                &own,
                Groups::Same,
                &hint,
            )?;
            let files: Vec<MaterialsDesc> = files.iter().cloned().chain(added.clone()).collect();
            assemble::load_and_assemble(scene, MaterialSource::Files(&files))?;
        }
        // Read whole, as the judging reads them: a reference that exists but is empty,
        // cut short or holds a NaN was met only after the renders before it.
        for (vi, view) in desc.views.iter().enumerate() {
            desc.view_image(vi, "an edit's views are its reference")?;
            ViewImages::Scene.read(view, scene)?;
        }
        let name = edit_name(scene);
        for arm in ["recovered", "truth"] {
            for folder in arm_folders(&args.out.join(&name), arm) {
                outputs.extend(render_cmd::output_files(
                    &folder,
                    desc.views.iter().map(|v| v.name.as_str()),
                ));
            }
        }
        inputs.extend(desc.input_files());
        inputs.extend(added.iter().flat_map(|a| a.input_files()));
    }
    outputs.extend(["edits.csv", "edits.json"].map(|f| args.out.join(f)));
    let set = OutputSet::keeping(inputs);
    set.check_targets(outputs)?;
    Ok(set)
}

fn write_outputs(mut set: OutputSet, out: &Path, outcomes: &[EditOutcome]) -> Result<(), Error> {
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
        "misfit_recovered",
        "misfit_truth",
        "misfit_ratio",
        "group_mean_bias_recovered",
        "group_mean_bias_truth",
        "group_mean_bias_ratio",
        "within_goal_noise_out",
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
            field(Some(o.recovered.misfit)),
            field(Some(o.truth.misfit)),
            field(Some(o.misfit_ratio)),
            field(Some(o.recovered.group_mean_bias)),
            field(Some(o.truth.group_mean_bias)),
            field(Some(o.group_mean_bias_ratio)),
            o.within_goal_noise_out.to_string(),
        ]);
    }
    set.add(&out.join("edits.csv"), csv.to_text().as_bytes())?;
    let json = serde_json::to_string_pretty(outcomes).map_err(|e| Error::Usage(e.to_string()))?;
    set.add(&out.join("edits.json"), json.as_bytes())?;
    set.commit()
}

/// The table a person reads: one line per edit, as the errors are and with the render
/// noise taken out, then the groups where the recovered model adds the most error.
pub fn print_table(outcomes: &[EditOutcome]) {
    print_errors(
        outcomes,
        ["rel RMS rec / truth", "group mean rec / truth"],
        |a| [a.rel_rms, a.group_mean_err],
        |o| ([o.rms_ratio, o.group_mean_ratio], o.within_goal),
    );
    println!("with the render noise taken out (a second render of each on seed + 1):");
    print_errors(
        outcomes,
        ["misfit rec / truth", "group bias rec / truth"],
        |a| [a.misfit, a.group_mean_bias],
        |o| {
            (
                [o.misfit_ratio, o.group_mean_bias_ratio],
                o.within_goal_noise_out,
            )
        },
    );
    for o in outcomes {
        let mut added: Vec<(String, f64, f64)> = o
            .recovered
            .views
            .groups
            .iter()
            .zip(&o.truth.views.groups)
            .filter_map(|(r, t)| Some((r.name.clone(), r.rel_mean_bias?, t.rel_mean_bias?)))
            .filter(|(_, r, t)| r.is_finite() && t.is_finite())
            .collect();
        added.sort_by(|a, b| (b.1.abs() - b.2.abs()).total_cmp(&(a.1.abs() - a.2.abs())));
        let worst: Vec<String> = added
            .iter()
            .take(3)
            .map(|(g, r, t)| format!("{g} {:+.1}% (truth {:+.1}%)", 100.0 * r, 100.0 * t))
            .collect();
        println!(
            "  {}: most added bias (noise out) in {}",
            o.edit,
            worst.join(", ")
        );
    }
}

/// One block of [`print_table`]: per edit, two errors of each arm (`errors`) and their
/// ratios with the verdict (`ratios`).
fn print_errors(
    outcomes: &[EditOutcome],
    headers: [&str; 2],
    errors: impl Fn(&ArmError) -> [f64; 2],
    ratios: impl Fn(&EditOutcome) -> ([f64; 2], bool),
) {
    println!(
        "{:<12} {:>7} {:>22} {:>7} {:>24} {:>7}  goal {RATIO_GOAL}x",
        "edit", "pixels", headers[0], "ratio", headers[1], "ratio"
    );
    // A ratio against an error of 0 is undefined (and not a pass): `-`, not `NaN`.
    let ratio = |r: f64| {
        if r.is_finite() {
            format!("{r:.2}")
        } else {
            "-".into()
        }
    };
    for o in outcomes {
        let ([rec_a, rec_b], [truth_a, truth_b]) = (errors(&o.recovered), errors(&o.truth));
        let ([ratio_a, ratio_b], met) = ratios(o);
        println!(
            "{:<12} {:>7} {:>10.2}% / {:>6.2}% {:>7} {:>11.2}% / {:>7.2}% {:>7}  {}",
            o.edit,
            o.pixels,
            100.0 * rec_a,
            100.0 * truth_a,
            ratio(ratio_a),
            100.0 * rec_b,
            100.0 * truth_b,
            ratio(ratio_b),
            if met { "met" } else { "missed" }
        );
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

    /// An edit of the bundled scene in `dir/<name>/scene.toml`: the scene as it is, with
    /// paths to its geometry and panorama (the references).
    fn cornell_edit(dir: &Path, name: &str) -> PathBuf {
        let cornell = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell");
        let text = std::fs::read_to_string(cornell.join("scene.toml"))
            .unwrap()
            .replace(
                "\"geometry.obj\"",
                &format!("{:?}", cornell.join("geometry.obj")),
            )
            .replace(
                "\"views/",
                &format!("\"{}/", cornell.join("views").display()),
            );
        std::fs::create_dir_all(dir.join(name)).unwrap();
        let scene = dir.join(name).join("scene.toml");
        std::fs::write(&scene, text).unwrap();
        scene
    }

    #[test]
    fn a_truth_of_another_scene_or_an_output_over_an_input_is_refused_before_any_render() {
        let dir = tempfile::tempdir().unwrap();
        let cornell = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell");
        let edit = cornell_edit(dir.path(), "same");
        let other = dir.path().join("other.toml");
        let text = std::fs::read_to_string(cornell.join("materials.toml")).unwrap();
        std::fs::write(&other, text.replace("\"sphere\"", "\"statue\"")).unwrap();
        let args = |truth: &Path| EditsArgs {
            edits: vec![edit.clone()],
            recovered: vec![cornell.join("materials.toml")],
            truth: truth.to_path_buf(),
            out: dir.path().join("out"),
            spp: 1,
            seed: 1,
            threads: Some(1),
        };
        let e = run(&args(&other)).err().unwrap().to_string();
        assert!(
            e.contains("other.toml: its groups are not those of the edit")
                && e.contains("only in this file: 'statue'; only in the edit: 'sphere'"),
            "{e}"
        );
        assert!(!dir.path().join("out").exists(), "nothing rendered");
        // The truth where the run writes its JSON.
        let inside = dir.path().join("out/edits.json");
        std::fs::create_dir_all(inside.parent().unwrap()).unwrap();
        std::fs::write(&inside, &text).unwrap();
        let e = run(&args(&inside)).err().unwrap().to_string();
        assert!(e.contains("would replace a materials file"), "{e}");
        assert!(!dir.path().join("out/same").exists(), "nothing rendered");
        assert_eq!(std::fs::read_to_string(&inside).unwrap(), text);
    }

    /// A later edit's reference image that exists but is no image (or a bad --threads)
    /// is refused before the first render, and leaves no folder: the first edit's
    /// renders were left behind, with no table.
    #[test]
    fn a_later_edits_bad_reference_or_threads_is_refused_before_any_render() {
        let dir = tempfile::tempdir().unwrap();
        let cornell = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/cornell");
        let first = cornell_edit(dir.path(), "first");
        let second = cornell_edit(dir.path(), "second");
        let empty = dir.path().join("second/empty.exr");
        std::fs::write(&empty, b"").unwrap();
        let nz = format!("{:?}", cornell.join("views/nz.exr").display().to_string());
        let text = std::fs::read_to_string(&second).unwrap();
        assert!(text.contains(&nz), "{text}");
        std::fs::write(&second, text.replace(&nz, "\"empty.exr\"")).unwrap();
        let out = dir.path().join("out");
        let args = |edits: Vec<PathBuf>, threads| EditsArgs {
            edits,
            recovered: vec![cornell.join("materials.toml")],
            truth: cornell.join("materials.toml"),
            out: out.clone(),
            spp: 1,
            seed: 1,
            threads,
        };
        let e = run(&args(vec![first.clone(), second], Some(1)))
            .err()
            .unwrap();
        assert_eq!(e.exit_code(), 3, "{e}");
        assert!(
            e.to_string().contains("empty.exr: the file is empty"),
            "{e}"
        );
        assert!(!out.exists(), "nothing rendered");
        let e = run(&args(vec![first], Some(0))).err().unwrap();
        assert_eq!(e.exit_code(), 2, "{e}");
        assert!(!out.exists(), "no folder made");
    }
}
