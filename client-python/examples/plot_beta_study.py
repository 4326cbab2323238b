"""The β study as pictures, without a notebook: the cactus benchmark's move, its measures
over β (SweepResult.plot) and one frame's measures with its per-triangle energies
(Frame.plot_measures), written as PNG files.

    python3 plot_beta_study.py [--data DIR] [--out DIR] [--betas 0,0.05,…] [--beta B]

Needs matplotlib (apt-get install python3-matplotlib). Without --server it starts a private
hdeform-server (HDEFORM_SERVER, the build tree or PATH).
"""
import argparse
import os

import matplotlib

matplotlib.use("Agg")  # files only: no display needed

import hdeform  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_DATA = os.environ.get("HDEFORM_DATA_DIR", os.path.join(HERE, "..", "..", "data"))

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("--data", default=DEFAULT_DATA, help="the repository's data/ folder")
ap.add_argument("--mesh", default="cactus")
ap.add_argument("--betas", default="0,0.001,0.01,0.05,0.1,0.2,0.3,0.5,0.7,0.9")
ap.add_argument("--beta", type=float, default=0.1, help="β of the frame whose measures are drawn")
ap.add_argument("--out", default=".", help="folder for the PNG files")
ap.add_argument("--server")
ap.add_argument("--token")
args = ap.parse_args()

bench = os.path.join(args.data, "botsch-sorkine", args.mesh)
betas = [float(b) for b in args.betas.split(",")]
os.makedirs(args.out, exist_ok=True)
sweep_png = os.path.join(args.out, f"{args.mesh}-sweep.png")
frame_png = os.path.join(args.out, f"{args.mesh}-measures.png")

with hdeform.connect(args.server, token=args.token) as hd:
    with hd.open(args.mesh) as s:
        s.constrain(fixed=hdeform.sel_file(bench + ".sel", hdeform.FIXED),
                    handles=[hdeform.sel_file(bench + ".sel", hdeform.HANDLE)])
        move = hdeform.read_def(bench + ".def")  # the benchmark's handle move
        s.update(matrix=move)
        rows = s.sweep(betas)
        rows.plot(path=sweep_png)
        s.set_beta(args.beta)
        frame = s.update(matrix=move, energies=True)
        frame.plot_measures(path=frame_png)
print(f"wrote {sweep_png}")
print(f"wrote {frame_png}")
