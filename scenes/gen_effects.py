#!/usr/bin/env python3
"""Writes glint's effect showcase scenes to scenes/effects/, one per effect:

  reflect.scene        mirror and tinted spheres over a checker floor (reflect: 4)
  soft_shadows.scene   a sphere light and a rectangle light (shadow_samples: 32)
  antialias.scene      a fan of thin wedges and a fine checker (spp: 16)
  motion_blur.scene    spheres moving at different speeds, a moving light
                       (shutter: 0.5, spp: 16, fps: 24; render with --frames)
  all_effects.scene    everything at once

They use glint's format extensions (see the README); the classic parts are
ordinary CSCI 420 objects. Run from the repository root:
python3 scenes/gen_effects.py
"""
import math
import os

OUT = os.path.join(os.path.dirname(__file__), "effects")


def fmt(*v):
    return " ".join(f"{x:.6g}" for x in v)


class Scene:
    def __init__(self, ambient, settings):
        self.ambient = ambient
        self.settings = settings
        self.objects = []

    def vertex(self, p, n, kd, ks, shi):
        return f"pos: {fmt(*p)}\nnor: {fmt(*n)}\ndif: {fmt(*kd)}\nspe: {fmt(*ks)}\nshi: {fmt(shi)}\n"

    def triangle(self, verts, vel=None):
        text = "triangle\n" + "".join(self.vertex(*v) for v in verts)
        if vel:
            text += f"vel: {fmt(*vel)}\n"
        self.objects.append(text)

    def sphere(self, c, r, kd, ks, shi, vel=None):
        text = f"sphere\npos: {fmt(*c)}\nrad: {fmt(r)}\ndif: {fmt(*kd)}\nspe: {fmt(*ks)}\nshi: {fmt(shi)}\n"
        if vel:
            text += f"vel: {fmt(*vel)}\n"
        self.objects.append(text)

    def light(self, p, col, rad=None, edges=None, vel=None):
        text = f"light\npos: {fmt(*p)}\ncol: {fmt(*col)}\n"
        if rad:
            text += f"rad: {fmt(rad)}\n"
        if edges:
            text += f"edge_u: {fmt(*edges[0])}\nedge_v: {fmt(*edges[1])}\n"
        if vel:
            text += f"vel: {fmt(*vel)}\n"
        self.objects.append(text)

    def floor(self, y, x0, x1, z0, z1, n, ks=(0.0, 0.0, 0.0)):
        up = (0, 1, 0)
        for i in range(n):
            for j in range(n):
                xa, xb = x0 + (x1 - x0) * i / n, x0 + (x1 - x0) * (i + 1) / n
                za, zb = z0 + (z1 - z0) * j / n, z0 + (z1 - z0) * (j + 1) / n
                kd = (0.85, 0.82, 0.75) if (i + j) % 2 == 0 else (0.15, 0.17, 0.25)
                m = (kd, ks, 20)
                a, b, c, d = (xa, y, za), (xb, y, za), (xb, y, zb), (xa, y, zb)
                self.triangle([(a, up, *m), (b, up, *m), (c, up, *m)])
                self.triangle([(a, up, *m), (c, up, *m), (d, up, *m)])

    def write(self, name, comment):
        path = os.path.join(OUT, name)
        with open(path, "w") as f:
            # The classic count is the first token; comments are not part of
            # the format, so the description lives in this generator.
            f.write(f"{len(self.objects)}\n")
            f.write(f"amb: {fmt(*self.ambient)}\n")
            for k, v in self.settings.items():
                f.write(f"{k}: {v}\n")
            f.write("".join(self.objects))
        print(f"wrote {path}: {comment}")


def reflect():
    s = Scene((0.08, 0.08, 0.1), {"reflect": 4})
    s.floor(-1.0, -8, 8, -2, -22, 10, ks=(0.25, 0.25, 0.25))
    s.sphere((0, 0.2, -7), 1.2, (0.05, 0.05, 0.05), (0.9, 0.9, 0.9), 200)
    s.sphere((-2.6, -0.2, -8.5), 0.8, (0.7, 0.15, 0.1), (0.4, 0.2, 0.2), 60)
    s.sphere((2.5, -0.3, -6.2), 0.7, (0.1, 0.5, 0.75), (0.5, 0.5, 0.5), 80)
    s.sphere((1.0, -0.65, -4.6), 0.35, (0.85, 0.7, 0.1), (0.3, 0.3, 0.3), 40)
    s.light((-4, 6, -2), (0.6, 0.6, 0.6))
    s.light((5, 4, -3), (0.35, 0.3, 0.25))
    s.write("reflect.scene", "mirror spheres and a glossy floor, 4 bounces")


