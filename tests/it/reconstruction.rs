//! Reconstructions through the pipeline: detection from the path's contents,
//! COLMAP models paired by image name or by stamped names, the output set in
//! the input's own format, octree ray origins from observing images, trajectory
//! files with their PLY, the real ORB-SLAM3 run (ns) against seconds ground
//! truth, and the errors (names that match nothing, a time reference for
//! images without stamps, no pairs by time).
//! (pycolmap checks the same outputs from the other side:
//! tests/python/test_reconstruction.py.)

use crate::common::{bin, data, stderr};

use std::path::{Path, PathBuf};

use nalgebra::{UnitQuaternion, Vector3};
use slam2world::cloud::PointCloud;
use slam2world::io::colmap::{
    read_colmap, CameraModel, ColmapCamera, ColmapFormat, ColmapImage, ColmapModel, ColmapPoint3D,
    Point2D, Rigid3, TrackElement,
};
use slam2world::io::ply::write_ply;
use slam2world::io::text::{read_trajectory, write_tum, TimeUnit};
use slam2world::map::MapParams;
use slam2world::pipeline::native::{FrameTimes, ReconstructionKind, ReferenceFormat};
use slam2world::pipeline::reconstruction::{
    attach_reference, detect_reconstruction, detect_reference_format, open_input,
    read_reconstruction, ReconstructionOptions, ReferenceSpec,
};
use slam2world::pipeline::{
    convert, convert_source, ConvertOptions, CLOUD_PLY, COLMAP_MODEL, MAP_BT, REPORT_HTML,
    REPORT_JSON, TRAJECTORY_TUM, WORLD_MCAP,
};
use slam2world::trajectory::Trajectory;
use slam2world::{Error, Sim3};

const FIRST_NS: u64 = 1_403_636_579_763_555_584;

/// A metric scene: one SIMPLE_RADIAL camera, `n` images along an arc looking
/// at 24 points, every point seen by every image but the last point by none.
fn scene(n: u32, stamped: bool) -> ColmapModel {
    let cameras = vec![ColmapCamera {
        id: 1,
        model: CameraModel::SimpleRadial,
        width: 640,
        height: 480,
        params: vec![500.0, 320.0, 240.0, 0.03],
    }];
    let points: Vec<Vector3<f64>> = (0..24)
        .map(|k| {
            Vector3::new(
                (k % 6) as f64 - 2.5,
                (k / 6) as f64 - 1.5,
                6.0 + 0.2 * (k % 5) as f64,
            )
        })
        .collect();
    let mut images = Vec::new();
    for i in 0..n {
        let a = i as f64;
        let world_from_cam = Sim3::try_new(
            UnitQuaternion::from_euler_angles(0.02 * a, -0.04 * a, 0.01),
            Vector3::new(0.4 * a, 0.1 * (0.7 * a).sin(), 0.05 * a * a),
            1.0,
        )
        .unwrap();
        let cam_from_world = world_from_cam.inverse();
        let points2d = points
            .iter()
            .enumerate()
            .map(|(k, p)| {
                let c = cam_from_world.transform_point(p);
                Point2D {
                    xy: [c.x / c.z * 500.0 + 320.0, c.y / c.z * 500.0 + 240.0],
                    point3d_id: (k < 23).then_some(k as u64 + 1),
                }
            })
            .collect();
        let name = if stamped {
            format!("{}.png", FIRST_NS + 50_000_000 * i as u64)
        } else {
            format!("img_{i:03}.jpg")
        };
        images.push(ColmapImage {
            id: i + 1,
            cam_from_world: Rigid3::from_parts(
                &cam_from_world.rotation,
                &cam_from_world.translation,
            ),
            camera_id: 1,
            name,
            points2d,
        });
    }
    let points3d = points
        .iter()
        .enumerate()
        .map(|(k, p)| ColmapPoint3D {
            id: k as u64 + 1,
            xyz: [p.x, p.y, p.z],
            rgb: [k as u8, 100, 200],
            error: 0.5,
            track: if k < 23 {
                images
                    .iter()
                    .map(|im| TrackElement {
                        image_id: im.id,
                        point2d_idx: k as u32,
                    })
                    .collect()
            } else {
                Vec::new()
            },
        })
        .collect();
    ColmapModel {
        format: ColmapFormat::Binary,
        cameras,
        images,
        points3d,
        rigs: None,
        frames: None,
    }
}

