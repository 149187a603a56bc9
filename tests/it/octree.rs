//! Occupancy octree: invariants, key math, determinism across thread counts,
//! file round trips and planner queries on a scene of cubes on a plane.

use std::collections::BTreeMap;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slam2world::map::{MapParams, OccupancyMap, VoxelState};

/// Axis-aligned cubes `(centre, half edge)` standing on the plane z = 0. The
/// first one's side faces lie mid-voxel at 0.1 m so that their voxels are certain.
const CUBES: [([f64; 3], f64); 3] = [
    ([2.0, 0.0, 0.45], 0.45),
    ([-2.0, 2.0, 0.75], 0.75),
    ([0.0, -3.0, 0.4], 0.4),
];

/// First hit of the ray `o + t d` with the plane z = 0 or a cube (slab test).
fn cast(o: [f64; 3], d: [f64; 3]) -> Option<[f64; 3]> {
    let mut best = f64::INFINITY;
    if d[2] < 0.0 {
        best = -o[2] / d[2];
    }
    for (c, h) in CUBES {
        let (mut tn, mut tf) = (f64::NEG_INFINITY, f64::INFINITY);
        for i in 0..3 {
            let (a, b) = ((c[i] - h - o[i]) / d[i], (c[i] + h - o[i]) / d[i]);
            tn = tn.max(a.min(b));
            tf = tf.min(a.max(b));
        }
        if tn <= tf && tn > 0.0 && tn < best {
            best = tn;
        }
    }
    best.is_finite()
        .then(|| [0, 1, 2].map(|i| o[i] + best * d[i]))
}

/// Points a camera at `o` looking at `target` sees (`n × n` rays, 90° field of view).
fn camera_scan(o: [f64; 3], target: [f64; 3], n: usize) -> Vec<f32> {
    let f = nalgebra::Vector3::from(target) - nalgebra::Vector3::from(o);
    let f = f.normalize();
    let r = f.cross(&nalgebra::Vector3::z()).normalize();
    let u = f.cross(&r);
    let mut pts = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let a = (i as f64 + 0.5) / n as f64 * 2.0 - 1.0;
            let b = (j as f64 + 0.5) / n as f64 * 2.0 - 1.0;
            let d = (f + r * a + u * b).normalize();
            if let Some(p) = cast(o, [d.x, d.y, d.z]) {
                pts.extend(p.map(|v| v as f32));
            }
        }
    }
    pts
}

fn scene_scans(n: usize) -> Vec<([f32; 3], Vec<f32>)> {
    (0..6)
        .map(|k| {
            let a = k as f64 * std::f64::consts::TAU / 6.0;
            let o = [5.0 * a.cos(), 5.0 * a.sin(), 1.5];
            (o.map(|v| v as f32), camera_scan(o, [0.0, 0.0, 0.3], n))
        })
        .collect()
}

fn scene_map(resolution: f64) -> OccupancyMap {
    let mut m = OccupancyMap::try_new(MapParams::new(resolution)).unwrap();
    for (o, pts) in scene_scans(120) {
        m.insert_scan(&pts, o).unwrap();
    }
    m
}

fn random_scans(seed: u64, n_scans: usize, n_points: usize) -> Vec<([f32; 3], Vec<f32>)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..n_scans)
        .map(|_| {
            let o = [0, 1, 2].map(|_| rng.random_range(-1.0f32..1.0));
            let pts = (0..n_points * 3)
                .map(|_| rng.random_range(-4.0f32..4.0))
                .collect();
            (o, pts)
        })
        .collect()
}

#[test]
fn inner_nodes_hold_the_max_of_their_children_and_identical_children_are_pruned() {
    let mut m = OccupancyMap::try_new(MapParams::new(0.1)).unwrap();
    for (o, pts) in random_scans(1, 5, 3000) {
        m.insert_scan(&pts, o).unwrap();
        m.check_invariants().unwrap();
    }
    // Space seen often is clamped free and pruned into leaves larger than a voxel.
    let leaves = m.leaves(VoxelState::Free);
    assert!(leaves.iter().any(|(_, s)| *s > 0.1 + 1e-9));
    let voxels = m.voxel_centers(VoxelState::Free).len();
    let free_leaves = leaves.len();
    assert!(
        voxels > free_leaves,
        "{voxels} voxels in {free_leaves} leaves"
    );
    // The root holds the largest log-odds of the map.
    let max_leaf = (m.leaves(VoxelState::Occupied).iter())
        .filter_map(|(c, _)| m.occupancy(*c))
        .fold(0.0f64, f64::max);
    let root = slam2world::map::probability(m.root_logodds().unwrap());
    assert!(
        (root - max_leaf).abs() < 1e-12,
        "root {root} max leaf {max_leaf}"
    );
}

