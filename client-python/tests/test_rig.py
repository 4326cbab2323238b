"""Session.export_rig (issue 39): the skinned GLB, its report of LBS against the exact solve
per pose, RigExport.to_csv as `hdeform rig --report` writes it, argument checks and tokens."""
import dataclasses
import json
import os
import struct
import subprocess

import numpy as np
import pytest

import hdeform
from conftest import BENCH

CSV_HEADER = "pose,time_s,max,rms"


def def_pose(s):
    """The cactus .def as rotation and translation about the handle's centroid (the polar
    decomposition's stretch is within 6e-7 of the identity: the 6-digit matrix's rounding)."""
    M = hdeform.read_def(os.path.join(BENCH, "cactus.def"))
    U, S, Vt = np.linalg.svd(M[:3, :3])
    assert np.abs(S - 1).max() < 1e-6
    p = s.pivots[0]
    return hdeform.transform(rotate=U @ Vt, translate=M[:3, :3] @ p + M[:3, 3] - p)


def glb_json(glb):
    magic, version, length = struct.unpack_from("<4sII", glb)
    assert (magic, version, length) == (b"glTF", 2, len(glb))
    json_len, json_type = struct.unpack_from("<II", glb, 12)
    assert json_type == 0x4E4F534A  # "JSON"
    return json.loads(glb[20:20 + json_len])


def test_export_rig_with_timeline(cactus, tmp_path):
    pose = def_pose(cactus)
    cactus.update(transforms=[pose])
    cactus.set_timeline([(0, [None]), (2, [pose])])
    rig = cactus.export_rig(tmp_path / "rig.glb", up="z")
    assert isinstance(rig, hdeform.RigExport)
    assert (tmp_path / "rig.glb").read_bytes() == rig.glb
    assert rig.joints == 2 and rig.influences == 4 and rig.version == cactus.refresh().version
    lo, hi = cactus.bbox
    assert rig.bbox_diagonal == pytest.approx(np.linalg.norm(hi - lo), rel=1e-12)
    assert len(rig.poses) == 3 and all(isinstance(p, hdeform.RigPoseError) for p in rig.poses)
    current, rest, posed = rig.poses
    assert current.current and current.time_s is None
    assert not rest.current and rest.time_s == 0 and not posed.current and posed.time_s == 2
    assert rest.max < 1e-12 and rest.rms <= rest.max  # the rest pose: LBS is the input
    # the key at 2 s is the current pose: the same numbers; LBS is not the exact solve
    assert (posed.max, posed.rms) == (current.max, current.rms)
    assert 0 < current.rms < current.max < 1
    doc = glb_json(rig.glb)
    assert len(doc["skins"]) == 1 and len(doc["skins"][0]["joints"]) == 2
    assert len(doc["animations"]) == 1
    with pytest.raises(dataclasses.FrozenInstanceError):
        rig.joints = 3  # type: ignore[misc]
    assert "glb=" not in repr(rig)  # the bytes are not printed

    still = cactus.export_rig(animation=False, influences=8)
    assert len(still.poses) == 1 and still.poses[0].current and still.influences == 8
    assert "animations" not in glb_json(still.glb)
    attributes = glb_json(still.glb)["meshes"][0]["primitives"][0]["attributes"]
    assert {"JOINTS_0", "WEIGHTS_0", "JOINTS_1", "WEIGHTS_1"} <= set(attributes)


def test_rig_report_csv(cactus, tmp_path):
    pose = def_pose(cactus)
    cactus.update(transforms=[pose])
    cactus.set_timeline([(0, [None]), (2, [pose])])
    rig = cactus.export_rig()
    text = rig.to_csv()
    rig.to_csv(tmp_path / "r.csv")
    assert (tmp_path / "r.csv").read_bytes() == text.encode()  # "\n", no "\r\n"
    lines = text.splitlines()
    assert lines[0] == CSV_HEADER and len(lines) == 4
    rows = [line.split(",") for line in lines[1:]]
    assert [r[:2] for r in rows] == [["current", ""], ["key", "0"], ["key", "2"]]
    for r, p in zip(rows, rig.poses):
        assert (float(r[2]), float(r[3])) == (p.max, p.rms)  # shortest round trip: exact


def test_rig_report_csv_is_the_clis(cactus, tmp_path):
    cli = os.environ.get("HDEFORM_CLI")
    if not cli:
        pytest.skip("HDEFORM_CLI (the built hdeform CLI) is not set; CTest sets it")
    report = tmp_path / "cli.csv"
    r = subprocess.run([cli, "rig", "cactus", "--sel", os.path.join(BENCH, "cactus.sel"),
                        "--def", os.path.join(BENCH, "cactus.def"), "-o",
                        str(tmp_path / "cli.glb"), "--animate", "2", "--up", "z",
                        "--report", str(report)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    theirs = report.read_text().splitlines()
    pose = def_pose(cactus)
    cactus.update(transforms=[pose])
    cactus.set_timeline([(0, [None]), (2, [pose])])
    ours = cactus.export_rig(up="z").to_csv().splitlines()
    assert len(ours) == len(theirs) == 4 and ours[0] == theirs[0] == CSV_HEADER
    for a, b in zip(ours[1:], theirs[1:]):
        fa, fb = a.split(","), b.split(",")
        assert fa[:2] == fb[:2]
        # The CLI applies the .def matrix (with its 6e-7 stretch), this test its rotation and
        # translation: the same pose to ~1e-6 of the diagonal.
        for x, y in zip(fa[2:], fb[2:]):
            assert float(x) == pytest.approx(float(y), abs=1e-5)


def test_export_rig_checks_arguments_before_any_call(cactus):
    dead = hdeform.Client("127.0.0.1:1", ready_timeout=0)
    try:
        offline = hdeform.Session(dead, cactus.info, cactus.edit_token)
        for kwargs, error, match in [
                (dict(influences=6), ValueError, r"^influences: one of 4, 8, got 6"),
                (dict(influences=0), ValueError, r"^influences: one of 4, 8, got 0"),
                (dict(influences=4.0), TypeError, r"^influences: expected 4 or 8"),
                (dict(influences=True), TypeError, r"^influences: expected 4 or 8"),
                (dict(up="x"), ValueError, r"^up: one of 'y', 'z', got 'x'"),
                (dict(up="Y"), ValueError, r"^up: one of 'y', 'z', got 'Y'"),
                (dict(animation="no"), TypeError, r"^animation: expected a bool"),
                (dict(timeout=0), ValueError, r"^timeout: seconds > 0")]:
            with pytest.raises(error, match=match):
                offline.export_rig(**kwargs)
        with pytest.raises(hdeform.Unavailable):  # valid arguments do reach the (dead) server
            offline.export_rig(influences=np.int64(8), up="z", timeout=5)
    finally:
        dead.close()


def test_export_rig_needs_the_edit_token(hd, cactus):
    anon = hdeform.connect(hd.address)
    try:
        viewer = anon.session(cactus.name, token=cactus.view_token)
        with pytest.raises(hdeform.PermissionDenied, match="edit token"):
            viewer.export_rig()
    finally:
        anon.close()


def test_export_rig_without_constraints(hd):
    with hd.open("cactus") as s:
        with pytest.raises(hdeform.FailedPrecondition, match="SetConstraints"):
            s.export_rig()
