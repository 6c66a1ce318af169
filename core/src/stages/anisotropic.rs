//! Stage 4: the anisotropic Ward model (RADIANCE plastic2 / metal2).
//!
//! A lobe's shape is `x = (ln roughness_u, ln roughness_v, angle)`, the angle turning its
//! `u` direction in the plane of two surface tangents `(t, b)`. For one shape a pixel is
//! linear in the reflectances, as under stage 2's isotropic lobe (`I = rho_d D + S B(x)`),
//! so [`isotropic::solve`](super::isotropic::solve) gives the best colour and specularity in closed form and only
//! the shape is searched: a grid, then Nelder-Mead from its best point ([`propose`]).
//! The host measures each shape's sums on a group's transport cache (in parallel); what
//! is decided from them is here.
//!
//! Unlike the paper, colour and specularity are fitted anew with every shape rather than
//! kept from stage 2: an isotropic lobe fitted to an anisotropic highlight takes a biased
//! specularity (the living room's brushed plate: 0.44 against a true 0.9), under which no
//! anisotropic shape fits.

use glam::Vec3;

use super::isotropic::{WardFit, ROUGHNESS_MAX, ROUGHNESS_MIN};
use crate::geometry::Triangle;
use crate::material::Material;
use crate::nelder_mead::NelderMead;
use crate::Error;

/// A lobe shape: (ln roughness_u, ln roughness_v, angle of `u` from the first tangent
/// towards the second).
pub type Shape = [f64; 3];

/// Log-spaced roughness levels of the proposal's grid (pairs with u <= v).
pub const GRID_ROUGHNESS_LEVELS: usize = 6;
/// Direction angles of the grid, over [0, pi).
pub const GRID_ANGLES: usize = 8;
/// Shapes in the grid: every pair of levels with u <= v, at every angle.
pub const GRID_SHAPES: usize =
    GRID_ROUGHNESS_LEVELS * (GRID_ROUGHNESS_LEVELS + 1) / 2 * GRID_ANGLES;
/// Nelder-Mead evaluations after the grid.
pub const REFINE_EVALUATIONS: u32 = 80;
/// Nelder-Mead's first step, as a fraction of each parameter's range.
const REFINE_INITIAL_STEP: f64 = 0.05;

/// Bounds of a shape's search: the roughnesses within stage 2's range, and the angle
/// allowed to leave [0, pi) by up to a half turn, so that no search stalls at 0.
pub fn shape_bounds() -> (Shape, Shape) {
    let (lo, hi) = (libm::log(ROUGHNESS_MIN), libm::log(ROUGHNESS_MAX));
    (
        [lo, lo, -core::f64::consts::FRAC_PI_2],
        [hi, hi, 1.5 * core::f64::consts::PI],
    )
}

/// The shapes of the proposal's grid, level pairs (u <= v: a shape with u > v is the same
/// lobe turned by pi/2) outermost, angles innermost. The first angle's `u == v` points are
/// the isotropic lobes of the same levels.
pub fn proposal_grid() -> [Shape; GRID_SHAPES] {
    let (lo, hi) = (libm::log(ROUGHNESS_MIN), libm::log(ROUGHNESS_MAX));
    let level = |i: usize| lo + (hi - lo) * i as f64 / (GRID_ROUGHNESS_LEVELS - 1) as f64;
    let angle = |k: usize| core::f64::consts::PI * k as f64 / GRID_ANGLES as f64;
    let mut grid = [[0.0; 3]; GRID_SHAPES];
    let mut at = 0;
    for i in 0..GRID_ROUGHNESS_LEVELS {
        for j in i..GRID_ROUGHNESS_LEVELS {
            for k in 0..GRID_ANGLES {
                grid[at] = [level(i), level(j), angle(k)];
                at += 1;
            }
        }
    }
    grid
}

/// Two unit tangents of a triangle's plane (`None` for a degenerate one): its first edge
/// and the normal crossed with it. A group's directions are angles in its largest
/// triangle's plane: reflectance.md projects any direction onto each surface, so one angle
/// covers a planar group exactly and a curved one as its main face sees it.
pub fn tangent_basis(triangle: &Triangle) -> Option<(Vec3, Vec3)> {
    let n = triangle.normal_area2().try_normalize()?;
    let t = (triangle.v[1] - triangle.v[0]).try_normalize()?;
    Some((t, n.cross(t)))
}

/// The roughnesses and `u` direction of shape `x` in the plane of `(t, b)`.
pub fn lobe_at(x: Shape, (t, b): (Vec3, Vec3)) -> (f64, f64, Vec3) {
    let (sin, cos) = libm::sincos(x[2]);
    (
        libm::exp(x[0]),
        libm::exp(x[1]),
        t * cos as f32 + b * sin as f32,
    )
}

