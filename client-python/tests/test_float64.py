"""Exact arrays (issue 38, item 1): a client's own frames are FLOAT64 by default, the server's
doubles in one call, checked against GetMesh's text (shortest round-trip doubles); the
buffers' sizes are checked when decoding."""
import json
import os
import struct
import warnings

import numpy as np
import pytest

import hdeform
from hdeform._frames import decode
from hdeform._proto import pb
from conftest import BENCH, DATA


def obj_vertices(text):
    """The `v` lines of an OBJ as float64 (Python's float() reads %.17g / shortest digits
    exactly)."""
    return np.array([[float(x) for x in line.split()[1:4]]
                     for line in text.splitlines() if line.startswith("v ")])


def test_update_is_the_servers_doubles_exactly(cactus):
    frame = cactus.update(matrix=hdeform.read_def(os.path.join(BENCH, "cactus.def")),
                          energies=True)
    assert frame.encoding == "float64" and frame.V.dtype == np.float64
    exact = obj_vertices(cactus.mesh_bytes("obj").decode())
    np.testing.assert_array_equal(frame.V, exact)  # bit for bit, no second call needed
    assert frame.N.shape == exact.shape and frame.energies.shape == (cactus.triangle_count,)
    np.testing.assert_allclose(np.linalg.norm(frame.N, axis=1), 1, atol=1e-12)
    # float32 is still there for bandwidth: within float32 rounding, not equal
    f32 = cactus.update(matrix=hdeform.read_def(os.path.join(BENCH, "cactus.def")),
                        encoding="float32")
    assert f32.encoding == "float32"
    np.testing.assert_array_equal(f32.V, exact.astype(np.float32).astype(np.float64))
    assert not np.array_equal(f32.V, exact)
    q = cactus.update(encoding="quantized")
    assert q.encoding == "quantized" and q.V.shape == exact.shape


def test_an_obj_upload_too(hd):
    with hd.upload_file(os.path.join(DATA, "models", "horse.obj")) as s:
        n = s.vertex_count
        V0, _ = s.rest()
        top = V0[:, 1] > np.quantile(V0[:, 1], 0.9)
        bottom = V0[:, 1] < np.quantile(V0[:, 1], 0.1)
        s.constrain(fixed=bottom, handles=[top])
        frame = s.update(rotate=hdeform.axis_angle("z", 20), translate=(0.01, 0.02, 0))
        assert frame.V.shape == (n, 3)
        np.testing.assert_array_equal(frame.V, obj_vertices(s.mesh_bytes("obj").decode()))
        np.testing.assert_array_equal(frame.V, s.mesh()[0])  # OFF: the same doubles


