//! COLMAP models: `.bin`/`.txt` round trips, the Sim(3) carry of a model with
//! rigs and frames, the real Maupertuis model, name references, bad input.
//! (pycolmap checks the same files from the other side: tests/python/test_colmap.py.)

use crate::common::data;

use std::path::Path;

use nalgebra::{UnitQuaternion, Vector3};
use slam2world::io::colmap::{
    detect_format, image_name_time, read_colmap, read_name_positions, CameraModel, ColmapCamera,
    ColmapFormat, ColmapFrame, ColmapImage, ColmapModel, ColmapPoint3D, ColmapRig, DataId, Point2D,
    RigSensor, Rigid3, SensorId, SensorType, TrackElement,
};
use slam2world::{Error, Sim3};

fn cam_sensor(id: u32) -> SensorId {
    SensorId {
        kind: SensorType::Camera,
        id,
    }
}

/// A two-camera rig (OPENCV + SIMPLE_RADIAL) over `n_frames` frames looking at
/// a grid of points, each point seen by every image.
fn synthetic(n_frames: u32, names_as_stamps: bool) -> ColmapModel {
    let cameras = vec![
        ColmapCamera {
            id: 1,
            model: CameraModel::OpenCv,
            width: 640,
            height: 480,
            params: vec![500.0, 505.0, 320.5, 240.25, -0.1, 0.01, 1e-4, -2e-4],
        },
        ColmapCamera {
            id: 2,
            model: CameraModel::SimpleRadial,
            width: 320,
            height: 240,
            params: vec![250.0, 160.0, 120.0, 0.02],
        },
    ];
    let cam2_from_rig = Rigid3::from_parts(
        &UnitQuaternion::from_euler_angles(0.01, -0.2, 0.03),
        &Vector3::new(0.12, -0.01, 0.02),
    );
    let rigs = vec![ColmapRig {
        id: 1,
        ref_sensor: Some(cam_sensor(1)),
        sensors: vec![RigSensor {
            sensor: cam_sensor(2),
            sensor_from_rig: Some(cam2_from_rig),
        }],
    }];
    let points: Vec<Vector3<f64>> = (0..30)
        .map(|k| {
            Vector3::new(
                (k % 6) as f64 - 2.5,
                (k / 6) as f64 - 2.0,
                8.0 + 0.1 * k as f64,
            )
        })
        .collect();
    let mut frames = Vec::new();
    let mut images = Vec::new();
    for f in 0..n_frames {
        let rig_from_world = Rigid3::from_parts(
            &UnitQuaternion::from_euler_angles(0.02 * f as f64, 0.05 * f as f64, -0.01),
            &Vector3::new(-0.3 * f as f64, 0.1, 0.05 * f as f64),
        );
        let mut data_ids = Vec::new();
        for cam in [1u32, 2] {
            let image_id = 2 * f + cam;
            data_ids.push(DataId {
                sensor: cam_sensor(cam),
                id: image_id as u64,
            });
            let sensor = if cam == 1 {
                Sim3::identity()
            } else {
                cam2_from_rig.to_sim3()
            };
            let cam_from_world = sensor * rig_from_world.to_sim3();
            let name = if names_as_stamps {
                format!(
                    "cam{cam}/{}.png",
                    1_403_636_579_763_555_584u64 + 50_000_000 * f as u64
                )
            } else {
                format!("cam{cam}/frame_{f:04}.png")
            };
            let mut points2d: Vec<Point2D> = points
                .iter()
                .enumerate()
                .map(|(k, p)| {
                    let c = cam_from_world.transform_point(p);
                    Point2D {
                        xy: [c.x / c.z * 500.0 + 320.0, c.y / c.z * 500.0 + 240.0],
                        point3d_id: Some(k as u64 + 1),
                    }
                })
                .collect();
            points2d.push(Point2D {
                xy: [1.5, 2.5],
                point3d_id: None,
            });
            images.push(ColmapImage {
                id: image_id,
                cam_from_world: Rigid3::from_parts(
                    &cam_from_world.rotation,
                    &cam_from_world.translation,
                ),
                camera_id: cam,
                name,
                points2d,
            });
        }
        frames.push(ColmapFrame {
            id: f + 1,
            rig_id: 1,
            rig_from_world,
            data_ids,
        });
    }
    let points3d = points
        .iter()
        .enumerate()
        .map(|(k, p)| ColmapPoint3D {
            id: k as u64 + 1,
            xyz: [p.x, p.y, p.z],
            rgb: [k as u8, 255 - k as u8, 7],
            error: 0.25 + k as f64 * 1e-3,
            track: images
                .iter()
                .map(|im| TrackElement {
                    image_id: im.id,
                    point2d_idx: k as u32,
                })
                .collect(),
        })
        .collect();
    ColmapModel {
        format: ColmapFormat::Binary,
        cameras,
        images,
        points3d,
        rigs: Some(rigs),
        frames: Some(frames),
    }
}