def soft_shadows():
    s = Scene((0.06, 0.06, 0.06), {"shadow_samples": 32})
    s.floor(-1.0, -8, 8, -2, -20, 8)
    s.sphere((-1.6, -0.1, -6.5), 0.9, (0.75, 0.2, 0.15), (0.3, 0.3, 0.3), 40)
    s.sphere((1.5, -0.4, -7.5), 0.6, (0.2, 0.6, 0.25), (0.3, 0.3, 0.3), 40)
    s.sphere((0.2, -0.75, -4.8), 0.25, (0.9, 0.8, 0.2), (0.3, 0.3, 0.3), 20)
    s.light((-3, 4, -4), (0.55, 0.5, 0.45), rad=0.8)
    s.light((3, 5, -8), (0.35, 0.38, 0.45), edges=((2.5, 0, 0), (0, 0, 1.5)))
    s.write("soft_shadows.scene", "a sphere light (radius 0.8) and a 2.5 x 1.5 rectangle light")


def antialias():
    s = Scene((0.05, 0.05, 0.05), {"spp": 16})
    s.floor(-1.5, -30, 30, -3, -60, 60)
    z = -6
    for i in range(24):
        a0 = math.pi * i / 24
        a1 = a0 + math.pi / 24 * 0.35
        c = (0, 1.2, z)
        p0 = (3.2 * math.cos(a0), 1.2 + 3.2 * math.sin(a0), z)
        p1 = (3.2 * math.cos(a1), 1.2 + 3.2 * math.sin(a1), z)
        kd = (0.9, 0.3 + 0.6 * i / 23, 0.2)
        m = (kd, (0.2, 0.2, 0.2), 10)
        s.triangle([(c, (0, 0, 1), *m), (p0, (0, 0, 1), *m), (p1, (0, 0, 1), *m)])
    s.light((0, 5, 0), (0.8, 0.8, 0.8))
    s.write("antialias.scene", "thin wedges and a fine checker that alias at 1 sample per pixel")


def motion_blur():
    s = Scene((0.07, 0.07, 0.08), {"spp": 16, "shutter": 0.5, "fps": 24})
    s.floor(-1.0, -8, 8, -2, -18, 8)
    s.sphere((-3.0, -0.3, -7), 0.7, (0.8, 0.2, 0.15), (0.4, 0.4, 0.4), 50, vel=(24.0, 0, 0))
    s.sphere((-1.5, 0.8, -9), 0.6, (0.2, 0.45, 0.8), (0.4, 0.4, 0.4), 50, vel=(8.0, 0, 0))
    s.sphere((2.5, -0.5, -6), 0.5, (0.2, 0.7, 0.3), (0.4, 0.4, 0.4), 50, vel=(0, 10.0, 0))
    s.sphere((0.5, -0.6, -5), 0.4, (0.85, 0.75, 0.2), (0.3, 0.3, 0.3), 30)
    s.light((-4, 6, -2), (0.6, 0.6, 0.6), vel=(2.0, 0, 0))
    s.light((4, 5, -4), (0.3, 0.3, 0.3))
    s.write("motion_blur.scene", "three moving spheres (one static), a moving light; shutter 0.5")


def all_effects():
    s = Scene((0.06, 0.06, 0.07), {"reflect": 3, "spp": 16, "shadow_samples": 16, "shutter": 0.5})
    s.floor(-1.0, -8, 8, -2, -18, 8, ks=(0.2, 0.2, 0.2))
    s.sphere((0, 0.1, -7), 1.0, (0.05, 0.05, 0.05), (0.85, 0.85, 0.85), 200)
    s.sphere((-2.5, -0.4, -6), 0.6, (0.8, 0.25, 0.15), (0.3, 0.3, 0.3), 40, vel=(12.0, 0, 0))
    s.sphere((2.2, -0.5, -5.5), 0.5, (0.2, 0.6, 0.8), (0.3, 0.3, 0.3), 40)
    s.light((-3, 5, -3), (0.55, 0.55, 0.5), rad=0.6)
    s.light((3, 5, -8), (0.3, 0.3, 0.35), edges=((2, 0, 0), (0, 0, 1)))
    s.write("all_effects.scene", "reflection, area lights, antialiasing and motion blur together")


if __name__ == "__main__":
    os.makedirs(OUT, exist_ok=True)
    reflect()
    soft_shadows()
    antialias()
    motion_blur()
    all_effects()
