import dataclasses
import os
import socket
import subprocess
import sys

import numpy as np
import pytest

import hdeform
from conftest import BENCH, DATA, HERE


def diag(s):
    lo, hi = s.bbox
    return np.linalg.norm(hi - lo)


def test_private_server_and_library(hd):
    assert hd.server is not None and hd.address.startswith("127.0.0.1:")
    names = [m.name for m in hd.meshes()]
    assert "cactus" in names and "bar" in names


def test_constrain_by_sel_file(cactus):
    assert cactus.handle_count == 1
    sel = np.loadtxt(os.path.join(BENCH, "cactus.sel"), comments="#", dtype=int)
    np.testing.assert_array_equal(cactus.fixed, np.flatnonzero(sel == 0))
    np.testing.assert_array_equal(cactus.handles[0], np.flatnonzero(sel == 2))


def test_identity_reproduces_rest_and_translation_moves_handle(cactus):
    V0, F0 = cactus.rest()
    assert V0.shape == (cactus.vertex_count, 3) and F0.shape == (cactus.triangle_count, 3)
    tol = 1e-9 * diag(cactus)
    frame = cactus.update()
    assert np.abs(frame.V - V0).max() <= tol
    f32 = cactus.update(encoding="float32")
    assert f32.encoding == "float32" and f32.V.dtype == np.float64
    assert f32.V.shape == V0.shape and f32.N.shape == V0.shape
    assert np.abs(f32.V - V0).max() <= 1e-6 * diag(cactus)
    np.testing.assert_allclose(np.linalg.norm(f32.N, axis=1), 1, atol=1e-5)
    assert f32.measures.flips == 0 and abs(f32.measures.e) < 1e-12

    t = np.array([0.05, -0.02, 0.1])
    moved = cactus.update(translate=t)
    h, fixed = cactus.handles[0], cactus.fixed
    assert np.abs(moved.V[h] - V0[h] - t).max() <= tol
    assert np.abs(moved.V[fixed] - V0[fixed]).max() <= tol
    assert isinstance(moved.measures, hdeform.Measures) and moved.measures.e > 0


def test_rotation_forms_agree(cactus):
    q = hdeform.axis_angle([1, 0, 0], 30)
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    R = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    a = cactus.update(rotate=q).V
    b = cactus.update(rotate=R).V
    assert np.abs(a - b).max() <= 1e-9 * diag(cactus)
    m = cactus.update(matrix=hdeform.read_def(os.path.join(BENCH, "cactus.def")))
    assert m.measures.e > 0


def test_beta(cactus):
    cactus.beta = 0.1
    assert cactus.beta == pytest.approx(0.1) and cactus.beta_units == "area"
    cactus.set_beta(0.25, units="raw")
    assert cactus.beta_units == "raw"
    cactus.update(matrix=hdeform.read_def(os.path.join(BENCH, "cactus.def")))
    cactus.beta = "auto"
    assert cactus.beta_automatic and 0 <= cactus.beta < 1
    frame = cactus.update()
    assert frame.beta_automatic and frame.beta == pytest.approx(cactus.beta)
    cactus.set_beta(0.05, local=[{"region": hdeform.sel_file(os.path.join(BENCH, "cactus.sel"),
                                                             hdeform.HANDLE),
                                  "beta": 0.3, "falloff_radius": 0.2}])
    assert len(cactus.info.beta.local) == 1


def test_sweep(cactus):
    cactus.update(matrix=hdeform.read_def(os.path.join(BENCH, "cactus.def")))
    rows = cactus.sweep([0, 0.1, 0.25])
    assert [r.beta for r in rows] == [0, 0.1, 0.25]
    assert all(isinstance(r.measures, hdeform.Measures) and r.measures.e > 0 for r in rows)
    assert rows.records()[1]["beta"] == 0.1
    pandas = pytest.importorskip("pandas")
    df = rows.to_dataframe()
    assert isinstance(df, pandas.DataFrame) and list(df["beta"]) == [0, 0.1, 0.25]


def test_constrain_by_ids_and_selectors(hd):
    with hd.open("bar") as s:
        V, _ = s.rest()
        lo, hi = s.bbox
        z = V[:, 2]
        bottom = np.flatnonzero(z <= lo[2] + 0.05 * (hi[2] - lo[2]))
        s.constrain(fixed=bottom, handles=[hdeform.half_space([0, 0, 1], hi[2] - 0.05 * (hi[2] - lo[2]))])
        np.testing.assert_array_equal(s.fixed, bottom)
        np.testing.assert_array_equal(s.handles[0], np.flatnonzero(z >= hi[2] - 0.05 * (hi[2] - lo[2])))
        s.constrain(fixed={"box": (lo - 1, [hi[0] + 1, hi[1] + 1, lo[2] + 0.05 * (hi[2] - lo[2])])},
                    handles=[[hdeform.ids(s.handles[0][:3]), hdeform.ids(s.handles[0][3:])]])
        np.testing.assert_array_equal(s.fixed, bottom)
        with pytest.raises(hdeform.InvalidArgument) as e:
            s.constrain(fixed=bottom, handles=[[len(V) + 5]])
        assert str(len(V) + 5) in e.value.message and e.value.code.name == "INVALID_ARGUMENT"


