"""Shared fixtures: the real-data folder beside the repository, skipped when absent."""

from __future__ import annotations

from pathlib import Path

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
