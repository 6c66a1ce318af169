//! A `#![no_std]` program, all storage on the stack, that proves the core's renderer *and*
//! its solver run without std or an allocator, as on a small target: it renders a small
//! scene (a checksum of a few pixels), then recovers a glossy floor's material from a
//! "panorama" rendered with known materials, by stage 1's diffuse iteration and stage 2's
//! closed-form isotropic fit over the transport cache, streamed pixel by pixel; stage 3's
//! contrast must call a checker floor textured and the glossy one not, and stage 5 must
//! recover the checker's map (`textured.rs`). It exits with 1 when a recovery misses the
//! known material, and prints a checksum of every bit it recovered.
//!
//! It builds for two targets, each with its own entry point, output and panic handler:
//! this machine (`platform_libc.rs`: libc's `main` and `write`, the CI's proof) and a
//! bare Cortex-M4F (`platform_cortex_m.rs`: cortex-m-rt's reset handler, semihosting
//! output; `run-cortex-m4` runs it under QEMU and checks that both print the same bytes).
#![no_std]
#![no_main]

#[cfg(not(target_os = "none"))]
#[path = "platform_libc.rs"]
mod platform;

#[cfg(target_os = "none")]
#[path = "platform_cortex_m.rs"]
mod platform;

mod brushed;
mod textured;

use relume_core::bvh::{Bvh, BvhBuffers, BvhNode, PackedTriangle};
use relume_core::fit::GroupFit;
use relume_core::geometry::{Surface, Triangle, View};
use relume_core::material::{Kind, Material, SurfaceMaterial, Textures};
use relume_core::math::{Vec2, Vec3};
use relume_core::render::{render_pixel, RenderSettings};
use relume_core::scene::{GroupPlane, LightTriangle, Scene, SceneStorage};
use relume_core::stages::{diffuse, isotropic};
use relume_core::transport::{
    self, IncidentSample, LobePoint, INCIDENT_PER_SAMPLE, MAX_INCIDENT_PER_SAMPLE,
};

/// A line of text built without an allocator.
struct Line {
    bytes: [u8; 160],
    len: usize,
}

impl Line {
    fn new(text: &str) -> Line {
        let mut line = Line {
            bytes: [0; 160],
            len: 0,
        };
        line.text(text);
        line
    }

    fn text(&mut self, text: &str) -> &mut Line {
        self.raw(text.as_bytes())
    }

    /// ASCII bytes; what does not fit is dropped.
    fn raw(&mut self, bytes: &[u8]) -> &mut Line {
        for &b in bytes {
            if self.len < self.bytes.len() {
                self.bytes[self.len] = b;
                self.len += 1;
            }
        }
        self
    }

    /// `value` with four decimals (non-negative values only; others print as `?`).
    fn number(&mut self, value: f64) -> &mut Line {
        if !(0.0..1e9).contains(&value) {
            return self.text("?");
        }
        self.decimal((value * 1e4 + 0.5) as u64, 4)
    }

    /// `value` in decimal.
    fn integer(&mut self, value: u32) -> &mut Line {
        self.decimal(value as u64, 0)
    }

    /// The digits of `value`, the last `decimals` of them after a point (and one at least
    /// before it).
    fn decimal(&mut self, value: u64, decimals: usize) -> &mut Line {
        let mut digits = [0u8; 20];
        let (mut n, mut rest) = (0, value);
        while n <= decimals || rest > 0 {
            digits[n] = b'0' + (rest % 10) as u8;
            rest /= 10;
            n += 1;
        }
        for i in (0..n).rev() {
            if decimals > 0 && i + 1 == decimals {
                self.text(".");
            }
            self.raw(&[digits[i]]);
        }
        self
    }

    /// `value` as eight hexadecimal digits.
    fn hex(&mut self, value: u32) -> &mut Line {
        for i in 0..8 {
            self.raw(&[b"0123456789abcdef"[((value >> (28 - 4 * i)) & 0xf) as usize]]);
        }
        self
    }

    fn print(&mut self) {
        self.text("\n");
        platform::print(&self.bytes[..self.len]);
    }
}

/// Two triangles of the quad `a b c d`, with texture coordinates `((x + 1) / 2, (y + 1) / 2)`
/// (the floor's [-1, 1]^2 over the map's [0, 1]^2).
fn quad(a: Vec3, b: Vec3, c: Vec3, d: Vec3, surface: Surface) -> [Triangle; 2] {
    let uv = |p: Vec3| Vec2::new((p.x + 1.0) * 0.5, (p.y + 1.0) * 0.5);
    [
        Triangle {
            v: [a, b, c],
            uv: [uv(a), uv(b), uv(c)],
            surface,
        },
        Triangle {
            v: [a, c, d],
            uv: [uv(a), uv(c), uv(d)],
            surface,
        },
    ]
}

