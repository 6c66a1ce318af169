#!/usr/bin/env python3
"""Glossy lobes in RADIANCE against relume: the measurements of
docs/renderer-vs-radiance.md, "Glossy lobes and RADIANCE's specular samples".

1. A small scene (a black glossy floor, a white wall, a square lamp): one block of pixels
   whose lobe sees the wall, traced by RADIANCE with the lamp a `light` at -ss 1 (sixteen
   times over), -ss 16 and -ss 64, with the lamp a `glow` that is no source (pure path
   tracing, -ss 64), and rendered by relume.
2. glossy's lobed groups: each group's pixels in the view that shows most of it, traced at
   the references' options with -ss 16 once and -ss 1 sixteen times (the same number of
   specular rays), sharing one irradiance cache so that only the specular sampling
   differs; against the reference's pixels and relume's render of the truth.

Needs RADIANCE: `pip install pyradiance==1.3.1` (its rtrace, oconv, pvalue) and numpy and
OpenEXR from PyPI. Takes some ten minutes on two cores.
Usage: radiance_specular_samples.py RELUME_BINARY BENCH_DIR OUT_DIR
"""
import os, subprocess, sys, tomllib

import numpy as np
import OpenEXR
import pyradiance

BIN = os.path.join(os.path.dirname(pyradiance.__file__), "bin")
ENV = dict(os.environ, PATH=BIN + os.pathsep + os.environ["PATH"],
           RAYPATH=os.path.join(os.path.dirname(pyradiance.__file__), "lib"))
# The references' rpict options (shared/bench/glossy/README.md), less the picture's.
REFERENCE = ("-dc 1 -dt 0 -dr 3 -dp 4096 -st 0 -lr -16 -lw 1e-5 -bv+ -av 0 0 0 -aw 0 "
             "-ab 8 -aa 0.12 -ad 800 -as 400 -ar 160 -ds 0.15 -dj 0.9").split()
VIEWS = {"px": ((1, 0, 0), (0, 0, 1)), "nx": ((-1, 0, 0), (0, 0, 1)),
         "py": ((0, 1, 0), (0, 0, 1)), "ny": ((0, -1, 0), (0, 0, 1)),
         "pz": ((0, 0, 1), (0, -1, 0)), "nz": ((0, 0, -1), (0, 1, 0))}


def run(args, cwd, stdin=None):
    return subprocess.run(args, cwd=cwd, env=ENV, input=stdin, capture_output=True,
                          check=True).stdout


def rays_of(position, direction, up, fov_deg, size, rows, cols, k):
    """`k x k` rays per pixel of rows x cols, by scene-format.md's pixel-to-ray mapping."""
    d = np.array(direction, float) / np.linalg.norm(direction)
    r = np.cross(d, up); r /= np.linalg.norm(r)
    u = np.cross(r, d)
    t = 2 * np.tan(np.radians(fov_deg) / 2)
    out = []
    for j in rows:
        for i in cols:
            for sj in range(k):
                for si in range(k):
                    x = (i + (si + 0.5) / k) / size - 0.5
                    y = 0.5 - (j + (sj + 0.5) / k) / size
                    v = d + x * t * r + y * t * u
                    out.append((*position, *(v / np.linalg.norm(v))))
    return np.array(out)


def rtrace(options, octree, rays, cwd, repeats=1):
    """The mean RGB per ray of `rays`, traced `repeats` times (fresh random numbers)."""
    text = "\n".join(" ".join(f"{x:.9f}" for x in ray) for ray in rays) + "\n"
    out = run(["rtrace", "-h", "-ov", "-u+", *options, octree], cwd, (text * repeats).encode())
    values = np.array([[float(x) for x in line.split()] for line in out.decode().splitlines()])
    return values.reshape(repeats, len(rays), 3).mean(axis=0)


def exr(path):
    return OpenEXR.File(path).channels()["RGB"].pixels.astype(np.float64)