fn secret() -> Sim3 {
    Sim3::try_new(
        UnitQuaternion::from_euler_angles(0.3, -1.1, 2.0),
        Vector3::new(12.0, -3.5, 100.25),
        7.3,
    )
    .unwrap()
}

#[test]
fn binary_and_text_round_trip_every_record() {
    let model = synthetic(4, false);
    for format in [ColmapFormat::Binary, ColmapFormat::Text] {
        let dir = tempfile::tempdir().unwrap();
        model.write(dir.path(), Some(format)).unwrap();
        assert_eq!(detect_format(dir.path(), None).unwrap(), format);
        let back = read_colmap(dir.path(), None).unwrap();
        assert_eq!(back.format, format);
        assert_eq!(
            ColmapModel {
                format: ColmapFormat::Binary,
                ..back.clone()
            },
            model,
            "{format:?}"
        );
        // Written back unchanged, the files are byte for byte the same.
        let again = tempfile::tempdir().unwrap();
        back.write(again.path(), None).unwrap();
        for stem in ["cameras", "images", "points3D", "rigs", "frames"] {
            let name = format!("{stem}.{}", format.extension());
            assert_eq!(
                std::fs::read(dir.path().join(&name)).unwrap(),
                std::fs::read(again.path().join(&name)).unwrap(),
                "{name}"
            );
        }
    }
}

#[test]
fn transformed_moves_centres_as_points_and_keeps_the_rig_consistent() {
    let model = synthetic(3, false);
    let t = secret();
    let moved = model.transformed(&t);
    assert_eq!(moved.cameras, model.cameras);
    for (a, b) in model.images.iter().zip(&moved.images) {
        let want = t.transform_point(&a.centre());
        assert!(
            (b.centre() - want).norm() < 1e-12 * want.norm(),
            "{} {}",
            b.centre(),
            want
        );
        // Projections are unchanged: the camera sees the moved points as before.
        let p = Vector3::new(0.5, -0.25, 9.0);
        let before = a.cam_from_world.to_sim3().transform_point(&p);
        let after = b
            .cam_from_world
            .to_sim3()
            .transform_point(&t.transform_point(&p))
            / t.scale;
        assert!((before - after).norm() < 1e-12 * before.norm());
    }
    // image pose == sensor_from_rig * rig_from_world, after the move too.
    let rig = &moved.rigs.as_ref().unwrap()[0];
    let s2 = rig.sensors[0].sensor_from_rig.unwrap();
    assert_eq!(
        s2.tvec,
        model.rigs.as_ref().unwrap()[0].sensors[0]
            .sensor_from_rig
            .unwrap()
            .tvec
            .map(|v| v * t.scale)
    );
    for f in moved.frames.as_ref().unwrap() {
        let im = moved
            .images
            .iter()
            .find(|im| im.id as u64 == f.data_ids[1].id)
            .unwrap();
        let composed = s2.to_sim3() * f.rig_from_world.to_sim3();
        let direct = im.cam_from_world.to_sim3();
        assert!((composed.matrix() - direct.matrix()).abs().max() < 1e-9);
    }
    for (a, b) in model.points3d.iter().zip(&moved.points3d) {
        let want = t.transform_point(&Vector3::from(a.xyz));
        assert!((Vector3::from(b.xyz) - want).norm() < 1e-12 * want.norm());
    }
    // The inverse brings the model back.
    let back = moved.transformed(&t.inverse());
    for (a, b) in model.images.iter().zip(&back.images) {
        assert!((a.centre() - b.centre()).norm() < 1e-9);
    }
}

