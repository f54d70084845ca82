"""Fixtures of the Python module's tests: the `rubble` executable and the source tree (set by ctest
through RUBBLE_EXE and RUBBLE_SOURCE_DIR; by hand: PYTHONPATH=build/ci/python RUBBLE_EXE=...)."""
import os
import pathlib
import re
import subprocess

import pytest

SOURCE_DIR = pathlib.Path(os.environ.get("RUBBLE_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))


@pytest.fixture(scope="session")
def source_dir():
    return SOURCE_DIR


@pytest.fixture(scope="session")
def rubble_exe():
    exe = os.environ.get("RUBBLE_EXE")
    if not exe:
        candidate = SOURCE_DIR / "build" / "ci" / "apps" / "rubble"
        exe = str(candidate)
    if not os.path.exists(exe):
        pytest.fail(f"the rubble executable is needed (RUBBLE_EXE): {exe} does not exist")
    return exe


@pytest.fixture(scope="session")
def tiny_deposit(source_dir):
    """27 spheres dropped into an open box under uniform gravity (h = 1e-4 s)."""
    return source_dir / "tests" / "postprocessing" / "tiny_deposit.toml"


def run_cli(exe, *args, check=True):
    """Runs `rubble ARGS`; returns the CompletedProcess (text)."""
    result = subprocess.run([exe, *map(str, args)], capture_output=True, text=True)
    if check and result.returncode != 0:
        raise AssertionError(f"rubble {' '.join(map(str, args))} exited {result.returncode}:\n{result.stderr}")
    return result


def cli_final_hash(stdout):
    """The state hash `rubble run` prints on its 'final state' line, as an int."""
    match = re.search(r"final state: step (\d+), hash ([0-9a-f]{16})", stdout)
    assert match, f"no final-state line in:\n{stdout}"
    return int(match.group(1)), int(match.group(2), 16)
