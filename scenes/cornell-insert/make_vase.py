#!/usr/bin/env python3
"""Writes vase.obj, the object inserted into the bundled `cornell` scene (run from this folder).

A closed surface of revolution 0.40 m tall and 0.32 m wide (16 segments around, flat
facets), standing on the floor of ../cornell in front of the blue box, left of the metal
sphere. Z up, metres, like ../cornell/geometry.obj. Every face is counter-clockwise seen from
outside. The base is 1 mm above the floor so that no face is coplanar with it.
"""
import math

CX, CY, Z0 = 1.2, 1.25, 0.001
N = 16
# The profile, bottom centre to top centre: (radius, height) in metres.
PROFILE = [
    (0.0, 0.0),
    (0.10, 0.0),
    (0.14, 0.05),
    (0.16, 0.13),
    (0.145, 0.22),
    (0.10, 0.30),
    (0.065, 0.35),
    (0.08, 0.40),
    (0.0, 0.40),
]


def point(i, k):
    r, z = PROFILE[i]
    a = 2 * math.pi * (k % N) / N
    return (CX + r * math.cos(a), CY + r * math.sin(a), Z0 + z)


out = ["# vase: the object inserted into the cornell scene (make_vase.py), Z up, metres", "o vase"]
n_v = 0
for i in range(len(PROFILE) - 1):
    for k in range(N):
        # Counter-clockwise seen from outside; a vertex on the axis makes a triangle.
        face = [point(i, k), point(i, k + 1), point(i + 1, k + 1), point(i + 1, k)]
        if PROFILE[i][0] == 0.0:
            del face[1]
        elif PROFILE[i + 1][0] == 0.0:
            del face[2]
        for v in face:
            out.append("v %.6f %.6f %.6f" % v)
        out.append("f " + " ".join(str(n_v + 1 + j) for j in range(len(face))))
        n_v += len(face)

open("vase.obj", "w").write("\n".join(out) + "\n")
