//! Geodesy, GNSS readers and georeferenced writers (core layer). The Python
//! tests check the same against pymap3d, pyproj, laspy and pypcd4.

use crate::common;

use std::path::Path;

use nalgebra::{Matrix3, Vector3};
use slam2world::cloud::PointCloud;
use slam2world::geo::{
    enu_to_crs, geodetic_to_utm, utm_to_geodetic, EnuFrame, FixStatus, GeoCrs, Geodetic, GnssFixes,
    Hemisphere, Origin, TimeBase, UtmProjection, UtmZone,
};
use slam2world::io::gnss::{parse_gnss_csv, parse_nmea, read_gnss, read_nmea, GnssFormat};
use slam2world::io::las::write_las;
use slam2world::Error;

fn nmea(body: &str) -> String {
    let c = body.bytes().fold(0u8, |a, b| a ^ b);
    format!("${body}*{c:02X}")
}

fn csv(text: &str) -> slam2world::Result<GnssFixes> {
    parse_gnss_csv(text.as_bytes(), Path::new("fixes.csv"), 0.0)
}

#[test]
fn evo_georeferenced_utm_round_trips_within_a_millimetre() {
    let Some(path) = common::data("evo_georeferenced_utm", "georeferenced.tum") else {
        return;
    };
    let t = slam2world::io::text::read_tum(&path).unwrap();
    assert_eq!(t.len(), 1000);
    let zone = UtmZone::try_new(32, Hemisphere::North).unwrap();
    let g = utm_to_geodetic(&t.positions, zone).unwrap();
    // Karlsruhe, as PROVENANCE.md says.
    assert!((g[0].lat - 49.01589).abs() < 1e-4 && (g[0].lon - 8.42661).abs() < 1e-4);
    let (back, z) = geodetic_to_utm(&g, None).unwrap();
    assert_eq!(z, zone);
    let worst = t
        .positions
        .iter()
        .zip(&back)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    assert!(worst < 1e-3, "worst round trip {worst} m");
}

#[test]
fn fourseasons_nmea_counts_and_first_fix() {
    let Some(path) = common::data("fourseasons_sample", "septentrio.nmea") else {
        return;
    };
    let f = read_nmea(&path, 0.0).unwrap();
    // 3414 GGA, all with a fix (qualities 4, 5, 2, 1); the first line is a fragment.
    assert_eq!(f.len(), 3414);
    assert_eq!(f.dropped_no_fix, 0);
    assert_eq!(f.time_base, TimeBase::Source);
    let count = |s| f.status.iter().filter(|&&x| x == s).count();
    assert_eq!(count(FixStatus::RtkFixed), 2794);
    assert_eq!(count(FixStatus::RtkFloat), 455);
    assert_eq!(count(FixStatus::Differential), 150);
    assert_eq!(count(FixStatus::Single), 15);
    // $GPGGA,124637.60,4811.7614623,N,01137.1671785,E,5,05,2.6,494.6573,M,47.5367,M,...
    // on 2020-10-07 (RMC 071020); GST sigmas lat 0.192, lon 0.124, alt 0.320.
    assert!(
        (f.times[0] - 1_602_074_797.6).abs() < 1e-6,
        "{}",
        f.times[0]
    );
    assert!((f.lat[0] - (48.0 + 11.7614623 / 60.0)).abs() < 1e-12);
    assert!((f.lon[0] - (11.0 + 37.1671785 / 60.0)).abs() < 1e-12);
    assert!((f.alt[0] - (494.6573 + 47.5367)).abs() < 1e-9);
    let c = f.covariance[0].unwrap();
    assert!((c[(0, 0)] - 0.124f64.powi(2)).abs() < 1e-12);
    assert!((c[(1, 1)] - 0.192f64.powi(2)).abs() < 1e-12);
    assert!((c[(2, 2)] - 0.320f64.powi(2)).abs() < 1e-12);
    assert!(f.covariance.iter().all(Option::is_some));
    // PROVENANCE.md: lat 48.19204–48.19626, ellipsoidal height 538.6–544.1 m, 12:46:37.6–12:53:28.8 UTC.
    let (lo, hi) = f
        .lat
        .iter()
        .fold((90.0f64, -90.0f64), |(a, b), &v| (a.min(v), b.max(v)));
    assert!(
        (lo - 48.19204).abs() < 1e-5 && (hi - 48.19626).abs() < 1e-5,
        "{lo} {hi}"
    );
    assert!((f.times[f.len() - 1] - f.times[0] - (6.0 * 60.0 + 51.2)).abs() < 1e-6);
    // Detected as NMEA, and it becomes a moving ENU track with weights.
    let g = read_gnss(&path, None, 0.0).unwrap();
    assert_eq!(g.len(), f.len());
    let track = f.to_enu(&Origin::Mean).unwrap();
    assert_eq!(track.weights.as_ref().unwrap().len(), 3414);
    let o = track.frame.origin();
    assert!(
        o.lat > 48.19 && o.lat < 48.197 && o.alt > 530.0 && o.alt < 550.0,
        "{o:?}"
    );
}

