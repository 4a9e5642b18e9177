#!/usr/bin/env python3
"""Scenes nobody tuned for: seeded random scene files (.json with OBJ/MTL meshes and PGM alpha
masks) for `gridrt diff` (the reference against the shaders, bit for bit) and `gridrt verify`
(against Embree). Each scene draws its parts, scale, placement, materials, lights, camera, moving
instances and grid overrides from its own seed, so a failing scene is rebuilt from its name alone.

  python3 tools/random_scenes.py OUT_DIR [COUNT [FIRST_SEED]]
  for s in OUT_DIR/rand-*.json; do gridrt diff $s --gpu-frame --width 320 --height 180 --frames 3; done

Parts (each scene takes 1 to 4):
  soup      random intersecting triangles in a box
  room      a closed axis-aligned box seen from inside, walls split into quads on a lattice
            (faces on the planes a regular grid's cell faces may share)
  terrain   a height field of quads, some flat (coplanar neighbours)
  sphere    a closed UV sphere (slivers at its poles)
  needles   long triangles a thousandth as wide
  cards     alpha-keyed quads (MTL map_d, a PGM mask of random blocks), some crossing each other
  stairs    thin steps stacked close together (many parallel faces a cell apart)
Moving instances (0 to 3): the built-in teapot or one of the scene's parts, turning about an axis
and/or following a path. Lights: 0 to 3, point and directional. Glossiness: random per scene.
Grid overrides, sometimes: a resolution, or a small capacity (saturated cells, the spill list).
The scene's scale is 10^-3 to 10^4 and its centre up to 10^4 scale-widths from the origin (at most
4e6: the camera stays inside the ray domain).
"""
import json
import math
import os
import random
import sys


def obj_write(path, V, F, mtl=None, material=None, VT=None):
    with open(path, "w") as f:
        if mtl:
            f.write("mtllib %s\nusemtl %s\n" % (mtl, material))
        for v in V:
            f.write("v %.9g %.9g %.9g\n" % tuple(v))
        if VT:
            for t in VT:
                f.write("vt %.9g %.9g\n" % tuple(t))
            for t in F:
                f.write("f %d/%d %d/%d %d/%d\n" % (t[0] + 1, t[0] + 1, t[1] + 1, t[1] + 1, t[2] + 1, t[2] + 1))
        else:
            for t in F:
                f.write("f %d %d %d\n" % (t[0] + 1, t[1] + 1, t[2] + 1))


def quad(V, F, a, b, c, d):
    n = len(V)
    V += [a, b, c, d]
    F += [(n, n + 1, n + 2), (n, n + 2, n + 3)]


def part_soup(R):
    V, F = [], []
    n = R.choice([50, 400, 3000])
    w = R.choice([0.02, 0.1, 0.3])
    for i in range(n):
        c = [R.uniform(-1, 1) for _ in range(3)]
        for _ in range(3):
            V.append([c[j] + R.uniform(-w, w) for j in range(3)])
        F.append((3 * i, 3 * i + 1, 3 * i + 2))
    return V, F


def part_room(R):
    V, F = [], []
    k = R.choice([1, 2, 4, 8])
    L = 1.0
    for axis in range(3):
        for side in (-L, L):
            for i in range(k):
                for j in range(k):
                    u0, u1 = -L + 2 * L * i / k, -L + 2 * L * (i + 1) / k
                    v0, v1 = -L + 2 * L * j / k, -L + 2 * L * (j + 1) / k
                    def p(u, v):
                        q = [0.0, 0.0, 0.0]
                        q[axis] = side
                        q[(axis + 1) % 3] = u
                        q[(axis + 2) % 3] = v
                        return q
                    if side > 0:
                        quad(V, F, p(u0, v0), p(u1, v0), p(u1, v1), p(u0, v1))
                    else:
                        quad(V, F, p(u0, v0), p(u0, v1), p(u1, v1), p(u1, v0))
    return V, F


