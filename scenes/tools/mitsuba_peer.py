#!/usr/bin/env python3
"""The issue's peer, run in the same session as relume: Mitsuba 3 (llvm_ad_rgb, Adam, 2
threads) recovering the albedos of an all-diffuse scene from its panorama, so that the
two are timed on one machine at one load (docs/tradeoff.md, "Against Mitsuba 3 in the
same run").

The scene is read from the scene.toml (its first OBJ, views, lights and groups) and the
truth from truth.toml, whose colours are used only to score each iteration. Each group
is one mesh with a two-sided diffuse BSDF (scene-format.md: surfaces reflect on both
sides, lights emit from the front only) starting at grey 0.5; each view is a perspective
camera with a box filter over its footprint, as the format defines a pixel. Every
iteration renders all views with path replay backpropagation (`prb`, 16 bounces, Russian
roulette from the 5th) at SPP samples a pixel on a fresh seed, takes the mean squared
error against the views, and steps Adam; the learning rate decays from LR by DECAY each
iteration (1 keeps it constant) down to LR / 100. Writes one JSON line per iteration (wall
seconds since the first, the albedos' mean and largest relative error; reading them back
is inside the timed loop, a small cost charged to the peer) to LOG, and prints the time it
first reached 1% mean relative error and its error at the end.

Needs mitsuba and drjit from PyPI and an LLVM of version 16 or later (Debian: libllvm19):
  python3 -m venv /tmp/emb && /tmp/emb/bin/pip install mitsuba numpy
  apt-get install libllvm19
  DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 \\
    /tmp/emb/bin/python mitsuba_peer.py SCENE.toml TRUTH.toml SECONDS SPP LR DECAY LOG
CHECK=1 (with the same arguments, of which only the two files are read) instead renders
each view with the true colours at 256 spp and prints how it differs from the panorama (that the cameras and lights are read as relume reads them).
"""
import json
import os
import sys
import time
import tomllib

import drjit as dr
import mitsuba as mi
import numpy as np

from obj_triangles import read_obj_triangles

mi.set_variant("llvm_ad_rgb")
PLY_DIR = "/tmp/mitsuba_peer_ply"


def write_ply(name, vertices, triangles):
    os.makedirs(PLY_DIR, exist_ok=True)
    used = sorted({i for t in triangles for i in t})
    index = {v: k for k, v in enumerate(used)}
    path = os.path.join(PLY_DIR, name + ".ply")
    with open(path, "w") as f:
        f.write(
            f"ply\nformat ascii 1.0\nelement vertex {len(used)}\nproperty float x\n"
            f"property float y\nproperty float z\nelement face {len(triangles)}\n"
            "property list uchar int vertex_indices\nend_header\n"
        )
        for i in used:
            f.write("%r %r %r\n" % tuple(float(x) for x in vertices[i]))
        for t in triangles:
            f.write("3 %d %d %d\n" % tuple(index[i] for i in t))
    return path


def load(scene_path):
    """The Mitsuba scene, its sensors, the views' images and each group's albedo key."""
    folder = os.path.dirname(os.path.abspath(scene_path))
    with open(scene_path, "rb") as f:
        desc = tomllib.load(f)
    vertices, all_triangles, owners = read_obj_triangles(os.path.join(folder, desc["geometry"][0]))
    group_of = {o: g["name"] for g in desc["group"] for o in g["objects"]}
    lights = {l["object"]: l["radiance"] for l in desc.get("light", [])}
    light_triangles, by_group = {}, {}
    for triangle, owner in zip(all_triangles.tolist(), owners):
        if owner in lights:
            light_triangles.setdefault(owner, []).append(triangle)
        elif owner in group_of:
            by_group.setdefault(group_of[owner], []).append(triangle)
    scene = {"type": "scene", "integrator": {"type": "prb", "max_depth": 16, "rr_depth": 5}}
    for name, triangles in light_triangles.items():
        scene["light_" + name] = {
            "type": "ply",
            "filename": write_ply(name, vertices, triangles),
            "face_normals": True,
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": lights[name]}},
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0, 0, 0]}},
        }
    for group, triangles in by_group.items():
        diffuse = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}}
        scene["group_" + group] = {
            "type": "ply",
            "filename": write_ply(group, vertices, triangles),
            "face_normals": True,  # flat faces: shared vertices would smooth a box's edges
            "bsdf": {"type": "twosided", "material": diffuse},
        }
    sensors, images = [], []
    for view in desc["view"]:
        width, height = view["size"]
        position = np.array(view["position"], float)
        target = position + np.array(view["direction"], float)
        sensors.append(
            mi.load_dict(
                {
                    "type": "perspective",
                    "fov": view["fov_deg"][0],
                    "fov_axis": "x",
                    "to_world": mi.ScalarTransform4f().look_at(
                        origin=position.tolist(), target=target.tolist(), up=view["up"]
                    ),
                    "film": {
                        "type": "hdrfilm",
                        "width": width,
                        "height": height,
                        "rfilter": {"type": "box"},
                        "pixel_format": "rgb",
                    },
                    "sampler": {"type": "independent"},
                }
            )
        )
        bitmap = mi.Bitmap(os.path.join(folder, view["image"]))
        pixels = bitmap.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False)
        images.append(mi.TensorXf(np.array(pixels, np.float32) * view.get("exposure", 1.0)))
    # optimize=False: Mitsuba would otherwise merge the groups' meshes, whose BSDFs start equal.
    loaded = mi.load_dict(scene, optimize=False)
    keys = {g: f"group_{g}.bsdf.brdf_0.reflectance.value" for g in by_group}
    return loaded, sensors, images, keys, [v["name"] for v in desc["view"]]


