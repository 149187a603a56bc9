//! Trajectory reading, association and alignment on the shared real data,
//! against the reference numbers in each folder's PROVENANCE.md (computed with
//! evo 1.38.1; the Python tests run evo itself). Skips when the data is absent.

use crate::common::data;

use nalgebra::Vector3;
use slam2world::align::trajectories::{align_trajectories, TrajectoryAlignOptions};
use slam2world::align::AlignMethod;
use slam2world::io::text::{read_euroc, read_tum, write_tum};
use slam2world::trajectory::associate;
use slam2world::{Error, Sim3, Trajectory};

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn fr2_desk_se3_reproduces_published_rmse() {
    let (Some(gt), Some(est)) = (
        data("evo_tum_fr2_desk", "fr2_desk_groundtruth.txt"),
        data("evo_tum_fr2_desk", "fr2_desk_ORB.txt"),
    ) else {
        return;
    };
    let gt = read_tum(gt).unwrap();
    let est = read_tum(est).unwrap();
    assert_eq!((gt.len(), est.len()), (20957, 2893));
    let opts = TrajectoryAlignOptions {
        scale: false,
        ..Default::default()
    };
    let r = align_trajectories(&est, &gt, &opts).unwrap();
    assert_eq!(r.ape.n_pairs, 2174);
    assert_eq!(r.alignment.transform.scale, 1.0);
    // evo doc/performance.md: rmse 0.008119, mean 0.007492, max 0.024300 (6 decimals).
    assert!((r.ape.rmse - 0.008119).abs() < 5e-7, "{}", r.ape.rmse);
    assert!((r.ape.mean - 0.007492).abs() < 5e-7);
    assert!((r.ape.max - 0.024300).abs() < 5e-7);
}

#[test]
fn fr2_desk_mono_keyframes_sim3() {
    let (Some(gt), Some(est)) = (
        data("evo_tum_fr2_desk", "fr2_desk_groundtruth.txt"),
        data("evo_tum_fr2_desk", "fr2_desk_ORB_kf_mono.txt"),
    ) else {
        return;
    };
    let gt = read_tum(gt).unwrap();
    let est = read_tum(est).unwrap();
    for method in [AlignMethod::Horn, AlignMethod::Umeyama] {
        let opts = TrajectoryAlignOptions {
            method,
            ..Default::default()
        };
        let r = align_trajectories(&est, &gt, &opts).unwrap();
        assert_eq!(r.pairs.len(), 118);
        let t = r.alignment.transform;
        assert!(rel(t.scale, 2.2280217535893287) < 1e-9, "{}", t.scale);
        let t_ref = Vector3::new(0.09862211, -2.40732409, 1.58242313);
        assert!((t.translation - t_ref).amax() < 1e-7);
        assert!((r.ape.rmse - 0.007729).abs() < 5e-7);
        // The scale found is s, not 1/s: mapping the SLAM positions gives metres.
        let span = |p: &[Vector3<f64>]| (p[p.len() - 1] - p[0]).norm();
        let mapped = est.transformed(&t);
        assert!(rel(span(&mapped.positions), span(&est.positions) * t.scale) < 1e-12);
    }
}

