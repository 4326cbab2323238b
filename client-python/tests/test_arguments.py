"""numpy habits (issue 38, item 3): boolean masks as vertex selections, axis_angle("x", 30),
and argument mistakes caught before any call, naming the argument."""
import math
import os

import numpy as np
import pytest

import hdeform
from conftest import BENCH


@pytest.fixture
def offline(cactus):
    """The cactus session seen through a client whose server does not exist: any RPC would
    fail with UNAVAILABLE, so a ValueError/TypeError shows the check ran before the call."""
    dead = hdeform.Client("127.0.0.1:1", ready_timeout=0)
    try:
        yield hdeform.Session(dead, cactus.info, cactus.edit_token)
    finally:
        dead.close()


def bar_masks(s):
    V, _ = s.rest()
    lo, hi = s.bbox
    z, h = V[:, 2], hi[2] - lo[2]
    return z <= lo[2] + 0.05 * h, z >= hi[2] - 0.05 * h


def test_boolean_masks_select_vertices(hd):
    with hd.open("bar") as s:
        bottom, top = bar_masks(s)
        assert bottom.dtype == np.bool_ and len(bottom) == s.vertex_count
        s.constrain(fixed=bottom, handles=[top])
        np.testing.assert_array_equal(s.fixed, np.flatnonzero(bottom))
        np.testing.assert_array_equal(s.handles[0], np.flatnonzero(top))
        # the same through ids(), base_ids(), a dict and a list of Python bools
        s.constrain(fixed=hdeform.ids(bottom), handles=[hdeform.base_ids(top)])
        np.testing.assert_array_equal(s.fixed, np.flatnonzero(bottom))
        np.testing.assert_array_equal(s.handles[0], np.flatnonzero(top))
        s.constrain(fixed={"ids": bottom}, handles=[top.tolist()])
        np.testing.assert_array_equal(s.handles[0], np.flatnonzero(top))
        # a mask in a union, and as a local β region
        half = top & (np.arange(len(top)) % 2 == 0)
        s.constrain(fixed=bottom, handles=[[hdeform.base_ids(half), hdeform.ids(top & ~half)]])
        np.testing.assert_array_equal(s.handles[0], np.flatnonzero(top))
        s.set_beta(0.05, local=[{"region": top, "beta": 0.3, "falloff_radius": 0.1}])
        assert len(s.info.beta.local) == 1
        assert s.update(translate=(0, 0, 0.1)).measures.e > 0


def test_mask_mistakes_name_the_argument(hd):
    with hd.open("bar") as s:
        bottom, top = bar_masks(s)
        s.constrain(fixed=bottom, handles=[top])
        version = s.refresh().version
        n = s.vertex_count
        with pytest.raises(ValueError, match=rf"^fixed: a boolean mask of 3 entries, but the "
                                             rf"session has {n} vertices"):
            s.constrain(fixed=np.ones(3, dtype=bool), handles=[top])
        with pytest.raises(ValueError, match=r"^handles\[0\]: a boolean mask of"):
            s.constrain(fixed=bottom, handles=[top[:-1]])
        with pytest.raises(ValueError, match=r"^handles\[0\]\[1\]: a boolean mask of"):
            s.constrain(fixed=bottom, handles=[[hdeform.ids([0]), hdeform.base_ids(top[1:])]])
        with pytest.raises(ValueError, match=r"^local\[0\]\.region: a boolean mask of"):
            s.set_beta(0.1, local=[{"region": np.append(top, True), "beta": 0.2}])
        with pytest.raises(ValueError, match=r"^fixed: a boolean mask must be 1-D"):
            s.constrain(fixed=np.stack([bottom, bottom]), handles=[top])
        with pytest.raises(TypeError, match=r"^fixed: vertex ids must be integers"):
            s.constrain(fixed=np.array([0.5, 1.5]), handles=[top])
        with pytest.raises(TypeError, match=r"^handles: expected a list with one region"):
            s.constrain(fixed=bottom, handles=top)  # would be one handle per vertex
        assert s.refresh().version == version  # none of them reached the server


