"""nerfstudio / instant-ngp ``transforms.json`` in and out: a scene written from the COLMAP model
of ``colmap_maupertuis`` in nerfstudio's convention (``colmap_to_json``'s steps), fitted by
``align`` against the same scene moved by a known Sim(3), comes back in the moved frame with
every other key kept."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import align_error, data_path

from slam2world._slam2world import run_cli

KNOWN_SCALE = 3.7


def known_sim3() -> np.ndarray:
    """A Sim(3) as a 4×4 matrix: a rotation about a tilted axis, scale, translation."""
    from scipy.spatial.transform import Rotation

    m = np.eye(4)
    m[:3, :3] = KNOWN_SCALE * Rotation.from_rotvec([0.3, -1.1, 0.5]).as_matrix()
    m[:3, 3] = [12.0, -4.5, 1.25]
    return m


def nerfstudio_scene() -> dict[str, Any]:
    """``transforms.json`` of the model as nerfstudio's ``colmap_to_json`` writes it."""
    pycolmap = pytest.importorskip("pycolmap")
    rec = pycolmap.Reconstruction(str(data_path("colmap_maupertuis", "reconstruction")))
    cam = next(iter(rec.cameras.values()))
    frames = []
    for image_id, im in sorted(rec.images.items()):
        w2c = np.eye(4)
        w2c[:3, :] = im.cam_from_world().matrix()
        c2w = np.linalg.inv(w2c)
        c2w[0:3, 1:3] *= -1
        c2w = c2w[np.array([0, 2, 1, 3]), :]
        c2w[2, :] *= -1
        frames.append(
            {
                "file_path": f"images/{im.name}",
                "transform_matrix": c2w.tolist(),
                "colmap_im_id": image_id,
            }
        )
    applied = np.eye(4)[:3, :][np.array([0, 2, 1]), :]
    applied[2, :] *= -1
    f, cx, cy = cam.params
    return {
        "w": cam.width,
        "h": cam.height,
        "fl_x": f,
        "fl_y": f,
        "cx": cx,
        "cy": cy,
        "k1": 0.0,
        "k2": 0.0,
        "p1": 0.0,
        "p2": 0.0,
        "camera_model": "OPENCV",
        "frames": frames,
        "applied_transform": applied.tolist(),
        "ply_file_path": "sparse_pc.ply",
    }


def moved(scene: dict[str, Any], t: np.ndarray) -> dict[str, Any]:
    """The scene with every camera carried by ``t`` (rotation kept orthonormal)."""
    out = json.loads(json.dumps(scene))
    s = np.cbrt(np.linalg.det(t[:3, :3]))
    for frame in out["frames"]:
        m = np.array(frame["transform_matrix"])
        n = np.eye(4)
        n[:3, :3] = t[:3, :3] / s @ m[:3, :3]
        n[:3, 3] = t[:3, :3] @ m[:3, 3] + t[:3, 3]
        frame["transform_matrix"] = n.tolist()
    return out


