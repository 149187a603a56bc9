//! Backprojection geometry, PLY files and real ORB-SLAM map points through the public API.

use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use slam2world::align::trajectories::{align_trajectories, TrajectoryAlignOptions};
use slam2world::cli::main_with_args;
use slam2world::cloud::{backproject, backproject_per_keyframe, PointCloud, PointFilter};
use slam2world::io::ply::{read_ply, read_xyz_text, write_ply};
use slam2world::io::text::read_tum;
use slam2world::{Keyframe, PinholeCamera, Sim3};

fn data_dir(folder: &str) -> Option<PathBuf> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data")
        .join(folder);
    if p.exists() {
        Some(p)
    } else {
        eprintln!("skipped: real data not present at {}", p.display());
        None
    }
}

/// A camera looking at the plane `z_cam = depth` everywhere: every backprojected
/// point must lie on that plane, carried by the poses into the world.
#[test]
fn fronto_parallel_plane_lands_on_the_world_plane() {
    let (w, h) = (64u32, 48u32);
    let cam = PinholeCamera::from_hfov(w, h, 70.0).unwrap();
    let depth = 2.5f32;
    let pose = Sim3::from_quaternion_xyzw([0.2, -0.1, 0.3, 0.9], Vector3::new(1.0, 2.0, -1.0), 0.4)
        .unwrap();
    let kf = Keyframe::try_new(
        7,
        1.0,
        pose,
        cam,
        vec![1.0 / depth; (w * h) as usize],
        Some(vec![1e-8; (w * h) as usize]),
        Some(vec![9u8; (3 * w * h) as usize]),
    )
    .unwrap();
    let world_slam =
        Sim3::from_quaternion_xyzw([0.0, 0.0, 0.6, 0.8], Vector3::new(0.0, 0.0, 5.0), 3.0).unwrap();
    let filter = PointFilter {
        cut_first_keyframes: None,
        ..PointFilter::default()
    };
    let cloud = backproject(&[&kf], &filter, Some(&world_slam)).unwrap();
    // Border skipped, every interior pixel supported by its 3x3 block.
    assert_eq!(cloud.len(), ((w - 2) * (h - 2)) as usize);
    assert_eq!(cloud.colors.as_ref().map(Vec::len), Some(3 * cloud.len()));
    // The plane z_cam = depth in the world: normal n_w = R_world_cam · e_z,
    // offset: n_w · p_w = n_w · t_world_cam + s_world_cam · depth.
    let world_cam = world_slam * pose;
    let n = world_cam.rotation * Vector3::z();
    let offset = n.dot(&world_cam.translation) + world_cam.scale * depth as f64;
    for p in cloud.points.chunks_exact(3) {
        let p = Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        assert!((n.dot(&p) - offset).abs() < 1e-5 * offset.abs().max(1.0));
    }
    // The principal-point pixel's ray is the optical axis: its point is on it.
    let centre = world_cam.transform_point(&Vector3::new(0.0, 0.0, depth as f64));
    let nearest = cloud
        .points
        .chunks_exact(3)
        .map(|p| (Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64) - centre).norm())
        .fold(f64::INFINITY, f64::min);
    // Pixel spacing on the plane, in world units.
    let spacing = world_cam.scale * depth as f64 / cam.fx;
    assert!(nearest < spacing, "{nearest} vs pixel spacing {spacing}");

    let per = backproject_per_keyframe(&[&kf], &filter, &[world_slam]).unwrap();
    assert_eq!(per, cloud);
}

#[test]
fn ply_round_trip_through_the_public_api() {
    let dir = tempfile::tempdir().unwrap();
    let pts: Vec<f32> = (0..300).map(|i| i as f32 * 0.5 - 40.0).collect();
    let cols: Vec<u8> = (0..300).map(|i| (i % 251) as u8).collect();
    let c = PointCloud::try_new(pts, Some(cols), None).unwrap();
    let path = dir.path().join("out.ply");
    write_ply(&path, &c).unwrap();
    let back = read_ply(&path).unwrap();
    assert_eq!(back.points, c.points);
    assert_eq!(back.colors, c.colors);
    // Overwrite in place with a cloud without colour.
    let plain = PointCloud::try_new(vec![1.0, 2.0, 3.0], None, None).unwrap();
    write_ply(&path, &plain).unwrap();
    assert_eq!(read_ply(&path).unwrap(), plain);
}

