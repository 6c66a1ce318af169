#!/usr/bin/env python3
"""Midpoint-subdivide every face of an OBJ k times: each triangle into 4^k, polygons fanned
first; objects, groups and other lines kept in place, vt and vn interpolated.

The same surfaces in many more triangles, as a scanned mesh gives them: how recovery's cost
grows with the triangle count (docs/renderer-vs-radiance.md, "Scenes of many triangles").

    python3 scenes/tools/subdivide_obj.py in.obj out.obj k
"""
import sys


def read(path):
    """Vertices, texture and normal coordinates, and the body: ('f', corners) or ('l', line)."""
    v, vt, vn, body = [], [], [], []

    def index(text, table):
        i = int(text)
        return i - 1 if i > 0 else len(table) + i

    for line in open(path):
        t = line.split()
        if not t:
            continue
        if t[0] == 'v':
            v.append(tuple(map(float, t[1:4])))
        elif t[0] == 'vt':
            vt.append(tuple(map(float, t[1:3])))
        elif t[0] == 'vn':
            vn.append(tuple(map(float, t[1:4])))
        elif t[0] == 'f':
            corners = []
            for c in t[1:]:
                parts = c.split('/') + ['', '']
                corners.append((
                    v[index(parts[0], v)],
                    vt[index(parts[1], vt)] if parts[1] else None,
                    vn[index(parts[2], vn)] if parts[2] else None,
                ))
            body.append(('f', corners))
        else:
            body.append(('l', line.rstrip('\n')))
    return body


def mid(a, b):
    return tuple(
        None if x is None else tuple((p + q) / 2 for p, q in zip(x, y))
        for x, y in zip(a, b)
    )


def split(tri, k):
    if k == 0:
        return [tri]
    a, b, c = tri
    ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
    return [t for part in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)) for t in split(part, k - 1)]


def corner(r, t, n):
    """A face corner at relative index r: v, v/vt, v//vn or v/vt/vn."""
    if n is not None:
        return '%d/%s/%d' % (r, r if t is not None else '', r)
    return '%d/%d' % (r, r) if t is not None else str(r)


def write(path, body, k):
    count = 0
    with open(path, 'w') as w:
        for kind, payload in body:
            if kind == 'l':
                w.write(payload + '\n')
                continue
            for i in range(1, len(payload) - 1):
                for tri in split((payload[0], payload[i], payload[i + 1]), k):
                    for p, t, n in tri:
                        w.write('v %.9g %.9g %.9g\n' % p)
                        if t is not None:
                            w.write('vt %.9g %.9g\n' % t)
                        if n is not None:
                            w.write('vn %.9g %.9g %.9g\n' % n)
                    # Each corner's own v (vt, vn) were just written: relative indices.
                    w.write('f ' + ' '.join(corner(j - 3, t, n) for j, (_, t, n) in enumerate(tri)) + '\n')
                    count += 1
    return count


if __name__ == '__main__':
    src, dst, k = sys.argv[1], sys.argv[2], int(sys.argv[3])
    print(write(dst, read(src), k), 'triangles')
