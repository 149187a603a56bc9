//! The 2-D grid: a hand-built octree (known boxes written as a `.bt` file, so
//! that leaves are pruned exactly where the test says) projects to exactly
//! the cells a voxel-by-voxel projection of the same boxes gives; band limits,
//! coarser cells, refusals; random maps against per-voxel queries and across
//! thread counts; the nav2 files and grid messages of one grid.

use std::collections::BTreeMap;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slam2world::error::Error;
use slam2world::io::mcap::grid_msgs::{self, CellValues};
use slam2world::io::mcap::WorldFlavor;
use slam2world::io::nav2;
use slam2world::map::{logodds, probability, Grid2d, MapParams, OccupancyMap, VoxelState};

const RES: f64 = 0.1;

/// A leaf of the hand-built tree: depth (16 = one voxel), lowest key, occupied.
#[derive(Clone, Copy, Debug)]
struct Leaf {
    depth: u32,
    key: [u32; 3],
    occupied: bool,
}

impl Leaf {
    fn edge(&self) -> u32 {
        1 << (16 - self.depth)
    }
    fn contains(&self, depth: u32, key: [u32; 3]) -> bool {
        let n = 1u32 << (16 - depth);
        (0..3).all(|i| key[i] <= self.key[i] && self.key[i] + self.edge() <= key[i] + n)
    }
}

/// The `.bt` bytes (OctoMap's binary format: per inner node two bytes, two
/// bits per child, `01` free leaf, `10` occupied leaf, `11` inner, `00`
/// unknown) of a tree holding exactly `leaves` (disjoint, aligned).
fn bt_bytes(leaves: &[Leaf]) -> Vec<u8> {
    fn node(leaves: &[Leaf], depth: u32, key: [u32; 3], out: &mut Vec<u8>, count: &mut usize) {
        let half = 1u32 << (15 - depth);
        let mut bits = [0u8; 2];
        let mut inner = Vec::new();
        for i in 0..8 {
            let k = [
                key[0] + if i & 1 != 0 { half } else { 0 },
                key[1] + if i & 2 != 0 { half } else { 0 },
                key[2] + if i & 4 != 0 { half } else { 0 },
            ];
            let code = if let Some(l) = leaves.iter().find(|l| l.depth == depth + 1 && l.key == k) {
                if l.occupied {
                    0b10
                } else {
                    0b01
                }
            } else if leaves.iter().any(|l| l.contains(depth + 1, k)) {
                inner.push(k);
                0b11
            } else {
                0b00
            };
            if code != 0 {
                *count += 1;
            }
            bits[i / 4] |= code << (2 * (i % 4));
        }
        out.extend_from_slice(&bits);
        for k in inner {
            node(leaves, depth + 1, k, out, count);
        }
    }
    let mut data = Vec::new();
    let mut count = 1;
    node(leaves, 0, [0; 3], &mut data, &mut count);
    let mut out =
        format!("# Octomap OcTree binary file\nid OcTree\nsize {count}\nres {RES}\ndata\n")
            .into_bytes();
    out.extend(data);
    out
}

fn read_bt(bytes: &[u8]) -> slam2world::error::Result<OccupancyMap> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("map.bt");
    std::fs::write(&path, bytes).unwrap();
    OccupancyMap::read_bt(&path, MapParams::new(RES))
}

/// Centre height of the voxel layer `i` (0: the layer just above z = 0), as
/// the octree computes it.
fn c(i: i32) -> f64 {
    (f64::from(i) + 0.5) * RES
}

/// Lowest key of the voxel whose lower corner is at `metres` along an axis.
fn k(metres: f64) -> u32 {
    ((metres / RES).round() as i64 + 32768) as u32
}