#[test]
fn maupertuis_reads_and_writes_back_unchanged() {
    let Some(dir) = data("colmap_maupertuis", "reconstruction") else {
        return;
    };
    let m = read_colmap(&dir, None).unwrap();
    assert_eq!(m.format, ColmapFormat::Text);
    assert_eq!(
        (m.cameras.len(), m.images.len(), m.points3d.len()),
        (1, 4, 1039)
    );
    assert_eq!(m.num_observations(), 3355);
    assert_eq!(m.cameras[0].model, CameraModel::SimplePinhole);
    assert!(m.rigs.is_none() && m.frames.is_none());
    let pin = m.cameras[0].pinhole().unwrap();
    assert!((pin.fx - 1847.53).abs() < 0.01 && pin.fx == pin.fy);
    // Centres from PROVENANCE.md (3 decimals).
    let want = [
        [-3.453, 2.279, 0.308],
        [-1.794, 2.180, -0.321],
        [5.247, 0.530, 0.013],
        [9.644, -2.710, 2.662],
    ];
    let mut centres = m.camera_centres();
    centres.sort_by(|a, b| a.name.cmp(&b.name));
    for (c, w) in centres.iter().zip(want) {
        assert!(
            (c.position - Vector3::from(w)).abs().max() < 6e-4,
            "{}: {}",
            c.name,
            c.position
        );
    }
    let out = tempfile::tempdir().unwrap();
    m.transformed(&Sim3::identity())
        .write(out.path(), None)
        .unwrap();
    assert_eq!(read_colmap(out.path(), None).unwrap(), m);
    let bin = tempfile::tempdir().unwrap();
    m.write(bin.path(), Some(ColmapFormat::Binary)).unwrap();
    let b = read_colmap(bin.path(), None).unwrap();
    assert_eq!(b.format, ColmapFormat::Binary);
    assert_eq!(b.images, m.images);
    assert_eq!(b.points3d, m.points3d);
}

#[test]
fn names_that_are_stamps_give_a_trajectory() {
    let model = synthetic(5, true);
    let traj = model.trajectory_by_name_time();
    // Two cameras per frame share a stamp: refused, naming both.
    match traj {
        Err(Error::InvalidArgument { reason, .. }) => {
            assert!(reason.contains("same time stamp"), "{reason}")
        }
        other => panic!("{other:?}"),
    }
    let mut one_cam = model.clone();
    one_cam.images.retain(|im| im.camera_id == 1);
    let traj = one_cam.trajectory_by_name_time().unwrap();
    assert_eq!(traj.len(), 5);
    assert!((traj.timestamps[1] - traj.timestamps[0] - 0.05).abs() < 1e-6);
    assert!((traj.timestamps[0] - 1_403_636_579.763_555_5).abs() < 1e-6);
    assert!((traj.positions[2] - one_cam.images[2].centre()).norm() < 1e-12);
    assert_eq!(
        image_name_time(&one_cam.images[0].name),
        Some(traj.timestamps[0])
    );
    let plain = synthetic(2, false);
    assert!(plain.trajectory_by_name_time().is_err());
}

#[test]
fn name_reference_files_in_their_variants() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("ref.txt");
    std::fs::write(
        &p,
        "# model_aligner reference\nimg_a.jpg 1 2 3\nimg_b.jpg\t4.5 -6 7e-1\n",
    )
    .unwrap();
    let r = read_name_positions(&p).unwrap();
    assert_eq!(r.len(), 2);
    assert_eq!(
        (r[1].name.as_str(), r[1].position),
        ("img_b.jpg", Vector3::new(4.5, -6.0, 0.7))
    );
    std::fs::write(&p, "name,x,y,z\nimg_a.jpg, 1, 2, 3\nimg_b.jpg,4,5,6\n").unwrap();
    let r = read_name_positions(&p).unwrap();
    assert_eq!(r[0].position, Vector3::new(1.0, 2.0, 3.0));
    for (text, line) in [
        ("a 1 2 3\na 4 5 6\n", 2),
        ("a 1 2 3\nb 1 2\n", 2),
        ("a 1 2 3\nb 1 2 x\n", 2),
        ("a 1 2 3\nb 1 2 nan\n", 2),
    ] {
        std::fs::write(&p, text).unwrap();
        match read_name_positions(&p) {
            Err(Error::Parse { line: l, .. }) => assert_eq!(l, line, "{text:?}"),
            other => panic!("{text:?}: {other:?}"),
        }
    }
}

