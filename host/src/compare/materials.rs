//! `relume compare materials`: recovered materials against the truth, group by group:
//! classes (models) right, relative errors of their parameters, the error of the
//! direction, the diffuse map's figures (`maps`), and with the truth's scene its kinds and
//! specular reflectance.

use std::collections::BTreeMap;
use std::path::Path;

use relume_core::material::Kind;
use serde::Serialize;

use super::maps::{psnr_json, set_map_measures};
use super::{check_groups, groups_of, Groups};
use crate::error::Error;
use crate::fsutil::{self, OutputSet};
use crate::materials_file::{self, MaterialDesc, MaterialsDesc, Model};
use crate::scene_file::{self, SceneDesc};

/// Errors of one recovered material against the truth; `None` where the parameter does not
/// apply to both, but for the specularity, which a model without a lobe has as 0: a lobe
/// missed reads 100% there (and no roughness error).
#[derive(Serialize, Debug, Default)]
pub struct MaterialRow {
    pub group: String,
    pub true_model: String,
    pub model: Option<String>,
    pub class_ok: bool,
    /// Mean over channels of |rho_d - rho_d true| / rho_d true, with rho_d = color (1 - s).
    pub diffuse_rel_err: Option<f64>,
    pub specularity_rel_err: Option<f64>,
    pub roughness_rel_err: Option<f64>,
    pub roughness_u_rel_err: Option<f64>,
    pub roughness_v_rel_err: Option<f64>,
    /// Angle between the u directions, sign ignored (d and -d are the same material).
    pub direction_err_deg: Option<f64>,
    /// PSNR of the diffuse map over all texels, peak = the truth's maximum. Infinite for a
    /// map equal to the truth's, written `"inf"` in JSON.
    #[serde(serialize_with = "psnr_json")]
    pub diffuse_map_psnr_db: Option<f64>,
    /// The same PSNR for the truth area-averaged to the recovered map's size: the most a
    /// map of that resolution can reach.
    #[serde(serialize_with = "psnr_json")]
    pub diffuse_map_psnr_ceiling_db: Option<f64>,
    /// The recovered map's mean luminance over the truth's, less 1 (signed): its level,
    /// which the panorama sees only through the lobe beside it (a lobe sending too much
    /// light towards the views leaves its map too dark; docs/edits.md).
    pub diffuse_map_level_err: Option<f64>,
    /// With `--scene`, where both models have a lobe: the kind of the recovered lobe (its
    /// material's `kind`, written for a group of kind "auto", else the scene's) and the
    /// truth's (the scene's).
    pub kind: Option<String>,
    pub true_kind: Option<String>,
    /// With `--scene`, where both models have a lobe: mean over channels of
    /// |S - S true| / S true, with S = s for plastic and c s for metal (reflectance.md).
    /// Where the kinds differ, `specularity` means different things on the two sides; this
    /// compares the light the lobes reflect.
    pub specular_reflectance_rel_err: Option<f64>,
}

fn rel(a: f64, truth: f64) -> f64 {
    if truth != 0.0 {
        (a - truth).abs() / truth.abs()
    } else {
        a.abs()
    }
}

fn diffuse_of(m: &MaterialDesc) -> Option<[f64; 3]> {
    let c = m.color?;
    let s = m.specularity.unwrap_or(0.0) as f64;
    match m.model {
        Model::Mirror => None,
        _ => Some(c.map(|c| c as f64 * (1.0 - s))),
    }
}

/// The specular reflectance S of a lobe of `kind` (reflectance.md): s, white, for
/// plastic; c s for metal. `None` without a specularity or, for metal, a colour.
fn specular_reflectance_of(m: &MaterialDesc, kind: Kind) -> Option<[f64; 3]> {
    let s = m.specularity? as f64;
    match kind {
        Kind::Plastic => Some([s; 3]),
        Kind::Metal => Some(m.color?.map(|c| c as f64 * s)),
    }
}

/// Each group of the truth against `materials` (its row `(missing)` where `materials` has
/// no entry for it). Errors: a file that does not parse, and one whose groups do not fit
/// the truth's ([`check_groups`], [`Groups::Within`]).
pub fn materials_report(truth: &Path, materials: &Path) -> Result<Vec<MaterialRow>, Error> {
    let t = materials_file::load_materials(truth)?;
    let m = materials_file::load_materials(materials)?;
    materials_rows(&t, &m)
}

