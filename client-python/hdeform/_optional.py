"""Optional dependencies (meshio, matplotlib): imported on first use, with the fix named."""
import importlib
from typing import Any


def require(module: str, what: str) -> Any:
    """`module`, or an ImportError saying that `what` needs it and how to install it."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise ImportError(
            f"{what} needs {module}: apt-get install python3-{module} (for Debian's "
            "/usr/bin/python3 or a venv made with --system-site-packages)",
            name=module) from e
