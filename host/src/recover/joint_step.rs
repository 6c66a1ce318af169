//! The diffuse iteration's step for all its groups at once: per channel, Broyden's joint
//! secant in log space (`relume_core::stages::diffuse::JointSecant`), which learns how each
//! group's render responds to every group's colour, not to its own alone.

use relume_core::fit::{self, GroupFit};
use relume_core::stages::diffuse::{self, JointSecant, MAX_DIFFUSE_REFLECTANCE};

/// One channel's estimate and what the last step left to learn from.
struct Channel {
    secant: JointSecant<Vec<f64>>,
    /// Per group, at the last render: its log colour and log mean render, where the group
    /// took the joint step.
    last: Vec<Option<(f64, f64)>>,
}

/// The iteration's state between its steps.
pub(super) struct JointStep {
    channels: [Channel; 3],
}

impl JointStep {
    /// A state for `n` groups, the paper's rule until it has learnt from a step.
    pub fn new(n: usize) -> JointStep {
        let room = JointSecant::<Vec<f64>>::storage_len(n, fit::DIFFUSE_MAX_STEPS as usize);
        JointStep {
            channels: core::array::from_fn(|_| Channel {
                secant: JointSecant::new(n, vec![0.0; room], vec![0.0; room]),
                last: vec![None; n],
            }),
        }
    }