def test_quantized_frames(cactus):
    t = [0, 0, 0.1]
    exact = cactus.update(translate=t)
    q = cactus.update(translate=t, encoding="quantized", energies=True)
    assert q.encoding == "quantized" and q.energies.shape == (cactus.triangle_count,)
    extent = diag(cactus)
    assert np.abs(q.V - exact.V).max() <= extent / 65535
    cos = np.clip((q.N * exact.N).sum(axis=1), -1, 1)
    assert np.degrees(np.arccos(cos)).max() < 1.5


def test_watch_sees_update_from_another_connection(hd, cactus):
    with cactus.watch() as w:
        assert w.state is not None and w.state.name == cactus.name
        other = hdeform.connect(hd.address, token=cactus.edit_token)
        try:
            sent = other.session(cactus.name).update(translate=[0, 0.1, 0])
        finally:
            other.close()
        frame = next(iter(w))
        assert frame.version == sent.version and frame.V.shape == (cactus.vertex_count, 3)
        # a watch's frames are float32 (shared by every watcher); the sender's are the doubles
        assert frame.encoding == "float32" and sent.encoding == "float64"
        np.testing.assert_array_equal(frame.V, sent.V.astype(np.float32).astype(np.float64))


def test_tokens(hd, cactus):
    anon = hdeform.connect(hd.address)
    try:
        with pytest.raises(hdeform.Unauthenticated):
            anon.session(cactus.name)
        with pytest.raises(hdeform.PermissionDenied) as e:
            anon.session(cactus.name, token="0" * 64)
        assert e.value.message
        viewer = anon.session(cactus.name, token=cactus.view_token)
        assert viewer.vertex_count == cactus.vertex_count
        with pytest.raises(hdeform.PermissionDenied):
            viewer.update()
        editor = anon.session(cactus.name, token=cactus.edit_token)
        assert editor.update().measures is not None
        # Without the operator token an unknown id answers like a session the token does
        # not open: ids cannot be probed.
        with pytest.raises(hdeform.PermissionDenied, match="opens no session of that name"):
            anon.session("sessions/nope", token=cactus.edit_token)
    finally:
        anon.close()


def test_upload_small_mesh(hd):
    # a tetrahedron: 4 vertices, 4 triangles; vertex order is kept
    V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0 / 3]])
    F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    with hd.upload(V, F) as s:
        assert (s.vertex_count, s.triangle_count) == (4, 4)
        R, RF = s.rest()
        np.testing.assert_array_equal(R, V)
        np.testing.assert_array_equal(RF, F)
        s.constrain(fixed=[0], handles=[[3]])
        f = s.update(translate=[0, 0, 0.5])
        np.testing.assert_allclose(f.V[3], V[3] + [0, 0, 0.5], atol=1e-12)
        np.testing.assert_array_equal(f.V[0], V[0])
    with pytest.raises(hdeform.InvalidArgument):
        hd.upload(V, F[:1] * 0)  # degenerate triangle
    with hd.upload_file(os.path.join(DATA, "botsch-sorkine", "bar.off")) as s:
        assert s.vertex_count > 1000


def test_context_manager_deletes(hd):
    with hd.open("cylinder") as s:
        name = s.name
        assert name in hd.sessions()
    assert s.deleted and name not in hd.sessions()
    with pytest.raises(hdeform.NotFound):
        hd.session(name)
    kept = hd.open("cylinder").keep()
    with hdeform.connect(hd.address, token=hd.token) as other:
        created = other.open("cylinder")
        assert created.name in hd.sessions()
    assert created.name not in hd.sessions() and kept.name in hd.sessions()
    kept.delete()


