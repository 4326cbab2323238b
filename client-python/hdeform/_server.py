"""The embedded default: a private hdeform-server on a free loopback port.

The server is started with `--port 0 --ready-file PATH --exit-with-parent`: it writes the
addresses it bound to PATH (JSON, atomically) once it serves, and it shuts down when the
process that started it exits, even by SIGKILL (PR_SET_PDEATHSIG). That signal follows the
*thread* that forked the server, so every private server is forked by one daemon thread that
lives as long as the process (not by the calling thread, which may end first)."""
import atexit
import concurrent.futures
import json
import os
import queue
import secrets
import shutil
import subprocess
import tempfile
import threading
import time
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, TypeVar, Union

from ._errors import ServerStartError

PathLike = Union[str, "os.PathLike[str]"]
T = TypeVar("T")

# What the private server inherits from the caller's environment: nothing else, since every
# HDEFORM_* variable is a server setting (--http-port, --web-root, limits, TLS, ...).
_INHERITED = frozenset((
    "PATH", "LANG", "TMPDIR",  # a process's basics: program lookup, locale, temporary files
    "LD_LIBRARY_PATH",  # a server linked against libraries outside the loader's default path
    # sanitizer builds (scripts/sanitize.sh, scripts/tsan.sh): suppressions, halt_on_error
    "ASAN_OPTIONS", "LSAN_OPTIONS", "TSAN_OPTIONS", "UBSAN_OPTIONS", "MSAN_OPTIONS",
))
# Not HOME / XDG_DATA_HOME: the server reads them only for its default --state-dir, and the
# private server always gets --state-dir or --no-state.

HOW_TO_GET_ONE = (
    "build it from the source tree: cmake -S . -B build && cmake --build build --target "
    "hdeform-server (then `cmake --install build` puts hdeform-server in PREFIX/bin, on PATH), "
    "or pass connect(server='/path/to/hdeform-server') or set HDEFORM_SERVER=/path/to/"
    "hdeform-server")


def server_environment(admin_token: str) -> Dict[str, str]:
    """The private server's environment: the allow-listed variables of this process (LC_*
    too) and HDEFORM_ADMIN_TOKEN; none of the caller's other (HDEFORM_*) variables."""
    env = {k: v for k, v in os.environ.items() if k in _INHERITED or k.startswith("LC_")}
    env["HDEFORM_ADMIN_TOKEN"] = admin_token
    return env


def _executable(path: str) -> bool:
    return os.path.isfile(path) and os.access(path, os.X_OK)


def server_candidates() -> List[Tuple[str, str]]:
    """(where, path) of the build-tree places find_server() looks at, in order: the build
    folder of the source tree this package sits in, then that of the current folder."""
    here = os.path.dirname(os.path.abspath(__file__))
    out = []
    for where, root in (("the source tree", os.path.dirname(os.path.dirname(here))),
                        ("the current folder", os.getcwd())):
        out.append((where, os.path.join(root, "build", "server", "hdeform-server")))
    return out


def find_server(binary: Optional[PathLike] = None) -> str:
    """The hdeform-server to start: `binary`, else $HDEFORM_SERVER, else the build tree's
    build/server/hdeform-server (of the source tree this package sits in, then of the current
    folder), else `hdeform-server` on PATH (where `cmake --install` puts it). None found:
    ServerStartError saying how to get one."""
    for what, path in (("server=", os.fspath(binary) if binary else None),
                       ("HDEFORM_SERVER", os.environ.get("HDEFORM_SERVER") or None)):
        if path is not None:
            if not _executable(path):
                raise ServerStartError(f"{what} {path!r} is not an executable file; "
                                       + HOW_TO_GET_ONE)
            return path
    looked = []
    for where, candidate in server_candidates():
        if _executable(candidate):
            return candidate
        looked.append(f"{candidate} ({where})")
    on_path = shutil.which("hdeform-server")
    if on_path:
        return on_path
    looked.append("hdeform-server on PATH")
    raise ServerStartError(
        "no hdeform-server found (no server= argument, HDEFORM_SERVER unset; looked for "
        + ", ".join(looked) + "): " + HOW_TO_GET_ONE)


def _tail(path: str, lines: int = 20) -> str:
    try:
        with open(path, "rb") as f:
            return b"".join(f.readlines()[-lines:]).decode(errors="replace")
    except OSError:
        return ""


# --- the spawner thread --------------------------------------------------------------------
_Job = Tuple[Callable[[], Any], "concurrent.futures.Future[Any]"]
_spawn_lock = threading.Lock()
_spawn_queue: "Optional[queue.Queue[_Job]]" = None


def _spawner_loop(q: "queue.Queue[_Job]") -> None:
    while True:
        fn, future = q.get()
        try:
            future.set_result(fn())
        except BaseException as e:  # noqa: BLE001 - handed to the caller
            future.set_exception(e)


def _reset_spawner() -> None:
    global _spawn_queue
    _spawn_queue = None  # a forked child has no spawner thread: start its own when needed