/// [`materials_report`] of files already read.
fn materials_rows(t: &MaterialsDesc, m: &MaterialsDesc) -> Result<Vec<MaterialRow>, Error> {
    // A recovery writes no entry for a group no pixel sees: the truth may have more
    // groups, but a group the truth lacks means a file of another scene, whose groups
    // were dropped in silence ("2 of 11 classes right").
    check_groups(
        &m.path,
        &groups_of(m),
        "the truth",
        &t.path,
        &groups_of(t),
        Groups::Within,
        "a file of another scene?",
    )?;
    let by_group: BTreeMap<&str, &MaterialDesc> =
        m.materials.iter().map(|d| (d.group.as_str(), d)).collect();
    let mut rows = Vec::new();
    for tm in &t.materials {
        let mut row = MaterialRow {
            group: tm.group.clone(),
            true_model: tm.model.name().into(),
            ..MaterialRow::default()
        };
        if let Some(rm) = by_group.get(tm.group.as_str()) {
            row.model = Some(rm.model.name().into());
            row.class_ok = rm.model == tm.model;
            if let (Some(a), Some(b)) = (diffuse_of(rm), diffuse_of(tm)) {
                row.diffuse_rel_err = Some((0..3).map(|c| rel(a[c], b[c])).sum::<f64>() / 3.0);
            }
            if tm.model == Model::Mirror {
                if let (Some(a), Some(b)) = (rm.color, tm.color) {
                    row.diffuse_rel_err =
                        Some((0..3).map(|c| rel(a[c] as f64, b[c] as f64)).sum::<f64>() / 3.0);
                }
            }
            // A lobe's shape only where both models have a lobe: a diffuse's `roughness =
            // 0.0` says it has none, and is no value of one. Its `specularity = 0.0` is a
            // value, the lobe's strength: a lobe missed reads 100% there.
            let pair = |key: &str, a: Option<f32>, b: Option<f32>| match (a, b) {
                (Some(a), Some(b))
                    if b > 0.0 && rm.model.requires(key) && tm.model.requires(key) =>
                {
                    Some(rel(a as f64, b as f64))
                }
                _ => None,
            };
            row.specularity_rel_err = match (rm.specularity, tm.specularity) {
                (Some(a), Some(b)) if b > 0.0 => Some(rel(a as f64, b as f64)),
                _ => None,
            };
            row.roughness_rel_err = pair("roughness", rm.roughness, tm.roughness);
            row.roughness_u_rel_err = pair("roughness_u", rm.roughness_u, tm.roughness_u);
            row.roughness_v_rel_err = pair("roughness_v", rm.roughness_v, tm.roughness_v);
            if let (Some(a), Some(b)) = (rm.direction_u, tm.direction_u) {
                row.direction_err_deg = Some(angle_between_axes_deg(a, b));
            }
            if let (Some(a), Some(b)) = (&rm.diffuse_map, &tm.diffuse_map) {
                let at = |file: &MaterialsDesc, m: &MaterialDesc| {
                    format!("{}:{}: group '{}'", file.path.display(), m.line, m.group)
                };
                set_map_measures(&mut row, (b, at(t, tm)), (a, at(m, rm)), rm.map_wrap)?;
            }
        }
        rows.push(row);
    }
    Ok(rows)
}

/// The angle between two axes (a direction and its opposite are the same axis), degrees.
fn angle_between_axes_deg(a: [f32; 3], b: [f32; 3]) -> f64 {
    let dot: f64 = (0..3).map(|i| a[i] as f64 * b[i] as f64).sum();
    let norm = |v: [f32; 3]| v.iter().map(|&x| x as f64 * x as f64).sum::<f64>().sqrt();
    let cos = dot.abs() / (norm(a) * norm(b)).max(f64::MIN_POSITIVE);
    libm::acos(cos.min(1.0)).to_degrees()
}

