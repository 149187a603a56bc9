"""Smoke test of the side-by-side benchmark (`benches/compare.py --smoke`): tiny
sizes, one repeat; checks the shape of the table, the JSON, the curves and the
thread-scaling table, never a timing."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
COMPARE = REPO / "benches" / "compare.py"
AREAS = {"align", "transform", "backproject", "octree", "mcap", "rosbag"}


def run(*args: str) -> subprocess.CompletedProcess[str]:
    if not COMPARE.exists():
        pytest.skip(f"benches not present: {COMPARE}")
    return subprocess.run(
        [sys.executable, str(COMPARE), "--smoke", *args],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


@pytest.mark.slow
def test_smoke_every_area(tmp_path: Path) -> None:
    out = tmp_path / "bench.json"
    proc = run("--json", str(out))
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(out.read_text())
    assert doc["mode"] == "smoke"
    assert doc["machine"]["cpus"] >= 1
    rows = doc["rows"]
    assert {r["area"] for r in rows} == AREAS
    lines = proc.stdout.splitlines()
    assert lines[0].split()[:3] == ["area", "row", "peer"]
    for r in rows:
        # Every row is in the printed table, measured or skipped with a reason.
        assert any(r["row"][:46] in line and r["peer"][:46] in line for line in lines)
        if "skipped" in r:
            assert r["skipped"]
            continue
        assert r["ours_s"] > 0 and r["throughput_ours_per_s"] > 0
        assert r["ratio"] > 0
        if r["target"] is not None:
            assert r["met"] is None  # targets are checked at full size only
    # Each issue's bars are rows of the table.
    targets = {(r["area"], r["peer"]) for r in rows if r["target"] is not None}
    assert ("transform", "copy of the same bytes (the limit)") in targets
    assert ("align", "evo umeyama_alignment") in targets
    assert ("octree", "OctoMap memoryUsage / leaves") in targets


@pytest.mark.slow
def test_smoke_curves_and_threads(tmp_path: Path) -> None:
    out = tmp_path / "bench.json"
    curves = tmp_path / "curves"
    proc = run(
        "--only", "transform", "--json", str(out), "--curves", str(curves), "--threads", "1,2"
    )
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(out.read_text())
    assert {r["area"] for r in doc["rows"]} == {"transform"}
    scaling = doc["thread_scaling"]
    assert scaling and all(set(e["speedup"]) == {"1", "2"} for e in scaling)
    assert all(e["speedup"]["1"] == pytest.approx(1.0) for e in scaling)
    series = json.loads((curves / "curves.json").read_text())
    copy = [s for k, s in series.items() if "copy of the same bytes" in k]
    assert copy and all("peer_s" in p for p in copy[0]["points"])
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        return
    assert (curves / "curves_transform.png").stat().st_size > 1000


def test_unknown_area_is_refused() -> None:
    proc = run("--only", "nonsense")
    assert proc.returncode != 0
    assert "unknown area" in proc.stderr
