"""The embedded default: a private hdeform-server on a free loopback port."""
import atexit
import os
import re
import secrets
import shutil
import subprocess
import tempfile
import time

from ._errors import ServerStartError

_LISTENING = re.compile(rb"hdeform-server listening on (\S+):(\d+)")

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


def server_environment(admin_token):
    """The private server's environment: the allow-listed variables of this process (LC_*
    too) and HDEFORM_ADMIN_TOKEN; none of the caller's other (HDEFORM_*) variables."""
    env = {k: v for k, v in os.environ.items() if k in _INHERITED or k.startswith("LC_")}
    env["HDEFORM_ADMIN_TOKEN"] = admin_token
    return env


def find_server(binary=None):
    """The hdeform-server to start: `binary`, else $HDEFORM_SERVER, else `hdeform-server` on
    PATH, else build/server/hdeform-server of the source tree this package sits in (or of the
    current folder)."""
    if binary:
        return os.fspath(binary)
    env = os.environ.get("HDEFORM_SERVER")
    if env:
        return env
    on_path = shutil.which("hdeform-server")
    if on_path:
        return on_path
    here = os.path.dirname(os.path.abspath(__file__))
    for root in (os.path.dirname(os.path.dirname(here)), os.getcwd()):
        candidate = os.path.join(root, "build", "server", "hdeform-server")
        if os.access(candidate, os.X_OK):
            return candidate
    raise ServerStartError(
        "no hdeform-server found: pass connect(server=PATH), set HDEFORM_SERVER, put "
        "hdeform-server on PATH, or build it (build/server/hdeform-server)")


def _tail(path, lines=20):
    try:
        with open(path, "rb") as f:
            return b"".join(f.readlines()[-lines:]).decode(errors="replace")
    except OSError:
        return ""


class LocalServer:
    """A private hdeform-server: --port 0 on 127.0.0.1, a random operator token (passed in the
    environment, not on the command line), no durable state unless `state_dir` is given. It
    gets a clean environment (server_environment): the caller's HDEFORM_* variables would
    otherwise configure it. Its output goes to a temporary log, removed by stop(); stop()
    runs at exit at the latest."""

    def __init__(self, binary=None, *, mesh_dir=None, state_dir=None, args=(), timeout=30.0):
        self.binary = find_server(binary)
        self.admin_token = secrets.token_hex(32)
        fd, self.log_path = tempfile.mkstemp(prefix="hdeform-server-", suffix=".log")
        cmd = [self.binary, "--port", "0", "--bind", "127.0.0.1"]
        cmd += ["--state-dir", os.fspath(state_dir)] if state_dir else ["--no-state"]
        if mesh_dir:
            cmd += ["--mesh-dir", os.fspath(mesh_dir)]
        cmd += list(args)
        env = server_environment(self.admin_token)  # never the caller's HDEFORM_* settings
        try:
            self.process = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=fd,
                                            stderr=fd, env=env)
        except OSError as e:
            os.close(fd)
            raise ServerStartError(f"cannot start {self.binary}: {e}") from e
        os.close(fd)
        atexit.register(self.stop)
        self.address = self._wait_listening(timeout)

    def _wait_listening(self, timeout):
        deadline = time.monotonic() + timeout
        while True:
            with open(self.log_path, "rb") as f:
                m = _LISTENING.search(f.read())
            if m:
                return f"{m.group(1).decode()}:{m.group(2).decode()}"
            code = self.process.poll()
            if code is not None or time.monotonic() > deadline:
                why = (f"exited with status {code}" if code is not None
                       else f"did not listen within {timeout:g} s")
                tail = _tail(self.log_path)
                self.stop(keep_log=True)
                raise ServerStartError(f"{self.binary} {why}; log {self.log_path}:\n{tail}")
            time.sleep(0.02)

    def log(self):
        """The server's output so far."""
        return _tail(self.log_path, lines=10**9)

    def stop(self, keep_log=False):
        """SIGTERM, then SIGKILL after 10 s; idempotent."""
        p = getattr(self, "process", None)
        if p is not None and p.poll() is None:
            p.terminate()
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        if not keep_log and os.path.exists(self.log_path):
            os.unlink(self.log_path)
        atexit.unregister(self.stop)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()