#[test]
fn nmea_checksum_errors_name_the_line() {
    let good = nmea("GPGGA,120000.00,4811.0000,N,01137.0000,E,1,08,1.0,500.0,M,47.5,M,,");
    let bad = good.replace("500.0", "501.0");
    let text = format!("{good}\n{bad}\n");
    match parse_nmea(text.as_bytes(), Path::new("x.nmea"), 0.0) {
        Err(Error::Parse { line, reason, .. }) => {
            assert_eq!(line, 2);
            assert!(reason.contains("checksum"), "{reason}");
        }
        other => panic!("{other:?}"),
    }
    let no_sum = "$GPGGA,120000.00,4811.0000,N,01137.0000,E,1,08,1.0,500.0,M,47.5,M,,\n";
    assert!(matches!(
        parse_nmea(no_sum.as_bytes(), Path::new("x"), 0.0),
        Err(Error::Parse { line: 1, .. })
    ));
}

#[test]
fn nmea_no_fix_is_dropped_and_counted_gst_and_zda_are_used() {
    let lines = [
        nmea("GNZDA,235959.00,31,12,2021,00,00"),
        nmea("GNGGA,235959.00,4811.0000,N,01137.0000,E,4,12,0.6,500.0,M,47.5,M,1.0,0001"),
        nmea("GNGST,235959.00,0.02,0.01,0.01,0.0,0.010,0.020,0.030"),
        nmea("GNGGA,000000.00,,,,,0,00,99.9,,M,,M,,"),
        nmea("GNGGA,000000.50,4811.0010,N,01137.0010,E,5,12,0.6,500.5,M,,M,1.0,0001"),
        "noise without a sentence".to_string(),
        nmea("GPGSV,3,1,12,01,40,083,46"),
    ];
    let f = parse_nmea(lines.join("\r\n").as_bytes(), Path::new("x"), 2.0).unwrap();
    assert_eq!(f.len(), 2);
    assert_eq!(f.dropped_no_fix, 1);
    assert_eq!(f.status, vec![FixStatus::RtkFixed, FixStatus::RtkFloat]);
    // ZDA 2021-12-31 23:59:59; the second fix is past midnight, on 2022-01-01.
    let t0 = 1_640_995_199.0;
    assert_eq!(f.times, vec![t0, t0 + 1.5]);
    let c = f.covariance[0].unwrap();
    assert_eq!(
        c.diagonal(),
        Vector3::new(0.02f64.powi(2), 0.01f64.powi(2), 0.03f64.powi(2))
    );
    assert!(f.covariance[1].is_none());
    // The second GGA has no geoid separation: the geoid offset is used.
    assert!((f.alt[0] - 547.5).abs() < 1e-12 && (f.alt[1] - 502.5).abs() < 1e-12);
    assert!(f.weights().is_none());
}

#[test]
fn csv_with_and_without_header_and_covariance() {
    let plain = "0.0 48.0 11.0 500.0\n1.0 48.001 11.0 501.0\n";
    let f = csv(plain).unwrap();
    assert_eq!(f.len(), 2);
    assert!(f.covariance.iter().all(Option::is_none));
    let header = "# a comment\ntime,lat,lon,alt,var_e,var_n,var_u\n\n0,48,11,500,1,2,3\n1,48.001,11,501,1,2,3\n";
    let f = csv(header).unwrap();
    assert_eq!(
        f.covariance[1].unwrap().diagonal(),
        Vector3::new(1.0, 2.0, 3.0)
    );
    assert_eq!(f.weights().unwrap(), vec![0.5, 0.5]); // 3 / trace
    let full = "t lat lon alt c00 c01 c02 c10 c11 c12 c20 c21 c22\n0 48 11 500 4 1 0 1 4 0 0 0 9\n";
    let f = csv(full).unwrap();
    assert_eq!(
        f.covariance[0].unwrap(),
        Matrix3::new(4.0, 1.0, 0.0, 1.0, 4.0, 0.0, 0.0, 0.0, 9.0)
    );
    let geoid = parse_gnss_csv(plain.as_bytes(), Path::new("x"), 47.5).unwrap();
    assert_eq!(geoid.alt, vec![547.5, 548.5]);
}

