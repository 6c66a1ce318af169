#!/usr/bin/env python3
"""Embree's closest hits on a ray file, timed in the same session as `relume bench rays`,
so that the two tracers are compared as a ratio on one machine at one load
(docs/renderer-vs-radiance.md, "Ray tracing speed"). Reads the OBJ's faces fan-triangulated
in file order (the global triangle index of shared/bench/rays/README.md), times Embree's
closest-hit query (embreex's `run`, one ray after another on one thread) as the best of
REPEATS after a warm-up, and counts its hits that agree with the reference hits beside the
rays (same triangle, or distances within 1e-4 relative). Prints one JSON object.

Needs embreex and numpy from PyPI, in a virtual environment of their own:
  python3 -m venv /tmp/emb && /tmp/emb/bin/pip install embreex numpy
Usage: /tmp/emb/bin/python embree_rays.py SCENE.obj RAYS.rays [REPEATS]
"""
import json, os, sys, time

import numpy as np
from embreex import rtcore as rtc, rtcore_scene as rtcs
from embreex.mesh_construction import TriangleMesh

from obj_triangles import read_obj_triangles


def read_rays(path):
    rays = np.fromfile(path, dtype="<f4", offset=8).reshape(-1, 6)
    return np.ascontiguousarray(rays[:, :3]), np.ascontiguousarray(rays[:, 3:])


def read_hits(path):
    hit = np.dtype([("t", "<f4"), ("triangle", "<i4")])
    return np.fromfile(path, dtype=hit, offset=8)


def agreeing(t, triangle, reference):
    same = triangle == reference["triangle"]
    both_hit = np.isfinite(t) & np.isfinite(reference["t"])
    with np.errstate(invalid="ignore"):
        close = both_hit & (np.abs(t - reference["t"]) <= 1e-4 * np.maximum(np.abs(reference["t"]), 1e-30))
    return int(np.count_nonzero(same | close))


def main(obj, rays_path, repeats):
    vertices, triangles, _ = read_obj_triangles(obj)
    vertices = vertices.astype(np.float32)
    start = time.perf_counter()
    scene = rtcs.EmbreeScene(rtc.EmbreeDevice())
    TriangleMesh(scene, vertices, triangles)
    origins, directions = read_rays(rays_path)
    out = scene.run(origins, directions, output=1)  # warm-up; commits the scene (builds the BVH)
    build_and_warm_up = time.perf_counter() - start
    best_wall, best_cpu = float("inf"), float("inf")
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        out = scene.run(origins, directions, output=1)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        if wall < best_wall:
            best_wall, best_cpu = wall, cpu
    t = np.where(out["primID"] >= 0, out["tfar"], np.inf).astype(np.float32)
    triangle = np.where(out["primID"] >= 0, out["primID"], -1)
    result = {
        "obj": obj,
        "rays_file": rays_path,
        "triangles": int(len(triangles)),
        "rays": int(len(origins)),
        "repeats": repeats,
        "build_and_warm_up_s": build_and_warm_up,
        "best_s": best_wall,
        "mrays_per_s": len(origins) / best_wall / 1e6,
        "cpu_over_wall": best_cpu / best_wall,
        "hit_fraction": float(np.mean(triangle >= 0)),
        "load_average": list(os.getloadavg()),
    }
    reference = os.path.splitext(rays_path)[0] + ".hits"
    if os.path.exists(reference):
        result["agreeing_with_reference"] = agreeing(t, triangle, read_hits(reference)) / len(origins)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2], int(sys.argv[3]) if len(sys.argv) == 4 else 7)
