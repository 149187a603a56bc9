//! Message encoders of the 2-D grid ([`Grid2d`]) and the channels
//! `world.mcap` gives it:
//!
//! - `nav_msgs/OccupancyGrid` in ROS 1 and ROS 2 (CDR) encodings: `int8`
//!   cells row-major from cell `(0, 0)` at `info.origin` (the lower-left
//!   corner of the lower-left cell, z = 0, no rotation), `-1` unknown,
//!   `0..=100` the occupancy probability in percent (or trinary `0` / `100`,
//!   see [`CellValues`]);
//! - `foxglove.Grid` (protobuf): the same cells with two `FLOAT32` fields,
//!   `probability` (NaN unknown) and `top_z` (centre height in metres of the
//!   highest occupied voxel, NaN where none), cell stride 8 bytes.
//!
//! All in the world frame named by `frame`, metres; stamps in seconds.

use super::wire::PbWriter;
use super::write::{ExtraChannel, WorldFlavor};
use crate::error::{Error, Result};
use crate::map::Grid2d;

/// `foxglove.Grid` (protobuf FileDescriptorSet, dumped from
/// `foxglove-schemas-protobuf` 0.4.0 like the other embedded schemas).
pub const FOXGLOVE_GRID: (&str, &str, &[u8]) = (
    "foxglove.Grid",
    "protobuf",
    include_bytes!("schemas/foxglove.Grid.fds.bin"),
);

/// `nav_msgs/OccupancyGrid` (ROS 1) with its dependencies, as `gendeps --cat`
/// concatenates them (comments left out).
pub const ROS1_OCCUPANCY_GRID: (&str, &str, &[u8]) = (
    "nav_msgs/OccupancyGrid",
    "ros1msg",
    b"Header header\nMapMetaData info\nint8[] data\n\
================================================================================\n\
MSG: std_msgs/Header\nuint32 seq\ntime stamp\nstring frame_id\n\
================================================================================\n\
MSG: nav_msgs/MapMetaData\ntime map_load_time\nfloat32 resolution\nuint32 width\nuint32 height\n\
geometry_msgs/Pose origin\n\
================================================================================\n\
MSG: geometry_msgs/Pose\nPoint position\nQuaternion orientation\n\
================================================================================\n\
MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n\
================================================================================\n\
MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n",
);

/// `nav_msgs/msg/OccupancyGrid` (ROS 2) with its dependencies.
pub const ROS2_OCCUPANCY_GRID: (&str, &str, &[u8]) = (
    "nav_msgs/msg/OccupancyGrid",
    "ros2msg",
    b"std_msgs/Header header\nMapMetaData info\nint8[] data\n\
================================================================================\n\
MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n\
================================================================================\n\
MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n\
================================================================================\n\
MSG: nav_msgs/MapMetaData\nbuiltin_interfaces/Time map_load_time\nfloat32 resolution\n\
uint32 width\nuint32 height\ngeometry_msgs/Pose origin\n\
================================================================================\n\
MSG: geometry_msgs/Pose\nPoint position\nQuaternion orientation\n\
================================================================================\n\
MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n\
================================================================================\n\
MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n",
);

/// Topic of the grid in `world.mcap`.
pub const GRID_TOPIC: &str = "/slam2world/grid";

/// Foxglove `PackedElementField.NumericType.FLOAT32`.
const FOXGLOVE_FLOAT32: i64 = 7;

/// What the `int8` cells of an `OccupancyGrid` hold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CellValues {
    /// The occupancy probability in percent, rounded (`0..=100`), as the
    /// message documents; `-1` unknown.
    Probability,
    /// `100` where the probability is at least `occupied` (compared in `f32`),
    /// `0` elsewhere
    /// known, `-1` unknown (what `map_server` publishes; nav2's costmap with
    /// `trinary_costmap: true` treats every value below its
    /// `lethal_cost_threshold`, 100 by default, as free).
    Trinary {
        /// Occupancy threshold, a probability (the octree's rule is 0.5).
        occupied: f64,
    },
}

/// The cells of an `OccupancyGrid`, row-major from cell `(0, 0)`.
pub fn occupancy_grid_data(grid: &Grid2d, values: CellValues) -> Vec<i8> {
    grid.probability
        .iter()
        .map(|&p| {
            if p.is_nan() {
                -1
            } else {
                match values {
                    CellValues::Probability => {
                        (f64::from(p) * 100.0).round().clamp(0.0, 100.0) as i8
                    }
                    CellValues::Trinary { occupied } => {
                        if p >= occupied as f32 {
                            100
                        } else {
                            0
                        }
                    }
                }
            }
        })
        .collect()
}