/// The boxes of the hand-built map, in metres by their lower corners.
fn boxes() -> Vec<Leaf> {
    let leaf = |depth, x: f64, y: f64, z: f64, occupied| Leaf {
        depth,
        key: [k(x), k(y), k(z)],
        occupied,
    };
    vec![
        // A pruned occupied 4x4x4 block: x, y in [0, 0.4), z in [0, 0.4).
        leaf(14, 0.0, 0.0, 0.0, true),
        // A pruned free 8x8x8 block beside it: x [0.8, 1.6), y [0, 0.8), z [0, 0.8).
        leaf(13, 0.8, 0.0, 0.0, false),
        // One column: a free voxel under an occupied one (the cell is occupied,
        // top at the occupied one's centre 0.35), and a free one above the band.
        leaf(16, 0.1, 0.7, 0.1, false),
        leaf(16, 0.1, 0.7, 0.3, true),
        leaf(16, 0.1, 0.7, 1.2, false),
        // An occupied voxel only above the band: its cell stays unknown.
        leaf(16, 0.5, 0.5, 1.5, true),
        // An occupied voxel below the band, under a free one in it.
        leaf(16, 0.6, 0.6, -0.3, true),
        leaf(16, 0.6, 0.6, 0.2, false),
        // Negative coordinates: a free 2x2x2 block and an occupied voxel.
        leaf(15, -0.8, -0.6, 0.0, false),
        leaf(16, -0.3, -0.1, 0.5, true),
        // A voxel whose centre (0.95) lies exactly on z_max of the band.
        leaf(16, 0.3, 0.5, 0.9, true),
    ]
}

/// Expected cells by brute force over every voxel of `leaves`: the column
/// `(kx / f, ky / f)` (cells of `f` voxels, aligned to world multiples) gets
/// the largest log-odds of its voxels with centre in `[z_min, z_max]` and the
/// highest occupied centre.
fn brute_force(
    leaves: &[Leaf],
    z_min: f64,
    z_max: f64,
    f: i64,
) -> BTreeMap<(i64, i64), (f32, Option<f64>)> {
    let (occ, free) = (logodds(0.971), logodds(0.1192));
    let mut out: BTreeMap<(i64, i64), (f32, Option<f64>)> = BTreeMap::new();
    for l in leaves {
        for dx in 0..l.edge() {
            for dy in 0..l.edge() {
                for dz in 0..l.edge() {
                    let v = [l.key[0] + dx, l.key[1] + dy, l.key[2] + dz].map(|k| k as i64 - 32768);
                    let zc = (v[2] as f64 + 0.5) * RES;
                    if zc < z_min || zc > z_max {
                        continue;
                    }
                    let value = if l.occupied { occ } else { free };
                    let e = out
                        .entry((v[0].div_euclid(f), v[1].div_euclid(f)))
                        .or_insert((f32::NEG_INFINITY, None));
                    e.0 = e.0.max(value);
                    if l.occupied {
                        e.1 = Some(e.1.map_or(zc, |t: f64| t.max(zc)));
                    }
                }
            }
        }
    }
    out
}

/// Checks `grid` cell by cell against the brute-force projection.
fn assert_matches(grid: &Grid2d, expected: &BTreeMap<(i64, i64), (f32, Option<f64>)>, f: i64) {
    let cell = RES * f as f64;
    let lo = (
        expected.keys().map(|c| c.0).min().unwrap(),
        expected.keys().map(|c| c.1).min().unwrap(),
    );
    let hi = (
        expected.keys().map(|c| c.0).max().unwrap(),
        expected.keys().map(|c| c.1).max().unwrap(),
    );
    assert_eq!(grid.width as i64, hi.0 - lo.0 + 1);
    assert_eq!(grid.height as i64, hi.1 - lo.1 + 1);
    assert!((grid.origin[0] - lo.0 as f64 * cell).abs() < 1e-12);
    assert!((grid.origin[1] - lo.1 as f64 * cell).abs() < 1e-12);
    assert!((grid.resolution - cell).abs() < 1e-15);
    for row in 0..grid.height {
        for col in 0..grid.width {
            let i = grid.index(col, row).unwrap();
            let key = (lo.0 + col as i64, lo.1 + row as i64);
            let (p, z) = (grid.probability[i], grid.top_z[i]);
            match expected.get(&key) {
                None => assert!(p.is_nan() && z.is_nan(), "cell {key:?}: {p} {z}"),
                Some((l, top)) => {
                    assert_eq!(p, probability(*l) as f32, "cell {key:?}");
                    match top {
                        Some(t) => {
                            assert!((f64::from(z) - t).abs() < 1e-6, "cell {key:?}: {z} {t}")
                        }
                        None => assert!(z.is_nan(), "cell {key:?}: {z}"),
                    }
                }
            }
        }
    }
}