def test_server_start_failure_reports_log(tmp_path):
    bad = tmp_path / "hdeform-server"
    bad.write_text("#!/bin/sh\necho 'boom: cannot start' >&2\nexit 3\n")
    bad.chmod(0o755)
    with pytest.raises(hdeform.ServerStartError) as e:
        hdeform.connect(server=str(bad), timeout=10)
    assert "boom: cannot start" in str(e.value) and "status 3" in str(e.value)
    from test_private_server import remove_kept_log
    remove_kept_log(str(e.value))


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_private_server_ignores_the_callers_hdeform_variables(monkeypatch, tmp_path):
    # Inherited, these would open an HTTP door serving the whole filesystem, refuse every
    # session and hide the mesh library.
    http_port = _free_port()
    monkeypatch.setenv("HDEFORM_HTTP_PORT", str(http_port))
    monkeypatch.setenv("HDEFORM_WEB_ROOT", "/")
    monkeypatch.setenv("HDEFORM_MAX_SESSIONS", "0")
    monkeypatch.setenv("HDEFORM_MESH_DIR", str(tmp_path))
    monkeypatch.setenv("HDEFORM_ADMIN_TOKEN", "the-callers-token")
    monkeypatch.setenv("UNRELATED_PARENT_VARIABLE", "not for the server")
    with hdeform.connect() as hd:
        names = [m.name for m in hd.meshes()]  # a real call: the server is up and answering
        with socket.socket() as probe:
            probe.settimeout(5)
            with pytest.raises(ConnectionRefusedError):
                probe.connect(("127.0.0.1", http_port))
        assert "http on" not in hd.server.log()
        assert "cactus" in names
        with hd.open("cactus") as s:
            assert s.vertex_count > 0
        environ = f"/proc/{hd.server.process.pid}/environ"
        if os.path.exists(environ):
            with open(environ, "rb") as f:
                env = dict(v.split(b"=", 1) for v in f.read().split(b"\0") if b"=" in v)
            assert {k for k in env if k.startswith(b"HDEFORM_")} == {b"HDEFORM_ADMIN_TOKEN"}
            assert env[b"HDEFORM_ADMIN_TOKEN"].decode() == hd.server.admin_token
            assert b"UNRELATED_PARENT_VARIABLE" not in env


@pytest.mark.parametrize("script,args", [
    ("beta_study.py", ["--csv", "study.csv", "--betas", "0,0.1"]),
    ("batch.py", [BENCH, "out"]),
])
def test_examples(tmp_path, script, args):
    path = os.path.join(HERE, "..", "examples", script)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [os.path.join(HERE, "..")] + [p for p in sys.path if p]))
    r = subprocess.run([sys.executable, path] + args, cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    if script == "beta_study.py":
        lines = (tmp_path / "study.csv").read_text().splitlines()
        assert lines[0] == "beta,E,E_iso_N,E_conf_N,E_area_pct,max_e_iso,max_e_conf,max_ef2,flips"
        assert len(lines) == 3 and lines[1].startswith("0,") and lines[2].startswith("0.1,")
    else:
        assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
            "bar.glb", "cactus.glb", "cylinder.glb", "measures.csv", "plane.glb"]
        assert (tmp_path / "out" / "cactus.glb").read_bytes()[:4] == b"glTF"


def test_undo_redo_history_and_snapshots(cactus):
    cactus.update(translate=(0.05, 0, 0))
    moved = cactus.refresh().info.transforms[0].translation.x
    assert moved == 0.05
    steps = cactus.history()
    assert isinstance(steps[0], hdeform.HistoryStep)
    assert steps[0].kind == "move" and steps[0].summary == "moved handle 0"
    assert steps[0].handles == (0,) and steps[0].client_id == cactus.client_id
    assert steps[-1].kind == "constraints" and [s.id for s in steps] == [2, 1]
    cactus.undo()
    assert cactus.info.transforms[0].translation.x == 0
    assert cactus.history(limit=1)[0].kind == "undo" and cactus.history(limit=1)[0].target == 2
    cactus.redo()
    assert cactus.info.transforms[0].translation.x == 0.05
    with pytest.raises(hdeform.Error) as e:
        cactus.redo()  # nothing left to redo: the server's message comes through
    assert "nothing to redo" in str(e.value)

    saved = cactus.save_snapshot("moved")
    assert isinstance(saved, hdeform.Snapshot) and saved.name == "moved"
    assert saved.transforms[0].translate == (0.05, 0.0, 0.0) and saved.handle_count == 1
    cactus.update(translate=(0, 0.1, 0))
    assert cactus.snapshots() == {"moved": saved}
    cactus.restore_snapshot("moved")
    assert cactus.info.transforms[0].translation.x == 0.05
    assert cactus.info.transforms[0].translation.y == 0
    cactus.delete_snapshot("moved")
    assert cactus.snapshots() == {}
    assert cactus.history(limit=1)[0].kind == "snapshot_delete"
    assert cactus.history(limit=1)[0].snapshot == "moved"
    cactus.undo()  # a delete is a step: the snapshot comes back
    assert set(cactus.snapshots()) == {"moved"}


def test_changes_carry_a_request_id_and_a_repeat_applies_nothing(cactus):
    from hdeform._proto import pb
    cactus.update(translate=(0.05, 0, 0))
    cactus.update(translate=(0.1, 0, 0))
    r = pb.UndoRequest(name=cactus.name, client_id=cactus.client_id)
    first = cactus._call("Undo", r)
    assert len(r.request_id) == 32  # filled in by the client
    again = cactus._call("Undo", r)  # as a retry after a lost answer would
    assert again == first
    assert [s.kind for s in cactus.history(limit=2)] == ["undo", "move"]
    assert cactus.refresh().info.transforms[0].translation.x == 0.05


