//! A `#![no_std]` program that builds a small scene with the core (all storage on the
//! stack), renders a few pixels and prints a checksum through libc `write`.
#![no_std]
#![no_main]

use relume_core::bvh::{Bvh, BvhBuffers, BvhNode, PackedTriangle};
use relume_core::geometry::{Surface, Triangle, View};
use relume_core::material::{Material, SurfaceMaterial, Textures};
use relume_core::math::{Vec2, Vec3};
use relume_core::render::{render_pixel, RenderSettings};
use relume_core::scene::{LightTriangle, Scene, SceneStorage};

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

fn print(bytes: &[u8]) {
    // SAFETY: `bytes` is a valid buffer for its length; fd 1 is stdout.
    unsafe {
        write(1, bytes.as_ptr(), bytes.len());
    }
}

fn quad(a: Vec3, b: Vec3, c: Vec3, d: Vec3, surface: Surface) -> [Triangle; 2] {
    let uv = [Vec2::ZERO; 3];
    [Triangle { v: [a, b, c], uv, surface }, Triangle { v: [a, c, d], uv, surface }]
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
    let materials = [SurfaceMaterial {
        material: Material::Diffuse { rho_d: Vec3::splat(0.5) },
        diffuse_map: None,
    }];
    let radiance = [Vec3::splat(10.0)];
    let (n_nodes, _) = Bvh::buffer_sizes(triangles.len());
    let mut nodes = [BvhNode::default(); 8];
    let mut packed = [PackedTriangle::default(); 4];
    let mut light_table = [LightTriangle::default(); 2];
    if n_nodes > nodes.len() {
        print(b"canary: BVH buffer too small\n");
        return 1;
    }
    let textures = Textures::default();
    let scene = match Scene::build(
        &triangles,
        &materials,
        &radiance,
        textures,
        SceneStorage {
            bvh: BvhBuffers { nodes: &mut nodes, packed: &mut packed },
            light_table: &mut light_table,
        },
    ) {
        Ok(s) => s,
        Err(_) => {
            print(b"canary: scene build failed\n");
            return 1;
        }
    };
    let view = match View::new(Vec3::new(0.0, 0.0, 0.5), -Vec3::Z, Vec3::Y, [90.0, 90.0], [4, 4]) {
        Ok(v) => v,
        Err(_) => return 1,
    };
    let settings = RenderSettings { spp: 16, ..RenderSettings::default() };
    let mut checksum = 0u32;
    for y in 0..4 {
        for x in 0..4 {
            let c = render_pixel(&scene, &view, 0, x, y, &settings);
            checksum = checksum.rotate_left(5) ^ c.x.to_bits() ^ c.y.to_bits() ^ c.z.to_bits();
        }
    }
    let mut line = *b"relume-core canary: checksum 00000000\n";
    let hex = b"0123456789abcdef";
    for i in 0..8 {
        line[29 + i] = hex[((checksum >> (28 - 4 * i)) & 0xf) as usize];
    }
    print(&line);
    0
}
