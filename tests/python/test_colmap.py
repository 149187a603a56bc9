"""COLMAP models against pycolmap: models pycolmap writes (with rigs, frames and
non-pinhole cameras) read here, carried by a Sim(3), written back and read by
pycolmap; the real Maupertuis model written back unchanged."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from numpy.testing import assert_allclose

import slam2world as s2w

pycolmap = pytest.importorskip("pycolmap")

MODELS = {
    "OPENCV": [1000.0, 1010.0, 512.0, 384.0, 0.01, -0.02, 0.001, 0.002],
    "SIMPLE_RADIAL": [1280.0, 512.0, 384.0, 0.05],
}


def synthetic(model: str) -> Any:
    """A pycolmap scene: 2 rigs of 2 cameras, 4 frames each, 60 points."""
    opts = pycolmap.SyntheticDatasetOptions(
        num_rigs=2,
        num_cameras_per_rig=2,
        num_frames_per_rig=4,
        num_points3D=60,
        camera_model_id=getattr(pycolmap.CameraModelId, model),
        camera_params=MODELS[model],
    )
    return pycolmap.synthesize_dataset(opts)


def secret() -> tuple[Any, s2w.Sim3]:
    """The same Sim(3) for pycolmap and for slam2world."""
    q = np.array([0.3, -0.5, 0.2, 0.78])
    q /= np.linalg.norm(q)
    t = np.array([120.0, -35.5, 8.25])
    scale = 0.137
    ours = s2w.Sim3.from_quaternion(q, t, scale)
    theirs = pycolmap.Sim3d(scale, pycolmap.Rotation3d(q), t)
    return theirs, ours


def write(rec: Any, path: Path, fmt: str) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    if fmt == "bin":
        rec.write_binary(str(path))
    else:
        rec.write_text(str(path))
    return path


def centres_by_id(model: s2w.ColmapModel) -> dict[int, np.ndarray]:
    im = model.images
    return {int(i): c for i, c in zip(im.ids, im.centres)}


def assert_same_reconstruction(a: Any, b: Any, tol: float) -> None:
    """Every camera, rig, frame, image, point and observation of `a` is in `b`."""
    assert (a.num_cameras(), a.num_rigs(), a.num_frames(), a.num_reg_images()) == (
        b.num_cameras(),
        b.num_rigs(),
        b.num_frames(),
        b.num_reg_images(),
    )
    assert (a.num_points3D(), a.compute_num_observations()) == (
        b.num_points3D(),
        b.compute_num_observations(),
    )
    for cid, cam in a.cameras.items():
        other = b.cameras[cid]
        assert (cam.model, cam.width, cam.height) == (other.model, other.width, other.height)
        assert_allclose(cam.params, other.params, rtol=0, atol=0)
    for iid, im in a.images.items():
        other = b.images[iid]
        assert (im.name, im.camera_id, im.frame_id) == (other.name, other.camera_id, other.frame_id)
        assert_allclose(
            im.cam_from_world().matrix(), other.cam_from_world().matrix(), rtol=0, atol=tol
        )
        assert len(im.points2D) == len(other.points2D)
        for p, q in zip(im.points2D, other.points2D):
            assert_allclose(p.xy, q.xy, rtol=0, atol=0)
            assert p.point3D_id == q.point3D_id
    for pid, p in a.points3D.items():
        q = b.points3D[pid]
        assert_allclose(p.xyz, q.xyz, rtol=0, atol=tol * max(1.0, np.abs(p.xyz).max()))
        assert_allclose(p.color, q.color, rtol=0, atol=0)
        assert p.error == q.error
        track = sorted((e.image_id, e.point2D_idx) for e in p.track.elements)
        assert track == sorted((e.image_id, e.point2D_idx) for e in q.track.elements)
    for fid, f in a.frames.items():
        g = b.frames[fid]
        assert f.rig_id == g.rig_id
        assert_allclose(f.rig_from_world.matrix(), g.rig_from_world.matrix(), rtol=0, atol=tol)


@pytest.mark.parametrize("fmt", ["bin", "txt"])
@pytest.mark.parametrize("model", list(MODELS))
def test_secret_sim3_model_converts_back_to_the_true_one(
    tmp_path: Path, fmt: str, model: str
) -> None:
    truth = synthetic(model)
    theirs, ours = secret()
    disguised = pycolmap.Reconstruction(truth)
    disguised.transform(theirs)
    src = write(disguised, tmp_path / "in", fmt)

    read = s2w.read_colmap(src)
    assert read.format == fmt
    assert (read.num_rigs, read.num_frames) == (2, 8)
    assert {c.model for c in read.cameras} == {model}
    metric = read.transformed(ours.inverse())

    # Camera centres come back to 1e-9 relative (noise-free).
    got = centres_by_id(metric)
    want = {i: im.projection_center() for i, im in truth.images.items()}
    assert got.keys() == want.keys()
    span = max(np.linalg.norm(c) for c in want.values())
    for i, c in want.items():
        assert np.linalg.norm(got[i] - c) < 1e-9 * span, (i, got[i], c)

    # pycolmap reads our output with everything it had.
    out = tmp_path / "out"
    metric.write(out)
    assert sorted(p.suffix for p in out.iterdir()) == [f".{fmt}"] * 5
    back = pycolmap.Reconstruction(str(out))
    assert_same_reconstruction(truth, back, tol=1e-9)
    for rid, rig in truth.rigs.items():
        other = back.rigs[rid]
        for sensor, pose in rig.non_ref_sensors.items():
            assert_allclose(
                pose.matrix(), other.non_ref_sensors[sensor].matrix(), rtol=0, atol=1e-9
            )


@pytest.mark.parametrize("fmt", ["bin", "txt"])
def test_transformed_equals_pycolmap_transform(tmp_path: Path, fmt: str) -> None:
    truth = synthetic("OPENCV")
    theirs, ours = secret()
    src = write(truth, tmp_path / "in", fmt)
    expected = pycolmap.Reconstruction(truth)
    expected.transform(theirs)
    s2w.read_colmap(src).transformed(ours).write(tmp_path / "out")
    got = pycolmap.Reconstruction(str(tmp_path / "out"))
    assert_same_reconstruction(expected, got, tol=1e-9)
    for rid, rig in expected.rigs.items():
        for sensor, pose in rig.non_ref_sensors.items():
            other = got.rigs[rid].non_ref_sensors[sensor]
            assert_allclose(pose.matrix(), other.matrix(), rtol=0, atol=1e-12)


@pytest.mark.slow
def test_maupertuis_written_back_unchanged(data: Any, tmp_path: Path) -> None:
    src = data.path("colmap_maupertuis", "reconstruction")
    original = pycolmap.Reconstruction(str(src))
    model = s2w.read_colmap(src)
    assert (len(model.cameras), len(model.images), len(model.points3D)) == (1, 4, 1039)
    assert model.num_observations == original.compute_num_observations() == 3355
    identity = model.transformed(s2w.Sim3.identity())
    identity.write(tmp_path / "txt")
    model.write(tmp_path / "bin", format="bin")
    for out in ("txt", "bin"):
        back = pycolmap.Reconstruction(str(tmp_path / out))
        assert_same_reconstruction(original, back, tol=0.0)
    # Centres use the stored quaternion normalised (the file's are rounded to
    # 6 digits; pycolmap's projection_center uses them as they are, ~1e-6 off).
    want = []
    for i in sorted(original.images):
        pose = original.images[i].cam_from_world()
        q = np.asarray(pose.rotation.quat)
        r = pycolmap.Rotation3d(q / np.linalg.norm(q)).matrix()
        want.append(-r.T @ pose.translation)
    got = model.images.centres[np.argsort(model.images.ids)]
    assert_allclose(got, np.array(want), rtol=0, atol=1e-12)


def test_summaries_are_typed_arrays(data: Any) -> None:
    src = data.path("colmap_maupertuis", "reconstruction")
    original = pycolmap.Reconstruction(str(src))
    model = s2w.read_colmap(src)
    im, pts = model.images, model.points3D
    assert len(im) == 4 and len(pts) == 1039
    assert im.centres.shape == (4, 3) and im.quaternions.shape == (4, 4)
    assert im.ids.dtype == np.uint32 and pts.rgb.dtype == np.uint8
    assert pts.xyz.shape == (1039, 3) and pts.track_lengths.sum() == 3355
    order = np.argsort(pts.ids)
    ids = sorted(original.points3D)
    assert_allclose(pts.xyz[order], np.array([original.points3D[i].xyz for i in ids]), atol=0)
    assert_allclose(pts.error[order], [original.points3D[i].error for i in ids], atol=0)
    names, centres = model.camera_centres()
    assert names == im.names and np.array_equal(centres, im.centres)
    cam = model.cameras[0]
    assert cam.model == "SIMPLE_PINHOLE" and cam.params.shape == (3,)
    pin = cam.pinhole()
    assert pin.fx == pin.fy == cam.params[0] and pin.cx == cam.params[1] - 0.5


def test_names_as_stamps_and_name_references(tmp_path: Path) -> None:
    rec = synthetic("SIMPLE_RADIAL")
    for i, image in rec.images.items():
        image.name = f"{1403636579763555584 + 50_000_000 * i}.png"
    write(rec, tmp_path / "m", "bin")
    model = s2w.read_colmap(tmp_path / "m")
    traj = model.trajectory()
    assert len(traj.timestamps) == rec.num_reg_images()
    assert np.all(np.diff(traj.timestamps) > 0.049)
    first = min(rec.images)
    assert_allclose(traj.positions[0], rec.images[first].projection_center(), atol=1e-12)
    ref = tmp_path / "ref.txt"
    ref.write_text("# name x y z\na.png 1 2 3\nb.png 4 5 6\n")
    names, pos = s2w.read_name_positions(ref)
    assert names == ["a.png", "b.png"] and pos.shape == (2, 3)


def test_bad_models_raise_format_errors(tmp_path: Path) -> None:
    src = write(synthetic("OPENCV"), tmp_path / "m", "bin")
    images = src / "images.bin"
    raw = images.read_bytes()
    images.write_bytes(raw[:-50])
    with pytest.raises(s2w.FormatError, match="images.bin: byte"):
        s2w.read_colmap(src)
    images.write_bytes(raw)
    cams = src / "cameras.bin"
    b = bytearray(cams.read_bytes())
    b[12:16] = (42).to_bytes(4, "little")
    cams.write_bytes(bytes(b))
    with pytest.raises(s2w.FormatError, match="model_id"):
        s2w.read_colmap(src)
    (src / "points3D.bin").unlink()
    with pytest.raises(s2w.FormatError, match="missing points3D.bin"):
        s2w.read_colmap(src)
    with pytest.raises(s2w.InvalidInputError, match="format"):
        s2w.read_colmap(src, format="ply")
    with pytest.raises(s2w.FormatError):
        s2w.read_colmap(tmp_path / "absent")
