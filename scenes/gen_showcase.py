#!/usr/bin/env python3
"""Writes scenes/showcase.scene: glint's own demo scene in the classic format.

A checkerboard floor, a smooth-shaded icosphere with per-vertex colours
(barycentric interpolation of normals and materials), a faceted pyramid
(flat normals), spheres of several shininesses, and two coloured lights.
Run from the repository root: python3 scenes/gen_showcase.py
"""
import colorsys
import math

objects = []


def fmt(*v):
    return " ".join(f"{x:.6g}" for x in v)


def vertex(p, n, kd, ks, shi):
    return f"pos: {fmt(*p)}\nnor: {fmt(*n)}\ndif: {fmt(*kd)}\nspe: {fmt(*ks)}\nshi: {fmt(shi)}\n"


def triangle(verts):
    objects.append("triangle\n" + "".join(vertex(*v) for v in verts))


def sphere(c, r, kd, ks, shi):
    objects.append(f"sphere\npos: {fmt(*c)}\nrad: {fmt(r)}\ndif: {fmt(*kd)}\nspe: {fmt(*ks)}\nshi: {fmt(shi)}\n")


def light(p, col):
    objects.append(f"light\npos: {fmt(*p)}\ncol: {fmt(*col)}\n")


# Checkerboard floor at y = -1.
up = (0, 1, 0)
x0, x1, z0, z1, n = -12.0, 12.0, -1.0, -25.0, 12
for i in range(n):
    for j in range(n):
        xa, xb = x0 + (x1 - x0) * i / n, x0 + (x1 - x0) * (i + 1) / n
        za, zb = z0 + (z1 - z0) * j / n, z0 + (z1 - z0) * (j + 1) / n
        kd = (0.85, 0.82, 0.75) if (i + j) % 2 == 0 else (0.12, 0.14, 0.22)
        m = (kd, (0.25, 0.25, 0.25), 30)
        a, b, c, d = (xa, -1, za), (xb, -1, za), (xb, -1, zb), (xa, -1, zb)
        triangle([(a, up, *m), (b, up, *m), (c, up, *m)])
        triangle([(a, up, *m), (c, up, *m), (d, up, *m)])

# Icosphere, subdivided twice, smooth normals, hue by angle around the view axis.
t = (1 + 5 ** 0.5) / 2
verts = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t),
         (0, -1, -t), (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]


def unit(v):
    l = math.sqrt(sum(c * c for c in v))
    return tuple(c / l for c in v)


verts = [unit(v) for v in verts]
for _ in range(2):
    cache, out = {}, []

    def mid(a, b):
        key = (min(a, b), max(a, b))
        if key not in cache:
            cache[key] = len(verts)
            verts.append(unit(tuple((p + q) / 2 for p, q in zip(verts[a], verts[b]))))
        return cache[key]

    for a, b, c in faces:
        ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
        out += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
    faces = out

centre, radius = (-2.6, 0.45, -9.0), 1.45
for f in faces:
    vs = []
    for k in f:
        nrm = verts[k]
        hue = (math.atan2(nrm[1], nrm[0]) / (2 * math.pi)) % 1.0
        kd = colorsys.hsv_to_rgb(hue, 0.75, 0.85)
        vs.append((tuple(c + radius * q for c, q in zip(centre, nrm)), nrm, kd, (0.5, 0.5, 0.5), 60))
    triangle(vs)

# Faceted pyramid: each face carries its own flat normal.
apex, base = (3.6, 1.0, -6.2), [(2.7, -1, -5.3), (4.5, -1, -5.3), (4.5, -1, -7.1), (2.7, -1, -7.1)]
gold = ((0.8, 0.6, 0.15), (0.6, 0.5, 0.3), 25)
for i in range(4):
    a, b = base[i], base[(i + 1) % 4]
    e1 = tuple(q - p for p, q in zip(a, b))
    e2 = tuple(q - p for p, q in zip(a, apex))
    nrm = unit((e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]))
    triangle([(a, nrm, *gold), (b, nrm, *gold), (apex, nrm, *gold)])

# Spheres: glossy blue, and a row of small ones from matte to sharp highlights.
sphere((0.7, 0.1, -11.0), 1.1, (0.1, 0.2, 0.6), (0.8, 0.8, 0.8), 120)
for i, shi in enumerate([1, 5, 20, 80, 300]):
    hue = i / 5
    sphere((-1.0 + 0.75 * i, -0.72, -4.3), 0.28, colorsys.hsv_to_rgb(hue, 0.6, 0.8), (0.6, 0.6, 0.6), shi)

light((-5.0, 7.0, -1.0), (0.65, 0.55, 0.45))
light((6.0, 4.0, -3.0), (0.25, 0.3, 0.45))

with open("scenes/showcase.scene", "w") as f:
    f.write(f"{len(objects)}\namb: 0.08 0.08 0.1\n")
    f.write("".join(objects))