#[test]
fn csv_bad_input_is_a_typed_error() {
    let invalid_fix = |text: &str| match csv(text) {
        Err(Error::InvalidFix { index, field, .. }) => (index, field),
        other => panic!("{text:?}: {other:?}"),
    };
    assert_eq!(
        invalid_fix("0 48 11 500\n1 nan 11 500\n"),
        (1, "latitude".into())
    );
    assert_eq!(
        invalid_fix("0 48 11 500\n1 95 11 500\n"),
        (1, "latitude".into())
    );
    assert_eq!(
        invalid_fix("0 48 11 500\n1 -90.5 11 500\n"),
        (1, "latitude".into())
    );
    assert_eq!(invalid_fix("0 48 nan 500\n"), (0, "longitude".into()));
    assert_eq!(invalid_fix("inf 48 11 500\n"), (0, "time".into()));
    assert_eq!(
        invalid_fix("5 48 11 500\n1 48 11 500\n"),
        (1, "time".into())
    );
    assert_eq!(
        invalid_fix("0 48 11 500 -1 1 1\n"),
        (0, "covariance".into())
    );
    for (text, line) in [
        ("0 48 11\n", 1),
        ("0 48 11 500\n1 48 11 500 1 1 1\n", 2),
        ("time lat lon alt\n0 48 x 500\n", 2),
        ("0,48,,500\n", 1),
    ] {
        match csv(text) {
            Err(Error::Parse { line: l, .. }) => assert_eq!(l, line, "{text:?}"),
            other => panic!("{text:?}: {other:?}"),
        }
    }
}

#[test]
fn endless_input_is_refused_without_growing() {
    let zero = Path::new("/dev/zero");
    if !zero.exists() {
        eprintln!("skipped: no /dev/zero");
        return;
    }
    for format in [None, Some(GnssFormat::Nmea), Some(GnssFormat::Csv)] {
        let e = read_gnss(zero, format, 0.0).unwrap_err();
        assert!(matches!(e, Error::Parse { line: 1, .. }), "{format:?}: {e}");
    }
}

#[test]
fn a_track_that_never_moves_is_refused() {
    // 50 fixes scattered by about 1 m around one point, covariance 1 m² per axis.
    let mut text = String::new();
    for i in 0..50 {
        let d = ((i * 37) % 11) as f64 / 11.0 - 0.5; // within ±0.5
        text += &format!(
            "{i} {} {} {} 1 1 1\n",
            48.0 + d * 1e-5,
            11.0 + d * 1e-5,
            500.0 + d
        );
    }
    let f = csv(&text).unwrap();
    assert!(matches!(
        f.to_enu(&Origin::First),
        Err(Error::Degenerate { .. })
    ));
    let one = csv("0 48 11 500\n").unwrap();
    assert!(matches!(
        one.to_enu(&Origin::First),
        Err(Error::TooFew { .. })
    ));
}

#[test]
fn enu_to_utm_goes_through_geodetic_not_a_translation() {
    let origin = Geodetic::try_new(49.0, 8.4, 120.0).unwrap();
    let frame = EnuFrame::new(origin).unwrap();
    let far = [0.0f32, 0.0, 0.0, 20_000.0, 15_000.0, 30.0];
    let utm = enu_to_crs(&far, &frame, GeoCrs::Utm(None)).unwrap();
    assert_eq!(utm.epsg, 32632);
    let proj = UtmProjection::new(utm.zone.unwrap()).unwrap();
    // The exact path: ENU -> geodetic -> UTM.
    let g = frame
        .enu_to_geodetic(&Vector3::new(20_000.0, 15_000.0, 30.0))
        .unwrap();
    let exact = proj.forward(&g, 0).unwrap();
    let got = Vector3::new(utm.xyz[3], utm.xyz[4], utm.xyz[5]);
    assert!((got - exact).norm() < 1e-6, "{got} vs {exact}");
    // A translation by the origin's UTM position is off by metres at 25 km.
    let naive = Vector3::new(
        utm.xyz[0] + 20_000.0,
        utm.xyz[1] + 15_000.0,
        utm.xyz[2] + 30.0,
    );
    assert!((got.xy() - naive.xy()).norm() > 1.0);
    // And ECEF is the frame's own map.
    let ecef = enu_to_crs(&far, &frame, GeoCrs::Ecef).unwrap();
    assert_eq!(ecef.epsg, 4978);
    let e = frame.enu_to_ecef(&Vector3::new(20_000.0, 15_000.0, 30.0));
    assert!((Vector3::new(ecef.xyz[3], ecef.xyz[4], ecef.xyz[5]) - e).norm() < 1e-6);
}

