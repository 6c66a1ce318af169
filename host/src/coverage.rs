//! `relume compare uncertainty`: do the standard errors a recovery reports cover the true
//! parameters as often as they claim (68% within one sigma, 95% within two)?

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::Error;
use crate::fsutil;
use crate::materials_file::{self, MaterialDesc};

/// The part of report.json this reads.
#[derive(Deserialize)]
struct Report {
    groups: Vec<ReportGroup>,
}

#[derive(Deserialize)]
struct ReportGroup {
    group: String,
    model: String,
    #[serde(default)]
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
    pub group: String,
    pub parameter: String,
    pub recovered: f64,
    pub sigma: f64,
    pub truth: f64,
    /// `|recovered - truth| / sigma`.
    pub z: f64,
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
    let text = std::fs::read_to_string(report).map_err(|e| Error::io(report, e))?;
    let r: Report = serde_json::from_str(&text)
        .map_err(|e| Error::input(report, format!("not a recover report.json: {e}")))?;
    let by_group: BTreeMap<&str, &MaterialDesc> =
        t.materials.iter().map(|d| (d.group.as_str(), d)).collect();
    let mut rows = Vec::new();
    for g in &r.groups {
        let Some(tm) = by_group.get(g.group.as_str()) else {
            continue;
        };
        if tm.model.name() != g.model {
            continue;
        }
        for p in &g.uncertainty {
            let Some(truth) = true_value(tm, &p.parameter) else {
                continue;
            };
            rows.push(CoverageRow {
                group: g.group.clone(),
                parameter: p.parameter.clone(),
                recovered: p.value,
                sigma: p.sigma,
                truth,
                z: if p.sigma > 0.0 {
                    (p.value - truth).abs() / p.sigma
                } else {
                    f64::INFINITY
                },
            });
        }
    }
    Ok(rows)
}

/// The fractions of rows within one and two sigma.
pub fn fractions(rows: &[CoverageRow]) -> (f64, f64) {
    let n = rows.len().max(1) as f64;
    let within = |k: f64| rows.iter().filter(|r| r.z <= k).count() as f64 / n;
    (within(1.0), within(2.0))
}

pub fn compare_uncertainty(truth: &Path, report: &Path, json: Option<&Path>) -> Result<(), Error> {
    let rows = coverage_rows(truth, report)?;
    println!(
        "{:<16} {:<12} {:>10} {:>10} {:>10} {:>7}",
        "group", "parameter", "recovered", "sigma", "truth", "z"
    );
    for r in &rows {
        println!(
            "{:<16} {:<12} {:>10.5} {:>10.5} {:>10.5} {:>7.2}",
            r.group, r.parameter, r.recovered, r.sigma, r.truth, r.z
        );
    }
    let (one, two) = fractions(&rows);
    println!(
        "{} parameters of groups in their true class: {:.0}% within 1 sigma (68% claimed), {:.0}% within 2 sigma (95% claimed)",
        rows.len(),
        100.0 * one,
        100.0 * two
    );
    if let Some(path) = json {
        let text = serde_json::to_string_pretty(&rows).map_err(|e| Error::Usage(e.to_string()))?;
        fsutil::write_atomic(path, text.as_bytes())?;
    }
    Ok(())
}
