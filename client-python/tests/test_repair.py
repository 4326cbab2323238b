"""Upload repair (repair=, Session.repair, the refusal's hint) and polygon meshes saved back
as polygons (docs/api.md "Repair", docs/python.md)."""
import math

import numpy as np
import pytest

import hdeform

# Two triangles touching at vertex 0 only: a bowtie (non-manifold vertex).
BOWTIE = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv -1 0 0\nv 0 -1 0\nf 1 2 3\nf 1 4 5\n"
HINT = " (upload with repair=True may fix it)"


def test_bowtie_is_refused_with_the_hint_and_opens_with_repair(hd, tmp_path):
    path = tmp_path / "bowtie.obj"
    path.write_text(BOWTIE)
    with pytest.raises(hdeform.InvalidArgument) as refused:
        hd.upload_file(path)
    assert refused.value.message.startswith("non-manifold vertex")
    assert refused.value.message.endswith(HINT)
    with hd.upload_file(path, repair=True) as s:
        assert s.vertex_count == 6 and s.triangle_count == 2
        report = s.repair
        assert isinstance(report, hdeform.RepairReport)
        assert report.split_vertices == 1 and report.added_vertices == 1
        assert (report.merged_vertices, report.degenerate_triangles, report.duplicate_triangles,
                report.unreferenced_vertices) == (0, 0, 0, 0)
        assert report.changed and len(report.lines) == 1 and "split 1" in report.lines[0]
        assert report.base_to_input is not None
        np.testing.assert_array_equal(report.base_to_input, [0, 1, 2, 3, 4, 0])
        assert not report.base_to_input.flags.writeable
        with pytest.raises(Exception):  # frozen
            report.split_vertices = 2  # type: ignore[misc]
        s.refresh()
        assert s.repair == report  # the creation's answer, kept
        assert hd.session(s.name, s.edit_token).repair is None
    # upload() and a tolerance: the same repair
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]], dtype=float)
    with pytest.raises(hdeform.InvalidArgument,
                       match=r"^INVALID_ARGUMENT: non-manifold vertex.*"
                             r"\(upload with repair=True may fix it\)$"):
        hd.upload(V, [[0, 1, 2], [0, 3, 4]])
    with hd.upload(V, [[0, 1, 2], [0, 3, 4]], repair=0.001) as s:
        assert s.vertex_count == 6 and s.repair is not None and s.repair.split_vertices == 1


def test_repair_argument_is_checked_locally(hd, tmp_path):
    path = tmp_path / "bowtie.obj"
    path.write_text(BOWTIE)
    V = np.eye(3)
    before = sorted(hd.sessions())
    for bad in (0.5, -1, 0.0100001, math.nan, math.inf, "yes", None, [0.001]):
        for call in (lambda: hd.upload_file(path, repair=bad),
                     lambda: hd.upload(V, [[0, 1, 2]], repair=bad),
                     lambda: hd.upload_meshio(object(), repair=bad)):
            with pytest.raises(ValueError, match=r"^repair: True, False or a merge tolerance "
                                                 r"in \[0, 0\.01\]"):
                call()
    assert sorted(hd.sessions()) == before  # refused before any call


def test_no_repair_asked_no_report_and_a_clean_mesh_comes_through(hd):
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=float)
    with hd.upload(V, [[0, 1, 2]]) as s:
        assert s.repair is None
    with hd.upload(V, [[0, 1, 2]], repair=True) as s:
        report = s.repair
        assert report == hdeform.RepairReport() and not report.changed
        assert report.base_to_input is None
        assert hash(report) == hash(hdeform.RepairReport())


