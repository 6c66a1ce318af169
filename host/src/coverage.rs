//! `relume compare uncertainty`: do the standard errors a recovery reports cover the true
//! parameters as often as they claim (68% within one sigma, 95% within two)?

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::Error;
use crate::fsutil;
use crate::materials_file::{self, MaterialDesc, Model};

/// The part of report.json this reads.
#[derive(Deserialize)]
struct Report {
    groups: Vec<ReportGroup>,
}

#[derive(Deserialize)]
struct ReportGroup {
    group: String,
    model: String,
    uncertainty: Vec<Parameter>,
}

#[derive(Deserialize)]
struct Parameter {
    parameter: String,
    value: f64,
    sigma: f64,
}

/// One recovered parameter against the truth.
#[derive(Serialize, Debug)]
pub struct CoverageRow {
    /// The report.json it is from.
    pub report: String,
    pub group: String,
    pub parameter: String,
    pub recovered: f64,
    pub sigma: f64,
    pub truth: f64,
    /// `|recovered - truth| / sigma`: infinite for a sigma of 0 (or one that small) off
    /// the truth, written `"inf"` in JSON.
    #[serde(serialize_with = "z_json")]
    pub z: f64,
}

/// A z in JSON: a number, `"inf"` where a sigma of 0 claims a value the truth is not (JSON
/// has no infinity, and serde_json would write `null`, which reads as no figure rather
/// than as a claim outside every number of sigmas).
fn z_json<S: serde::Serializer>(z: &f64, out: S) -> Result<S::Ok, S::Error> {
    if z.is_infinite() {
        out.serialize_str("inf")
    } else {
        out.serialize_f64(*z)
    }
}

/// The parameters report.json gives uncertainties for, each with the materials.toml key
/// it is part of.
const PARAMETERS: [(&str, &str); 7] = [
    ("color_r", "color"),
    ("color_g", "color"),
    ("color_b", "color"),
    ("specularity", "specularity"),
    ("roughness", "roughness"),
    ("roughness_u", "roughness_u"),
    ("roughness_v", "roughness_v"),
];

/// What report.json calls a group whose material was not recovered (no parameters).
const UNSEEN: &str = "unseen";

/// Why a reported parameter cannot be a recovery's (a report edited by hand, or another
/// tool's), or `None`: a parameter of the group's model, given once, with a finite value
/// in the range materials.toml allows (roughnesses in (0, 1], the rest in [0, 1]) and a
/// finite sigma >= 0.
fn implausible(model: Option<Model>, p: &Parameter, earlier: &[Parameter]) -> Option<String> {
    let Some(&(_, key)) = PARAMETERS.iter().find(|(name, _)| *name == p.parameter) else {
        let names: Vec<&str> = PARAMETERS.iter().map(|(name, _)| *name).collect();
        return Some(format!(
            "unknown parameter '{}' (expected one of {})",
            p.parameter,
            names.join(", ")
        ));
    };
    let model_name = model.map_or(UNSEEN, Model::name);
    if !model.is_some_and(|m| m.requires(key)) {
        return Some(format!(
            "model '{model_name}' has no parameter '{}'",
            p.parameter
        ));
    }
    if earlier.iter().any(|e| e.parameter == p.parameter) {
        return Some(format!("parameter '{}' is given twice", p.parameter));
    }
    let lowest_open = key.starts_with("roughness");
    let in_range = (0.0..=1.0).contains(&p.value) && !(lowest_open && p.value == 0.0);
    if !in_range || !p.sigma.is_finite() || p.sigma < 0.0 {
        let range = if lowest_open { "(0, 1]" } else { "[0, 1]" };
        return Some(format!(
            "parameter '{}' has value {:?} and sigma {:?}: a value in {range} and a finite sigma >= 0 are expected",
            p.parameter, p.value, p.sigma
        ));
    }
    None
}

/// The truth's value of a parameter named as in report.json.
fn true_value(m: &MaterialDesc, parameter: &str) -> Option<f64> {
    let channel = |c: usize| m.color.map(|v| v[c] as f64);
    match parameter {
        "color_r" => channel(0),
        "color_g" => channel(1),
        "color_b" => channel(2),
        "specularity" => m.specularity.map(f64::from),
        "roughness" => m.roughness.map(f64::from),
        "roughness_u" => m.roughness_u.map(f64::from),
        "roughness_v" => m.roughness_v.map(f64::from),
        _ => None,
    }
}

