//! Stages 3 and 5 on the canary's floor: the cross contrast (stage 3) tells a checker
//! floor, fitted as one colour, from the glossy floor under its recovered lobe, and the
//! map solve (stage 5) recovers the checker's texels from its pixels and the irradiance.
//! As the host does it (`host/src/recover/texture/`), in fixed storage.

use crate::{render_view, Line, PANORAMA_SPP, PIXELS, RENDER_SPP, SIDE};
use relume_core::fit::TEXTURE_STEP;
use relume_core::geometry::View;
use relume_core::material::{
    Material, SurfaceMaterial, TextureGrid, TextureId, TextureInfo, Textures, Wrap,
};
use relume_core::math::{self, luminance, Vec2, Vec3};
use relume_core::scene::Scene;
use relume_core::stages::texture;
use relume_core::stages::texture_map::{self, MapObservation, FOOTPRINT_OFFSETS};

/// Texels a side of the checker's map: the view sees the middle half of the floor, 4 x 4
/// texels, each about 4 pixels wide.
const CHECKER: u32 = 8;
/// Texels a side of one square of the checker. At one, every texel unlike its neighbours,
/// the pattern is at the map's Nyquist limit, which the solver's iterations leave smoothed
/// by design (`texture_map::SOLVER_ITERATIONS`): dark texels read 5-8% bright.
const SQUARE: u32 = 2;
const TEXELS: usize = (CHECKER * CHECKER) as usize;
const LIGHT_SQUARE: [f32; 3] = [0.7, 0.6, 0.5];
const DARK_SQUARE: [f32; 3] = [0.2, 0.25, 0.3];

/// How far a recovered texel the view sees may be from the truth (relative, per channel):
/// at these samples the worst of the 48 values (16 texels, 3 channels) misses by 3.0%,
/// the rest by at most 2.5%.
const MAP_TOLERANCE: f32 = 0.05;

/// Samples per pixel of the irradiance render (with a white map).
const GAIN_SPP: u32 = 64;

fn checker() -> [Vec3; TEXELS] {
    core::array::from_fn(|k| {
        let (i, j) = (k as u32 % CHECKER, k as u32 / CHECKER);
        Vec3::from(if (i / SQUARE + j / SQUARE).is_multiple_of(2) {
            LIGHT_SQUARE
        } else {
            DARK_SQUARE
        })
    })
}

const GRID: TextureGrid = TextureGrid {
    width: CHECKER,
    height: CHECKER,
    wrap: Wrap::Clamp,
};

const INFOS: [TextureInfo; 1] = [TextureInfo {
    grid: GRID,
    offset: 0,
}];

/// The floor under map 0 (its `rho_d` unused: the map replaces it).
fn mapped_floor() -> [SurfaceMaterial; 1] {
    [SurfaceMaterial {
        material: Material::Diffuse { rho_d: Vec3::ONE },
        diffuse_map: Some(TextureId(0)),
    }]
}

/// Stage 3's statistic for the floor of `scene` (under the model its materials hold)
/// against `real`: the noise-free RMS change of `ln(real / rendered)` over
/// `TEXTURE_STEP` pixels along rows and columns, from two independent renders.
pub fn contrast(scene: &Scene, view: &View, real: &[Vec3; PIXELS]) -> Option<f64> {
    let a = render_view(scene, view, RENDER_SPP, 4);
    let b = render_view(scene, view, RENDER_SPP, 5);
    let log_ratio = |rendered: &[Vec3; PIXELS], i: usize| {
        let (real, rendered) = (luminance(real[i]) as f64, luminance(rendered[i]) as f64);
        (real > 0.0 && rendered > 0.0).then(|| libm::log(real / rendered))
    };
    let step = TEXTURE_STEP as usize;
    let side = SIDE as usize;
    let along_rows = (0..PIXELS)
        .filter(move |i| i % side + step < side)
        .map(move |i| (i, i + step));
    let along_columns = (0..PIXELS - step * side).map(move |i| (i, i + step * side));
    texture::cross_contrast(along_rows.chain(along_columns).filter_map(|(i, j)| {
        Some((
            log_ratio(&a, i)? - log_ratio(&a, j)?,
            log_ratio(&b, i)? - log_ratio(&b, j)?,
        ))
    }))
}

