#!/usr/bin/env python3
"""The pictures and numbers of docs/rig.md: the exact deformation against the rig's linear
blend skinning (LBS) on the Botsch–Sorkine cactus and bar at a few poses.

For each mesh: its benchmark constraints (.sel), β = 0 (a new session's default), and the
.def transform at 1/3, 2/3 and full strength (the rotation's angle scaled about its axis, the
translation scaled, both about the handle's centroid; the .def's polar stretch, within 6e-7 of
the identity, left out). At each pose: the exact solve (Session.update) and the rig
(Session.export_rig); the LBS surface is computed here from the GLB file alone (positions,
JOINTS/WEIGHTS, the skin's inverse bind matrices and the joint nodes' TRS), checked against
the distances the server reports, and drawn coloured by each vertex's distance to the exact
surface. Then the file size of the rig's skeletal animation against the morph-target
animation (Session.export_animation, 30 fps) of the same 2-second timeline.

  PYTHONPATH=build/tests/python/stubs:client-python /usr/bin/python3 scripts/rig_pictures.py

Writes docs/images/rig/{cactus,bar}.png (--out DIR elsewhere) and prints markdown tables.
Needs matplotlib (python3-matplotlib) and a built hdeform-server (hdeform.connect()).
"""
import argparse
import json
import os
import struct
import sys
import time

import numpy as np

import hdeform

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
BENCH = os.path.join(ROOT, "data", "botsch-sorkine")
STRENGTHS = (1 / 3, 2 / 3, 1.0)
STRENGTH_NAMES = ("1/3", "2/3", "full")
# mesh, up axis (both are z-up: see their bounding boxes), view azimuth/elevation in degrees
MESHES = (("cactus", "z", 20.0, 12.0), ("bar", "z", 35.0, 12.0))
AGREE = 1e-6  # the LBS computed here vs the server's report, in units of the diagonal


# --- the .def pose, and a fraction of it -----------------------------------------------------
def def_motion(s, name):
    """(axis, degrees, translation) of the .def transform about the handle's centroid."""
    M = hdeform.read_def(os.path.join(BENCH, name + ".def"))
    U, S, Vt = np.linalg.svd(M[:3, :3])
    if np.abs(S - 1).max() > 1e-6:
        raise SystemExit(f"{name}.def: not a rotation (singular values {S})")
    R = U @ Vt
    p = s.pivots[0]
    t = M[:3, :3] @ p + M[:3, 3] - p  # x' = M x + c = p + R (x − p) + t
    q = hdeform.Transform(rotate=R).to_proto().rotation  # the package's unit quaternion
    w, v = q.w, np.array([q.x, q.y, q.z])
    angle = 2 * np.degrees(np.arctan2(np.linalg.norm(v), w))
    axis = v / np.linalg.norm(v) if np.linalg.norm(v) > 0 else np.array([0.0, 0.0, 1.0])
    return axis, angle, t


def pose(motion, strength):
    axis, angle, t = motion
    return hdeform.transform(rotate=hdeform.axis_angle(axis, strength * angle),
                             translate=strength * t)


# --- LBS from the GLB file ----------------------------------------------------------------------
_DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32,
           5126: np.float32}
_SIZES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def parse_glb(glb):
    magic, version, length = struct.unpack_from("<4sII", glb)
    assert magic == b"glTF" and version == 2 and length == len(glb)
    json_len, _ = struct.unpack_from("<II", glb, 12)
    doc = json.loads(glb[20:20 + json_len])
    at = 20 + json_len
    bin_len, _ = struct.unpack_from("<II", glb, at)
    return doc, glb[at + 8:at + 8 + bin_len]