/// The scene without its last point (the one no image observes).
fn seen(n: u32) -> ColmapModel {
    let mut m = scene(n, false);
    m.points3d.pop();
    m
}

/// `T_slam_world` of the disguise.
fn secret() -> Sim3 {
    Sim3::try_new(
        UnitQuaternion::from_euler_angles(0.3, -1.1, 2.0),
        Vector3::new(12.0, -3.5, 100.25),
        0.137,
    )
    .unwrap()
}

/// The scene in the secret SLAM frame, written in `format` under `dir/sparse`.
fn disguised(dir: &Path, truth: &ColmapModel, format: ColmapFormat) -> PathBuf {
    let p = dir.join("sparse");
    truth
        .transformed(&secret())
        .write(&p, Some(format))
        .unwrap();
    p
}

fn write_names(path: &Path, rows: &[(String, Vector3<f64>)]) -> PathBuf {
    let text: String = rows
        .iter()
        .map(|(n, c)| format!("{n} {:?} {:?} {:?}\n", c.x, c.y, c.z))
        .collect();
    std::fs::write(path, text).unwrap();
    path.to_path_buf()
}

fn true_centres(m: &ColmapModel) -> Vec<(String, Vector3<f64>)> {
    m.images
        .iter()
        .map(|im| (im.name.clone(), im.centre()))
        .collect()
}

fn spec(path: PathBuf) -> ReferenceSpec {
    ReferenceSpec {
        path,
        format: None,
        time_unit: None,
    }
}

fn max_matrix_diff(a: &Sim3, b: &Sim3) -> f64 {
    (a.matrix() - b.matrix()).abs().max()
}

#[test]
fn detection_from_the_contents() {
    let dir = tempfile::tempdir().unwrap();
    let truth = scene(5, false);
    let sparse = disguised(dir.path(), &truth, ColmapFormat::Text);
    assert_eq!(
        detect_reconstruction(&sparse, None).unwrap(),
        Some(ReconstructionKind::Colmap(ColmapFormat::Text))
    );
    // A COLMAP folder missing a file names it.
    std::fs::remove_file(sparse.join("points3D.txt")).unwrap();
    let e = detect_reconstruction(&sparse, None).unwrap_err();
    assert!(e.to_string().contains("missing points3D.txt"), "{e}");
    // A DROID-SLAM folder is told by any of its arrays (the reader names the rest).
    let droid = dir.path().join("droid");
    std::fs::create_dir(&droid).unwrap();
    std::fs::write(droid.join("poses.npy"), b"").unwrap();
    assert_eq!(
        detect_reconstruction(&droid, None).unwrap(),
        Some(ReconstructionKind::Droid)
    );
    let Err(Error::Reconstruction { reason, .. }) =
        read_reconstruction(&droid, &ReconstructionOptions::default())
    else {
        panic!("expected a Reconstruction error")
    };
    assert!(reason.contains("missing tstamps.npy"), "{reason}");
    // A text file is a trajectory; an MCAP file and a rosbag2 folder are logs.
    let txt = dir.path().join("kf.txt");
    std::fs::write(&txt, "0 0 0 0 0 0 0 1\n").unwrap();
    assert_eq!(
        detect_reconstruction(&txt, None).unwrap(),
        Some(ReconstructionKind::Trajectory)
    );
    let mcap = dir.path().join("log.mcap");
    std::fs::write(&mcap, b"\x89MCAP0\r\n rest").unwrap();
    assert_eq!(detect_reconstruction(&mcap, None).unwrap(), None);
    let bag = dir.path().join("bag");
    std::fs::create_dir(&bag).unwrap();
    std::fs::write(
        bag.join("metadata.yaml"),
        "rosbag2_bagfile_information: {}\n",
    )
    .unwrap();
    assert_eq!(detect_reconstruction(&bag, None).unwrap(), None);
    // Binary junk is left to the log reader, a PLY alone is refused.
    let junk = dir.path().join("junk");
    std::fs::write(&junk, [0u8, 159, 146, 150, 0, 1]).unwrap();
    assert_eq!(detect_reconstruction(&junk, None).unwrap(), None);
    let ply = dir.path().join("cloud.ply");
    write_ply(
        &ply,
        &PointCloud::try_new(vec![0.0; 3], None, None).unwrap(),
    )
    .unwrap();
    assert!(detect_reconstruction(&ply, None)
        .unwrap_err()
        .to_string()
        .contains("no poses"));
    // An empty folder says what was looked for.
    let empty = tempfile::tempdir().unwrap();
    let e = detect_reconstruction(empty.path(), None).unwrap_err();
    assert!(e.to_string().contains("COLMAP model"), "{e}");
}

