"""Ctrl-C of a test run leaves no process behind (issue 38, item 4).

Each test runs a small pytest session in its own process session, whose session fixture starts a
child that has children of its own; once they all run, pytest gets SIGINT. ``subprocess.run`` in
the fixture answers by killing its child with SIGKILL, which gives the child no chance to end its
own children (the worst case of Ctrl-C at a terminal, where the child may or may not get there
first), so the grandchildren live on unless something else ends them:

* lanelab-synth's pool workers die with their parent (:mod:`lanelab.child_processes`), with
  no help from the test run;
* any other grandchild is killed by the suite's :mod:`descendant_reaper` plugin.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from descendant_reaper import alive

TESTS = Path(__file__).resolve().parent
pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="reads /proc; the reaper needs Linux's PR_SET_CHILD_SUBREAPER")

SYNTH_FIXTURE = """
import subprocess, sys
import pytest

@pytest.fixture(scope="session")
def logs():
    subprocess.run([sys.executable, "-m", "data_ingest.synth.cli", "output_dir={out}", "num_logs=4", "workers=2",
                    "duration_s=600", "camera.width=160", "camera.height=120"], check=True)

def test_with_logs(logs):
    pass
"""

# The grandchild: it ignores Ctrl-C and does not watch its parent (it tells the test it runs).
STUBBORN = "import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); open({ready!r}, 'w').close(); time.sleep(600)"
STUBBORN_FIXTURE = """
import subprocess, sys
import pytest

GRANDCHILD = {grandchild!r}
CHILD = f"import subprocess, sys, time; subprocess.Popen([sys.executable, '-c', {{GRANDCHILD!r}}]); time.sleep(600)"

@pytest.fixture(scope="session")
def helper():
    subprocess.run([sys.executable, "-c", CHILD], check=True)

def test_with_helper(helper):
    pass
"""


def session_processes(sid: int) -> set[int]:
    """The running processes of session ``sid`` (from /proc)."""
    found = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            if int(stat.read_text().rsplit(")", 1)[1].split()[3]) == sid and alive(int(stat.parent.name)):
                found.add(int(stat.parent.name))
        except (OSError, IndexError, ValueError):
            continue
    return found


def interrupt_when_ready(test_file: Path, ready, *plugins: str) -> set[int]:
    """Run pytest on ``test_file`` in a new session, send it SIGINT once ``ready()``,
    and return the processes of its session still running 5 s after pytest exited."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(TESTS), os.environ.get("PYTHONPATH", "")])}
    command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *plugins, str(test_file)]
    run = subprocess.Popen(command, cwd=test_file.parent, env=env, start_new_session=True,
                           preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        deadline = time.monotonic() + 120
        while not ready():
            assert run.poll() is None, run.stdout.read()
            assert time.monotonic() < deadline, "the fixture's processes never started"
            time.sleep(0.05)
        os.kill(run.pid, signal.SIGINT)
        output, _ = run.communicate(timeout=60)
        assert "KeyboardInterrupt" in output, output
        deadline = time.monotonic() + 5
        while session_processes(run.pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        return session_processes(run.pid)
    finally:
        for pid in session_processes(run.pid):
            os.kill(pid, signal.SIGKILL)
        run.kill()
        run.wait()


@pytest.mark.slow
def test_ctrl_c_while_a_fixture_runs_lanelab_synth_with_workers_leaves_no_process(tmp_path):
    """The run that the issue saw leave two lanelab-synth workers behind (no reaper here)."""
    out = tmp_path / "logs"
    test_file = tmp_path / "test_synth_fixture.py"
    test_file.write_text(SYNTH_FIXTURE.format(out=out))
    assert interrupt_when_ready(test_file, lambda: len(list(out.glob(".*.partial"))) == 2) == set()


def test_ctrl_c_while_a_fixture_runs_a_child_with_a_stubborn_child_leaves_no_process(tmp_path):
    ready = tmp_path / "grandchild_runs"
    test_file = tmp_path / "test_stubborn_fixture.py"
    test_file.write_text(STUBBORN_FIXTURE.format(grandchild=STUBBORN.format(ready=str(ready))))
    assert interrupt_when_ready(test_file, ready.exists, "-p", "descendant_reaper") == set()