def accessor(doc, binary, index):
    a = doc["accessors"][index]
    view = doc["bufferViews"][a["bufferView"]]
    dtype = np.dtype(_DTYPES[a["componentType"]]).newbyteorder("<")
    width = _SIZES[a["type"]]
    stride = view.get("byteStride", dtype.itemsize * width)
    start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
    rows = np.ndarray((a["count"], width), dtype=dtype, buffer=binary, offset=start,
                      strides=(stride, dtype.itemsize))
    out = rows.astype(np.float64)
    if a.get("normalized"):
        out /= np.iinfo(dtype).max  # unsigned: q / 255 or q / 65535
    return out


def node_matrix(node):
    if "matrix" in node:
        return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T  # column-major
    x, y, z, w = node.get("rotation", (0, 0, 0, 1))
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = R * np.asarray(node.get("scale", (1, 1, 1)))  # R · diag(s)
    m[:3, 3] = node.get("translation", (0, 0, 0))
    return m


def lbs_from_glb(glb):
    """(rest positions, skinned positions) of the GLB's skinned mesh in its current pose (the
    nodes' TRS), in the model's coordinates."""
    doc, binary = parse_glb(glb)
    nodes = doc["nodes"]
    parent = {c: i for i, n in enumerate(nodes) for c in n.get("children", ())}

    def world(i):
        m = node_matrix(nodes[i])
        while i in parent:
            i = parent[i]
            m = node_matrix(nodes[i]) @ m
        return m

    mesh_node = next(i for i, n in enumerate(nodes) if "skin" in n)
    skin = doc["skins"][nodes[mesh_node]["skin"]]
    ibm = accessor(doc, binary, skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
    # glTF skinning: the skinned vertex is Σ w · inverse(world(mesh node)) · world(joint) ·
    # inverseBind · x, in the scene's (y-up) frame. A z-up model's skeleton hangs under a node
    # turning z-up to y-up: its inverse brings the result back to the model's coordinates.
    root = skin.get("skeleton", skin["joints"][0])
    to_model = np.linalg.inv(world(parent[root])) if root in parent else np.eye(4)
    to_mesh = to_model @ np.linalg.inv(world(mesh_node))
    joint_m = np.stack([to_mesh @ world(j) @ ibm[k] for k, j in enumerate(skin["joints"])])
    prim = doc["meshes"][nodes[mesh_node]["mesh"]]["primitives"][0]["attributes"]
    V = accessor(doc, binary, prim["POSITION"])
    Vh = np.hstack([V, np.ones((len(V), 1))])
    out = np.zeros_like(V)
    total = np.zeros(len(V))
    for set_ in range(2):
        if f"JOINTS_{set_}" not in prim:
            break
        J = accessor(doc, binary, prim[f"JOINTS_{set_}"]).astype(np.int64)
        W = accessor(doc, binary, prim[f"WEIGHTS_{set_}"])
        for slot in range(J.shape[1]):
            A = joint_m[J[:, slot]]  # n × 4 × 4
            out += W[:, slot, None] * np.einsum("nij,nj->ni", A, Vh)[:, :3]
            total += W[:, slot]
    assert np.abs(total - 1).max() < 1e-6, "weights do not sum to 1"
    return V, out


def section_radius(V, rest, s):
    """The mean distance to the twist axis (vertical, through the handle's pivot) of the
    vertices halfway between the fixed region and the handle (rest z within 1% of the bar's
    height of the middle): how much a twisted cross-section keeps of its size."""
    z = rest[:, 2]
    middle = (z[s.fixed].max() + z[s.handles[0]].min()) / 2
    ring = np.abs(z - middle) < 0.01 * np.ptp(z)
    p = s.pivots[0]
    return float(np.linalg.norm(V[ring, :2] - p[:2], axis=1).mean())


# --- pictures ---------------------------------------------------------------------------------
def view_basis(azimuth, elevation):
    """(right, up, toward the viewer) for a z-up model seen from azimuth/elevation."""
    a, e = np.radians(azimuth), np.radians(elevation)
    toward = np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])
    right = np.cross([0.0, 0.0, 1.0], toward)
    right /= np.linalg.norm(right)
    return right, np.cross(toward, right), toward