#[test]
fn hand_built_octree_projects_to_the_expected_cells() {
    let leaves = boxes();
    let map = read_bt(&bt_bytes(&leaves)).unwrap();
    // The file's leaves are the boxes, pruned where they are blocks.
    assert_eq!(map.leaves(VoxelState::Occupied).len(), 6);
    let (z_min, z_max) = (c(0), c(9));
    let g = map.grid(z_min, z_max, None).unwrap();
    let expected = brute_force(&leaves, z_min, z_max, 1);
    assert_matches(&g, &expected, 1);

    // Spot checks written out: the pruned block occupied up to its highest
    // voxel in the band (centre 0.35), the free block free, the mixed
    // column occupied with its top at 0.35, the voxel above the band unseen,
    // the voxel centred on z_max counted.
    let at = |x: f64, y: f64| {
        let (c, r) = g.cell_of(x, y).unwrap();
        let i = g.index(c, r).unwrap();
        (g.probability[i], g.top_z[i])
    };
    let (p, z) = at(0.15, 0.15);
    assert!(p > 0.97 && (z - 0.35).abs() < 1e-6);
    let (p, z) = at(1.25, 0.45);
    assert!(p < 0.12 && z.is_nan());
    let (p, z) = at(0.15, 0.75);
    assert!(p > 0.97 && (z - 0.35).abs() < 1e-6);
    assert!(at(0.55, 0.55).0.is_nan());
    let (p, z) = at(0.65, 0.65);
    assert!(p < 0.12 && z.is_nan());
    let (p, z) = at(0.35, 0.55);
    assert!(p > 0.97 && (z - 0.95).abs() < 1e-6);
    assert!(g.origin[0] < -0.75 && g.origin[1] < -0.55);
}

#[test]
fn band_limits_are_inclusive_on_voxel_centres() {
    let leaves = boxes();
    let map = read_bt(&bt_bytes(&leaves)).unwrap();
    for (z_min, z_max) in [
        (c(0), c(9)),
        (c(0) + 1e-7, c(9) - 1e-7), // both end layers out
        (c(3), c(3)),               // one layer
        (c(-3), c(15)),             // everything
        (c(3) + 0.01, c(4) - 0.01), // between two centres: nothing
        (c(15), c(15)),             // only the voxel above the band
    ] {
        let g = map.grid(z_min, z_max, None).unwrap();
        let expected = brute_force(&leaves, z_min, z_max, 1);
        if expected.is_empty() {
            assert!(g.is_empty() && g.probability.is_empty(), "{z_min} {z_max}");
        } else {
            assert_matches(&g, &expected, 1);
        }
    }
}

#[test]
fn coarser_cells_take_the_most_occupied_voxel() {
    let leaves = boxes();
    let map = read_bt(&bt_bytes(&leaves)).unwrap();
    for f in [2i64, 3, 4, 8] {
        let g = map.grid(c(0), c(9), Some(RES * f as f64)).unwrap();
        assert_matches(&g, &brute_force(&leaves, c(0), c(9), f), f);
    }
}

