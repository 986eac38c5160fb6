import os
import subprocess
import sys

import pytest

IAMP = [sys.executable, "-m", "iamp"]


def run_cli(*args, cwd=None, timeout=600):
    """Run the CLI as a user would; returns CompletedProcess with text output."""
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    return subprocess.run(IAMP + [str(a) for a in args], capture_output=True, text=True, cwd=cwd,
                          timeout=timeout, env=env)


@pytest.fixture
def cli():
    return run_cli
