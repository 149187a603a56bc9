"""Every reconstruction in, metric out: COLMAP models written by pycolmap under a
secret Sim(3) convert back to the true model (and agree with pycolmap's own
Sim(3) routines), the real Maupertuis model comes back unchanged, a DROID-SLAM
folder of the simulated scene converts as well as the LSD-SLAM path does, and a
real ORB-SLAM3 run in nanoseconds aligns with seconds ground truth without a flag."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from numpy.testing import assert_allclose

import slam2world as s2w

pycolmap = pytest.importorskip("pycolmap")

SCHEMA = Path(__file__).resolve().parents[2] / "schema" / "report.schema.json"

CAMERAS = {
    "OPENCV": [1000.0, 1010.0, 512.0, 384.0, 0.01, -0.02, 0.001, 0.002],
    "SIMPLE_RADIAL": [1280.0, 512.0, 384.0, 0.05],
}


def synthetic(model: str, seed: int = 0) -> Any:
    """A pycolmap scene: 2 rigs of 2 cameras, 4 frames each, 60 points."""
    pycolmap.set_random_seed(seed)  # synthesize_dataset draws from it
    opts = pycolmap.SyntheticDatasetOptions(
        num_rigs=2,
        num_cameras_per_rig=2,
        num_frames_per_rig=4,
        num_points3D=60,
        camera_model_id=getattr(pycolmap.CameraModelId, model),
        camera_params=CAMERAS[model],
    )
    return pycolmap.synthesize_dataset(opts)


def secret() -> tuple[Any, s2w.Sim3]:
    """T_slam_world: the same Sim(3) for pycolmap and for slam2world."""
    q = np.array([0.3, -0.5, 0.2, 0.78])
    q /= np.linalg.norm(q)
    t = np.array([120.0, -35.5, 8.25])
    scale = 0.137
    return pycolmap.Sim3d(scale, pycolmap.Rotation3d(q), t), s2w.Sim3.from_quaternion(q, t, scale)


def write(rec: Any, path: Path, fmt: str) -> Path:
    path.mkdir(parents=True, exist_ok=True)
    if fmt == "bin":
        rec.write_binary(str(path))
    else:
        rec.write_text(str(path))
    return path


def true_centres(truth: Any) -> dict[str, npt.NDArray[np.float64]]:
    return {im.name: np.asarray(im.projection_center()) for im in truth.images.values()}


def write_names(path: Path, centres: dict[str, npt.NDArray[np.float64]]) -> Path:
    lines = [" ".join([n, *(repr(float(v)) for v in c[:3])]) for n, c in sorted(centres.items())]
    path.write_text("\n".join(lines) + "\n")
    return path


def disguised_model(tmp_path: Path, model: str, fmt: str) -> tuple[Any, Path]:
    """The true scene and, on disk, the same scene in a secret SLAM frame."""
    truth = synthetic(model)
    theirs, _ = secret()
    slam = pycolmap.Reconstruction(truth)
    slam.transform(theirs)
    return truth, write(slam, tmp_path / "sparse", fmt)


def assert_same_model(a: Any, b: Any, tol: float) -> None:
    """Every camera, image, observation and point of `a` is in `b` (poses and
    points to `tol` relative to the scene's size)."""
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
    span = max(float(np.linalg.norm(im.projection_center())) for im in a.images.values())
    for cid, cam in a.cameras.items():
        other = b.cameras[cid]
        assert (cam.model, cam.width, cam.height) == (other.model, other.width, other.height)
        assert_allclose(cam.params, other.params, rtol=0, atol=0)
    for iid, im in a.images.items():
        other = b.images[iid]
        assert (im.name, im.camera_id) == (other.name, other.camera_id)
        assert_allclose(im.projection_center(), other.projection_center(), rtol=0, atol=tol * span)
        assert [p.point3D_id for p in im.points2D] == [p.point3D_id for p in other.points2D]
    for pid, p in a.points3D.items():
        q = b.points3D[pid]
        assert_allclose(p.xyz, q.xyz, rtol=0, atol=tol * max(span, np.abs(p.xyz).max()))
        assert_allclose(p.color, q.color, rtol=0, atol=0)
        assert sorted((e.image_id, e.point2D_idx) for e in p.track.elements) == sorted(
            (e.image_id, e.point2D_idx) for e in q.track.elements
        )


def sim3_difference(a: s2w.Sim3, m: npt.NDArray[np.float64]) -> float:
    """Largest entry of the difference of two 3x4 [sR t] matrices, the
    translation relative to its size."""
    ours = a.matrix()[:3]
    d = np.abs(ours - m)
    return float(max(d[:, :3].max(), d[:, 3].max() / max(1.0, np.abs(m[:, 3]).max())))


@pytest.mark.parametrize("fmt", ["bin", "txt"])
@pytest.mark.parametrize("model", list(CAMERAS))
def test_secret_sim3_model_converts_back_by_name(tmp_path: Path, fmt: str, model: str) -> None:
    truth, src = disguised_model(tmp_path, model, fmt)
    ref = write_names(tmp_path / "ref.txt", true_centres(truth))
    conv = s2w.convert(src, reference=ref)

    # T_world_slam is the inverse of the secret, to 1e-9 noise-free.
    _, ours = secret()
    assert sim3_difference(conv.transform, ours.inverse().matrix()[:3]) < 1e-9

    # The metric model's camera centres are the true ones to 1e-9 relative.
    metric = conv.model
    assert metric is not None and metric.format == fmt
    assert (metric.num_rigs, metric.num_frames) == (2, 8)
    want = true_centres(truth)
    span = max(np.linalg.norm(c) for c in want.values())
    got = dict(zip(metric.images.names, metric.images.centres))
    assert got.keys() == want.keys()
    for name, c in want.items():
        assert np.linalg.norm(got[name] - c) < 1e-9 * span, name

    # The whole set, and pycolmap reads our model with everything it had.
    out = tmp_path / "out"
    conv.write_all(out)
    assert sorted(p.name for p in out.iterdir()) == [
        "cloud.ply",
        "model",
        "report.html",
        "report.json",
        "trajectory.txt",
        "world.mcap",
    ]
    assert sorted(p.suffix for p in (out / "model").iterdir()) == [f".{fmt}"] * 5
    back = pycolmap.Reconstruction(str(out / "model"))
    assert_same_model(truth, back, tol=1e-9)

    report = json.loads((out / "report.json").read_text())
    assert report["format"] == "colmap"
    assert report["reconstruction"]["kind"] == "colmap"
    assert report["reconstruction"]["flavour"] == fmt
    assert report["reference_file"]["pairing"] == "name"
    assert report["reference_file"]["format"] == "names"
    assert report["reference_file"]["format_detected"] is True
    assert report["reference_file"]["names"]["matched"] == 16
    assert report["max_diff"] == 0.0 and report["pairs_fitted"] == 16
    assert {p["name"] for p in report["pairs"]} == set(want)
    cloud = s2w.read_ply(out / "cloud.ply")
    assert cloud.points.shape == (60, 3)


def test_pycolmap_sim3_routines_give_the_same_transform(tmp_path: Path) -> None:
    truth, src = disguised_model(tmp_path, "OPENCV", "bin")
    slam = pycolmap.Reconstruction(str(src))
    centres = true_centres(truth)
    names = sorted(centres)
    tgt = np.array([centres[n] for n in names])
    by_name = {im.name: np.asarray(im.projection_center()) for im in slam.images.values()}
    src_centres = np.array([by_name[n] for n in names])

    ransac = pycolmap.RANSACOptions()
    ransac.max_error = 1e-6
    for noise in (0.0, 0.05):
        rng = np.random.default_rng(7)
        noisy = tgt + noise * rng.standard_normal(tgt.shape)
        ref = write_names(tmp_path / f"ref_{noise}.txt", dict(zip(names, noisy)))
        ours = s2w.convert(src, reference=ref).transform
        lsq = pycolmap.estimate_sim3d(src_centres, noisy)
        aligner = pycolmap.align_reconstruction_to_locations(
            slam, names, noisy, 3, ransac if noise == 0.0 else pycolmap.RANSACOptions()
        )
        assert lsq is not None and aligner is not None
        d_lsq = sim3_difference(ours, lsq.matrix())
        d_aligner = sim3_difference(ours, aligner.matrix())
        print(
            f"noise {noise} m: |ours - estimate_sim3d| {d_lsq:.3e}, "
            f"|ours - align_reconstruction_to_locations| {d_aligner:.3e}"
        )
        if noise == 0.0:
            assert d_lsq < 1e-9 and d_aligner < 1e-9
        else:
            # The same least-squares estimator on the same noisy centres.
            assert d_lsq < 1e-9
            # model_aligner's LO-RANSAC refines on its inliers: close, not equal.
            assert d_aligner < 0.05


def test_secret_sim3_by_time_from_stamped_names(tmp_path: Path) -> None:
    truth = synthetic("SIMPLE_RADIAL")
    first = 1403636579763555584
    for image in truth.images.values():
        image.name = f"cam{image.camera_id}/{first + 50_000_000 * (image.frame_id)}.png"
    theirs, ours = secret()
    slam = pycolmap.Reconstruction(truth)
    slam.transform(theirs)
    src = write(slam, tmp_path / "m", "txt")

    rec = s2w.read_reconstruction(src)
    assert rec.kind == "colmap" and rec.flavour == "txt"
    # A rig's cameras share each stamp: one image per stamp for the time pairing.
    assert len(rec) == 8 and any("share their time stamp" in n for n in rec.notes)
    assert "time stamps" in rec.frame_times

    # Ground truth by time (seconds, TUM order): at each stamp the centre of the
    # image of the lowest camera id, the one the time pairing keeps.
    lowest: dict[int, Any] = {}
    for im in truth.images.values():
        if im.frame_id not in lowest or im.camera_id < lowest[im.frame_id].camera_id:
            lowest[im.frame_id] = im
    rows = []
    for fid, im in lowest.items():
        t = (first + 50_000_000 * fid) / 1e9
        c = im.projection_center()
        rows.append(f"{t!r} {float(c[0])!r} {float(c[1])!r} {float(c[2])!r} 0 0 0 1")
    gt = tmp_path / "gt.txt"
    gt.write_text("\n".join(sorted(rows)) + "\n")
    # pycolmap's synthetic frames are scattered, no path: the noise estimate
    # from second differences would call them noise, so the (zero) noise is stated.
    conv = s2w.convert(rec, reference=gt, reference_noise=1e-6)
    assert sim3_difference(conv.transform, ours.inverse().matrix()[:3]) < 1e-8
    report = conv.report
    assert report["reference_file"]["pairing"] == "time"
    assert report["reference_file"]["text"]["unit"] == "s"
    assert report["pairs_fitted"] == 8


def test_maupertuis_written_back_unchanged(data: Any, tmp_path: Path) -> None:
    src = data.path("colmap_maupertuis", "reconstruction")
    original = pycolmap.Reconstruction(str(src))
    rec = s2w.read_reconstruction(src)
    assert rec.kind == "colmap" and len(rec) == 4
    assert rec.names == ["00.jpg", "01.jpg", "02.jpg", "03.jpg"]
    assert "rank" in rec.frame_times
    cams = rec.cameras
    assert cams is not None and all(c is not None for c in cams)
    model = rec.model
    assert model is not None
    model.transformed(s2w.Sim3.identity()).write(tmp_path / "identity")
    assert_same_model(original, pycolmap.Reconstruction(str(tmp_path / "identity")), tol=0.0)

    # Through convert, with the model's own centres as the metric reference:
    # the fit is the identity to rounding and the output the original.
    names, centres = model.camera_centres()
    ref = write_names(tmp_path / "ref.txt", dict(zip(names, centres)))
    conv = s2w.convert(src, reference=ref)
    assert_allclose(conv.transform.matrix(), np.eye(4), atol=1e-9)
    conv.write_all(tmp_path / "out")
    assert_same_model(original, pycolmap.Reconstruction(str(tmp_path / "out" / "model")), 1e-9)
    # A reference by time cannot pair images named 00.jpg …
    tum = tmp_path / "tum.txt"
    tum.write_text("".join(f"{k} {c[0]} {c[1]} {c[2]} 0 0 0 1\n" for k, c in enumerate(centres)))
    with pytest.raises(s2w.InvalidInputError, match="no time stamps"):
        s2w.convert(src, reference=tum)


def test_octree_from_colmap_points_uses_observing_images(tmp_path: Path) -> None:
    truth, src = disguised_model(tmp_path, "OPENCV", "bin")
    ref = write_names(tmp_path / "ref.txt", true_centres(truth))
    conv = s2w.convert(src, reference=ref, octree_resolution=0.25)
    assert conv.octree is not None
    report = conv.report
    assert report["octree"]["points"] == 60
    assert "nearest" in report["reconstruction"]["octree_origins"]
    # Every point's voxel is occupied, and the rays from the cameras cleared space.
    assert np.all(conv.octree.state(conv.cloud.points) == 1)
    assert report["octree"]["leaves_free"] > 0


def test_reference_names_are_checked(tmp_path: Path) -> None:
    truth, src = disguised_model(tmp_path, "OPENCV", "bin")
    centres = true_centres(truth)
    two = dict(list(centres.items())[:2])
    two["nope.png"] = np.zeros(3)
    with pytest.raises(s2w.InvalidInputError, match=r"nope\.png.*need at least 3, got 2"):
        s2w.convert(src, reference=write_names(tmp_path / "few.txt", two))
    extra = dict(centres)
    extra["missing.png"] = np.ones(3)
    conv = s2w.convert(src, reference=write_names(tmp_path / "extra.txt", extra))
    names = conv.report["reference_file"]["names"]
    assert (names["matched"], names["unknown"], names["unknown_examples"]) == (
        16,
        1,
        ["missing.png"],
    )
    with pytest.raises(s2w.InvalidInputError, match="offset"):
        s2w.convert(src, reference=tmp_path / "extra.txt", offset=0.5)
    with pytest.raises(s2w.InvalidInputError, match="reference"):
        s2w.convert(src, reference_format="names")
    with pytest.raises(s2w.InvalidInputError, match="reference"):
        s2w.convert(src)


# ---------------------------------------------------------------- DROID-SLAM


def quat_xyzw(r: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Unit quaternion (x, y, z, w) of a rotation matrix (Shepperd)."""
    t = np.trace(r)
    if t > 0:
        s = 2 * np.sqrt(1 + t)
        q = [(r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s, s / 4]
    else:
        i = int(np.argmax(np.diag(r)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2 * np.sqrt(1 + r[i, i] - r[j, j] - r[k, k])
        q = [0.0, 0.0, 0.0, (r[k, j] - r[j, k]) / s]
        q[i] = s / 4
        q[j] = (r[j, i] + r[i, j]) / s
        q[k] = (r[k, i] + r[i, k]) / s
    return np.array(q)


def write_droid(sim: s2w.Simulation, path: Path) -> None:
    """The simulated keyframes as DROID-SLAM's save_reconstruction writes them:
    world-to-camera [t, q xyzw], full-resolution disparities (disps_up),
    intrinsics at 1/8, BGR images channel first. LSD-SLAM keyframe poses carry
    a scale s (p_slam = s R p_cam + t); DROID-SLAM's are rigid, so the depth
    takes it: disparity / s."""
    path.mkdir(parents=True, exist_ok=True)
    fx, fy, cx, cy, w, h = sim.camera
    poses = []
    disps = []
    for pose, idepth in zip(sim.keyframe_poses, sim.keyframe_idepth):
        m = pose.matrix()
        r = m[:3, :3] / pose.scale
        inv_r = r.T
        t = -inv_r @ m[:3, 3]
        poses.append(np.concatenate([t, quat_xyzw(inv_r)]))
        disps.append(idepth / pose.scale)
    gray = sim.keyframe_intensity
    images = np.repeat(gray[:, None, :, :], 3, axis=1)
    n = len(poses)
    np.save(path / "tstamps.npy", sim.keyframe_timestamps.astype(np.float64))
    np.save(path / "images.npy", images.astype(np.uint8))
    np.save(path / "poses.npy", np.array(poses, dtype=np.float32))
    np.save(path / "disps.npy", np.array(disps, dtype=np.float32))
    np.save(path / "intrinsics.npy", np.tile(np.array([fx, fy, cx, cy]) / 8, (n, 1)))


@pytest.mark.slow
def test_droid_folder_of_the_simulated_scene(tmp_path: Path) -> None:
    sim = s2w.simulate(seed=3, reduced=8)
    folder = tmp_path / "droid"
    write_droid(sim, folder)
    ref = tmp_path / "reference.txt"
    sim.reference.write_tum(ref)

    rec = s2w.read_reconstruction(folder, depth_threshold=0.05)
    assert rec.kind == "droid" and len(rec.keyframes) == len(sim.keyframe_poses)
    conv = s2w.convert(rec, reference=ref)
    truth = s2w.backproject(rec.keyframes, s2w.PointFilter.none(), transform=sim.t_world_slam)
    assert len(conv.cloud.points) == len(truth.points) > 1000
    ev = s2w.evaluate(sim, conv.cloud.points, conv.transform)
    ev_true = s2w.evaluate(sim, truth.points, sim.t_world_slam)
    print(
        f"DROID cloud rmse {ev['cloud']['rmse']:.5f} m, "
        f"with the true transform {ev_true['cloud']['rmse']:.5f} m"
    )
    assert ev["cloud"]["rmse"] <= 1.1 * ev_true["cloud"]["rmse"]
    report = conv.report
    assert report["reconstruction"]["kind"] == "droid"
    assert any("neighbouring keyframes" in n for n in report["reconstruction"]["notes"])

    # The same folder from its path, written as a set.
    conv2 = s2w.convert(folder, reference=ref, depth_threshold=0.05)
    assert_allclose(conv2.transform.matrix(), conv.transform.matrix(), atol=1e-12)
    conv2.write_all(tmp_path / "out")
    back, _ = s2w.read_trajectory(tmp_path / "out" / "trajectory.txt")
    assert len(back) == len(sim.keyframe_poses)


# ---------------------------------------------------------------- trajectory files


def test_orbslam3_nanoseconds_align_without_a_flag(data: Any, tmp_path: Path) -> None:
    kf = data.path("euroc_mh01_orbslam3_mono", "kf_dataset-MH01_mono.txt")
    gt = data.path("euroc_mh01_orbslam3_mono", "MH_01_easy.txt")
    rec = s2w.read_reconstruction(kf)
    info = rec.text_info
    assert info is not None and (info.unit, info.unit_detected) == ("ns", True)
    conv = s2w.convert(kf, reference=gt)
    report = conv.report
    # evo 1.38.1 -as on the same files (PROVENANCE.md): 352/363 pairs,
    # scale 5.148581120866326, rmse 0.047964 m.
    assert report["ape"]["n_pairs"] == 352
    assert conv.transform.scale == pytest.approx(5.148581120866326, rel=1e-9)
    assert report["ape"]["rmse"] == pytest.approx(0.047964, abs=5e-7)
    text = report["reconstruction"]["text"]
    assert (text["unit"], text["unit_detected"], text["delimiter"]) == ("ns", True, "whitespace")
    ref_text = report["reference_file"]["text"]
    assert (ref_text["unit"], report["reference_file"]["format"]) == ("s", "tum")
    conv.write_all(tmp_path / "out")
    written = json.loads((tmp_path / "out" / "report.json").read_text())
    assert written["reconstruction"]["text"]["unit"] == "ns"
    jsonschema = pytest.importorskip("jsonschema")
    jsonschema.validate(
        written, json.loads(SCHEMA.read_text()), cls=jsonschema.Draft202012Validator
    )


def test_nanoseconds_forced_to_seconds_name_both_ranges(data: Any) -> None:
    kf = data.path("euroc_mh01_orbslam3_mono", "kf_dataset-MH01_mono.txt")
    gt = data.path("euroc_mh01_orbslam3_mono", "MH_01_easy.txt")
    with pytest.raises(s2w.InvalidInputError, match="nanoseconds") as e:
        s2w.convert(kf, reference=gt, time_unit="s")
    assert "kf_dataset-MH01_mono.txt" in str(e.value) and "MH_01_easy.txt" in str(e.value)


def test_trajectory_with_its_ply(tmp_path: Path) -> None:
    """A MASt3R-SLAM-like logs/ folder: seq.txt (TUM) and seq.ply side by side."""
    rng = np.random.default_rng(2)
    secret_t = s2w.Sim3.from_quaternion([0.1, 0.2, -0.1, 0.97], [1.0, 2.0, 3.0], 0.25)
    times = np.arange(40) * 0.1
    world = np.column_stack([np.cos(times), np.sin(times), 0.3 * times])
    gt = s2w.Trajectory(times, world)
    gt.write_tum(tmp_path / "gt.txt")
    slam = gt.transformed(secret_t)
    logs = tmp_path / "logs"
    logs.mkdir()
    slam.write_tum(logs / "seq.txt")
    pts_world = rng.uniform(-1, 1, size=(500, 3))
    s2w.PointCloud(secret_t.apply(pts_world).astype(np.float32)).write_ply(logs / "seq.ply")
    rec = s2w.read_reconstruction(logs)
    assert rec.kind == "trajectory" and rec.cloud is not None and len(rec.cloud.points) == 500
    conv = s2w.convert(logs, reference=tmp_path / "gt.txt")
    assert_allclose(conv.cloud.points, pts_world, atol=1e-5)
    assert conv.report["reconstruction"]["cloud"].endswith("seq.ply")
    with pytest.raises(s2w.InvalidInputError, match="rays"):
        s2w.convert(logs, reference=tmp_path / "gt.txt", octree_resolution=0.1)
    with pytest.raises(s2w.FormatError, match="no poses"):
        s2w.read_reconstruction(logs / "seq.ply")
