//! The recovered parameters' spread over the seed family's runs, per parameter and by
//! kind, and the groups whose class varies over the seeds.

use std::collections::BTreeMap;

use super::{Family, StabilityRun, SEED_SPREAD_TARGET};
use crate::bench::Judged;
use crate::materials_file::{MaterialDesc, Model};

/// The spread over seeds of one recovered parameter of one group.
#[derive(Clone, Debug, PartialEq)]
pub struct Spread {
    pub group: String,
    /// The model most seeds recovered (ties: the first seed's), and in how many seeds.
    pub model: String,
    pub seeds_with_model: usize,
    pub seeds: usize,
    pub parameter: &'static str,
    pub truth: Option<f64>,
    pub mean: f64,
    /// Sample standard deviation over the seeds that recovered `model`.
    pub std: f64,
    /// `std / |mean|`; `None` when the mean is 0.
    pub rel_std: Option<f64>,
}

/// Mean, sample standard deviation and relative standard deviation; `None` for fewer than
/// two values.
pub fn spread_of(values: &[f64]) -> Option<(f64, f64, Option<f64>)> {
    if values.len() < 2 {
        return None;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0);
    let std = var.sqrt();
    Some((mean, std, (mean != 0.0).then(|| std / mean.abs())))
}

/// The scalar parameters a material of `model` carries, as written in materials.toml: the
/// colour (none for a textured model, whose colour is its map), and a lobe's specularity
/// and roughness or roughnesses, textured or not. (A lobe's direction is a vector, left
/// out.)
fn parameters(m: &MaterialDesc) -> Vec<(&'static str, Option<f64>)> {
    let c = m.color.map(|c| c.map(f64::from));
    let mut p = vec![
        ("color_r", c.map(|c| c[0])),
        ("color_g", c.map(|c| c[1])),
        ("color_b", c.map(|c| c[2])),
    ];
    let scalar = |v: Option<f32>| v.map(f64::from);
    match m.model {
        Model::Isotropic | Model::TexturedIsotropic => {
            p.push(("specularity", scalar(m.specularity)));
            p.push(("roughness", scalar(m.roughness)));
        }
        Model::Anisotropic | Model::TexturedAnisotropic => {
            p.push(("specularity", scalar(m.specularity)));
            p.push(("roughness_u", scalar(m.roughness_u)));
            p.push(("roughness_v", scalar(m.roughness_v)));
        }
        Model::Diffuse | Model::Mirror | Model::TexturedDiffuse => {}
    }
    p
}

/// The seed runs' judgements, in order.
fn seed_runs(runs: &[StabilityRun]) -> Vec<&Judged> {
    runs.iter()
        .filter(|r| r.family == Family::Seed)
        .map(|r| &r.judged)
        .collect()
}

/// `group`'s most common model over `seeds` (a tie goes to the first seed's) and the
/// materials recovered with it; `None` where no seed recovered the group.
fn common_model<'a>(
    seeds: &[&'a Judged],
    group: &str,
) -> Option<(&'static str, Vec<&'a MaterialDesc>)> {
    let recovered: Vec<&MaterialDesc> = seeds
        .iter()
        .filter_map(|j| j.group(group)?.recovered.as_ref())
        .collect();
    let mut counts: BTreeMap<&'static str, usize> = BTreeMap::new();
    for m in &recovered {
        *counts.entry(m.model.name()).or_default() += 1;
    }
    let first_model = recovered.first()?.model.name();
    let top = counts.values().copied().max().unwrap_or(0);
    let model = if counts[first_model] == top {
        first_model
    } else {
        counts
            .iter()
            .find(|(_, &n)| n == top)
            .map_or(first_model, |(m, _)| *m)
    };
    let same = recovered
        .into_iter()
        .filter(|m| m.model.name() == model)
        .collect();
    Some((model, same))
}

/// The groups whose model is not the same on every seed, as "group (model in n/N)" with
/// the most common model: from the classes themselves, so that a group whose model has
/// no parameter to spread (textured-diffuse) is counted too.
pub fn class_flips(runs: &[StabilityRun]) -> Vec<String> {
    let seeds = seed_runs(runs);
    let Some(first) = seeds.first() else {
        return Vec::new();
    };
    first
        .groups
        .iter()
        .filter_map(|g| {
            let (model, same) = common_model(&seeds, &g.group)?;
            (same.len() < seeds.len())
                .then(|| format!("{} ({model} in {}/{})", g.group, same.len(), seeds.len()))
        })
        .collect()
}