def small_scene(relume, out):
    """Part 1: the pixel block's mean by each estimator."""
    os.makedirs(out, exist_ok=True)
    lamp = "-0.5 -0.5 2  -0.5 0.5 2  0.5 0.5 2  0.5 -0.5 2"
    floor = "-10 -10 0  10 -10 0  10 10 0  -10 10 0"
    wall = "-3 1 0  3 1 0  3 1 3  -3 1 3"
    for name, lamp_material in (("light", "void light lamp\n0\n0\n3 50 50 50\n"),
                                ("glow", "void glow lamp\n0\n0\n4 50 50 50 0\n")):
        with open(os.path.join(out, f"{name}.rad"), "w") as f:
            f.write(lamp_material + f"lamp polygon lampq\n0\n0\n12 {lamp}\n"
                    "void plastic shiny\n0\n0\n5 0 0 0 0.08 0.15\n"
                    f"shiny polygon floor\n0\n0\n12 {floor}\n"
                    "void plastic white\n0\n0\n5 0.8 0.8 0.8 0 0\n"
                    f"white polygon wall\n0\n0\n12 {wall}\n")
        with open(os.path.join(out, f"{name}.oct"), "wb") as f:
            f.write(run(["oconv", "-f", f"{name}.rad"], out))
    with open(os.path.join(out, "scene.obj"), "w") as f:
        for k, (obj, corners) in enumerate((("lampq", lamp), ("floor", floor), ("wall", wall))):
            c = corners.split()
            f.write(f"o {obj}\n" + "".join(f"v {' '.join(c[3 * i:3 * i + 3])}\n" for i in range(4))
                    + "f " + " ".join(str(4 * k + i) for i in range(1, 5)) + "\n")
    view = dict(position=[0.0, -2.5, 1.2], direction=[0.0, 1.0, -0.45], fov=50.0, size=64)
    with open(os.path.join(out, "scene.toml"), "w") as f:
        f.write('format = 1\nname = "lobe-sees-a-wall"\ngeometry = ["scene.obj"]\nhide = []\n'
                f'[[view]]\nname = "v"\nposition = {view["position"]}\n'
                f'direction = {view["direction"]}\nup = [0.0, 0.0, 1.0]\n'
                f'fov_deg = [50.0, 50.0]\nsize = [64, 64]\n'
                '[[light]]\nobject = "lampq"\nradiance = [50.0, 50.0, 50.0]\n'
                '[[group]]\nname = "floor"\nkind = "plastic"\nobjects = ["floor"]\n'
                '[[group]]\nname = "wall"\nkind = "plastic"\nobjects = ["wall"]\n')
    with open(os.path.join(out, "materials.toml"), "w") as f:
        f.write('format = 1\n[[material]]\ngroup = "floor"\nmodel = "isotropic"\n'
                'color = [0.0, 0.0, 0.0]\nspecularity = 0.08\nroughness = 0.15\n'
                '[[material]]\ngroup = "wall"\nmodel = "diffuse"\ncolor = [0.8, 0.8, 0.8]\n'
                'specularity = 0.0\nroughness = 0.0\n')
    run([relume, "render", "scene.toml", "--materials", "materials.toml", "--out", "relume",
         "--spp", "8192", "--seed", "3"], out)
    rows, cols = range(48, 56), range(24, 40)
    ours = exr(os.path.join(out, "relume", "v.exr"))[48:56, 24:40, 0].mean()
    rays = rays_of(view["position"], view["direction"], (0, 0, 1), view["fov"], 64, rows, cols, 3)
    paths = "-ab 2 -aa 0 -ad 256 -as 0 -ds 0.02 -dj 0.9 -st 0 -dc 1 -dt 0 -lr -16 -lw 1e-5".split()
    print("1. a black glossy floor whose lobe sees a lit wall: mean red radiance of pixels "
          "48-55 x 24-39")
    print(f"   relume, 8192 spp                    {ours:.4f}")
    for label, octree, ss, repeats in (("light, -ss 1 (x16)", "light.oct", 1, 16),
                                       ("light, -ss 16", "light.oct", 16, 1),
                                       ("light, -ss 64", "light.oct", 64, 1),
                                       ("glow (no source), -ss 64 (x4)", "glow.oct", 64, 4)):
        value = rtrace([*paths, "-ss", str(ss)], octree, rays, out, repeats)[:, 0].mean()
        print(f"   RADIANCE, lamp a {label:28s} {value:.4f} ({value / ours - 1:+.2%} against relume)")


