"""Geodesy against pymap3d and pyproj; GNSS readers on files written by pynmea2,
numpy and the mcap packages; LAS/LAZ read by laspy (+ lazrs), PCD by pypcd4 and
by a reader written from the PCD spec."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any, Literal

import laspy
import numpy as np
import pymap3d as pm
import pynmea2
import pytest
from conftest import data_path
from foxglove_schemas_protobuf.LocationFix_pb2 import LocationFix
from mcap.writer import Writer as McapWriter
from mcap_protobuf.writer import Writer as ProtobufWriter
from mcap_ros1._vendor.genpy.dynamic import generate_dynamic
from mcap_ros1.writer import Writer as Ros1Writer
from mcap_ros2.writer import Writer as Ros2Writer
from pypcd4 import PointCloud as PcdCloud
from pyproj import Transformer

import slam2world as s2w

MM = 1e-3
RNG = np.random.default_rng(16)


def _around(lat0: float, lon0: float, n: int, radius_m: float) -> tuple[np.ndarray, ...]:
    """Random positions within ~radius_m of (lat0, lon0), heights -100..3000 m."""
    north = RNG.uniform(-radius_m, radius_m, n)
    east = RNG.uniform(-radius_m, radius_m, n)
    lat = np.clip(lat0 + np.degrees(north / 6.37e6), -90.0, 90.0)
    coslat = max(np.cos(np.radians(lat0)), 1e-3)
    lon = lon0 + np.degrees(east / (6.37e6 * coslat))
    lon = (lon + 180.0) % 360.0 - 180.0
    alt = RNG.uniform(-100.0, 3000.0, n)
    return lat, lon, alt


def _pyproj_enu(lat: np.ndarray, lon: np.ndarray, alt: np.ndarray, o: tuple[float, ...]) -> Any:
    pipe = (
        "+proj=pipeline +step +proj=unitconvert +xy_in=deg +xy_out=rad "
        "+step +proj=cart +ellps=WGS84 "
        f"+step +proj=topocentric +ellps=WGS84 +lat_0={o[0]!r} +lon_0={o[1]!r} +h_0={o[2]!r}"
    )
    t = Transformer.from_pipeline(pipe)
    return np.column_stack(t.transform(lon, lat, alt))


ORIGINS = {
    "munich": (48.19, 11.62, 540.0),
    "equator": (0.0, 0.0, 0.0),
    "south": (-33.9, 18.4, 20.0),
    "near_north_pole": (89.7, 40.0, 100.0),
    "north_pole": (90.0, 0.0, 0.0),
    "near_south_pole": (-89.6, -120.0, 2800.0),
    "antimeridian_east": (10.0, 179.9, 50.0),
    "antimeridian_west": (-45.0, -179.95, 10.0),
}


@pytest.mark.parametrize("name", sorted(ORIGINS))
def test_enu_agrees_with_pymap3d_and_pyproj_over_100_km(name: str) -> None:
    o = ORIGINS[name]
    lat, lon, alt = _around(o[0], o[1], 500, 70_000.0)  # corners ~100 km away
    ours = s2w.geodetic_to_enu(lat, lon, alt, o)
    assert ours.shape == (500, 3) and ours.dtype == np.float64
    e, n, u = pm.geodetic2enu(lat, lon, alt, *o)
    np.testing.assert_allclose(ours, np.column_stack([e, n, u]), rtol=0, atol=MM)
    np.testing.assert_allclose(ours, _pyproj_enu(lat, lon, alt, o), rtol=0, atol=MM)
    assert np.max(np.hypot(ours[:, 0], ours[:, 1])) > 60_000.0
    # back again, compared in ECEF (longitude is meaningless at a pole)
    blat, blon, balt = s2w.enu_to_geodetic(ours, o)
    plat, plon, palt = pm.enu2geodetic(ours[:, 0], ours[:, 1], ours[:, 2], *o)
    a = np.column_stack(pm.geodetic2ecef(blat, blon, balt))
    b = np.column_stack(pm.geodetic2ecef(plat, plon, palt))
    c = np.column_stack(pm.geodetic2ecef(lat, lon, alt))
    np.testing.assert_allclose(a, b, rtol=0, atol=MM)
    np.testing.assert_allclose(a, c, rtol=0, atol=MM)


def test_ecef_agrees_with_pyproj_both_ways() -> None:
    lat = RNG.uniform(-90, 90, 300)
    lon = RNG.uniform(-180, 180, 300)
    alt = RNG.uniform(-500, 20_000, 300)
    ours = s2w.geodetic_to_ecef(lat, lon, alt)
    t = Transformer.from_crs("EPSG:4979", "EPSG:4978", always_xy=True)
    np.testing.assert_allclose(ours, np.column_stack(t.transform(lon, lat, alt)), atol=MM, rtol=0)
    blat, blon, balt = s2w.ecef_to_geodetic(ours)
    back = s2w.geodetic_to_ecef(blat, blon, balt)
    np.testing.assert_allclose(back, ours, atol=MM, rtol=0)
    np.testing.assert_allclose(balt, alt, atol=MM, rtol=0)


def _pyproj_utm(epsg: int, lat: np.ndarray, lon: np.ndarray) -> Any:
    t = Transformer.from_crs("EPSG:4326", f"EPSG:{epsg}", always_xy=True)
    return np.column_stack(t.transform(lon, lat))


@pytest.mark.parametrize(
    ("zone", "south", "lat_range"),
    [
        (32, False, (0.0, 84.0)),
        (1, False, (0.0, 60.0)),
        (60, True, (-80.0, 0.0)),
        (34, True, (-80, 0)),
    ],
)
def test_utm_agrees_with_pyproj_to_the_zone_edges(
    zone: int, south: bool, lat_range: tuple[float, float]
) -> None:
    cm = zone * 6 - 183
    # inside the zone, on both edges and half a degree beyond them
    lon = np.concatenate(
        [RNG.uniform(cm - 3, cm + 3, 200), [cm - 3.0, cm + 3.0, cm - 2.9999, cm + 2.9999]]
    )
    lon = np.concatenate([lon, [cm - 3.5, cm + 3.5]])
    lat = RNG.uniform(*lat_range, lon.size)
    lon = (lon + 180.0) % 360.0 - 180.0
    alt = RNG.uniform(0, 1000, lon.size)
    hemi: Literal["north", "south"] = "south" if south else "north"
    xyz, z, h, epsg = s2w.geodetic_to_utm(lat, lon, alt, zone, hemisphere=hemi)
    assert (z, h, epsg) == (zone, hemi, (32700 if south else 32600) + zone)
    np.testing.assert_allclose(xyz[:, :2], _pyproj_utm(epsg, lat, lon), atol=MM, rtol=0)
    np.testing.assert_array_equal(xyz[:, 2], alt)
    blat, blon, balt = s2w.utm_to_geodetic(xyz, zone, hemi)
    np.testing.assert_allclose(
        s2w.geodetic_to_ecef(blat, blon, balt), s2w.geodetic_to_ecef(lat, lon, alt), atol=MM
    )


def test_utm_zone_chosen_from_the_first_point() -> None:
    xyz, z, h, epsg = s2w.geodetic_to_utm([49.0, 49.1], [8.4, 8.5], [100.0, 90.0])
    assert (z, h, epsg) == (32, "north", 32632)
    np.testing.assert_allclose(
        xyz[:, :2], _pyproj_utm(32632, np.array([49.0, 49.1]), np.array([8.4, 8.5])), atol=MM
    )
    _, z, h, epsg = s2w.geodetic_to_utm([-12.0], [-77.0], [0.0])
    assert (z, h, epsg) == (18, "south", 32718)
    with pytest.raises(s2w.InvalidInputError, match="latitude"):
        s2w.geodetic_to_utm([86.0], [0.0], [0.0])


def test_evo_georeferenced_utm_round_trip() -> None:
    path = data_path("evo_georeferenced_utm", "georeferenced.tum")
    xyz = np.loadtxt(path)[:, 1:4]
    lat, lon, alt = s2w.utm_to_geodetic(xyz, 32, "north")
    t = Transformer.from_crs("EPSG:32632", "EPSG:4326", always_xy=True)
    plon, plat = t.transform(xyz[:, 0], xyz[:, 1])
    np.testing.assert_allclose(lat, plat, atol=1e-9)
    np.testing.assert_allclose(lon, plon, atol=1e-9)
    back, zone, hemi, epsg = s2w.geodetic_to_utm(lat, lon, alt)
    assert epsg == 32632
    assert np.max(np.linalg.norm(back - xyz, axis=1)) < MM


def test_shapes_and_bad_values_name_the_argument() -> None:
    with pytest.raises(s2w.InvalidInputError, match="lon"):
        s2w.geodetic_to_enu([1.0, 2.0], [1.0], [0.0, 0.0], (0.0, 0.0, 0.0))
    with pytest.raises(s2w.InvalidInputError, match="enu"):
        s2w.enu_to_geodetic(np.zeros((4, 2)), (0.0, 0.0, 0.0))
    with pytest.raises(s2w.InvalidInputError, match="position 1: latitude"):
        s2w.geodetic_to_ecef([0.0, 91.0], [0.0, 0.0], [0.0, 0.0])
    with pytest.raises(s2w.InvalidInputError, match="latitude"):
        s2w.geodetic_to_enu([0.0], [0.0], [0.0], (np.nan, 0.0, 0.0))
    with pytest.raises(s2w.InvalidInputError, match="origin"):
        s2w.geodetic_to_enu([0.0], [0.0], [0.0], "middle")  # type: ignore[arg-type]
    with pytest.raises(s2w.InvalidInputError, match="zone"):
        s2w.utm_to_geodetic(np.zeros((1, 3)), 61, "north")
    with pytest.raises(s2w.DegenerateError):
        s2w.ecef_to_geodetic(np.zeros((1, 3)))
    enu = s2w.geodetic_to_enu([10.0, 10.001], [20.0, 20.0], [5.0, 5.0], "first")
    np.testing.assert_allclose(enu[0], 0.0, atol=1e-9)


# ------------------------------------------------------------------ GNSS fixes


def test_gnss_fixes_checks_and_drops_no_fix() -> None:
    f = s2w.GnssFixes(
        [0.0, 1.0, 2.0],
        [48.0, np.nan, 48.001],
        [11.0, np.nan, 11.0],
        [500.0, np.nan, 501.0],
        status=["rtk_fixed", "no_fix", "single"],
    )
    assert len(f) == 2 and f.dropped_no_fix == 1
    assert f.status == ["rtk_fixed", "single"]
    assert f.covariance is None and f.weights() is None
    with pytest.raises(s2w.InvalidInputError, match="fix 1: latitude"):
        s2w.GnssFixes([0.0, 1.0], [48.0, np.nan], [11.0, 11.0], [0.0, 0.0])
    with pytest.raises(s2w.InvalidInputError, match="fix 0: latitude = 91"):
        s2w.GnssFixes([0.0], [91.0], [11.0], [0.0])
    with pytest.raises(s2w.InvalidInputError, match="fix 1: time"):
        s2w.GnssFixes([0.0, np.inf], [48.0, 48.0], [11.0, 11.0], [0.0, 0.0])
    with pytest.raises(s2w.InvalidInputError, match="covariance"):
        s2w.GnssFixes([0.0], [48.0], [11.0], [0.0], covariance=np.zeros((2, 3, 3)))
    with pytest.raises(s2w.InvalidInputError, match="status"):
        s2w.GnssFixes([0.0], [48.0], [11.0], [0.0], status=["great"])


def test_to_enu_weights_and_origin() -> None:
    n = 40
    lat = 48.0 + np.arange(n) * 2e-5
    lon = np.full(n, 11.0)
    alt = np.full(n, 500.0)
    cov = np.tile(np.diag([1.0, 2.0, 3.0]), (n, 1, 1))
    cov[3] = np.diag([4.0, 4.0, 4.0])
    f = s2w.GnssFixes(np.arange(n, dtype=float), lat, lon, alt, covariance=cov)
    traj, w, origin = f.to_enu("first")
    assert origin == (48.0, 11.0, 500.0)
    assert w is not None
    np.testing.assert_allclose(w[0], 1.0 / 2.0)
    np.testing.assert_allclose(w[3], 1.0 / 4.0)
    e, nn, u = pm.geodetic2enu(lat, lon, alt, *origin)
    np.testing.assert_allclose(traj.positions, np.column_stack([e, nn, u]), atol=MM)
    assert traj.orientations is None
    _, _, mean_origin = f.to_enu("mean")
    assert abs(mean_origin[0] - lat.mean()) < 1e-7
    with pytest.raises(s2w.DegenerateError, match="never moves"):
        s2w.GnssFixes(np.arange(5.0), np.full(5, 48.0), np.full(5, 11.0), np.full(5, 1.0)).to_enu()


def _gga(t: str, lat: str, ns: str, lon: str, ew: str, q: str, alt: str, sep: str) -> str:
    msg = pynmea2.GGA(
        "GN", "GGA", (t, lat, ns, lon, ew, q, "12", "0.8", alt, "M", sep, "M", "", "")
    )
    return str(msg)


def test_nmea_written_by_pynmea2(tmp_path: Path) -> None:
    lines = [
        str(
            pynmea2.RMC(
                "GP",
                "RMC",
                ("101500.00", "A", "4811.0", "N", "01137.0", "E", "0.1", "0.0", "070521", "", ""),
            )
        ),
        _gga("101500.00", "4811.0000", "N", "01137.0000", "E", "4", "500.0", "47.5"),
        str(
            pynmea2.GST(
                "GP", "GST", ("101500.00", "0.1", "0.1", "0.1", "0", "0.015", "0.012", "0.030")
            )
        ),
        _gga("101500.10", "", "", "", "", "0", "", ""),
        _gga("101500.20", "3352.2000", "S", "07037.8000", "W", "2", "12.5", "-20.0"),
    ]
    path = tmp_path / "log.nmea"
    path.write_text("\r\n".join(lines) + "\r\n")
    f = s2w.read_gnss(path)
    assert len(f) == 2 and f.dropped_no_fix == 1 and f.time_base == "source"
    parsed = [pynmea2.parse(s) for s in lines if "GGA" in s and ",0," not in s]
    np.testing.assert_allclose(f.lat, [p.latitude for p in parsed], atol=1e-12)
    np.testing.assert_allclose(f.lon, [p.longitude for p in parsed], atol=1e-12)
    np.testing.assert_allclose(f.alt, [547.5, -7.5])
    # 2021-05-07 10:15:00 UTC
    np.testing.assert_allclose(f.times, [1620382500.0, 1620382500.2], atol=1e-6)
    assert f.status == ["rtk_fixed", "differential"]
    cov = f.covariance
    assert cov is not None
    np.testing.assert_allclose(np.diag(cov[0]), [0.012**2, 0.015**2, 0.030**2])
    assert np.isnan(cov[1]).all()
    bad = path.read_text().replace("4811.0000", "4811.0001", 1)
    (tmp_path / "bad.nmea").write_text(bad)
    with pytest.raises(s2w.FormatError, match=r"bad.nmea:2: NMEA checksum"):
        s2w.read_gnss(tmp_path / "bad.nmea")


def test_fourseasons_nmea() -> None:
    f = s2w.read_gnss(data_path("fourseasons_sample", "septentrio.nmea"))
    assert len(f) == 3414 and f.dropped_no_fix == 0
    first = pynmea2.parse(
        "$GPGGA,124637.60,4811.7614623,N,01137.1671785,E,5,05,2.6,494.6573,M,47.5367,M,0.6,3119*42"
    )
    assert abs(f.lat[0] - first.latitude) < 1e-12 and abs(f.lon[0] - first.longitude) < 1e-12
    assert f.status.count("rtk_fixed") == 2794


def test_csv_written_by_numpy(tmp_path: Path) -> None:
    t = np.arange(6) * 0.2
    lat = 42.3758 + np.arange(6) * 1e-4
    lon = np.full(6, -71.147)
    alt = np.linspace(10, 12, 6)
    var = np.tile([0.81, 0.81, 3.24], (6, 1))
    path = tmp_path / "fix.csv"
    np.savetxt(
        path,
        np.column_stack([t, lat, lon, alt, var]),
        delimiter=",",
        header="t,lat,lon,alt,ve,vn,vu",
    )
    f = s2w.read_gnss(path)
    np.testing.assert_array_equal(f.lat, lat)
    w = f.weights()
    assert w is not None
    np.testing.assert_allclose(w, 3.0 / 4.86)
    txt = tmp_path / "fix.txt"
    np.savetxt(txt, np.column_stack([t, lat, lon, alt]))
    g = s2w.read_gnss(txt, format="csv", geoid_offset=-33.0)
    np.testing.assert_allclose(g.alt, alt - 33.0)
    assert g.covariance is None
    full = tmp_path / "full.csv"
    cov = np.array([[4.0, 1.0, 0.0], [1.0, 4.0, 0.5], [0.0, 0.5, 9.0]])
    np.savetxt(full, np.column_stack([t, lat, lon, alt, np.tile(cov.ravel(), (6, 1))]), fmt="%.10g")
    h = s2w.read_gnss(full)
    c = h.covariance
    assert c is not None
    np.testing.assert_array_equal(c, np.broadcast_to(cov, (6, 3, 3)))
    with pytest.raises(s2w.InvalidInputError, match="format"):
        s2w.read_gnss(txt, format="gpx")


NAVSATFIX_ROS1 = """std_msgs/Header header
sensor_msgs/NavSatStatus status
float64 latitude
float64 longitude
float64 altitude
float64[9] position_covariance
uint8 position_covariance_type
================================================================================
MSG: std_msgs/Header
uint32 seq
time stamp
string frame_id
================================================================================
MSG: sensor_msgs/NavSatStatus
int8 status
uint16 service
"""

NAVSATFIX_ROS2 = """std_msgs/Header header
NavSatStatus status
float64 latitude
float64 longitude
float64 altitude
float64[9] position_covariance
uint8 position_covariance_type
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
================================================================================
MSG: sensor_msgs/NavSatStatus
int8 status
uint16 service
"""

N_FIX = 12
FIX_LAT = 42.3758 + np.arange(N_FIX) * 2e-4
FIX_LON = -71.1478 + np.arange(N_FIX) * 1e-4
FIX_ALT = np.linspace(-5.0, 5.0, N_FIX)
FIX_STATUS = [1] * N_FIX
FIX_STATUS[4] = -1  # no fix
FIX_COV = [0.81, 0.0, 0.0, 0.0, 0.81, 0.0, 0.0, 0.0, 3.24]


def _check_fixes(f: s2w.GnssFixes, times: np.ndarray, cov: bool = True) -> None:
    keep = np.array(FIX_STATUS) >= 0
    assert len(f) == N_FIX - 1 and f.dropped_no_fix == 1
    np.testing.assert_allclose(f.times, times[keep], atol=1e-9)
    np.testing.assert_array_equal(f.lat, FIX_LAT[keep])
    np.testing.assert_array_equal(f.lon, FIX_LON[keep])
    np.testing.assert_array_equal(f.alt, FIX_ALT[keep])
    if cov:
        c = f.covariance
        assert c is not None
        np.testing.assert_array_equal(c[0], np.reshape(FIX_COV, (3, 3)))


def test_navsatfix_ros1_mcap(tmp_path: Path) -> None:
    Fix = generate_dynamic("sensor_msgs/NavSatFix", NAVSATFIX_ROS1)["sensor_msgs/NavSatFix"]
    path = tmp_path / "ros1.mcap"
    times = 1432235498.0 + 0.4 * np.arange(N_FIX)
    with open(path, "wb") as fh:
        w = Ros1Writer(fh)
        for i in range(N_FIX):
            m = Fix()
            m.header.stamp.secs = int(times[i])
            m.header.stamp.nsecs = int(round((times[i] - int(times[i])) * 1e9))
            m.header.frame_id = "/gps"
            m.status.status = FIX_STATUS[i]
            m.status.service = 1
            m.latitude, m.longitude, m.altitude = FIX_LAT[i], FIX_LON[i], FIX_ALT[i]
            m.position_covariance = FIX_COV
            m.position_covariance_type = 1
            w.write_message("/fix", m, log_time=i)
        w.finish()
    f = s2w.read_gnss(path)
    _check_fixes(f, times)
    assert set(f.status) == {"differential"}


def test_navsatfix_ros2_mcap(tmp_path: Path) -> None:
    path = tmp_path / "ros2.mcap"
    times = 100.0 + 0.2 * np.arange(N_FIX)
    with open(path, "wb") as fh:
        w = Ros2Writer(fh)
        schema = w.register_msgdef("sensor_msgs/msg/NavSatFix", NAVSATFIX_ROS2)
        for i in range(N_FIX):
            msg = {
                "header": {
                    "stamp": {"sec": int(times[i]), "nanosec": int(round((times[i] % 1) * 1e9))},
                    "frame_id": "gnss",
                },
                "status": {"status": FIX_STATUS[i], "service": 3},
                "latitude": FIX_LAT[i],
                "longitude": FIX_LON[i],
                "altitude": FIX_ALT[i],
                "position_covariance": FIX_COV,
                "position_covariance_type": 2,
            }
            w.write_message("/gnss/fix", schema, msg, log_time=i, publish_time=i)
        w.finish()
    _check_fixes(s2w.read_gnss(path), times)


def test_location_fix_protobuf_and_json_mcap(tmp_path: Path) -> None:
    times = 50.0 + 0.5 * np.arange(N_FIX)
    keep = [i for i in range(N_FIX) if FIX_STATUS[i] >= 0]
    pb = tmp_path / "pb.mcap"
    with open(pb, "wb") as fh:
        w = ProtobufWriter(fh)
        for i in keep:
            m = LocationFix()
            m.timestamp.seconds = int(times[i])
            m.timestamp.nanos = int(round((times[i] % 1) * 1e9))
            m.frame_id = "antenna"
            m.latitude, m.longitude, m.altitude = FIX_LAT[i], FIX_LON[i], FIX_ALT[i]
            m.position_covariance.extend(FIX_COV)
            m.position_covariance_type = LocationFix.DIAGONAL_KNOWN
            w.write_message("/location", m, log_time=i, publish_time=i)
        w.finish()
    f = s2w.read_gnss(pb)
    assert len(f) == len(keep) and f.dropped_no_fix == 0
    np.testing.assert_array_equal(f.lat, FIX_LAT[keep])
    np.testing.assert_allclose(f.times, times[keep], atol=1e-9)
    cov = f.covariance
    assert cov is not None
    np.testing.assert_array_equal(cov[2], np.reshape(FIX_COV, (3, 3)))

    js = tmp_path / "json.mcap"
    with open(js, "wb") as fh:
        jw = McapWriter(fh)
        jw.start(profile="", library="test")
        sid = jw.register_schema(name="foxglove.LocationFix", encoding="jsonschema", data=b"{}")
        cid = jw.register_channel(topic="/location", message_encoding="json", schema_id=sid)
        for i in keep:
            doc = {
                "timestamp": {"sec": int(times[i]), "nsec": int(round((times[i] % 1) * 1e9))},
                "frame_id": "antenna",
                "latitude": FIX_LAT[i],
                "longitude": FIX_LON[i],
                "altitude": FIX_ALT[i],
                "position_covariance": FIX_COV,
                "position_covariance_type": 2,
            }
            jw.add_message(cid, log_time=i, data=json.dumps(doc).encode(), publish_time=i)
        jw.finish()
    g = s2w.read_gnss(js)
    # serde_json parses floats to within 1 ulp (no float_roundtrip feature): 1e-14 degrees
    np.testing.assert_allclose(g.lat, f.lat, rtol=0, atol=1e-12)
    np.testing.assert_allclose(g.alt, f.alt, rtol=0, atol=1e-12)
    np.testing.assert_allclose(g.times, f.times, atol=1e-9)


# ------------------------------------------------------------------ georeferenced outputs


def _cloud(n: int = 3000, colors: bool = True) -> s2w.PointCloud:
    pts = np.column_stack(
        [RNG.uniform(-800, 800, n), RNG.uniform(-600, 600, n), RNG.uniform(-20, 60, n)]
    ).astype(np.float32)
    col = RNG.integers(0, 256, (n, 3), dtype=np.uint8) if colors else None
    return s2w.PointCloud(pts, col)


@pytest.mark.parametrize("suffix", ["las", "laz"])
def test_las_in_utm_read_by_laspy_matches_pyproj(tmp_path: Path, suffix: str) -> None:
    origin = (49.0159, 8.4266, 115.0)
    cloud = _cloud()
    path = tmp_path / f"map.{suffix}"
    assert cloud.write_las(path, origin=origin) == 32632
    las = laspy.read(path)
    assert las.header.version.major == 1 and las.header.version.minor == 4
    crs = las.header.parse_crs()
    assert crs is not None and crs.to_epsg() == 32632
    assert crs.utm_zone == "32N" and crs.ellipsoid is not None
    assert crs.ellipsoid.inverse_flattening == pytest.approx(298.257223563, abs=1e-9)
    p = cloud.points.astype(np.float64)
    lat, lon, alt = pm.enu2geodetic(p[:, 0], p[:, 1], p[:, 2], *origin)
    t = Transformer.from_crs("EPSG:4979", "EPSG:32632", always_xy=True)
    e, n = t.transform(lon, lat)
    got = np.column_stack([las.x, las.y, las.z])
    np.testing.assert_allclose(got, np.column_stack([e, n, alt]), atol=MM, rtol=0)
    colors = cloud.colors
    assert colors is not None
    np.testing.assert_array_equal(las.red, colors[:, 0].astype(np.uint16) * 257)
    np.testing.assert_array_equal(las.blue, colors[:, 2].astype(np.uint16) * 257)
    assert max(las.header.scales) <= MM


def test_las_in_ecef_and_other_zones(tmp_path: Path) -> None:
    origin = (-33.9, 18.4, 20.0)
    cloud = _cloud(500, colors=False)
    path = tmp_path / "ecef.las"
    assert cloud.write_las(path, origin=origin, crs="ecef") == 4978
    las = laspy.read(path)
    crs = las.header.parse_crs()
    assert crs is not None and crs.to_epsg() == 4978
    p = cloud.points.astype(np.float64)
    x, y, z = pm.enu2ecef(p[:, 0], p[:, 1], p[:, 2], *origin)
    np.testing.assert_allclose(
        np.column_stack([las.x, las.y, las.z]), np.column_stack([x, y, z]), atol=MM
    )
    # a zone that is not the origin's: still exact
    path = tmp_path / "z33.las"
    assert cloud.write_las(path, origin=origin, zone=33, hemisphere="south") == 32733
    las = laspy.read(path)
    lat, lon, alt = pm.enu2geodetic(p[:, 0], p[:, 1], p[:, 2], *origin)
    e, n = Transformer.from_crs("EPSG:4979", "EPSG:32733", always_xy=True).transform(lon, lat)
    np.testing.assert_allclose(np.column_stack([las.x, las.y]), np.column_stack([e, n]), atol=MM)
    with pytest.raises(s2w.InvalidInputError, match="crs"):
        cloud.write_las(tmp_path / "x.las", origin=origin, crs="wgs84")
    with pytest.raises(s2w.InvalidInputError, match="origin"):
        cloud.write_las(tmp_path / "x.las", origin=(1.0, 2.0))  # type: ignore[arg-type]
    assert not (tmp_path / "x.las").exists()


def _read_pcd_by_spec(path: Path) -> tuple[dict[str, list[str]], np.ndarray]:
    """A binary PCD reader written from the PCL file format page."""
    raw = path.read_bytes()
    header: dict[str, list[str]] = {}
    pos = 0
    while True:
        end = raw.index(b"\n", pos)
        line = raw[pos:end].decode("ascii").strip()
        pos = end + 1
        if not line or line.startswith("#"):
            continue
        key, *vals = line.split()
        header[key] = vals
        if key == "DATA":
            break
    assert header["DATA"] == ["binary"]
    kinds = {("F", "4"): "<f4", ("U", "4"): "<u4", ("U", "1"): "u1"}
    dtype = np.dtype(
        [(f, kinds[(t, s)]) for f, t, s in zip(header["FIELDS"], header["TYPE"], header["SIZE"])]
    )
    n = int(header["POINTS"][0])
    return header, np.frombuffer(raw, dtype=dtype, count=n, offset=pos)


def test_pcd_read_by_pypcd4_and_by_the_spec(tmp_path: Path) -> None:
    cloud = _cloud(700)
    path = tmp_path / "map.pcd"
    cloud.write_pcd(path)
    header, rec = _read_pcd_by_spec(path)
    assert header["FIELDS"] == ["x", "y", "z", "rgb"] and header["HEIGHT"] == ["1"]
    xyz = np.column_stack([rec["x"], rec["y"], rec["z"]])
    np.testing.assert_array_equal(xyz, cloud.points)
    packed = rec["rgb"].view("<u4")
    colors = cloud.colors
    assert colors is not None
    expect = (
        (colors[:, 0].astype(np.uint32) << 16)
        | (colors[:, 1].astype(np.uint32) << 8)
        | colors[:, 2]
    )
    np.testing.assert_array_equal(packed, expect)
    pc = PcdCloud.from_path(path)
    np.testing.assert_array_equal(pc.numpy(("x", "y", "z")), cloud.points)
    rgb = PcdCloud.decode_rgb(pc.numpy(("rgb",)).ravel())
    np.testing.assert_array_equal(rgb, colors)
    plain = _cloud(10, colors=False)
    plain.write_pcd(tmp_path / "plain.pcd")
    header, rec = _read_pcd_by_spec(tmp_path / "plain.pcd")
    assert header["FIELDS"] == ["x", "y", "z"]
    np.testing.assert_array_equal(np.column_stack([rec["x"], rec["y"], rec["z"]]), plain.points)
