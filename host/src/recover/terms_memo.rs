//! The paired cross terms of the last few measurements, kept by everything that sets
//! them. A decision's ladder weighs its simple model against rung after rung at the same
//! pixels, samples and seed ([`super::Recovery::compare_models`]), and each time rendered
//! the simple model again: on the living room at 64 px, 7.8% of the samples of every
//! paired measurement were such repeats. A render is a function of the scene, its
//! settings and the pixels, so a measurement found here is the one a render would give,
//! to the bit.

use std::collections::VecDeque;

use super::model::GroupModel;
use super::pixels::PurePixel;
use super::texture::RecoveredMap;

/// One pixel's paired cross terms and `|T|^2` (see `pixels::paired_cross_terms`).
pub type Terms = ([f64; 2], f64);

/// What a measurement's terms depend on besides the fixed geometry, lights and panorama:
/// every group's model, the maps the textured ones index, the pixels, and the settings.
#[derive(PartialEq)]
pub struct MeasurementKey {
    pub models: Vec<GroupModel>,
    pub maps: Vec<RecoveredMap>,
    pub pixels: Vec<PurePixel>,
    pub spp: u32,
    pub seed: u64,
}

/// The last [`TermsMemo::CAPACITY`] measurements, the newest last.
#[derive(Default)]
pub struct TermsMemo {
    entries: VecDeque<(MeasurementKey, Vec<Terms>)>,
}

impl TermsMemo {
    /// A ladder's repeats come a rung or two apart (its simple model at each of its
    /// sample counts); a few entries hold them without holding a run's every measurement.
    const CAPACITY: usize = 8;

    /// The terms measured under `key`, if they are still held.
    pub fn get(&self, key: &MeasurementKey) -> Option<&[Terms]> {
        self.entries
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, terms)| terms.as_slice())
    }

    /// Keeps `terms` as measured under `key`, forgetting the oldest entry when full.
    pub fn keep(&mut self, key: MeasurementKey, terms: Vec<Terms>) {
        if self.entries.len() == Self::CAPACITY {
            self.entries.pop_front();
        }
        self.entries.push_back((key, terms));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(spp: u32, color: f64) -> MeasurementKey {
        MeasurementKey {
            models: vec![GroupModel::Diffuse { color: [color; 3] }],
            maps: Vec::new(),
            pixels: vec![PurePixel {
                view: 0,
                x: 1,
                y: 2,
                group: 0,
            }],
            spp,
            seed: 7,
        }
    }

    #[test]
    fn a_measurement_is_found_only_under_its_own_key() {
        let mut memo = TermsMemo::default();
        memo.keep(key(32, 0.5), vec![([1.0, 2.0], 3.0)]);
        assert_eq!(memo.get(&key(32, 0.5)), Some(&[([1.0, 2.0], 3.0)][..]));
        assert_eq!(memo.get(&key(64, 0.5)), None);
        assert_eq!(memo.get(&key(32, 0.25)), None);
    }

    #[test]
    fn the_oldest_measurement_is_forgotten_first() {
        let mut memo = TermsMemo::default();
        for i in 0..=TermsMemo::CAPACITY as u32 {
            memo.keep(key(i, 0.5), vec![([i as f64, 0.0], 0.0)]);
        }
        assert_eq!(memo.get(&key(0, 0.5)), None);
        assert!(memo.get(&key(1, 0.5)).is_some());
        assert!(memo.get(&key(TermsMemo::CAPACITY as u32, 0.5)).is_some());
    }
}