#[test]
fn orbslam2_map_points_read() {
    let Some(dir) = data_dir("euroc_v101_orbslam2_map") else {
        return;
    };
    let c = read_xyz_text(dir.join("MapPoints.txt")).unwrap();
    assert_eq!(c.len(), 6300);
    // The extent stated in PROVENANCE.md: x −2.79…6.39, y −2.02…3.17, z −6.0…3.3.
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for p in c.points.chunks_exact(3) {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let want_lo = [-2.79, -2.02, -6.0];
    let want_hi = [6.39, 3.17, 3.3];
    for k in 0..3 {
        assert!((lo[k] - want_lo[k]).abs() < 0.06, "min {k}: {}", lo[k]);
        assert!((hi[k] - want_hi[k]).abs() < 0.06, "max {k}: {}", hi[k]);
    }
    // Carried by a rotation about z, the points keep their distances to the origin.
    let t = Sim3::try_new(
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 1.0),
        Vector3::zeros(),
        1.0,
    )
    .unwrap();
    let moved = c.transformed(&t).unwrap();
    for (a, b) in c.points.chunks_exact(3).zip(moved.points.chunks_exact(3)) {
        let na = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        let nb = (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]).sqrt();
        assert!((na - nb).abs() < 1e-5 * na.max(1.0));
        assert!((a[2] - b[2]).abs() < 1e-5 * na.max(1.0));
    }
}

/// The floor of a metric, gravity-aligned cloud: a plane fitted to the lowest 40 %
/// of the points, refitted five times on the points within 5 cm of it. Returns the
/// unit normal (z ≥ 0), the offset `n · p` and the inlier count.
fn floor_plane(points: &[Vector3<f64>]) -> (Vector3<f64>, f64, usize) {
    let mut z: Vec<f64> = points.iter().map(|p| p.z).collect();
    z.sort_by(f64::total_cmp);
    let cut = z[z.len() * 2 / 5];
    let mut set: Vec<Vector3<f64>> = points.iter().filter(|p| p.z <= cut).copied().collect();
    let (mut n, mut d) = (Vector3::z(), 0.0);
    for _ in 0..6 {
        let c = set.iter().sum::<Vector3<f64>>() / set.len() as f64;
        let cov: Matrix3<f64> = set.iter().map(|p| (p - c) * (p - c).transpose()).sum();
        let eig = cov.symmetric_eigen();
        let k = eig.eigenvalues.imin();
        n = eig.eigenvectors.column(k).into_owned();
        if n.z < 0.0 {
            n = -n;
        }
        d = n.dot(&c);
        set = points
            .iter()
            .filter(|p| (n.dot(p) - d).abs() < 0.05)
            .copied()
            .collect();
    }
    (n, d, set.len())
}

/// ORB-SLAM2's 6300 map points of EuRoC V1_01, carried into the Vicon frame by the
/// Sim(3) of the keyframe trajectory onto the ground truth: the floor must come out
/// horizontal at z ≈ 0 and the points inside the room around the flight.
#[test]
fn orbslam2_map_points_land_in_the_vicon_room() {
    let Some(dir) = data_dir("euroc_v101_orbslam2_map") else {
        return;
    };
    let est = read_tum(dir.join("KeyFrameTrajectory_TUM_Format.txt")).unwrap();
    let gt = read_tum(dir.join("V1_01_easy_original.txt")).unwrap();
    let fit = align_trajectories(&est, &gt, &TrajectoryAlignOptions::default()).unwrap();
    let t = fit.alignment.transform;
    // evo 1.38.1 (PROVENANCE.md): 73 pairs, scale 1.00813, rmse 0.110870 m.
    assert_eq!(fit.pairs.len(), 73);
    assert!((t.scale - 1.0081319980644732).abs() < 1e-6);
    assert!((fit.ape.rmse - 0.110870).abs() < 1e-5);

    let cloud = read_xyz_text(dir.join("MapPoints.txt")).unwrap();
    let world = cloud.transformed(&t).unwrap();
    let pts: Vec<Vector3<f64>> = world
        .points
        .chunks_exact(3)
        .map(|p| Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64))
        .collect();
    assert_eq!(pts.len(), 6300);

    let (n, d, inliers) = floor_plane(&pts);
    let tilt = n.angle(&Vector3::z()).to_degrees();
    eprintln!("floor: normal {n:?}, tilt {tilt:.2} deg, z {d:.3} m, {inliers} points");
    assert!(tilt < 3.0, "floor tilted by {tilt:.2} deg");
    assert!(d.abs() < 0.1, "floor at z = {d:.3} m");
    assert!(inliers > 1500, "{inliers} floor points");

    // The room: above the floor and below 3 m for 99 % of the points, and
    // horizontally within 3 m of the ground-truth flight area.
    let (mut lo, mut hi) = (
        Vector3::repeat(f64::INFINITY),
        Vector3::repeat(f64::NEG_INFINITY),
    );
    for p in &gt.positions {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let inside_height = pts.iter().filter(|p| p.z > -0.3 && p.z < 3.0).count();
    assert!(
        inside_height as f64 >= 0.99 * pts.len() as f64,
        "{inside_height} of 6300"
    );
    for p in &pts {
        for k in 0..2 {
            assert!(
                p[k] > lo[k] - 3.0 && p[k] < hi[k] + 3.0,
                "{p:?} outside the room"
            );
        }
    }

    // The check can fail: a 5° error in the alignment's rotation tilts the floor.
    let tilt5 = Sim3::try_new(
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 5f64.to_radians()),
        Vector3::zeros(),
        1.0,
    )
    .unwrap();
    let wrong = cloud.transformed(&(tilt5 * t)).unwrap();
    let wrong: Vec<Vector3<f64>> = wrong
        .points
        .chunks_exact(3)
        .map(|p| Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64))
        .collect();
    let (n5, _, _) = floor_plane(&wrong);
    assert!(n5.angle(&Vector3::z()).to_degrees() > 3.0);
}

