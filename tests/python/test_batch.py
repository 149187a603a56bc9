"""slam2world.batch: one convert per log on a local Ray (2 CPUs, one session for the module).

Six small simulated logs: four good ones, one truncated, one without a reference
pose topic (nor IMU, so nothing gives the world frame). The good rows carry the
numbers of a single ``convert`` of the same log; the broken ones their typed error.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest

import slam2world as s2w
from slam2world._slam2world import run_cli

ray = pytest.importorskip("ray", reason="Ray is the batch path's optional dependency (test extra)")
pq = pytest.importorskip("pyarrow.parquet", reason="pyarrow comes with Ray")
mcap_reader = pytest.importorskip(
    "mcap.reader", reason="the mcap package writes the log without a reference"
)
mcap_writer = pytest.importorskip("mcap.writer")

from slam2world import batch  # noqa: E402

GOOD = 4
# Small logs: every pixel with depth is a point (the viewer's filters would drop most).
OPTIONS = {"octree": 0.5, "no_filter": True}


@pytest.fixture(scope="module")
def ray_session() -> Iterator[None]:
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def _without_reference(src: Path, dst: Path) -> None:
    """A copy of ``src`` with only the keyframe and graph topics (no poses, no IMU),
    written by the mcap package."""
    with open(src, "rb") as f, open(dst, "wb") as g:
        reader = mcap_reader.make_reader(f)
        w = mcap_writer.Writer(g)
        w.start()
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for schema, channel, message in reader.iter_messages():
            if "keyframe" not in (schema.name if schema else ""):
                continue
            if schema.id not in schemas:
                schemas[schema.id] = w.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = w.register_channel(
                    channel.topic, channel.message_encoding, schemas[schema.id]
                )
            w.add_message(
                channels[channel.id], message.log_time, message.data, message.publish_time
            )
        w.finish()


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    d = tmp_path_factory.mktemp("logs")
    paths = []
    for seed in range(GOOD):
        p = d / f"run{seed}.mcap"
        assert (
            run_cli(
                ["slam2world", "simulate", "-o", str(p), "--reduced", "16", "--seed", str(seed)]
            )
            == 0
        )
        paths.append(p)
    truncated = d / "truncated.mcap"
    data = paths[0].read_bytes()
    truncated.write_bytes(data[: len(data) // 2])
    noref = d / "noref.mcap"
    _without_reference(paths[1], noref)
    return [*paths, truncated, noref]


@pytest.mark.slow
def test_batch_rows_match_single_convert_and_broken_logs_are_rows(
    ray_session: None, logs: list[Path], tmp_path: Path
) -> None:
    out = tmp_path / "out"
    rows = batch.convert_many(logs, out, options=OPTIONS)
    assert [r["path"] for r in rows] == [str(p) for p in logs]
    assert [r["status"] for r in rows] == ["ok"] * GOOD + ["error", "error"]
    assert rows[GOOD]["error_class"] == "FormatError"
    assert "truncated" in rows[GOOD]["message"]
    assert rows[GOOD + 1]["error_class"] == "FormatError"
    assert "no reference pose topic" in rows[GOOD + 1]["message"]
    for row, log in zip(rows[:GOOD], logs[:GOOD], strict=True):
        single = s2w.convert(log, octree_resolution=0.5, filter=s2w.PointFilter.none())
        r = single.report
        assert row["output"] == str(out / log.stem)
        assert row["scale"] == pytest.approx(r["t_world_slam"]["scale"], rel=1e-12)
        assert row["rmse"] == pytest.approx(r["fit_rmse"], rel=1e-12)
        assert row["pairs"] == r["pairs_fitted"]
        assert row["points"] == r["points"] == len(single.cloud) > 0
        assert row["octree_leaves"] == r["octree"]["leaves_occupied"] > 0
        assert row["total_s"] > 0
        written = json.loads((out / log.stem / "report.json").read_text())
        assert written["points"] == r["points"]
    table = pq.read_table(out / "summary.parquet").to_pylist()
    assert [t["status"] for t in table] == [r["status"] for r in rows]
    assert list(table[0]) == list(batch.COLUMNS)
    assert table[0]["scale"] == rows[0]["scale"]
    with open(out / "summary.csv", newline="") as f:
        text = list(csv.DictReader(f))
    assert [t["error_class"] for t in text] == ["", "", "", "", "FormatError", "FormatError"]
    # A broken log wrote nothing of its own.
    assert not (out / "truncated" / "report.json").exists()

    # --resume: the complete outputs are not converted again (their files untouched).
    stamps = {p: os.stat(out / p.stem / "world.mcap").st_mtime_ns for p in logs[:GOOD]}
    again = batch.convert_many(logs, out, options=OPTIONS, resume=True)
    assert [r["status"] for r in again] == ["skipped"] * GOOD + ["error", "error"]
    assert [r["scale"] for r in again[:GOOD]] == [r["scale"] for r in rows[:GOOD]]
    for p, t in stamps.items():
        assert os.stat(out / p.stem / "world.mcap").st_mtime_ns == t
    # Other options are other outputs: converted again.
    other = batch.convert_many(logs[:1], out, resume=True)
    assert other[0]["status"] == "ok" and other[0]["octree_leaves"] is None


# Ray Data's own context warns about its own deprecated settings on import.
@pytest.mark.slow
@pytest.mark.filterwarnings("ignore::DeprecationWarning:ray")
def test_convert_many_takes_a_ray_dataset(
    ray_session: None, logs: list[Path], tmp_path: Path
) -> None:
    ds = ray.data.from_items([{"path": str(p)} for p in logs[:2]])
    rows = batch.convert_many(ds, tmp_path / "ds", workers=2)
    assert [r["status"] for r in rows] == ["ok", "ok"]
    assert {r["path"] for r in rows} == {str(p) for p in logs[:2]}


@pytest.mark.slow
def test_duplicate_stems_get_their_own_folders(
    ray_session: None, logs: list[Path], tmp_path: Path
) -> None:
    other = tmp_path / "elsewhere"
    other.mkdir()
    shutil.copy(logs[0], other / logs[0].name)
    rows = batch.convert_many([logs[0], other / logs[0].name], tmp_path / "dup", workers=1)
    assert [Path(r["output"]).name for r in rows] == ["run0", "run0-2"]
    assert rows[0]["scale"] == rows[1]["scale"]


@pytest.mark.slow
def test_console_script_batch(ray_session: None, logs: list[Path], tmp_path: Path) -> None:
    out = tmp_path / "cli"
    code = batch.main(
        [
            str(logs[0]),
            str(logs[4]),
            "-o",
            str(out),
            "--octree",
            "0.5",
            "--no-filter",
            "--workers",
            "2",
        ]
    )
    assert code == 1  # one log failed, the batch ran
    table = pq.read_table(out / "summary.parquet").to_pylist()
    assert [t["status"] for t in table] == ["ok", "error"]
    assert table[0]["octree_leaves"] > 0


def test_bad_options_are_errors_of_the_batch_not_of_ray(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="workers"):
        batch.convert_many([], tmp_path, workers=0)
    with pytest.raises(ValueError, match="output folder"):
        batch.convert_many([], tmp_path, options=["-o", "x"])


def test_binary_points_at_the_python_package() -> None:
    assert run_cli(["slam2world", "batch", "a.mcap", "-o", "out"]) == 1
