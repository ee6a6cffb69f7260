"""Write the third-party-style test scenes of docs/trace.md ("glassbake vs Mitsuba 3 on glTF
files written elsewhere"): plain glTF 2.0 files as an exporter would write them, with
KHR_materials_transmission / _ior / _volume / _specular, plus a glassbake manifest each
(camera range and a rectangle light: glTF has no area lights).

    python3 tools/mitsuba-compare/make_scenes.py OUT_DIR

Scenes (each OUT_DIR/NAME/manifest.toml):
  lambertian-box      Cornell-style box, every wall KHR_materials_specular specularFactor 0
                      (Lambertian), a thin-walled glass pane (transmission without volume)
  default-box         the same box without KHR_materials_specular: glTF's default opaque
                      material (a 4% dielectric specular layer over the diffuse base)
  transmission-test   after Khronos' TransmissionTest idea: a Lambertian floor and back wall,
                      a row of solid glass spheres (KHR_materials_volume) with IOR 1.5 and
                      1.33 and a thin-walled sphere, and a tinted thin pane
Only the Python standard library is used: the geometry is generated, not downloaded.
"""
import json
import math
import os
import struct
import sys


class Builder:
    """Accumulates meshes into one binary buffer and one glTF document."""

    def __init__(self):
        self.bin = bytearray()
        self.doc = {
            "asset": {"version": "2.0", "generator": "glassbake tools/mitsuba-compare/make_scenes.py"},
            "scene": 0,
            "scenes": [{"nodes": []}],
            "nodes": [],
            "meshes": [],
            "materials": [],
            "accessors": [],
            "bufferViews": [],
            "buffers": [],
            "extensionsUsed": [],
        }

    def _view(self, data, target):
        while len(self.bin) % 4:
            self.bin.append(0)
        offset = len(self.bin)
        self.bin.extend(data)
        self.doc["bufferViews"].append({"buffer": 0, "byteOffset": offset, "byteLength": len(data), "target": target})
        return len(self.doc["bufferViews"]) - 1

    def _accessor(self, values, kind, component, count, target, minmax=False):
        fmt = "<" + ("f" if component == 5126 else "I") * len(values)
        view = self._view(struct.pack(fmt, *values), target)
        acc = {"bufferView": view, "componentType": component, "count": count, "type": kind}
        if minmax:
            xs, ys, zs = values[0::3], values[1::3], values[2::3]
            acc["min"] = [min(xs), min(ys), min(zs)]
            acc["max"] = [max(xs), max(ys), max(zs)]
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def material(self, name, color, roughness=1.0, specular=None, transmission=None, ior=None, volume=False):
        m = {"name": name, "pbrMetallicRoughness": {"baseColorFactor": list(color) + [1.0], "metallicFactor": 0.0, "roughnessFactor": roughness}}
        ext = {}
        if specular is not None:
            ext["KHR_materials_specular"] = {"specularFactor": specular}
        if transmission is not None:
            ext["KHR_materials_transmission"] = {"transmissionFactor": transmission}
        if ior is not None:
            ext["KHR_materials_ior"] = {"ior": ior}
        if volume:
            ext["KHR_materials_volume"] = {"thicknessFactor": 1.0}
        if ext:
            m["extensions"] = ext
            for k in ext:
                if k not in self.doc["extensionsUsed"]:
                    self.doc["extensionsUsed"].append(k)
        self.doc["materials"].append(m)
        return len(self.doc["materials"]) - 1

    def mesh(self, name, positions, normals, indices, material, translation=(0.0, 0.0, 0.0)):
        pos = self._accessor([c for p in positions for c in p], "VEC3", 5126, len(positions), 34962, minmax=True)
        nrm = self._accessor([c for n in normals for c in n], "VEC3", 5126, len(normals), 34962)
        idx = self._accessor([i for t in indices for i in t], "SCALAR", 5125, 3 * len(indices), 34963)
        self.doc["meshes"].append({"name": name, "primitives": [{"attributes": {"POSITION": pos, "NORMAL": nrm}, "indices": idx, "material": material}]})
        self.doc["nodes"].append({"name": name, "mesh": len(self.doc["meshes"]) - 1, "translation": list(translation)})
        self.doc["scenes"][0]["nodes"].append(len(self.doc["nodes"]) - 1)

    def write(self, directory):
        os.makedirs(directory, exist_ok=True)
        self.doc["buffers"] = [{"uri": "scene.bin", "byteLength": len(self.bin)}]
        with open(os.path.join(directory, "scene.bin"), "wb") as f:
            f.write(self.bin)
        with open(os.path.join(directory, "scene.gltf"), "w") as f:
            json.dump(self.doc, f, indent=1)


def quad(corner, u, v):
    """A parallelogram facing u x v, two triangles."""
    n = cross(u, v)
    length = math.sqrt(sum(c * c for c in n))
    n = tuple(c / length for c in n)
    p = [corner, add(corner, u), add(add(corner, u), v), add(corner, v)]
    return p, [n] * 4, [(0, 1, 2), (0, 2, 3)]


