"""rvehub.local(): starting, finding and stopping rve_server; tokens;
connect() to a running server."""

import os
import subprocess
import sys
import textwrap

import grpc
import pytest

import rvehub


def test_context_manager_stops_the_server():
    with rvehub.local(threads=1) as hub:
        proc = hub.process
        assert hub.target.startswith("127.0.0.1:")
        assert hub.info().num_rves == 0
        assert proc.poll() is None
    assert proc.returncode == 0
    with pytest.raises(RuntimeError, match="is closed"):
        hub.info()


def test_connect_to_a_running_server():
    with rvehub.local(threads=1) as server:
        with rvehub.connect(server.target, timeout=30) as hub:
            assert hub.info().api_version == "rvehub.v1"
            assert hub.runs() == []
        assert server.stop() == 0
        assert server.stop() == 0  # idempotent


def test_token():
    with rvehub.local(threads=1, token="s3cret-token") as server:
        assert server.info().auth_required
        with rvehub.connect(server.target) as anonymous:
            with pytest.raises(rvehub.RveError) as e:
                anonymous.runs()
            assert e.value.code == grpc.StatusCode.UNAUTHENTICATED
        with rvehub.connect(server.target, token="wrong") as wrong:
            with pytest.raises(rvehub.RveError) as e:
                wrong.templates()
            assert e.value.code == grpc.StatusCode.UNAUTHENTICATED
        # The token reaches rve_cli upload-template too.
        with rvehub.connect(server.target, token="s3cret-token") as hub:
            t = hub.prepare_template("SET-dense", seed=1)
            assert t.name == "SET-dense-seed1"
            run = hub.create_run("r", t.name, ids=[0])
            assert run.created.failed == 0


def test_finding_binaries(tmp_path, monkeypatch):
    found = rvehub.find_binary("rve_server")
    assert os.access(found, os.X_OK)
    with pytest.raises(FileNotFoundError, match="is not an executable file"):
        rvehub.local(server=str(tmp_path / "nope"))
    # The given folder first, then RVEHUB_BUILD_DIR, then build/ under the repository.
    monkeypatch.setenv("RVEHUB_BUILD_DIR", str(tmp_path / "env"))
    (tmp_path / "rve_cli").write_text("#!/bin/sh\n")
    (tmp_path / "rve_cli").chmod(0o755)
    assert rvehub.find_binary("rve_cli", build_dir=str(tmp_path)) == str(tmp_path / "rve_cli")
    repo_build = os.path.join(rvehub._binaries.repo_root(), "build")
    if os.path.isfile(os.path.join(repo_build, "rve_server", "server", "rve_server")):
        assert rvehub.find_binary("rve_server", build_dir=str(tmp_path / "a")).startswith(repo_build)
    else:
        with pytest.raises(FileNotFoundError, match="rve_server not found"):
            rvehub.find_binary("rve_server", build_dir=str(tmp_path / "a"))


def test_a_server_that_cannot_start_says_why():
    with pytest.raises(RuntimeError, match="(?s)did not start.*--threads=-1 must lie in"):
        rvehub.local(threads=-1, start_timeout=30)


def test_the_server_stops_when_the_interpreter_exits(tmp_path):
    # A script that leaves its hub open: the server still ends with it.
    script = tmp_path / "leave_open.py"
    script.write_text(textwrap.dedent("""
        import rvehub
        hub = rvehub.local(threads=1)
        print(hub.process.pid, flush=True)
    """))
    out = subprocess.run([sys.executable, str(script)], check=True, capture_output=True,
                         text=True, timeout=60, env=os.environ.copy())
    pid = int(out.stdout.split()[0])
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)


def test_stubs_found_from_the_build_folder():
    # With only python/ on PYTHONPATH, the stubs are looked for in
    # $RVEHUB_BUILD_DIR/python (and build/python under the repository).
    package_dir = os.path.dirname(os.path.dirname(rvehub.__file__))
    stubs = os.path.dirname(os.path.dirname(os.path.dirname(rvehub.hub.pb.__file__)))
    env = dict(os.environ, PYTHONPATH=package_dir, RVEHUB_BUILD_DIR=os.path.dirname(stubs))
    code = "import rvehub, rvehub_gen; print(rvehub_gen.__file__)"
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True,
                         timeout=60, env=env)
    assert out.stdout.startswith(stubs)
