"""Shared fixtures: the real-data folder beside the repository, skipped when absent."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[2]
DATA = REPO.parent / "shared" / "data"


def data_path(*parts: str) -> Path:
    """A file or folder under ../shared/data; skips the test when it is absent."""
    path = DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"real data not present: {path} (a plain clone has no ../shared/data)")
    return path


@pytest.fixture
def data() -> type:
    """Access to ``data_path`` as a fixture."""

    class _Data:
        path = staticmethod(data_path)

    return _Data


def align_json(capfd: pytest.CaptureFixture[str], *args: str) -> dict[str, Any]:
    """``slam2world align ARGS --json`` in process: its JSON report (exit 0 asserted)."""
    from slam2world._slam2world import run_cli

    capfd.readouterr()
    assert run_cli(["slam2world", "align", *args, "--json"]) == 0
    out, _ = capfd.readouterr()
    doc: dict[str, Any] = json.loads(out)
    return doc


def align_error(capfd: pytest.CaptureFixture[str], *args: str) -> str:
    """``slam2world align ARGS`` in process, exit 1 asserted: what it wrote on stderr."""
    from slam2world._slam2world import run_cli

    capfd.readouterr()
    assert run_cli(["slam2world", "align", *args]) == 1
    _, err = capfd.readouterr()
    return err
