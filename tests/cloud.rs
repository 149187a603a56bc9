//! Backprojection geometry, PLY files and real ORB-SLAM map points through the public API.

use std::path::{Path, PathBuf};

use nalgebra::{UnitQuaternion, Vector3};
use slam2world::cloud::{backproject, backproject_per_keyframe, PointCloud, PointFilter};
use slam2world::io::ply::{read_ply, read_xyz_text, write_ply};
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
