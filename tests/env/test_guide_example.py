"""The closed-loop guide's (and README's) example runs as written: the guide's first
Python block, executed verbatim, with ``roslan/Landing-v0`` pointed at a 1 s landing (the
registered default landing takes minutes of CPU, too long for a test)."""

from __future__ import annotations

import re
from pathlib import Path

import gymnasium
import pytest
import yaml

import roslan.env  # noqa: F401  (registers the ids)
from env_helpers import tiny_config

pytest.importorskip("roslan.render.gl")

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "guide" / "closed-loop.md"


def test_the_guide_example_lands(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = re.search(r"```python\n(.*?)```", GUIDE.read_text(), re.S)
    assert code is not None
    cfg = tmp_path / "tiny.yaml"
    cfg.write_text(yaml.safe_dump(tiny_config()))
    spec = gymnasium.registry["roslan/Landing-v0"]
    saved = dict(spec.kwargs)
    spec.kwargs["config"] = str(cfg)
    try:
        exec(compile(code.group(1), str(GUIDE), "exec"), {"__name__": "__main__"})
    finally:
        spec.kwargs.clear()
        spec.kwargs.update(saved)
    printed = capsys.readouterr().out
    assert "'reason': 'touchdown'" in printed
    assert "'success': True" in printed
