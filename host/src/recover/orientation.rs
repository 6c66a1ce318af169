//! Is each view's image the right way round? Cube faces come in several conventions, and a
//! face written mirrored or turned a quarter keeps its mean, so the calibration checks do
//! not see it; yet its pure pixels then show other surfaces than the geometry says, and
//! the recovery fits them all the same (cornell with its `px` face mirrored: two classes of
//! nine wrong, a colour 42% off, and only a warning that the view's exposure might be off).
//!
//! The geometry says where a view's groups meet: two pure pixels [`PAIR_STEP`] apart of
//! different groups straddle a boundary, where the image shows an edge (another material,
//! another normal, a shadow line) far more often than between two pixels of one group. So
//! each view is read in every orientation its shape allows, and for each the share of its
//! boundary pairs whose difference in log luminance exceeds [`EDGE_QUANTILE`] of the
//! within-group pairs' is counted: the image the right way round shows the most boundaries.
//! One that shows more than [`ORIENTATION_MARGIN`] more of them read otherwise is told.
//! No render is needed, so it is told before the work.

use serde::Serialize;

use relume_core::math::{luminance, Vec3};

use super::pixels::PurePixel;
use crate::images::Image;

/// How many more of a view's boundary pairs an orientation must show as edges than the
/// image as it is, for the image to be called turned or mirrored. On the four references
/// at 64 px and cornell at 32 px (26 views) no orientation showed more than the image as it
/// is (ties where a view is symmetric); cornell's `px` mirrored showed 20% as it is against
/// 75% read mirrored back.
pub const ORIENTATION_MARGIN: f64 = 0.2;

/// Pure pixels this far apart, in a row or a column, make a pair: one apart they cannot
/// be of different groups (a pixel on a boundary is not pure).
pub const PAIR_STEP: u32 = 2;

/// A boundary pair shows an edge where its difference exceeds this quantile of the
/// within-group pairs' differences.
pub const EDGE_QUANTILE: f64 = 0.9;

/// A view with fewer boundary pairs is not judged: the share of so few is too noisy.
pub const MIN_BOUNDARY_PAIRS: usize = 50;

/// A view whose boundaries show as edges, in every orientation, no more than this many
/// standard errors above chance (`1 - EDGE_QUANTILE` of pairs that straddle nothing) is
/// told: its image may be another view's. Two faces' images swapped passed every check
/// (cornell's `py` and `ny`: 6% of 113 boundaries as it is, 8% at best read otherwise),
/// and three classes of nine came out wrong. The references' views read 26-100% as they
/// are (box-diffuse's `ny` the least, 128 boundaries, where this bound is 15%).
pub const CHANCE_SIGMAS: f64 = 2.0;

/// A view with fewer boundary pairs is not judged against chance: the right image can
/// read as little (textured at 32 px, `py`: 10% of 50 boundaries, its groups alike where
/// they meet at that size; 51% of 137 at 64 px).
pub const MIN_CHANCE_PAIRS: usize = 100;

/// The share of `pairs` boundary pairs a view's image shows as edges by chance alone, plus
/// [`CHANCE_SIGMAS`] binomial standard errors.
fn chance_bound(pairs: usize) -> f64 {
    let p = 1.0 - EDGE_QUANTILE;
    p + CHANCE_SIGMAS * (p * (1.0 - p) / pairs.max(1) as f64).sqrt()
}

/// The ways an image can be turned or mirrored: each names the pixel of the image that
/// reads it so at `(x, y)`. The last four need a square image.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Orientation {
    AsIs,
    MirroredLeftRight,
    MirroredTopBottom,
    HalfTurn,
    Transposed,
    QuarterTurnClockwise,
    QuarterTurnAnticlockwise,
    AntiTransposed,
}

impl Orientation {
    const ALL: [Orientation; 8] = [
        Orientation::AsIs,
        Orientation::MirroredLeftRight,
        Orientation::MirroredTopBottom,
        Orientation::HalfTurn,
        Orientation::Transposed,
        Orientation::QuarterTurnClockwise,
        Orientation::QuarterTurnAnticlockwise,
        Orientation::AntiTransposed,
    ];

    /// The pixel of a `w` x `h` image that this reading puts at `(x, y)`.
    fn source(self, x: u32, y: u32, w: u32, h: u32) -> (u32, u32) {
        match self {
            Orientation::AsIs => (x, y),
            Orientation::MirroredLeftRight => (w - 1 - x, y),
            Orientation::MirroredTopBottom => (x, h - 1 - y),
            Orientation::HalfTurn => (w - 1 - x, h - 1 - y),
            Orientation::Transposed => (y, x),
            Orientation::QuarterTurnClockwise => (y, h - 1 - x),
            Orientation::QuarterTurnAnticlockwise => (w - 1 - y, x),
            Orientation::AntiTransposed => (w - 1 - y, h - 1 - x),
        }
    }