def sphere(radius, rings=32, segments=64):
    positions, normals, indices = [], [], []
    for i in range(rings + 1):
        theta = math.pi * i / rings
        for j in range(segments + 1):
            phi = 2 * math.pi * j / segments
            n = (math.sin(theta) * math.cos(phi), math.cos(theta), math.sin(theta) * math.sin(phi))
            normals.append(n)
            positions.append(tuple(radius * c for c in n))
    for i in range(rings):
        for j in range(segments):
            a, b = i * (segments + 1) + j, (i + 1) * (segments + 1) + j
            # Counter-clockwise seen from outside.
            if i != 0:
                indices.append((a, a + 1, b))
            if i != rings - 1:
                indices.append((a + 1, b + 1, b))
    return positions, normals, indices


def add(a, b):
    return tuple(x + y for x, y in zip(a, b))


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


MANIFEST = """name = "{name}"
geometry = "scene.gltf"
background = [0.0, 0.0, 0.0]

[camera]
target = {target}
fov_x_deg = 45.0
near = 0.05
far = 50.0
position = {{ kind = "box", min = {position}, max = {position} }}

[[lights]]
name = "ceiling"
corner = {light_corner}
edge_u = [0.6, 0.0, 0.0]
edge_v = [0.0, 0.0, 0.6]
radiance = [12.0, 12.0, 12.0]
"""


def box(out, scene_name, specular):
    b = Builder()
    white = b.material("white", (0.75, 0.75, 0.75), specular=specular)
    red = b.material("red", (0.65, 0.06, 0.05), specular=specular)
    green = b.material("green", (0.12, 0.45, 0.15), specular=specular)
    pane = b.material("pane", (0.95, 0.97, 1.0), roughness=0.0, transmission=1.0, ior=1.5)
    s = 2.0
    for name, (c, u, v), m in [
        ("floor", (( -1, 0, 1), (2, 0, 0), (0, 0, -2)), white),
        ("ceiling", ((-1, s, -1), (2, 0, 0), (0, 0, 2)), white),
        ("back", ((-1, 0, -1), (2, 0, 0), (0, s, 0)), white),
        ("left", ((-1, 0, 1), (0, 0, -2), (0, s, 0)), red),
        ("right", ((1, 0, -1), (0, 0, 2), (0, s, 0)), green),
    ]:
        p, n, i = quad(c, u, v)
        # Walls face into the box: flip where u x v points out.
        center = tuple(ci + 0.5 * (ui + vi) for ci, ui, vi in zip(c, u, v))
        if sum(nc * (0 - cc) for nc, cc in zip(n[0], (center[0], center[1] - 1.0, center[2]))) < 0:
            p, n, i = quad(c, v, u)
        b.mesh(name, p, n, i, m)
    p, n, i = quad((-0.5, 0.0, 0.2), (0.0, 1.2, 0.0), (0.9, 0.0, -0.6))
    b.mesh("pane", p, n, i, pane)
    bx, by, bz = sphere(0.25, 16, 32)
    b.mesh("ball", bx, by, bz, white, translation=(0.45, 0.25, -0.45))
    d = os.path.join(out, scene_name)
    b.write(d)
    with open(os.path.join(d, "manifest.toml"), "w") as f:
        f.write(MANIFEST.format(name=scene_name, target="[0.0, 0.9, 0.0]", position="[0.0, 1.0, 3.4]", light_corner="[-0.3, 1.99, -0.3]"))


def transmission_test(out):
    b = Builder()
    floor = b.material("floor", (0.6, 0.6, 0.55), specular=0.0)
    back = b.material("back", (0.2, 0.3, 0.6), specular=0.0)
    glass15 = b.material("glass_ior_1.5", (1.0, 1.0, 1.0), roughness=0.0, transmission=1.0, ior=1.5, volume=True)
    glass133 = b.material("glass_ior_1.33", (0.9, 1.0, 0.95), roughness=0.0, transmission=1.0, ior=1.33, volume=True)
    thin = b.material("thin_sphere", (1.0, 0.9, 0.8), roughness=0.0, transmission=1.0, ior=1.5)
    tinted = b.material("tinted_pane", (0.9, 0.5, 0.3), roughness=0.0, transmission=1.0, ior=1.5)
    p, n, i = quad((-3, 0, 3), (6, 0, 0), (0, 0, -6))
    b.mesh("floor", p, n, i, floor)
    p, n, i = quad((-3, 0, -1.5), (6, 0, 0), (0, 4, 0))
    b.mesh("back", p, n, i, back)
    for k, (m, x) in enumerate([(glass15, -1.1), (glass133, 0.0), (thin, 1.1)]):
        sp, sn, si = sphere(0.45)
        b.mesh(f"sphere{k}", sp, sn, si, m, translation=(x, 0.45, 0.0))
    p, n, i = quad((-1.6, 0.0, 0.9), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    b.mesh("pane", p, n, i, tinted)
    d = os.path.join(out, "transmission-test")
    b.write(d)
    with open(os.path.join(d, "manifest.toml"), "w") as f:
        f.write(MANIFEST.format(name="transmission-test", target="[0.0, 0.5, 0.0]", position="[0.0, 1.6, 4.0]", light_corner="[-0.3, 3.0, 0.2]"))


def main():
    if len(sys.argv) != 2:
        print(__doc__)
        return 2
    box(sys.argv[1], "lambertian-box", specular=0.0)
    box(sys.argv[1], "default-box", specular=None)
    transmission_test(sys.argv[1])
    return 0


if __name__ == "__main__":
    sys.exit(main())