/// Per group and parameter, the spread over the seed family's runs (those that recovered
/// the group's most common model).
pub fn seed_spread(runs: &[StabilityRun], truth: &[MaterialDesc]) -> Vec<Spread> {
    let seeds = seed_runs(runs);
    let Some(first) = seeds.first() else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for g in &first.groups {
        let Some((model, same)) = common_model(&seeds, &g.group) else {
            continue;
        };
        let true_m = truth.iter().find(|t| t.group == g.group);
        let true_params: Vec<(&'static str, Option<f64>)> =
            true_m.map(parameters).unwrap_or_default();
        for (i, (name, _)) in parameters(same[0]).into_iter().enumerate() {
            let values: Vec<f64> = same.iter().filter_map(|m| parameters(m)[i].1).collect();
            let Some((mean, std, rel_std)) = spread_of(&values) else {
                continue;
            };
            out.push(Spread {
                group: g.group.clone(),
                model: model.into(),
                seeds_with_model: same.len(),
                seeds: seeds.len(),
                parameter: name,
                truth: true_params
                    .iter()
                    .find(|(n, _)| *n == name)
                    .and_then(|(_, v)| *v),
                mean,
                std,
                rel_std,
            });
        }
    }
    out
}

/// The seed spread of one kind of parameter: the diffuse groups' colours, the colours
/// under a lobe (or a map), the lobes' own parameters. The target weighs them alike, but
/// they part by orders of magnitude: a weak lobe's roughness is loose in its pixels.
#[derive(Debug, PartialEq)]
pub struct KindSpread {
    pub kind: &'static str,
    pub largest: f64,
    pub above: usize,
    pub parameters: usize,
}

/// The kinds of [`spread_by_kind`], in its order.
pub const SPREAD_KINDS: [&str; 3] = [
    "diffuse groups' colours",
    "colours under a lobe",
    "lobe parameters",
];

/// [`Spread`]s gathered by kind, the kinds that have any, in [`SPREAD_KINDS`]' order.
pub fn spread_by_kind(spread: &[Spread]) -> Vec<KindSpread> {
    let kind_of = |s: &Spread| match (s.parameter.starts_with("color_"), s.model.as_str()) {
        (true, "diffuse") => SPREAD_KINDS[0],
        (true, _) => SPREAD_KINDS[1],
        (false, _) => SPREAD_KINDS[2],
    };
    SPREAD_KINDS
        .into_iter()
        .filter_map(|kind| {
            let rel: Vec<f64> = spread
                .iter()
                .filter(|s| kind_of(s) == kind)
                .filter_map(|s| s.rel_std)
                .collect();
            (!rel.is_empty()).then(|| KindSpread {
                kind,
                largest: rel.iter().copied().fold(0.0, f64::max),
                above: rel.iter().filter(|&&r| r > SEED_SPREAD_TARGET).count(),
                parameters: rel.len(),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bench::stability::tests::{material, outcome, seed_run};

    #[test]
    fn spread_is_the_sample_deviation_relative_to_the_mean() {
        let (mean, std, rel) = spread_of(&[1.0, 2.0, 3.0]).unwrap();
        assert_eq!((mean, std), (2.0, 1.0));
        assert_eq!(rel, Some(0.5));
        assert_eq!(spread_of(&[1.0]), None);
        assert_eq!(spread_of(&[0.0, 0.0]).unwrap().2, None);
    }

    #[test]
    fn seed_spread_uses_the_common_model_and_counts_the_others() {
        let runs: Vec<StabilityRun> = [0.5f32, 0.51, 0.49]
            .iter()
            .enumerate()
            .map(|(i, &c)| {
                let model = if i == 2 {
                    Model::Diffuse
                } else {
                    Model::Isotropic
                };
                seed_run(
                    i as u64,
                    vec![
                        outcome("a", material("a", Model::Diffuse, c, 0.0), 100),
                        outcome("b", material("b", model, c, 0.1 + 0.01 * i as f32), 50),
                    ],
                )
            })
            .collect();
        let truth = [material("a", Model::Diffuse, 0.5, 0.0)];
        let spread = seed_spread(&runs, &truth);
        let a_r = spread
            .iter()
            .find(|s| s.group == "a" && s.parameter == "color_r")
            .unwrap();
        assert_eq!((a_r.seeds_with_model, a_r.seeds), (3, 3));
        assert_eq!(a_r.truth, Some(0.5));
        assert!((a_r.rel_std.unwrap() - 0.01 / 0.5).abs() < 1e-6);
        // Diffuse "a" has no specularity to spread; "b" is isotropic in 2 of 3 seeds.
        assert!(!spread
            .iter()
            .any(|s| s.group == "a" && s.parameter == "specularity"));
        let b_s = spread
            .iter()
            .find(|s| s.group == "b" && s.parameter == "specularity")
            .unwrap();
        assert_eq!((b_s.model.as_str(), b_s.seeds_with_model), ("isotropic", 2));
        assert!((b_s.mean - 0.105).abs() < 1e-6);
    }

    /// A group whose common model has no parameter to spread still counts as varying: the
    /// living room's picture_3, textured-diffuse on 9 seeds of 10 at 256 px and
    /// textured-anisotropic on one, was not named (2026-12-06).
    #[test]
    fn a_class_that_varies_over_seeds_is_named_whatever_its_parameters() {
        let picture = |model: Model| {
            let mut m = MaterialDesc::new("p", model);
            if model == Model::TexturedAnisotropic {
                m.specularity = Some(0.05);
                m.roughness_u = Some(0.05);
                m.roughness_v = Some(0.1);
            }
            outcome("p", m, 50)
        };
        let runs: Vec<StabilityRun> = [
            Model::TexturedDiffuse,
            Model::TexturedAnisotropic,
            Model::TexturedDiffuse,
        ]
        .into_iter()
        .enumerate()
        .map(|(i, m)| seed_run(i as u64, vec![picture(m)]))
        .collect();
        assert!(seed_spread(&runs, &[]).is_empty());
        assert_eq!(class_flips(&runs), ["p (textured-diffuse in 2/3)"]);
        assert!(class_flips(&runs[..1]).is_empty());
    }

    /// A textured or anisotropic lobe's parameters spread too: the textured study's seed
    /// spread held the diffuse groups' colours alone, not the checker's lobe (2026-12-01).
    #[test]
    fn seed_spread_covers_anisotropic_and_textured_lobes() {
        let lobe = |model: Model, s: f32| {
            let mut m = MaterialDesc::new("p", model);
            m.specularity = Some(s);
            m.roughness_u = Some(0.05);
            m.roughness_v = Some(2.0 * s);
            m
        };
        let runs: Vec<StabilityRun> = [0.06f32, 0.07]
            .iter()
            .enumerate()
            .map(|(i, &s)| {
                let picture = outcome("p", lobe(Model::TexturedAnisotropic, s), 50);
                seed_run(i as u64, vec![picture])
            })
            .collect();
        let spread = seed_spread(&runs, &[lobe(Model::TexturedAnisotropic, 0.06)]);
        let names: Vec<&str> = spread.iter().map(|s| s.parameter).collect();
        assert_eq!(names, ["specularity", "roughness_u", "roughness_v"]);
        let v = spread
            .iter()
            .find(|s| s.parameter == "roughness_v")
            .unwrap();
        assert_eq!(v.truth, Some(f64::from(0.12f32)));
        assert!((v.mean - 0.13).abs() < 1e-6, "{v:?}");
    }

    /// The spread parts by kind: the diffuse groups' colours, the colours under a lobe,
    /// the lobes' parameters.
    #[test]
    fn seed_spread_by_kind_parts_colours_from_lobes() {
        let spread = |group: &str, model: &str, parameter, rel| Spread {
            group: group.into(),
            model: model.into(),
            seeds_with_model: 10,
            seeds: 10,
            parameter,
            truth: None,
            mean: 1.0,
            std: rel,
            rel_std: Some(rel),
        };
        let all = [
            spread("wall", "diffuse", "color_r", 0.001),
            spread("wall", "diffuse", "color_g", 0.002),
            spread("ball", "isotropic", "color_r", 0.01),
            spread("ball", "isotropic", "specularity", 0.2),
            spread("ball", "isotropic", "roughness", 0.004),
        ];
        assert_eq!(
            spread_by_kind(&all),
            [
                KindSpread {
                    kind: "diffuse groups' colours",
                    largest: 0.002,
                    above: 0,
                    parameters: 2
                },
                KindSpread {
                    kind: "colours under a lobe",
                    largest: 0.01,
                    above: 1,
                    parameters: 1
                },
                KindSpread {
                    kind: "lobe parameters",
                    largest: 0.2,
                    above: 1,
                    parameters: 2
                },
            ]
        );
        assert_eq!(spread_by_kind(&all[..2]).len(), 1);
    }
}