/// Each row's `kind`, `true_kind` and `specular_reflectance_rel_err` (see [`MaterialRow`])
/// from `scene`, the scene whose kinds the truth has: a recovery of kind "auto" groups is
/// judged on the kinds it chose.
/// A scene whose groups are not the truth's is an error.
fn set_kinds<'a>(
    rows: &mut [MaterialRow],
    scene: &SceneDesc,
    t: &'a MaterialsDesc,
    m: &'a MaterialsDesc,
) -> Result<(), Error> {
    let scene_groups: Vec<&str> = scene.groups.iter().map(|g| g.name.as_str()).collect();
    check_groups(
        &scene.path,
        &scene_groups,
        "the truth",
        &t.path,
        &groups_of(t),
        Groups::Same,
        "the truth's own scene.toml gives its kinds",
    )?;
    let scene_kind = |group: &str| scene.groups.iter().find(|g| g.name == group)?.kind.given();
    // A truth's lobe whose kind the scene leaves to "auto" could not be judged: refused
    // rather than left out of the count in silence.
    let undecided: Vec<String> = t
        .materials
        .iter()
        .filter(|x| x.model.has_lobe() && scene_kind(&x.group).is_none())
        .map(|x| format!("'{}'", x.group))
        .collect();
    if !undecided.is_empty() {
        return Err(Error::input(
            &scene.path,
            format!(
                "{} {} of kind \"auto\", whose truth has a lobe: the truth's own scene.toml \
                 gives each lobe's kind, \"plastic\" or \"metal\"",
                if undecided.len() == 1 {
                    "group"
                } else {
                    "groups"
                },
                undecided.join(", ")
            ),
        ));
    }
    let lobe = |d: &'a MaterialsDesc, group: &str| {
        d.materials
            .iter()
            .find(|x| x.group == group && x.model.has_lobe())
    };
    for row in rows.iter_mut() {
        if let (Some(recovered), Some(truth)) = (lobe(m, &row.group), lobe(t, &row.group)) {
            let name = |k: Option<Kind>| k.map(|k| materials_file::kind_name(k).to_string());
            let given = scene_kind(&row.group);
            let kind = recovered.kind.or(given);
            row.kind = name(kind);
            row.true_kind = name(given);
            let reflectance = |d: &MaterialDesc, k: Option<Kind>| specular_reflectance_of(d, k?);
            if let (Some(a), Some(b)) = (reflectance(recovered, kind), reflectance(truth, given)) {
                row.specular_reflectance_rel_err = (0..3)
                    .all(|c| b[c] > 0.0)
                    .then(|| (0..3).map(|c| rel(a[c], b[c])).sum::<f64>() / 3.0);
            }
        }
    }
    Ok(())
}

/// The line that counts the kinds right (where [`set_kinds`] gave both).
fn kind_summary(rows: &[MaterialRow]) -> String {
    let judged: Vec<&MaterialRow> = rows
        .iter()
        .filter(|r| r.kind.is_some() && r.true_kind.is_some())
        .collect();
    let wrong: Vec<String> = judged
        .iter()
        .filter(|r| r.kind != r.true_kind)
        .map(|r| {
            format!(
                "{}: {}, truth {}",
                r.group,
                r.kind.as_deref().unwrap_or("-"),
                r.true_kind.as_deref().unwrap_or("-")
            )
        })
        .collect();
    count_right(
        "kinds right",
        judged.len(),
        " (groups with a lobe in both)",
        &wrong,
        "; ",
    )
}