def test_axis_angle_by_name():
    x = hdeform.axis_angle([1, 0, 0], 30)
    np.testing.assert_array_equal(hdeform.axis_angle("x", 30), x)
    np.testing.assert_array_equal(hdeform.axis_angle("X", 30), x)
    np.testing.assert_array_equal(hdeform.axis_angle("+x", 30), x)
    np.testing.assert_array_equal(hdeform.axis_angle("x,30", None), x)  # the CLI's text
    np.testing.assert_array_equal(hdeform.axis_angle("x,30"), x)
    np.testing.assert_array_equal(hdeform.axis_angle("-x", 30), hdeform.axis_angle([-1, 0, 0], 30))
    np.testing.assert_array_equal(hdeform.axis_angle("-x", 30), hdeform.axis_angle("x", -30))
    np.testing.assert_array_equal(hdeform.axis_angle("y", 90), hdeform.axis_angle([0, 2, 0], 90))
    np.testing.assert_array_equal(hdeform.axis_angle("z", 45), hdeform.axis_angle("0,0,1,45"))
    c, s = np.cos(np.radians(15)), np.sin(np.radians(15))
    np.testing.assert_allclose(hdeform.axis_angle("z", 30), [c, 0, 0, s], atol=1e-16)
    with pytest.raises(ValueError, match=r"^axis_angle axis: 'x', 'y', 'z'"):
        hdeform.axis_angle("w", 30)
    with pytest.raises(ValueError, match=r"^axis_angle axis: expected shape 3, got 2"):
        hdeform.axis_angle([1, 0], 30)
    with pytest.raises(ValueError, match=r"^axis_angle axis: must be non-zero"):
        hdeform.axis_angle([0, 0, 0], 30)
    with pytest.raises(TypeError, match=r"^axis_angle degrees: expected a number"):
        hdeform.axis_angle("x", "30")
    with pytest.raises(ValueError, match=r"^axis_angle: expected 'AXIS,DEG'"):
        hdeform.axis_angle("x")
    with pytest.raises(ValueError, match=r"^axis_angle degrees: expected a finite number"):
        hdeform.axis_angle("x", math.nan)


def test_axis_angle_rotates_like_the_matrix(cactus):
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    R = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    a = cactus.update(rotate=hdeform.axis_angle("x", 30)).V
    b = cactus.update(rotate=R).V
    lo, hi = cactus.bbox
    assert np.abs(a - b).max() <= 1e-9 * np.linalg.norm(hi - lo)


@pytest.mark.parametrize("value,error,match", [
    (1, ValueError, r"^beta: must be in \[0, 1\), got 1\.0"),
    (1.5, ValueError, r"^beta: must be in \[0, 1\)"),
    (-0.1, ValueError, r"^beta: must be in \[0, 1\)"),
    (math.nan, ValueError, r"^beta: expected a finite number"),
    (math.inf, ValueError, r"^beta: expected a finite number"),
    (True, TypeError, r"^beta: expected a number, got bool"),
    ("0.1", ValueError, r"^beta: a number in \[0, 1\) or 'auto'"),
    (None, TypeError, r"^beta: expected a number"),
])
def test_beta_is_checked_before_the_call(offline, value, error, match):
    with pytest.raises(error, match=match):
        offline.set_beta(value)
    with pytest.raises(error, match=match):
        offline.beta = value


def test_beta_lists_are_checked_before_the_call(offline):
    handle = hdeform.sel_file(os.path.join(BENCH, "cactus.sel"), hdeform.HANDLE)
    with pytest.raises(ValueError, match=r"^local\[0\]\.beta: must be in \[0, 1\)"):
        offline.set_beta(0.1, local=[{"region": handle, "beta": 1.0}])
    with pytest.raises(ValueError, match=r"^local\[0\]\.falloff_radius: must be >= 0"):
        offline.set_beta(0.1, local=[{"region": handle, "beta": 0.2, "falloff_radius": -1}])
    with pytest.raises(TypeError, match=r"^local\[0\]: expected a dict with 'region'"):
        offline.set_beta(0.1, local=[handle])
    with pytest.raises(ValueError, match=r"^betas\[2\]: must be in \[0, 1\), got 1\.0"):
        offline.sweep([0, 0.5, 1])
    with pytest.raises(ValueError, match=r"^betas\[0\]: expected a finite number"):
        offline.sweep(np.array([np.nan]))
    with pytest.raises(ValueError, match=r"^betas: no values"):
        offline.sweep([])
    with pytest.raises(TypeError, match=r"^betas: expected a list of numbers"):
        offline.sweep(0.1)
    with pytest.raises(ValueError, match=r"^keys\[1\] beta: must be in \[0, 1\)"):
        offline.set_timeline([(0, [None]), (1, [None], 2.0)])
    with pytest.raises(ValueError, match=r"^units: one of 'area', 'raw', got 'cm'"):
        offline.set_beta(0.1, units="cm")