def draw(ax, V, F, basis, colors):
    """The mesh as depth-sorted, Lambert-shaded triangles (orthographic)."""
    from matplotlib.collections import PolyCollection
    right, up, toward = basis
    P = np.stack([V @ right, V @ up], axis=1)
    T = V[F]
    n = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    light = toward + 0.4 * up + 0.3 * right
    shade = 0.35 + 0.65 * np.abs(n @ (light / np.linalg.norm(light)))
    order = np.argsort(T.mean(axis=1) @ toward)  # far first
    rgb = np.clip(colors[order, :3] * shade[order, None], 0, 1)
    ax.add_collection(PolyCollection(P[F[order]], facecolors=rgb, edgecolors=rgb,
                                     linewidths=0.15, antialiaseds=False))
    ax.set_aspect("equal")
    ax.set_axis_off()


def picture(path, mesh, F, basis, exact, lbs, dists, titles, vmax, dpi):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import cm, colors as mcolors
    cols = len(exact)
    everything = np.concatenate([np.concatenate([e, l]) for e, l in zip(exact, lbs)])
    right, up, _ = basis
    xs, ys = everything @ right, everything @ up
    pad = 0.03 * max(np.ptp(xs), np.ptp(ys))
    height = 2.8  # inches per panel; the width follows the shapes' extent
    width = max(1.5, height * (np.ptp(xs) + 2 * pad) / (np.ptp(ys) + 2 * pad))
    fig, axes = plt.subplots(2, cols, figsize=(width * cols + 1.5, 2 * height + 0.7),
                             squeeze=False)
    norm = mcolors.Normalize(0, vmax)
    cmap = matplotlib.colormaps["viridis"]
    grey = np.tile([0.78, 0.78, 0.8, 1.0], (len(F), 1))
    for c in range(cols):
        draw(axes[0, c], exact[c], F, basis, grey)
        draw(axes[1, c], lbs[c], F, basis, cmap(norm(dists[c][F].mean(axis=1))))
        axes[0, c].set_title(titles[c], fontsize=9)
        for r in range(2):
            axes[r, c].set_xlim(xs.min() - pad, xs.max() + pad)
            axes[r, c].set_ylim(ys.min() - pad, ys.max() + pad)
    axes[0, 0].text(-0.04, 0.5, "exact", rotation=90, va="center", ha="right",
                    transform=axes[0, 0].transAxes, fontsize=10)
    axes[1, 0].text(-0.04, 0.5, "rig (LBS)", rotation=90, va="center", ha="right",
                    transform=axes[1, 0].transAxes, fontsize=10)
    bar = fig.colorbar(cm.ScalarMappable(norm=norm, cmap=cmap), ax=axes[1, :].tolist(),
                       fraction=0.04, pad=0.02)
    bar.set_label("distance to exact / bbox diagonal", fontsize=8)
    bar.ax.tick_params(labelsize=7)
    fig.suptitle(f"{mesh}: the .def pose at 1/3, 2/3 and full strength", fontsize=9)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