#[test]
fn fr1_xyz_and_euroc_v102_sim3() {
    if let (Some(gt), Some(est)) = (
        data("evo_tum_fr1_xyz", "freiburg1_xyz-groundtruth.txt"),
        data("evo_tum_fr1_xyz", "freiburg1_xyz-ORB_kf_mono.txt"),
    ) {
        let r = align_trajectories(
            &read_tum(est).unwrap(),
            &read_tum(gt).unwrap(),
            &TrajectoryAlignOptions::default(),
        )
        .unwrap();
        assert_eq!(r.ape.n_pairs, 32);
        assert!(rel(r.alignment.transform.scale, 1.1056223637370346) < 1e-9);
        assert!((r.ape.rmse - 0.009755).abs() < 5e-7);
    }
    if let (Some(gt), Some(est)) = (
        data("euroc_v102", "V102_groundtruth.csv"),
        data("euroc_v102", "V102.txt"),
    ) {
        let gt = read_euroc(gt).unwrap();
        assert_eq!(gt.len(), 16702);
        assert!((gt.timestamps[0] - 1403715524.907).abs() < 1e-3);
        let est = read_tum(est).unwrap();
        let r = align_trajectories(&est, &gt, &TrajectoryAlignOptions::default()).unwrap();
        assert_eq!(r.ape.n_pairs, 798);
        assert!(rel(r.alignment.transform.scale, 0.9796982521745786) < 1e-9);
        assert!((r.ape.rmse - 0.083841).abs() < 5e-7);
        let se3 = TrajectoryAlignOptions {
            scale: false,
            ..Default::default()
        };
        let r = align_trajectories(&est, &gt, &se3).unwrap();
        assert!((r.ape.rmse - 0.091727).abs() < 5e-7);
    }
}

#[test]
fn tum_write_read_round_trip_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.txt");
    let t = Trajectory::try_new(
        vec![1311868163.8697, 1311868163.9, 1311868164.0000001],
        vec![
            Vector3::new(0.1, -2.0 / 3.0, 1e-17),
            Vector3::new(1.0, 2.0, 3.0),
            Vector3::new(-1e6, 0.5, 0.25),
        ],
        None,
    )
    .unwrap();
    let s = Sim3::from_quaternion_xyzw([0.1, 0.2, 0.3, 0.9], Vector3::zeros(), 1.0).unwrap();
    let t = Trajectory {
        orientations: Some(vec![s.rotation; 3]),
        ..t
    };
    write_tum(&t, &path).unwrap();
    let back = read_tum(&path).unwrap();
    assert_eq!(back.timestamps, t.timestamps);
    assert_eq!(back.positions, t.positions);
    let (q0, q1) = (t.orientations.unwrap()[0], back.orientations.unwrap()[0]);
    assert!(q0.angle_to(&q1) < 1e-15);
    // No temporary file is left next to the output.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn readers_report_line_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.txt");
    std::fs::write(&path, "# header\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 x 1\n").unwrap();
    match read_tum(&path) {
        Err(Error::Parse { line, .. }) => assert_eq!(line, 3),
        other => panic!("{other:?}"),
    }
    std::fs::write(&path, "1 0 0 0 0 0 0 1\n2 0 0 0\n").unwrap();
    assert!(matches!(read_tum(&path), Err(Error::Parse { line: 2, .. })));
    std::fs::write(&path, "2 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n").unwrap();
    assert!(matches!(read_tum(&path), Err(Error::Parse { line: 2, .. })));
    std::fs::write(&path, "#only a header\n").unwrap();
    assert!(read_tum(&path).is_err());
    assert!(matches!(
        read_tum(dir.path().join("missing.txt")),
        Err(Error::Io { .. })
    ));
    std::fs::write(&path, "#t,x\n1000000000,1,2,3,1,0,0,0\n2000000000,1,2\n").unwrap();
    assert!(matches!(
        read_euroc(&path),
        Err(Error::Parse { line: 3, .. })
    ));
}

#[test]
fn associate_is_symmetric_in_its_pairs() {
    let (Some(gt), Some(est)) = (
        data("evo_tum_fr1_xyz", "freiburg1_xyz-groundtruth.txt"),
        data("evo_tum_fr1_xyz", "freiburg1_xyz-ORB_kf_mono.txt"),
    ) else {
        return;
    };
    let gt = read_tum(gt).unwrap();
    let est = read_tum(est).unwrap();
    let ab = associate(&gt, &est, 0.01, 0.0);
    let ba: Vec<(usize, usize)> = associate(&est, &gt, 0.01, 0.0)
        .into_iter()
        .map(|(i, j)| (j, i))
        .collect();
    assert_eq!(ab, ba);
    for &(i, j) in &ab {
        assert!((gt.timestamps[i] - est.timestamps[j]).abs() <= 0.01);
    }
}
