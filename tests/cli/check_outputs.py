#!/usr/bin/env python3
"""Checks the files the hdeform CLI writes: GLB, sweep CSV, sweep SVG, run summary CSV.

  check_outputs.py glb FILE [VERTICES]
  check_outputs.py sweep-csv FILE BETA,BETA,...
  check_outputs.py svg FILE PANELS POINTS
  check_outputs.py summary FILE ITEMS
"""
import csv
import json
import math
import struct
import sys
import xml.etree.ElementTree as ET

SWEEP_HEADER = "beta,E,E_iso_N,E_conf_N,E_area_pct,max_e_iso,max_e_conf,max_ef2,flips"


def fail(msg):
    print("check_outputs: " + msg, file=sys.stderr)
    sys.exit(1)


def check_glb(path, vertices=None):
    data = open(path, "rb").read()
    if len(data) < 20:
        fail(f"{path}: too short for a GLB")
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    if magic != b"glTF" or version != 2:
        fail(f"{path}: not a glTF 2 binary (magic {magic!r}, version {version})")
    if length != len(data):
        fail(f"{path}: header length {length} != file size {len(data)}")
    clen, ctype = struct.unpack_from("<II", data, 12)
    if ctype != 0x4E4F534A:
        fail(f"{path}: first chunk is not JSON")
    doc = json.loads(data[20:20 + clen].decode("utf-8"))
    prim = doc["meshes"][0]["primitives"][0]
    pos = doc["accessors"][prim["attributes"]["POSITION"]]
    if pos["type"] != "VEC3" or pos["componentType"] != 5126:
        fail(f"{path}: POSITION is not float32 VEC3")
    if vertices is not None and pos["count"] != vertices:
        fail(f"{path}: {pos['count']} vertices, expected {vertices}")
    if "indices" not in prim or doc["accessors"][prim["indices"]]["count"] % 3:
        fail(f"{path}: no triangle indices")
    # the binary chunk holds the buffer
    off = 20 + clen
    blen, btype = struct.unpack_from("<II", data, off)
    if btype != 0x004E4942 or blen < doc["buffers"][0]["byteLength"]:
        fail(f"{path}: bad BIN chunk")
    bv = doc["bufferViews"][pos["bufferView"]]
    start = off + 8 + bv.get("byteOffset", 0) + pos.get("byteOffset", 0)
    xs = struct.unpack_from(f"<{3 * pos['count']}f", data, start)
    if not all(math.isfinite(x) for x in xs):
        fail(f"{path}: non-finite positions")
    print(f"{path}: GLB ok, {pos['count']} vertices")


def check_sweep_csv(path, betas):
    lines = open(path, newline="").read().splitlines()
    if not lines or lines[0] != SWEEP_HEADER:
        fail(f"{path}: header {lines[0] if lines else ''!r} != {SWEEP_HEADER!r}")
    rows = lines[1:]
    want = [float(b) for b in betas.split(",")]
    if len(rows) != len(want):
        fail(f"{path}: {len(rows)} rows, expected {len(want)}")
    for row, b in zip(rows, want):
        f = row.split(",")
        if len(f) != 9:
            fail(f"{path}: row {row!r} has {len(f)} fields")
        vals = [float(x) for x in f]
        if not all(math.isfinite(v) for v in vals):
            fail(f"{path}: non-finite value in {row!r}")
        if vals[0] != b:
            fail(f"{path}: beta {vals[0]} != {b}")
        if int(f[8]) != vals[8]:
            fail(f"{path}: flips {f[8]!r} is not an integer")
    print(f"{path}: CSV ok, {len(rows)} rows")


def check_svg(path, panels, points):
    root = ET.parse(path).getroot()
    ns = "{http://www.w3.org/2000/svg}"
    if root.tag != ns + "svg":
        fail(f"{path}: root element is {root.tag}")
    groups = [g for g in root.iter(ns + "g") if g.get("class") == "panel"]
    if len(groups) != panels:
        fail(f"{path}: {len(groups)} panels, expected {panels}")
    for g in groups:
        texts = [t.text for t in g.iter(ns + "text")]
        if len(texts) < 5:
            fail(f"{path}: panel {g.get('id')} has no tick labels")
        circles = list(g.iter(ns + "circle"))
        if len(circles) != points:
            fail(f"{path}: panel {g.get('id')} has {len(circles)} points, expected {points}")
        if points > 1 and not list(g.iter(ns + "polyline")):
            fail(f"{path}: panel {g.get('id')} has no line")
    print(f"{path}: SVG ok, {len(groups)} panels")


def check_summary(path, items):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if len(rows) != items:
        fail(f"{path}: {len(rows)} rows, expected {items}")
    for r in rows:
        if r["status"] != "ok":
            fail(f"{path}: item {r['mesh']} {r['constraints']} {r['transform']} failed: {r['status']}")
        float(r["E"])
        if r["output"]:
            check_glb(r["output"])
    print(f"{path}: summary ok, {len(rows)} items")


def main():
    kind, path = sys.argv[1], sys.argv[2]
    if kind == "glb":
        check_glb(path, int(sys.argv[3]) if len(sys.argv) > 3 else None)
    elif kind == "sweep-csv":
        check_sweep_csv(path, sys.argv[3])
    elif kind == "svg":
        check_svg(path, int(sys.argv[3]), int(sys.argv[4]))
    elif kind == "summary":
        check_summary(path, int(sys.argv[3]))
    else:
        fail("unknown check " + kind)


if __name__ == "__main__":
    main()