def test_a_scene_fitted_to_its_moved_copy_comes_back_moved(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    scene = nerfstudio_scene()
    target = moved(scene, known_sim3())
    est, ref, out = (tmp_path / n for n in ("transforms.json", "metric.json", "out.json"))
    est.write_text(json.dumps(scene, indent=4))
    ref.write_text(json.dumps(target, indent=4))
    capfd.readouterr()
    code = run_cli(["slam2world", "align", str(est), str(ref), "-o", str(out), "--json"])
    stdout, stderr = capfd.readouterr()
    assert code == 0, stderr
    doc = json.loads(stdout)
    assert doc["n_pairs"] == 4
    assert abs(doc["scale"] - KNOWN_SCALE) < 1e-9 * KNOWN_SCALE
    written = json.loads(out.read_text())
    for got, want in zip(written["frames"], target["frames"], strict=True):
        assert np.allclose(got["transform_matrix"], want["transform_matrix"], rtol=0, atol=1e-9)
    # Every other key as it was (parsed and compared), in the same order.
    assert list(written) == list(scene)
    for got, was in zip(written["frames"], scene["frames"], strict=True):
        assert list(got) == list(was)
        assert {k: v for k, v in got.items() if k != "transform_matrix"} == {
            k: v for k, v in was.items() if k != "transform_matrix"
        }
    assert {k: v for k, v in written.items() if k != "frames"} == {
        k: v for k, v in scene.items() if k != "frames"
    }


def test_the_written_scene_holds_what_nerfstudio_reads(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """The keys nerfstudio's ``Nerfstudio`` dataparser reads, with the types and shapes it
    needs (nerfstudio itself needs torch, which the tests do not install)."""
    scene = nerfstudio_scene()
    est, ref, out = (tmp_path / n for n in ("transforms.json", "metric.json", "out.json"))
    est.write_text(json.dumps(scene))
    ref.write_text(json.dumps(moved(scene, known_sim3())))
    assert run_cli(["slam2world", "align", str(est), str(ref), "-o", str(out)]) == 0
    meta = json.loads(out.read_text())
    for key in ("fl_x", "fl_y", "cx", "cy", "k1", "k2", "p1", "p2"):
        assert isinstance(meta[key], float), key
    assert isinstance(meta["w"], int) and isinstance(meta["h"], int)
    assert meta["camera_model"] == "OPENCV"
    assert np.array(meta["applied_transform"]).shape == (3, 4)
    for frame, was in zip(meta["frames"], scene["frames"], strict=True):
        m = np.array(frame["transform_matrix"], dtype=float)
        assert m.shape == (4, 4)
        assert np.array_equal(m[3], [0, 0, 0, 1])
        # A rotation as orthonormal as the input's (COLMAP's 6-digit quaternions: ~1e-6 off).
        r, r0 = m[:3, :3], np.array(was["transform_matrix"])[:3, :3]
        off, off0 = (np.abs(x.T @ x - np.eye(3)).max() for x in (r, r0))
        assert off <= off0 + 1e-12
        assert np.linalg.det(r) == pytest.approx(np.linalg.det(r0), abs=1e-12)
        assert frame["file_path"].startswith("images/")


def test_python_reads_and_writes_a_scene(tmp_path: Path) -> None:
    import slam2world as sw

    scene = nerfstudio_scene()
    src = tmp_path / "transforms.json"
    src.write_text(json.dumps(scene))
    traj, names = sw.read_transforms(src)
    assert names == [f["file_path"] for f in scene["frames"]]
    # The OpenGL camera turned to the project's: the same centres, y and z flipped.
    flip = np.diag([1.0, -1.0, -1.0])
    for f, pos, q in zip(scene["frames"], traj.positions, traj.orientations, strict=True):
        m = np.array(f["transform_matrix"])
        assert np.allclose(pos, m[:3, 3], rtol=0, atol=1e-12)
        r = sw.Sim3.from_quaternion(q, [0, 0, 0], 1.0).matrix()[:3, :3]
        assert np.allclose(r, m[:3, :3] @ flip, rtol=0, atol=1e-6)
    t = known_sim3()
    out = tmp_path / "moved.json"
    sw.write_transforms(src, out, sw.Sim3.from_matrix(t))
    want = moved(scene, t)
    for got, w in zip(json.loads(out.read_text())["frames"], want["frames"], strict=True):
        assert np.allclose(got["transform_matrix"], w["transform_matrix"], rtol=0, atol=1e-9)
    with pytest.raises(sw.FileError, match="never replaces an input"):
        sw.write_transforms(src, src, sw.Sim3.from_matrix(t))
    assert json.loads(src.read_text()) == scene


def trained(poses: list[Any], dataparser: dict[str, Any]) -> np.ndarray:
    """The poses in a model's training frame, as nerfstudio's dataparser makes them:
    ``transform @ pose``, then the translations times ``scale``."""
    t = np.array(dataparser["transform"])
    out = np.array([t @ np.array(p) for p in poses])
    out[:, :3, 3] *= dataparser["scale"]
    return out


def test_a_trained_models_dataparser_transform_follows_the_scene(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    from scipy.spatial.transform import Rotation

    scene = nerfstudio_scene()
    transform = np.hstack([Rotation.from_rotvec([0.1, 0.2, -0.7]).as_matrix(), [[0.5], [-1], [2]]])
    dataparser = {"transform": transform.tolist(), "scale": 0.0625}
    est, ref, out = (tmp_path / n for n in ("transforms.json", "metric.json", "out.json"))
    dp_in, dp_out = tmp_path / "dataparser_transforms.json", tmp_path / "metric_dataparser.json"
    est.write_text(json.dumps(scene))
    ref.write_text(json.dumps(moved(scene, known_sim3())))
    dp_in.write_text(json.dumps(dataparser))
    args = [str(est), str(ref), "-o", str(out), "--dataparser-transforms", str(dp_in), str(dp_out)]
    assert run_cli(["slam2world", "align", *args]) == 0
    new = json.loads(dp_out.read_text())
    assert new["scale"] == pytest.approx(dataparser["scale"] / KNOWN_SCALE, rel=1e-12)
    before = trained([f["transform_matrix"] for f in scene["frames"]], dataparser)
    after = trained([f["transform_matrix"] for f in json.loads(out.read_text())["frames"]], new)
    assert np.allclose(after, before, rtol=0, atol=1e-9)
    # The dataparser file is an input: never an output.
    capfd.readouterr()
    assert (
        run_cli(
            ["slam2world", "align", *args[:4], "--dataparser-transforms", str(dp_in), str(dp_in)]
        )
        == 1
    )
    assert json.loads(dp_in.read_text()) == dataparser


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ('{"fl_x": 500}', 'no "frames" list'),
        ('{"frames": []}', '"frames" is empty'),
        ('{"frames": [{"file_path": "a.png"}]}', 'frames[0]: no 4×4 "transform_matrix"'),
        ('{"frames": [', "not a transforms.json"),
    ],
)
def test_bad_scenes_get_one_clear_error(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], text: str, needle: str
) -> None:
    bad = tmp_path / "transforms.json"
    bad.write_text(text)
    ref = data_path("evo_tum_fr2_desk", "fr2_desk_groundtruth.txt")
    err = align_error(capfd, str(bad), str(ref))
    assert needle in err and len(err.strip().splitlines()) == 1, err


def test_a_scene_timed_by_frame_order_does_not_pair_with_stamps(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    scene = tmp_path / "transforms.json"
    scene.write_text(json.dumps(nerfstudio_scene()))
    ref = data_path("evo_tum_fr2_desk", "fr2_desk_groundtruth.txt")
    err = align_error(capfd, str(scene), str(ref))
    assert "timed by their order" in err and len(err.strip().splitlines()) == 1, err