def test_double_is_a_deprecated_no_op(cactus):
    with pytest.warns(DeprecationWarning, match="not needed: frames are float64 by default"):
        a = cactus.update(translate=(0, 0, 0.1), double=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        b = cactus.update(translate=(0, 0, 0.1))
        c = cactus.update(translate=(0, 0, 0.1), double=False)
    np.testing.assert_array_equal(a.V, b.V)
    np.testing.assert_array_equal(a.V, c.V)
    with pytest.raises(ValueError, match=r"^double=True \(deprecated\) asks for exact doubles"):
        cactus.update(double=True, encoding="float32")
    with pytest.raises(TypeError, match="^double: expected a bool"):
        cactus.update(double="yes")


def test_watch_refuses_float64_locally(cactus):
    with pytest.raises(ValueError, match=r"^watch encoding: one of 'float32', 'quantized', "
                                         r"got 'float64' \(float64 is for a client's own"):
        cactus.watch(encoding="float64")
    with pytest.raises(ValueError, match=r"^encoding: one of 'float64', 'float32', 'quantized'"):
        cactus.update(encoding="double")


def raw_frame(encoding, **fields):
    return pb.Frame(session="sessions/x", encoding=encoding, **fields)


def test_decode_checks_buffer_sizes():
    F64, F32, Q = pb.FRAME_ENCODING_FLOAT64, pb.FRAME_ENCODING_FLOAT32, pb.FRAME_ENCODING_QUANTIZED
    good = np.arange(9, dtype="<f8").tobytes()
    f = decode(raw_frame(F64, positions=good, normals=good), vertex_count=3)
    np.testing.assert_array_equal(f.V, np.arange(9.0).reshape(3, 3))
    cases = [
        (raw_frame(F64, positions=good[:-8]), 3, None,
         "FLOAT64 frame: positions holds 64 bytes, not a multiple of 24 (3 × float64 per vertex)"),
        (raw_frame(F64, positions=good), 4, None,
         "FLOAT64 frame: positions holds 72 bytes = 3 items of 3 × float64 per vertex, but the "
         "session has 4"),
        # a float32 buffer under a FLOAT64 label: the sizes give it away
        (raw_frame(F64, positions=np.arange(9, dtype="<f4").tobytes()), 3, None,
         "FLOAT64 frame: positions holds 36 bytes, not a multiple of 24"),
        (raw_frame(F64, positions=good, normals=good[:48]), None, None,
         "FLOAT64 frame: 3 positions but 2 normals"),
        (raw_frame(F32, positions=b"\0" * 36, energies=b"\0" * 6), 3, None,
         "FLOAT32 frame: energies holds 6 bytes, not a multiple of 4 (float32 per triangle)"),
        (raw_frame(F32, positions=b"\0" * 36, energies=b"\0" * 8), 3, 1,
         "FLOAT32 frame: energies holds 8 bytes = 2 items of float32 per triangle, but the "
         "session has 1"),
        (raw_frame(Q, vertices=b"\0" * 20), 3, None,
         "QUANTIZED frame: vertices holds 20 bytes, not a multiple of 8 (8 bytes per vertex)"),
        (raw_frame(pb.FRAME_ENCODING_MESHOPT, vertices=b"\0"), None, None,
         "frame encoding 2 is not supported by the Python client"),
    ]
    for frame, n, m, message in cases:
        with pytest.raises(hdeform.FrameDecodeError) as e:
            decode(frame, vertex_count=n, triangle_count=m)
        assert str(e.value).startswith(message), str(e.value)
        assert isinstance(e.value, ValueError)


def glb(positions, indices):
    """A minimal GLB: one primitive, float32 POSITION, uint32 indices."""
    pos = np.asarray(positions, dtype="<f4").tobytes()
    idx = np.asarray(indices, dtype="<u4").tobytes()
    p = np.asarray(positions, dtype=np.float32)
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "buffers": [{"byteLength": len(pos) + len(idx)}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(pos)},
                        {"buffer": 0, "byteOffset": len(pos), "byteLength": len(idx)}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": len(p), "type": "VEC3",
             "min": p.min(axis=0).tolist(), "max": p.max(axis=0).tolist()},
            {"bufferView": 1, "componentType": 5125, "count": len(idx) // 4,
             "type": "SCALAR"}]}
    j = json.dumps(doc).encode()
    j += b" " * (-len(j) % 4)
    body = pos + idx
    total = 12 + 8 + len(j) + 8 + len(body)
    return (struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<II", len(j), 0x4E4F534A)
            + j + struct.pack("<II", len(body), 0x004E4942) + body)


def test_gltf_frames_are_in_base_glb_order(hd, tmp_path):
    # an octahedron with every triangle's corners split (as a flat-shaded glTF is): 24 base
    # vertices over 6 welded ones; frames and Frame.F are in the base GLB's order
    corners = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]],
                       dtype=float)
    tris = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5),
            (0, 3, 5)]
    P = np.array([corners[i] for t in tris for i in t])
    split = np.arange(len(P)).reshape(-1, 3)
    path = tmp_path / "octa.glb"
    path.write_bytes(glb(P, split))
    with hd.upload_file(path) as s:
        assert (s.vertex_count, s.triangle_count) == (24, 8)
        np.testing.assert_array_equal(s.triangles(), split)
        s.constrain(fixed=hdeform.base_ids(P[:, 2] < -0.5),
                    handles=[hdeform.base_ids(P[:, 2] > 0.5)])
        frame = s.update(translate=(0, 0, 0.25))
        assert frame.V.shape == (24, 3)
        np.testing.assert_array_equal(frame.F, split)
        top = P[:, 2] > 0.5
        np.testing.assert_allclose(frame.V[top], P[top] + [0, 0, 0.25], atol=1e-12)
        # welded copies carry identical doubles
        for c in corners:
            rows = frame.V[(P == c).all(axis=1)]
            assert (rows == rows[0]).all()