#[test]
fn colmap_by_name_converts_back_to_the_true_model_as_one_output_set() {
    let truth = scene(8, false);
    for format in [ColmapFormat::Binary, ColmapFormat::Text] {
        let dir = tempfile::tempdir().unwrap();
        let sparse = disguised(dir.path(), &truth, format);
        let reference = write_names(&dir.path().join("ref.txt"), &true_centres(&truth));
        assert_eq!(
            detect_reference_format(&reference).unwrap(),
            ReferenceFormat::Names
        );
        let opts = ConvertOptions::default();
        let src = open_input(
            &sparse,
            &opts.read,
            &ReconstructionOptions::default(),
            Some(&spec(reference)),
        )
        .unwrap();
        let c = convert_source(&*src, &opts).unwrap();
        assert!(max_matrix_diff(&c.transform(), &secret().inverse()) < 1e-9);
        let r = &c.report;
        assert_eq!(
            (r.format.as_str(), r.max_diff, r.pairs_fitted),
            ("colmap", 0.0, 8)
        );
        assert_eq!(r.frames_dropped, Vec::<i32>::new());
        let names: Vec<_> = r.pairs.iter().filter_map(|p| p.name.clone()).collect();
        assert_eq!(names.len(), 8);
        let recon = r.reconstruction.as_ref().unwrap();
        assert_eq!(recon.flavour.as_deref(), Some(format.extension()));
        assert!(recon.frame_times.contains("rank"), "{}", recon.frame_times);
        let reference = r.reference_file.as_ref().unwrap();
        assert_eq!(
            (reference.pairing.as_str(), reference.format_detected),
            ("name", true)
        );

        let out = dir.path().join("out");
        c.write_all(&out, slam2world::io::mcap::WorldFlavor::Foxglove)
            .unwrap();
        let mut listing: Vec<String> = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        listing.sort();
        assert_eq!(
            listing,
            [
                CLOUD_PLY,
                COLMAP_MODEL,
                REPORT_HTML,
                REPORT_JSON,
                TRAJECTORY_TUM,
                WORLD_MCAP
            ]
        );
        let back = read_colmap(&out.join(COLMAP_MODEL), None).unwrap();
        assert_eq!(back.format, format);
        assert_eq!(back.cameras, truth.cameras);
        assert_eq!(back.num_observations(), truth.num_observations());
        for (a, b) in truth.images.iter().zip(&back.images) {
            assert_eq!((a.id, &a.name), (b.id, &b.name));
            assert!((a.centre() - b.centre()).norm() < 1e-9 * 10.0);
        }
        for (a, b) in truth.points3d.iter().zip(&back.points3d) {
            let d = (Vector3::from(a.xyz) - Vector3::from(b.xyz)).norm();
            assert!(d < 1e-9 * 10.0, "{d}");
        }
        let (world, info) = read_trajectory(&out.join(TRAJECTORY_TUM), None).unwrap();
        assert_eq!((world.len(), info.unit), (8, TimeUnit::Seconds));
    }
}