def check(scene, sensors, images, keys, names, truth):
    params = mi.traverse(scene)
    for group, key in keys.items():
        params[key] = mi.Color3f(truth[group])
    params.update()
    for name, sensor, image in zip(names, sensors, images):
        rendered = np.array(mi.render(scene, sensor=sensor, spp=256))
        real = np.array(image)
        median = float(np.median(np.abs(rendered - real) / np.maximum(real, 1e-3)))
        mean = (rendered.mean() - real.mean()) / real.mean()
        print(f"{name}: mean {mean:+.2%}, median pixel difference {median:.2%}")


def recover(scene, sensors, images, keys, truth, seconds, spp, lr, decay, log_path):
    params = mi.traverse(scene)
    opt = mi.ad.Adam(lr=lr)
    for key in keys.values():
        opt[key] = params[key]
    params.update(opt)
    start, iteration, first_at_1pct, rate = time.perf_counter(), 0, None, lr
    with open(log_path, "w") as log:
        while True:
            loss = 0
            for sensor, image in zip(sensors, images):
                rendered = mi.render(scene, params, sensor=sensor, spp=spp, seed=iteration)
                loss = loss + dr.mean(dr.square(rendered - image))
            dr.backward(loss)
            opt.step()
            for key in keys.values():
                opt[key] = dr.clip(opt[key], 0.0, 1.0)
            params.update(opt)
            rate = max(lr / 100, rate * decay)
            opt.set_learning_rate(rate)
            iteration += 1
            errors = []
            for group, key in keys.items():
                albedo = np.array(params[key]).ravel()
                errors.extend(np.abs(albedo - truth[group]) / truth[group])
            elapsed = time.perf_counter() - start
            mean_error = float(np.mean(errors))
            if first_at_1pct is None and mean_error <= 0.01:
                first_at_1pct = elapsed
            line = {"iteration": iteration, "seconds": elapsed, "mean_rel_err": mean_error,
                    "max_rel_err": float(np.max(errors))}
            log.write(json.dumps(line) + "\n")
            log.flush()
            if elapsed > seconds:
                break
    print(json.dumps({"iterations": iteration, "seconds": elapsed, "mean_rel_err": mean_error,
                      "first_at_1pct_s": first_at_1pct, "spp": spp, "lr": lr, "decay": decay,
                      "albedos": {g: np.array(params[k]).ravel().round(4).tolist() for g, k in keys.items()},
                      "load_average": list(os.getloadavg())}))


def main():
    dr.set_thread_count(int(os.environ.get("THREADS", "2")))
    if len(sys.argv) != 8:
        sys.exit(__doc__)
    scene_path, truth_path = sys.argv[1], sys.argv[2]
    seconds, spp, lr, decay = float(sys.argv[3]), int(sys.argv[4]), float(sys.argv[5]), float(sys.argv[6])
    with open(truth_path, "rb") as f:
        truth = {m["group"]: np.array(m["color"], float) for m in tomllib.load(f)["material"]}
    scene, sensors, images, keys, names = load(scene_path)
    if os.environ.get("CHECK"):
        check(scene, sensors, images, keys, names, truth)
    else:
        recover(scene, sensors, images, keys, truth, seconds, spp, lr, decay, sys.argv[7])


if __name__ == "__main__":
    main()