    fn needs_square(self) -> bool {
        matches!(
            self,
            Orientation::Transposed
                | Orientation::QuarterTurnClockwise
                | Orientation::QuarterTurnAnticlockwise
                | Orientation::AntiTransposed
        )
    }

    /// What to do to the image for it to read so, said to a user.
    fn correction(self) -> &'static str {
        match self {
            Orientation::AsIs => "as it is",
            Orientation::MirroredLeftRight => "mirrored left to right",
            Orientation::MirroredTopBottom => "mirrored top to bottom",
            Orientation::HalfTurn => "turned half a turn",
            Orientation::Transposed => "mirrored about its main diagonal",
            Orientation::QuarterTurnClockwise => "turned a quarter turn clockwise",
            Orientation::QuarterTurnAnticlockwise => "turned a quarter turn anticlockwise",
            Orientation::AntiTransposed => "mirrored about its other diagonal",
        }
    }
}

/// One view's image against its groups' boundaries.
#[derive(Serialize, Clone, Debug, PartialEq)]
pub struct OrientationReading {
    pub view: String,
    /// Pairs of pure pixels across a boundary between groups, and within one group.
    pub boundary_pairs: usize,
    pub within_pairs: usize,
    /// The share of boundary pairs the image as it is shows as edges.
    pub edges_as_is: f64,
    /// The other reading that shows most, and its share.
    pub best_other: Orientation,
    pub edges_best_other: f64,
}

impl OrientationReading {
    /// One line for a reader: how much of the view's boundaries its image shows as it is,
    /// and read the best other way.
    pub fn describe(&self) -> String {
        format!(
            "view '{}' shows {:.0}% of {} boundaries between groups as edges as it is, {:.0}% read {}",
            self.view,
            100.0 * self.edges_as_is,
            self.boundary_pairs,
            100.0 * self.edges_best_other,
            self.best_other.correction()
        )
    }
}

/// A reading per view with at least [`MIN_BOUNDARY_PAIRS`] boundary pairs (`pure` as
/// labelled).
pub fn read_orientations(
    pure: &[PurePixel],
    real: &[Image],
    view_names: &[String],
) -> Vec<OrientationReading> {
    let mut readings = Vec::new();
    for (v, image) in real.iter().enumerate() {
        let (boundary, within) = pairs(pure, v, image);
        if boundary.len() < MIN_BOUNDARY_PAIRS || within.is_empty() {
            continue;
        }
        let square = image.width == image.height;
        let logs = log_luminance(image);
        let shares: Vec<(Orientation, f64)> = Orientation::ALL
            .into_iter()
            .filter(|o| square || !o.needs_square())
            .map(|o| (o, edge_share(&logs, image, o, &boundary, &within)))
            .collect();
        let as_is = shares[0].1;
        let best = shares[1..]
            .iter()
            .copied()
            .reduce(|best, s| if s.1 > best.1 { s } else { best });
        if let Some((best_other, share)) = best {
            readings.push(OrientationReading {
                view: view_names[v].clone(),
                boundary_pairs: boundary.len(),
                within_pairs: within.len(),
                edges_as_is: as_is,
                best_other,
                edges_best_other: share,
            });
        }
    }
    readings
}

/// A pair of pixels `(x, y)` of one view.
type Pair = [(u32, u32); 2];

/// View `v`'s pairs of pure pixels [`PAIR_STEP`] apart: those of two groups, and those of
/// one, in row order.
fn pairs(pure: &[PurePixel], v: usize, image: &Image) -> (Vec<Pair>, Vec<Pair>) {
    let (w, h) = (image.width, image.height);
    let mut group = vec![None; (w * h) as usize];
    for p in pure.iter().filter(|p| p.view as usize == v) {
        group[(p.y * w + p.x) as usize] = Some(p.group);
    }
    let (mut boundary, mut within) = (Vec::new(), Vec::new());
    for y in 0..h {
        for x in 0..w {
            let Some(g) = group[(y * w + x) as usize] else {
                continue;
            };
            let right = (x + PAIR_STEP < w).then(|| (x + PAIR_STEP, y));
            let below = (y + PAIR_STEP < h).then(|| (x, y + PAIR_STEP));
            for (qx, qy) in right.into_iter().chain(below) {
                match group[(qy * w + qx) as usize] {
                    Some(o) if o == g => within.push([(x, y), (qx, qy)]),
                    Some(_) => boundary.push([(x, y), (qx, qy)]),
                    None => {}
                }
            }
        }
    }
    (boundary, within)
}

