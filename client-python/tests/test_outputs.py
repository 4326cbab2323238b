"""Small mismatches (issue 38, item 7): the sweep CSV is the CLI's, save() writes STL, the
pandas hint, Selector reprs that show their parameters, quads and polygons."""
import os
import subprocess
import sys

import numpy as np
import pytest

import hdeform
from conftest import BENCH

CSV_HEADER = "beta,E,E_iso_N,E_conf_N,E_area_pct,max_e_iso,max_e_conf,max_ef2,flips"
BETAS = [0, 0.1, 1e-05, 0.25, 0.0001, 0.5]


def test_sweep_csv_format(cactus, tmp_path):
    cactus.update(matrix=hdeform.read_def(os.path.join(BENCH, "cactus.def")))
    rows = cactus.sweep(BETAS)
    text = rows.to_csv()
    rows.to_csv(tmp_path / "sweep.csv")
    assert (tmp_path / "sweep.csv").read_bytes() == text.encode()  # "\n", no "\r\n"
    lines = text.splitlines()
    assert lines[0] == CSV_HEADER and len(lines) == 1 + len(BETAS)
    # β as std::to_chars writes it: shortest round trip, "0" not "0.0", "1e-04" not "0.0001"
    assert [line.split(",")[0] for line in lines[1:]] == ["0", "0.1", "1e-05", "0.25", "1e-04",
                                                          "0.5"]
    for line, r in zip(lines[1:], rows):
        fields = line.split(",")
        m = r.measures
        assert fields[1:8] == [format(v, ".17g") for v in (
            m.e, m.e_iso_n, m.e_conf_n, m.e_area_pct, m.max_e_iso, m.max_e_conf, m.max_ef2)]
        assert fields[8] == str(m.flips)
    # records() and to_dataframe() keep the Python names
    assert list(rows.records()[0]) == rows.columns and rows.csv_columns == CSV_HEADER.split(",")