#[test]
fn keys_at_negative_coordinates_and_voxel_boundaries() {
    let m = OccupancyMap::try_new(MapParams::new(0.1)).unwrap();
    assert_eq!(m.key_of([0.0, 0.0, 0.0]), Some([32768; 3]));
    assert_eq!(m.key_of([-0.05, -1e-9, -0.1]), Some([32767; 3]));
    assert_eq!(
        m.key_of([-0.1000001, 0.0999999, 0.1]),
        Some([32766, 32768, 32769])
    );
    let c = m.key_center([32767, 32768, 0]);
    assert!((c[0] + 0.05).abs() < 1e-12 && (c[1] - 0.05).abs() < 1e-12);
    assert!((c[2] - (-32768.0 + 0.5) * 0.1).abs() < 1e-9);
    assert_eq!(m.key_of([3276.8, 0.0, 0.0]), None);
    assert_eq!(m.key_of([-3276.8, 0.0, 0.0]), Some([0, 32768, 32768]));
    assert_eq!(m.state([1e6, 0.0, 0.0]), VoxelState::Unknown);

    // A scan from the origin towards negative x marks the voxel of the point.
    let mut m = OccupancyMap::try_new(MapParams::new(0.1)).unwrap();
    m.insert_scan(&[-0.95, -0.05, -0.05], [0.05, -0.05, -0.05])
        .unwrap();
    assert_eq!(m.state([-0.95, -0.05, -0.05]), VoxelState::Occupied);
    assert_eq!(m.state([-0.85, -0.05, -0.05]), VoxelState::Free);
    assert_eq!(m.state([0.05, -0.05, -0.05]), VoxelState::Free);
    assert_eq!(m.state([-1.05, -0.05, -0.05]), VoxelState::Unknown);
    assert_eq!(m.state([-0.95, 0.05, -0.05]), VoxelState::Unknown);
    let p = m.occupancy([-0.95, -0.05, -0.05]).unwrap();
    assert!((p - 0.7).abs() < 1e-6, "one hit gives prob_hit, got {p}");
}

#[test]
fn max_range_truncates_the_free_ray_and_marks_no_endpoint() {
    let mut p = MapParams::new(0.1);
    p.max_range = Some(1.0);
    let mut m = OccupancyMap::try_new(p).unwrap();
    m.insert_scan(&[3.05, 0.05, 0.05], [0.05, 0.05, 0.05])
        .unwrap();
    assert_eq!(m.state([3.05, 0.05, 0.05]), VoxelState::Unknown);
    assert_eq!(m.state([0.55, 0.05, 0.05]), VoxelState::Free);
    assert_eq!(m.state([0.95, 0.05, 0.05]), VoxelState::Free);
    assert_eq!(m.state([1.25, 0.05, 0.05]), VoxelState::Unknown);
}

#[test]
fn occupied_wins_over_free_within_a_scan() {
    let mut m = OccupancyMap::try_new(MapParams::new(0.1)).unwrap();
    // The second ray passes through the first one's endpoint voxel.
    m.insert_scan(&[1.05, 0.05, 0.05, 2.05, 0.05, 0.05], [0.05, 0.05, 0.05])
        .unwrap();
    assert_eq!(m.state([1.05, 0.05, 0.05]), VoxelState::Occupied);
    let p = m.occupancy([1.05, 0.05, 0.05]).unwrap();
    assert!((p - 0.7).abs() < 1e-6);
    // Each voxel is updated once per scan: two rays through a voxel give one miss.
    let q = m.occupancy([0.55, 0.05, 0.05]).unwrap();
    assert!((q - 0.4).abs() < 1e-6, "got {q}");
}