def glossy(relume, bench, out):
    """Part 2: the lobed groups' pixels, -ss 16 against -ss 1, the reference and relume."""
    scene = os.path.join(bench, "glossy")
    os.makedirs(out, exist_ok=True)
    radiance_dir = os.path.join(scene, "radiance")
    with open(os.path.join(out, "glossy.oct"), "wb") as f:
        f.write(run(["oconv", "-f", "materials.rad", "lights.rad", "geometry.rad"], radiance_dir))
    small = os.path.join(scene, "scene-small.toml")
    truth = os.path.join(scene, "truth.toml")
    run([relume, "render", small, "--materials", truth, "--out", "truth", "--spp", "4096",
         "--seed", "5"], out)
    materials = tomllib.load(open(truth, "rb"))["material"]
    lobed = [m["group"] for m in materials if m["model"] == "isotropic"]

    def write(path, rows):
        with open(path, "w") as f:
            f.write("format = 1\n")
            for m in rows:
                f.write("[[material]]\n" + "".join(
                    f'{k} = "{v}"\n' if isinstance(v, str) else f"{k} = {v!r}\n"
                    for k, v in m.items()))

    # The lobes taken out (colour times 1 - s, specularity 0): what is left is the rest.
    write(os.path.join(out, "nospec.toml"), [
        dict(m, model="diffuse", color=[c * (1 - m["specularity"]) for c in m["color"]],
             specularity=0.0, roughness=0.0) for m in materials])
    run([relume, "render", small, "--materials", "nospec.toml", "--out", "nospec", "--spp",
         "4096", "--seed", "6"], out)
    print("2. glossy's lobed groups: pixels inside the group (a 4-neighbourhood), in the view "
          "that shows most of it")
    print("   group             view pixels lobe share  ss16/ref  ss1/ss16  ours/ss16  ours/ss1")
    for group in ("sphere_blue", "metal_gold", "metal_steel", "sphere_red", "box_yellow"):
        # The group alone, white and diffuse, the rest black: its pixels (the lamp excepted).
        write(os.path.join(out, "only.toml"), [
            dict(m, model="diffuse", specularity=0.0, roughness=0.0,
                 color=[1.0] * 3 if m["group"] == group else [0.0] * 3) for m in materials])
        run([relume, "render", small, "--materials", "only.toml", "--out", "only", "--spp",
             "16", "--seed", "1"], out)

        def inner(view):
            m = exr(os.path.join(out, "only", f"{view}.exr")).sum(axis=2)
            inside = (m > 0) & (m < 50)
            mask = inside.copy()
            mask[1:-1, 1:-1] &= inside[:-2, 1:-1] & inside[2:, 1:-1] & inside[1:-1, :-2] & inside[1:-1, 2:]
            mask[0, :] = mask[-1, :] = mask[:, 0] = mask[:, -1] = False
            return mask

        view = max(VIEWS, key=lambda v: inner(v).sum())
        mask = inner(view)
        ys, xs = np.nonzero(mask)
        rows, cols = range(ys.min(), ys.max() + 1), range(xs.min(), xs.max() + 1)
        k = 8
        rays = rays_of((2.2, 1.6, 1.25), VIEWS[view][0], VIEWS[view][1], 90.0, 64, rows, cols, k)
        amb = ["-af", "glossy.amb"]
        shape = (len(rows), len(cols), k, k, 3)
        ss16 = rtrace([*REFERENCE, *amb, "-ss", "16"], "glossy.oct", rays, out).reshape(shape)
        ss1 = rtrace([*REFERENCE, *amb, "-ss", "1"], "glossy.oct", rays, out, 16).reshape(shape)
        block = (slice(rows.start, rows.stop), slice(cols.start, cols.stop))
        pixel = lambda a: a.mean(axis=(2, 3)).sum(axis=2)
        ss16, ss1 = pixel(ss16), pixel(ss1)
        reference = exr(os.path.join(scene, "views-small", f"{view}.exr")).sum(axis=2)[block]
        ours = exr(os.path.join(out, "truth", f"{view}.exr")).sum(axis=2)[block]
        rest = exr(os.path.join(out, "nospec", f"{view}.exr")).sum(axis=2)[block]
        m = mask[block]
        s = lambda a: a[m].sum()
        print(f"   {group:17s} {view:4s} {m.sum():6d} {s(ours - rest) / s(ours):10.2f}"
              f" {s(ss16) / s(reference) - 1:+9.2%} {s(ss1) / s(ss16) - 1:+9.2%}"
              f" {s(ours) / s(ss16) - 1:+10.2%} {s(ours) / s(ss1) - 1:+9.2%}")


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    relume, bench, out = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2]), sys.argv[3]
    small_scene(relume, os.path.join(out, "small"))
    glossy(relume, bench, os.path.join(out, "glossy"))
