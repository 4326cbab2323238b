"""A batch over a folder of meshes: each mesh with a Botsch–Sorkine NAME.sel/NAME.def beside
it is uploaded, deformed at β, saved as NAME.glb, and its measures go to one CSV.

    python3 batch.py [MESH_DIR] [OUT_DIR] [--beta 0.1] [--server HOST:PORT --token T]
"""
import argparse
import csv
import glob
import os

import hdeform

HERE = os.path.dirname(os.path.abspath(__file__))
DATA = os.environ.get("HDEFORM_DATA_DIR", os.path.join(HERE, "..", "..", "data"))

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("mesh_dir", nargs="?", default=os.path.join(DATA, "botsch-sorkine"))
ap.add_argument("out_dir", nargs="?", default="batch-out")
ap.add_argument("--beta", type=float, default=0.1)
ap.add_argument("--server")
ap.add_argument("--token")
args = ap.parse_args()
os.makedirs(args.out_dir, exist_ok=True)

rows = []
with hdeform.connect(args.server, token=args.token) as hd:
    for path in sorted(glob.glob(os.path.join(args.mesh_dir, "*"))):
        stem, ext = os.path.splitext(path)
        if ext.lower() not in (".off", ".obj", ".ply", ".stl") or not os.path.exists(stem + ".sel"):
            continue
        name = os.path.basename(stem)
        with hd.upload_file(path) as s:
            s.constrain(fixed=hdeform.sel_file(stem + ".sel", hdeform.FIXED),
                        handles=[hdeform.sel_file(stem + ".sel", hdeform.HANDLE)])
            s.beta = args.beta
            frame = s.update(matrix=hdeform.read_def(stem + ".def"))
            s.save(os.path.join(args.out_dir, name + ".glb"))
            rows.append(dict(mesh=name, vertices=s.vertex_count, beta=frame.beta,
                             solve_ms=round(frame.solve_ms, 3), **frame.measures.as_dict()))
            print(f"{name}: {s.vertex_count} vertices, E_iso_n {frame.measures.e_iso_n:.5f}")

out = os.path.join(args.out_dir, "measures.csv")
with open(out, "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0]) if rows else ["mesh"])
    w.writeheader()
    w.writerows(rows)
print(f"wrote {len(rows)} GLBs and {out}")
