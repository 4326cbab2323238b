"""Installing (issue 38, item 6): a Python without the apt packages gets an import error
that names the fix. The pip path itself is pip_install_check.py (CTest python_pip_install)."""
import os
import subprocess
import sys

import pytest


@pytest.mark.parametrize("missing", ["grpc", "google.protobuf", "numpy"])
def test_import_error_names_the_fix(missing):
    # As a pyenv python3 would be: the module cannot be imported (None in sys.modules).
    code = f"import sys; sys.modules[{missing!r}] = None; import hdeform"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                       timeout=60)
    assert r.returncode != 0
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("ImportError: hdeform needs grpc, protobuf and numpy")
    assert f"has no {missing}" in last
    assert "apt-get install python3-grpcio python3-protobuf python3-numpy" in last
    assert "/usr/bin/python3" in last and "--system-site-packages" in last
