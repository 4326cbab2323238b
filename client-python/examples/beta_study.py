"""A β study on the Botsch–Sorkine cactus: its .sel/.def constraints, the seven measures for a
list of β, printed and written as CSV.

    python3 beta_study.py [--data DIR] [--csv OUT.csv] [--server HOST:PORT --token T]

Without --server it starts a private hdeform-server (HDEFORM_SERVER, the build tree or PATH).
"""
import argparse
import os

import hdeform

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_DATA = os.environ.get("HDEFORM_DATA_DIR", os.path.join(HERE, "..", "..", "data"))

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--data", default=DEFAULT_DATA, help="the repository's data/ folder")
ap.add_argument("--mesh", default="cactus")
ap.add_argument("--betas", default="0,0.01,0.05,0.1,0.25,0.5")
ap.add_argument("--csv", default="beta-study.csv")
ap.add_argument("--server")
ap.add_argument("--token")
args = ap.parse_args()

bench = os.path.join(args.data, "botsch-sorkine", args.mesh)
betas = [float(b) for b in args.betas.split(",")]

with hdeform.connect(args.server, token=args.token) as hd:
    with hd.open(args.mesh) as s:
        s.constrain(fixed=hdeform.sel_file(bench + ".sel", hdeform.FIXED),
                    handles=[hdeform.sel_file(bench + ".sel", hdeform.HANDLE)])
        s.update(matrix=hdeform.read_def(bench + ".def"))  # the benchmark's handle move
        rows = s.sweep(betas)
        rows.to_csv(args.csv)
        print(f"{args.mesh}: {s.vertex_count} vertices, {len(s.handles[0])} handle vertices")
        print(f"{'beta':>6} {'E_iso_n':>10} {'E_conf_n':>10} {'area %':>8} {'max E_iso':>10} flips")
        for r in rows:
            m = r.measures
            print(f"{r.beta:6.3f} {m.e_iso_n:10.5f} {m.e_conf_n:10.5f} {m.e_area_pct:8.3f} "
                  f"{m.max_e_iso:10.5f} {m.flips:5d}")
print(f"wrote {args.csv}")