#[test]
fn output_sets_replace_each_other_whole() {
    let truth = seen(6);
    let dir = tempfile::tempdir().unwrap();
    let sparse = disguised(dir.path(), &truth, ColmapFormat::Binary);
    let reference = write_names(&dir.path().join("ref.txt"), &true_centres(&truth));
    let mut rec = read_reconstruction(&sparse, &ReconstructionOptions::default()).unwrap();
    attach_reference(&mut rec, &spec(reference)).unwrap();
    let with_map = ConvertOptions {
        map: Some(MapParams::new(0.5)),
        ..ConvertOptions::default()
    };
    let out = dir.path().join("out");
    let flavor = slam2world::io::mcap::WorldFlavor::Foxglove;
    convert(&rec, &with_map)
        .unwrap()
        .write_all(&out, flavor)
        .unwrap();
    assert!(out.join(MAP_BT).is_file());
    // A text model written over a binary one: the folder holds only the new flavour.
    let mut text = rec.clone();
    if let Some(slam2world::pipeline::NativeModel::Colmap(m)) = &mut text.native {
        m.format = ColmapFormat::Text;
    }
    convert(&text, &ConvertOptions::default())
        .unwrap()
        .write_all(&out, flavor)
        .unwrap();
    assert!(
        !out.join(MAP_BT).exists(),
        "the stale map of the first set is gone"
    );
    let mut model: Vec<String> = std::fs::read_dir(out.join(COLMAP_MODEL))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    model.sort();
    assert_eq!(model, ["cameras.txt", "images.txt", "points3D.txt"]);
    // No staging folder is left behind.
    assert!(std::fs::read_dir(&out).unwrap().all(|e| !e
        .unwrap()
        .file_name()
        .to_string_lossy()
        .starts_with('.')));
}

#[test]
fn octree_rays_start_at_the_nearest_observing_image() {
    let truth = scene(6, false);
    let dir = tempfile::tempdir().unwrap();
    let sparse = disguised(dir.path(), &truth, ColmapFormat::Binary);
    let rec = read_reconstruction(&sparse, &ReconstructionOptions::default()).unwrap();
    let cloud = rec.cloud.as_ref().unwrap();
    let origins = rec.cloud_origins.as_ref().unwrap();
    let model = rec.native.as_ref().and_then(|m| m.colmap()).unwrap();
    for (k, p) in model.points3d.iter().enumerate() {
        let id = cloud.keyframe_ids[k];
        if p.track.is_empty() {
            assert_eq!(id, -1);
            continue;
        }
        let x = Vector3::from(p.xyz);
        let nearest = model
            .images
            .iter()
            .min_by(|a, b| (a.centre() - x).norm().total_cmp(&(b.centre() - x).norm()))
            .unwrap();
        assert_eq!(id, nearest.id as i32, "point {}", p.id);
        assert!((origins[&id] - nearest.centre()).norm() < 1e-12);
    }
    // The last point is observed by no image: the octree refuses it by index.
    let mut rec = rec;
    let reference = write_names(&dir.path().join("ref.txt"), &true_centres(&truth));
    attach_reference(&mut rec, &spec(reference.clone())).unwrap();
    let opts = ConvertOptions {
        map: Some(MapParams::new(0.25)),
        ..ConvertOptions::default()
    };
    let Err(Error::InvalidArgument { what, reason }) = convert(&rec, &opts) else {
        panic!("expected the octree refusal")
    };
    assert_eq!(what, "octree");
    assert!(
        reason.contains("point 23") && reason.contains("no ray origin"),
        "{reason}"
    );
    // Without it, every point is occupied in the octree, one scan per nearest image.
    let truth = seen(6);
    let other = tempfile::tempdir().unwrap();
    let sparse = disguised(other.path(), &truth, ColmapFormat::Binary);
    let mut rec = read_reconstruction(&sparse, &ReconstructionOptions::default()).unwrap();
    attach_reference(&mut rec, &spec(reference)).unwrap();
    let mut nearest: Vec<i32> = rec.cloud.as_ref().unwrap().keyframe_ids.clone();
    nearest.sort_unstable();
    nearest.dedup();
    let conv = convert(&rec, &opts).unwrap();
    let map = conv.octree.as_ref().unwrap();
    for p in conv.cloud.points.chunks_exact(3) {
        let s = map.state([p[0] as f64, p[1] as f64, p[2] as f64]);
        assert_eq!(s, slam2world::map::VoxelState::Occupied);
    }
    let o = conv.report.octree.as_ref().unwrap();
    assert_eq!((o.points, o.scans), (23, nearest.len()));
    assert!(o.leaves_free > 0, "the rays cleared space");
}