/// Every parameter of every group recovered in the true class, with its z.
pub fn coverage_rows(truth: &Path, report: &Path) -> Result<Vec<CoverageRow>, Error> {
    let t = materials_file::load_materials(truth)?;
    let text = crate::fsutil::read_text(report)?;
    let r: Report = serde_json::from_str(&text)
        .map_err(|e| Error::input(report, format!("not a recover report.json: {e}")))?;
    // A report of another scene would be judged against the wrong groups. A report may
    // leave groups out (one edited by hand), as a recovery's materials may.
    let reported: Vec<&str> = r.groups.iter().map(|g| g.group.as_str()).collect();
    crate::compare::check_groups(
        report,
        &reported,
        "the truth",
        truth,
        &crate::compare::groups_of(&t),
        crate::compare::Groups::Within,
        "a report of another scene?",
    )?;
    let by_group: BTreeMap<&str, &MaterialDesc> =
        t.materials.iter().map(|d| (d.group.as_str(), d)).collect();
    // One edited by hand would count a group twice.
    let mut seen = BTreeSet::new();
    if let Some(g) = r.groups.iter().find(|g| !seen.insert(g.group.as_str())) {
        return Err(Error::input(
            report,
            format!("group '{}' appears twice", g.group),
        ));
    }
    let mut rows = Vec::new();
    for g in &r.groups {
        let Some(tm) = by_group.get(g.group.as_str()) else {
            continue; // not reached: every group is in the truth (checked above)
        };
        let model = Model::from_name(&g.model);
        if model.is_none() && g.model != UNSEEN {
            let names: Vec<&str> = Model::ALL.iter().map(|m| m.name()).collect();
            return Err(Error::input(
                report,
                format!(
                    "group '{}': unknown model '{}' (expected {} or {UNSEEN})",
                    g.group,
                    g.model,
                    names.join(", ")
                ),
            ));
        }
        for (i, p) in g.uncertainty.iter().enumerate() {
            if let Some(why) = implausible(model, p, &g.uncertainty[..i]) {
                return Err(Error::input(report, format!("group '{}': {why}", g.group)));
            }
        }
        // A recovery gives every parameter of the model or none (too few pixels): one
        // given in part would be judged on the parameters left (a colour alone read
        // "100% within 1 sigma").
        let missing: Vec<&str> = PARAMETERS
            .iter()
            .filter(|(_, key)| model.is_some_and(|m| m.requires(key)))
            .map(|(name, _)| *name)
            .filter(|name| !g.uncertainty.iter().any(|p| p.parameter == *name))
            .collect();
        if !g.uncertainty.is_empty() && !missing.is_empty() {
            return Err(Error::input(
                report,
                format!(
                    "group '{}': model '{}' has no uncertainty for {} (a recovery gives every parameter of its model, or none)",
                    g.group,
                    g.model,
                    missing.join(", ")
                ),
            ));
        }
        if tm.model.name() != g.model {
            continue;
        }
        for p in &g.uncertainty {
            let Some(truth) = true_value(tm, &p.parameter) else {
                continue;
            };
            rows.push(CoverageRow {
                report: report.display().to_string(),
                group: g.group.clone(),
                parameter: p.parameter.clone(),
                recovered: p.value,
                sigma: p.sigma,
                truth,
                z: z_score(p.value, p.sigma, truth),
            });
        }
    }
    Ok(rows)
}

/// `|value - truth| / sigma`; a sigma of 0 claims an exact value, covered only when it is.
fn z_score(value: f64, sigma: f64, truth: f64) -> f64 {
    if sigma > 0.0 {
        (value - truth).abs() / sigma
    } else if value == truth {
        0.0
    } else {
        f64::INFINITY
    }
}

/// The fractions of rows within one and two sigma.
pub fn fractions<'a>(rows: impl IntoIterator<Item = &'a CoverageRow>) -> (f64, f64) {
    let zs: Vec<f64> = rows.into_iter().map(|r| r.z).collect();
    let n = zs.len().max(1) as f64;
    let within = |k: f64| zs.iter().filter(|&&z| z <= k).count() as f64 / n;
    (within(1.0), within(2.0))
}

/// Whether a parameter is a lobe's (specularity, roughnesses), not a colour: the two are
/// estimated differently and covered differently, so the pooled figures are given apart.
fn is_lobe(parameter: &str) -> bool {
    parameter == "specularity" || parameter.starts_with("roughness")
}

/// The fractions within one and two sigma of every row, of the colours and of the lobes'
/// parameters, with their counts (the last two only when there are any).
pub fn pooled(rows: &[CoverageRow]) -> Vec<(&'static str, usize, (f64, f64))> {
    let (lobes, colours): (Vec<&CoverageRow>, Vec<&CoverageRow>) =
        rows.iter().partition(|r| is_lobe(&r.parameter));
    let mut out = vec![("parameters", rows.len(), fractions(rows))];
    for (what, part) in [("colours", colours), ("lobe parameters", lobes)] {
        if !part.is_empty() {
            out.push((what, part.len(), fractions(part)));
        }
    }
    out
}