# --- main -------------------------------------------------------------------------------------
def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "images", "rig"),
                    help="folder for the PNGs (default: docs/images/rig)")
    ap.add_argument("--dpi", type=int, default=100)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    errors, sizes, sections = [], [], []
    with hdeform.connect() as hd:
        for mesh, up, azimuth, elevation in MESHES:
            sel = os.path.join(BENCH, mesh + ".sel")
            with hd.open(mesh) as s:
                s.constrain(fixed=hdeform.sel_file(sel, hdeform.FIXED),
                            handles=[hdeform.sel_file(sel, hdeform.HANDLE)])
                lo, hi = s.bbox
                diagonal = float(np.linalg.norm(hi - lo))
                motion = def_motion(s, mesh)
                F = s.triangles()
                exact, lbs, dists, titles = [], [], [], []
                rest = s.update().V
                for strength, label in zip(STRENGTHS, STRENGTH_NAMES):
                    frame = s.update(transforms=[pose(motion, strength)])
                    rig = s.export_rig(up=up, animation=False)
                    assert abs(rig.bbox_diagonal - diagonal) <= 1e-12 * diagonal
                    _, X = lbs_from_glb(rig.glb)
                    d = np.linalg.norm(X - frame.V, axis=1) / diagonal
                    ours = (float(d.max()), float(np.sqrt(np.mean(d * d))))
                    theirs = (rig.poses[0].max, rig.poses[0].rms)
                    if max(abs(x - y) for x, y in zip(ours, theirs)) > AGREE:
                        raise SystemExit(f"{mesh} {label}: LBS from the GLB gives max/rms "
                                         f"{ours}, the server reports {theirs}")
                    errors.append((mesh, label, motion[1] * strength, *theirs))
                    if mesh == "bar":  # a twist: the candy wrapper
                        sections.append((label, motion[1] * strength,
                                         section_radius(rest, rest, s),
                                         section_radius(frame.V, rest, s),
                                         section_radius(X, rest, s)))
                    exact.append(frame.V)
                    lbs.append(X)
                    dists.append(d)
                    titles.append(f"{label}: {motion[1] * strength:.0f}°, "
                                  f"max {theirs[0]:.3f}")
                vmax = max(float(d.max()) for d in dists)
                basis = view_basis(azimuth, elevation)
                path = os.path.join(a.out, mesh + ".png")
                picture(path, mesh, F, basis, exact, lbs, dists, titles, vmax, a.dpi)
                print(f"wrote {os.path.relpath(path, ROOT)} ({os.path.getsize(path)} bytes)",
                      file=sys.stderr)

                # The same motion as a timeline: rest at 0 s, the full pose at 2 s.
                s.update(transforms=[pose(motion, 1.0)])
                s.set_timeline([(0, [None]), (2, [pose(motion, 1.0)])])
                t0 = time.perf_counter()
                rig = s.export_rig(up=up)
                rig_s = time.perf_counter() - t0
                t0 = time.perf_counter()
                morph = s.export_animation(fps=30, up=up)
                morph_s = time.perf_counter() - t0
                sizes.append((mesh, s.vertex_count, s.triangle_count, len(rig.glb), rig_s,
                              len(morph), morph_s))

    print("| mesh | pose | rotation | max | rms |")
    print("|---|---|---:|---:|---:|")
    for mesh, label, degrees, mx, rms in errors:
        print(f"| {mesh} | {label} | {degrees:.1f}° | {mx:.4f} | {rms:.4f} |")
    print()
    print("| mesh | vertices | triangles | rig GLB (2 keys) | morph targets (30 fps, 2 s) "
          "| ratio |")
    print("|---|---:|---:|---:|---:|---:|")
    for mesh, n, m, rig_b, rig_s, morph_b, morph_s in sizes:
        print(f"| {mesh} | {n} | {m} | {rig_b / 1e3:.0f} kB | {morph_b / 1e6:.1f} MB "
              f"| {morph_b / rig_b:.0f}× |")
    print()
    print("| bar, twist | mid-height radius: rest | exact | rig (LBS) | LBS / exact |")
    print("|---|---:|---:|---:|---:|")
    for label, degrees, r0, r_exact, r_lbs in sections:
        print(f"| {label} ({degrees:.0f}°) | {r0:.2f} | {r_exact:.2f} | {r_lbs:.2f} "
              f"| {r_lbs / r_exact:.2f} |")
    for mesh, n, m, rig_b, rig_s, morph_b, morph_s in sizes:
        print(f"export time, {mesh}: rig {rig_s:.3f} s, morph targets {morph_s:.3f} s",
              file=sys.stderr)


if __name__ == "__main__":
    main()
