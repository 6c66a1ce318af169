//! `relume compare`: how far a rendering is from a reference, group by group, and how far
//! recovered materials are from the truth. These are the user's yardsticks (and ours).
//!
//! One file per yardstick: `views` (a rendering against a reference, `compare views`),
//! `materials` (recovered materials against the truth, `compare materials`) and `maps` (a
//! recovered diffuse map against the truth's). Here: what they and `coverage` (`compare
//! uncertainty`) share, the groups a file must have to be judged against another, and the
//! checks `compare uncertainty` makes before its work.

mod maps;
mod materials;
mod views;

pub use materials::{compare_materials, materials_report, MaterialRow};
pub use views::{
    compare_views, views_report, views_report_of, ViewImages, ViewsReport, ViewsRow,
    LABEL_RAYS_PER_SIDE,
};

use std::path::{Path, PathBuf};

use crate::error::Error;
use crate::fsutil::{self, OutputSet};
use crate::materials_file::{self, MaterialsDesc};

/// The groups of a materials file, in its order.
pub(crate) fn groups_of(m: &MaterialsDesc) -> Vec<&str> {
    m.materials.iter().map(|d| d.group.as_str()).collect()
}

/// How the groups of a file must match those it is judged against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Groups {
    /// Exactly the same groups: a truth and the scene it is the truth of.
    Same,
    /// Some or all of them, and no other: a recovery's materials (none is written for a
    /// group no pixel sees) against the truth.
    Within,
}

/// An input error on `file` when its `groups` do not match `their`, the groups of `what`
/// (`"the truth"`, `"the scene"`) at `other`: a file of another scene would be judged
/// against the wrong groups, or for a few groups only, and give meaningless figures. The
/// error names the groups missing on each side and ends with `hint`.
pub fn check_groups(
    file: &Path,
    groups: &[&str],
    what: &str,
    other: &Path,
    their: &[&str],
    rule: Groups,
    hint: &str,
) -> Result<(), Error> {
    let only_here: Vec<&str> = groups
        .iter()
        .filter(|g| !their.contains(g))
        .copied()
        .collect();
    let only_there: Vec<&str> = their
        .iter()
        .filter(|g| !groups.contains(g))
        .copied()
        .collect();
    let fits = only_here.is_empty()
        && match rule {
            Groups::Same => only_there.is_empty(),
            Groups::Within => !groups.is_empty() || their.is_empty(),
        };
    if fits {
        return Ok(());
    }
    let list = |names: &[&str]| {
        names
            .iter()
            .map(|g| format!("'{g}'"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let mut sides = Vec::new();
    if !only_here.is_empty() {
        sides.push(format!("only in this file: {}", list(&only_here)));
    }
    if !only_there.is_empty() {
        sides.push(format!("only in {what}: {}", list(&only_there)));
    }
    Err(Error::input(
        file,
        format!(
            "its groups are not those of {what} {}: {} ({hint})",
            other.display(),
            sides.join("; ")
        ),
    ))
}

/// The checks `relume compare uncertainty` makes before its work (its comparison is
/// `coverage::compare_uncertainty`): no report given twice, which would pool its
/// parameters twice and claim a coverage over more recoveries than were made; and no
/// `json` that would replace an input (the truth, its maps, a report).
pub fn check_uncertainty_run(
    truth: &Path,
    reports: &[PathBuf],
    json: Option<&Path>,
) -> Result<(), Error> {
    if let Some((report, first)) = fsutil::given_twice(reports) {
        return Err(Error::Usage(format!(
            "{} is given twice as a report (also as {}): its parameters would be pooled twice",
            report.display(),
            first.display()
        )));
    }
    if let Some(path) = json {
        let mut inputs = materials_file::load_materials(truth)?.input_files();
        inputs.extend(reports.iter().map(|r| (r.clone(), "a report".to_string())));
        OutputSet::keeping(inputs).check_target(path)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn groups_that_do_not_match_are_named_on_each_side() {
        let (file, truth) = (Path::new("m.toml"), Path::new("t.toml"));
        let check = |groups: &[&str], rule| {
            check_groups(
                file,
                groups,
                "the truth",
                truth,
                &["floor", "walls", "desk"],
                rule,
                "a file of another scene?",
            )
            .map_err(|e| e.to_string())
        };
        assert!(check(&["desk", "floor", "walls"], Groups::Same).is_ok());
        // A recovery that left a group out is judged; as the truth of a scene it is not.
        assert!(check(&["floor", "desk"], Groups::Within).is_ok());
        let e = check(&["floor", "desk"], Groups::Same).unwrap_err();
        assert_eq!(
            e,
            "m.toml: its groups are not those of the truth t.toml: only in the truth: 'walls' (a file of another scene?)"
        );
        let e = check(&["floor", "sofa", "lamp"], Groups::Within).unwrap_err();
        assert!(
            e.contains("only in this file: 'sofa', 'lamp'; only in the truth: 'walls', 'desk'"),
            "{e}"
        );
        // A file with no group at all has nothing to judge.
        let e = check(&[], Groups::Within).unwrap_err();
        assert!(
            e.contains("only in the truth: 'floor', 'walls', 'desk'"),
            "{e}"
        );
    }
}
