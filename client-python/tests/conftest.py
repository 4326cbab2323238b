import os
import sys

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))  # the package from the source tree
DATA = os.environ.get("HDEFORM_DATA_DIR", os.path.join(HERE, "..", "..", "data"))
BENCH = os.path.join(DATA, "botsch-sorkine")

import hdeform  # noqa: E402


@pytest.fixture(scope="session")
def hd():
    with hdeform.connect() as client:  # a private server (HDEFORM_SERVER)
        yield client


@pytest.fixture
def cactus(hd):
    with hd.open("cactus") as s:
        s.constrain(fixed=hdeform.sel_file(os.path.join(BENCH, "cactus.sel"), hdeform.FIXED),
                    handles=[hdeform.sel_file(os.path.join(BENCH, "cactus.sel"),
                                              hdeform.HANDLE)])
        yield s
