//! DROID-SLAM reconstruction folders written here in the `.npy` layout numpy
//! uses (the Python tests write them with numpy itself): both disparity
//! resolutions, the pose inversion, colours, the depth-consistency filter,
//! bad folders.

use std::path::Path;

use nalgebra::{UnitQuaternion, Vector3};
use slam2world::io::droid::{depth_consistency_counts, filter_consistent, read_droid, DepthFilter};
use slam2world::{Error, Sim3};

/// A version 1.0 `.npy` file, as `numpy.save` lays it out.
fn npy(path: &Path, descr: &str, shape: &[usize], data: &[u8]) {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape = match dims.len() {
        1 => format!("({},)", dims[0]),
        _ => format!("({})", dims.join(", ")),
    };
    let mut h = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    while (10 + h.len() + 1) % 64 != 0 {
        h.push(' ');
    }
    h.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend((h.len() as u16).to_le_bytes());
    out.extend(h.as_bytes());
    out.extend(data);
    std::fs::write(path, out).unwrap();
}

fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

const N: usize = 8;
const H: usize = 48;
const W: usize = 64;
/// Intrinsics at 1/8 resolution, as DROID-SLAM stores them.
const K8: [f32; 4] = [7.0, 7.5, 3.9, 2.8];

/// Camera `i` of the scene: `T_world_cam`, moving sideways and looking at the
/// plane z = 5 of the world.
fn cam_pose(i: usize) -> Sim3 {
    Sim3::try_new(
        UnitQuaternion::from_euler_angles(0.0, 0.01 * i as f64, 0.0),
        Vector3::new(0.05 * i as f64, 0.02, 0.0),
        1.0,
    )
    .unwrap()
}

/// Disparity of the plane z = 5 seen by camera `i` at grid pixel (x, y) of a
/// camera with intrinsics `k`.
fn plane_disparity(i: usize, k: [f64; 4], x: usize, y: usize) -> f32 {
    let t = cam_pose(i);
    let ray = t.rotation * Vector3::new((x as f64 - k[2]) / k[0], (y as f64 - k[3]) / k[1], 1.0);
    // world point o + λ·ray with z = 5; the depth along the camera z is λ.
    let lambda = (5.0 - t.translation.z) / ray.z;
    (1.0 / lambda) as f32
}

/// Writes a folder whose disparities are at `1/r` of the image resolution.
fn write_folder(dir: &Path, r: usize) {
    let (h, w) = (H * 8 / r, W * 8 / r);
    let (big_h, big_w) = (H * 8, W * 8);
    let k = K8.map(|v| v as f64 * 8.0 / r as f64);
    let tstamps: Vec<f32> = (0..N).map(|i| (3 * i) as f32).collect();
    npy(&dir.join("tstamps.npy"), "<f4", &[N], &f32s(&tstamps));
    let mut poses = Vec::new();
    for i in 0..N {
        let g = cam_pose(i).inverse(); // world-to-camera, as DROID-SLAM stores it
        let q = g.quaternion_xyzw();
        poses.extend([
            g.translation.x,
            g.translation.y,
            g.translation.z,
            q[0],
            q[1],
            q[2],
            q[3],
        ]);
    }
    let poses: Vec<u8> = poses.iter().flat_map(|v| v.to_le_bytes()).collect();
    npy(&dir.join("poses.npy"), "<f8", &[N, 7], &poses);
    let intr: Vec<f32> = (0..N).flat_map(|_| K8).collect();
    npy(&dir.join("intrinsics.npy"), "<f4", &[N, 4], &f32s(&intr));
    let mut disps = Vec::with_capacity(N * h * w);
    for i in 0..N {
        for y in 0..h {
            for x in 0..w {
                disps.push(plane_disparity(i, k, x, y));
            }
        }
    }
    npy(&dir.join("disps.npy"), "<f4", &[N, h, w], &f32s(&disps));
    // BGR planes: B = frame index, G = row / 2, R = column / 2 (full resolution).
    let mut images = Vec::with_capacity(N * 3 * big_h * big_w);
    for i in 0..N {
        images.extend(std::iter::repeat_n(i as u8, big_h * big_w));
        for y in 0..big_h {
            images.extend(std::iter::repeat_n((y / 2) as u8, big_w));
        }
        for _ in 0..big_h {
            images.extend((0..big_w).map(|x| (x / 2) as u8));
        }
    }
    npy(
        &dir.join("images.npy"),
        "|u1",
        &[N, 3, big_h, big_w],
        &images,
    );
}