    /// The next colours of the groups that are `Some` in `colours`, from `fits`, the
    /// render of the colours as they are. A group takes the joint step in a channel where
    /// its colour, panorama and render are all above 0 (a log exists) and it is not held at
    /// its bound; elsewhere the paper's rule ([`diffuse::update`]). Returns the largest
    /// relative change.
    pub fn step(&mut self, colours: &mut [Option<[f64; 3]>], fits: &[GroupFit]) -> f64 {
        let n = colours.len();
        let mut next: Vec<Option<[f64; 3]>> = colours
            .iter()
            .zip(fits)
            .map(|(colour, fit)| colour.map(|c| diffuse::update(c, fit).0))
            .collect();
        for (c, channel) in self.channels.iter_mut().enumerate() {
            let now: Vec<Option<(f64, f64)>> = (0..n)
                .map(|g| {
                    let colour = colours[g]?[c];
                    let fit = &fits[g];
                    let (real, rendered) = (fit.sum_real[c], fit.sum_rendered[c]);
                    // A colour at its bound that the panorama would raise is held there,
                    // out of the system: the joint step would count on its rise.
                    let held = colour >= MAX_DIFFUSE_REFLECTANCE && real > rendered;
                    (fit.pixels > 0 && colour > 0.0 && real > 0.0 && rendered > 0.0 && !held)
                        .then(|| (libm::log(colour), libm::log(rendered / fit.pixels as f64)))
                })
                .collect();
            let mut s = vec![0.0; n];
            let mut y = vec![0.0; n];
            for g in 0..n {
                if let (Some(a), Some(b)) = (channel.last[g], now[g]) {
                    s[g] = b.0 - a.0;
                    y[g] = b.1 - a.1;
                }
            }
            channel.secant.learn(&s, &y);
            let residual: Vec<f64> = (0..n)
                .map(|g| match now[g] {
                    Some(_) => libm::log(fits[g].mean_ratio()[c]),
                    None => 0.0,
                })
                .collect();
            let mut dx = vec![0.0; n];
            channel.secant.step(&residual, &mut dx);
            for g in 0..n {
                if let (Some(colour), Some(next)) = (colours[g], next[g].as_mut()) {
                    if now[g].is_some() {
                        next[c] =
                            (colour[c] * libm::exp(dx[g])).clamp(0.0, MAX_DIFFUSE_REFLECTANCE);
                    }
                }
            }
            channel.last = now;
        }
        let mut change = 0.0f64;
        for (colour, next) in colours.iter_mut().zip(next) {
            if let (Some(before), Some(after)) = (*colour, next) {
                change = change.max(diffuse::relative_distance(after, before));
                *colour = Some(after);
            }
        }
        change
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use relume_core::math::Vec3;

    /// A room of three groups lit by interreflection: group `g`'s mean render is
    /// `rho_g * (e_g + sum_h F_gh B_h)` with radiosities `B` (Jacobi-solved), and group 1
    /// lit only by the others.
    fn render(rho: &[f64]) -> Vec<f64> {
        let e = [1.0, 0.0, 0.6];
        let f = [[0.1, 0.5, 0.3], [0.6, 0.0, 0.3], [0.3, 0.4, 0.2]];
        let mut b = vec![0.0; 3];
        for _ in 0..2000 {
            b = (0..3)
                .map(|g| rho[g] * (e[g] + (0..3).map(|h| f[g][h] * b[h]).sum::<f64>()))
                .collect();
        }
        b
    }

    fn fit_of(real: f64, rendered: f64) -> GroupFit {
        let mut fit = GroupFit::default();
        fit.add(
            Vec3::splat(real as f32),
            Vec3::splat(rendered as f32),
            Vec3::ZERO,
        );
        fit
    }

    /// The fits of the room rendered with the channel-0 colours of `colours` against the
    /// panorama `real` (one mean per group).
    fn fits_of(colours: &[Option<[f64; 3]>], real: &[f64]) -> Vec<GroupFit> {
        let rho: Vec<f64> = colours.iter().map(|c| c.unwrap()[0]).collect();
        render(&rho)
            .iter()
            .zip(real)
            .map(|(&r, &t)| fit_of(t, r))
            .collect()
    }

    /// Steps until every colour is within `tol` of the truth, by the joint step or by the
    /// paper's rule.
    fn steps_to(joint: bool, tol: f64) -> usize {
        let truth = [0.7, 0.6, 0.8];
        let real = render(&truth);
        let mut colours = vec![Some([0.5; 3]); 3];
        let mut state = JointStep::new(3);
        for step in 1..=60 {
            let fits = fits_of(&colours, &real);
            if joint {
                state.step(&mut colours, &fits);
            } else {
                for (colour, fit) in colours.iter_mut().zip(&fits) {
                    *colour = Some(diffuse::update(colour.unwrap(), fit).0);
                }
            }
            let worst = (0..3)
                .map(|g| (colours[g].unwrap()[0] / truth[g] - 1.0).abs())
                .fold(0.0, f64::max);
            if worst < tol {
                return step;
            }
        }
        60
    }

    #[test]
    fn the_joint_step_learns_the_rooms_coupling() {
        let (plain, joint) = (steps_to(false, 1e-4), steps_to(true, 1e-4));
        assert!(joint <= 8, "joint {joint}");
        assert!(2 * joint <= plain, "joint {joint} vs plain {plain}");
    }

    /// A panorama brighter than any colour renders (a light too dim): every colour ends
    /// at its bound, the one lit only by the others too, though the joint step had learnt
    /// to expect its light to rise with theirs.
    #[test]
    fn a_panorama_too_bright_sends_every_colour_to_its_bound() {
        let real: Vec<f64> = render(&[0.7, 0.6, 0.8]).iter().map(|r| 10.0 * r).collect();
        let mut colours = vec![Some([0.5; 3]); 3];
        let mut state = JointStep::new(3);
        for _ in 0..20 {
            let fits = fits_of(&colours, &real);
            state.step(&mut colours, &fits);
        }
        for colour in colours {
            assert_eq!(colour.unwrap()[0], MAX_DIFFUSE_REFLECTANCE, "{colour:?}");
        }
    }

    #[test]
    fn groups_without_a_log_take_the_papers_rule_and_others_stay() {
        let mut state = JointStep::new(3);
        // Group 0 unseen (no pixels), group 1 black in the panorama, group 2 not iterated.
        let mut colours = vec![Some([0.5; 3]), Some([0.5; 3]), None];
        let fits = [GroupFit::default(), fit_of(0.0, 0.2), fit_of(0.3, 0.1)];
        state.step(&mut colours, &fits);
        assert_eq!(colours[0], Some([0.5; 3]));
        assert_eq!(colours[1], Some([0.0; 3]));
        assert_eq!(colours[2], None);
    }
}
