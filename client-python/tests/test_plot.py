"""Pictures (issue 38, item 8): SweepResult.plot() and Frame.plot_measures() with matplotlib
(Debian's python3-matplotlib, optional for the package, installed by
scripts/install-deps.sh for the suite), and the notebook-free example writing PNGs."""
import os
import struct
import subprocess
import sys
import zlib

import pytest

import hdeform
from conftest import BENCH, HERE

try:
    import matplotlib
except ImportError:  # pragma: no cover - the suite's machines have it
    pytest.fail("the plot tests need matplotlib: apt-get install python3-matplotlib "
                "(scripts/install-deps.sh)", pytrace=False)
matplotlib.use("Agg")


def png_size(path):
    """(width, height) of a PNG, after checking its signature and every chunk's CRC."""
    data = open(path, "rb").read()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path}: not a PNG"
    pos, chunks = 8, []
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        crc, = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])
        assert zlib.crc32(kind + body) == crc, f"{path}: bad CRC in {kind}"
        chunks.append(kind)
        pos += 12 + length
    assert chunks[0] == b"IHDR" and chunks[-1] == b"IEND" and b"IDAT" in chunks
    return struct.unpack(">II", data[16:24])


def test_example_writes_pngs(tmp_path):
    path = os.path.join(HERE, "..", "examples", "plot_beta_study.py")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [os.path.join(HERE, "..")] + [p for p in sys.path if p]))
    env.pop("DISPLAY", None)
    env.pop("MPLBACKEND", None)
    r = subprocess.run([sys.executable, path, "--out", "pictures", "--betas", "0,0.05,0.1,0.3"],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    for name in ("cactus-sweep.png", "cactus-measures.png"):
        png = tmp_path / "pictures" / name
        assert f"wrote {os.path.join('pictures', name)}" in r.stdout
        width, height = png_size(png)
        assert 600 <= width <= 3000 and 400 <= height <= 2000, (name, width, height)
        assert 10_000 < png.stat().st_size < 2_000_000


def test_plot_on_given_axes_and_files(cactus, tmp_path):
    from matplotlib.figure import Figure
    cactus.update(matrix=hdeform.read_def(os.path.join(BENCH, "cactus.def")))
    rows = cactus.sweep([0.3, 0, 0.1])
    fig = Figure()
    ax = fig.add_subplot()
    assert rows.plot(ax=ax) is fig
    lines = ax.get_lines()
    assert [line.get_label() for line in lines[:4]] == ["e_iso_n", "e_conf_n", "max_e_iso",
                                                        "max_e_conf"]
    assert list(lines[0].get_xdata()) == [0, 0.1, 0.3]  # sorted by β
    by_beta = sorted(rows, key=lambda r: r.beta)
    assert list(lines[0].get_ydata()) == [r.measures.e_iso_n for r in by_beta]
    assert ax.get_xlabel() == "β (area units)"
    svg = tmp_path / "sweep.svg"
    rows.plot(path=svg, measures=["e_area_pct"], logy=False)
    assert svg.read_text().lstrip().startswith("<?xml")

    frame = cactus.update(matrix=hdeform.read_def(os.path.join(BENCH, "cactus.def")),
                          energies=True)
    fig = frame.plot_measures(path=tmp_path / "m.png")
    assert len(fig.axes) == 2  # bars and the energies' histogram
    assert png_size(tmp_path / "m.png")[0] > 1000
    no_energies = cactus.update(matrix=hdeform.read_def(os.path.join(BENCH, "cactus.def")))
    assert len(no_energies.plot_measures(path=tmp_path / "n.png").axes) == 1

    with pytest.raises(ValueError, match=r"^measures\[1\]: one of e, e_iso_n"):
        rows.plot(ax=ax, measures=["e", "E_iso_N"])
    with pytest.raises(ValueError, match="the sweep has no rows"):
        hdeform.SweepResult().plot(ax=ax)


def test_without_matplotlib_the_error_names_the_fix(tmp_path):
    code = ("import sys; sys.modules['matplotlib'] = None\n"
            "import hdeform\n"
            "from hdeform import Measures, SweepRow, SweepResult\n"
            "m = Measures(1, 1, 1, 1, 1, 1, 1, 0)\n"
            "SweepResult([SweepRow(0.1, m)]).plot(path='x.png')\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                       timeout=60, cwd=tmp_path)
    last = r.stderr.strip().splitlines()[-1]
    assert last == ("ImportError: SweepResult.plot() needs matplotlib: apt-get install "
                    "python3-matplotlib (for Debian's /usr/bin/python3 or a venv made with "
                    "--system-site-packages)")