/// Checks what every encoder needs: consistent layers, sizes that fit the
/// messages' `uint32` fields, a finite origin and resolution, a valid stamp
/// (`0 ≤ stamp < 2^31` s: ROS 2's `int32` seconds) and threshold.
fn check(grid: &Grid2d, stamp: f64, values: CellValues) -> Result<()> {
    let cells = grid.width.checked_mul(grid.height);
    for (what, layer) in [("probability", &grid.probability), ("top_z", &grid.top_z)] {
        if cells != Some(layer.len()) {
            return Err(Error::ShapeMismatch {
                what: what.into(),
                expected: format!("{} x {} cells", grid.height, grid.width),
                got: format!("{} values", layer.len()),
            });
        }
    }
    for (what, n) in [("width", grid.width), ("height", grid.height)] {
        if u32::try_from(n).is_err() || n.saturating_mul(8) > u32::MAX as usize {
            return Err(Error::invalid(
                what,
                format!("{n} cells do not fit a grid message"),
            ));
        }
    }
    if cells.is_some_and(|c| c.saturating_mul(8) > u32::MAX as usize) {
        return Err(Error::invalid(
            "grid",
            format!("{} cells do not fit one message", grid.width * grid.height),
        ));
    }
    if !(grid.resolution.is_finite() && grid.resolution > 0.0) {
        return Err(Error::invalid(
            "resolution",
            format!("{} is not a positive length", grid.resolution),
        ));
    }
    if let Some(i) = grid.origin.iter().position(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "origin".into(),
            index: i,
        });
    }
    if !(0.0..2_147_483_648.0).contains(&stamp) {
        return Err(Error::invalid(
            "stamp",
            format!("{stamp} s is not a message time (0 ≤ t < 2^31 s)"),
        ));
    }
    if let CellValues::Trinary { occupied } = values {
        if !(occupied > 0.0 && occupied <= 1.0) {
            return Err(Error::invalid(
                "occupied_threshold",
                format!("{occupied} is not a probability in (0, 1]"),
            ));
        }
    }
    Ok(())
}

/// Seconds and nanoseconds of a checked stamp.
fn sec_nsec(t: f64) -> (u32, u32) {
    let sec = t.floor();
    (
        sec as u32,
        ((t - sec) * 1e9).round().min(999_999_999.0) as u32,
    )
}

/// The ROS 1 `nav_msgs/OccupancyGrid` of `grid` (header `seq`, `stamp` in
/// seconds, `frame`; `info.map_load_time` = `stamp`).
pub fn occupancy_grid_ros1(
    grid: &Grid2d,
    seq: u32,
    stamp: f64,
    frame: &str,
    values: CellValues,
) -> Result<Vec<u8>> {
    check(grid, stamp, values)?;
    let (sec, nsec) = sec_nsec(stamp);
    let n = grid.probability.len();
    let mut m = Vec::with_capacity(96 + frame.len() + n);
    let u32le = |m: &mut Vec<u8>, v: u32| m.extend_from_slice(&v.to_le_bytes());
    u32le(&mut m, seq);
    u32le(&mut m, sec);
    u32le(&mut m, nsec);
    u32le(&mut m, frame.len() as u32);
    m.extend_from_slice(frame.as_bytes());
    u32le(&mut m, sec);
    u32le(&mut m, nsec);
    m.extend_from_slice(&(grid.resolution as f32).to_le_bytes());
    u32le(&mut m, grid.width as u32);
    u32le(&mut m, grid.height as u32);
    for v in origin_pose(grid) {
        m.extend_from_slice(&v.to_le_bytes());
    }
    u32le(&mut m, n as u32);
    m.extend(occupancy_grid_data(grid, values).iter().map(|&v| v as u8));
    Ok(m)
}

/// `info.origin` as `[x, y, z, qx, qy, qz, qw]`.
fn origin_pose(grid: &Grid2d) -> [f64; 7] {
    [grid.origin[0], grid.origin[1], 0.0, 0.0, 0.0, 0.0, 1.0]
}

/// Little-endian CDR (XCDR1) with alignment counted after the 4-byte
/// encapsulation header.
struct Cdr(Vec<u8>);

