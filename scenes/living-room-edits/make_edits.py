#!/usr/bin/env python3
"""Renders four edits of the reference living room with RADIANCE and its TRUE materials.

The reference scenes promise `living-room/edits/` (relit, new-light, novel-view, remove-add),
but the folder is not in ../shared, so this script makes our own, the same way the references
were made: RADIANCE 6.0a (the binaries of the PyPI wheel pyradiance 1.3.1), the references'
rpict options (MAIN, or QUICK: MAIN with a coarser irradiance cache), every view rendered at 3x3 its size and box-filtered (numpy mean of
`pvalue -o -df` floats), the six faces of a scene sharing one irradiance cache.

Each edit is a folder holding `scene.toml` (format 1; its view images are these renders) and,
where the edit adds an object, `materials.toml` with the added group's material. Run:

    python3 -m venv env && env/bin/pip install pyradiance==1.3.1 numpy openexr
    env/bin/python make_edits.py [--reference ../../../shared/bench/living-room] [--only NAMES]
                                 [--quality quick|main]

With `--quality quick` (the default) it takes a few minutes per edit on one core; with
`--quality main` (the references' own options) hours. `relume bench edits` reads the
result.
"""

import argparse
import os
import shutil
import subprocess
import sys
import tempfile

import numpy as np
import OpenEXR

HERE = os.path.dirname(os.path.abspath(__file__))

# The references' MAIN options (shared/bench/README.md) without the picture size.
MAIN = ("-ps 1 -pt 0 -pa 0 -dc 1 -dt 0 -dr 3 -dp 4096 -st 0 -lr -16 -lw 1e-5 -bv+ -av 0 0 0 "
        "-aw 0 -ab 8 -aa 0.12 -ad 800 -as 400 -ar 160 -ds 0.15 -dj 0.9 -ss 4 -pj 0.9").split()
# The same with a coarser irradiance cache (8 bounces kept). MAIN's cache on the living
# room took over 15 minutes for one face here (the statue's 2880 facets at -aa 0.12 and
# -ad 800), QUICK 22 s. The `original` edit measures what QUICK costs in accuracy: it is
# the reference panorama itself, rendered again with QUICK.
QUICK = ("-ps 1 -pt 0 -pa 0 -dc 1 -dt 0 -dr 3 -dp 4096 -st 0 -lr -16 -lw 1e-5 -bv+ -av 0 0 0 "
         "-aw 0 -ab 8 -aa 0.2 -ad 256 -as 128 -ar 64 -ds 0.15 -dj 0.9 -ss 1 -pj 0.9").split()
QUALITY = {"main": MAIN, "quick": QUICK}
SUPERSAMPLE = 3
# A face that takes longer than this is left out of its edit. Now and then rpict spends
# tens of minutes on one scanline of the living room without writing an ambient value or a
# pixel (seen on faces that the same options rendered in seconds in another run); an edit
# with five faces is still an edit.
FACE_TIMEOUT_S = 300

CUBE = [  # name, direction, up: the faces of the references' panoramas
    ("px", (1, 0, 0), (0, 0, 1)),
    ("nx", (-1, 0, 0), (0, 0, 1)),
    ("py", (0, 1, 0), (0, 0, 1)),
    ("ny", (0, -1, 0), (0, 0, 1)),
    ("pz", (0, 0, 1), (0, -1, 0)),
    ("nz", (0, 0, -1), (0, -1, 0)),
]
ORIGINAL_POSITION = (2.6, 2.2, 1.3)
CEILING_LAMP = (50.0, 48.0, 44.0)

# The added object of remove-add: a box on the floor where the original panorama's nz face
# sees it, in a material no group of the room has.
ADDED_BOX = {"name": "added_box", "lo": (3.0, 2.6, 0.0), "hi": (3.4, 3.0, 0.4)}
ADDED_MATERIAL = {"color": (0.2, 0.45, 0.6), "specularity": 0.05, "roughness": 0.08}

