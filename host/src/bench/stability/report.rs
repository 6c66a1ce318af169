//! What the study writes and prints of its runs: stability.csv, seed-spread.csv, the
//! chart (stability.svg and .png) and the table of runs.

use super::verdict::{new_input_warnings, same_class};
use super::{Family, Spread, StabilityRun};
use crate::bench::chart::{Axis, Chart, ChartPoint, Panel, Series};
use crate::bench::{field, pct, Csv, GroupOutcome, Judged};

pub(super) fn runs_csv(runs: &[StabilityRun], baseline: &Judged) -> Csv {
    let mut csv = Csv::new(&[
        "family",
        "size",
        "seed",
        "group",
        "true_model",
        "model",
        "class_ok",
        "class_as_baseline",
        "diffuse_err",
        "specularity_err",
        "roughness_err",
        "param_err",
        "error_final",
        "pure_pixels",
        "input_warnings",
        "seconds",
        "cpu_seconds",
        "run",
    ]);
    for r in runs {
        let same = same_class(&r.judged, baseline);
        let warned = new_input_warnings(&r.judged, baseline).len();
        for (g, same) in r.judged.groups.iter().zip(same) {
            csv.push(vec![
                r.family.name().into(),
                r.size.to_string(),
                r.seed.to_string(),
                g.group.clone(),
                g.true_model.clone(),
                g.model.clone().unwrap_or_default(),
                g.class_ok.to_string(),
                same.to_string(),
                field(g.diffuse_err),
                field(g.specularity_err),
                field(g.roughness_err),
                field(g.param_err()),
                field(g.error_final),
                g.pure_pixels.to_string(),
                warned.to_string(),
                format!("{:.3}", r.judged.seconds),
                field(r.judged.cpu_seconds),
                r.run.clone(),
            ]);
        }
    }
    csv
}

pub(super) fn spread_csv(spread: &[Spread]) -> Csv {
    let mut csv = Csv::new(&[
        "group",
        "model",
        "seeds_with_model",
        "seeds",
        "parameter",
        "truth",
        "mean",
        "std",
        "rel_std",
    ]);
    for s in spread {
        csv.push(vec![
            s.group.clone(),
            s.model.clone(),
            s.seeds_with_model.to_string(),
            s.seeds.to_string(),
            s.parameter.into(),
            field(s.truth),
            field(Some(s.mean)),
            field(Some(s.std)),
            field(s.rel_std),
        ]);
    }
    csv
}

pub(super) struct ChartContext<'a> {
    pub(super) view_side: u32,
    pub(super) group: &'a str,
    pub(super) group_pixels: u32,
    /// The families run, in the study's order: one column of panels each.
    pub(super) families: &'a [Family],
}

