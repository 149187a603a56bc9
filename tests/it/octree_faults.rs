//! Octree faults a hostile input brings (issue 17): rays whose `f32` length
//! underflows or overflows (OctoMap's tracer never ends on them), a tiny
//! `.bt` whose one leaf is 2^45 voxels, `.bt` headers whose declared size
//! the data cannot hold. Every call here must return; a watchdog turns a
//! hang into a failure naming the case.

use std::collections::BTreeMap;
use std::sync::mpsc;
use std::time::Duration;

use slam2world::error::Error;
use slam2world::map::{MapParams, OccupancyMap, VoxelState};

/// Runs `f` on another thread and fails (naming `what`) when it has not
/// returned within `secs` seconds: a guard against hangs, far above any
/// real run time, not a timing assertion.
fn returns<T: Send + 'static>(what: &str, secs: u64, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    match rx.recv_timeout(Duration::from_secs(secs)) {
        Ok(v) => v,
        Err(_) => panic!("{what} did not return within {secs} s"),
    }
}

fn map(res: f64, max_range: Option<f64>) -> OccupancyMap {
    OccupancyMap::try_new(MapParams {
        max_range,
        ..MapParams::new(res)
    })
    .unwrap()
}

/// The point of issue 17: a ray of length 1.4e-30 m that crosses the face
/// x = 0. Its squared length underflows to 0 in `f32`.
const TINY: [f32; 3] = [-1e-30, 1e-30, 0.0];

#[test]
fn tiny_ray_returns_and_marks_its_two_voxels() {
    for max_range in [None, Some(5.0)] {
        for parallel in [true, false] {
            let m = returns("tiny ray", 60, move || {
                let mut m = map(0.1, max_range);
                let u = if parallel {
                    m.insert_scan(&TINY, [0.0; 3]).unwrap()
                } else {
                    m.insert_scan_sequential(&TINY, [0.0; 3]).unwrap()
                };
                assert_eq!((u.free, u.occupied), (1, 1));
                m
            });
            // The end voxel (x < 0) occupied, the origin voxel free.
            assert_eq!(m.state([-0.05, 0.05, 0.05]), VoxelState::Occupied);
            assert_eq!(m.state([0.05, 0.05, 0.05]), VoxelState::Free);
            m.check_invariants().unwrap();
        }
    }
}

#[test]
fn tiny_rays_return_through_insert_keyframes() {
    let m = returns("insert_keyframes", 60, || {
        let mut m = map(0.1, Some(10.0));
        let pts = [TINY, [1e-40, -1e-40, 1e-40], [0.0; 3]].concat();
        let origins = BTreeMap::from([(3, [0.0f32; 3]), (4, [-1e-41, 0.0, 0.0])]);
        m.insert_keyframes(&pts, &[3, 3, 4], &origins).unwrap();
        m
    });
    assert_eq!(m.state([-0.05, 0.05, 0.05]), VoxelState::Occupied);
}

/// A ray case: origin, point, resolution, max range.
type Case = ([f32; 3], [f32; 3], f64, Option<f64>);

#[test]
fn zero_denormal_and_huge_rays_return() {
    let cases: Vec<Case> = vec![
        ([0.0; 3], [0.0; 3], 0.1, None),                    // zero length
        ([0.0; 3], [-0.0, 0.0, -0.0], 0.1, Some(1.0)),      // signed zeros
        ([-1e-45, 0.0, 0.0], [1e-45, 0.0, 0.0], 0.1, None), // denormal, across x = 0
        ([0.0; 3], [1e-38, -1e-38, 1e-38], 0.1, Some(2.0)), // below f32::MIN_POSITIVE²
        ([0.0; 3], [3000.0, -3000.0, 3000.0], 0.1, None),   // 52 000 voxels
        ([0.0; 3], [1e30, 1e30, -1e30], 0.1, None),         // end outside the tree
        ([0.0; 3], [1e30, 1e30, -1e30], 0.1, Some(3.0)),    // cut to 3 m
        ([-3e38, 0.0, 0.0], [3e38, 1.0, 0.0], 1e35, None),  // f32 difference overflows
        ([-3e38, 0.0, 0.0], [3e38, 1.0, 0.0], 1e35, Some(2e36)), // and its max range
    ];
    for (i, (o, p, res, max_range)) in cases.into_iter().enumerate() {
        let (m, u) = returns(&format!("case {i}"), 120, move || {
            let mut m = map(res, max_range);
            let u = m.insert_scan(&p, o).unwrap();
            let mut s = map(res, max_range);
            let us = s.insert_scan_sequential(&p, o).unwrap();
            assert_eq!(u, us, "case {i}");
            assert!(m == s, "case {i}");
            (m, u)
        });
        m.check_invariants().unwrap();
        match i {
            0 | 1 => assert_eq!((u.free, u.occupied), (0, 1), "case {i}"),
            2 | 3 => assert_eq!(u.occupied, 1, "case {i}"),
            4 => assert!(u.free > 50_000 && u.occupied == 1, "case {i}: {u:?}"),
            5 => assert_eq!((u.free, u.occupied), (0, 0), "case {i}"),
            6 => {
                // 3 m along the diagonal cleared, nothing occupied.
                assert!(u.free > 25 && u.occupied == 0, "case {i}: {u:?}");
                let d = 2.5 / 3f64.sqrt();
                assert_eq!(m.state([d, d, -d]), VoxelState::Free);
            }
            7 => assert!(u.free > 5 && u.occupied == 1, "case {i}: {u:?}"),
            _ => assert!(u.free > 5 && u.occupied == 0, "case {i}: {u:?}"),
        }
    }
}