/// The log of each pixel's luminance, a black pixel counted as a thousandth of the
/// image's mean (the same in any orientation) so that a log is taken.
fn log_luminance(image: &Image) -> Vec<f64> {
    let luminances: Vec<f64> = image
        .pixels
        .iter()
        .map(|&p| luminance(Vec3::from(p)) as f64)
        .collect();
    let mean = luminances.iter().sum::<f64>() / luminances.len() as f64;
    let floor = (1e-3 * mean).max(f64::MIN_POSITIVE);
    luminances
        .iter()
        .map(|&l| libm::log(l.max(floor)))
        .collect()
}

/// The share of `boundary` pairs whose difference in `logs` (of `image`'s pixels), read
/// in `orientation`, exceeds the [`EDGE_QUANTILE`] of the `within` pairs'.
fn edge_share(
    logs: &[f64],
    image: &Image,
    orientation: Orientation,
    boundary: &[Pair],
    within: &[Pair],
) -> f64 {
    let (w, h) = (image.width, image.height);
    let log_at = |(x, y): (u32, u32)| {
        let (sx, sy) = orientation.source(x, y, w, h);
        logs[(sy * w + sx) as usize]
    };
    let difference = |[a, b]: &Pair| (log_at(*a) - log_at(*b)).abs();
    let mut within_differences: Vec<f64> = within.iter().map(difference).collect();
    let k = ((EDGE_QUANTILE * (within_differences.len() - 1) as f64) as usize)
        .min(within_differences.len() - 1);
    let (_, &mut threshold, _) = within_differences.select_nth_unstable_by(k, f64::total_cmp);
    let edges = boundary
        .iter()
        .filter(|p| difference(p) > threshold)
        .count();
    edges as f64 / boundary.len() as f64
}