#[test]
fn bad_arguments_are_refused_with_their_names() {
    let map = read_bt(&bt_bytes(&boxes())).unwrap();
    let name = |r: slam2world::error::Result<Grid2d>| match r {
        Err(Error::InvalidArgument { what, .. }) => what,
        other => panic!("expected an invalid argument, got {other:?}"),
    };
    assert_eq!(name(map.grid(1.0, 0.0, None)), "z_min");
    assert_eq!(name(map.grid(f64::NAN, 1.0, None)), "z_min");
    assert_eq!(name(map.grid(0.0, f64::INFINITY, None)), "z_max");
    assert_eq!(name(map.grid(0.0, 1.0, Some(0.05))), "resolution");
    assert_eq!(name(map.grid(0.0, 1.0, Some(0.25))), "resolution");
    assert_eq!(name(map.grid(0.0, 1.0, Some(-0.2))), "resolution");
    // Nothing known in a far band, or an empty map: an empty grid.
    assert!(map.grid(100.0, 200.0, None).unwrap().is_empty());
    let empty = OccupancyMap::try_new(MapParams::new(RES)).unwrap();
    assert!(empty.grid(0.0, 1.0, None).unwrap().is_empty());
    // A bound on the cells, checked before allocating.
    match map.grid_bounded(c(0), c(9), None, 10) {
        Err(Error::TooLarge { count, limit, .. }) => assert!(count > 10 && limit == 10),
        other => panic!("{other:?}"),
    }
}

#[test]
fn one_leaf_near_the_root_is_refused_at_fine_cells_and_fills_coarse_ones() {
    // A depth-1 occupied leaf: x, y, z in [-3276.8, 0).
    let leaves = [Leaf {
        depth: 1,
        key: [0, 0, 0],
        occupied: true,
    }];
    let map = read_bt(&bt_bytes(&leaves)).unwrap();
    match map.grid(-1.0, -0.5, None) {
        Err(Error::TooLarge { count, limit, .. }) => {
            assert_eq!((count, limit), (1 << 30, slam2world::map::MAX_GRID_CELLS))
        }
        other => panic!("{other:?}"),
    }
    let g = map.grid(-1.0, -0.5, Some(RES * 4096.0)).unwrap();
    assert_eq!((g.width, g.height), (8, 8));
    assert!(g.probability.iter().all(|&p| p > 0.97));
    assert!(g.top_z.iter().all(|&z| (z + 0.55).abs() < 1e-5));
}

/// Scans of random points around a few origins: a map with free and occupied
/// leaves at many depths.
fn random_map(seed: u64) -> OccupancyMap {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut map = OccupancyMap::try_new(MapParams {
        max_range: Some(4.0),
        ..MapParams::new(RES)
    })
    .unwrap();
    for _ in 0..4 {
        let o = [0, 1, 2].map(|_| rng.random_range(-1.0f32..1.0));
        let pts: Vec<f32> = (0..3000)
            .flat_map(|i| {
                let mut p = [0, 1, 2].map(|_| rng.random_range(-3.0f32..3.0));
                if i % 3 == 0 {
                    p[2] = -0.45; // a floor
                }
                p
            })
            .collect();
        map.insert_scan(&pts, o).unwrap();
    }
    map
}

#[test]
fn random_maps_match_per_voxel_queries() {
    let map = random_map(11);
    let (z_min, z_max) = (-0.5, 0.7);
    let g = map.grid(z_min, z_max, None).unwrap();
    assert!(g.width > 40 && g.height > 40);
    let mut n_occ = 0;
    for row in 0..g.height {
        for col in 0..g.width {
            let [x, y] = g.cell_center(col, row);
            let (mut best, mut top) = (None::<f32>, None::<f64>);
            let mut z = -0.45;
            while z <= z_max {
                if let Some(l) = map.logodds_at([x, y, z]) {
                    best = Some(best.map_or(l, |b| b.max(l)));
                    if l >= 0.0 {
                        top = Some(z);
                    }
                }
                z += RES;
            }
            let i = g.index(col, row).unwrap();
            match best {
                None => assert!(g.probability[i].is_nan(), "({col}, {row})"),
                Some(l) => assert_eq!(g.probability[i], probability(l) as f32, "({col}, {row})"),
            }
            match top {
                None => assert!(g.top_z[i].is_nan()),
                Some(t) => {
                    n_occ += 1;
                    assert!((f64::from(g.top_z[i]) - t).abs() < 1e-5, "({col}, {row})");
                }
            }
        }
    }
    assert!(n_occ > 100, "{n_occ} occupied cells");
}