/// A `.bt` file of the given header size line and data bytes.
fn bt(size: &str, data: &[u8]) -> Vec<u8> {
    let mut b = format!("# Octomap OcTree binary file\nid OcTree\nsize {size}\nres 0.1\ndata\n")
        .into_bytes();
    b.extend_from_slice(data);
    b
}

fn read(bytes: &[u8]) -> slam2world::error::Result<OccupancyMap> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.bt");
    std::fs::write(&path, bytes).unwrap();
    OccupancyMap::read_bt(&path, MapParams::new(0.1))
}

#[test]
fn one_leaf_near_the_root_is_counted_not_expanded() {
    // The root's child 0 is an occupied leaf at depth 1: 2^15 voxels an edge.
    let m = read(&bt("2", &[0b10, 0])).unwrap();
    assert_eq!(m.count_voxels(VoxelState::Occupied), 1 << 45);
    assert_eq!(m.count_voxels(VoxelState::Free), 0);
    let leaves = m.leaves(VoxelState::Occupied);
    assert_eq!(leaves, vec![([-1638.4, -1638.4, -1638.4], 3276.8)]);
    match m.try_voxel_centers(VoxelState::Occupied, 1 << 24) {
        Err(Error::TooLarge { count, limit, what }) => {
            assert_eq!((count, limit), (1 << 45, 1 << 24));
            assert!(what.contains("occupied"), "{what}");
        }
        other => panic!("{:?}", other.map(|v| v.len())),
    }
    assert!(m.try_voxel_centers(VoxelState::Free, 0).unwrap().is_empty());
    // A small leaf expands as before.
    let mut small = map(0.1, None);
    small
        .insert_scan(&[0.05, 0.05, 0.05], [0.35, 0.05, 0.05])
        .unwrap();
    let c = small.try_voxel_centers(VoxelState::Free, 3).unwrap();
    assert_eq!(c.len(), 3);
    assert_eq!(c, small.voxel_centers(VoxelState::Free));
    assert!(small.try_voxel_centers(VoxelState::Free, 2).is_err());
}

#[test]
fn declared_sizes_are_checked_against_the_data() {
    // More nodes than 2 data bytes can describe: refused before reading.
    match read(&bt("1000000000000", &[0b10, 0])) {
        Err(Error::Parse { reason, .. }) => {
            assert!(
                reason.contains("1000000000000") && reason.contains("2 data bytes"),
                "{reason}"
            )
        }
        other => panic!("{other:?}"),
    }
    // A size the tree does not have (OctoMap's readBinary refuses it too).
    match read(&bt("5", &[0b10, 0])) {
        Err(Error::Parse { reason, .. }) => assert!(reason.contains("holds 2 nodes"), "{reason}"),
        other => panic!("{other:?}"),
    }
    // A node cut short names its byte offset from the start of the file.
    let b = bt("3", &[0b11, 0, 0b10]);
    let header = b.len() - 3;
    match read(&b) {
        Err(Error::Parse { reason, .. }) => {
            assert!(reason.contains(&format!("byte {}", header + 2)), "{reason}")
        }
        other => panic!("{other:?}"),
    }
    // Resolutions that give no finite tree.
    let mut b = bt("0", &[]);
    let s = String::from_utf8(b.clone())
        .unwrap()
        .replace("res 0.1", "res 1e-320");
    b = s.into_bytes();
    assert!(read(&b).is_err());
    assert!(OccupancyMap::try_new(MapParams::new(1e305)).is_err());
    assert!(read(&bt("0", &[])).unwrap().num_nodes() == 0);
}