/// The floor's true material (RADIANCE plastic: colour, specularity, roughness).
const TRUE_COLOR: [f32; 3] = [0.6, 0.5, 0.4];
const TRUE_SPECULARITY: f32 = 0.08;
const TRUE_ROUGHNESS: f32 = 0.1;

/// Pixels per side of the view the floor is recovered from: at 8 the pixels around the
/// highlight are too few to pin its roughness (a lobe of 0.012 fits them as well as 0.1).
const SIDE: u32 = 16;
const PIXELS: usize = (SIDE * SIDE) as usize;
/// Samples per pixel of the "panorama", of stage 1's renders and of the transport cache.
const PANORAMA_SPP: u32 = 256;
const RENDER_SPP: u32 = 32;
const CACHE_SPP: u32 = 256;

/// How far the recovered floor may be from the truth (relative): about three times what
/// 256 pixels at these samples miss it by (colour 0.3%, specularity 2.6%, roughness 0.4%).
const COLOR_TOLERANCE: f64 = 0.01;
const LOBE_TOLERANCE: f64 = 0.08;

/// A square view of `side` pixels from half a unit above the floor, looking down at it.
fn looking_down(side: u32) -> Option<View> {
    View::new(
        Vec3::new(0.0, 0.0, 0.5),
        -Vec3::Z,
        Vec3::Y,
        [90.0, 90.0],
        [side, side],
    )
    .ok()
}

fn floor_material(material: Material) -> [SurfaceMaterial; 1] {
    [SurfaceMaterial {
        material,
        diffuse_map: None,
    }]
}

fn diffuse_floor(rho_d: [f64; 3]) -> [SurfaceMaterial; 1] {
    let rho_d = Vec3::new(rho_d[0] as f32, rho_d[1] as f32, rho_d[2] as f32);
    floor_material(Material::Diffuse { rho_d })
}

/// Stage 1 on the floor: `rho_d <- rho_d * mean(real) / mean(rendered)` (with the measured
/// slope) until it converges. Returns the reflectance and its fit's relative error.
fn recover_diffuse(scene: &Scene, view: &View, real: &[Vec3; PIXELS]) -> ([f64; 3], f64) {
    let settings = RenderSettings {
        spp: RENDER_SPP,
        seed: 2,
        ..RenderSettings::default()
    };
    let fit_of = |rho_d: [f64; 3]| {
        let materials = diffuse_floor(rho_d);
        let mut scene = *scene;
        scene.materials = &materials;
        let mut fit = GroupFit::default();
        for (i, real) in real.iter().enumerate() {
            let (x, y) = (i as u32 % SIDE, i as u32 / SIDE);
            fit.add(
                *real,
                render_pixel(&scene, view, 0, x, y, &settings),
                Vec3::ZERO,
            );
        }
        fit
    };
    let mut rho_d = [0.5; 3];
    let mut previous = None;
    let mut last_change = f64::INFINITY;
    for step in 1.. {
        let fit = fit_of(rho_d);
        let (next, change) = diffuse::update_with_slope(rho_d, &fit, previous);
        let back = previous.map_or(f64::INFINITY, |(earlier, _)| {
            diffuse::relative_distance(next, earlier)
        });
        previous = Some((rho_d, fit.mean_rendered()));
        rho_d = next;
        if diffuse::converged(step, change, last_change, back) {
            break;
        }
        last_change = change;
    }
    (
        rho_d,
        fit_of(rho_d).relative_error().unwrap_or(f64::INFINITY),
    )
}

/// Room for one pixel's cache: its incident samples and their lobe points, at `spp`
/// samples. Lent by the caller, sized for its samples: at 256 it is 54 KiB.
struct PixelCache<'a> {
    entries: &'a mut [IncidentSample],
    points: &'a mut [LobePoint],
    spp: u32,
}