def part_terrain(R):
    V, F = [], []
    n = R.choice([8, 32, 64])
    amp = R.choice([0.0, 0.05, 0.3])
    H = [[(amp * math.sin(3 * i / n + R.uniform(0, 0.3)) * math.cos(5 * j / n) if R.random() < 0.7 else 0.0)
          for j in range(n + 1)] for i in range(n + 1)]
    for i in range(n):
        for j in range(n):
            def p(a, b):
                return [-1 + 2 * a / n, H[a][b] - 0.9, -1 + 2 * b / n]
            quad(V, F, p(i, j), p(i, j + 1), p(i + 1, j + 1), p(i + 1, j))
    return V, F


def part_sphere(R):
    V, F = [], []
    N = R.choice([12, 60, 150])
    M = N // 2
    r = R.uniform(0.2, 0.6)
    c = [R.uniform(-0.4, 0.4) for _ in range(3)]
    for i in range(M + 1):
        th = math.pi * i / M
        for j in range(N):
            ph = 2 * math.pi * j / N
            V.append([c[0] + r * math.sin(th) * math.cos(ph), c[1] + r * math.cos(th), c[2] + r * math.sin(th) * math.sin(ph)])
    for i in range(M):
        for j in range(N):
            a, b = i * N + j, i * N + (j + 1) % N
            c2, d = (i + 1) * N + (j + 1) % N, (i + 1) * N + j
            F += [(a, b, c2), (a, c2, d)]
    return V, F


def part_needles(R):
    V, F = [], []
    for i in range(R.choice([100, 1000])):
        a = [R.uniform(-1, 1) for _ in range(3)]
        b = [R.uniform(-1, 1) for _ in range(3)]
        e = [R.uniform(-1e-3, 1e-3) for _ in range(3)]
        V += [a, b, [a[j] + e[j] for j in range(3)]]
        F.append((3 * i, 3 * i + 1, 3 * i + 2))
    return V, F