/// `relume compare materials`: the table, and `json` if given. The JSON may replace none
/// of the run's inputs (either materials file or their maps), checked before the work.
/// With `scene` (the truth's scene.toml), each group with a lobe in both is judged on its
/// kind too.
pub fn compare_materials(
    truth: &Path,
    materials: &Path,
    scene: Option<&Path>,
    json: Option<&Path>,
) -> Result<(), Error> {
    if fsutil::same_file(truth, materials) {
        return Err(Error::Usage(format!(
            "the truth and the materials compared are the same file ({}): every error would read 0",
            materials.display()
        )));
    }
    let t = materials_file::load_materials(truth)?;
    let m = materials_file::load_materials(materials)?;
    let scene = scene.map(scene_file::load_scene).transpose()?;
    let mut inputs = [t.input_files(), m.input_files()].concat();
    if let Some(scene) = &scene {
        inputs.push((scene.path.clone(), "the scene".to_string()));
    }
    let mut set = OutputSet::keeping(inputs);
    if let Some(path) = json {
        set.check_target(path)?;
    }
    let mut rows = materials_rows(&t, &m)?;
    if let Some(scene) = &scene {
        set_kinds(&mut rows, scene, &t, &m)?;
    }
    let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{:.2}%", 100.0 * v));
    let db = |v: Option<f64>| v.map_or("-".to_string(), |p| format!("{p:.1}dB"));
    println!(
        "{:<16} {:<22} {:<22} {:>5} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>7} {:>8} {:>8} {:>9}",
        "group",
        "true model",
        "model",
        "class",
        "diffuse",
        "spec",
        "S refl",
        "rough",
        "rough_u",
        "rough_v",
        "dir",
        "map PSNR",
        "ceiling",
        "map level"
    );
    for r in &rows {
        println!(
            "{:<16} {:<22} {:<22} {:>5} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>7} {:>8} {:>8} {:>9}",
            r.group,
            r.true_model,
            r.model.as_deref().unwrap_or("(missing)"),
            if r.class_ok { "ok" } else { "WRONG" },
            pct(r.diffuse_rel_err),
            pct(r.specularity_rel_err),
            pct(r.specular_reflectance_rel_err),
            pct(r.roughness_rel_err),
            pct(r.roughness_u_rel_err),
            pct(r.roughness_v_rel_err),
            r.direction_err_deg
                .map_or("-".to_string(), |d| format!("{d:.1}deg")),
            db(r.diffuse_map_psnr_db),
            db(r.diffuse_map_psnr_ceiling_db),
            r.diffuse_map_level_err
                .map_or("-".to_string(), |v| format!("{:+.2}%", 100.0 * v)),
        );
    }
    println!("{}", class_summary(&rows));
    if scene.is_some() {
        println!("{}", kind_summary(&rows));
    }
    if let Some(path) = json {
        let text = serde_json::to_string_pretty(&rows).map_err(|e| Error::Usage(e.to_string()))?;
        set.add(path, text.as_bytes())?;
    }
    set.commit()
}

/// The table's closing line: how many groups have their true model, and which do not (the
/// first of the targets, and what a reader of a long table looks for first).
fn class_summary(rows: &[MaterialRow]) -> String {
    let wrong: Vec<String> = rows
        .iter()
        .filter(|r| !r.class_ok)
        .map(|r| r.group.clone())
        .collect();
    count_right("classes right", rows.len(), "", &wrong, ", ")
}

