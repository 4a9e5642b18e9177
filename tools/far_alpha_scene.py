#!/usr/bin/env python3
"""Twelve alpha-keyed quads (a 32x32 checkerboard mask) in front of a wall, as a scene at the
origin (near.json) and the same scene moved to (1e5, -2e4, 7e4) (far.json), for comparing the
grid's alpha keying with Embree's far from the origin (docs/ACCURACY.md, "Alpha keying far from
the origin"):

  python3 tools/far_alpha_scene.py OUT_DIR
  for b in cpu embree; do gridrt render OUT_DIR/far.json -b $b --no-bounce --shadows off \\
      --width 192 --height 108 -o OUT_DIR/far-$b.pfm; done

The placement is random with a fixed seed; nothing in data/ is like it and nothing is tuned on it.
"""
import json
import os
import random
import struct
import sys
import zlib


def png_rgba(path, w, h, pixel):
    raw = b"".join(b"\x00" + b"".join(bytes(pixel(x, y)) for x in range(w)) for y in range(h))

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 6, 0, 0, 0)) +
                chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def scene(offset):
    rng = random.Random(5)
    instances = [{"name": "wall", "mesh": "wall", "translate": offset}]
    for i in range(12):
        degrees = rng.uniform(0, 360)
        instances.append({
            "name": "leaf%d" % i, "mesh": "leaf",
            "translate": [offset[0] + rng.uniform(-4, 3), offset[1] + rng.uniform(-3, 2), offset[2] + rng.uniform(-1, 1)],
            "rotate": {"axis": [rng.uniform(-1, 1), rng.uniform(-1, 1), 1], "degrees": degrees},
            "scale": rng.uniform(0.5, 2.0)})
    return {"name": "far-alpha", "meshes": {"leaf": {"file": "leaf.obj"}, "wall": {"file": "wall.obj"}},
            "instances": instances,
            "camera": {"eye": [offset[0], offset[1], offset[2] + 9], "target": offset, "up": [0, 1, 0], "vfov": 50}}


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: far_alpha_scene.py OUT_DIR")
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    png_rgba(os.path.join(out, "mask.png"), 32, 32, lambda x, y: (200, 120, 60, 255 if (x + y) % 2 == 0 else 0))
    with open(os.path.join(out, "leaf.mtl"), "w") as f:
        f.write("newmtl leaf\nKd 0.8 0.5 0.3\nmap_Kd mask.png\nmap_d mask.png\n")
    with open(os.path.join(out, "leaf.obj"), "w") as f:
        f.write("mtllib leaf.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
                "usemtl leaf\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    with open(os.path.join(out, "wall.obj"), "w") as f:
        f.write("v -20 -20 -3\nv 20 -20 -3\nv 20 20 -3\nv -20 20 -3\nf 1 2 3\nf 1 3 4\n")
    for name, offset in (("near.json", [0, 0, 0]), ("far.json", [1e5, -2e4, 7e4])):
        with open(os.path.join(out, name), "w") as f:
            json.dump(scene(offset), f, indent=1)


if __name__ == "__main__":
    main()
