#!/usr/bin/env python3
"""Writes geometry.obj of the bundled `cornell` scene (run from this folder).

A 3 x 3 x 2.5 m room (Z up, metres) with a ceiling light, a glossy box, a metal sphere,
a brushed metal plate and a mirror. Every quad is counter-clockwise seen from inside the
room, so the light's front faces down.
"""
import math


class ObjWriter:
    """OBJ text built object by object, each face a list of (x, y, z) corners."""

    def __init__(self, header):
        self.lines = [header]
        self.n_v = 0

    def obj(self, name, faces):
        self.lines.append(f"o {name}")
        for face in faces:
            for v in face:
                self.lines.append("v %.6f %.6f %.6f" % v)
            idx = " ".join(str(self.n_v + 1 + i) for i in range(len(face)))
            self.lines.append(f"f {idx}")
            self.n_v += len(face)

    def text(self):
        return "\n".join(self.lines) + "\n"


W, D, H = 3.0, 3.0, 2.5


def room(w):
    """The room's floor, ceiling and four walls, facing in."""
    w.obj("floor", [[(0, 0, 0), (W, 0, 0), (W, D, 0), (0, D, 0)]])
    w.obj("ceiling", [[(0, 0, H), (0, D, H), (W, D, H), (W, 0, H)]])
    w.obj("wall_left", [[(0, 0, 0), (0, D, 0), (0, D, H), (0, 0, H)]])
    w.obj("wall_right", [[(W, 0, 0), (W, 0, H), (W, D, H), (W, D, 0)]])
    w.obj("wall_back", [[(0, D, 0), (W, D, 0), (W, D, H), (0, D, H)]])
    w.obj("wall_front", [[(0, 0, 0), (0, 0, H), (W, 0, H), (W, 0, 0)]])


def box(x0, y0, x1, y1, z1):
    p = lambda x, y, z: (x, y, z)
    return [
        [p(x0, y0, z1), p(x1, y0, z1), p(x1, y1, z1), p(x0, y1, z1)],  # top
        [p(x0, y0, 0), p(x1, y0, 0), p(x1, y0, z1), p(x0, y0, z1)],
        [p(x1, y0, 0), p(x1, y1, 0), p(x1, y1, z1), p(x1, y0, z1)],
        [p(x1, y1, 0), p(x0, y1, 0), p(x0, y1, z1), p(x1, y1, z1)],
        [p(x0, y1, 0), p(x0, y0, 0), p(x0, y0, z1), p(x0, y1, z1)],
    ]


def main():
    w = ObjWriter("# cornell: relume's bundled scene (make_geometry.py), Z up, metres")
    obj = w.obj
    room(w)
    # Light: 0.8 x 0.8 m just below the ceiling, facing down.
    lz = H - 0.01
    obj("light", [[(1.1, 1.1, lz), (1.1, 1.9, lz), (1.9, 1.9, lz), (1.9, 1.1, lz)]])

    obj("box", box(0.5, 1.8, 1.2, 2.5, 0.9))

    # A UV sphere (12 x 8), radius 0.35, resting on the floor.
    cx, cy, cz, r = 2.1, 1.2, 0.35, 0.35
    faces = []
    n_lon, n_lat = 12, 8
    def sp(i, j):
        th = math.pi * j / n_lat
        ph = 2 * math.pi * i / n_lon
        return (cx + r * math.sin(th) * math.cos(ph), cy + r * math.sin(th) * math.sin(ph), cz + r * math.cos(th))
    for j in range(n_lat):
        for i in range(n_lon):
            a, b, c, d = sp(i, j), sp(i, j + 1), sp(i + 1, j + 1), sp(i + 1, j)
            if j == 0:
                faces.append([a, b, c])
            elif j == n_lat - 1:
                faces.append([a, b, d])
            else:
                faces.append([a, b, c, d])
    obj("sphere", faces)

    # A brushed plate on the right wall and a mirror on the back wall.
    obj("plate", [[(W - 0.01, 0.6, 0.9), (W - 0.01, 0.6, 1.7), (W - 0.01, 1.4, 1.7), (W - 0.01, 1.4, 0.9)]])
    obj("mirror", [[(1.6, D - 0.01, 0.8), (2.6, D - 0.01, 0.8), (2.6, D - 0.01, 1.8), (1.6, D - 0.01, 1.8)]])

    open("geometry.obj", "w").write(w.text())


if __name__ == "__main__":
    main()