#[test]
#[ignore = "slow: make test runs it"]
fn parallel_insertion_equals_sequential_for_any_thread_count() {
    let scans = random_scans(7, 4, 5000);
    let mut seq = OccupancyMap::try_new(MapParams::new(0.05)).unwrap();
    for (o, pts) in &scans {
        seq.insert_scan_sequential(pts, *o).unwrap();
    }
    assert!(seq.num_leaf_nodes() > 1000);
    for threads in 1..=4 {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let par = pool.install(|| {
            let mut m = OccupancyMap::try_new(MapParams::new(0.05)).unwrap();
            for (o, pts) in &scans {
                m.insert_scan(pts, *o).unwrap();
            }
            m
        });
        assert!(par == seq, "{threads} threads differ from sequential");
        assert_eq!(par.to_ot_bytes(), seq.to_ot_bytes());
    }
}

#[test]
fn keyframe_insertion_uses_each_keyframes_camera_centre() {
    let scans = random_scans(3, 3, 500);
    let mut by_scan = OccupancyMap::try_new(MapParams::new(0.1)).unwrap();
    for (o, pts) in &scans {
        by_scan.insert_scan(pts, *o).unwrap();
    }
    // Points of keyframes 10, 20, 30 interleaved; ids ascending = scan order.
    let mut points = Vec::new();
    let mut ids = Vec::new();
    for i in 0..500 {
        for (k, (_, pts)) in scans.iter().enumerate() {
            points.extend_from_slice(&pts[3 * i..3 * i + 3]);
            ids.push(10 * (k as i32 + 1));
        }
    }
    let origins: BTreeMap<i32, [f32; 3]> = (0..3)
        .map(|k| (10 * (k + 1), scans[k as usize].0))
        .collect();
    let mut by_kf = OccupancyMap::try_new(MapParams::new(0.1)).unwrap();
    by_kf.insert_keyframes(&points, &ids, &origins).unwrap();
    assert!(by_kf == by_scan);
    let mut missing = origins.clone();
    missing.remove(&20);
    let err = by_kf.insert_keyframes(&points, &ids, &missing).unwrap_err();
    assert!(err.to_string().contains("20"), "{err}");
}

#[test]
#[ignore = "slow: make test runs it"]
fn bt_round_trip_keeps_every_voxel_state() {
    let m = scene_map(0.1);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("map.bt");
    m.write_bt(&path).unwrap();
    let r = OccupancyMap::read_bt(&path, MapParams::new(1.0)).unwrap();
    assert_eq!(r.resolution(), 0.1);
    for state in [VoxelState::Free, VoxelState::Occupied] {
        let leaves = m.leaves(state);
        assert!(!leaves.is_empty());
        for (c, _) in &leaves {
            assert_eq!(r.state(*c), state, "at {c:?}");
        }
        assert_eq!(r.voxel_centers(state).len(), m.voxel_centers(state).len());
    }
    // Writing the read map again gives the same bytes.
    assert_eq!(r.to_bt_bytes(), m.to_bt_bytes());
    let text = String::from_utf8_lossy(&m.to_bt_bytes()[..200]).to_string();
    assert!(text.starts_with("# Octomap OcTree binary file\n"));
    assert!(text.contains("\nid OcTree\n") && text.contains("\nres 0.1\ndata\n"));
}

#[test]
fn ot_file_holds_every_node() {
    let m = scene_map(0.2);
    let bytes = m.to_ot_bytes();
    let head = format!(
        "# Octomap OcTree file\n# (feel free to add / change comments, but leave the first line as it is!)\n#\nid OcTree\nsize {}\nres 0.2\ndata\n",
        m.num_nodes()
    );
    assert!(bytes.starts_with(head.as_bytes()));
    assert_eq!(bytes.len(), head.len() + 5 * m.num_nodes());
    // The first node is the root: its log-odds, then its child mask.
    let v = f32::from_le_bytes(bytes[head.len()..head.len() + 4].try_into().unwrap());
    assert_eq!(Some(v), m.root_logodds());
}