#[test]
fn las_and_laz_hold_the_coordinates_to_a_millimetre_with_the_crs() {
    let dir = tempfile::tempdir().unwrap();
    let origin = Geodetic::try_new(-33.9, 18.4, 20.0).unwrap();
    let mut pts = Vec::new();
    let mut colors = Vec::new();
    for i in 0..2000 {
        let a = i as f32 * 0.01;
        pts.extend_from_slice(&[a.cos() * 300.0, a.sin() * 200.0, (i % 17) as f32 * 0.37]);
        colors.extend_from_slice(&[(i % 256) as u8, 7, 200]);
    }
    let cloud = PointCloud::try_new(pts.clone(), Some(colors), None).unwrap();
    let frame = EnuFrame::new(origin).unwrap();
    let want = enu_to_crs(&pts, &frame, GeoCrs::Utm(None)).unwrap();
    for name in ["c.las", "c.laz"] {
        let path = dir.path().join(name);
        let info = write_las(&path, &cloud, &origin, GeoCrs::Utm(None)).unwrap();
        assert_eq!(info.epsg, 32734);
        assert_eq!(info.compressed, name.ends_with(".laz"));
        let mut reader = las::Reader::from_path(&path).unwrap();
        let header = reader.header().clone();
        assert_eq!(header.version(), las::Version::new(1, 4));
        assert!(header.has_wkt_crs());
        let wkt = String::from_utf8_lossy(header.get_wkt_crs_bytes().unwrap()).into_owned();
        assert!(
            wkt.contains("UTM zone 34S") && wkt.contains("\"32734\""),
            "{wkt}"
        );
        let data = reader.read_all().unwrap();
        let read: Vec<las::Point> = data.points().map(|p| p.unwrap()).collect();
        assert_eq!(read.len(), 2000);
        for (i, p) in read.iter().enumerate() {
            let d = Vector3::new(p.x, p.y, p.z)
                - Vector3::new(want.xyz[3 * i], want.xyz[3 * i + 1], want.xyz[3 * i + 2]);
            assert!(d.amax() <= 0.5e-3 + 1e-9, "point {i}: {d}");
            assert_eq!(p.color.unwrap().red, (i % 256) as u16 * 257);
        }
    }
    // ECEF with no colours.
    let plain = PointCloud::try_new(pts, None, None).unwrap();
    let path = dir.path().join("ecef.las");
    let info = write_las(&path, &plain, &origin, GeoCrs::Ecef).unwrap();
    assert_eq!(info.epsg, 4978);
    let reader = las::Reader::from_path(&path).unwrap();
    let wkt = String::from_utf8_lossy(reader.header().get_wkt_crs_bytes().unwrap()).into_owned();
    assert!(wkt.starts_with("GEOCCS[") && wkt.contains("\"4978\""));
}

#[test]
fn a_failed_las_write_leaves_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.las");
    let cloud = PointCloud::try_new(vec![0.0, 0.0, f32::NAN], None, None).unwrap();
    let origin = Geodetic::try_new(10.0, 10.0, 0.0).unwrap();
    assert!(matches!(
        write_las(&path, &cloud, &origin, GeoCrs::Utm(None)),
        Err(Error::NonFinite { index: 0, .. })
    ));
    assert!(!path.exists());
    let polar = Geodetic::try_new(88.0, 10.0, 0.0).unwrap();
    let ok = PointCloud::try_new(vec![0.0; 3], None, None).unwrap();
    assert!(write_las(&path, &ok, &polar, GeoCrs::Utm(None)).is_err());
    assert!(!path.exists());
}
