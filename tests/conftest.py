"""Test-wide settings: Rerun must not collect usage data from tests (the Makefile also disables it)."""

import os
import shutil
import subprocess

import pytest


@pytest.fixture(scope="session", autouse=True)
def _rerun_analytics_off():
    rerun = shutil.which("rerun", path=os.path.dirname(os.path.realpath(__import__("sys").executable)))
    if rerun:
        subprocess.run([rerun, "analytics", "disable"], capture_output=True, check=False, timeout=30)
    yield