/// The unit specular lobe (`rho_s = 1`, no diffuse part) of shape `x`, whose pixel parts
/// are a shape's `B(x)`.
pub fn unit_lobe(x: Shape, basis: (Vec3, Vec3)) -> Material {
    let (alpha_u, alpha_v, direction) = lobe_at(x, basis);
    Material::WardAnisotropic {
        rho_d: Vec3::ZERO,
        rho_s: Vec3::ONE,
        alpha_u: alpha_u as f32,
        alpha_v: alpha_v as f32,
        direction,
    }
}

/// A lobe shape and its closed-form reflectances.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Proposal {
    pub fit: WardFit,
    pub x: Shape,
}

/// Stage 4's proposal: the grid's best shape (the first of equals, in grid order), then
/// Nelder-Mead from it, every point fitted by `fit_at`. `grid_fits[i]` is `fit_at` of
/// [`proposal_grid`]`()[i]`, measured by the caller (in parallel if it likes). Returns the
/// best shape seen and the evaluations spent, the grid's included.
pub fn propose(
    grid_fits: &[WardFit; GRID_SHAPES],
    mut fit_at: impl FnMut(Shape) -> WardFit,
) -> Result<(Proposal, u32), Error> {
    let grid = proposal_grid();
    let mut best = Proposal {
        fit: grid_fits[0],
        x: grid[0],
    };
    let offer = |p: Proposal, best: &mut Proposal| {
        if p.fit.sse < best.fit.sse {
            *best = p;
        }
    };
    for (&x, &fit) in grid.iter().zip(grid_fits).skip(1) {
        offer(Proposal { fit, x }, &mut best);
    }
    let (lower, upper) = shape_bounds();
    let mut search = NelderMead::new(
        lower,
        upper,
        best.x,
        best.fit.sse,
        REFINE_EVALUATIONS,
        REFINE_INITIAL_STEP,
    )?;
    let mut evaluations = GRID_SHAPES as u32;
    while !search.is_done() {
        evaluations += 1;
        let x = search.propose();
        let fit = fit_at(x);
        search.tell(fit.sse);
        offer(Proposal { fit, x }, &mut best);
    }
    Ok((best, evaluations))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::Kind;
    use crate::stages::isotropic::{self, LinearSums};
    use crate::transport::{self, IncidentSample, LobePoint};

    const SIDE: usize = 8;
    const SAMPLES: usize = 96;

    /// One pixel of a flat group (normal +z) that sees a small bright source near its
    /// mirror direction: `(i, j)` moves the view across the highlight, whose shape is what
    /// tells lobes apart.
    fn pixel_samples(i: usize, j: usize) -> [IncidentSample; SAMPLES] {
        let source = Vec3::new(0.3, -0.2, 1.0).normalize();
        let (x, y) = (
            i as f32 / (SIDE - 1) as f32 - 0.5,
            j as f32 / (SIDE - 1) as f32 - 0.5,
        );
        let wo = Vec3::new(-source.x + 0.5 * x, -source.y + 0.5 * y, source.z).normalize();
        core::array::from_fn(|k| {
            let (a, b) = ((k % 12) as f32 / 11.0 - 0.5, (k / 12) as f32 / 7.0 - 0.5);
            let wi = (source + Vec3::new(0.4 * a, 0.4 * b, 0.0)).normalize();
            let spot = libm::expf(-(wi - source).length_squared() / 0.01);
            IncidentSample {
                wo,
                n: Vec3::Z,
                wi,
                weight: Vec3::splat(0.2 + 5.0 * spot),
                uv: [0.0, 0.0],
            }
        })
    }

    /// The normal-equation sums of the synthetic group under `lobe`, its pixels rendered
    /// exactly (same samples) under `truth`.
    fn sums(truth: &Material, lobe: &Material) -> LinearSums {
        let mut sums = LinearSums::default();
        for i in 0..SIDE {
            for j in 0..SIDE {
                let samples = pixel_samples(i, j);
                let n = SAMPLES as u32;
                let mut points = [LobePoint::default(); SAMPLES];
                let mut count = 0;
                for p in samples.iter().filter_map(transport::lobe_point) {
                    points[count] = p;
                    count += 1;
                }
                let d = transport::diffuse_part(&samples, n);
                let b = transport::specular_part(&points[..count], n, lobe);
                let t = transport::shade(&samples, n, truth, None);
                sums.add(d.to_array(), b.to_array(), t.to_array());
            }
        }
        sums
    }

    fn propose_for(truth: &Material, kind: Kind, basis: (Vec3, Vec3)) -> (Proposal, u32) {
        let fit_at = |x: Shape| isotropic::solve(kind, &sums(truth, &unit_lobe(x, basis)));
        let grid = proposal_grid();
        let grid_fits = core::array::from_fn(|i| fit_at(grid[i]));
        propose(&grid_fits, fit_at).unwrap()
    }

    /// The shape's roughnesses and direction named with u <= v (a shape with u > v is the
    /// same lobe, its direction turned by pi/2 about the normal +z).
    fn canonical(x: Shape, basis: (Vec3, Vec3)) -> (f64, f64, Vec3) {
        let (u, v, d) = lobe_at(x, basis);
        if u <= v {
            (u, v, d)
        } else {
            (v, u, Vec3::Z.cross(d))
        }
    }

    #[test]
    fn the_proposal_recovers_an_anisotropic_metal_lobe_and_its_direction() {
        let (color, s) = (Vec3::new(0.75, 0.76, 0.78), 0.9);
        let direction = Vec3::new(1.0, 1.0, 0.0).normalize();
        let truth = Material::WardAnisotropic {
            rho_d: color * (1.0 - s),
            rho_s: color * s,
            alpha_u: 0.05,
            alpha_v: 0.2,
            direction,
        };
        let basis = (Vec3::X, Vec3::Y);
        let (p, evaluations) = propose_for(&truth, Kind::Metal, basis);
        assert!(evaluations > GRID_SHAPES as u32, "{evaluations}");
        let (u, v, d) = canonical(p.x, basis);
        assert!((u / 0.05 - 1.0).abs() < 0.05, "{p:?}");
        assert!((v / 0.2 - 1.0).abs() < 0.05, "{p:?}");
        let off = libm::acosf(d.dot(direction).abs().min(1.0)).to_degrees();
        assert!(off < 3.0, "direction {off} degrees off: {p:?}");
        assert!((p.fit.specularity - 0.9).abs() < 0.02, "{p:?}");
        assert!(p.fit.relative_error < 0.01, "{p:?}");
    }

    #[test]
    fn an_isotropic_plastic_lobe_comes_out_with_equal_roughnesses() {
        let truth = Material::Ward {
            rho_d: Vec3::new(0.5, 0.4, 0.3) * 0.94,
            rho_s: Vec3::splat(0.06),
            alpha: 0.1,
        };
        // Tangents off the axes: the answer must not depend on the basis.
        let t = Vec3::new(0.6, 0.8, 0.0);
        let (p, _) = propose_for(&truth, Kind::Plastic, (t, Vec3::Z.cross(t)));
        let (u, v, _) = canonical(p.x, (t, Vec3::Z.cross(t)));
        assert!(
            (u / 0.1 - 1.0).abs() < 0.05 && (v / 0.1 - 1.0).abs() < 0.05,
            "{p:?}"
        );
        assert!((p.fit.specularity - 0.06).abs() < 0.003, "{p:?}");
    }

    #[test]
    fn the_grid_spans_the_bounds_with_u_at_most_v_and_the_isotropic_lobes_first_at_each_level() {
        let grid = proposal_grid();
        let (lower, upper) = shape_bounds();
        for x in &grid {
            assert!(x[0] <= x[1], "{x:?}");
            // Within the bounds, up to the rounding of `lo + (hi - lo) * 5 / 5`.
            for k in 0..3 {
                assert!(
                    lower[k] - 1e-12 <= x[k] && x[k] <= upper[k] + 1e-12,
                    "{x:?}"
                );
            }
            assert!(x[2] < core::f64::consts::PI);
        }
        let (u0, v0, _) = lobe_at(grid[0], (Vec3::X, Vec3::Y));
        assert!((u0 - ROUGHNESS_MIN).abs() < 1e-12 && (v0 - ROUGHNESS_MIN).abs() < 1e-12);
        let (u, v, _) = lobe_at(grid[GRID_SHAPES - 1], (Vec3::X, Vec3::Y));
        assert!((u - ROUGHNESS_MAX).abs() < 1e-12 && (v - ROUGHNESS_MAX).abs() < 1e-12);
    }

    #[test]
    fn a_degenerate_triangle_has_no_tangent_plane() {
        let flat = Triangle {
            v: [Vec3::ZERO, Vec3::X, Vec3::Y],
            uv: [glam::Vec2::ZERO; 3],
            surface: crate::geometry::Surface::Group(0),
        };
        let (t, b) = tangent_basis(&flat).unwrap();
        assert!((t - Vec3::X).length() < 1e-6 && (b - Vec3::Y).length() < 1e-6);
        let line = Triangle {
            v: [Vec3::ZERO, Vec3::X, 2.0 * Vec3::X],
            ..flat
        };
        assert_eq!(tangent_basis(&line), None);
    }
}
