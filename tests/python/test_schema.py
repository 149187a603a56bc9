"""Every JSON document the commands write validates against its published
JSON Schema (``schema/NAME.schema.json``), and the published files are the
schemas of the report model as built (``slam2world schema -o DIR``)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import pytest
from conftest import REPO, data_path

import slam2world as s2w
from slam2world._slam2world import run_cli

SCHEMA_DIR = REPO / "schema"
NAMES = ["report", "align", "imu-init", "evaluate", "demo", "truth", "follow"]


def _schema(name: str) -> dict[str, Any]:
    schema: dict[str, Any] = json.loads((SCHEMA_DIR / f"{name}.schema.json").read_text())
    return schema


def _validate(name: str, doc: Any) -> None:
    jsonschema.validate(doc, _schema(name), cls=jsonschema.Draft202012Validator)


def _cli(capfd: pytest.CaptureFixture[str], *args: str) -> str:
    capfd.readouterr()
    code = run_cli(["slam2world", *args])
    out, err = capfd.readouterr()
    assert code == 0, err
    return out


def test_published_schemas_are_the_model(tmp_path: Path) -> None:
    assert run_cli(["slam2world", "schema", "-o", str(tmp_path)]) == 0
    built = sorted(p.name for p in tmp_path.iterdir())
    assert built == sorted(f"{n}.schema.json" for n in NAMES)
    for n in NAMES:
        assert (tmp_path / f"{n}.schema.json").read_text() == (
            SCHEMA_DIR / f"{n}.schema.json"
        ).read_text(), f"schema/{n}.schema.json is stale: run `slam2world schema -o schema`"
        jsonschema.Draft202012Validator.check_schema(_schema(n))


@pytest.fixture(scope="module")
def simulated(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A reduced simulated run: its log, truth, conversion and demo outputs."""
    d = tmp_path_factory.mktemp("sim")
    assert run_cli(["slam2world", "simulate", "-o", str(d / "s.mcap"), "--reduced", "4"]) == 0
    args = ["convert", str(d / "s.mcap"), "-o", str(d / "out"), "--octree", "0.2", "-q"]
    assert run_cli(["slam2world", *args, "--skip-init", "auto", "--robust"]) == 0
    assert (
        run_cli(["slam2world", "demo", "-o", str(d / "demo"), "--reduced", "8", "--no-plots"]) == 0
    )
    return d


@pytest.mark.slow
def test_convert_report_validates(simulated: Path) -> None:
    report = json.loads((simulated / "out" / "report.json").read_text())
    _validate("report", report)
    # The simulated log has live frames: the start-up cut comes from them.
    assert report["startup"]["stages"]["stable_start"] >= 0
    assert report["startup"]["stable_time"] > 0 and report["octree"]["resolution"] == 0.2
    # A report that lost a required field does not validate (the schema is not vacuous).
    del report["t_world_slam"]
    with pytest.raises(jsonschema.ValidationError):
        _validate("report", report)


@pytest.mark.slow
def test_convert_report_of_the_imu_path_validates(tmp_path: Path) -> None:
    log = tmp_path / "imu.mcap"
    args = ["simulate", "-o", str(log), "--reduced", "4", "--no-reference"]
    assert run_cli(["slam2world", *args]) == 0
    assert s2w.read_mcap(log).reference is None
    assert run_cli(["slam2world", "convert", str(log), "-o", str(tmp_path / "o"), "-q"]) == 0
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    _validate("report", report)
    assert report["fit"] is None and report["imu"]["used_for_transform"] is True


def test_truth_demo_and_evaluate_validate(
    simulated: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    _validate("truth", json.loads((simulated / "s.truth.json").read_text()))
    _validate("demo", json.loads((simulated / "demo" / "demo.json").read_text()))
    out = _cli(
        capfd,
        "evaluate",
        "--truth",
        str(simulated / "s.truth.json"),
        "--cloud",
        str(simulated / "out" / "cloud.ply"),
        "--transform",
        str(simulated / "out" / "report.json"),
    )
    doc = json.loads(out)
    _validate("evaluate", doc)
    assert doc["ape_stable_frames"]["n"] > 0


def _tum(path: Path, t: np.ndarray, p: np.ndarray, q: np.ndarray) -> None:
    rows = np.column_stack([t, p, q])
    np.savetxt(path, rows, fmt="%.9f")


def test_align_json_validates(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    rng = np.random.default_rng(1)
    t = np.arange(200) * 0.05
    p = np.column_stack([np.sin(t), np.cos(0.7 * t), 0.1 * t])
    angles = np.column_stack([0.3 * np.sin(t), 0.2 * np.cos(t), t])
    from_euler = [s2w.Sim3.from_matrix(_euler(a)).quaternion for a in angles]
    q = np.array(from_euler)
    world = s2w.Sim3.from_quaternion([0.1, 0.2, 0.3, 0.9], [1.0, 2.0, 3.0], 4.0)
    _tum(tmp_path / "est.txt", t, p, q)
    _tum(tmp_path / "ref.txt", t, world.apply(p) + rng.normal(0, 0.01, p.shape), q)
    est, ref = str(tmp_path / "est.txt"), str(tmp_path / "ref.txt")
    for extra in ([], ["--robust", "--skip-init", "5", "--estimate-offset"]):
        doc = json.loads(_cli(capfd, "align", est, ref, "--json", *extra))
        _validate("align", doc)
        assert doc["n_pairs"] == 200
    doc = json.loads(_cli(capfd, "align", est, ref, "--json", "--estimate-body-from-cam"))
    _validate("align", doc)
    assert "body_from_cam_estimate" in doc


def _euler(a: np.ndarray) -> np.ndarray:
    cx, cy, cz = np.cos(a)
    sx, sy, sz = np.sin(a)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = rz @ ry @ rx
    return m


def test_imu_init_json_validates(capfd: pytest.CaptureFixture[str]) -> None:
    est = data_path("euroc_v102", "V102.txt")
    imu = data_path("euroc_v102_imu", "V102.txt")
    gt = data_path("euroc_v102", "V102_groundtruth.csv")
    args = ["imu-init", str(est), str(imu), "--start", "10", "--reference", str(gt), "--json"]
    out = _cli(capfd, *args)
    doc = json.loads(out)
    _validate("imu-init", doc)
    assert doc["reference_check"]["n_pairs"] > 0