/// The texture coordinates of pixel `i`'s footprint samples on the floor (z = 0, its
/// coordinates `((x + 1) / 2, (y + 1) / 2)`).
fn footprint_uv(view: &View, i: usize) -> [Vec2; texture_map::FOOTPRINT_SAMPLES] {
    let (x, y) = ((i as u32 % SIDE) as f32, (i as u32 / SIDE) as f32);
    FOOTPRINT_OFFSETS.map(|[dx, dy]| {
        let ray = view.ray(x + dx, y + dy);
        let p = ray.at(-ray.origin.z / ray.direction.z);
        Vec2::new((p.x + 1.0) * 0.5, (p.y + 1.0) * 0.5)
    })
}

/// Renders the checker floor of `scene` (the canary's, whose floor has texture
/// coordinates), tests it with stage 3 under the one colour stage 1 gives it, and recovers
/// its map by stage 5. Whether both came out right; `glossy_contrast` is stage 3's
/// statistic of the glossy floor under its recovered lobe, which must read untextured.
/// Mixes the contrasts and the recovered texels into `checksum`.
#[inline(never)]
pub fn recover_checker(
    scene: &Scene,
    view: &View,
    glossy_contrast: Option<f64>,
    checksum: &mut u32,
) -> bool {
    let truth = checker();
    let Ok(textures) = Textures::new(&INFOS, &truth) else {
        return false;
    };
    let materials = mapped_floor();
    let mut mapped = *scene;
    mapped.materials = &materials;
    mapped.textures = textures;
    let real = render_view(&mapped, view, PANORAMA_SPP, 1);

    // Stage 1 gives the checker one colour; stage 3 must find the pattern it leaves.
    let (rho_d, _) = crate::recover_diffuse(scene, view, &real);
    let uniform = crate::diffuse_floor(rho_d);
    let mut uniform_scene = *scene;
    uniform_scene.materials = &uniform;
    let checker_contrast = contrast(&uniform_scene, view, &real);
    let textured = |c: Option<f64>| c.is_some_and(texture::has_texture_contrast);
    let print = |c: Option<f64>| c.unwrap_or(f64::INFINITY);
    Line::new("stage 3: step contrast, the checker ")
        .number(print(checker_contrast))
        .text(", the glossy floor ")
        .number(print(glossy_contrast))
        .print();
    let classes_ok = textured(checker_contrast) && !textured(glossy_contrast);

    // Stage 5: the gain of each pixel (radiance per unit reflectance, E / pi) from a
    // render under a white map, then the map that explains the pixels.
    let white = [Vec3::ONE; TEXELS];
    let Ok(white_textures) = Textures::new(&INFOS, &white) else {
        return false;
    };
    mapped.textures = white_textures;
    let gain = render_view(&mapped, view, GAIN_SPP, 6);
    let observations: [MapObservation; PIXELS] = core::array::from_fn(|i| MapObservation {
        uv: footprint_uv(view, i),
        gain: gain[i],
        target: real[i],
        weight: 1.0,
    });
    let start = Vec3::new(rho_d[0] as f32, rho_d[1] as f32, rho_d[2] as f32);
    let mut texels = [start; TEXELS];
    let (mut numerator, mut denominator) = ([Vec3::ZERO; TEXELS], [Vec3::ZERO; TEXELS]);
    let solved = texture_map::solve_map(
        &observations,
        GRID,
        0.99,
        &mut texels,
        &mut numerator,
        &mut denominator,
    );
    // The texels whose centres the view sees (the middle half of the floor): columns and
    // rows 2 to 5.
    let middle = |i: usize| (CHECKER as usize / 4..3 * CHECKER as usize / 4).contains(&i);
    let seen =
        (0..TEXELS).filter(|&k| middle(k % CHECKER as usize) && middle(k / CHECKER as usize));
    let worst = seen
        .flat_map(|k| (0..3).map(move |c| (k, c)))
        .map(|(k, c)| math::abs(texels[k][c] / truth[k][c] - 1.0))
        .fold(0.0f32, f32::max);
    for value in [checker_contrast, glossy_contrast] {
        crate::mix(checksum, value.unwrap_or(f64::NAN));
    }
    for texel in &texels {
        for c in 0..3 {
            crate::mix(checksum, texel[c] as f64);
        }
    }
    Line::new("stage 5: the checker's map, worst texel seen off by ")
        .number(worst as f64)
        .print();
    classes_ok && solved.is_ok() && worst <= MAP_TOLERANCE
}
