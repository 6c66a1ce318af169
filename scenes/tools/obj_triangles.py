"""The OBJ reading the peer scripts share: vertices, and every face fan-triangulated in file
order with the object it belongs to (the last `o` or `g` line before it). The order is the
global triangle index of shared/bench/rays/README.md."""
import numpy as np


def read_obj_triangles(path):
    """`(vertices, triangles, objects)`: an `n x 3` float64 array, an `m x 3` int32 array of
    vertex indices, and the object name of each triangle."""
    vertices, triangles, objects, current = [], [], [], None
    with open(path) as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                vertices.append([float(x) for x in parts[1:4]])
            elif parts[0] in ("o", "g") and len(parts) > 1:
                current = parts[1]
            elif parts[0] == "f":
                corners = [int(c.split("/")[0]) for c in parts[1:]]
                corners = [c - 1 if c > 0 else len(vertices) + c for c in corners]
                for k in range(1, len(corners) - 1):
                    triangles.append([corners[0], corners[k], corners[k + 1]])
                    objects.append(current)
    return np.array(vertices, np.float64), np.array(triangles, np.int32).reshape(-1, 3), objects