#[test]
fn grid_is_the_same_on_one_thread_and_many() {
    let map = random_map(12);
    let grid_on = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| map.grid(-0.5, 0.7, None).unwrap())
    };
    let bits = |g: &Grid2d| {
        (
            g.width,
            g.height,
            g.origin.map(f64::to_bits),
            g.probability
                .iter()
                .map(|v| v.to_bits())
                .collect::<Vec<_>>(),
            g.top_z.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
        )
    };
    let one = grid_on(1);
    // The map has enough nodes for the parallel traversal (2^14) and enough
    // leaves in the band for the parallel fill (2^12).
    assert!(map.num_nodes() > 1 << 14, "{} nodes", map.num_nodes());
    let in_band = [VoxelState::Free, VoxelState::Occupied]
        .iter()
        .flat_map(|&s| map.leaves(s))
        .filter(|(c, size)| c[2] + 0.5 * size > -0.5 && c[2] - 0.5 * size < 0.7)
        .count();
    assert!(in_band > 1 << 12, "{in_band} leaves in the band");
    assert_eq!(bits(&one), bits(&grid_on(4)));
    assert_eq!(bits(&one), bits(&grid_on(3)));
}

#[test]
fn nav2_files_of_a_grid() {
    let map = read_bt(&bt_bytes(&boxes())).unwrap();
    let g = map.grid(c(0), c(9), None).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let files = nav2::write_nav2(&g, dir.path(), 0.5).unwrap();
    assert_eq!(files.image, dir.path().join("map.pgm"));
    let pgm = std::fs::read(&files.image).unwrap();
    let header = format!("P5\n{} {}\n255\n", g.width, g.height);
    assert!(pgm.starts_with(header.as_bytes()));
    let px = &pgm[header.len()..];
    assert_eq!(px.len(), g.width * g.height);
    // Image row 0 is the grid's top row (highest y).
    for row in 0..g.height {
        for col in 0..g.width {
            let p = g.probability[g.index(col, row).unwrap()];
            let want = if p.is_nan() {
                205
            } else if p >= 0.5 {
                0
            } else {
                254
            };
            assert_eq!(px[(g.height - 1 - row) * g.width + col], want);
        }
    }
    let yaml = std::fs::read_to_string(&files.yaml).unwrap();
    assert!(yaml.starts_with("image: map.pgm\nmode: trinary\nresolution: 0.1\n"));
    assert!(std::fs::read(&files.height)
        .unwrap()
        .starts_with(b"\x93NUMPY"));
    // Nothing else left in the folder (no temporary files).
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 3);
    let empty = map.grid(100.0, 101.0, None).unwrap();
    assert!(nav2::write_nav2(&empty, &dir.path().join("none"), 0.5).is_err());
    assert!(!dir.path().join("none.pgm").exists());
}

#[test]
fn grid_channels_per_flavour() {
    let map = read_bt(&bt_bytes(&boxes())).unwrap();
    let g = map.grid(c(0), c(9), None).unwrap();
    let fox = grid_msgs::grid_channels(&g, 2.0, "world", WorldFlavor::Foxglove).unwrap();
    assert_eq!(fox.len(), 1);
    assert_eq!(fox[0].schema.0, "foxglove.Grid");
    assert_eq!(fox[0].message_encoding, "protobuf");
    assert_eq!(
        fox[0].data,
        grid_msgs::foxglove_grid(&g, 2.0, "world").unwrap()
    );
    let ros = grid_msgs::grid_channels(&g, 2.0, "world", WorldFlavor::Ros2).unwrap();
    assert_eq!(ros[0].schema.0, "nav_msgs/msg/OccupancyGrid");
    assert_eq!(ros[0].message_encoding, "cdr");
    let cells = grid_msgs::occupancy_grid_data(&g, CellValues::Probability);
    assert!(ros[0]
        .data
        .ends_with(&cells.iter().map(|&v| v as u8).collect::<Vec<_>>()));
    assert_eq!(ros[0].topic, fox[0].topic);
}

