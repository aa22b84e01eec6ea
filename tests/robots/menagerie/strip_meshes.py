"""Mesh-free copies of MuJoCo Menagerie's robot models, for tests that must build offline.

    python3 tests/robots/menagerie/strip_meshes.py MENAGERIE/unitree_go1/go1.xml tests/robots/menagerie/unitree_go1

writes ``OUT/go1.xml`` and copies the model's ``LICENSE`` beside it. The copy is the published
file with these changes only (everything else, classes, defaults, joints, actuators, keyframes,
contact parameters, sites and comments, stays as written):

- a geom of type mesh that takes no part in contacts (contype and conaffinity 0, its own or its
  class's) is dropped;
- a geom of type mesh that collides is replaced by a primitive fitted to the mesh. Its shape comes
  from the mesh's bounding box in its principal frame (MuJoCo's ``geom_aabb``): where the box's
  two largest sides agree within 10 % (a ball or a disc, touching the ground at its rim) a
  sphere of the largest half side at the box's centre; where the longest side is 1.3 times the
  next a capsule, else a box, both as MuJoCo's compiler fits them to the mesh (its
  equivalent-inertia fit: a tapered link's capsule is not as thick as its thickest end). Its
  name, class and contact attributes stay; its position and orientation are written in its
  body's frame;
- the ``<mesh>`` assets, the ``mesh`` and ``type="mesh"`` of default geoms, the textures read
  from files and the materials' references to them are dropped.

The collision meshes must be present (their shapes are fitted); visual meshes and textures may be
missing. Needs only MuJoCo and the standard library.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path
from xml.parsers import expat
from xml.sax.saxutils import quoteattr

import mujoco
import numpy as np

BALL = 0.9  # the two largest half sizes agree within this ratio: a sphere
LONG = 1.3  # the largest half size is this times the next: a capsule
_PLACE = ("pos", "quat", "euler", "axisangle", "xyaxes", "zaxis", "fromto", "size", "type", "mesh", "fitscale")
_TEMP = "strip_meshes_geom_{}"


def _parse(path: Path) -> ET.ElementTree:
    return ET.parse(path, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))


def _defaults(root: ET.Element) -> tuple[dict[str, ET.Element], dict[str, str | None]]:
    """Every default class -> its element, and its parent class (None for 'main')."""
    by_name, parent = {}, {}

    def walk(el: ET.Element, up: str | None) -> None:
        name = el.get("class", "main" if up is None else None)
        if name is None:
            raise SystemExit(f"a nested <default> without a class in {root.get('model')}")
        by_name[name], parent[name] = el, up
        for child in el.findall("default"):
            walk(child, name)

    for top in root.findall("default"):
        walk(top, None)
    return by_name, parent


def _resolved(geom: ET.Element, cls: str, by_name: dict, parent: dict, attr: str) -> str | None:
    """The geom's attribute as MuJoCo reads it: its own, else its class's, up to 'main'."""
    if attr in geom.attrib:
        return geom.get(attr)
    c: str | None = cls
    while c is not None:
        for g in by_name.get(c, ET.Element("x")).findall("geom"):
            if attr in g.attrib:
                return g.get(attr)
        c = parent.get(c)
    return None


def _geoms(root: ET.Element) -> list[tuple[ET.Element, ET.Element, str]]:
    """(geom, its parent element, its class) for every geom of the world body, in file order."""
    out = []

    def walk(el: ET.Element, childclass: str) -> None:
        for child in list(el):
            if child.tag == "geom":
                out.append((child, el, child.get("class", childclass)))
            elif child.tag in ("body", "frame"):
                walk(child, child.get("childclass", childclass))

    for wb in root.findall("worldbody"):
        walk(wb, "main")
    return out


def _fits(src: Path, root: ET.Element, colliding: list[ET.Element]) -> dict[int, tuple[str, list, list, list]]:
    """Per colliding mesh geom (by position in ``colliding``): the primitive (type, size, pos,
    quat in its body's frame) fitted by MuJoCo's compiler to the mesh."""
    tmp_root = ET.fromstring(ET.tostring(root))
    names = {}
    # the same walk over the copy: mark the colliding mesh geoms, drop the visual ones and textures
    by_name, parent = _defaults(tmp_root)
    ids = {id(g): i for i, g in enumerate(colliding)}
    for (g, up, cls), (g0, _, _) in zip(_geoms(tmp_root), _geoms(root)):
        if id(g0) in ids:
            g.set("name", _TEMP.format(ids[id(g0)]))
            names[ids[id(g0)]] = _TEMP.format(ids[id(g0)])
        elif _resolved(g, cls, by_name, parent, "type") == "mesh":
            up.remove(g)
    used = {_resolved(g, cls, by_name, parent, "mesh") for g, _, cls in _geoms(tmp_root)}
    for asset in tmp_root.findall("asset"):
        for m in asset.findall("mesh"):  # the visual meshes' files need not be there
            if m.get("name", Path(m.get("file", "")).stem) not in used:
                asset.remove(m)
        for t in asset.findall("texture"):
            if "file" in t.attrib or any(a.startswith("file") for a in t.attrib):
                asset.remove(t)
        for m in asset.findall("material"):
            m.attrib.pop("texture", None)
    comp = tmp_root.find("compiler")
    if comp is None:
        comp = ET.SubElement(tmp_root, "compiler")
    meshdir = comp.get("meshdir", comp.get("assetdir", ""))
    comp.set("meshdir", str((src.parent / meshdir).resolve()))
    comp.attrib.pop("assetdir", None)
    comp.attrib.pop("texturedir", None)
    comp.set("fitaabb", "false")  # MuJoCo's equivalent-inertia fit (its default)
    marked = {name: g for g in tmp_root.iter("geom") if (name := g.get("name")) in names.values()}
    model = _compile(tmp_root, src.name)
    kinds, out = {}, {}
    for i, name in names.items():  # the shape, from the mesh's bounding box in its principal frame
        g = model.geom(name).id
        a, b, c = sorted(float(x) for x in model.geom_aabb[g, 3:])
        kinds[i] = "sphere" if b >= BALL * c else "capsule" if c >= LONG * b else "box"
        if kinds[i] == "sphere":  # a ball or a disc touches the ground at its rim: the box's largest half size
            centre = np.zeros(3)
            mujoco.mju_rotVecQuat(centre, model.geom_aabb[g, :3], model.geom_quat[g])
            out[i] = ("sphere", [c], list(model.geom_pos[g] + centre), [1.0, 0.0, 0.0, 0.0])
        marked[name].set("type", kinds[i])
        marked[name].attrib.pop("size", None)
    model = _compile(tmp_root, src.name)  # MuJoCo fits the capsules and boxes to their meshes
    for i, name in names.items():
        if kinds[i] != "sphere":
            g = model.geom(name).id
            n = {"capsule": 2, "box": 3}[kinds[i]]
            out[i] = (kinds[i], list(model.geom_size[g, :n]), list(model.geom_pos[g]), list(model.geom_quat[g]))
    return out


def _compile(root: ET.Element, name: str) -> mujoco.MjModel:
    with tempfile.TemporaryDirectory() as d:
        f = Path(d) / name
        f.write_text(ET.tostring(root, encoding="unicode"))
        return mujoco.MjModel.from_xml_path(str(f))


def _num(x: float) -> str:
    v = float(f"{x:.6g}")
    return "0" if v == 0 else f"{v:.6g}"


def _spans(data: bytes, root: ET.Element) -> dict[int, tuple[int, int]]:
    """Where each element's start tag lies in the file: id(element) -> (first, past last) byte
    (the whole element for the self-closing ones this script edits)."""
    starts = []
    p = expat.ParserCreate()
    p.StartElementHandler = lambda name, attrs: starts.append(p.CurrentByteIndex)
    p.Parse(data, True)
    elements = [el for el in root.iter() if isinstance(el.tag, str)]
    assert len(elements) == len(starts)
    return {id(el): (a, data.index(b">", a) + 1) for el, a in zip(elements, starts)}


def _tag(el: ET.Element, attrs: dict[str, str]) -> bytes:
    return (f"<{el.tag} " + " ".join(f"{k}={quoteattr(v)}" for k, v in attrs.items()) + "/>").encode()


def _edit(data: bytes, edits: list[tuple[int, int, bytes]]) -> bytes:
    """Apply (first, past last, replacement) edits; an element removed alone on its line takes
    its line with it."""
    for a, b, new in sorted(edits, reverse=True):
        if not new:
            line_a = data.rfind(b"\n", 0, a) + 1
            line_b = data.find(b"\n", b)
            if not data[line_a:a].strip() and not data[b:line_b].strip():
                a, b = line_a, line_b + 1
        data = data[:a] + new + data[b:]
    return data


def strip(src: Path, out_dir: Path) -> Path:
    """Write the mesh-free copy of ``src`` into ``out_dir`` (and its LICENSE); return its path."""
    data = src.read_bytes()
    root = _parse(src).getroot()
    spans = _spans(data, root)
    by_name, parent = _defaults(root)
    visual, colliding = [], []
    for g, _, cls in _geoms(root):
        if _resolved(g, cls, by_name, parent, "type") != "mesh":
            continue
        contype = int(_resolved(g, cls, by_name, parent, "contype") or 1)
        conaffinity = int(_resolved(g, cls, by_name, parent, "conaffinity") or 1)
        (colliding if contype or conaffinity else visual).append(g)
    fits = _fits(src, root, colliding)
    edits = [(*spans[id(g)], b"") for g in visual]
    for i, g in enumerate(colliding):
        kind, size, pos, quat = fits[i]
        keep = {k: v for k, v in g.attrib.items() if k not in _PLACE}
        attrs = {k: keep.pop(k) for k in ("name", "class") if k in keep}
        attrs.update(type=kind, size=" ".join(_num(x) for x in size), pos=" ".join(_num(x) for x in pos))
        if kind != "sphere":
            attrs["quat"] = " ".join(_num(x) for x in quat)
        edits.append((*spans[id(g)], _tag(g, attrs | keep)))
    for d in by_name.values():  # no default may name a mesh any more
        for g in d.findall("geom"):
            if "mesh" in g.attrib or g.get("type") == "mesh":
                attrs = {k: v for k, v in g.attrib.items() if k != "mesh" and (k, v) != ("type", "mesh")}
                edits.append((*spans[id(g)], _tag(g, attrs) if attrs else b""))
    dropped = set()
    for asset in root.findall("asset"):
        for el in asset:
            if el.tag == "mesh" or (el.tag == "texture" and any(a.startswith("file") for a in el.attrib)):
                if el.tag == "texture":
                    dropped.add(el.get("name") or Path(el.get("file", "")).stem)
                edits.append((*spans[id(el)], b""))
        for m in asset.findall("material"):
            if m.get("texture") in dropped:
                edits.append((*spans[id(m)], _tag(m, {k: v for k, v in m.attrib.items() if k != "texture"})))
    note = (f"<!-- A mesh-free copy of MuJoCo Menagerie's {src.parent.name}/{src.name}, made by\n"
            f"     tests/robots/menagerie/strip_meshes.py: visual meshes dropped, collision meshes replaced by\n"
            f"     fitted primitives, textures dropped; all else as published. Licence: LICENSE beside it. -->\n")
    out_dir.mkdir(parents=True, exist_ok=True)
    out = out_dir / src.name
    out.write_bytes(note.encode() + _edit(data, edits))
    lic = src.parent / "LICENSE"
    if lic.is_file():
        shutil.copyfile(lic, out_dir / "LICENSE")
    mujoco.MjModel.from_xml_path(str(out))  # the copy compiles with no files beside it
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", type=Path, help="a Menagerie model's MJCF, e.g. unitree_go1/go1.xml")
    ap.add_argument("out_dir", type=Path, help="folder of the copy (and its LICENSE)")
    args = ap.parse_args(argv)
    out = strip(args.model, args.out_dir)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