EDITS = {
    # No edit: the reference panorama again, to measure the render options against MAIN.
    "original": {},
    # The ceiling lamp dimmer and bluer. With one light on, light transport is linear in
    # its radiance, so these views are `original`'s scaled channel by channel: what RADIANCE
    # would render but for its noise, without another hour of irradiance cache.
    "relit": {"lights": {"ceiling_lamp": (30.0, 34.0, 42.0)}, "scale_of": "original"},
    # The desk lamp switched on beside the ceiling lamp.
    "new-light": {"lights": {"desk_lamp_bulb": (300.0, 270.0, 210.0)}},
    # A new viewpoint: a panorama from near the mirror, higher than the original.
    "novel-view": {"position": (1.2, 1.6, 1.7)},
    # The statue taken away, a box put in.
    "remove-add": {"hide": ["statue"], "add_box": True},
}


def run(cmd, **kw):
    return subprocess.run(cmd, check=True, **kw)


class FaceTimeout(Exception):
    pass


def box_faces(lo, hi):
    """The six outward quads of an axis-aligned box, counter-clockwise seen from outside."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    return [
        [(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)],  # -z
        [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)],  # +z
        [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)],  # -y
        [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)],  # +y
        [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)],  # -x
        [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)],  # +x
    ]


def write_box_obj(path, box):
    with open(path, "w") as f:
        f.write(f"# {box['name']}: the object remove-add puts in (made by make_edits.py)\n")
        f.write(f"o {box['name']}\n")
        faces = box_faces(box["lo"], box["hi"])
        for quad in faces:
            for v in quad:
                f.write("v %.6f %.6f %.6f\n" % v)
        for i in range(len(faces)):
            f.write("f %d %d %d %d\n" % tuple(4 * i + k + 1 for k in range(4)))


def box_rad(box, material):
    out = [f"void plastic m_{box['name']}\n0\n0\n5 %g %g %g %g %g\n" % (
        *material["color"], material["specularity"], material["roughness"])]
    for i, quad in enumerate(box_faces(box["lo"], box["hi"])):
        coords = " ".join("%.6f %.6f %.6f" % v for v in quad)
        out.append(f"m_{box['name']} polygon {box['name']}.{i}\n0\n0\n12 {coords}\n")
    return "\n".join(out)


def block_object(block):
    """The OBJ object of a geometry.rad block headed `<modifier> polygon <object>.<face>`."""
    header = block.strip().split("\n", 1)[0].split()
    return header[2].rsplit(".", 1)[0] if len(header) == 3 else None


def edited_geometry(text, hide):
    """geometry.rad without the polygons of hidden objects."""
    return "\n\n".join(b for b in text.split("\n\n") if block_object(b) not in hide)


def edited_lights(text, radiances):
    """lights.rad with new radiances for the named light objects."""
    lines = text.splitlines()
    for i, line in enumerate(lines):
        parts = line.split()
        if len(parts) == 3 and parts[0] == "void" and parts[1] == "light":
            name = parts[2][2:]  # l_<object>
            if name in radiances:
                lines[i + 3] = "3 %g %g %g" % radiances[name]
    return "\n".join(lines) + "\n"


def light_radiances(text):
    found = {}
    lines = text.splitlines()
    for i, line in enumerate(lines):
        parts = line.split()
        if len(parts) == 3 and parts[0] == "void" and parts[1] == "light":
            found[parts[2][2:]] = tuple(float(x) for x in lines[i + 3].split()[1:4])
    return found


def render_face(bindir, options, octree, ambient, position, direction, up, size, workdir):
    res = size * SUPERSAMPLE
    view = ["-vtv", "-vp", *map(str, position), "-vd", *map(str, direction),
            "-vu", *map(str, up), "-vh", "90", "-vv", "90"]
    pic = os.path.join(workdir, "face.hdr")
    with open(pic, "wb") as f:
        try:
            run([os.path.join(bindir, "rpict"), *options, *view, "-x", str(res), "-y", str(res),
                 "-t", "30", "-af", ambient, octree], stdout=f, cwd=workdir,
                timeout=FACE_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            raise FaceTimeout()
    raw = run([os.path.join(bindir, "pvalue"), "-o", "-df", "-h", "-H", pic],
              stdout=subprocess.PIPE, cwd=workdir).stdout
    rgb = np.frombuffer(raw, dtype=np.float32).reshape(res, res, 3)
    return rgb.astype(np.float64).reshape(size, SUPERSAMPLE, size, SUPERSAMPLE, 3).mean(axis=(1, 3)).astype(np.float32)


def write_exr(path, rgb):
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {"RGB": np.ascontiguousarray(rgb)}).write(path)


def scene_toml(name, edit, reference, position, size, lights, quality, faces):
    geometry = os.path.relpath(os.path.join(reference, "geometry.obj"), os.path.join(HERE, name))
    files = [geometry] + (["added_box.obj"] if edit.get("add_box") else [])
    out = [f"# {name}: an edit of the reference living room, made by ../make_edits.py.",
           (f"# The view images are ../{edit['scale_of']}'s scaled channel by channel by the light's change."
            if "scale_of" in edit else
            f"# The view images are RADIANCE renders with the TRUE materials ({quality} options)."),
           "format = 1", f'name = "living-room-{name}"',
           "geometry = [%s]" % ", ".join(f'"{g}"' for g in files),
           "hide = [%s]" % ", ".join(f'"{h}"' for h in edit.get("hide", [])), ""]
    left_out = [f for f, _, _ in CUBE if f not in faces]
    if left_out:
        out += ["# Left out: RADIANCE did not finish %s within %d s (make_edits.py)."
                % (", ".join(left_out), FACE_TIMEOUT_S), ""]
    for face, direction, up in CUBE:
        if face not in faces:
            continue
        out += ["[[view]]", f'name = "{face}"', f'image = "views/{face}.exr"',
                "position = [%s]" % ", ".join("%g" % c for c in position),
                "direction = [%s]" % ", ".join("%.1f" % c for c in direction),
                "up = [%s]" % ", ".join("%.1f" % c for c in up),
                "fov_deg = [90.0, 90.0]", f"size = [{size}, {size}]", "exposure = 1.0", ""]
    for light, rad in lights.items():
        out += ["[[light]]", f'object = "{light}"',
                "radiance = [%s]" % ", ".join("%.1f" % c for c in rad), ""]
    return "\n".join(out)


def groups_of(reference_scene):
    """The [[group]] tables of the reference scene.toml, copied verbatim."""
    text = open(reference_scene).read()
    return text[text.index("[[group]]"):]


def render_views(bindir, args, work, scene, edit, out_dir):
    """Renders the six faces of an edit with RADIANCE into out_dir/views."""
    name = os.path.basename(out_dir)
    octree = os.path.join(work, "scene.oct")
    with open(octree, "wb") as f:
        run([os.path.join(bindir, "oconv"), *scene], stdout=f, cwd=work)
    position = edit.get("position", ORIGINAL_POSITION)
    ambient = os.path.join(work, "scene.amb")
    rendered = []
    for face, direction, up in CUBE:
        if face not in args.faces:
            if os.path.exists(os.path.join(out_dir, "views", f"{face}.exr")):
                rendered.append(face)
            continue
        print(f"{name}: {face}", file=sys.stderr, flush=True)
        try:
            rgb = render_face(bindir, QUALITY[args.quality], octree, ambient, position,
                              direction, up, args.size, work)
        except FaceTimeout:
            print(f"{name}: {face} left out after {FACE_TIMEOUT_S} s", file=sys.stderr)
            continue
        write_exr(os.path.join(out_dir, "views", f"{face}.exr"), rgb)
        rendered.append(face)
    return rendered


def scale_views(source_dir, out_dir, lights, original_lights):
    """out_dir/views = source_dir/views x (new radiance / old radiance) per channel, for an
    edit that changes the radiance of the one light that is on."""
    changed = [n for n in lights if lights[n] != original_lights[n]]
    lit = [n for n in lights if any(lights[n])]
    if len(changed) != 1 or lit != changed or not all(original_lights[changed[0]]):
        sys.exit("scale_of needs one light on, the same one, whose radiance changes")
    ratio = np.array(lights[changed[0]]) / np.array(original_lights[changed[0]])
    faces = [f for f, _, _ in CUBE if os.path.exists(os.path.join(source_dir, "views", f"{f}.exr"))]
    for face in faces:
        channels = OpenEXR.File(os.path.join(source_dir, "views", f"{face}.exr")).channels()
        if "RGB" in channels:
            rgb = channels["RGB"].pixels.astype(np.float64)
        else:
            rgb = np.stack([channels[c].pixels for c in "RGB"], axis=-1).astype(np.float64)
        write_exr(os.path.join(out_dir, "views", f"{face}.exr"), (rgb * ratio).astype(np.float32))
    return faces


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--reference", default=os.path.join(HERE, "../../../shared/bench/living-room"))
    ap.add_argument("--only", nargs="*", default=list(EDITS))
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--quality", choices=list(QUALITY), default="quick")
    ap.add_argument("--faces", nargs="*", default=[f for f, _, _ in CUBE],
                    help="render only these faces, keeping the edit's other rendered ones")
    args = ap.parse_args()
    import pyradiance
    bindir = os.path.join(os.path.dirname(pyradiance.__file__), "bin")
    os.environ["RAYPATH"] = os.pathsep.join(
        [".", os.path.join(os.path.dirname(pyradiance.__file__), "lib")])
    reference = os.path.abspath(args.reference)
    rad = os.path.join(reference, "radiance")
    for name in args.only:
        edit = EDITS[name]
        out_dir = os.path.join(HERE, name)
        os.makedirs(os.path.join(out_dir, "views"), exist_ok=True)
        with tempfile.TemporaryDirectory() as work:
            for f in os.listdir(rad):
                shutil.copy(os.path.join(rad, f), work)
            lights_text = open(os.path.join(rad, "lights.rad")).read()
            lights = light_radiances(lights_text)
            lights.update(edit.get("lights", {}))
            with open(os.path.join(work, "lights.rad"), "w") as f:
                f.write(edited_lights(lights_text, lights))
            geometry = edited_geometry(open(os.path.join(rad, "geometry.rad")).read(),
                                       set(edit.get("hide", [])))
            with open(os.path.join(work, "geometry.rad"), "w") as f:
                f.write(geometry)
            scene = ["materials.rad", "lights.rad", "geometry.rad"]
            groups = groups_of(os.path.join(reference, "scene.toml"))
            if edit.get("add_box"):
                with open(os.path.join(work, "added.rad"), "w") as f:
                    f.write(box_rad(ADDED_BOX, ADDED_MATERIAL))
                scene.append("added.rad")
                write_box_obj(os.path.join(out_dir, "added_box.obj"), ADDED_BOX)
                m = ADDED_MATERIAL
                with open(os.path.join(out_dir, "materials.toml"), "w") as f:
                    f.write("# The material of the object remove-add puts in (make_edits.py).\n"
                            "format = 1\n\n[[material]]\n"
                            f'group = "{ADDED_BOX["name"]}"\nmodel = "isotropic"\n'
                            "color = [%g, %g, %g]\n" % m["color"] +
                            f"specularity = {m['specularity']}\nroughness = {m['roughness']}\n")
                groups += (f'\n[[group]]\nname = "{ADDED_BOX["name"]}"\nkind = "plastic"\n'
                           f'objects = ["{ADDED_BOX["name"]}"]\n')
            if "scale_of" in edit:
                faces = scale_views(os.path.join(HERE, edit["scale_of"]), out_dir, lights,
                                    light_radiances(lights_text))
            else:
                faces = render_views(bindir, args, work, scene, edit, out_dir)
        position = edit.get("position", ORIGINAL_POSITION)
        with open(os.path.join(out_dir, "scene.toml"), "w") as f:
            f.write(scene_toml(name, edit, reference, position, args.size, lights,
                               args.quality, faces) + groups)


if __name__ == "__main__":
    main()