/// Per family, two panels: the fraction of classes right (against the truth) and
/// unchanged (against the baseline), and the mean parameter error; the pixels family also
/// shows the limited group alone.
pub(super) fn chart(
    runs: &[StabilityRun],
    baseline: &Judged,
    ctx: &ChartContext,
    title: &str,
) -> Chart {
    let mut class_panels = Vec::new();
    let mut error_panels = Vec::new();
    for &family in ctx.families {
        // The family's runs plus the baseline at its natural place, sorted along x.
        let mut points: Vec<(f64, &Judged)> = runs
            .iter()
            .filter(|r| r.family == family)
            .map(|r| (r.size, &r.judged))
            .collect();
        let baseline_x = match family {
            Family::Seed => None,
            Family::Resolution => Some(ctx.view_side as f64),
            Family::Pixels => Some(ctx.group_pixels as f64),
            _ => Some(0.0),
        };
        if let Some(x) = baseline_x {
            points.push((x, baseline));
        }
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        let series = |name: String, y: &dyn Fn(&Judged) -> Option<f64>| Series {
            name,
            points: points
                .iter()
                .filter_map(|(x, j)| {
                    Some(ChartPoint {
                        x: *x,
                        y: y(j)?,
                        label: String::new(),
                    })
                })
                .collect(),
        };
        let right = |j: &Judged| Some(j.summary().class_accuracy);
        let unchanged = |j: &Judged| {
            let same = same_class(j, baseline);
            Some(same.iter().filter(|&&s| s).count() as f64 / same.len().max(1) as f64)
        };
        let mut class_series = vec![
            series("right (vs truth)".into(), &right),
            series("as baseline".into(), &unchanged),
        ];
        let mut error_series = vec![series("all groups".into(), &|j: &Judged| {
            j.summary().param_err
        })];
        if family == Family::Pixels {
            let own = |j: &Judged| j.group(ctx.group).map(|g| f64::from(u8::from(g.class_ok)));
            class_series.push(series(format!("{} right", ctx.group), &own));
            let own_err = |j: &Judged| j.group(ctx.group).and_then(GroupOutcome::param_err);
            error_series.push(series(ctx.group.to_string(), &own_err));
        }
        let title = match family {
            Family::Pixels => format!("pixels of {}", ctx.group),
            f => f.name().to_string(),
        };
        class_panels.push(Panel {
            title: format!("{title}: classes"),
            x: family.x_axis(),
            y: Axis {
                label: "fraction of groups".into(),
                log: false,
                percent: false,
                range: Some((0.0, 1.0)),
            },
            series: class_series,
        });
        error_panels.push(Panel {
            title: format!("{title}: parameter error"),
            x: family.x_axis(),
            y: Axis {
                label: "mean relative parameter error".into(),
                log: true,
                percent: true,
                range: None,
            },
            series: error_series,
        });
    }
    // Three families per row band: their class panels above their error panels.
    let columns = band_width(ctx.families.len());
    let mut panels = Vec::new();
    for (classes, errors) in class_panels
        .chunks(columns)
        .zip(error_panels.chunks(columns))
    {
        panels.extend_from_slice(classes);
        panels.extend_from_slice(errors);
    }
    Chart {
        title: title.into(),
        columns,
        panels,
    }
}

/// How many families share a band of the chart (their class panels above their error
/// panels): a width that divides their count, so that every band is full and a class
/// panel never sits beside another family's error panel; three for the whole study.
fn band_width(families: usize) -> usize {
    match families {
        n if n % 3 == 0 => 3,
        n if n % 2 == 0 => 2,
        n => n.max(1),
    }
}

/// The runs as a Markdown table (readable in a terminal, pasted as is into docs/).
pub(super) fn print_runs(runs: &[StabilityRun], baseline: &Judged, group: &str) {
    println!("| family | size | wall s | classes right | as baseline | param | image | input warnings | changed classes |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for r in runs {
        let s = r.judged.summary();
        let same = same_class(&r.judged, baseline);
        let mut notes: Vec<String> = r
            .judged
            .groups
            .iter()
            .zip(&same)
            .filter(|(_, &s)| !s)
            .map(|(g, _)| format!("{} {}", g.group, g.model.as_deref().unwrap_or("none")))
            .collect();
        if r.family == Family::Pixels {
            if let Some(g) = r.judged.group(group) {
                notes.insert(
                    0,
                    format!(
                        "({group}: {}, param {})",
                        g.model.as_deref().unwrap_or("none"),
                        pct(g.param_err())
                    ),
                );
            }
        }
        println!(
            "| {} | {} | {:.1} | {}/{} | {}/{} | {} | {} | {} | {} |",
            r.family.name(),
            r.size,
            r.judged.seconds,
            s.classes_right,
            s.groups,
            same.iter().filter(|&&x| x).count(),
            same.len(),
            pct(s.param_err),
            pct(s.image_err),
            new_input_warnings(&r.judged, baseline).len(),
            notes.join(", ")
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every band of the chart is full: a family's class panel is always above its own
    /// error panel, whatever the number of families.
    #[test]
    fn the_chart_bands_divide_the_families() {
        for n in 1..=Family::ALL.len() {
            let width = band_width(n);
            assert_eq!(n % width, 0, "{n} families in bands of {width}");
            assert!(width <= 5);
        }
        assert_eq!(band_width(Family::ALL.len()), 3);
    }
}