def test_sweep_csv_is_the_clis(hd, cactus):
    cli = os.environ.get("HDEFORM_CLI")
    if not cli:
        pytest.skip("HDEFORM_CLI (the built hdeform CLI) is not set; CTest sets it")
    cactus.update(matrix=hdeform.read_def(os.path.join(BENCH, "cactus.def")))
    ours = cactus.sweep(BETAS).to_csv().splitlines()
    r = subprocess.run([cli, "--server", hd.address, "--token", cactus.edit_token, "sweep",
                        "--session", cactus.name, "--betas", ",".join(map(repr, BETAS)),
                        "--csv", "-"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    theirs = r.stdout.splitlines()
    assert theirs[0] == ours[0] == CSV_HEADER and len(theirs) == len(ours)
    for a, b in zip(ours[1:], theirs[1:]):
        fa, fb = a.split(","), b.split(",")
        assert fa[0] == fb[0] and fa[8] == fb[8]  # β and flips: the same text
        # Same numbers written the same way ("%.17g"): equal text unless the two sweeps'
        # solves differ in the last bits, which the format check then still covers.
        for x, y in zip(fa[1:8], fb[1:8]):
            assert x == format(float(x), ".17g") and y == format(float(y), ".17g")
            assert float(x) == pytest.approx(float(y), rel=1e-12, abs=1e-300)


def test_save_stl(cactus, tmp_path):
    cactus.update(translate=(0.05, 0, 0.1))
    V, F = cactus.mesh()
    path = tmp_path / "cactus.stl"
    cactus.save(path)
    data = path.read_bytes()
    assert len(data) == 84 + 50 * len(F) and not data.startswith(b"solid")
    assert data == cactus.mesh_bytes("stl")
    with cactus.client.upload_file(path) as back:  # the server reads its own STL
        assert back.triangle_count == cactus.triangle_count
        assert back.vertex_count == cactus.vertex_count
        V2, F2 = back.rest()
        # the same triangles in the same order; corners at float32 precision (STL's own)
        np.testing.assert_array_equal(V2[F2], V[F].astype(np.float32).astype(np.float64))
    rest = tmp_path / "rest.STL"
    cactus.save(rest, rest=True)
    V0, F0 = cactus.rest()
    assert rest.read_bytes() == hdeform.stl_bytes(V0, F0)
    with pytest.raises(ValueError, match="compression: GLB only"):
        cactus.save(tmp_path / "x.stl", compression="quantized")


def test_to_dataframe_without_pandas_names_the_package(cactus, monkeypatch):
    rows = cactus.sweep([0, 0.1])
    monkeypatch.setitem(sys.modules, "pandas", None)  # as if python3-pandas were missing
    with pytest.raises(ImportError, match=r"apt-get install python3-pandas"):
        rows.to_dataframe()
    assert len(rows.records()) == 2 and rows.to_csv().startswith(CSV_HEADER)


def test_selector_repr_shows_its_parameters():
    path = os.path.join(BENCH, "cactus.sel")
    cases = {
        "hdeform.box(min=(0.0, -1.0, 0.5), max=(1.0, 2.0, 3.25))":
            hdeform.box([0, -1, 0.5], (1, 2, 3.25)),
        "hdeform.sphere(center=(0.1, 0.2, 0.3), radius=0.05)":
            hdeform.sphere([0.1, 0.2, 0.3], 0.05),
        "hdeform.half_space(normal=(0.0, 0.0, 1.0), offset=0.75)":
            hdeform.half_space([0, 0, 1], 0.75),
        "hdeform.ids([3, 1, 2])": hdeform.ids([3, 1, 2]),
        "hdeform.base_ids([7])": hdeform.base_ids(np.array([7])),
        f"hdeform.sel_file({path!r}, hdeform.HANDLE)": hdeform.sel_file(path, hdeform.HANDLE),
    }
    for text, sel in cases.items():
        assert repr(sel) == text
        again = eval(text, {"hdeform": hdeform})  # noqa: S307 - our own repr
        assert again.to_proto() == sel.to_proto()
    assert repr(hdeform.sel("1\n2\n", hdeform.FIXED)) == "hdeform.sel(<4 bytes>, hdeform.FIXED)"
    assert repr(hdeform.ids(range(100))) == "hdeform.ids([0, 1, 2, 3, 4, 5, 6, 7, … 100 ids])"
    assert repr(hdeform.ids(np.array([False, True, True]))) == (
        "hdeform.ids([1, 2], from a mask of 3)")


CUBE_V = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
                   [0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], dtype=float)
CUBE_QUADS = np.array([[0, 3, 2, 1], [4, 5, 6, 7], [0, 1, 5, 4], [1, 2, 6, 5], [2, 3, 7, 6],
                       [3, 0, 4, 7]])


def test_quads_and_polygons_are_fan_triangulated_like_the_servers_readers(hd, tmp_path):
    tris = hdeform.triangulate(CUBE_QUADS)
    np.testing.assert_array_equal(tris[:2], [[0, 3, 2], [0, 2, 1]])
    obj = tmp_path / "cube.obj"
    obj.write_text("".join(f"v {x:g} {y:g} {z:g}\n" for x, y, z in CUBE_V) +
                   "".join("f " + " ".join(str(i + 1) for i in q) + "\n" for q in CUBE_QUADS))
    with hd.upload_file(obj) as from_file, hd.upload(CUBE_V, CUBE_QUADS) as from_arrays:
        assert from_arrays.triangle_count == from_file.triangle_count == 12
        Vf, Ff = from_file.rest()
        Va, Fa = from_arrays.rest()
        np.testing.assert_array_equal(Va, Vf)
        np.testing.assert_array_equal(Fa, Ff)  # the server's fan is ours
        np.testing.assert_array_equal(Fa, tris)
    # polygons of several sizes: a list of index lists
    V = np.array([[0, 0, 0], [2, 0, 0], [3, 1, 0], [2, 2, 0], [0, 2, 0], [1, 1, 1.5]])
    faces = [[0, 1, 2, 3, 4], [0, 5, 1], [1, 5, 2], [2, 5, 3], [3, 5, 4], [4, 5, 0]]
    np.testing.assert_array_equal(hdeform.triangulate(faces)[:3], [[0, 1, 2], [0, 2, 3],
                                                                   [0, 3, 4]])
    with hd.upload(V, faces) as s:
        assert s.triangle_count == 3 + 5
    with pytest.raises(ValueError, match=r"^F\[1\]: a face needs at least 3 vertices"):
        hdeform.triangulate([[0, 1, 2], [0, 1]])
    with pytest.raises(ValueError, match=r"^F: expected an m×3 array of triangles"):
        hd.upload(CUBE_V, CUBE_QUADS[:, :2])