fn write_bin(model: &ColmapModel) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    model.write(dir.path(), Some(ColmapFormat::Binary)).unwrap();
    dir
}

fn binary_error(dir: &Path) -> (String, u64, String) {
    match read_colmap(dir, None) {
        Err(Error::BinaryFormat {
            path, offset, what, ..
        }) => (
            path.file_name().unwrap().to_string_lossy().into_owned(),
            offset,
            what,
        ),
        other => panic!("expected a binary format error, got {other:?}"),
    }
}

#[test]
fn truncated_files_and_lying_counts_are_typed_errors() {
    let model = synthetic(2, false);
    // Truncated images.bin: cut inside the second image.
    let dir = write_bin(&model);
    let p = dir.path().join("images.bin");
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() - 100]).unwrap();
    let (file, _, what) = binary_error(dir.path());
    assert_eq!(file, "images.bin");
    assert!(
        what.starts_with("points2D") || what.contains("num_points2D"),
        "{what}"
    );

    // A hostile num_points2D (2^62) is refused before any allocation.
    std::fs::write(&p, &bytes).unwrap();
    let mut evil = bytes.clone();
    let name_end =
        8 + 4 + 56 + 4 + evil[8 + 4 + 56 + 4..].iter().position(|&b| b == 0).unwrap() + 1;
    evil[name_end..name_end + 8].copy_from_slice(&(1u64 << 62).to_le_bytes());
    std::fs::write(&p, &evil).unwrap();
    let (_, offset, what) = binary_error(dir.path());
    assert_eq!(offset, name_end as u64);
    assert!(what.ends_with("num_points2D"), "{what}");

    // num_points3D larger than the file can hold.
    std::fs::write(&p, &bytes).unwrap();
    let q = dir.path().join("points3D.bin");
    let mut pts = std::fs::read(&q).unwrap();
    pts[..8].copy_from_slice(&u64::MAX.to_le_bytes());
    std::fs::write(&q, &pts).unwrap();
    assert_eq!(
        binary_error(dir.path()),
        ("points3D.bin".into(), 0, "num_points3D".into())
    );

    // A count smaller than the records leaves bytes over: refused too.
    pts[..8].copy_from_slice(&29u64.to_le_bytes());
    std::fs::write(&q, &pts).unwrap();
    assert_eq!(binary_error(dir.path()).2, "end of file");
}