/// `slam2world transform-cloud` writes the same points as the library.
#[test]
fn cli_transform_cloud_on_real_data() {
    let Some(dir) = data_dir("euroc_v101_orbslam2_map") else {
        return;
    };
    let out = tempfile::tempdir().unwrap();
    let ply = out.path().join("world.ply");
    let s = |p: PathBuf| p.display().to_string();
    let args = [
        "slam2world".to_string(),
        "transform-cloud".into(),
        s(dir.join("MapPoints.txt")),
        "--align".into(),
        s(dir.join("KeyFrameTrajectory_TUM_Format.txt")),
        s(dir.join("V1_01_easy_original.txt")),
        "-o".into(),
        s(ply.clone()),
    ];
    assert_eq!(main_with_args(args.clone()), 0);
    let written = read_ply(&ply).unwrap();
    let est = read_tum(dir.join("KeyFrameTrajectory_TUM_Format.txt")).unwrap();
    let gt = read_tum(dir.join("V1_01_easy_original.txt")).unwrap();
    let t = align_trajectories(&est, &gt, &TrajectoryAlignOptions::default())
        .unwrap()
        .alignment
        .transform;
    let want = read_xyz_text(dir.join("MapPoints.txt"))
        .unwrap()
        .transformed(&t)
        .unwrap();
    assert_eq!(written.points, want.points);

    // A PLY file is accepted as IN too (recognised by its magic line).
    let again = out.path().join("again.ply");
    let mut args2 = args.clone();
    args2[2] = s(ply.clone());
    args2[7] = s(again.clone());
    assert_eq!(main_with_args(args2), 0);
    assert_eq!(read_ply(&again).unwrap().len(), 6300);

    // Bad input: exit 1, and no output file left behind.
    let bad = out.path().join("bad.txt");
    std::fs::write(&bad, "1 2 3\n4 5\n").unwrap();
    let mut args3 = args;
    args3[2] = s(bad);
    args3[7] = s(out.path().join("never.ply"));
    assert_eq!(main_with_args(args3), 1);
    assert!(!out.path().join("never.ply").exists());
}

/// `transform-cloud` on files made here: EST is REF mapped by a known Sim(3)
/// inverse, so the cloud must come out mapped by that Sim(3).
#[test]
fn cli_transform_cloud_on_synthetic_files() {
    let dir = tempfile::tempdir().unwrap();
    let t = Sim3::try_new(
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2),
        Vector3::new(1.0, 2.0, 3.0),
        4.0,
    )
    .unwrap();
    let inv = t.inverse();
    let (mut est, mut reference) = (String::new(), String::new());
    for i in 0..30 {
        let s = i as f64 * 0.1;
        let r = Vector3::new(s.sin() * 3.0, (2.0 * s).cos(), 0.5 * s);
        let e = inv.transform_point(&r);
        reference += &format!("{s:.3} {} {} {} 0 0 0 1\n", r.x, r.y, r.z);
        est += &format!("{s:.3} {} {} {} 0 0 0 1\n", e.x, e.y, e.z);
    }
    let p = |name: &str| dir.path().join(name).display().to_string();
    std::fs::write(p("est.txt"), est).unwrap();
    std::fs::write(p("ref.txt"), reference).unwrap();
    std::fs::write(p("cloud.txt"), "# x y z\n0 0 0\n1 0 0\n0.5 -2 7\n").unwrap();
    let run = |input: &str, output: &str| {
        main_with_args([
            "slam2world",
            "transform-cloud",
            &p(input),
            "--align",
            &p("est.txt"),
            &p("ref.txt"),
            "-o",
            &p(output),
        ])
    };
    assert_eq!(run("cloud.txt", "world.ply"), 0);
    let world = read_ply(p("world.ply")).unwrap();
    let want = [[1.0, 2.0, 3.0], [1.0, 6.0, 3.0], [9.0, 4.0, 31.0]];
    for (got, want) in world.points.chunks_exact(3).zip(want) {
        for k in 0..3 {
            assert!(
                (got[k] as f64 - want[k]).abs() < 1e-5,
                "{got:?} vs {want:?}"
            );
        }
    }
    // Missing files and usage errors: exit 1 and 2, nothing written.
    assert_eq!(run("absent.txt", "x.ply"), 1);
    assert_eq!(
        main_with_args([
            "slam2world",
            "transform-cloud",
            &p("cloud.txt"),
            "-o",
            &p("x.ply")
        ]),
        2
    );
    assert!(!dir.path().join("x.ply").exists());
}
