"""The README's Python example runs as written, and its quick start matches .ci/run."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def test_readme_python_example_runs():
    text = (REPO / "README.md").read_text()
    block = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    ns: dict = {}
    exec(compile(block, "README.md", "exec"), ns)
    assert ns["res"].cost >= 0
    assert len(ns["costs"]) == 5 and np.all(np.isfinite(ns["costs"]))


def test_readme_test_command_is_what_ci_runs():
    text = (REPO / "README.md").read_text()
    quick = re.search(r"```bash\n(.*?)```", text, re.S).group(1).strip().splitlines()
    assert len(quick) == 2, "the README opens with exactly two set-up commands"
    assert "shapetree demo" in quick[0]
    test_cmd = quick[1].split("#")[0].strip()
    assert test_cmd in (REPO / ".ci" / "run").read_text()
