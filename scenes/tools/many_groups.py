#!/usr/bin/env python3
"""Cornell's room with N boxes on its floor, each box its own group, and L lights (1 or a
square number): how recovery's cost grows with a scene's groups (docs/recovery.md,
"Figures", 2026-12-05). Every 8th box is a weak glossy plastic, every 16th a metal, the
rest diffuse of random colours (seeded by N); six 64x64 cube faces look out from the room's
middle. Writes geometry.obj, scene.toml and truth.toml into DIR; render the panorama with
`relume render DIR/scene.toml --materials DIR/truth.toml --out DIR/views --spp 256`.

Usage: many_groups.py N L DIR
"""
import math, os, sys, random

# Cornell's room, its OBJ writer and its boxes, from the bundled scene's generator.
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "cornell"))
from make_geometry import ObjWriter, room, box, H  # noqa: E402

def main(n, n_lights, out_dir):
    os.makedirs(out_dir, exist_ok=True)
    rnd = random.Random(1234 + n)
    w = ObjWriter(f"# synthetic: {n} boxes, {n_lights} lights")
    obj = w.obj
    room(w)
    lz = H - 0.01
    lights = []
    if n_lights == 1:
        obj("light", [[(1.1, 1.1, lz), (1.1, 1.9, lz), (1.9, 1.9, lz), (1.9, 1.1, lz)]])
        lights.append("light")
    else:
        k = int(round(math.sqrt(n_lights)))
        assert k * k == n_lights
        side = 0.8 / k  # same total area as cornell's light
        pitch = 2.0 / k
        for i in range(k):
            for j in range(k):
                cx = 0.5 + pitch * (i + 0.5); cy = 0.5 + pitch * (j + 0.5)
                x0, x1, y0, y1 = cx - side / 2, cx + side / 2, cy - side / 2, cy + side / 2
                name = f"light_{i}_{j}"
                obj(name, [[(x0, y0, lz), (x0, y1, lz), (x1, y1, lz), (x1, y0, lz)]])
                lights.append(name)
    cols = math.ceil(math.sqrt(n)); rows = math.ceil(n / cols)
    lo, hi = 0.2, 2.8
    px, py = (hi - lo) / cols, (hi - lo) / rows
    mats = []
    for b in range(n):
        i, j = b % cols, b // cols
        cx = lo + px * (i + 0.5); cy = lo + py * (j + 0.5)
        hw, hd = 0.35 * px, 0.35 * py
        h = 0.1 + 0.3 * rnd.random()
        obj(f"box_{b}", box(cx - hw, cy - hd, cx + hw, cy + hd, h))
        col = [round(0.1 + 0.7 * rnd.random(), 3) for _ in range(3)]
        if b % 16 == 5:
            mats.append((f"box_{b}", "metal", "isotropic", col, 0.9, 0.15))
        elif b % 8 == 3:
            mats.append((f"box_{b}", "plastic", "isotropic", col, 0.06, 0.08))
        else:
            mats.append((f"box_{b}", "plastic", "diffuse", col, 0.0, 0.0))
    open(os.path.join(out_dir, "geometry.obj"), "w").write(w.text())
    pos = [1.5, 1.5, 1.3]
    views = [("px", [1, 0, 0], [0, 0, 1]), ("nx", [-1, 0, 0], [0, 0, 1]),
             ("py", [0, 1, 0], [0, 0, 1]), ("ny", [0, -1, 0], [0, 0, 1]),
             ("pz", [0, 0, 1], [0, -1, 0]), ("nz", [0, 0, -1], [0, 1, 0])]
    s = ["format = 1", f'name = "boxes{n}_l{n_lights}"', 'geometry = ["geometry.obj"]', "hide = []", ""]
    for name, d, u in views:
        s += ["[[view]]", f'name = "{name}"', f'image = "views/{name}.exr"',
              f"position = {[float(x) for x in pos]}", f"direction = {[float(x) for x in d]}",
              f"up = {[float(x) for x in u]}", "fov_deg = [90.0, 90.0]", "size = [64, 64]",
              "exposure = 1.0", ""]
    for l in lights:
        s += ["[[light]]", f'object = "{l}"', "radiance = [30.0, 28.0, 24.0]", ""]
    room_groups = [("floor", ["floor"]), ("ceiling", ["ceiling"]), ("wall_red", ["wall_left"]),
            ("wall_green", ["wall_right"]), ("walls_white", ["wall_back", "wall_front"])]
    for g, objs in room_groups:
        s += ["[[group]]", f'name = "{g}"', 'kind = "plastic"', "objects = [" + ", ".join(f'"{o}"' for o in objs) + "]", ""]
    for g, kind, *_ in mats:
        s += ["[[group]]", f'name = "{g}"', f'kind = "{kind}"', f'objects = ["{g}"]', ""]
    open(os.path.join(out_dir, "scene.toml"), "w").write("\n".join(s))
    t = ["format = 1", ""]
    room_cols = {"floor": [0.5, 0.42, 0.32], "ceiling": [0.7, 0.7, 0.68], "wall_red": [0.63, 0.12, 0.1],
                 "wall_green": [0.14, 0.5, 0.16], "walls_white": [0.66, 0.64, 0.6]}
    for g, c in room_cols.items():
        t += ["[[material]]", f'group = "{g}"', 'model = "diffuse"', f"color = {c}", "specularity = 0.0", "roughness = 0.0", ""]
    for g, kind, model, c, sp, r in mats:
        t += ["[[material]]", f'group = "{g}"', f'model = "{model}"', f"color = {c}", f"specularity = {sp}", f"roughness = {r}", ""]
    open(os.path.join(out_dir, "truth.toml"), "w").write("\n".join(t))

if __name__ == "__main__":
    main(int(sys.argv[1]), int(sys.argv[2]), sys.argv[3])
