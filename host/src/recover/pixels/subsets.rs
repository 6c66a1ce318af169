//! Which of a group's pure pixels a measurement takes: an even subset of a large group,
//! whole tiles for the uncertainty's clusters, every k-th for a cache.

use super::{group_counts, PurePixel};

/// Keeps `limit` of `count` items met one by one, evenly over their order: item `seen`
/// when it crosses the next multiple of `count / limit` (the first item always); all of
/// them when `count <= limit`.
#[derive(Clone, Copy)]
struct EvenPick {
    count: usize,
    limit: usize,
    seen: usize,
    kept: usize,
}

impl EvenPick {
    fn new(count: usize, limit: usize) -> Self {
        EvenPick {
            count,
            limit: limit.min(count),
            seen: 0,
            kept: 0,
        }
    }

    /// Whether the next item is kept.
    fn next(&mut self) -> bool {
        let keep = self.kept < self.limit && self.seen * self.limit >= self.kept * self.count;
        self.seen += 1;
        self.kept += keep as usize;
        keep
    }
}

/// `pure` with group `g` thinned to at most `limit` pixels, evenly over its pixel order
/// (the other groups untouched).
pub fn limit_group(pure: Vec<PurePixel>, g: u16, limit: usize) -> Vec<PurePixel> {
    let count = pure.iter().filter(|p| p.group == g).count();
    if count <= limit {
        return pure;
    }
    let mut pick = EvenPick::new(count, limit);
    pure.into_iter()
        .filter(|p| p.group != g || pick.next())
        .collect()
}

/// At most `limit` pure pixels of each group, evenly over the group's pixel order (views,
/// then rows, then columns), so spread over every view and row in proportion to the
/// group's pixels there; a group of `limit` pixels or fewer is kept whole. The pixels keep
/// their order in `pure`, so when no group is larger than `limit` the result is `pure`
/// itself and every sum over it has the same bits. Deterministic: no seed.
pub fn spread_subset(pure: &[PurePixel], n_groups: usize, limit: usize) -> Vec<PurePixel> {
    let mut picks: Vec<EvenPick> = group_counts(pure, n_groups)
        .into_iter()
        .map(|count| EvenPick::new(count as usize, limit))
        .collect();
    pure.iter()
        .filter(|p| picks[p.group as usize].next())
        .copied()
        .collect()
}

/// The pixels of at most `limit` of the `tile` x `tile` tiles that `pixels` fall in,
/// whole tiles kept evenly over their order (view, tile row, tile column), the pixels in
/// their order; and the share of the tiles kept (1 when they are no more than `limit`,
/// and then the pixels are `pixels` itself). For an estimate that clusters by tile: a
/// sum over the kept tiles over the share estimates the sum over all of them.
pub fn whole_tiles(pixels: Vec<PurePixel>, tile: u32, limit: usize) -> (Vec<PurePixel>, f64) {
    let key = |p: &PurePixel| (p.view, p.y / tile, p.x / tile);
    let tiles: std::collections::BTreeSet<(u32, u32, u32)> = pixels.iter().map(key).collect();
    if tiles.len() <= limit {
        return (pixels, 1.0);
    }
    let mut pick = EvenPick::new(tiles.len(), limit);
    let kept: std::collections::BTreeSet<(u32, u32, u32)> =
        tiles.iter().copied().filter(|_| pick.next()).collect();
    let share = kept.len() as f64 / tiles.len() as f64;
    let pixels = pixels
        .into_iter()
        .filter(|p| kept.contains(&key(p)))
        .collect();
    (pixels, share)
}

