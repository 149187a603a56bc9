"""The 2-D grid from Python: the simulated paper scene projected against its geometry,
nav2 map_server files read by Pillow / PyYAML / numpy (and decoded with map_server's
own rule), and the grid messages decoded by the ROS 1 / ROS 2 / protobuf MCAP packages."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt
import pytest

import slam2world as s2w

RES = 0.1


@pytest.fixture(scope="module")
def scene(tmp_path_factory: pytest.TempPathFactory) -> tuple[s2w.Simulation, s2w.OccupancyMap]:
    """The paper's run (reduced 4x: 160x120 images, 30 keyframes), simulated to an
    MCAP log, converted with a 0.1 m octree."""
    log = tmp_path_factory.mktemp("sim") / "sim.mcap"
    argv = ["slam2world", "simulate", "-o", str(log), "--reduced", "4", "--seed", "1"]
    assert s2w._slam2world.run_cli(argv) == 0
    sim = s2w.simulate(seed=1, reduced=4)
    conv = s2w.convert(log, skip_init="auto", octree_resolution=RES)
    assert conv.octree is not None
    return sim, conv.octree


def cell_centres(g: s2w.Grid) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """World x, y of every cell centre, (height, width) each."""
    x0, y0 = g.origin
    xs = x0 + (np.arange(g.width) + 0.5) * g.resolution
    ys = y0 + (np.arange(g.height) + 0.5) * g.resolution
    return np.meshgrid(xs, ys)


def cube_distance(
    sim: s2w.Simulation, x: npt.NDArray[np.float64], y: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """Distance (metres, x-y plane) from each point to the nearest cube footprint
    (0 inside one), from the scene geometry."""
    best = np.full(x.shape, np.inf)
    for lo in sim.cube_min:
        hi = lo + sim.cube_size
        dx = np.maximum(np.maximum(lo[0] - x, x - hi[0]), 0.0)
        dy = np.maximum(np.maximum(lo[1] - y, y - hi[1]), 0.0)
        best = np.minimum(best, np.hypot(dx, dy))
    return best


@pytest.mark.slow
def test_scene_grid_marks_the_cubes_occupied_and_the_plane_free(
    scene: tuple[s2w.Simulation, s2w.OccupancyMap],
) -> None:
    sim, m = scene
    # Above the floor's voxel layer (centres 0.05) and below the cube tops (1 m).
    g = m.grid(0.15, 0.85)
    assert g.resolution == RES and g.z_band == (0.15, 0.85)
    assert g.probability.shape == g.top_z.shape == (g.height, g.width)
    assert g.probability.dtype == np.float32
    x, y = cell_centres(g)
    d = cube_distance(sim, x, y)
    occ = g.occupied()
    free = g.free()
    known = ~np.isnan(g.probability)
    assert np.array_equal(occ | free, known) and not np.any(occ & free)

    # Every cube: the side faces the camera sees make the cells along them
    # occupied. A face lies on a cell border, so its voxels are the cells within
    # half a cell of the face line (on either side); the far faces are never seen.
    for i, lo in enumerate(sim.cube_min):
        hi = lo + sim.cube_size
        along_y = (y > lo[1] + RES) & (y < hi[1] - RES)
        along_x = (x > lo[0] + RES) & (x < hi[0] - RES)
        faces = {
            "-x": along_y & (np.abs(x - lo[0]) < RES),
            "+x": along_y & (np.abs(x - hi[0]) < RES),
            "-y": along_x & (np.abs(y - lo[1]) < RES),
            "+y": along_x & (np.abs(y - hi[1]) < RES),
        }
        seen = {k: float(occ[f].mean()) for k, f in faces.items() if f.sum() >= 8}
        assert max(seen.values()) >= 0.9, f"cube {i}: faces occupied {seen}"
        near = (x > lo[0] - RES) & (x < hi[0] + RES) & (y > lo[1] - RES) & (y < hi[1] + RES)
        assert int((occ & near).sum()) >= 16, f"cube {i}"
        # The inside (a cell or more from every face) is never seen free: rays
        # stop at the faces.
        core = (x > lo[0] + RES) & (x < hi[0] - RES) & (y > lo[1] + RES) & (y < hi[1] - RES)
        assert not np.any(free[core]), f"cube {i} has free cells inside"
        # Occupied cells carry the height of a voxel in the band.
        tops = g.top_z[near & occ]
        assert np.all((tops >= 0.15 - 1e-6) & (tops <= 0.85 + 1e-6))

    # Occupied cells lie on the cubes' outlines (within 0.2 m of a footprint),
    # apart from a few noisy points.
    stray = occ & (d > 0.2)
    assert stray.sum() <= 0.005 * occ.sum(), (
        f"{stray.sum()} of {occ.sum()} occupied cells off the cubes"
    )

    # The plane between the cubes: known and free.
    px, py = sim.plane_half
    open_floor = (d > 0.25) & (np.abs(x) < px - 0.25) & (np.abs(y) < py - 0.25)
    n_open = int(open_floor.sum())
    assert n_open > 1000
    assert float(known[open_floor].mean()) > 0.7
    assert not np.any(occ[open_floor])
    assert np.all(np.isnan(g.top_z[open_floor & free]))


def test_coarse_cells_keep_every_obstacle(
    scene: tuple[s2w.Simulation, s2w.OccupancyMap],
) -> None:
    _, m = scene
    fine = m.grid(0.15, 0.85)
    coarse = m.grid(0.15, 0.85, resolution=0.3)
    assert coarse.resolution == pytest.approx(0.3)
    # Cells of 0.3 m align to multiples of 0.3 m in the world.
    assert coarse.origin[0] / 0.3 == pytest.approx(round(coarse.origin[0] / 0.3))
    # Every fine occupied cell's coarse cell is occupied (the most occupied voxel wins).
    x, y = cell_centres(fine)
    sel = fine.occupied()
    cols = np.floor((x[sel] - coarse.origin[0]) / 0.3).astype(int)
    rows = np.floor((y[sel] - coarse.origin[1]) / 0.3).astype(int)
    assert np.all(coarse.occupied()[rows, cols])
    with pytest.raises(s2w.InvalidInputError, match="resolution"):
        m.grid(0.15, 0.85, resolution=0.25)
    with pytest.raises(s2w.InvalidInputError, match="resolution"):
        m.grid(0.15, 0.85, resolution=0.05)


def test_nav2_files_read_back(
    scene: tuple[s2w.Simulation, s2w.OccupancyMap], tmp_path: Path
) -> None:
    image_mod = pytest.importorskip("PIL.Image")
    yaml = pytest.importorskip("yaml")
    _, m = scene
    g = m.grid(0.15, 0.85)
    image, meta, height = g.write_nav2(tmp_path)
    assert Path(image) == tmp_path / "map.pgm"
    assert Path(meta) == tmp_path / "map.yaml"
    assert Path(height) == tmp_path / "map_height.npy"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.pgm", "map.yaml", "map_height.npy"]

    with image_mod.open(image) as im:
        assert im.format == "PPM" and im.mode == "L"
        assert im.size == (g.width, g.height)
        px = np.asarray(im)
    assert set(np.unique(px).tolist()) <= {0, 205, 254}
    # Row 0 of the image is the highest y.
    want = np.full(g.probability.shape, 205, dtype=np.uint8)
    want[g.free()] = 254
    want[g.occupied()] = 0
    np.testing.assert_array_equal(px, np.flipud(want))

    with open(meta) as f:
        doc = yaml.safe_load(f)
    assert set(doc) == {
        "image",
        "mode",
        "resolution",
        "origin",
        "negate",
        "occupied_thresh",
        "free_thresh",
    }
    assert doc["image"] == "map.pgm" and doc["mode"] == "trinary" and doc["negate"] == 0
    assert doc["resolution"] == pytest.approx(RES)
    assert doc["origin"] == pytest.approx([g.origin[0], g.origin[1], 0.0])
    assert 0 < doc["free_thresh"] < doc["occupied_thresh"] <= 1

    # nav2 map_server's loadMapFromFile on these files (map_io.cpp, trinary):
    # occ = 1 - value / 255; occupied if occupied_thresh < occ, free if
    # occ < free_thresh, else unknown; image row y is grid row height - 1 - y.
    occ = 1.0 - px.astype(np.float64) / 255.0
    loaded = np.full(px.shape, -1, dtype=np.int8)
    loaded[occ < doc["free_thresh"]] = 0
    loaded[doc["occupied_thresh"] < occ] = 100
    loaded = np.flipud(loaded)
    expect = np.full(g.probability.shape, -1, dtype=np.int8)
    expect[g.free()] = 0
    expect[g.occupied()] = 100
    np.testing.assert_array_equal(loaded, expect)
    assert np.any(expect == -1) and np.any(expect == 0) and np.any(expect == 100)

    top = np.load(height)
    assert top.dtype == np.float32 and top.shape == (g.height, g.width)
    np.testing.assert_array_equal(top, np.flipud(g.top_z))

    # A prefix instead of a folder, and a stricter threshold.
    files = g.write_nav2(tmp_path / "floor", occupied_threshold=0.9)
    assert [Path(p).name for p in files] == ["floor.pgm", "floor.yaml", "floor_height.npy"]
    with open(files[1]) as f:
        assert yaml.safe_load(f)["image"] == "floor.pgm"
    with image_mod.open(files[0]) as im:
        strict = np.asarray(im)
    assert (strict == 0).sum() <= (px == 0).sum()
    with pytest.raises(s2w.InvalidInputError, match="occupied_threshold"):
        g.write_nav2(tmp_path / "bad", occupied_threshold=1.5)


def test_grid_arrays_are_read_only_and_masks_follow_the_threshold(
    scene: tuple[s2w.Simulation, s2w.OccupancyMap],
) -> None:
    _, m = scene
    g = m.grid(0.15, 0.85)
    with pytest.raises(ValueError):
        g.probability[0, 0] = 1.0
    # The same array every time (built once, not copied per access).
    assert g.probability is g.probability
    p = g.probability
    np.testing.assert_array_equal(g.occupied(0.7), ~np.isnan(p) & (p >= np.float32(0.7)))
    np.testing.assert_array_equal(g.free(0.7), ~np.isnan(p) & (p < np.float32(0.7)))
    with pytest.raises(s2w.InvalidInputError, match="threshold"):
        g.occupied(0.0)
    assert "Grid(width=" in repr(g)


def _reference_ros1_definition() -> bytes:
    # nav_msgs/OccupancyGrid with its dependencies, from the ROS 1 message files.
    sep = "=" * 80 + "\n"
    return (
        "Header header\nnav_msgs/MapMetaData info\nint8[] data\n"
        + sep
        + "MSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n"
        + sep
        + "MSG: nav_msgs/MapMetaData\ntime map_load_time\nfloat32 resolution\n"
        "uint32 width\nuint32 height\ngeometry_msgs/Pose origin\n"
        + sep
        + "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\n"
        "geometry_msgs/Quaternion orientation\n"
        + sep
        + "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n"
        + sep
        + "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n"
    ).encode()


def _mcap_roundtrip(
    schema_name: str,
    schema_encoding: str,
    schema_data: bytes,
    message_encoding: str,
    data: bytes,
    factory: Any,
) -> Any:
    from mcap.reader import make_reader
    from mcap.writer import Writer

    buf = io.BytesIO()
    w: Any = Writer(buf)
    w.start()
    sid = w.register_schema(name=schema_name, encoding=schema_encoding, data=schema_data)
    cid = w.register_channel(topic="/grid", message_encoding=message_encoding, schema_id=sid)
    w.add_message(channel_id=cid, log_time=7, data=data, publish_time=7)
    w.finish()
    buf.seek(0)
    msgs = [
        m for _, _, _, m in make_reader(buf, decoder_factories=[factory]).iter_decoded_messages()
    ]
    assert len(msgs) == 1
    return msgs[0]


def _expected_cells(g: s2w.Grid, threshold: float | None) -> npt.NDArray[np.int8]:
    p = g.probability
    out = np.full(p.shape, -1, dtype=np.int8)
    known = ~np.isnan(p)
    if threshold is None:
        out[known] = np.clip(np.round(p[known].astype(np.float64) * 100), 0, 100).astype(np.int8)
    else:
        out[known] = np.where(p[known] >= threshold, 100, 0)
    return out.ravel()


@pytest.mark.parametrize("threshold", [None, 0.5])
def test_occupancy_grid_decodes_with_the_ros_packages(
    scene: tuple[s2w.Simulation, s2w.OccupancyMap], threshold: float | None
) -> None:
    ros1 = pytest.importorskip("mcap_ros1.decoder")
    ros2 = pytest.importorskip("mcap_ros2.decoder")
    _, m = scene
    g = m.grid(0.15, 0.85, resolution=0.2)
    want = _expected_cells(g, threshold)
    assert np.any(want == -1) and np.any(want > 50)
    cases: list[tuple[Literal["ros1", "ros2"], Any, bytes | None]] = [
        ("ros1", ros1.DecoderFactory(), _reference_ros1_definition()),
        ("ros2", ros2.DecoderFactory(), None),
    ]
    for kind, factory, reference in cases:
        name, senc, sdata, menc, data = g.encode(
            kind, stamp=12.25, frame_id="world", occupied_threshold=threshold
        )
        assert name in ("nav_msgs/OccupancyGrid", "nav_msgs/msg/OccupancyGrid")
        # Decoded with our schema text and (ROS 1) with the ROS message files' text.
        for definition in [sdata] + ([reference] if reference else []):
            msg = _mcap_roundtrip(name, senc, definition, menc, data, factory)
            assert msg.header.frame_id == "world"
            stamp = msg.header.stamp
            sec = stamp.secs if kind == "ros1" else stamp.sec
            nsec = stamp.nsecs if kind == "ros1" else stamp.nanosec
            assert (sec, nsec) == (12, 250_000_000)
            info = msg.info
            assert (info.width, info.height) == (g.width, g.height)
            assert info.resolution == pytest.approx(0.2)
            assert (info.origin.position.x, info.origin.position.y) == g.origin
            assert info.origin.orientation.w == 1.0
            cells = np.frombuffer(bytes(np.asarray(msg.data, dtype=np.int8)), dtype=np.int8)
            np.testing.assert_array_equal(cells, want)


def test_foxglove_grid_decodes_with_protobuf(
    scene: tuple[s2w.Simulation, s2w.OccupancyMap],
) -> None:
    descriptor_pb2 = pytest.importorskip("google.protobuf.descriptor_pb2")
    descriptor_pool = pytest.importorskip("google.protobuf.descriptor_pool")
    message_factory = pytest.importorskip("google.protobuf.message_factory")

    _, m = scene
    g = m.grid(0.15, 0.85)
    name, senc, sdata, menc, data = g.encode("foxglove", stamp=3.5, frame_id="world")
    assert (name, senc, menc) == ("foxglove.Grid", "protobuf", "protobuf")
    fds = descriptor_pb2.FileDescriptorSet.FromString(sdata)
    pool = descriptor_pool.DescriptorPool()
    for f in fds.file:
        pool.Add(f)
    cls = message_factory.GetMessageClass(pool.FindMessageTypeByName("foxglove.Grid"))
    msg = cls.FromString(data)
    assert msg.frame_id == "world"
    assert (msg.timestamp.seconds, msg.timestamp.nanos) == (3, 500_000_000)
    assert (msg.pose.position.x, msg.pose.position.y, msg.pose.position.z) == (*g.origin, 0.0)
    assert msg.pose.orientation.w == 1.0
    assert msg.column_count == g.width
    assert (msg.cell_size.x, msg.cell_size.y) == (g.resolution, g.resolution)
    assert msg.cell_stride == 8 and msg.row_stride == 8 * g.width
    float32 = 7  # foxglove.PackedElementField.NumericType.FLOAT32
    assert [(f.name, f.offset, f.type) for f in msg.fields] == [
        ("probability", 0, float32),
        ("top_z", 4, float32),
    ]
    cells = np.frombuffer(msg.data, dtype="<f4").reshape(g.height, g.width, 2)
    np.testing.assert_array_equal(cells[..., 0], g.probability)
    np.testing.assert_array_equal(cells[..., 1], g.top_z)

    # The same through an MCAP file and the protobuf decoder Foxglove-style readers use.
    pb = pytest.importorskip("mcap_protobuf.decoder")
    decoded = _mcap_roundtrip(name, senc, sdata, menc, data, pb.DecoderFactory())
    assert decoded.column_count == g.width
    with pytest.raises(s2w.InvalidInputError, match="kind"):
        g.encode("json")  # type: ignore[arg-type]