/// `"<what>: <right> of <total><note>"`, then ` (wrong: ...)` listing `wrong` with `sep`
/// unless it is empty.
fn count_right(what: &str, total: usize, note: &str, wrong: &[String], sep: &str) -> String {
    let mut line = format!("{what}: {} of {total}{note}", total - wrong.len());
    if !wrong.is_empty() {
        line += &format!(" (wrong: {})", wrong.join(sep));
    }
    line
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use super::*;
    use crate::compare::check_uncertainty_run;

    #[test]
    fn the_summary_counts_the_classes_right_and_names_the_wrong_ones() {
        let row = |group: &str, class_ok| MaterialRow {
            group: group.into(),
            class_ok,
            ..MaterialRow::default()
        };
        assert_eq!(
            class_summary(&[row("floor", true), row("desk", false), row("lamp", false)]),
            "classes right: 1 of 3 (wrong: desk, lamp)"
        );
        assert_eq!(
            class_summary(&[row("floor", true)]),
            "classes right: 1 of 1"
        );
    }

    /// A materials file of `groups`, all diffuse grey, in `dir`.
    fn materials_file_of(dir: &Path, name: &str, groups: &[&str]) -> PathBuf {
        let mut text = String::from("format = 1\n");
        for g in groups {
            text += &format!(
                "\n[[material]]\ngroup = \"{g}\"\nmodel = \"diffuse\"\ncolor = [0.5, 0.5, 0.5]\n"
            );
        }
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn materials_of_another_scene_are_refused_and_a_partial_recovery_is_judged() {
        let dir = tempfile::tempdir().unwrap();
        let truth = materials_file_of(dir.path(), "t.toml", &["floor", "walls"]);
        let other = materials_file_of(dir.path(), "o.toml", &["floor", "sofa"]);
        let e = materials_report(&truth, &other).unwrap_err().to_string();
        assert!(
            e.contains("o.toml")
                && e.contains("only in this file: 'sofa'")
                && e.contains("only in the truth: 'walls'"),
            "{e}"
        );
        let partial = materials_file_of(dir.path(), "p.toml", &["walls"]);
        let rows = materials_report(&truth, &partial).unwrap();
        assert_eq!(rows.len(), 2);
        assert_eq!((rows[0].model.as_deref(), rows[0].class_ok), (None, false));
        assert!(rows[1].class_ok);
    }

    /// A recovered diffuse writes `specularity = 0.0` and `roughness = 0.0`: against a
    /// truth with a lobe the specularity is a lobe missed, 100% off, but the roughness is
    /// no value of a lobe and read a 100% error of a parameter its model does not have. A
    /// truth's diffuse against a recovered lobe has no relative error of either.
    #[test]
    fn a_roughness_only_one_side_has_gives_no_error() {
        let dir = tempfile::tempdir().unwrap();
        let file = |name: &str, material: &str| {
            let path = dir.path().join(name);
            let text = format!("format = 1\n\n[[material]]\ngroup = \"box\"\n{material}");
            std::fs::write(&path, text).unwrap();
            path
        };
        let lobe = "model = \"isotropic\"\ncolor = [0.5, 0.5, 0.5]\nspecularity = 0.06\nroughness = 0.08\n";
        let diffuse =
            "model = \"diffuse\"\ncolor = [0.5, 0.5, 0.5]\nspecularity = 0.0\nroughness = 0.0\n";
        let (lobe, diffuse) = (file("lobe.toml", lobe), file("diffuse.toml", diffuse));
        for (truth, recovered, specularity) in
            [(&lobe, &diffuse, Some(1.0)), (&diffuse, &lobe, None)]
        {
            let row = &materials_report(truth, recovered).unwrap()[0];
            assert!(!row.class_ok && row.diffuse_rel_err.is_some(), "{row:?}");
            assert_eq!(
                (row.specularity_rel_err, row.roughness_rel_err),
                (specularity, None),
                "{row:?}"
            );
        }
        std::fs::copy(&lobe, dir.path().join("copy.toml")).unwrap();
        let row = &materials_report(&lobe, &dir.path().join("copy.toml")).unwrap()[0];
        assert_eq!(
            (row.specularity_rel_err, row.roughness_rel_err),
            (Some(0.0), Some(0.0))
        );
    }

    #[test]
    fn compare_json_that_would_replace_an_input_is_refused_before_the_work() {
        let dir = tempfile::tempdir().unwrap();
        let truth = materials_file_of(dir.path(), "t.toml", &["floor"]);
        let recovered = materials_file_of(dir.path(), "r.toml", &["floor"]);
        let before = std::fs::read(&truth).unwrap();
        let e = compare_materials(&truth, &recovered, None, Some(&truth))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.toml")
                && e.contains("would replace a materials file, an input of this run"),
            "{e}"
        );
        assert_eq!(std::fs::read(&truth).unwrap(), before);
        // compare uncertainty: a report as the JSON, and a report given twice.
        let report = dir.path().join("report.json");
        std::fs::write(&report, "{\"groups\": []}").unwrap();
        let reports = [report.clone()];
        let e = check_uncertainty_run(&truth, &reports, Some(&report))
            .unwrap_err()
            .to_string();
        assert!(e.contains("would replace a report"), "{e}");
        let twice = [report.clone(), dir.path().join(".").join("report.json")];
        let e = check_uncertainty_run(&truth, &twice, None).unwrap_err();
        assert_eq!(e.exit_code(), 2);
        assert!(e.to_string().contains("given twice as a report"), "{e}");
        check_uncertainty_run(&truth, &reports, Some(&dir.path().join("out.json"))).unwrap();
    }
}