#[test]
#[ignore = "slow: make test runs it"]
fn both_disparity_resolutions_read_to_the_scene() {
    for r in [8usize, 1] {
        let dir = tempfile::tempdir().unwrap();
        write_folder(dir.path(), r);
        let rec = read_droid(dir.path()).unwrap();
        assert_eq!(rec.downsample, r as u32);
        assert_eq!(rec.image_size, ((H * 8) as u32, (W * 8) as u32));
        assert_eq!(rec.keyframes.len(), N);
        let s = 8.0 / r as f64;
        for (i, kf) in rec.keyframes.iter().enumerate() {
            assert_eq!((kf.id, kf.timestamp), (i as i32, (3 * i) as f64));
            let c = kf.camera;
            assert_eq!(
                (c.width as usize, c.height as usize),
                (W * 8 / r, H * 8 / r)
            );
            assert!(
                (c.fx - K8[0] as f64 * s).abs() < 1e-5 && (c.cy - K8[3] as f64 * s).abs() < 1e-5
            );
            // T_slam_cam: the camera centre is the known one.
            let centre = kf.pose.translation;
            assert!(
                (centre - cam_pose(i).translation).norm() < 1e-12,
                "{centre}"
            );
            assert!(kf.pose.rotation.angle_to(&cam_pose(i).rotation) < 1e-12);
            // Backprojected pixels lie on the plane z = 5.
            let (x, y) = (c.width as usize / 3, c.height as usize / 2);
            let d = kf.idepth[y * c.width as usize + x] as f64;
            let p =
                kf.pose
                    .transform_point(&Vector3::from(c.backproject(x as f64, y as f64, 1.0 / d)));
            assert!((p.z - 5.0).abs() < 1e-4, "{}", p.z);
            // Colour: RGB from the BGR image, sampled at r·x + (r−1)/2.
            let color = kf.color.as_ref().unwrap();
            let at = 3 * (y * c.width as usize + x);
            let off = (r - 1) / 2;
            assert_eq!(
                &color[at..at + 3],
                &[
                    ((r * x + off) / 2) as u8,
                    ((r * y + off) / 2) as u8,
                    i as u8
                ]
            );
        }
    }
}

#[test]
fn consistency_filter_keeps_the_plane_and_drops_a_wrong_keyframe() {
    let dir = tempfile::tempdir().unwrap();
    write_folder(dir.path(), 8);
    let mut kfs = read_droid(dir.path()).unwrap().keyframes;
    // Keyframe 4 gets disparities 30 % too large: no neighbour agrees with it.
    for d in &mut kfs[4].idepth {
        *d *= 1.3;
    }
    let filter = DepthFilter {
        threshold: 0.05,
        min_disparity_ratio: 0.0,
        ..DepthFilter::default()
    };
    let counts = depth_consistency_counts(&kfs, &filter).unwrap();
    let total = |i: usize| counts[i].iter().filter(|&&c| c >= 2).count();
    let n = H * W;
    assert!(total(1) > n / 2, "{} of {n}", total(1));
    assert_eq!(total(4), 0);
    // Keyframe 0 has only later neighbours at +3, +4 (+5 is 5, fine): it keeps points too.
    assert!(total(0) > n / 4, "{}", total(0));
    let kept = filter_consistent(&kfs, &filter).unwrap();
    assert!(kept[4].idepth.iter().all(|&d| d == 0.0));
    let survivors = kept[1].idepth.iter().filter(|&&d| d > 0.0).count();
    assert_eq!(survivors, total(1));
    assert!(depth_consistency_counts(
        &kfs,
        &DepthFilter {
            threshold: 0.0,
            ..filter
        }
    )
    .is_err());
}

#[test]
fn bad_folders_are_typed_errors() {
    let dir = tempfile::tempdir().unwrap();
    write_folder(dir.path(), 8);
    std::fs::remove_file(dir.path().join("intrinsics.npy")).unwrap();
    match read_droid(dir.path()) {
        Err(Error::Reconstruction { reason, .. }) => {
            assert!(reason.contains("intrinsics.npy"), "{reason}")
        }
        other => panic!("{other:?}"),
    }
    // Wrong shape: poses (N, 6).
    write_folder(dir.path(), 8);
    npy(
        &dir.path().join("poses.npy"),
        "<f4",
        &[N, 6],
        &[0; N * 6 * 4],
    );
    match read_droid(dir.path()) {
        Err(Error::Reconstruction { path, reason }) => {
            assert!(
                path.ends_with("poses.npy") && reason.contains("(8, 7)"),
                "{reason}"
            )
        }
        other => panic!("{other:?}"),
    }
    // Wrong dtype: images as float.
    write_folder(dir.path(), 8);
    npy(
        &dir.path().join("images.npy"),
        "<f4",
        &[N, 3, 1, 1],
        &[0; N * 3 * 4],
    );
    assert!(matches!(
        read_droid(dir.path()),
        Err(Error::Reconstruction { .. })
    ));
    // A disparity grid that is no whole fraction of the image.
    write_folder(dir.path(), 8);
    npy(
        &dir.path().join("disps.npy"),
        "<f4",
        &[N, 7, 9],
        &[0; N * 63 * 4],
    );
    match read_droid(dir.path()) {
        Err(Error::Reconstruction { reason, .. }) => {
            assert!(reason.contains("whole number"), "{reason}")
        }
        other => panic!("{other:?}"),
    }
    // A broken .npy header and a data length that lies.
    write_folder(dir.path(), 8);
    std::fs::write(
        dir.path().join("tstamps.npy"),
        b"\x93NUMPY\x01\x00\x10\x00{'descr': <f4}  ",
    )
    .unwrap();
    assert!(matches!(
        read_droid(dir.path()),
        Err(Error::BinaryFormat { .. })
    ));
    npy(
        &dir.path().join("tstamps.npy"),
        "<f4",
        &[N + 1],
        &f32s(&[0.0; N]),
    );
    match read_droid(dir.path()) {
        Err(Error::BinaryFormat { what, offset, .. }) => {
            assert_eq!((what.as_str(), offset), ("data", 128))
        }
        other => panic!("{other:?}"),
    }
    // A zero quaternion.
    npy(
        &dir.path().join("tstamps.npy"),
        "<f4",
        &[N],
        &f32s(&[0.0; N]),
    );
    npy(
        &dir.path().join("poses.npy"),
        "<f4",
        &[N, 7],
        &[0; N * 7 * 4],
    );
    match read_droid(dir.path()) {
        Err(Error::Reconstruction { reason, .. }) => assert!(reason.contains("pose 0"), "{reason}"),
        other => panic!("{other:?}"),
    }
}
