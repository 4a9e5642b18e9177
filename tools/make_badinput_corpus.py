#!/usr/bin/env python3
"""Writes the regression corpus of malformed inputs: tests/corpus/<kind>/.

Names say what the replay driver (tests/fuzz/replay.cpp) expects:
  bad_*  must give a clean Error (exit 1 from the tool),
  ok_*   must load,
  other  (fuzzer finds, random corruption): a clean Error or a load, never a crash.
Run: python3 tools/make_badinput_corpus.py [OUT]   (OUT: tests/corpus by default)
(it writes its cases over their files and keeps the corpus's other files, made by hand).
"""
import argparse
import base64
import json
import os
import random
import struct
import zlib

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "corpus")


def out(kind, name, data):
    d = os.path.join(ROOT, kind)
    os.makedirs(d, exist_ok=True)
    mode = "wb" if isinstance(data, bytes) else "w"
    with open(os.path.join(d, name), mode, newline="" if mode == "w" else None) as f:
        f.write(data)


TRI_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def png(width, height, rows=None):
    """A PNG whose header says width x height; its data is one tiny (wrong-sized) image."""
    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xFFFFFFFF)
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    raw = rows if rows is not None else b"\x00" + b"\xff" * 4
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


def obj_cases():
    out("obj", "ok_triangle.obj", TRI_OBJ)
    out("obj", "ok_bom.obj", "\ufeff" + TRI_OBJ)
    out("obj", "ok_crlf.obj", TRI_OBJ.replace("\n", "\r\n"))
    out("obj", "ok_bare_cr.obj", TRI_OBJ.replace("\n", "\r"))
    # A bare CR hides a line from a checker that splits at LF only.
    out("obj", "bad_bare_cr_hidden_nan.obj", "v 0 0 0\rv nan nan nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    out("obj", "bad_bare_cr_hidden_index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\rf 1 2 9\nf 1 2 3\n")
    n = 2000
    out("obj", "bad_face_2000_vertices.obj",
        "".join(f"v {i % 7} {i % 5} {i % 3}\n" for i in range(n)) + "f " + " ".join(str(i + 1) for i in range(n)) + "\n")
    out("obj", "bad_vn_nan.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn nan 0 1\nf 1//1 2//1 3//1\n")
    out("obj", "bad_vt_inf.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt inf 0\nf 1/1 2/1 3/1\n")
    out("obj", "bad_index_zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")
    out("obj", "bad_all_one_point.obj", "v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n")
    out("obj", "bad_huge_coordinates.obj", "v -3e38 0 0\nv 3e38 0 0\nv 0 3e38 0\nf 1 2 3\n")
    out("obj", "bad_mtllib_directory.obj", "mtllib .\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    for name, mtl in [("dev_zero", "newmtl m\nmap_Kd /dev/zero\n"),
                      ("negative_opacity", "newmtl m\nd -0.5\n"),
                      ("negative_colour", "newmtl m\nKd -1 0.5 0.5\n"),
                      ("nan_colour", "newmtl m\nKd nan 0.5 0.5\n"),
                      ("huge_png", "newmtl m\nmap_Kd huge_1e6.png\n"),
                      ("png_65535", "newmtl m\nmap_Kd huge_65535.png\n"),
                      ("texture_directory", "newmtl m\nmap_Kd .\n")]:
        out("obj", f"bad_{name}.mtl", mtl)
        out("obj", f"bad_{name}.obj", f"mtllib bad_{name}.mtl\nusemtl m\n" + TRI_OBJ)
    out("obj", "huge_1e6.png", png(1000000, 1000000))
    out("obj", "huge_65535.png", png(65535, 65535))


def gltf_doc(positions=None, indices=None, extra=None, normals=None):
    """A one-triangle glTF with an embedded buffer; `extra` patches the document."""
    pos = positions if positions is not None else [0, 0, 0, 1, 0, 0, 0, 1, 0]
    idx = indices if indices is not None else [0, 1, 2]
    data = struct.pack(f"<{len(pos)}f", *pos) + struct.pack(f"<{len(idx)}H", *idx)
    if len(data) % 4:
        data += b"\0" * (4 - len(data) % 4)
    nrm = b""
    if normals is not None:
        nrm = struct.pack(f"<{len(normals)}f", *normals)
    doc = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(data) + len(nrm),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(data + nrm).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(pos) * 4},
                        {"buffer": 0, "byteOffset": len(pos) * 4, "byteLength": len(idx) * 2}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(pos) // 3, "type": "VEC3"},
                      {"bufferView": 1, "componentType": 5123, "count": len(idx), "type": "SCALAR"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "nodes": [{"mesh": 0}],
        "scenes": [{"nodes": [0]}],
        "scene": 0,
    }
    if normals is not None:
        doc["bufferViews"].append({"buffer": 0, "byteOffset": len(data), "byteLength": len(nrm)})
        doc["accessors"].append({"bufferView": 2, "componentType": 5126, "count": len(normals) // 3, "type": "VEC3"})
        doc["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = 2
    if extra:
        extra(doc)
    return doc


def glb(doc, binary=b""):
    j = json.dumps(doc).encode()
    j += b" " * ((4 - len(j) % 4) % 4)
    body = struct.pack("<I4s", len(j), b"JSON") + j
    if binary:
        binary += b"\0" * ((4 - len(binary) % 4) % 4)
        body += struct.pack("<I4s", len(binary), b"BIN\0") + binary
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def gltf_cases():
    def w(name, doc):
        out("gltf", name, json.dumps(doc))
    w("ok_triangle.gltf", gltf_doc())
    out("gltf", "ok_bom.gltf", "\ufeff" + json.dumps(gltf_doc()))
    w("bad_indices_count_2e63.gltf", gltf_doc(extra=lambda d: d["accessors"][1].update(count=9223372036854775000)))
    # Counts whose byte span wraps to a few bytes in 64-bit arithmetic: 2 * 2^63 and 4 * 2^62.
    w("bad_indices_count_wraps.gltf", gltf_doc(extra=lambda d: d["accessors"][1].update(count=2**63 + 1)))
    w("bad_indices_u32_count_wraps.gltf", gltf_doc(extra=lambda d: (
        d["accessors"][1].update(count=2**62 + 1, componentType=5125),
        d["bufferViews"][1].update(byteLength=4))))
    w("bad_position_count_2e62.gltf", gltf_doc(extra=lambda d: d["accessors"][0].update(count=4611686018427387904)))
    w("bad_view_offset_huge.gltf", gltf_doc(extra=lambda d: d["bufferViews"][0].update(byteOffset=18446744073709551000)))
    w("bad_accessor_offset_huge.gltf", gltf_doc(extra=lambda d: d["accessors"][0].update(byteOffset=18446744073709551000)))
    w("bad_byte_stride_small.gltf", gltf_doc(extra=lambda d: d["bufferViews"][0].update(byteStride=4)))

    doc = json.dumps(gltf_doc())
    out("gltf", "bad_extras_30000_deep.gltf", doc[:-1] + ', "extras": ' + "[" * 30000 + "]" * 30000 + "}")
    w("bad_buffer_uri_directory.gltf", gltf_doc(extra=lambda d: d["buffers"][0].update(uri=".")))
    w("bad_buffer_uri_dev_zero.gltf", gltf_doc(extra=lambda d: d["buffers"][0].update(uri="/dev/zero")))

    def chain(d, n=2000):
        d["nodes"] = [{"children": [i + 1]} for i in range(n - 1)] + [{"mesh": 0}]
    w("bad_node_chain_2000.gltf", gltf_doc(extra=chain))
    w("bad_node_cycle.gltf", gltf_doc(extra=lambda d: d.update(nodes=[{"mesh": 0, "children": [1]}, {"children": [0]}])))
    w("bad_nan_normal.gltf", gltf_doc(normals=[float("nan"), 0, 1, 0, 0, 1, 0, 0, 1]))
    w("bad_nan_position.gltf", gltf_doc(positions=[0, 0, 0, float("inf"), 0, 0, 0, 1, 0]))
    w("bad_negative_opacity.gltf", gltf_doc(extra=lambda d: (
        d.update(materials=[{"pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, -0.5]}}]),
        d["meshes"][0]["primitives"][0].update(material=0))))

    def huge_image(d):
        d["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(png(1000000, 1000000)).decode()}]
        d["textures"] = [{"source": 0}]
        d["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
        d["meshes"][0]["primitives"][0]["material"] = 0
    w("bad_png_1e6.gltf", gltf_doc(extra=huge_image))
    # "scene" naming a scene the file does not have; a rotation far from a unit quaternion (one
    # within 1e-3 is an exporter's rounding: normalized); a model translated past the domain
    w("bad_scene_out_of_range.gltf", gltf_doc(extra=lambda d: d.update(scene=7)))
    w("bad_rotation_not_unit.gltf", gltf_doc(extra=lambda d: d["nodes"][0].update(rotation=[0, 0, 10, 0])))
    w("ok_rotation_nearly_unit.gltf", gltf_doc(extra=lambda d: d["nodes"][0].update(rotation=[0, 0, 0.7074, 0.7074])))
    w("bad_translation_1e38.gltf", gltf_doc(extra=lambda d: d["nodes"][0].update(translation=[1e38, 0, 0])))
    out("gltf", "bad_integer_400_digits.gltf", json.dumps(gltf_doc())[:-1] + ', "extras": ' + "9" * 400 + "}")
    # GLB: the same document with the buffer in the BIN chunk.
    d = gltf_doc()
    raw = base64.b64decode(d["buffers"][0]["uri"].split(",")[1])
    del d["buffers"][0]["uri"]
    out("gltf", "ok_triangle.glb", glb(d, raw))
    d2 = json.loads(json.dumps(d))
    d2["accessors"][1]["count"] = 9223372036854775000
    out("gltf", "bad_count_2e63.glb", glb(d2, raw))
    j = json.dumps(d)
    deep_doc = j[:-1] + ', "extras": ' + "{\"a\":" * 20000 + "1" + "}" * 20000 + "}"
    body = deep_doc.encode()
    body += b" " * ((4 - len(body) % 4) % 4)
    out("gltf", "bad_deep_json.glb", struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(body)) +
        struct.pack("<I4s", len(body), b"JSON") + body)
    out("gltf", "bad_truncated.glb", glb(d, raw)[:40])


SCENE = {"meshes": {"tri": {"file": "../obj/ok_triangle.obj"}}, "instances": [{"mesh": "tri"}]}


def json_cases():
    def w(name, patch):
        doc = json.loads(json.dumps(SCENE))
        patch(doc)
        out("json", name, json.dumps(doc, indent=1))
    w("ok_scene.json", lambda d: None)
    out("json", "ok_bom.json", "\ufeff" + json.dumps(SCENE))
    out("json", "bad_30000_deep.json", "[" * 30000 + "]" * 30000)
    out("json", "bad_nul_then_garbage.json", json.dumps(SCENE) + "\0garbage")
    out("json", "bad_integer_400_digits.json", '{"name": ' + "9" * 400 + "}")
    w("bad_zero_light_direction.json", lambda d: d.update(lights=[{"direction": [0, 0, 0]}]))
    w("bad_negative_intensity.json", lambda d: d.update(lights=[{"position": [0, 5, 0], "intensity": -1}]))
    w("bad_negative_colour.json", lambda d: d.update(lights=[{"position": [0, 5, 0], "color": [1, -1, 1]}]))
    w("bad_tiny_period.json", lambda d: d["instances"][0].update(
        motion={"path": {"points": [[0, 0, 0], [1, 0, 0]], "period": 1e-45}}))
    w("bad_huge_speed.json", lambda d: d["instances"][0].update(motion={"rotate": {"speed": 1e30}}))
    w("bad_negative_opacity.json", lambda d: d.update(materials={"overrides": {"default": {"opacity": -1}}}))
    w("bad_mesh_is_directory.json", lambda d: d["meshes"]["tri"].update(file="../obj"))
    w("bad_mesh_file_directory_obj.json", lambda d: d["meshes"]["tri"].update(file="dir.obj"))
    os.makedirs(os.path.join(ROOT, "json", "dir.obj"), exist_ok=True)
    with open(os.path.join(ROOT, "json", "dir.obj", "README"), "w") as f:
        f.write("A folder named like a model: loading it must say it is a directory.\n")


class Cache:
    """Writes the .gridscene format (common/scene_io.cpp) field by field."""

    def __init__(self):
        self.b = bytearray(b"GRIDSCN\0") + struct.pack("<I", 1)

    def str(self, s):
        self.b += struct.pack("<Q", len(s)) + s.encode()

    def pod(self, fmt, *v):
        self.b += struct.pack("<" + fmt, *v)

    def vec(self, fmt, items):
        self.b += struct.pack("<Q", len(items))
        for it in items:
            self.b += struct.pack("<" + fmt, *it)


def cache(tex=None, normal=None, uv=None, opacity=1.0, light=None, period=1.0, path=None, camera=None):
    c = Cache()
    c.str("corpus")
    c.pod("3f", 0.5, 0.6, 0.7)
    c.pod("Q", 1)
    c.str("tri")
    c.vec("3f", [(0, 0, 0), (1, 0, 0), (0, 1, 0)])
    c.vec("3f", [normal or (0, 0, 1)] * 3 if normal else [])
    c.vec("2f", [uv] * 3 if uv else [])
    c.vec("3I", [(0, 1, 2)])
    c.vec("I", [(0,)])
    c.pod("Q", 1)
    c.str("m")
    c.pod("3f", 0.8, 0.8, 0.8)
    c.pod("ii", 0 if tex else -1, -1)
    c.pod("ff", 0.0, opacity)
    if tex:
        w, h, texels = tex
        c.pod("Q", 1)
        c.str("t")
        c.pod("IIB", w, h, 0)
        c.vec("B", [(x,) for x in texels])
    else:
        c.pod("Q", 0)
    c.pod("Q", 1)
    c.str("i")
    c.pod("I", 0)
    c.pod("16f", *[1 if r == k else 0 for r in range(4) for k in range(4)])
    c.pod("B", 1 if path else 0)
    c.pod("3f", 0, 1, 0)
    c.pod("3f", 0, 0, 0)
    c.pod("f", 0)
    c.vec("3f", path or [])
    c.pod("f", period)
    if camera:
        c.pod("B", 1)
        c.pod("3f3f3ff", *camera)
    else:
        c.pod("B", 0)
    lights = [light] if light else []
    c.pod("Q", len(lights))
    for pos, col, inten, directional in lights:
        c.pod("3f3ffB", *pos, *col, inten, directional)
    c.pod("B3I", 0, 0, 0, 0)
    c.pod("BI", 0, 0)
    c.pod("Bf", 0, 0)
    c.b += b"ENDSCN\0\0"
    return bytes(c.b)


def gridscene_cases():
    nan = float("nan")
    out("gridscene", "ok_triangle.gridscene", cache())
    out("gridscene", "ok_texture.gridscene", cache(tex=(2, 1, [255] * 8)))
    out("gridscene", "bad_texture_2e31.gridscene", cache(tex=(1 << 31, 1 << 31, [])))
    out("gridscene", "bad_texture_5x0.gridscene", cache(tex=(5, 0, [])))
    out("gridscene", "bad_texture_0x0.gridscene", cache(tex=(0, 0, [])))
    out("gridscene", "bad_nan_normal.gridscene", cache(normal=(nan, 0, 1)))
    out("gridscene", "bad_nan_uv.gridscene", cache(uv=(nan, 0)))
    out("gridscene", "bad_negative_opacity.gridscene", cache(opacity=-1.0))
    out("gridscene", "bad_zero_light_direction.gridscene", cache(light=((0, 0, 0), (1, 1, 1), 1.0, 1)))
    out("gridscene", "bad_negative_intensity.gridscene", cache(light=((0, 5, 0), (1, 1, 1), -2.0, 0)))
    out("gridscene", "bad_tiny_period.gridscene", cache(path=[(0, 0, 0), (1, 0, 0)], period=1e-45))
    out("gridscene", "bad_camera_nan.gridscene", cache(camera=(nan, 0, 5, 0, 0, 0, 0, 1, 0, 60)))
    # Random corruption of a valid cache: truncations and byte flips (seeded, reproducible).
    base = cache(tex=(2, 2, [200] * 16), light=((0, 5, 0), (1, 1, 1), 1.0, 0))
    rng = random.Random(16)
    for i in range(24):
        b = bytearray(base)
        if i < 8:
            b = b[:rng.randrange(len(b))]
        else:
            for _ in range(1 + i % 4):
                b[rng.randrange(len(b))] = rng.randrange(256)
        out("gridscene", f"mutated_{i:02d}.gridscene", bytes(b))


def map_cases():
    out("map", "ok_small.map", "size 3 3 1\nmap\n111\n1E1\n111\n")
    out("map", "ok_bom_crlf.map", "\ufeffsize 3 3 1\r\nmap\r\n111\r\n1E1\r\n111\r\n")
    rows = ["1" * 255] + ["1" + "".join("1" if (x * 7 + z * 3) % 5 == 0 else "." for x in range(253)) + "1"
                          for z in range(253)] + ["1" * 255]
    rows[1] = "1E" + rows[1][2:]
    out("map", "ok_255x255x253.map", "size 255 255 253\nmap\n" + "\n".join(rows) + "\n")
    out("map", "bad_size_overflow.map", "size 99999999999999999999 1 1\nmap\n1\n")
    out("map", "bad_nan_colour.map", "size 3 3 1\nmaterial X red nan 0 0\nmap\n111\n1E1\n111\n")
    out("map", "bad_ior_inf.map", "size 3 3 1\nmaterial X glass 1 1 1 glass inf\nmap\n111\n1E1\n111\n")
    out("map", "bad_nul_in_row.map", "size 3 3 1\nmap\n111\n1E\x001\n111\n")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", nargs="?", default=ROOT,
                        help="the corpus folder (default: this checkout's tests/corpus)")
    ROOT = parser.parse_args().out
    # Each case's file is written over; the corpus's other files (cases made by hand: the
    # bad_requires_*.gltf from a real model, the block maps) are kept, not removed
    obj_cases()
    gltf_cases()
    json_cases()
    gridscene_cases()
    map_cases()
    total = sum(len(f) for _, _, f in os.walk(ROOT))
    print(f"wrote {total} files under {os.path.normpath(ROOT)}")
