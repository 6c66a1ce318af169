//! A `#![no_std]` program, all storage on the stack, that proves the core's renderer *and*
//! its solver run without std or an allocator, as on a small target: it renders a small
//! scene (a checksum of a few pixels), then recovers a glossy floor's material from a
//! "panorama" rendered with known materials, by stage 1's diffuse iteration and stage 2's
//! closed-form isotropic fit over the transport cache, streamed pixel by pixel. It prints
//! through libc `write` and exits with 1 when the recovery misses the known material.
#![no_std]
#![no_main]

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

extern "C" {
    fn write(fd: i32, buf: *const u8, count: usize) -> isize;
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    loop {}
}

#[cfg(debug_assertions)]
#[unsafe(no_mangle)]
pub extern "C" fn rust_eh_personality() {}

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
        let scaled = (value * 1e4 + 0.5) as u64;
        let mut digits = [0u8; 20];
        let mut n = 0;
        let mut rest = scaled;
        while n < 5 || rest > 0 {
            digits[n] = b'0' + (rest % 10) as u8;
            rest /= 10;
            n += 1;
        }
        for i in (0..n).rev() {
            if i == 3 {
                self.text(".");
            }
            self.raw(&[digits[i]]);
        }
        self
    }

    fn print(&mut self) {
        self.text("\n");
        // SAFETY: `bytes[..len]` is a valid buffer for its length; fd 1 is stdout.
        unsafe {
            write(1, self.bytes.as_ptr(), self.len);
        }
    }
}

fn quad(a: Vec3, b: Vec3, c: Vec3, d: Vec3, surface: Surface) -> [Triangle; 2] {
    let uv = [Vec2::ZERO; 3];
    [
        Triangle {
            v: [a, b, c],
            uv,
            surface,
        },
        Triangle {
            v: [a, c, d],
            uv,
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

/// The normal equations of the floor's pixels for a unit lobe of roughness `alpha`, from
/// the transport cache traced pixel by pixel (the same fixed random numbers every time), so
/// that no more than one pixel's samples are held at once.
fn floor_sums(
    scene: &Scene,
    view: &View,
    real: &[Vec3; PIXELS],
    alpha: f64,
) -> isotropic::LinearSums {
    let settings = RenderSettings {
        spp: CACHE_SPP,
        seed: 3,
        ..RenderSettings::default()
    };
    let lobe = transport::unit_isotropic_lobe(alpha as f32);
    let mut entries = [IncidentSample::default(); INCIDENT_PER_SAMPLE * CACHE_SPP as usize];
    let mut points = [LobePoint::default(); INCIDENT_PER_SAMPLE * CACHE_SPP as usize];
    let mut sums = isotropic::LinearSums::default();
    for (i, real) in real.iter().enumerate() {
        let (x, y) = (i as u32 % SIDE, i as u32 / SIDE);
        let mut n = 0;
        for sample in 0..CACHE_SPP {
            // The scene has no mirror: INCIDENT_PER_SAMPLE are written at most.
            let mut out = [IncidentSample::default(); MAX_INCIDENT_PER_SAMPLE];
            let written =
                transport::trace_pixel_sample(scene, view, 0, x, y, sample, 0, &settings, &mut out);
            entries[n..n + written].copy_from_slice(&out[..written]);
            n += written;
        }
        let mut m = 0;
        for e in &entries[..n] {
            if let Some(p) = transport::lobe_point(e) {
                points[m] = p;
                m += 1;
            }
        }
        let d = transport::diffuse_part(&entries[..n], CACHE_SPP);
        let b = transport::specular_part(&points[..m], CACHE_SPP, &lobe);
        sums.add(d.to_array(), b.to_array(), real.to_array());
    }
    sums
}

/// Recovers the floor of `scene` (group 0) as the core's stages would, and checks it
/// against the material the "panorama" was rendered with. Returns whether it matched.
fn recover_floor(scene: &Scene) -> bool {
    let Some(view) = looking_down(SIDE) else {
        return false;
    };
    // The "panorama": the floor rendered with its true material.
    let truth = Material::Ward {
        rho_d: Vec3::from(TRUE_COLOR) * (1.0 - TRUE_SPECULARITY),
        rho_s: Vec3::splat(TRUE_SPECULARITY),
        alpha: TRUE_ROUGHNESS,
    };
    let materials = floor_material(truth);
    let mut true_scene = *scene;
    true_scene.materials = &materials;
    let settings = RenderSettings {
        spp: PANORAMA_SPP,
        seed: 1,
        ..RenderSettings::default()
    };
    let real: [Vec3; PIXELS] = core::array::from_fn(|i| {
        render_pixel(
            &true_scene,
            &view,
            0,
            i as u32 % SIDE,
            i as u32 / SIDE,
            &settings,
        )
    });

    let (rho_d, diffuse_error) = recover_diffuse(scene, &view, &real);
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
    let sse =
        |alpha: f64| isotropic::solve(Kind::Plastic, &floor_sums(scene, &view, &real, alpha)).sse;
    let (alpha, _) = isotropic::minimise_1d(
        sse,
        isotropic::ROUGHNESS_MIN,
        isotropic::ROUGHNESS_MAX,
        isotropic::ROUGHNESS_GRID,
        isotropic::ROUGHNESS_REFINE_STEPS,
        true,
    );
    let sums = floor_sums(scene, &view, &real, alpha);
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

    let off = |value: f64, truth: f32| (value / truth as f64 - 1.0).abs();
    let color_ok = (0..3).all(|c| off(lobe.color[c], TRUE_COLOR[c]) <= COLOR_TOLERANCE);
    let lobe_ok = off(lobe.specularity, TRUE_SPECULARITY) <= LOBE_TOLERANCE
        && off(alpha, TRUE_ROUGHNESS) <= LOBE_TOLERANCE;
    color_ok && lobe_ok && lobe.relative_error < without_lobe.relative_error
}

#[unsafe(no_mangle)]
pub extern "C" fn main(_argc: i32, _argv: *const *const u8) -> i32 {
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
        return 1;
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
            return 1;
        }
    };
    let Some(view) = looking_down(4) else {
        return 1;
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
    let mut hex = [0u8; 8];
    for (i, h) in hex.iter_mut().enumerate() {
        *h = b"0123456789abcdef"[((checksum >> (28 - 4 * i)) & 0xf) as usize];
    }
    Line::new("relume-core canary: checksum ").raw(&hex).print();

    if recover_floor(&scene) {
        Line::new("relume-core canary: the floor's material recovered").print();
        0
    } else {
        Line::new("relume-core canary: the floor's recovered material is off its truth").print();
        1
    }
}