/// The normal equations of the floor's pixels for unit lobes `lobe(0)`, `lobe(1)`, ... into
/// `sums` (one each), from the transport cache traced pixel by pixel (the same fixed random
/// numbers every time), so that no more than one pixel's samples are held at once, however
/// many lobes are measured on them. Not inlined, so that its frame is given back before the
/// next stage's is taken.
#[inline(never)]
fn floor_sums(
    scene: &Scene,
    view: &View,
    real: &[Vec3; PIXELS],
    cache: PixelCache,
    lobe: impl Fn(usize) -> Material,
    sums: &mut [isotropic::LinearSums],
) {
    let spp = cache
        .spp
        .min((cache.entries.len() / INCIDENT_PER_SAMPLE) as u32);
    let settings = RenderSettings {
        spp,
        seed: 3,
        ..RenderSettings::default()
    };
    sums.fill(isotropic::LinearSums::default());
    for (i, real) in real.iter().enumerate() {
        let (x, y) = (i as u32 % SIDE, i as u32 / SIDE);
        let mut n = 0;
        for sample in 0..spp {
            // The scene has no mirror: INCIDENT_PER_SAMPLE are written at most.
            let mut out = [IncidentSample::default(); MAX_INCIDENT_PER_SAMPLE];
            let written =
                transport::trace_pixel_sample(scene, view, 0, x, y, sample, 0, &settings, &mut out);
            cache.entries[n..n + written].copy_from_slice(&out[..written]);
            n += written;
        }
        let mut m = 0;
        for e in &cache.entries[..n] {
            if let Some(p) = transport::lobe_point(e) {
                cache.points[m] = p;
                m += 1;
            }
        }
        let d = transport::diffuse_part(&cache.entries[..n], spp);
        for (k, sums) in sums.iter_mut().enumerate() {
            let b = transport::specular_part(&cache.points[..m], spp, &lobe(k));
            sums.add(d.to_array(), b.to_array(), real.to_array());
        }
    }
}

/// [`floor_sums`] of the unit isotropic lobe of roughness `alpha` at `CACHE_SPP`.
fn isotropic_sums(
    scene: &Scene,
    view: &View,
    real: &[Vec3; PIXELS],
    alpha: f64,
) -> isotropic::LinearSums {
    let mut entries = [IncidentSample::default(); INCIDENT_PER_SAMPLE * CACHE_SPP as usize];
    let mut points = [LobePoint::default(); INCIDENT_PER_SAMPLE * CACHE_SPP as usize];
    let cache = PixelCache {
        entries: &mut entries,
        points: &mut points,
        spp: CACHE_SPP,
    };
    let lobe = transport::unit_isotropic_lobe(alpha as f32);
    let mut sums = [isotropic::LinearSums::default()];
    floor_sums(scene, view, real, cache, |_| lobe, &mut sums);
    sums[0]
}

/// Every pixel of `view` rendered from `scene` at `spp` samples with `seed`.
fn render_view(scene: &Scene, view: &View, spp: u32, seed: u64) -> [Vec3; PIXELS] {
    let settings = RenderSettings {
        spp,
        seed,
        ..RenderSettings::default()
    };
    core::array::from_fn(|i| {
        render_pixel(scene, view, 0, i as u32 % SIDE, i as u32 / SIDE, &settings)
    })
}

/// Recovers the floor of `scene` (group 0) as the core's stages would, and checks it
/// against the material the "panorama" was rendered with: whether it matched, and stage
/// 3's statistic of the floor under the recovered lobe. Mixes the recovered numbers into
/// `checksum`.
#[inline(never)]
fn recover_floor(scene: &Scene, view: &View, checksum: &mut u32) -> (bool, Option<f64>) {
    // The "panorama": the floor rendered with its true material.
    let truth = Material::Ward {
        rho_d: Vec3::from(TRUE_COLOR) * (1.0 - TRUE_SPECULARITY),
        rho_s: Vec3::splat(TRUE_SPECULARITY),
        alpha: TRUE_ROUGHNESS,
    };
    let materials = floor_material(truth);
    let mut true_scene = *scene;
    true_scene.materials = &materials;
    let real = render_view(&true_scene, view, PANORAMA_SPP, 1);

    let (rho_d, diffuse_error) = recover_diffuse(scene, view, &real);
    Line::new("stage 1: diffuse ")
        .number(rho_d[0])
        .text(" ")
        .number(rho_d[1])
        .text(" ")
        .number(rho_d[2])
        .text(", relative error ")
        .number(diffuse_error)
        .print();

    // Stage 2: the best roughness by grid and golden section, reflectances in closed form.
    let sse = |alpha: f64| {
        isotropic::solve(Kind::Plastic, &isotropic_sums(scene, view, &real, alpha)).sse
    };
    let (alpha, _) = isotropic::minimise_1d(
        sse,
        isotropic::ROUGHNESS_MIN,
        isotropic::ROUGHNESS_MAX,
        isotropic::ROUGHNESS_GRID,
        isotropic::ROUGHNESS_REFINE_STEPS,
        true,
    );
    let sums = isotropic_sums(scene, view, &real, alpha);
    let lobe = isotropic::solve(Kind::Plastic, &sums);
    let without_lobe = isotropic::solve_diffuse(&sums);
    Line::new("stage 2: plastic colour ")
        .number(lobe.color[0])
        .text(" ")
        .number(lobe.color[1])
        .text(" ")
        .number(lobe.color[2])
        .text(", specularity ")
        .number(lobe.specularity)
        .text(", roughness ")
        .number(alpha)
        .text("; relative error ")
        .number(lobe.relative_error)
        .text(" against ")
        .number(without_lobe.relative_error)
        .text(" diffuse")
        .print();

    let lobe_numbers = [lobe.specularity, alpha, lobe.relative_error];
    for value in rho_d.iter().chain(&lobe.color).chain(&lobe_numbers) {
        mix(checksum, *value);
    }
    // Stage 3 under the recovered lobe: what is left is noise, not texture.
    let s = lobe.specularity as f32;
    let color = Vec3::new(
        lobe.color[0] as f32,
        lobe.color[1] as f32,
        lobe.color[2] as f32,
    );
    let recovered = floor_material(Material::Ward {
        rho_d: color * (1.0 - s),
        rho_s: Vec3::splat(s),
        alpha: alpha as f32,
    });
    let mut recovered_scene = *scene;
    recovered_scene.materials = &recovered;
    let contrast = textured::contrast(&recovered_scene, view, &real);

    let off = |value: f64, truth: f32| (value / truth as f64 - 1.0).abs();
    let color_ok = (0..3).all(|c| off(lobe.color[c], TRUE_COLOR[c]) <= COLOR_TOLERANCE);
    let lobe_ok = off(lobe.specularity, TRUE_SPECULARITY) <= LOBE_TOLERANCE
        && off(alpha, TRUE_ROUGHNESS) <= LOBE_TOLERANCE;
    let ok = color_ok && lobe_ok && lobe.relative_error < without_lobe.relative_error;
    (ok, contrast)
}