def test_new_constraints_keep_another_clients_keys_unless_asked(cactus):
    cactus.set_timeline([(0, [None]), (1, [dict(translate=(0, 0, 0.2))])])
    other = cactus.client.session(cactus.name, token=cactus.edit_token)  # another script
    fixed, handle = cactus.fixed, cactus.handles[0]
    split = [hdeform.ids(handle[:3]), hdeform.ids(handle[3:])]  # two handles now
    with pytest.raises(hdeform.Error) as e:
        other.constrain(fixed=fixed, handles=split)
    assert e.value.code.name == "ABORTED" and "2 key(s)" in str(e.value)
    assert len(cactus.timeline().keys) == 2
    other.constrain(fixed=fixed, handles=split, discard_timeline=True)
    assert len(cactus.timeline().keys) == 0
    other.undo()
    assert len(cactus.timeline().keys) == 2
    assert cactus.history(limit=1)[0].kind == "undo"


def test_timeline_pose_and_animated_glb(cactus, tmp_path):
    import struct
    t = cactus.set_timeline([(0, [None]), (1, [dict(translate=(0, 0, 0.2))], 0.25),
                             (2, [dict(translate=(0, 0, 0.4), rotate=(0.9659258262890683, 0.25881904510252074, 0, 0))])],
                            easing="smoothstep")
    assert isinstance(t, hdeform.Timeline) and t == cactus.timeline()
    assert len(t.keys) == 3 and t.easing == "smoothstep" and t.client_id == cactus.client_id
    assert t.keys[1].time_s == 1 and t.keys[1].transforms[0].translate == (0, 0, 0.2)
    assert t.keys[1].beta == hdeform.Beta(0.25, "area") and t.keys[0].beta is None
    mid = cactus.pose_at(0.5)  # smoothstep(0.5) = 0.5: halfway to the first move
    assert isinstance(mid, hdeform.Keyframe) and mid.time_s == 0.5
    assert abs(mid.transforms[0].translate[2] - 0.1) < 1e-12
    assert mid.beta is None and cactus.pose_at(1.5).beta.value == 0.25
    # A key's own easing: the first segment linear in a smoothstep timeline.
    t2 = cactus.set_timeline([dict(time=0, transforms=[None], easing="linear"),
                              (1, [dict(translate=(0, 0, 0.2))])], easing="smoothstep")
    assert t2.keys[0].easing == "linear" and t2.keys[1].easing is None
    assert abs(cactus.pose_at(0.25).transforms[0].translate[2] - 0.05) < 1e-12  # not 0.03125
    t = cactus.set_timeline([(0, [None]), (1, [dict(translate=(0, 0, 0.2))], 0.25),
                             (2, [dict(translate=(0, 0, 0.4), rotate=(0.9659258262890683, 0.25881904510252074, 0, 0))])],
                            easing="smoothstep")
    shown = cactus.update(transforms=list(mid.transforms))  # a Keyframe's pose, shown
    assert shown.measures.e > 0
    with pytest.raises(dataclasses.FrozenInstanceError):
        mid.time_s = 1  # type: ignore[misc]
    data = cactus.export_animation(tmp_path / "anim.glb", fps=4)
    assert data[:4] == b"glTF" and (tmp_path / "anim.glb").read_bytes() == data
    # GLB header: magic, version 2, total length.
    assert struct.unpack("<4sII", data[:12])[1:] == (2, len(data))
    with pytest.raises(hdeform.Error) as e:
        cactus.export_animation(fps=1000)
    assert "fps" in str(e.value)
    cactus.set_timeline([])
    with pytest.raises(hdeform.Error) as e:
        cactus.pose_at(1)
    assert "no timeline" in str(e.value)


def test_compressed_glb(cactus, tmp_path):
    cactus.update(translate=[0.05, 0, 0.1])
    plain = cactus.mesh_bytes("glb")
    q = cactus.mesh_bytes("glb", compression="quantized")
    m = tmp_path / "c.glb"
    cactus.save(m, compression="meshopt")
    packed = m.read_bytes()
    assert q[:4] == packed[:4] == b"glTF"
    assert b"KHR_mesh_quantization" in q and b"EXT_meshopt_compression" not in q
    assert b"EXT_meshopt_compression" in packed
    assert len(packed) < len(q) < 0.6 * len(plain)
    with pytest.raises(ValueError, match="compression"):
        cactus.mesh_bytes("glb", compression="draco")
    with pytest.raises(hdeform.InvalidArgument, match="GLB only"):
        cactus.mesh_bytes("obj", compression="quantized")