os.register_at_fork(after_in_child=_reset_spawner)


def _in_spawner(fn: Callable[[], T]) -> T:
    """fn() run by the process's spawner thread (a daemon that never ends): the parent thread
    of every private server, so that --exit-with-parent stops it with the process only."""
    global _spawn_queue
    with _spawn_lock:
        if _spawn_queue is None:
            _spawn_queue = queue.Queue()
            threading.Thread(target=_spawner_loop, args=(_spawn_queue,),
                             name="hdeform-server-spawner", daemon=True).start()
        q = _spawn_queue
    future: "concurrent.futures.Future[T]" = concurrent.futures.Future()
    q.put((fn, future))
    return future.result()


class LocalServer:
    """A private hdeform-server: --port 0 on 127.0.0.1, a random operator token (passed in the
    environment, not on the command line), no durable state unless `state_dir` is given. It
    gets a clean environment (server_environment): the caller's HDEFORM_* variables would
    otherwise configure it. It reports its address through --ready-file and exits with this
    process (--exit-with-parent). Its output goes to a temporary log, removed by stop();
    stop() runs at exit at the latest."""

    def __init__(self, binary: Optional[PathLike] = None, *,
                 mesh_dir: Optional[PathLike] = None, state_dir: Optional[PathLike] = None,
                 args: Sequence[str] = (), timeout: float = 30.0) -> None:
        self.binary = find_server(binary)
        self.admin_token = secrets.token_hex(32)
        self.http_address: Optional[str] = None
        self._dir = tempfile.mkdtemp(prefix="hdeform-server-")
        self.log_path = os.path.join(self._dir, "server.log")
        self.ready_path = os.path.join(self._dir, "ready.json")
        cmd = [self.binary, "--port", "0", "--bind", "127.0.0.1", "--ready-file",
               self.ready_path, "--exit-with-parent"]
        cmd += ["--state-dir", os.fspath(state_dir)] if state_dir else ["--no-state"]
        if mesh_dir:
            cmd += ["--mesh-dir", os.fspath(mesh_dir)]
        cmd += [str(a) for a in args]
        env = server_environment(self.admin_token)  # never the caller's HDEFORM_* settings
        self.process: Optional["subprocess.Popen[bytes]"] = None
        with open(self.log_path, "wb") as log:
            try:
                self.process = _in_spawner(lambda: subprocess.Popen(
                    cmd, stdin=subprocess.DEVNULL, stdout=log, stderr=log, env=env))
            except OSError as e:
                shutil.rmtree(self._dir, ignore_errors=True)
                raise ServerStartError(f"cannot start {self.binary}: {e}") from e
        atexit.register(self.stop)
        self.address = self._wait_ready(timeout)

    @property
    def pid(self) -> Optional[int]:
        """The server's process id."""
        return self.process.pid if self.process is not None else None

    def _wait_ready(self, timeout: float) -> str:
        assert self.process is not None
        deadline = time.monotonic() + timeout
        while True:
            ready = self._read_ready()
            if ready is not None:
                self.http_address = ready.get("http")
                return str(ready["grpc"])
            code = self.process.poll()
            if code is not None or time.monotonic() > deadline:
                why = (f"exited with status {code}" if code is not None
                       else f"wrote no --ready-file within {timeout:g} s")
                tail = _tail(self.log_path)
                hint = ""
                if "ready-file" in tail or "exit-with-parent" in tail:
                    hint = (" (this hdeform-server predates --ready-file / --exit-with-parent: "
                            "use one built from the same checkout as the client; "
                            + HOW_TO_GET_ONE + ")")
                self.stop(keep_log=True)
                raise ServerStartError(f"{self.binary} {why}{hint}; log {self.log_path}:\n"
                                       f"{tail}")
            time.sleep(0.02)

    def _read_ready(self) -> Optional[Dict[str, Any]]:
        try:
            with open(self.ready_path, encoding="utf-8") as f:
                data = json.load(f)
        except FileNotFoundError:
            return None
        except (OSError, ValueError) as e:
            raise ServerStartError(f"{self.binary}: unreadable --ready-file "
                                   f"{self.ready_path}: {e}") from e
        if not isinstance(data, dict) or not isinstance(data.get("grpc"), str):
            raise ServerStartError(f"{self.binary}: --ready-file {self.ready_path} has no "
                                   f"\"grpc\" address: {data!r}")
        return data

    def log(self) -> str:
        """The server's output so far."""
        return _tail(self.log_path, lines=10**9)

    def stop(self, keep_log: bool = False) -> None:
        """SIGTERM, then SIGKILL after 10 s; idempotent. keep_log: leave the log (and its
        temporary folder) for reading."""
        p = self.process
        if p is not None and p.poll() is None:
            p.terminate()
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        if not keep_log:
            shutil.rmtree(self._dir, ignore_errors=True)
        atexit.unregister(self.stop)

    def __enter__(self) -> "LocalServer":
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