#[test]
fn stamped_names_pair_by_time_and_unknown_names_are_counted() {
    let truth = scene(7, true);
    let dir = tempfile::tempdir().unwrap();
    let sparse = disguised(dir.path(), &truth, ColmapFormat::Binary);
    let rec = read_reconstruction(&sparse, &ReconstructionOptions::default()).unwrap();
    let info = rec.source.reconstruction.as_ref().unwrap();
    assert_eq!(info.frame_times, FrameTimes::ImageNames);
    // Ground truth in TUM order, nanosecond stamps: detected.
    let times: Vec<f64> = (0..7)
        .map(|i| (FIRST_NS + 50_000_000 * i as u64) as f64)
        .collect();
    let gt = Trajectory::try_new(
        times,
        truth.images.iter().map(|im| im.centre()).collect(),
        None,
    )
    .unwrap();
    let gt_path = dir.path().join("gt.txt");
    write_tum(&gt, &gt_path).unwrap();
    let mut timed = rec.clone();
    attach_reference(&mut timed, &spec(gt_path.clone())).unwrap();
    let c = convert(&timed, &ConvertOptions::default()).unwrap();
    assert!(max_matrix_diff(&c.transform(), &secret().inverse()) < 1e-8);
    let text = c
        .report
        .reference_file
        .as_ref()
        .unwrap()
        .text
        .as_ref()
        .unwrap();
    assert_eq!((text.unit.as_str(), text.unit_detected), ("ns", true));

    // By name, with a name the model lacks.
    let mut rows = true_centres(&truth);
    rows.push(("not_an_image.png".into(), Vector3::zeros()));
    let names = write_names(&dir.path().join("names.txt"), &rows);
    let mut named = rec.clone();
    attach_reference(&mut named, &spec(names)).unwrap();
    let c = convert(&named, &ConvertOptions::default()).unwrap();
    let n = c
        .report
        .reference_file
        .as_ref()
        .unwrap()
        .names
        .clone()
        .unwrap();
    assert_eq!((n.reference_names, n.matched, n.unknown), (8, 7, 1));
    assert_eq!(n.unknown_examples, ["not_an_image.png"]);
    // A time offset does not apply to names.
    let shifted = ConvertOptions {
        align: slam2world::align::trajectories::TrajectoryAlignOptions {
            offset: 0.5,
            ..Default::default()
        },
        ..ConvertOptions::default()
    };
    assert!(matches!(
        convert(&named, &shifted),
        Err(Error::InvalidArgument { what, .. }) if what == "offset"
    ));
}

