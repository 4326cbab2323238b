"""timeout= on every call that does an RPC, set_beta() for writing β (issue 38, item 4)."""
import inspect
import math
import threading
import time
from concurrent import futures

import grpc
import pytest

import hdeform
from hdeform._proto import pb_grpc

SHORT = 0.05  # seconds: long enough to be sent, and the stalling server never answers


@pytest.fixture(scope="module")
def stalling():
    """The address of a gRPC server of the Deformation service that never answers: each
    call waits until its client gives up, so every deadline surely expires (the real server
    answers most calls in well under any timeout one could pick)."""
    closing = threading.Event()

    def stall(self, request, context):
        while context.is_active() and not closing.is_set():
            time.sleep(0.005)
        context.abort(grpc.StatusCode.CANCELLED, "stalling server stopped")

    methods = [n for n in vars(pb_grpc.DeformationServicer) if not n.startswith("_")]
    servicer = type("Stalling", (pb_grpc.DeformationServicer,), {n: stall for n in methods})()
    server = grpc.server(futures.ThreadPoolExecutor(max_workers=16))
    pb_grpc.add_DeformationServicer_to_server(servicer, server)
    port = server.add_insecure_port("127.0.0.1:0")
    server.start()
    try:
        yield f"127.0.0.1:{port}"
    finally:
        closing.set()
        server.stop(grace=None)


@pytest.fixture
def stalled(stalling, cactus):
    """(client, session): the cactus session as seen through the stalling server."""
    with hdeform.connect(stalling, token="t") as c:
        yield c, hdeform.Session(c, cactus.info, cactus.edit_token)


def public_methods(cls, without=()):
    return {n: f for n, f in inspect.getmembers(cls, inspect.isfunction)
            if not n.startswith("_") and n not in without}


def test_every_call_takes_a_timeout():
    # Methods without an RPC: Client.close (no call), Session.keep (a local flag).
    for cls, without in ((hdeform.Client, {"close"}), (hdeform.Session, {"keep"})):
        methods = public_methods(cls, without)
        assert len(methods) > 5
        for name, fn in methods.items():
            p = inspect.signature(fn).parameters.get("timeout")
            assert p is not None and p.default is None, f"{cls.__name__}.{name}"
    assert "call_timeout" in inspect.signature(hdeform.connect).parameters


def expect_deadline(call, method):
    with pytest.raises(hdeform.DeadlineExceeded) as e:
        call()
    err = e.value
    assert isinstance(err, hdeform.Error) and err.code == grpc.StatusCode.DEADLINE_EXCEEDED
    assert err.message.startswith(f"{method}: ") and "timeout=" in err.message
    assert str(err).startswith("DEADLINE_EXCEEDED: ")
    return err


def test_deadline_exceeded_names_the_call_and_the_timeout(stalled, tmp_path):
    hd, s = stalled
    e = expect_deadline(lambda: s.update(translate=(0, 0, 0.1), timeout=SHORT),
                        "UpdateHandles")
    assert "timeout=0.05 s" in e.message and "may still apply the change" in e.message
    e = expect_deadline(lambda: s.sweep([0, 0.1], timeout=SHORT), "Sweep")
    assert "change" not in e.message  # a read
    expect_deadline(lambda: s.set_beta(0.2, timeout=SHORT), "SetBeta")
    expect_deadline(lambda: s.constrain(fixed=[0], handles=[[1]], timeout=SHORT),
                    "SetConstraints")
    expect_deadline(lambda: s.refresh(timeout=SHORT), "GetSession")
    expect_deadline(lambda: s.history(timeout=SHORT), "ListHistory")
    expect_deadline(lambda: s.mesh_bytes("glb", timeout=SHORT), "GetMesh")  # a stream
    expect_deadline(lambda: s.save(tmp_path / "never.stl", timeout=SHORT), "GetMesh")
    expect_deadline(lambda: s.export_animation(timeout=SHORT), "ExportAnimation")
    expect_deadline(lambda: s.export_rig(tmp_path / "never.glb", timeout=SHORT), "ExportRig")
    expect_deadline(lambda: s.undo(timeout=SHORT), "Undo")
    expect_deadline(lambda: s.delete(timeout=SHORT), "DeleteSession")
    expect_deadline(lambda: hd.meshes(timeout=SHORT), "ListMeshes")
    expect_deadline(lambda: hd.open("cactus", timeout=SHORT), "CreateSession")  # a client stream
    expect_deadline(lambda: hd.session(s.name, timeout=SHORT), "GetSession")
    e = expect_deadline(lambda: s.watch(timeout=SHORT), "WatchSession")
    assert "the stream ended at its timeout=0.05 s" in e.message
    assert not (tmp_path / "never.stl").exists() and not (tmp_path / "never.glb").exists()