def test_wrong_types_and_shapes_name_the_argument(offline):
    cases = [
        (ValueError, r"^translate: expected shape 3, got 2",
         lambda: offline.update(translate=[1, 2])),
        (TypeError, r"^translate: expected numbers of shape 3",
         lambda: offline.update(translate="up")),
        (ValueError, r"^translate: expected finite numbers",
         lambda: offline.update(translate=[0, 0, np.inf])),
        (ValueError, r"^pivot: expected shape 3", lambda: offline.update(pivot=[0, 0])),
        (ValueError, r"^matrix: expected shape 4×4, got 3×3",
         lambda: offline.update(matrix=np.eye(3))),
        (ValueError, r"^scale: expected 1, 3 or 3×3 numbers",
         lambda: offline.update(scale=[1, 2])),
        (ValueError, r"^rotate: expected a quaternion", lambda: offline.update(rotate=[1, 0])),
        (TypeError, r"^rotate: expected a quaternion", lambda: offline.update(rotate="x")),
        (ValueError, r"^encoding: one of", lambda: offline.update(encoding="meshopt")),
        (ValueError, r"^transform dict: unknown keys \['translation'\]",
         lambda: offline.update(transforms=[{"translation": (0, 0, 1)}])),
        (ValueError, r"^box min: expected shape 3",
         lambda: offline.constrain(fixed=hdeform.box([0, 0], [1, 1, 1]), handles=[[0]])),
        (TypeError, r"^sphere radius: expected a number",
         lambda: hdeform.sphere([0, 0, 0], "1")),
        (TypeError, r"^fixed: expected a selector", lambda: offline.constrain(fixed="top")),
        (ValueError, r"^fixed: a selector dict has one key of",
         lambda: offline.constrain(fixed={"cube": 1}, handles=[[0]])),
        (ValueError, r"^easing: one of 'linear', 'smoothstep', got 'ease'",
         lambda: offline.set_timeline([], easing="ease")),
        (TypeError, r"^keys\[0\]: expected \(time_s, transforms\[, beta\]\)",
         lambda: offline.set_timeline([1.0])),
        (TypeError, r"^keys\[0\]: a dict needs 'time' and 'transforms'",
         lambda: offline.set_timeline([{"t": 0, "transforms": [None]}])),
        (TypeError, r"^keys\[0\]: unknown key\(s\) \['ease'\]",
         lambda: offline.set_timeline([{"time": 0, "transforms": [None], "ease": "linear"}])),
        (ValueError, r"^keys\[0\] easing: one of 'linear', 'smoothstep', got 'fast'",
         lambda: offline.set_timeline([{"time": 0, "transforms": [None], "easing": "fast"}])),
        (ValueError, r"^up: one of 'y', 'z', got 'x'", lambda: offline.export_animation(up="x")),
        (TypeError, r"^fps: expected a number", lambda: offline.export_animation(fps="24")),
        (ValueError, r"^format: one of", lambda: offline.mesh_bytes("3mf")),
        (ValueError, r"^path: the extension picks the format", lambda: offline.save("out.3mf")),
        (ValueError, r"^timeout: seconds > 0", lambda: offline.refresh(timeout=0)),
        (ValueError, r"^timeout: seconds > 0", lambda: offline.update(timeout=-1)),
        (TypeError, r"^timeout: expected a number", lambda: offline.refresh(timeout="5")),
        (ValueError, r"^V: expected an n×3 array",
         lambda: offline.client.upload(np.zeros((4, 2)), [[0, 1, 2]])),
        (TypeError, r"^F: vertex ids must be integers",
         lambda: offline.client.upload(np.zeros((4, 3)), np.zeros((1, 3)))),
        (TypeError, r"^mesh: a library mesh name", lambda: offline.client.open(None)),
    ]
    for error, match, call in cases:
        with pytest.raises(error, match=match):
            call()