#[test]
fn name_and_time_references_that_cannot_pair_are_refused() {
    let truth = scene(5, false);
    let dir = tempfile::tempdir().unwrap();
    let sparse = disguised(dir.path(), &truth, ColmapFormat::Binary);
    let rec = read_reconstruction(&sparse, &ReconstructionOptions::default()).unwrap();
    // Two names only.
    let few = write_names(
        &dir.path().join("few.txt"),
        &true_centres(&truth)[..2]
            .iter()
            .cloned()
            .chain([("x.png".to_string(), Vector3::zeros())])
            .collect::<Vec<_>>(),
    );
    let Err(Error::TooFew { what, need, got }) = attach_reference(&mut rec.clone(), &spec(few))
    else {
        panic!("expected TooFew")
    };
    assert_eq!((need, got), (3, 2));
    assert!(
        what.contains("\"x.png\"") && what.contains("\"img_000.jpg\""),
        "{what}"
    );
    // A time reference for images named img_000.jpg …
    let tum = dir.path().join("t.txt");
    std::fs::write(&tum, "0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n2 2 1 0 0 0 0 1\n").unwrap();
    let Err(Error::InvalidArgument { what, reason }) =
        attach_reference(&mut rec.clone(), &spec(tum))
    else {
        panic!("expected the refusal")
    };
    assert_eq!(what, "reference");
    assert!(reason.contains("no time stamps"), "{reason}");
    // No reference at all.
    let Err(Error::InvalidArgument { what, .. }) = convert(&rec, &ConvertOptions::default()) else {
        panic!("expected the refusal")
    };
    assert_eq!(what, "reference");
}

#[test]
fn trajectory_file_with_its_ply_beside_it() {
    let dir = tempfile::tempdir().unwrap();
    let t_slam_world = secret();
    let times: Vec<f64> = (0..30).map(|i| i as f64 * 0.1).collect();
    let world: Vec<Vector3<f64>> = times
        .iter()
        .map(|&t| Vector3::new(t.cos(), t.sin(), 0.2 * t))
        .collect();
    let gt_path = dir.path().join("gt.csv");
    // A comma-separated TUM-order reference with a header.
    let mut text = String::from("t,x,y,z,qx,qy,qz,qw\n");
    for (t, p) in times.iter().zip(&world) {
        text += &format!("{t},{},{},{},0,0,0,1\n", p.x, p.y, p.z);
    }
    std::fs::write(&gt_path, text).unwrap();
    assert_eq!(
        detect_reference_format(&gt_path).unwrap(),
        ReferenceFormat::Tum
    );
    // DPVO's layout: saved_trajectories/run.txt and run.ply one folder up.
    let saved = dir.path().join("saved_trajectories");
    std::fs::create_dir(&saved).unwrap();
    let slam = Trajectory::try_new(
        times.iter().map(|t| t * 1e3).collect(),
        world
            .iter()
            .map(|p| t_slam_world.transform_point(p))
            .collect(),
        None,
    )
    .unwrap();
    write_tum(&slam, saved.join("run.txt")).unwrap();
    let pts: Vec<f32> = world
        .iter()
        .flat_map(|p| {
            let q = t_slam_world.transform_point(&(p + Vector3::new(0.0, 0.0, 1.0)));
            [q.x as f32, q.y as f32, q.z as f32]
        })
        .collect();
    write_ply(
        dir.path().join("run.ply"),
        &PointCloud::try_new(pts, None, None).unwrap(),
    )
    .unwrap();
    let mut rec =
        read_reconstruction(&saved.join("run.txt"), &ReconstructionOptions::default()).unwrap();
    let info = rec.source.reconstruction.as_ref().unwrap();
    assert_eq!(info.slam_text.unwrap().unit, TimeUnit::Milliseconds);
    assert_eq!(rec.source.cloud_path, Some(dir.path().join("run.ply")));
    attach_reference(&mut rec, &spec(gt_path)).unwrap();
    let c = convert(&rec, &ConvertOptions::default()).unwrap();
    assert!(max_matrix_diff(&c.transform(), &t_slam_world.inverse()) < 1e-6);
    for (k, p) in c.cloud.points.chunks_exact(3).enumerate() {
        let want = world[k] + Vector3::new(0.0, 0.0, 1.0);
        let d = (Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64) - want).norm();
        assert!(d < 1e-3, "{d}");
    }
    let text = c
        .report
        .reference_file
        .as_ref()
        .unwrap()
        .text
        .clone()
        .unwrap();
    assert_eq!((text.delimiter.as_str(), text.header), ("comma", true));
    // The wrong unit given: no pairs, and the error names both files.
    let forced = ReconstructionOptions {
        time_unit: Some(TimeUnit::Seconds),
        ..ReconstructionOptions::default()
    };
    let mut rec = read_reconstruction(&saved.join("run.txt"), &forced).unwrap();
    attach_reference(&mut rec, &spec(dir.path().join("gt.csv"))).unwrap();
    let Err(Error::Unmatched {
        slam_span,
        reference_span,
        cause,
        ..
    }) = convert(&rec, &ConvertOptions::default())
    else {
        panic!("expected Unmatched")
    };
    assert!(slam_span.contains("run.txt"), "{slam_span}");
    assert!(reference_span.contains("gt.csv"), "{reference_span}");
    assert!(cause.contains("milliseconds"), "{cause}");
}