/// Prints every parameter of each report against the truth, then the fractions within
/// one and two sigma, pooled over the reports (several seeds of one scene), for every
/// parameter, the colours and the lobes; `json` gets every row.
pub fn compare_uncertainty(
    truth: &Path,
    reports: &[PathBuf],
    json: Option<&Path>,
) -> Result<(), Error> {
    // A copy under another name would count each parameter twice in the pooled
    // fractions (no two runs write the same bytes: the report holds their times).
    let mut texts: Vec<(&PathBuf, Vec<u8>)> = Vec::new();
    for report in reports {
        let bytes = fsutil::read_bytes(report)?;
        if let Some((first, _)) = texts.iter().find(|(_, b)| *b == bytes) {
            return Err(Error::input(
                report,
                format!(
                    "holds the same bytes as {}: a copy of one report would count each parameter twice",
                    first.display()
                ),
            ));
        }
        texts.push((report, bytes));
    }
    let mut rows = Vec::new();
    for report in reports {
        rows.extend(coverage_rows(truth, report)?);
    }
    // Percentages of nothing ("0 parameters ...: 0% within 1 sigma") are no finding.
    if let (true, Some(first)) = (rows.is_empty(), reports.first()) {
        let also = match reports.len() {
            1 => String::new(),
            n => format!(" (nor do the other {} reports)", n - 1),
        };
        return Err(Error::input(
            first,
            format!("gives no uncertainty for a group recovered in its true class{also}: nothing to judge"),
        ));
    }
    let several = reports.len() > 1;
    let mut last_report = None;
    for r in &rows {
        if last_report != Some(&r.report) {
            if several {
                println!("{}", r.report);
            }
            println!(
                "{:<16} {:<12} {:>10} {:>10} {:>10} {:>7}",
                "group", "parameter", "recovered", "sigma", "truth", "z"
            );
            last_report = Some(&r.report);
        }
        println!(
            "{:<16} {:<12} {:>10.5} {:>10.5} {:>10.5} {:>7.2}",
            r.group, r.parameter, r.recovered, r.sigma, r.truth, r.z
        );
    }
    let of_reports = if several {
        format!(" over {} reports", reports.len())
    } else {
        String::new()
    };
    for (what, n, (one, two)) in pooled(&rows) {
        println!(
            "{n} {what} of groups in their true class{of_reports}: {:.0}% within 1 sigma (68% claimed), {:.0}% within 2 sigma (95% claimed)",
            100.0 * one,
            100.0 * two
        );
    }
    if let Some(path) = json {
        let text = serde_json::to_string_pretty(&rows).map_err(|e| Error::Usage(e.to_string()))?;
        fsutil::write_atomic(path, text.as_bytes())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(parameter: &str, z: f64) -> CoverageRow {
        CoverageRow {
            report: "r.json".into(),
            group: "g".into(),
            parameter: parameter.into(),
            recovered: 0.0,
            sigma: 1.0,
            truth: z,
            z,
        }
    }

    #[test]
    fn a_sigma_of_zero_covers_only_the_exact_value() {
        assert!((z_score(0.3, 0.1, 0.5) - 2.0).abs() < 1e-12);
        assert_eq!(z_score(0.5, 0.0, 0.5), 0.0);
        assert_eq!(z_score(0.5, 0.0, 0.50001), f64::INFINITY);
    }

    #[test]
    fn a_z_of_a_sigma_of_zero_off_the_truth_is_inf_in_json_not_null() {
        let json = |z| serde_json::to_value(row("color_r", z)).unwrap();
        assert_eq!(json(f64::INFINITY)["z"], "inf");
        assert_eq!(json(1.5)["z"], 1.5);
        assert_eq!(json(0.0)["z"], 0.0);
    }

    #[test]
    fn colours_and_lobes_are_pooled_apart() {
        let rows = [
            row("color_r", 0.5),
            row("color_g", 1.5),
            row("color_b", 2.5),
            row("specularity", 0.2),
            row("roughness_u", 3.0),
        ];
        let all = pooled(&rows);
        assert_eq!(all[0], ("parameters", 5, (0.4, 0.6)));
        assert_eq!(all[1].0, "colours");
        assert_eq!(all[1].1, 3);
        assert!((all[1].2 .0 - 1.0 / 3.0).abs() < 1e-12 && (all[1].2 .1 - 2.0 / 3.0).abs() < 1e-12);
        assert_eq!(all[2], ("lobe parameters", 2, (0.5, 0.5)));
        // A diffuse scene has no lobe line.
        assert_eq!(pooled(&rows[..3]).len(), 2);
    }
}