/// A small run of the paper's scene over the whole path (every cube seen):
/// fewer frames, keyframes and pixels than the paper's.
fn scene_run() -> slam2world::sim::Simulation {
    let cfg = slam2world::sim::SimConfig {
        n_frames: 700,
        n_keyframes: 48,
        width: 160,
        height: 120,
        converge_start: 110,
        stable_start: 430,
        ..slam2world::sim::SimConfig::default()
    };
    slam2world::sim::simulate(&cfg).unwrap()
}

/// Distance (metres) in x-y from `(x, y)` to the footprint of the cube with
/// lower corner `c` and edge `e` (0 inside).
fn footprint_distance(c: &nalgebra::Vector3<f64>, e: f64, x: f64, y: f64) -> f64 {
    let dx = (c.x - x).max(x - (c.x + e)).max(0.0);
    let dy = (c.y - y).max(y - (c.y + e)).max(0.0);
    dx.hypot(dy)
}

#[test]
#[ignore = "slow: make test runs it"]
fn convert_grid_marks_the_cubes_occupied_and_the_plane_between_them_free() {
    use slam2world::io::mcap::{write_slam_log, SlamLogOptions};
    use slam2world::map::GridParams;
    use slam2world::pipeline::{convert_path, ConvertOptions};

    let sim = scene_run();
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("run.mcap");
    write_slam_log(
        &log,
        &sim.keyframes,
        Some(&sim.reference),
        None,
        &[],
        &SlamLogOptions::default(),
    )
    .unwrap();
    let opts = ConvertOptions {
        map: Some(MapParams::new(RES)),
        grid: Some(GridParams::new(0.25, 0.75)),
        ..ConvertOptions::default()
    };
    let c = convert_path(&log, &opts).unwrap();
    let (g, params) = c.grid.as_ref().expect("a grid");
    assert_eq!(params.z_min, 0.25);
    assert!((g.resolution - RES).abs() < 1e-12);
    let scene = &sim.truth.scene;
    let states = g.states(0.5);
    let (mut rim, mut rim_occupied) = (0usize, 0usize);
    let (mut between, mut between_known, mut between_free) = (0usize, 0usize, 0usize);
    let mut stray_occupied = Vec::new();
    for row in 0..g.height {
        for col in 0..g.width {
            let [x, y] = g.cell_center(col, row);
            let s = states[g.index(col, row).unwrap()];
            let d = scene
                .cube_min
                .iter()
                .map(|m| footprint_distance(m, scene.cube_size, x, y))
                .fold(f64::INFINITY, f64::min);
            let inside_plane =
                x.abs() < scene.plane_half[0] - 0.2 && y.abs() < scene.plane_half[1] - 0.2;
            // Cells on a cube's side faces: the voxels its points fall in.
            let on_rim = scene.cube_min.iter().any(|m| {
                let e = scene.cube_size;
                let inside = x > m.x && x < m.x + e && y > m.y && y < m.y + e;
                let edge = (x - m.x)
                    .abs()
                    .min((x - m.x - e).abs())
                    .min((y - m.y).abs())
                    .min((y - m.y - e).abs());
                inside && edge < RES
            });
            if on_rim {
                rim += 1;
                rim_occupied += usize::from(s == slam2world::map::CellState::Occupied);
            }
            if d > 3.0 * RES && inside_plane {
                between += 1;
                if s != slam2world::map::CellState::Unknown {
                    between_known += 1;
                    between_free += usize::from(s == slam2world::map::CellState::Free);
                }
            }
            if d > 3.0 * RES && s == slam2world::map::CellState::Occupied {
                stray_occupied.push((x, y));
            }
        }
    }
    // Every cube is there: most cells along its faces are occupied.
    for m in &scene.cube_min {
        let e = scene.cube_size;
        let centre = [m.x + 0.5 * e, m.y + 0.5 * e];
        let near: Vec<CellStateAt> = (0..g.height)
            .flat_map(|row| (0..g.width).map(move |col| (col, row)))
            .filter_map(|(col, row)| {
                let [x, y] = g.cell_center(col, row);
                let inside = x > m.x && x < m.x + e && y > m.y && y < m.y + e;
                inside.then(|| states[g.index(col, row).unwrap()])
            })
            .collect();
        let occupied = near
            .iter()
            .filter(|s| **s == slam2world::map::CellState::Occupied)
            .count();
        // At least one and a half faces' worth of cells (a face is ten).
        assert!(
            occupied >= 15,
            "cube at {centre:?}: {occupied} of {} footprint cells occupied",
            near.len()
        );
    }
    // Not every face is seen from the path: most are.
    assert!(
        rim_occupied * 2 >= rim,
        "{rim_occupied} of {rim} cube-face cells occupied"
    );
    // The plane between the cubes: seen (known) and free.
    assert!(
        between_known * 10 >= between * 6,
        "{between_known} of {between} cells known"
    );
    assert!(
        between_free * 100 >= between_known * 99,
        "{between_free} of {between_known} known cells between the cubes free"
    );
    assert!(
        stray_occupied.is_empty(),
        "{} occupied cells away from every cube, e.g. {:?}",
        stray_occupied.len(),
        stray_occupied.first()
    );
    // The report says the same.
    let r = c.report.grid.as_ref().unwrap();
    assert_eq!((r.width, r.height), (g.width, g.height));
    assert_eq!(
        r.cells_occupied + r.cells_free + r.cells_unknown,
        g.width * g.height
    );
    assert_eq!(
        r.cells_occupied,
        states
            .iter()
            .filter(|s| **s == slam2world::map::CellState::Occupied)
            .count()
    );

    // Written with the other outputs; the grid channel in world.mcap.
    let out = dir.path().join("out");
    c.write_all(&out, WorldFlavor::Foxglove).unwrap();
    let pgm = std::fs::read(out.join("map.pgm")).unwrap();
    assert!(pgm.starts_with(format!("P5\n{} {}\n255\n", g.width, g.height).as_bytes()));
    let yaml = std::fs::read_to_string(out.join("map.yaml")).unwrap();
    assert!(yaml.contains("mode: trinary\n"), "{yaml}");
    assert!(out.join("map_height.npy").exists());
    let world = slam2world::io::mcap::McapFile::open(out.join("world.mcap")).unwrap();
    let topics: Vec<String> = world
        .channels()
        .unwrap()
        .values()
        .map(|c| c.topic.clone())
        .collect();
    assert!(
        topics.iter().any(|t| t == grid_msgs::GRID_TOPIC),
        "{topics:?}"
    );
    // A conversion without a grid removes the stale grid files.
    let no_grid = ConvertOptions {
        grid: None,
        ..opts.clone()
    };
    convert_path(&log, &no_grid)
        .unwrap()
        .write_all(&out, WorldFlavor::Foxglove)
        .unwrap();
    assert!(!out.join("map.pgm").exists() && !out.join("map.yaml").exists());
}

type CellStateAt = slam2world::map::CellState;

#[test]
fn a_grid_needs_an_octree_and_a_sound_band() {
    use slam2world::map::GridParams;
    use slam2world::pipeline::ConvertOptions;
    let no_map = ConvertOptions {
        grid: Some(GridParams::new(0.0, 1.0)),
        ..ConvertOptions::default()
    };
    assert!(matches!(no_map.check(), Err(Error::InvalidArgument { .. })));
    for (lo, hi) in [(1.0, 0.0), (f64::NAN, 1.0)] {
        let bad = ConvertOptions {
            map: Some(MapParams::new(RES)),
            grid: Some(GridParams::new(lo, hi)),
            ..ConvertOptions::default()
        };
        assert!(bad.check().is_err(), "{lo} {hi}");
    }
}