#[test]
fn orbslam3_keyframes_in_nanoseconds_against_seconds_ground_truth() {
    let (Some(kf), Some(gt)) = (
        data("euroc_mh01_orbslam3_mono", "kf_dataset-MH01_mono.txt"),
        data("euroc_mh01_orbslam3_mono", "MH_01_easy.txt"),
    ) else {
        return;
    };
    let opts = ConvertOptions::default();
    let src = open_input(
        &kf,
        &opts.read,
        &ReconstructionOptions::default(),
        Some(&spec(gt)),
    )
    .unwrap();
    let c = convert_source(&*src, &opts).unwrap();
    let r = &c.report;
    let text = r.reconstruction.as_ref().unwrap().text.as_ref().unwrap();
    assert_eq!((text.unit.as_str(), text.unit_detected), ("ns", true));
    // evo 1.38.1 -as, max_diff 0.01 s (PROVENANCE.md): 352/363 pairs,
    // scale 5.148581120866326, rmse 0.047964 m.
    let ape = r.ape.as_ref().unwrap();
    assert_eq!((r.keyframes, ape.n_pairs), (363, 352));
    assert!((c.transform().scale / 5.148581120866326 - 1.0).abs() < 1e-9);
    assert!((ape.rmse - 0.047964).abs() < 5e-7, "{}", ape.rmse);
}

#[test]
fn cli_converts_a_reconstruction_and_says_the_unit() {
    let (Some(kf), Some(gt)) = (
        data("euroc_mh01_orbslam3_mono", "kf_dataset-MH01_mono.txt"),
        data("euroc_mh01_orbslam3_mono", "MH_01_easy.txt"),
    ) else {
        return;
    };
    let out = tempfile::tempdir().unwrap();
    let o = bin(&[
        "convert",
        kf.to_str().unwrap(),
        "--reference",
        gt.to_str().unwrap(),
        "-o",
        out.path().to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("stamps in ns (detected)"), "{text}");
    assert!(text.contains("paired by time"), "{text}");
    assert!(out.path().join(TRAJECTORY_TUM).is_file());
    // --reference-format names on a pose file: a parse error, exit 1.
    let o = bin(&[
        "convert",
        kf.to_str().unwrap(),
        "--reference",
        gt.to_str().unwrap(),
        "--reference-format",
        "names",
        "-o",
        out.path().to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    // An unknown format is a usage error.
    let o = bin(&[
        "convert",
        kf.to_str().unwrap(),
        "--reference",
        gt.to_str().unwrap(),
        "--reference-format",
        "ply",
        "-o",
        out.path().to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
}