def part_cards(R):
    V, F, VT = [], [], []
    for i in range(R.choice([4, 40, 200])):
        c = [R.uniform(-0.8, 0.8) for _ in range(3)]
        s = R.uniform(0.05, 0.4)
        u = [R.gauss(0, 1) for _ in range(3)]
        lu = math.sqrt(sum(x * x for x in u)) or 1.0
        u = [x / lu for x in u]
        w = [R.gauss(0, 1) for _ in range(3)]
        d = sum(w[k] * u[k] for k in range(3))
        w = [w[k] - d * u[k] for k in range(3)]
        lw = math.sqrt(sum(x * x for x in w)) or 1.0
        w = [x / lw for x in w]
        pts = [[c[k] + s * (a * u[k] + b * w[k]) for k in range(3)] for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
        quad(V, F, *pts)
        t0 = R.choice([0.0, 0.5])
        VT += [[t0, 0], [t0 + 1, 0], [t0 + 1, 1], [t0, 1]]
    return V, F, VT


def part_stairs(R):
    V, F = [], []
    n = R.choice([10, 50])
    for i in range(n):
        y = -1 + 2 * i / n
        z = -1 + 2 * i / n
        quad(V, F, [-1, y, z], [-1, y, z + 2 / n], [1, y, z + 2 / n], [1, y, z])
        quad(V, F, [-1, y, z + 2 / n], [-1, y + 2 / n, z + 2 / n], [1, y + 2 / n, z + 2 / n], [1, y, z + 2 / n])
    return V, F


PARTS = {"soup": part_soup, "room": part_room, "terrain": part_terrain, "sphere": part_sphere,
         "needles": part_needles, "cards": part_cards, "stairs": part_stairs}


def write_mask(path, R):
    n = R.choice([4, 16, 64])
    with open(path, "w") as f:
        f.write("P2\n%d %d\n255\n" % (n, n))
        for _ in range(n):
            f.write(" ".join(str(R.choice([0, 255, 127, 128])) for _ in range(n)) + "\n")


def scene(out, seed):
    R = random.Random(seed)
    name = "rand-%d" % seed
    scale = 10 ** R.uniform(-3, 4)
    # (within 2^22 of the origin, so the camera stays inside the ray domain's 2^24)
    centre = [max(-4e6, min(4e6, R.choice([0.0, 1.0, 100.0, 1e4]) * scale * R.uniform(-1, 1))) for _ in range(3)]
    meshes, instances, made = {}, [], []
    for kind in R.sample(list(PARTS), R.randint(1, 4)):
        file = "%s-%s.obj" % (name, kind)
        if kind == "cards":
            V, F, VT = part_cards(R)
            mask = "%s-mask.pgm" % name
            write_mask(os.path.join(out, mask), R)
            with open(os.path.join(out, "%s.mtl" % name), "w") as f:
                f.write("newmtl card\nKd 0.7 0.6 0.3\nmap_d %s\n" % mask)
            obj_write(os.path.join(out, file), V, F, "%s.mtl" % name, "card", VT)
        else:
            V, F = PARTS[kind](R)
            obj_write(os.path.join(out, file), V, F)
        meshes[kind] = {"file": file}
        made.append(kind)
        inst = {"name": kind, "mesh": kind, "translate": centre, "scale": scale}
        if R.random() < 0.3:
            inst["rotate"] = {"axis": [R.uniform(-1, 1), 1, R.uniform(-1, 1)], "degrees": R.uniform(0, 360)}
        instances.append(inst)
    for i in range(R.choice([0, 0, 1, 2, 3])):
        if R.random() < 0.6:
            meshes.setdefault("teapot", {"builtin": "teapot", "level": R.choice([2, 4, 6]), "diffuse": [0.8, 0.3, 0.2]})
            mesh, s = "teapot", scale * R.uniform(0.05, 0.2)
        else:
            mesh, s = R.choice(made), scale * R.uniform(0.1, 0.5)
        motion = {}
        if R.random() < 0.8:
            motion["rotate"] = {"axis": [R.uniform(-1, 1), 1, R.uniform(-1, 1)], "speed": R.uniform(-3, 3)}
        if R.random() < 0.6 or not motion:
            motion["path"] = {"points": [[R.uniform(-0.5, 0.5) * scale for _ in range(3)] for _ in range(R.randint(2, 4))],
                              "period": R.uniform(0.5, 4)}
        p = [centre[k] + R.uniform(-0.6, 0.6) * scale for k in range(3)]
        instances.append({"name": "moving%d" % i, "mesh": mesh, "translate": p, "scale": s, "motion": motion})
    lights = []
    for _ in range(R.choice([0, 1, 1, 2, 3])):
        if R.random() < 0.6:
            lights.append({"position": [centre[k] + R.uniform(-0.9, 0.9) * scale for k in range(3)],
                           "intensity": (0.5 * scale) ** 2})
        else:
            lights.append({"direction": [R.uniform(-1, 1), R.uniform(0.2, 1), R.uniform(-1, 1)]})
    d = [R.gauss(0, 1) for _ in range(3)]
    ld = math.sqrt(sum(x * x for x in d)) or 1.0
    dist = R.choice([0.5, 2.5, 6.0]) * scale
    eye = [centre[k] + dist * d[k] / ld for k in range(3)]
    target = [centre[k] + R.uniform(-0.2, 0.2) * scale for k in range(3)]
    doc = {"name": name, "description": "tools/random_scenes.py, seed %d" % seed, "meshes": meshes,
           "instances": instances, "materials": {"glossiness": R.choice([0.0, 0.3, 0.8, 1.0])},
           "camera": {"eye": eye, "target": target, "vfov": R.choice([30, 60, 90])}, "lights": lights}
    g = R.random()
    if g < 0.15:
        doc["grid"] = {"capacity": R.choice([1, 2, 4])}
    elif g < 0.3:
        doc["grid"] = {"resolution": [R.randint(1, 80) for _ in range(3)]}
    with open(os.path.join(out, name + ".json"), "w") as f:
        json.dump(doc, f, indent=1)
    return name


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    out = sys.argv[1]
    count = int(sys.argv[2]) if len(sys.argv) > 2 else 20
    first = int(sys.argv[3]) if len(sys.argv) > 3 else 1
    os.makedirs(out, exist_ok=True)
    for s in range(first, first + count):
        print(scene(out, s))


if __name__ == "__main__":
    main()
