"""meshio (issue 38, item 9): hdeform.from_meshio / Client.upload_meshio take any mesh meshio
reads; Frame.to_meshio() gives one meshio writes. Debian's python3-meshio
(scripts/install-deps.sh installs it)."""
import os
import subprocess
import sys

import numpy as np
import pytest

import hdeform
from conftest import BENCH

try:
    import meshio
except ImportError:  # pragma: no cover - the suite's machines have it
    pytest.fail("the meshio tests need meshio: apt-get install python3-meshio "
                "(scripts/install-deps.sh)", pytrace=False)


def quad_grid(n=12):
    """An n×n quad grid on the unit square, slightly curved in z."""
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    points = np.c_[x.ravel(), y.ravel(), 0.1 * np.sin(np.pi * x.ravel()) * y.ravel()]
    ids = np.arange(n * n).reshape(n, n)
    quads = np.stack([ids[:-1, :-1], ids[1:, :-1], ids[1:, 1:], ids[:-1, 1:]], axis=-1)
    return points, quads.reshape(-1, 4)


@pytest.mark.parametrize("ext", [".vtk", ".ply"])
def test_round_trip_through_files(hd, tmp_path, ext):
    points, quads = quad_grid()
    src = tmp_path / f"grid{ext}"
    if ext == ".ply":  # PLY as triangles (meshio's PLY writer)
        cells = [("triangle", hdeform.triangulate(quads))]
    else:
        cells = [("quad", quads)]
    meshio.write(src, meshio.Mesh(points, cells))
    mesh = meshio.read(src)
    V, F = hdeform.from_meshio(mesh)
    np.testing.assert_array_equal(V, points)  # meshio kept the doubles; rows unchanged
    np.testing.assert_array_equal(F, hdeform.triangulate(quads))  # quads: fan, (0,1,2)(0,2,3)

    with hd.upload_meshio(mesh) as s:
        assert (s.vertex_count, s.triangle_count) == (len(points), 2 * len(quads))
        np.testing.assert_array_equal(s.triangles(), F)
        s.constrain(fixed=points[:, 0] < 0.01, handles=[points[:, 0] > 0.99])
        frame = s.update(translate=(0, 0, 0.2), rotate=hdeform.axis_angle("y", 10),
                         energies=True)
        out = frame.to_meshio()
        assert isinstance(out, meshio.Mesh)
        dst = tmp_path / "deformed.vtk"
        meshio.write(dst, out)  # binary VTK: doubles as they are
        back = meshio.read(dst)
        np.testing.assert_array_equal(back.points, frame.V)
        np.testing.assert_array_equal(back.points, s.mesh()[0])  # the server's doubles
        assert [b.type for b in back.cells] == ["triangle"]
        np.testing.assert_array_equal(back.cells[0].data, F)
        np.testing.assert_array_equal(back.point_data["normals"], frame.N)
        np.testing.assert_array_equal(back.cell_data["energies"][0], frame.energies)
        assert back.points[points[:, 0] > 0.99, 2].mean() > 0.15  # the handle moved

        bare = frame.to_meshio(normals=False, energies=False)
        assert not bare.point_data and not bare.cell_data
        ply = tmp_path / "deformed.ply"
        meshio.write(ply, bare)
        np.testing.assert_array_equal(meshio.read(ply).points, frame.V)


def test_a_path_and_the_cactus(hd, cactus, tmp_path):
    V0, F0 = cactus.rest()
    path = tmp_path / "cactus.ply"
    meshio.write(path, meshio.Mesh(V0, [("triangle", F0)]))
    V, F = hdeform.from_meshio(path)  # a path: meshio reads it
    np.testing.assert_array_equal(V, V0)
    np.testing.assert_array_equal(F, F0)
    d = hdeform.read_def(os.path.join(BENCH, "cactus.def"))
    with hd.upload(V, F) as s:  # the same mesh, the same constraints: the same doubles
        s.constrain(fixed=cactus.fixed, handles=cactus.handles)
        np.testing.assert_array_equal(s.update(matrix=d).V, cactus.update(matrix=d).V)


def test_refusals():
    pts = np.zeros((4, 3))
    with pytest.raises(ValueError, match=r"'tetra' cells are not surface cells; .* extract the "
                                         r"boundary surface first"):
        hdeform.from_meshio(meshio.Mesh(pts, [("tetra", [[0, 1, 2, 3]])]))
    with pytest.raises(ValueError, match=r"'triangle6' cells are higher-order; .*"
                                         r"block.data\[:, :3\]"):
        hdeform.from_meshio(meshio.Mesh(np.zeros((6, 3)), [("triangle6", [list(range(6))])]))
    with pytest.raises(ValueError, match=r"no triangle, quad or polygon cells \(cell types: "
                                         r"line\)"):
        hdeform.from_meshio(meshio.Mesh(pts, [("line", [[0, 1]])]))
    with pytest.raises(ValueError, match=r"expected an n×3 array, got shape \(4, 2\) \(a 2-D "
                                         r"mesh: add a z column"):
        hdeform.from_meshio(meshio.Mesh(np.zeros((4, 2)), [("triangle", [[0, 1, 2]])]))
    with pytest.raises(ValueError, match=r"vertex ids must be in \[0, 4\)"):
        hdeform.from_meshio(meshio.Mesh(pts, [("triangle", [[0, 1, 7]])]))
    with pytest.raises(TypeError, match="expected a meshio.Mesh"):
        hdeform.from_meshio([[0, 0, 0]])
    # lines and points are dropped; triangles and a polygon block are kept in order
    V, F = hdeform.from_meshio(meshio.Mesh(np.zeros((6, 3)), [
        ("vertex", [[5]]), ("triangle", [[0, 1, 2]]), ("line", [[0, 5]]),
        ("polygon", [[1, 2, 3, 4, 5]])]))
    np.testing.assert_array_equal(F, [[0, 1, 2], [1, 2, 3], [1, 3, 4], [1, 4, 5]])


def test_without_meshio_the_error_names_the_fix(tmp_path):
    code = ("import sys; sys.modules['meshio'] = None\n"
            "import hdeform\n"
            "hdeform.from_meshio('x.vtk')\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                       timeout=60, cwd=tmp_path)
    last = r.stderr.strip().splitlines()[-1]
    assert last == ("ImportError: hdeform.from_meshio(path) needs meshio: apt-get install "
                    "python3-meshio (for Debian's /usr/bin/python3 or a venv made with "
                    "--system-site-packages)")