/// Mixes every bit of `value` into `checksum`, so that two machines' results can be
/// compared exactly.
fn mix(checksum: &mut u32, value: f64) {
    let bits = value.to_bits();
    *checksum = checksum.rotate_left(5) ^ (bits as u32) ^ ((bits >> 32) as u32);
}

/// Renders the checksum scene, then recovers its floor as glossy, checker and brushed;
/// whether every floor came out right.
fn run() -> bool {
    let floor = quad(
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0),
        Surface::Group(0),
    );
    let light = quad(
        Vec3::new(-0.2, -0.2, 1.0),
        Vec3::new(-0.2, 0.2, 1.0),
        Vec3::new(0.2, 0.2, 1.0),
        Vec3::new(0.2, -0.2, 1.0),
        Surface::Light(0),
    );
    let triangles = [floor[0], floor[1], light[0], light[1]];
    let materials = diffuse_floor([0.5; 3]);
    let radiance = [Vec3::splat(10.0)];
    let (n_nodes, _) = Bvh::buffer_sizes(triangles.len());
    let mut nodes = [BvhNode::default(); 4];
    let mut packed = [PackedTriangle::default(); 4];
    let mut light_table = [LightTriangle::default(); 2];
    let mut group_planes = [GroupPlane::default(); 1];
    if n_nodes > nodes.len() {
        Line::new("canary: BVH buffer too small").print();
        return false;
    }
    let textures = Textures::default();
    let scene = match Scene::build(
        &triangles,
        &materials,
        &radiance,
        textures,
        SceneStorage {
            bvh: BvhBuffers {
                nodes: &mut nodes,
                packed: &mut packed,
            },
            light_table: &mut light_table,
            group_planes: &mut group_planes,
        },
    ) {
        Ok(s) => s,
        Err(_) => {
            Line::new("canary: scene build failed").print();
            return false;
        }
    };
    let Some(view) = looking_down(4) else {
        return false;
    };
    let settings = RenderSettings {
        spp: 16,
        ..RenderSettings::default()
    };
    let mut checksum = 0u32;
    for y in 0..4 {
        for x in 0..4 {
            let c = render_pixel(&scene, &view, 0, x, y, &settings);
            checksum = checksum.rotate_left(5) ^ c.x.to_bits() ^ c.y.to_bits() ^ c.z.to_bits();
        }
    }
    Line::new("relume-core canary: checksum ")
        .hex(checksum)
        .print();

    let Some(view) = looking_down(SIDE) else {
        return false;
    };
    let mut recovered = 0u32;
    let (floor_ok, glossy_contrast) = recover_floor(&scene, &view, &mut recovered);
    let checker_ok = textured::recover_checker(&scene, &view, glossy_contrast, &mut recovered);
    let brushed_ok = brushed::recover_brushed(&scene, &view, &mut recovered);
    Line::new("relume-core canary: recovery checksum ")
        .hex(recovered)
        .print();
    if !floor_ok {
        Line::new("relume-core canary: the glossy floor's recovered material is off its truth")
            .print();
    }
    if !checker_ok {
        Line::new("relume-core canary: the checker floor is misclassified or its map is off")
            .print();
    }
    if !brushed_ok {
        Line::new("relume-core canary: the brushed floor's recovered lobe is off its truth")
            .print();
    }
    if floor_ok && checker_ok && brushed_ok {
        Line::new("relume-core canary: the floors' materials recovered").print();
    }
    floor_ok && checker_ok && brushed_ok
}
