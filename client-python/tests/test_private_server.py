"""The private server (issue 38, item 5): its address comes from --ready-file, it exits with
the Python process that started it (--exit-with-parent), even one killed by SIGKILL, and a
missing binary is reported with how to get one."""
import os
import re
import shutil
import signal
import subprocess
import sys
import textwrap
import threading
import time

import pytest

import hdeform
from hdeform import _server


def gone(pid):
    """True once `pid` has exited (a zombie counts: nobody may reap an orphan here)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] in ("Z", "X")
    except FileNotFoundError:
        return True


def cmdline(pid):
    with open(f"/proc/{pid}/cmdline", "rb") as f:
        return [a.decode() for a in f.read().split(b"\0") if a]


def test_handshake_by_ready_file(hd):
    args = cmdline(hd.server.pid)
    assert args[args.index("--port") + 1] == "0"
    assert "--exit-with-parent" in args
    ready = args[args.index("--ready-file") + 1]
    assert os.path.dirname(ready) == os.path.dirname(hd.server.log_path)
    assert hd.address.startswith("127.0.0.1:") and hd.address != "127.0.0.1:0"
    assert hd.server.http_address is None  # no --http-port
    assert os.readlink(f"/proc/{hd.server.pid}/fd/0") == "/dev/null"  # stdin


def test_server_exits_when_its_python_is_killed(tmp_path):
    child = subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent("""
            import sys, time, hdeform
            hd = hdeform.connect()
            assert hd.meshes()
            print(hd.server.pid, flush=True)
            time.sleep(600)
        """)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = child.stdout.readline()
        assert line.strip().isdigit(), child.stderr.read() if child.poll() is not None else line
        server = int(line)
        assert not gone(server)
        args = cmdline(server)
        folder = os.path.dirname(args[args.index("--ready-file") + 1])
        child.send_signal(signal.SIGKILL)  # no atexit, no stop(): only --exit-with-parent
        child.wait(10)
        killed = time.monotonic()
        while not gone(server) and time.monotonic() < killed + 5:
            time.sleep(0.02)
        assert gone(server), f"hdeform-server {server} outlived its killed parent by 5 s"
        print(f"the server exited {time.monotonic() - killed:.2f} s after its parent")
        shutil.rmtree(folder)  # its log and ready file: a killed client cannot remove them
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()


def test_a_server_started_from_a_thread_outlives_the_thread():
    # PR_SET_PDEATHSIG follows the forking *thread*: the client forks its servers from one
    # daemon thread, so a connect() in a short-lived thread keeps its server.
    box = {}
    t = threading.Thread(target=lambda: box.setdefault("hd", hdeform.connect()))
    t.start()
    t.join()
    with box["hd"] as hd:
        time.sleep(0.5)  # the signal would have come by now
        assert not gone(hd.server.pid)
        assert "cactus" in [m.name for m in hd.meshes()]
    assert gone(hd.server.pid)


def test_find_server_order(monkeypatch, tmp_path):
    def exe(path):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("#!/bin/sh\n")
        path.chmod(0o755)
        return str(path)

    explicit = exe(tmp_path / "explicit" / "hdeform-server")
    from_env = exe(tmp_path / "env" / "hdeform-server")
    tree = exe(tmp_path / "tree" / "build" / "server" / "hdeform-server")
    on_path = exe(tmp_path / "bin" / "hdeform-server")
    monkeypatch.setattr(_server, "server_candidates",
                        lambda: [("the source tree", tree)])
    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    monkeypatch.setenv("HDEFORM_SERVER", from_env)
    assert hdeform.find_server(explicit) == explicit
    assert hdeform.find_server() == from_env
    monkeypatch.delenv("HDEFORM_SERVER")
    assert hdeform.find_server() == tree
    os.unlink(tree)
    assert hdeform.find_server() == on_path  # where `cmake --install` puts it
    os.unlink(on_path)
    with pytest.raises(hdeform.ServerStartError) as e:
        hdeform.find_server()
    message = str(e.value)
    assert "no hdeform-server found" in message and tree in message
    assert "cmake -S . -B build && cmake --build build --target hdeform-server" in message
    assert "cmake --install build" in message
    assert "connect(server=" in message and "HDEFORM_SERVER=" in message
    monkeypatch.setenv("HDEFORM_SERVER", str(tmp_path / "nope"))
    with pytest.raises(hdeform.ServerStartError, match="HDEFORM_SERVER .*nope.* is not an "
                                                       "executable file; build it"):
        hdeform.find_server()


def test_the_source_trees_build_is_a_candidate():
    here = os.path.dirname(os.path.abspath(hdeform.__file__))
    tree = os.path.dirname(os.path.dirname(here))
    assert _server.server_candidates()[0] == (
        "the source tree", os.path.join(tree, "build", "server", "hdeform-server"))


def test_an_old_server_without_ready_file_is_named(tmp_path):
    old = tmp_path / "hdeform-server"
    old.write_text("#!/bin/sh\necho 'The following argument was not expected: "
                   "--ready-file' >&2\nexit 109\n")
    old.chmod(0o755)
    with pytest.raises(hdeform.ServerStartError) as e:
        hdeform.connect(server=str(old), timeout=10)
    assert "predates --ready-file" in str(e.value) and "status 109" in str(e.value)
    remove_kept_log(str(e.value))


def remove_kept_log(message):
    """A failed start keeps its log (named in the message) for reading: removed here."""
    log = re.search(r"; log (\S+/server\.log):", message).group(1)
    assert os.path.isfile(log)
    shutil.rmtree(os.path.dirname(log))