#[test]
fn bad_files_and_inputs_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.bt");
    std::fs::write(&p, b"not an octree\n").unwrap();
    assert!(matches!(
        OccupancyMap::read_bt(&p, MapParams::new(0.1)),
        Err(slam2world::Error::Parse { .. })
    ));
    std::fs::write(
        &p,
        b"# Octomap OcTree binary file\nid OcTree\nsize 5\nres 0.1\ndata\n\xff",
    )
    .unwrap();
    assert!(matches!(
        OccupancyMap::read_bt(&p, MapParams::new(0.1)),
        Err(slam2world::Error::Parse { .. })
    ));
    assert!(matches!(
        OccupancyMap::read_bt(&dir.path().join("missing.bt"), MapParams::new(0.1)),
        Err(slam2world::Error::Io { .. })
    ));
    assert!(OccupancyMap::try_new(MapParams::new(0.0)).is_err());
    let mut m = OccupancyMap::try_new(MapParams::new(0.1)).unwrap();
    assert!(matches!(
        m.insert_scan(&[0.0, f32::NAN, 1.0], [0.0; 3]),
        Err(slam2world::Error::NonFinite { .. })
    ));
    assert!(matches!(
        m.insert_scan(&[0.0, 1.0], [0.0; 3]),
        Err(slam2world::Error::ShapeMismatch { .. })
    ));
    assert!(m.collides_sphere([0.0; 3], -1.0).is_err());
}

#[test]
fn scene_of_cubes_marks_cubes_occupied_and_space_in_front_free() {
    let m = scene_map(0.1);
    m.check_invariants().unwrap();
    // Cube 0 spans x in [1.55, 2.45]; cameras on a circle of radius 5 see its faces.
    assert_eq!(m.state([1.55, 0.05, 0.55]), VoxelState::Occupied);
    assert_eq!(m.state([2.45, 0.05, 0.55]), VoxelState::Occupied);
    assert_eq!(m.state([1.25, 0.05, 0.55]), VoxelState::Free);
    assert_eq!(m.state([3.05, 0.05, 0.55]), VoxelState::Free);
    // Inside the cube nothing is observed.
    assert_eq!(m.state([2.05, 0.05, 0.55]), VoxelState::Unknown);
    // The ground in view is occupied, the air above it free.
    // (ground points at z = 0 fall in the voxel above or, rounded, below it)
    let ground = [m.state([3.55, 1.05, 0.05]), m.state([3.55, 1.05, -0.05])];
    assert!(ground.contains(&VoxelState::Occupied), "{ground:?}");
    assert_eq!(m.state([3.55, 1.05, 0.55]), VoxelState::Free);

    // Planner queries: through the cube collides, beside it is free.
    assert!(!m
        .segment_is_free([1.0, 0.0, 0.6], [3.0, 0.0, 0.6], 0.0)
        .unwrap());
    assert!(m
        .segment_is_free([1.0, 1.2, 0.6], [3.0, 1.2, 0.6], 0.0)
        .unwrap());
    assert!(!m
        .segment_is_free([1.0, 1.2, 0.6], [3.0, 1.2, 0.6], 0.8)
        .unwrap());
    assert!(m
        .segment_is_free([1.0, 1.2, 0.6], [3.0, 1.2, 0.6], 0.3)
        .unwrap());
    assert!(m.collides_sphere([1.3, 0.0, 0.6], 0.3).unwrap());
    assert!(!m.collides_sphere([1.0, 0.0, 0.6], 0.3).unwrap());
    assert!(m.collides_box([2.0, 0.8, 0.6], [0.2, 0.4, 0.2]).unwrap());
    assert!(!m.collides_box([2.0, 1.2, 0.6], [0.2, 0.2, 0.2]).unwrap());

    // A ray towards the cube stops at its first face voxel.
    let hit = m
        .cast_ray([0.05, 0.05, 0.55], [1.0, 0.0, 0.0], Some(10.0), true)
        .unwrap()
        .unwrap();
    assert!(
        (hit[0] - 1.55).abs() < 1e-9 && (hit[2] - 0.55).abs() < 1e-9,
        "{hit:?}"
    );
    let miss = m
        .cast_ray([0.05, 1.25, 0.55], [1.0, 0.0, 0.0], Some(3.0), true)
        .unwrap();
    assert_eq!(miss, None);
}

#[test]
fn points_outside_the_tree_and_huge_ranges_are_skipped_like_octomap() {
    let mut p = MapParams::new(0.1);
    p.max_range = Some(1e30);
    let mut m = OccupancyMap::try_new(p).unwrap();
    // 1e5 m lies outside a 0.1 m tree (±3276.8 m): no ray, no endpoint.
    m.insert_scan(&[1e5, 0.0, 0.0, 1.05, 0.05, 0.05], [0.05, 0.05, 0.05])
        .unwrap();
    assert_eq!(m.state([1.05, 0.05, 0.05]), VoxelState::Occupied);
    assert_eq!(m.state([2.05, 0.05, 0.05]), VoxelState::Unknown);
    m.check_invariants().unwrap();
}