/// Every k-th of `pixels`, from the first, with k the smallest stride that leaves at most
/// `at_most` (all of them when they are no more).
pub fn every_kth(pixels: Vec<PurePixel>, at_most: usize) -> Vec<PurePixel> {
    let stride = pixels.len().div_ceil(at_most.max(1)).max(1);
    pixels.into_iter().step_by(stride).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::recover::pixels::of_group;

    /// Whole tiles or none: every tile kept holds all its pixels, the tiles are spread
    /// over the views and rows, the share is the tiles' (not the pixels'), and a group in
    /// no more tiles than the limit is kept as it is.
    #[test]
    fn a_group_in_many_tiles_keeps_whole_tiles_spread_evenly() {
        // Two views of 16 x 8 pixels, tiles of 4: 4 x 2 tiles each, 16 in all; the last
        // column of view 1 left out, so its right tiles hold 12 pixels.
        let pixels: Vec<PurePixel> = (0..2)
            .flat_map(|view| {
                (0..8).flat_map(move |y| {
                    (0..16)
                        .filter(move |&x| !(view == 1 && x == 15))
                        .map(move |x| PurePixel {
                            view,
                            x,
                            y,
                            group: 3,
                        })
                })
            })
            .collect();
        let (same, share) = whole_tiles(pixels.clone(), 4, 16);
        assert_eq!((same, share), (pixels.clone(), 1.0));
        let (kept, share) = whole_tiles(pixels.clone(), 4, 6);
        assert_eq!(share, 6.0 / 16.0);
        let mut tiles = std::collections::BTreeMap::new();
        for p in &kept {
            *tiles.entry((p.view, p.y / 4, p.x / 4)).or_insert(0) += 1;
        }
        // Tiles 0, 3, 6, 8, 11 and 14 of 16: both views, both rows, and the short one.
        let expected = [
            ((0, 0, 0), 16),
            ((0, 0, 3), 16),
            ((0, 1, 2), 16),
            ((1, 0, 0), 16),
            ((1, 0, 3), 12),
            ((1, 1, 2), 16),
        ];
        assert_eq!(tiles.into_iter().collect::<Vec<_>>(), expected);
        // In their order.
        assert!(kept
            .windows(2)
            .all(|w| (w[0].view, w[0].y, w[0].x) < (w[1].view, w[1].y, w[1].x)));
        let (_, share) = whole_tiles(pixels, 4, 15);
        assert_eq!(share, 15.0 / 16.0);
    }

    #[test]
    fn limiting_a_group_keeps_an_even_subset_and_the_other_groups() {
        let pure: Vec<PurePixel> = (0..100)
            .map(|i| PurePixel {
                view: 0,
                x: i,
                y: 0,
                group: (i % 2) as u16,
            })
            .collect();
        let limited = limit_group(pure.clone(), 1, 10);
        let ones: Vec<u32> = limited
            .iter()
            .filter(|p| p.group == 1)
            .map(|p| p.x)
            .collect();
        assert_eq!(ones.len(), 10);
        assert!(ones.windows(2).all(|w| w[1] - w[0] == 10), "{ones:?}");
        assert_eq!(limited.iter().filter(|p| p.group == 0).count(), 50);
        assert_eq!(limit_group(pure.clone(), 1, 80), pure);
    }

    /// Two views of 40 x 30 pixels: group 0 the whole first view and the left half of the
    /// second, group 1 the second's right half, group 2 a 4 x 4 patch cut out of group 0.
    fn two_views() -> Vec<PurePixel> {
        let mut pure = Vec::new();
        for view in 0..2 {
            for y in 0..30 {
                for x in 0..40 {
                    let group = match (view, x, y) {
                        (0, 10..14, 10..14) => 2,
                        (1, 20.., _) => 1,
                        _ => 0,
                    };
                    pure.push(PurePixel { view, x, y, group });
                }
            }
        }
        pure
    }

    #[test]
    fn the_spread_subset_caps_large_groups_keeps_small_ones_whole_and_is_deterministic() {
        let pure = two_views();
        let counts = group_counts(&pure, 3);
        assert_eq!(counts, vec![1784, 600, 16]);
        let subset = spread_subset(&pure, 3, 100);
        assert_eq!(group_counts(&subset, 3), vec![100, 100, 16]);
        // Small groups whole, every pixel from `pure`, in `pure`'s order.
        assert_eq!(of_group(&subset, 2), of_group(&pure, 2));
        let position = |p: &PurePixel| pure.iter().position(|q| q == p).unwrap();
        let positions: Vec<usize> = subset.iter().map(position).collect();
        assert!(positions.windows(2).all(|w| w[0] < w[1]));
        // Deterministic, and the identity when no group is over the cap.
        assert_eq!(spread_subset(&pure, 3, 100), subset);
        assert_eq!(spread_subset(&pure, 3, 1784), pure);
        // A cap of one keeps one pixel per group.
        assert_eq!(group_counts(&spread_subset(&pure, 3, 1), 3), vec![1, 1, 1]);
    }

    #[test]
    fn the_spread_subset_covers_the_group_evenly() {
        let pure = two_views();
        let subset = spread_subset(&pure, 3, 100);
        // Group 0: 1184 of its 1784 pixels in view 0 and 600 in view 1, so about 66 and 34
        // of the 100; in every band of 5 rows of each view about a sixth of those.
        let group0 = of_group(&subset, 0);
        let in_view = |v: u32| group0.iter().filter(|p| p.view == v).count();
        assert!((65..=67).contains(&in_view(0)), "{}", in_view(0));
        assert!((33..=35).contains(&in_view(1)), "{}", in_view(1));
        for view in 0..2 {
            let per_band = in_view(view) as f64 / 6.0;
            for band in 0..6 {
                let n = group0
                    .iter()
                    .filter(|p| p.view == view && p.y / 5 == band)
                    .count() as f64;
                assert!((n - per_band).abs() <= 1.5, "view {view} band {band}: {n}");
            }
        }
        // Columns too: a quarter of group 1's pixels lie in each 5-column band of its 20.
        let group1 = of_group(&subset, 1);
        for band in 0..4 {
            let n = group1.iter().filter(|p| (p.x - 20) / 5 == band).count();
            assert!((15..=35).contains(&n), "band {band}: {n}");
        }
        // The group's mean of any smooth quantity (here x + y) is kept within a pixel.
        let mean = |pixels: &[PurePixel]| {
            pixels.iter().map(|p| (p.x + p.y) as f64).sum::<f64>() / pixels.len() as f64
        };
        assert!((mean(&group1) - mean(&of_group(&pure, 1))).abs() < 1.0);
    }
}
