"""The Sphinx site builds with warnings as errors, executing every tutorial on a small budget."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def test_docs_build_without_warnings(tmp_path):
    pytest.importorskip("sphinx_gallery")
    env = {**os.environ, "TELEOPKIT_DOCS_BUDGET": "small", "NUMBA_NUM_THREADS": "1",
           "MPLBACKEND": "Agg"}
    build = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html",
         "-d", str(tmp_path / "doctrees"), str(ROOT / "docs"), str(tmp_path / "html")],
        capture_output=True, text=True, env=env, check=False, timeout=900)
    assert build.returncode == 0, build.stderr[-3000:]
    assert (tmp_path / "html" / "auto_examples" / "plot_simulate.html").exists()