impl Cdr {
    fn align(&mut self, n: usize) {
        while (self.0.len() - 4) % n != 0 {
            self.0.push(0);
        }
    }
    fn u32(&mut self, v: u32) {
        self.align(4);
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f32(&mut self, v: f32) {
        self.align(4);
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.align(8);
        self.0.extend_from_slice(&v.to_le_bytes());
    }
}

/// The ROS 2 `nav_msgs/msg/OccupancyGrid` of `grid` (CDR, little endian).
pub fn occupancy_grid_cdr(
    grid: &Grid2d,
    stamp: f64,
    frame: &str,
    values: CellValues,
) -> Result<Vec<u8>> {
    check(grid, stamp, values)?;
    let (sec, nsec) = sec_nsec(stamp);
    let n = grid.probability.len();
    let mut w = Cdr(Vec::with_capacity(112 + frame.len() + n));
    w.0.extend_from_slice(&[0, 1, 0, 0]);
    w.u32(sec); // int32 sec (< 2^31, checked)
    w.u32(nsec);
    w.u32(frame.len() as u32 + 1);
    w.0.extend_from_slice(frame.as_bytes());
    w.0.push(0);
    w.u32(sec);
    w.u32(nsec);
    w.f32(grid.resolution as f32);
    w.u32(grid.width as u32);
    w.u32(grid.height as u32);
    for v in origin_pose(grid) {
        w.f64(v);
    }
    w.u32(n as u32);
    w.0.extend(occupancy_grid_data(grid, values).iter().map(|&v| v as u8));
    Ok(w.0)
}

/// The `foxglove.Grid` of `grid`: pose at the origin corner (z = 0), cells of
/// `resolution`, `column_count = width`, `row_stride = 8 · width`,
/// `cell_stride = 8`, fields `probability` (offset 0) and `top_z` (offset 4),
/// both `FLOAT32`, NaN where unknown / none.
pub fn foxglove_grid(grid: &Grid2d, stamp: f64, frame: &str) -> Result<Vec<u8>> {
    check(grid, stamp, CellValues::Probability)?;
    let (sec, nsec) = sec_nsec(stamp);
    let mut m = PbWriter::new();
    let mut t = PbWriter::new();
    t.int(1, i64::from(sec));
    t.int(2, i64::from(nsec));
    m.message(1, &t);
    m.bytes(2, frame.as_bytes());
    let p = origin_pose(grid);
    let mut pos = PbWriter::new();
    for (i, v) in p[..3].iter().enumerate() {
        pos.double(i as u32 + 1, *v);
    }
    let mut q = PbWriter::new();
    for (i, v) in p[3..].iter().enumerate() {
        q.double(i as u32 + 1, *v);
    }
    let mut pose = PbWriter::new();
    pose.message(1, &pos);
    pose.message(2, &q);
    m.message(3, &pose);
    m.fixed32(4, grid.width as u32);
    let mut size = PbWriter::new();
    size.double(1, grid.resolution);
    size.double(2, grid.resolution);
    m.message(5, &size);
    m.fixed32(6, 8 * grid.width as u32);
    m.fixed32(7, 8);
    for (name, offset) in [("probability", 0u32), ("top_z", 4)] {
        let mut f = PbWriter::new();
        f.bytes(1, name.as_bytes());
        f.fixed32(2, offset);
        f.int(3, FOXGLOVE_FLOAT32);
        m.message(8, &f);
    }
    let mut data = Vec::with_capacity(8 * grid.probability.len());
    for (p, z) in grid.probability.iter().zip(&grid.top_z) {
        data.extend_from_slice(&p.to_le_bytes());
        data.extend_from_slice(&z.to_le_bytes());
    }
    m.bytes(9, &data);
    Ok(m.buf)
}

/// One channel of the grid in `world.mcap` and its one message.
#[derive(Clone, Debug)]
pub struct GridChannel {
    /// Topic ([`GRID_TOPIC`]).
    pub topic: &'static str,
    /// Schema record: `(name, encoding, data)`.
    pub schema: (&'static str, &'static str, &'static [u8]),
    /// Message encoding of the channel (`protobuf`, `cdr`).
    pub message_encoding: &'static str,
    /// The encoded message.
    pub data: Vec<u8>,
}

impl GridChannel {
    /// The channel as `write_world_mcap_extra_into` takes it (the message borrowed).
    pub fn as_extra(&self) -> ExtraChannel<'_> {
        ExtraChannel {
            topic: self.topic,
            schema: self.schema,
            message_encoding: self.message_encoding,
            data: &self.data,
        }
    }
}

/// The grid channels `write_world_mcap` adds for `flavor`: Foxglove, one
/// `foxglove.Grid` (probability and height); ROS 2, one
/// `nav_msgs/msg/OccupancyGrid` (probability in percent), for RViz 2.
pub fn grid_channels(
    grid: &Grid2d,
    stamp: f64,
    frame: &str,
    flavor: WorldFlavor,
) -> Result<Vec<GridChannel>> {
    Ok(vec![match flavor {
        WorldFlavor::Foxglove => GridChannel {
            topic: GRID_TOPIC,
            schema: FOXGLOVE_GRID,
            message_encoding: "protobuf",
            data: foxglove_grid(grid, stamp, frame)?,
        },
        WorldFlavor::Ros2 => GridChannel {
            topic: GRID_TOPIC,
            schema: ROS2_OCCUPANCY_GRID,
            message_encoding: "cdr",
            data: occupancy_grid_cdr(grid, stamp, frame, CellValues::Probability)?,
        },
    }])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::mcap::wire::pb_fields;

    fn grid() -> Grid2d {
        Grid2d {
            resolution: 0.25,
            origin: [-1.0, 2.5],
            width: 2,
            height: 2,
            z_band: [0.0, 1.0],
            probability: vec![0.971, 0.12, f32::NAN, 0.5],
            top_z: vec![0.875, f32::NAN, f32::NAN, 0.125],
        }
    }

    #[test]
    fn cells_are_percent_or_trinary() {
        assert_eq!(
            occupancy_grid_data(&grid(), CellValues::Probability),
            vec![97, 12, -1, 50]
        );
        assert_eq!(
            occupancy_grid_data(&grid(), CellValues::Trinary { occupied: 0.5 }),
            vec![100, 0, -1, 100]
        );
    }

    #[test]
    fn ros1_layout_is_packed() {
        let m = occupancy_grid_ros1(&grid(), 7, 12.5, "world", CellValues::Probability).unwrap();
        // seq, sec, nsec, frame (4 + 5), load time (8), resolution, width, height,
        // origin (56), data length (4) + 4 cells.
        assert_eq!(m.len(), 12 + 9 + 8 + 12 + 56 + 4 + 4);
        assert_eq!(&m[0..4], &7u32.to_le_bytes());
        assert_eq!(&m[4..8], &12u32.to_le_bytes());
        assert_eq!(&m[8..12], &500_000_000u32.to_le_bytes());
        assert_eq!(&m[16..21], b"world");
        assert_eq!(&m[29..33], &0.25f32.to_le_bytes());
        assert_eq!(&m[m.len() - 4..], &[97, 12, 255, 50]);
    }

    #[test]
    fn cdr_aligns_the_origin_to_eight() {
        let m = occupancy_grid_cdr(&grid(), 1.0, "map", CellValues::Probability).unwrap();
        assert_eq!(&m[..4], &[0, 1, 0, 0]);
        // header: sec, nsec, len (4) + "map\0" -> 16 bytes; info: 8 + 4 + 4 + 4 = 36,
        // then pad to 8 (offset 36 -> 40), 56 bytes of pose, length, cells.
        assert_eq!(m.len(), 4 + 40 + 56 + 4 + 4);
        assert_eq!(&m[4 + 40..4 + 48], &(-1.0f64).to_le_bytes());
    }

    #[test]
    fn foxglove_grid_fields_and_cells() {
        let m = foxglove_grid(&grid(), 3.0, "world").unwrap();
        let mut names = Vec::new();
        let mut data = None;
        for f in pb_fields(&m) {
            let (n, v) = f.unwrap();
            match n {
                4 => assert_eq!(v.as_u64().unwrap(), 2),
                6 => assert_eq!(v.as_u64().unwrap(), 16),
                7 => assert_eq!(v.as_u64().unwrap(), 8),
                8 => {
                    for g in pb_fields(v.as_bytes().unwrap()) {
                        let (k, w) = g.unwrap();
                        if k == 1 {
                            names.push(String::from_utf8(w.as_bytes().unwrap().to_vec()).unwrap());
                        }
                    }
                }
                9 => data = Some(v.as_bytes().unwrap().to_vec()),
                _ => {}
            }
        }
        assert_eq!(names, ["probability", "top_z"]);
        let data = data.unwrap();
        assert_eq!(data.len(), 32);
        assert_eq!(&data[24..28], &0.5f32.to_le_bytes());
        assert_eq!(&data[28..32], &0.125f32.to_le_bytes());
    }

    #[test]
    fn bad_stamps_and_shapes_are_refused() {
        let g = grid();
        for t in [-1.0, f64::NAN, 3e9] {
            assert!(foxglove_grid(&g, t, "w").is_err(), "{t}");
        }
        let mut bad = grid();
        bad.probability.pop();
        assert!(matches!(
            occupancy_grid_cdr(&bad, 0.0, "w", CellValues::Probability),
            Err(Error::ShapeMismatch { .. })
        ));
        assert!(
            occupancy_grid_ros1(&g, 0, 0.0, "w", CellValues::Trinary { occupied: 0.0 }).is_err()
        );
    }
}