/// A warning for each view whose image shows its groups' boundaries far better read
/// otherwise, or in no reading more than chance would.
pub fn orientation_warnings(readings: &[OrientationReading]) -> Vec<String> {
    let turned = readings
        .iter()
        .filter(|r| r.edges_best_other - r.edges_as_is > ORIENTATION_MARGIN)
        .map(|r| {
            format!(
                "view '{}': its image shows the geometry's boundaries between groups far better {} ({:.0}% of {} boundaries as edges, against {:.0}% as it is; more than ORIENTATION_MARGIN {ORIENTATION_MARGIN} apart): is it written in another cube-face convention? relume reads views as `rpict -vtv` renders them, row 0 at the top (scene-format.md), and every recovered material depends on it",
                r.view,
                r.best_other.correction(),
                100.0 * r.edges_best_other,
                r.boundary_pairs,
                100.0 * r.edges_as_is
            )
        });
    let unrelated = readings
        .iter()
        .filter(|r| {
            r.boundary_pairs >= MIN_CHANCE_PAIRS
                && r.edges_as_is.max(r.edges_best_other) <= chance_bound(r.boundary_pairs)
        })
        .map(|r| {
            format!(
                "view '{}': its image shows the geometry's boundaries between groups no more often than chance in any reading ({:.0}% of {} boundaries as edges as it is, {:.0}% at best read {}, {:.0}% by chance with CHANCE_SIGMAS {CHANCE_SIGMAS} standard errors): is it another view's image, or of another scene? (Or do its groups look alike where they meet?) Every recovered material depends on it",
                r.view,
                100.0 * r.edges_as_is,
                r.boundary_pairs,
                100.0 * r.edges_best_other,
                r.best_other.correction(),
                100.0 * chance_bound(r.boundary_pairs)
            )
        });
    turned.chain(unrelated).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_orientation_reads_each_pixel_once_and_the_quarter_turns_undo_each_other() {
        for (w, h) in [(4, 4), (5, 3)] {
            for o in Orientation::ALL
                .into_iter()
                .filter(|o| w == h || !o.needs_square())
            {
                let mut read: Vec<(u32, u32)> = (0..h)
                    .flat_map(|y| (0..w).map(move |x| o.source(x, y, w, h)))
                    .collect();
                read.sort_unstable();
                read.dedup();
                assert_eq!(read.len(), (w * h) as usize, "{o:?} on {w}x{h}");
            }
        }
        let (cw, acw) = (
            Orientation::QuarterTurnClockwise,
            Orientation::QuarterTurnAnticlockwise,
        );
        for (x, y) in [(0, 0), (3, 1), (2, 3)] {
            let (sx, sy) = cw.source(x, y, 4, 4);
            assert_eq!(acw.source(sx, sy, 4, 4), (x, y));
        }
        // Turned clockwise, the top-left pixel is read at the top right.
        assert_eq!(cw.source(3, 0, 4, 4), (0, 0));
    }

    /// A `w` x `h` grey image of `albedo_at` each pixel under a gentle shading down the
    /// rows, with a little noise of its own (2%, the same draws for every image).
    fn shaded(w: u32, h: u32, albedo_at: impl Fn(u32, u32) -> f32) -> Image {
        let mut noise = 0x2545_f491_4f6c_dd1d_u64;
        let pixels = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| {
                noise ^= noise << 13;
                noise ^= noise >> 7;
                noise ^= noise << 17;
                let jitter = 1.0 + 0.02 * ((noise % 1000) as f32 / 1000.0 - 0.5);
                [albedo_at(x, y) * (1.0 + 0.01 * y as f32) * jitter; 3]
            })
            .collect();
        Image {
            width: w,
            height: h,
            pixels,
        }
    }

    /// A 64x64 view whose top-left 24x40 block is one group (dark) and the rest another
    /// (bright), each with a gentle shading and a little noise of its own: the image as it
    /// is shows the boundary; written mirrored left to right, it is told so.
    #[test]
    fn a_mirrored_view_is_told_and_one_the_right_way_round_is_not() {
        let (w, h) = (64u32, 64u32);
        let group_at = |x: u32, y: u32| u16::from(!(x < 24 && y < 40));
        let pure: Vec<PurePixel> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            // The pixels on the boundary are not pure.
            .filter(|&(x, y)| x != 24 && y != 40)
            .map(|(x, y)| PurePixel {
                view: 0,
                x,
                y,
                group: group_at(x, y),
            })
            .collect();
        let image = shaded(w, h, |x, y| if group_at(x, y) == 0 { 0.1 } else { 0.6 });
        let names = ["px".to_string()];
        let right = read_orientations(&pure, std::slice::from_ref(&image), &names);
        assert_eq!(right.len(), 1);
        assert!(right[0].edges_as_is > 0.9, "{right:?}");
        assert!(orientation_warnings(&right).is_empty(), "{right:?}");

        let mirrored = Image {
            pixels: (0..h)
                .flat_map(|y| (0..w).map(move |x| (w - 1 - x, y)))
                .map(|(x, y)| image.pixels[(y * w + x) as usize])
                .collect(),
            ..image
        };
        let wrong = read_orientations(&pure, &[mirrored], &names);
        assert_eq!(
            wrong[0].best_other,
            Orientation::MirroredLeftRight,
            "{wrong:?}"
        );
        let warnings = orientation_warnings(&wrong);
        assert_eq!(warnings.len(), 1, "{wrong:?}");
        assert!(
            warnings[0].contains("view 'px': its image shows the geometry's boundaries between groups far better mirrored left to right"),
            "{warnings:?}"
        );
    }

    /// A 64x64 view of two groups in 8x8 squares: its image shows their boundaries, and
    /// another image of the same shading and noise but no squares (another view's, as
    /// two faces' images swapped) shows none more than chance in any reading, and is told.
    #[test]
    fn a_view_whose_image_shows_no_boundary_more_than_chance_is_told() {
        let (w, h) = (64u32, 64u32);
        let group_at = |x: u32, y: u32| ((x / 8 + y / 8) % 2) as u16;
        let pure: Vec<PurePixel> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .filter(|&(x, y)| x % 8 != 0 && y % 8 != 0)
            .map(|(x, y)| PurePixel {
                view: 0,
                x,
                y,
                group: group_at(x, y),
            })
            .collect();
        let image = |squares: bool| {
            shaded(w, h, |x, y| match (squares, group_at(x, y)) {
                (true, 0) => 0.1,
                (true, _) => 0.6,
                (false, _) => 0.3,
            })
        };
        let names = ["py".to_string()];
        let right = read_orientations(&pure, &[image(true)], &names);
        assert!(right[0].boundary_pairs >= MIN_CHANCE_PAIRS, "{right:?}");
        assert!(orientation_warnings(&right).is_empty(), "{right:?}");
        let unrelated = read_orientations(&pure, &[image(false)], &names);
        let warnings = orientation_warnings(&unrelated);
        assert_eq!(warnings.len(), 1, "{unrelated:?}");
        assert!(
            warnings[0].contains("view 'py': its image shows the geometry's boundaries between groups no more often than chance in any reading"),
            "{warnings:?}"
        );
    }
}
