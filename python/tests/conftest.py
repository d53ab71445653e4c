"""Fixtures of the rvehub tests: rve_servers on 127.0.0.1 (port 0), always
stopped, and a prepared template."""

import os
import re
import sys

import pytest

pytest.importorskip("numpy", reason="needs python3-numpy")
pytest.importorskip("grpc", reason="needs python3-grpcio")

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

import rvehub  # noqa: E402

TEMPLATE_MATERIAL = "SET-dense"
TEMPLATE_SEED = 1


@pytest.fixture(scope="module")
def hub():
    """One single-threaded local server for a test module."""
    with rvehub.local(threads=1, timeout=120) as h:
        yield h
        assert h.stop() == 0, open(h.log_path).read()


@pytest.fixture(scope="module")
def template(hub):
    """SET-dense seed 1 (400 discs) prepared and uploaded: its name."""
    return hub.prepare_template(TEMPLATE_MATERIAL, seed=TEMPLATE_SEED).name


_counter = [0]


@pytest.fixture
def run_id(request):
    """A run id of its own for each test."""
    _counter[0] += 1
    return f"{re.sub(r'[^A-Za-z0-9._-]', '_', request.node.name)[:80]}-{_counter[0]}"