#[test]
fn unknown_camera_model_and_sensor_type_are_typed_errors() {
    let model = synthetic(1, false);
    let dir = write_bin(&model);
    let p = dir.path().join("cameras.bin");
    let mut b = std::fs::read(&p).unwrap();
    b[12..16].copy_from_slice(&99i32.to_le_bytes());
    std::fs::write(&p, &b).unwrap();
    match read_colmap(dir.path(), None) {
        Err(Error::BinaryFormat {
            offset: 12,
            what,
            found,
            ..
        }) => {
            assert_eq!((what.as_str(), found.as_str()), ("camera 1 model_id", "99"))
        }
        other => panic!("{other:?}"),
    }
    let dir = write_bin(&model);
    let p = dir.path().join("rigs.bin");
    let mut b = std::fs::read(&p).unwrap();
    b[16..20].copy_from_slice(&7i32.to_le_bytes());
    std::fs::write(&p, &b).unwrap();
    assert_eq!(binary_error(dir.path()).2, "rig 1 ref_sensor");

    let dir = tempfile::tempdir().unwrap();
    model.write(dir.path(), Some(ColmapFormat::Text)).unwrap();
    let p = dir.path().join("cameras.txt");
    let t = std::fs::read_to_string(&p)
        .unwrap()
        .replace("OPENCV", "OPENCV_MAGIC");
    std::fs::write(&p, t).unwrap();
    match read_colmap(dir.path(), None) {
        Err(Error::Parse {
            line: 4, reason, ..
        }) => assert!(reason.contains("OPENCV_MAGIC"), "{reason}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn folders_that_are_not_one_model_are_refused() {
    let model = synthetic(1, false);
    let reason = |dir: &Path| match read_colmap(dir, None) {
        Err(Error::Reconstruction { reason, .. }) => reason,
        other => panic!("{other:?}"),
    };
    let dir = write_bin(&model);
    std::fs::remove_file(dir.path().join("points3D.bin")).unwrap();
    assert!(reason(dir.path()).contains("missing points3D.bin"));

    let dir = write_bin(&model);
    std::fs::remove_file(dir.path().join("frames.bin")).unwrap();
    assert!(reason(dir.path()).contains("come together"));

    // Both flavours: refused unless one is named; writing beside one is refused.
    let dir = write_bin(&model);
    let txt = tempfile::tempdir().unwrap();
    model.write(txt.path(), Some(ColmapFormat::Text)).unwrap();
    for f in std::fs::read_dir(txt.path()).unwrap() {
        let f = f.unwrap();
        std::fs::copy(f.path(), dir.path().join(f.file_name())).unwrap();
    }
    assert!(reason(dir.path()).contains("both flavours"));
    assert_eq!(
        read_colmap(dir.path(), Some(ColmapFormat::Text))
            .unwrap()
            .format,
        ColmapFormat::Text
    );
    let only_bin = write_bin(&model);
    assert!(matches!(
        model.write(only_bin.path(), Some(ColmapFormat::Text)),
        Err(Error::Reconstruction { .. })
    ));

    let empty = tempfile::tempdir().unwrap();
    assert!(reason(empty.path()).contains("no COLMAP model files"));

    // A track that names a missing image.
    let mut broken = model.clone();
    broken.points3d[0].track[0].image_id = 99;
    let dir = write_bin(&broken);
    assert!(reason(dir.path()).contains("image 99"));
}

#[test]
fn a_failed_write_leaves_the_folder_as_it_was() {
    let model = synthetic(1, false);
    let dir = write_bin(&model);
    let before: Vec<_> = ["cameras", "images", "points3D"]
        .iter()
        .map(|s| std::fs::read(dir.path().join(format!("{s}.bin"))).unwrap())
        .collect();
    let mut bad = model.transformed(&secret());
    bad.images[0].name = "has space.png".into();
    let txt = tempfile::tempdir().unwrap();
    assert!(bad.write(txt.path(), Some(ColmapFormat::Text)).is_err());
    assert_eq!(std::fs::read_dir(txt.path()).unwrap().count(), 0);
    // Overwriting in the same flavour replaces every file; nothing else is left.
    bad.write(dir.path(), None).unwrap();
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 5);
    assert_ne!(
        std::fs::read(dir.path().join("images.bin")).unwrap(),
        before[1]
    );
    assert_eq!(
        std::fs::read(dir.path().join("cameras.bin")).unwrap(),
        before[0]
    );
}

#[test]
fn every_truncation_and_byte_flip_is_an_error_or_a_model_never_a_panic() {
    use rand::{Rng, SeedableRng};
    let model = synthetic(1, false);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(15);
    for format in [ColmapFormat::Binary, ColmapFormat::Text] {
        let dir = tempfile::tempdir().unwrap();
        model.write(dir.path(), Some(format)).unwrap();
        for stem in ["cameras", "rigs", "frames", "images", "points3D"] {
            let p = dir.path().join(format!("{stem}.{}", format.extension()));
            let good = std::fs::read(&p).unwrap();
            let step = (good.len() / 120).max(1);
            for cut in (0..good.len()).step_by(step) {
                std::fs::write(&p, &good[..cut]).unwrap();
                // Text files cut between records are still models; binary ones never are.
                let r = read_colmap(dir.path(), None);
                if format == ColmapFormat::Binary {
                    assert!(r.is_err(), "{stem} cut at {cut}");
                }
            }
            for _ in 0..120 {
                let mut bad = good.clone();
                let i = rng.random_range(0..bad.len());
                bad[i] = rng.random();
                std::fs::write(&p, &bad).unwrap();
                let _ = read_colmap(dir.path(), None);
            }
            std::fs::write(&p, &good).unwrap();
        }
        assert_eq!(read_colmap(dir.path(), None).unwrap().images, model.images);
    }
}
