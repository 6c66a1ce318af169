//! Stage 4 on the canary's floor: a brushed floor (anisotropic Ward, RADIANCE plastic2)
//! recovered by stage 4's proposal, a grid of lobe shapes and then Nelder-Mead, each
//! shape's colour and specularity in closed form over the transport cache. The cache is
//! traced anew, pixel by pixel, for every shape the search asks for (the grid's in one
//! pass), so that no more than one pixel's samples are held at once.

use crate::{floor_material, floor_sums, render_view, Line, PixelCache, PANORAMA_SPP};
use core::f64::consts::PI;
use relume_core::geometry::View;
use relume_core::material::{Kind, Material};
use relume_core::math::Vec3;
use relume_core::scene::Scene;
use relume_core::stages::anisotropic::{self, Shape, GRID_SHAPES};
use relume_core::stages::isotropic::{self, LinearSums, WardFit};
use relume_core::transport::{IncidentSample, LobePoint, INCIDENT_PER_SAMPLE};

/// The brushed floor's true material: plastic2's colour, specularity, roughness along and
/// across its brushing, and the brushing's angle from the floor's x axis.
const TRUE_COLOR: [f32; 3] = [0.45, 0.5, 0.55];
const TRUE_SPECULARITY: f32 = 0.15;
const TRUE_ROUGHNESS_U: f64 = 0.06;
const TRUE_ROUGHNESS_V: f64 = 0.2;
const TRUE_ANGLE_DEG: f64 = 30.0;

/// Samples per pixel of the cache stage 4 searches on: each of its some 250 shapes traces
/// the view again. At 32 the proposal's roughness along the brushing spread from 5% to
/// 36% off over the cache's seeds 3-8, with plain samples and with stratified ones alike,
/// wider than the check below allows.
const STAGE4_SPP: u32 = 64;

/// How far the recovered lobe may be from the truth: its roughnesses (relative) and its
/// direction (degrees). At these samples, over the cache's seeds 3-8, it misses the
/// roughnesses by 7-19% and 1-8%, the direction by at most 3.9 degrees (seed 3: 17%, 1%
/// and 1.3 degrees).
const ROUGHNESS_TOLERANCE: f64 = 0.3;
const ANGLE_TOLERANCE_DEG: f64 = 10.0;

/// `x` as (roughness along, roughness across, angle in [0, 180) degrees), the
/// smoother direction first: `(u, v, a)` and `(v, u, a + 90)` are the same lobe, as are
/// angles half a turn apart.
fn canonical(x: Shape) -> (f64, f64, f64) {
    let (u, v) = (libm::exp(x[0]), libm::exp(x[1]));
    let (u, v, angle) = if u <= v {
        (u, v, x[2])
    } else {
        (v, u, x[2] + PI / 2.0)
    };
    let degrees = angle.to_degrees();
    (u, v, degrees - 180.0 * libm::floor(degrees / 180.0))
}

/// Renders the brushed floor of `scene` and recovers its lobe by stage 4. Whether the
/// lobe came out right and fits better than an isotropic one; mixes what was recovered
/// into `checksum`.
#[inline(never)]
pub fn recover_brushed(scene: &Scene, view: &View, checksum: &mut u32) -> bool {
    let Some(basis) = scene.triangles.first().and_then(anisotropic::tangent_basis) else {
        return false;
    };
    let angle = TRUE_ANGLE_DEG.to_radians();
    let truth = floor_material(Material::WardAnisotropic {
        rho_d: Vec3::from(TRUE_COLOR) * (1.0 - TRUE_SPECULARITY),
        rho_s: Vec3::splat(TRUE_SPECULARITY),
        alpha_u: TRUE_ROUGHNESS_U as f32,
        alpha_v: TRUE_ROUGHNESS_V as f32,
        direction: Vec3::new(libm::cos(angle) as f32, libm::sin(angle) as f32, 0.0),
    });
    let mut true_scene = *scene;
    true_scene.materials = &truth;
    let real = render_view(&true_scene, view, PANORAMA_SPP, 1);

    let mut entries = [IncidentSample::default(); INCIDENT_PER_SAMPLE * STAGE4_SPP as usize];
    let mut points = [LobePoint::default(); INCIDENT_PER_SAMPLE * STAGE4_SPP as usize];
    let mut sums_of = |lobe: &dyn Fn(usize) -> Material, sums: &mut [LinearSums]| {
        let cache = PixelCache {
            entries: &mut entries,
            points: &mut points,
            spp: STAGE4_SPP,
        };
        floor_sums(scene, view, &real, cache, lobe, sums);
    };
    let fit_of = |sums: &LinearSums| isotropic::solve(Kind::Plastic, sums);
    let grid = anisotropic::proposal_grid();
    let mut grid_fits = [WardFit::default(); GRID_SHAPES];
    {
        let mut grid_sums = [LinearSums::default(); GRID_SHAPES];
        sums_of(&|k| anisotropic::unit_lobe(grid[k], basis), &mut grid_sums);
        for (fit, sums) in grid_fits.iter_mut().zip(&grid_sums) {
            *fit = fit_of(sums);
        }
    }
    let proposal = anisotropic::propose(&grid_fits, |x| {
        let mut sums = [LinearSums::default()];
        sums_of(&|_| anisotropic::unit_lobe(x, basis), &mut sums);
        fit_of(&sums[0])
    });
    let Ok((proposal, evaluations)) = proposal else {
        return false;
    };
    // The best isotropic lobe of the grid (its first angle's u == v shapes), for scale.
    let isotropic_sse = grid
        .iter()
        .zip(&grid_fits)
        .filter(|(x, _)| x[0] == x[1] && x[2] == 0.0)
        .map(|(_, fit)| fit.sse)
        .fold(f64::INFINITY, f64::min);

    let (u, v, degrees) = canonical(proposal.x);
    Line::new("stage 4: plastic2 specularity ")
        .number(proposal.fit.specularity)
        .text(", roughness ")
        .number(u)
        .text(" x ")
        .number(v)
        .text(" at ")
        .number(degrees)
        .text(" degrees, in ")
        .integer(evaluations)
        .text(" shapes; error ")
        .number(proposal.fit.sse / isotropic_sse)
        .text(" of the best isotropic grid lobe's")
        .print();
    for value in proposal.fit.color.iter().chain(&[proposal.fit.specularity]) {
        crate::mix(checksum, *value);
    }
    for value in proposal.x {
        crate::mix(checksum, value);
    }

    let off = |value: f64, truth: f64| libm::fabs(value / truth - 1.0);
    let turn = libm::fabs(degrees - TRUE_ANGLE_DEG);
    off(u, TRUE_ROUGHNESS_U) <= ROUGHNESS_TOLERANCE
        && off(v, TRUE_ROUGHNESS_V) <= ROUGHNESS_TOLERANCE
        && turn.min(180.0 - turn) <= ANGLE_TOLERANCE_DEG
        && proposal.fit.sse < isotropic_sse
}
