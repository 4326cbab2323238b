#!/usr/bin/env python3
"""CTest python_mypy: `mypy --strict` on the hdeform package (client-python/hdeform) with the
configuration in client-python/pyproject.toml ([tool.mypy]: strict; the generated
hdeform.v1 stubs and the untyped dependencies are not checked). Debian's mypy.

  run_mypy.py CLIENT_PYTHON_DIR CACHE_DIR
"""
import os
import sys

try:
    from mypy import api
except ImportError:
    sys.exit("python_mypy: no mypy for " + sys.executable + ": apt-get install mypy "
             "(scripts/install-deps.sh installs it)")

client, cache = sys.argv[1], sys.argv[2]
args = ["--strict", "--config-file", os.path.join(client, "pyproject.toml"), "--cache-dir",
        cache, os.path.join(client, "hdeform")]
out, err, status = api.run(args)
sys.stdout.write(out)
sys.stderr.write(err)
print(f"python_mypy: mypy {' '.join(args)}: exit {status}")
sys.exit(status)
