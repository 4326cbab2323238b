"""The documented pip install (docs/python.md, Install), followed as a user would: a venv made
by Debian's /usr/bin/python3 with --system-site-packages, `pip install --no-build-isolation
--no-deps ./client-python` offline, then an example run from outside the source tree against
a private server. CTest python_pip_install runs it (not in the main suite: pytest collects
test_*.py only).

Honest about the stubs: the build tree's stubs (build/tests/python/stubs) are never on the
venv's path. The package is installed from a copy of client-python/ and proto/ without any
generated hdeform/v1/deform_pb2*.py, so the installed stubs can only come from setup.py's
build_py step (protoc + grpc_python_plugin), and the copy is removed before the example runs.
"""
import os
import shutil
import subprocess

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
CLIENT = os.path.dirname(HERE)
REPO = os.path.dirname(CLIENT)
DATA = os.environ.get("HDEFORM_DATA_DIR", os.path.join(REPO, "data"))
PYTHON = "/usr/bin/python3"  # the docs' interpreter: Debian's, which sees the apt packages


def clean_env(**extra):
    """The user's environment: no PYTHONPATH (the build tree's stubs), no HDEFORM_PROTO_DIR,
    no pip configuration; pip offline (no index) and without its cache in HOME."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "HDEFORM_PROTO_DIR", "PYTHONHOME", "VIRTUAL_ENV")
           and not k.startswith("PIP_")}
    env.update(PIP_NO_INDEX="1", PIP_NO_CACHE_DIR="1", PIP_DISABLE_PIP_VERSION_CHECK="1",
               PIP_CONFIG_FILE=os.devnull, PYTHONDONTWRITEBYTECODE="1")
    env.update(extra)
    return env


def run(cmd, cwd, env, timeout=300):
    r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0, f"{' '.join(map(str, cmd))} failed:\n{r.stdout}\n{r.stderr}"
    return r


def test_documented_pip_install_runs_an_example(tmp_path):
    if not os.access(PYTHON, os.X_OK):
        pytest.fail(f"{PYTHON} missing: the docs' install path needs Debian's python3")
    server = os.environ.get("HDEFORM_SERVER")
    assert server and os.path.isabs(server), "HDEFORM_SERVER: the built hdeform-server"

    # A checkout's two folders the install reads (setup.py: ../proto), no generated stubs.
    src = tmp_path / "checkout"
    ignore = shutil.ignore_patterns("build", "*.egg-info", "__pycache__", "tests",
                                    "deform_pb2*.py")
    shutil.copytree(CLIENT, src / "client-python", ignore=ignore)
    shutil.copytree(os.path.join(REPO, "proto"), src / "proto")
    assert not list((src / "client-python").rglob("deform_pb2*.py"))

    (tmp_path / "home").mkdir()
    env = clean_env(HOME=str(tmp_path / "home"))
    venv = tmp_path / "hdeform-venv"
    run([PYTHON, "-m", "venv", "--system-site-packages", str(venv)], tmp_path, env)
    pip = venv / "bin" / "pip"
    r = run([str(pip), "install", "--no-build-isolation", "--no-deps", "./client-python"],
            src, env)
    assert "Successfully installed hdeform" in r.stdout
    shutil.rmtree(src)  # nothing of the checkout is left to import from

    py = venv / "bin" / "python"
    work = tmp_path / "work"
    work.mkdir()
    r = run([str(py), "-c", "import hdeform, hdeform.v1.deform_pb2 as pb, sys; "
             "print(hdeform.__file__); print(pb.__file__); print(list(hdeform.__path__))"],
            work, env)
    package, stubs, paths = r.stdout.splitlines()
    site = str(venv / "lib")
    assert package.startswith(site) and stubs.startswith(site), r.stdout
    assert all(p.startswith(site) for p in eval(paths)), paths  # noqa: S307 - a list literal
    # PEP 561: the type hints are for users' type checkers too
    assert os.path.isfile(os.path.join(os.path.dirname(package), "py.typed")), package

    # An example from outside the source tree: it starts a private server ($HDEFORM_SERVER).
    shutil.copy(os.path.join(CLIENT, "examples", "beta_study.py"), work)
    r = run([str(py), "beta_study.py", "--data", DATA, "--betas", "0,0.1", "--csv", "out.csv"],
            work, dict(env, HDEFORM_SERVER=server))
    assert "wrote out.csv" in r.stdout
    lines = (work / "out.csv").read_text().splitlines()
    assert lines[0] == "beta,E,E_iso_N,E_conf_N,E_area_pct,max_e_iso,max_e_conf,max_ef2,flips"
    assert [line.split(",")[0] for line in lines[1:]] == ["0", "0.1"]