def test_hint_only_for_what_repair_may_fix(hd, tmp_path):
    # zero area: hinted, and repaired (the sliver dropped, then its unused vertex)
    zero = tmp_path / "zero.obj"
    zero.write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nv 0 1 0\nf 1 2 4\nf 1 2 3\n")
    with pytest.raises(hdeform.InvalidArgument,
                       match=r"^INVALID_ARGUMENT: zero-area triangles: .*"
                             r"\(upload with repair=True may fix it\)$"):
        hd.upload_file(zero)
    with hd.upload_file(zero, repair=True) as s:
        assert s.repair is not None
        assert (s.repair.degenerate_triangles, s.repair.unreferenced_vertices) == (1, 1)
        np.testing.assert_array_equal(s.repair.base_to_input, [0, 1, 3])
    # inconsistent orientation: no hint (repair does not fix it), with or without repair
    flipped = tmp_path / "flipped.obj"
    flipped.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nf 1 2 3\nf 1 2 4\n")
    for repair in (False, True):
        with pytest.raises(hdeform.InvalidArgument) as refused:
            hd.upload_file(flipped, repair=repair)
        assert refused.value.message.startswith("inconsistent orientation")
        assert not refused.value.message.endswith(HINT)
    # a refusal after a repair carries no hint either
    with pytest.raises(hdeform.InvalidArgument) as refused:
        hd.upload_file(flipped, repair=0.0)
    assert HINT not in str(refused.value)


def _grid_obj(n=3):
    """An n×n grid of quads, (n+1)² vertices, curved in z (OBJ text, 1-based)."""
    lines = [f"v {x} {y} {0.1 * (x - n / 2) ** 2}" for y in range(n + 1) for x in range(n + 1)]
    for y in range(n):
        for x in range(n):
            a = y * (n + 1) + x + 1
            lines.append(f"f {a} {a + 1} {a + n + 2} {a + n + 1}")
    return "\n".join(lines) + "\n"


def _obj(text):
    V = [[float(t) for t in line.split()[1:4]] for line in text.splitlines()
         if line.startswith("v ")]
    faces = [[int(t.split("/")[0]) - 1 for t in line.split()[1:]]
             for line in text.splitlines() if line.startswith("f ")]
    return np.array(V, dtype=np.float64), faces


def _off_faces(text, n_vertices):
    body = [line.split() for line in text.splitlines()[2 + n_vertices:] if line.strip()]
    return [[int(t) for t in f[1:1 + int(f[0])]] for f in body]


def test_quad_mesh_is_saved_as_quads(hd, tmp_path):
    src = tmp_path / "grid.obj"
    src.write_text(_grid_obj(3))
    _, quads = _obj(src.read_text())
    with hd.upload_file(src) as s:
        assert (s.vertex_count, s.triangle_count) == (16, 18)
        s.constrain(fixed=hdeform.ids([0, 1, 2, 3]), handles=[hdeform.ids([12, 13, 14, 15])])
        frame = s.update(translate=(0.2, 0.1, 0.5))
        assert not np.array_equal(frame.V, s.rest()[0])
        s.save(tmp_path / "out.obj")
        s.save(tmp_path / "out.off")
        s.save(tmp_path / "out.ply")
        V, faces = _obj((tmp_path / "out.obj").read_text())
        assert len(faces) == 9 and all(len(f) == 4 for f in faces)
        assert faces == quads  # the same corners, in the upload's order
        np.testing.assert_array_equal(V, frame.V)
        off = (tmp_path / "out.off").read_text()
        V_off, F_off = hdeform.parse_off(off)
        np.testing.assert_array_equal(V_off, frame.V)
        np.testing.assert_array_equal(F_off, hdeform.triangulate(quads))  # the solve's fan
        assert _off_faces(off, 16) == quads
        ply = (tmp_path / "out.ply").read_bytes()
        assert b"element face 9\n" in ply
        assert (tmp_path / "out.off").read_bytes() == s.mesh_bytes("off")
        # the rest mesh too
        s.save(tmp_path / "rest.obj", rest=True)
        V_rest, faces_rest = _obj((tmp_path / "rest.obj").read_text())
        assert faces_rest == quads
        np.testing.assert_array_equal(V_rest, _obj(src.read_text())[0])


def test_triangle_mesh_save_is_the_servers_file(cactus, tmp_path):
    cactus.update(translate=(0, 0, 0.1))
    for ext in ("obj", "off", "ply"):
        cactus.save(tmp_path / f"c.{ext}")
        assert (tmp_path / f"c.{ext}").read_bytes() == cactus.mesh_bytes(ext)
    text = (tmp_path / "c.obj").read_text()
    assert all(len(line.split()) == 4 for line in text.splitlines() if line.startswith("f "))