def test_a_generous_timeout_changes_nothing(cactus):
    cactus.set_beta(0.1, timeout=60)
    frame = cactus.update(translate=(0, 0, 0.1), timeout=60)
    assert frame.beta == pytest.approx(0.1) and frame.V.shape == (cactus.vertex_count, 3)
    assert len(cactus.sweep([0, 0.1], timeout=60)) == 2
    assert cactus.mesh_bytes("glb", timeout=math.inf)[:4] == b"glTF"


def test_watch_ends_at_its_timeout(cactus):
    started = time.monotonic()
    with cactus.watch(timeout=0.3) as w:  # subscribed, then no frame comes
        with pytest.raises(hdeform.DeadlineExceeded, match="WatchSession: the stream ended at "
                                                           "its timeout=0.3 s"):
            next(iter(w))
    assert 0.29 < time.monotonic() - started < 10


def test_client_call_timeout_is_every_calls_default(hd, cactus, stalling):
    with pytest.raises(ValueError, match=r"^call_timeout: seconds > 0"):
        hdeform.connect(hd.address, token=hd.token, call_timeout=0)
    with hdeform.connect(stalling, call_timeout=SHORT) as impatient:
        assert impatient.call_timeout == SHORT
        e = expect_deadline(impatient.meshes, "ListMeshes")
        assert "timeout=0.05 s" in e.message
        s = hdeform.Session(impatient, cactus.info, cactus.edit_token)
        expect_deadline(lambda: s.update(translate=(0, 0, 0.1)), "UpdateHandles")
        with pytest.raises(hdeform.DeadlineExceeded, match="SetBeta"):
            s.beta = 0.2  # the setter is set_beta() with the client's default
        e = expect_deadline(lambda: s.sweep([0.1], timeout=0.1), "Sweep")  # its own wins
        assert "timeout=0.1 s" in e.message
    # the same against the real server: a call's own timeout (or math.inf: none) wins
    with hdeform.connect(hd.address, token=hd.token, call_timeout=30) as patient:
        assert "cactus" in [m.name for m in patient.meshes(timeout=math.inf)]
        s = patient.session(cactus.name, token=cactus.edit_token)
        assert s.update(translate=(0, 0, 0.1)).measures.e > 0
        # a watch is meant to last: call_timeout does not end it (only its own timeout=)
        with s.watch() as w:
            assert w._deadline.timeout is None
            s.update(translate=(0, 0, 0.2))
            assert next(iter(w)).version > 0
    with hdeform.connect(hd.address, token=hd.token) as default:
        assert default.call_timeout is None  # the default: no deadline


def test_set_beta_writes_and_the_property_reads(cactus):
    assert cactus.set_beta(0.3, timeout=30) is cactus
    assert cactus.beta == pytest.approx(0.3) and not cactus.beta_automatic
    cactus.beta = 0.2  # the documented shorthand
    assert cactus.beta == pytest.approx(0.2)
    cactus.set_beta("auto", timeout=30)
    assert cactus.beta_automatic
