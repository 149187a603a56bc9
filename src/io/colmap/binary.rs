//! COLMAP `.bin` files (`reconstruction_io_binary.cc`): little-endian, a `u64`
//! record count, then the records. Every count is checked against the bytes
//! left (times the smallest size of its records) before anything is reserved.

use std::path::Path;

use super::{
    CameraModel, ColmapCamera, ColmapFrame, ColmapImage, ColmapPoint3D, ColmapRig, DataId, Point2D,
    RigSensor, Rigid3, SensorId, SensorType, TrackElement,
};
use crate::error::{Error, Result};

/// Bytes of one `point2D` (x, y f64; point3D id u64).
const POINT2D_BYTES: usize = 24;
/// Bytes of one track element (image id u32, point2D index u32).
const TRACK_BYTES: usize = 8;
/// Smallest camera: id, model, width, height, no params.
const CAMERA_MIN: usize = 4 + 4 + 8 + 8;
/// Smallest image: id, pose, camera id, empty name (one NUL), point count.
const IMAGE_MIN: usize = 4 + 56 + 4 + 1 + 8;
/// Smallest point: id, xyz, rgb, error, track length.
const POINT_MIN: usize = 8 + 24 + 3 + 8 + 8;
/// Smallest rig: id, sensor count.
const RIG_MIN: usize = 4 + 4;
/// Smallest non-reference rig sensor: type, id, has-pose flag.
const SENSOR_MIN: usize = 4 + 4 + 1;
/// Smallest frame: id, rig id, pose, data count.
const FRAME_MIN: usize = 4 + 4 + 56 + 4;
/// One data id: type, sensor id, data id.
const DATA_BYTES: usize = 4 + 4 + 8;
/// `kInvalidPoint3DId`.
const INVALID_POINT3D: u64 = u64::MAX;

/// A bounds-checked little-endian reader that names the file and the offset.
struct Cursor<'a> {
    path: &'a Path,
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn new(path: &'a Path, bytes: &'a [u8]) -> Self {
        Cursor {
            path,
            bytes,
            pos: 0,
        }
    }

    fn left(&self) -> usize {
        self.bytes.len() - self.pos
    }

    fn err(&self, at: usize, what: &str, expected: String, found: String) -> Error {
        Error::BinaryFormat {
            path: self.path.into(),
            offset: at as u64,
            what: what.into(),
            expected,
            found,
        }
    }

    fn take<const N: usize>(&mut self, what: &str) -> Result<[u8; N]> {
        if self.left() < N {
            return Err(self.err(
                self.pos,
                what,
                format!("{N} bytes"),
                format!("{} bytes before the end of the file", self.left()),
            ));
        }
        let mut b = [0u8; N];
        b.copy_from_slice(&self.bytes[self.pos..self.pos + N]);
        self.pos += N;
        Ok(b)
    }

    fn u8(&mut self, what: &str) -> Result<u8> {
        Ok(self.take::<1>(what)?[0])
    }
    fn u32(&mut self, what: &str) -> Result<u32> {
        Ok(u32::from_le_bytes(self.take(what)?))
    }
    fn i32(&mut self, what: &str) -> Result<i32> {
        Ok(i32::from_le_bytes(self.take(what)?))
    }
    fn u64(&mut self, what: &str) -> Result<u64> {
        Ok(u64::from_le_bytes(self.take(what)?))
    }
    fn f64(&mut self, what: &str) -> Result<f64> {
        Ok(f64::from_le_bytes(self.take(what)?))
    }

    /// A `u64` count of records of at least `min_bytes` each, checked against
    /// the bytes left so that a hostile count cannot reserve memory.
    fn count(&mut self, what: &str, min_bytes: usize) -> Result<usize> {
        let at = self.pos;
        let n = self.u64(what)?;
        self.check_count(at, what, n, min_bytes)
    }

    fn check_count(&self, at: usize, what: &str, n: u64, min_bytes: usize) -> Result<usize> {
        let fits = usize::try_from(n)
            .ok()
            .and_then(|n| n.checked_mul(min_bytes))
            .is_some_and(|b| b <= self.left());
        if !fits {
            return Err(self.err(
                at,
                what,
                format!(
                    "at most {} (the {} bytes left, {min_bytes} or more each)",
                    self.left() / min_bytes.max(1),
                    self.left()
                ),
                n.to_string(),
            ));
        }
        Ok(n as usize)
    }

    fn pose(&mut self, what: &str) -> Result<Rigid3> {
        let mut v = [0.0; 7];
        for x in &mut v {
            *x = self.f64(what)?;
        }
        Ok(Rigid3 {
            qvec: [v[0], v[1], v[2], v[3]],
            tvec: [v[4], v[5], v[6]],
        })
    }

    fn sensor(&mut self, what: &str) -> Result<SensorId> {
        let at = self.pos;
        let t = self.i32(what)?;
        let kind = SensorType::from_id(t).ok_or_else(|| {
            self.err(
                at,
                what,
                "a sensor type -1 (INVALID), 0 (CAMERA) or 1 (IMU)".into(),
                t.to_string(),
            )
        })?;
        Ok(SensorId {
            kind,
            id: self.u32(what)?,
        })
    }

    fn name(&mut self, what: &str) -> Result<String> {
        let at = self.pos;
        let end = self.bytes[self.pos..]
            .iter()
            .position(|&b| b == 0)
            .ok_or_else(|| {
                self.err(
                    at,
                    what,
                    "a NUL-terminated name".into(),
                    "no NUL before the end of the file".into(),
                )
            })?;
        let raw = &self.bytes[self.pos..self.pos + end];
        let s = std::str::from_utf8(raw)
            .map_err(|_| self.err(at, what, "a UTF-8 name".into(), format!("{raw:?}")))?;
        self.pos += end + 1;
        Ok(s.to_owned())
    }

    fn finish(&self) -> Result<()> {
        if self.left() != 0 {
            return Err(self.err(
                self.pos,
                "end of file",
                "no bytes after the declared records".into(),
                format!("{} more bytes", self.left()),
            ));
        }
        Ok(())
    }
}

/// Reads `cameras.bin`.
pub fn read_cameras(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapCamera>> {
    let mut c = Cursor::new(path, bytes);
    let n = c.count("num_cameras", CAMERA_MIN)?;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let id = c.u32(&format!("camera {i} camera_id"))?;
        let at = c.pos;
        let m = c.i32(&format!("camera {id} model_id"))?;
        let model = CameraModel::from_id(m).ok_or_else(|| {
            c.err(
                at,
                &format!("camera {id} model_id"),
                "a COLMAP camera model id 0..=17".into(),
                m.to_string(),
            )
        })?;
        let width = c.u64(&format!("camera {id} width"))?;
        let height = c.u64(&format!("camera {id} height"))?;
        let mut params = Vec::with_capacity(model.num_params());
        for _ in 0..model.num_params() {
            params.push(c.f64(&format!("camera {id} params"))?);
        }
        out.push(ColmapCamera {
            id,
            model,
            width,
            height,
            params,
        });
    }
    c.finish()?;
    Ok(out)
}

/// Reads `images.bin`.
pub fn read_images(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapImage>> {
    let mut c = Cursor::new(path, bytes);
    let n = c.count("num_reg_images", IMAGE_MIN)?;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let id = c.u32(&format!("image {i} image_id"))?;
        let cam_from_world = c.pose(&format!("image {id} cam_from_world"))?;
        let camera_id = c.u32(&format!("image {id} camera_id"))?;
        let name = c.name(&format!("image {id} name"))?;
        let np = c.count(&format!("image {id} num_points2D"), POINT2D_BYTES)?;
        let mut points2d = Vec::with_capacity(np);
        for _ in 0..np {
            let x = c.f64("points2D x")?;
            let y = c.f64("points2D y")?;
            let p = c.u64("points2D point3D_id")?;
            points2d.push(Point2D {
                xy: [x, y],
                point3d_id: (p != INVALID_POINT3D).then_some(p),
            });
        }
        out.push(ColmapImage {
            id,
            cam_from_world,
            camera_id,
            name,
            points2d,
        });
    }
    c.finish()?;
    Ok(out)
}

/// Reads `points3D.bin`.
pub fn read_points3d(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapPoint3D>> {
    let mut c = Cursor::new(path, bytes);
    let n = c.count("num_points3D", POINT_MIN)?;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let id = c.u64(&format!("point {i} point3D_id"))?;
        let what = format!("point {id}");
        let xyz = [c.f64(&what)?, c.f64(&what)?, c.f64(&what)?];
        let rgb = [c.u8(&what)?, c.u8(&what)?, c.u8(&what)?];
        let error = c.f64(&what)?;
        let nt = c.count(&format!("point {id} track_length"), TRACK_BYTES)?;
        let mut track = Vec::with_capacity(nt);
        for _ in 0..nt {
            track.push(TrackElement {
                image_id: c.u32("track image_id")?,
                point2d_idx: c.u32("track point2D_idx")?,
            });
        }
        out.push(ColmapPoint3D {
            id,
            xyz,
            rgb,
            error,
            track,
        });
    }
    c.finish()?;
    Ok(out)
}

/// Reads `rigs.bin`.
pub fn read_rigs(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapRig>> {
    let mut c = Cursor::new(path, bytes);
    let n = c.count("num_rigs", RIG_MIN)?;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let id = c.u32(&format!("rig {i} rig_id"))?;
        let at = c.pos;
        let ns = c.u32(&format!("rig {id} num_sensors"))? as u64;
        let mut ref_sensor = None;
        let mut sensors = Vec::new();
        if ns > 0 {
            ref_sensor = Some(c.sensor(&format!("rig {id} ref_sensor"))?);
            let more = c.check_count(at, &format!("rig {id} num_sensors"), ns - 1, SENSOR_MIN)?;
            sensors.reserve(more);
            for _ in 0..more {
                let sensor = c.sensor(&format!("rig {id} sensor"))?;
                let flag_at = c.pos;
                let has = c.u8(&format!("rig {id} sensor has_pose"))?;
                let sensor_from_rig = match has {
                    0 => None,
                    1 => Some(c.pose(&format!("rig {id} sensor_from_rig"))?),
                    v => {
                        return Err(c.err(
                            flag_at,
                            &format!("rig {id} sensor has_pose"),
                            "0 or 1".into(),
                            v.to_string(),
                        ))
                    }
                };
                sensors.push(RigSensor {
                    sensor,
                    sensor_from_rig,
                });
            }
        }
        out.push(ColmapRig {
            id,
            ref_sensor,
            sensors,
        });
    }
    c.finish()?;
    Ok(out)
}

/// Reads `frames.bin`.
pub fn read_frames(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapFrame>> {
    let mut c = Cursor::new(path, bytes);
    let n = c.count("num_frames", FRAME_MIN)?;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let id = c.u32(&format!("frame {i} frame_id"))?;
        let rig_id = c.u32(&format!("frame {id} rig_id"))?;
        let rig_from_world = c.pose(&format!("frame {id} rig_from_world"))?;
        let at = c.pos;
        let nd = c.u32(&format!("frame {id} num_data_ids"))? as u64;
        let nd = c.check_count(at, &format!("frame {id} num_data_ids"), nd, DATA_BYTES)?;
        let mut data_ids = Vec::with_capacity(nd);
        for _ in 0..nd {
            let sensor = c.sensor(&format!("frame {id} data_id"))?;
            data_ids.push(DataId {
                sensor,
                id: c.u64(&format!("frame {id} data_id"))?,
            });
        }
        out.push(ColmapFrame {
            id,
            rig_id,
            rig_from_world,
            data_ids,
        });
    }
    c.finish()?;
    Ok(out)
}

fn put_pose(out: &mut Vec<u8>, p: &Rigid3) {
    for v in p.qvec.iter().chain(&p.tvec) {
        out.extend(v.to_le_bytes());
    }
}

fn put_sensor(out: &mut Vec<u8>, s: &SensorId) {
    out.extend(s.kind.id().to_le_bytes());
    out.extend(s.id.to_le_bytes());
}

/// `cameras.bin` bytes.
pub fn write_cameras(cameras: &[ColmapCamera]) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend((cameras.len() as u64).to_le_bytes());
    for c in cameras {
        out.extend(c.id.to_le_bytes());
        out.extend(c.model.id().to_le_bytes());
        out.extend(c.width.to_le_bytes());
        out.extend(c.height.to_le_bytes());
        for p in &c.params {
            out.extend(p.to_le_bytes());
        }
    }
    out
}

/// `images.bin` bytes.
pub fn write_images(images: &[ColmapImage]) -> Vec<u8> {
    let size: usize = images
        .iter()
        .map(|im| IMAGE_MIN + im.name.len() + POINT2D_BYTES * im.points2d.len())
        .sum();
    let mut out = Vec::with_capacity(8 + size);
    out.extend((images.len() as u64).to_le_bytes());
    for im in images {
        out.extend(im.id.to_le_bytes());
        put_pose(&mut out, &im.cam_from_world);
        out.extend(im.camera_id.to_le_bytes());
        out.extend(im.name.as_bytes());
        out.push(0);
        out.extend((im.points2d.len() as u64).to_le_bytes());
        for p in &im.points2d {
            out.extend(p.xy[0].to_le_bytes());
            out.extend(p.xy[1].to_le_bytes());
            out.extend(p.point3d_id.unwrap_or(INVALID_POINT3D).to_le_bytes());
        }
    }
    out
}

/// `points3D.bin` bytes.
pub fn write_points3d(points: &[ColmapPoint3D]) -> Vec<u8> {
    let size: usize = points
        .iter()
        .map(|p| POINT_MIN + TRACK_BYTES * p.track.len())
        .sum();
    let mut out = Vec::with_capacity(8 + size);
    out.extend((points.len() as u64).to_le_bytes());
    for p in points {
        out.extend(p.id.to_le_bytes());
        for v in p.xyz {
            out.extend(v.to_le_bytes());
        }
        out.extend(p.rgb);
        out.extend(p.error.to_le_bytes());
        out.extend((p.track.len() as u64).to_le_bytes());
        for t in &p.track {
            out.extend(t.image_id.to_le_bytes());
            out.extend(t.point2d_idx.to_le_bytes());
        }
    }
    out
}

/// `rigs.bin` bytes.
pub fn write_rigs(rigs: &[ColmapRig]) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend((rigs.len() as u64).to_le_bytes());
    for r in rigs {
        out.extend(r.id.to_le_bytes());
        match &r.ref_sensor {
            None => out.extend(0u32.to_le_bytes()),
            Some(refs) => {
                out.extend((r.sensors.len() as u32 + 1).to_le_bytes());
                put_sensor(&mut out, refs);
                for s in &r.sensors {
                    put_sensor(&mut out, &s.sensor);
                    match &s.sensor_from_rig {
                        None => out.push(0),
                        Some(p) => {
                            out.push(1);
                            put_pose(&mut out, p);
                        }
                    }
                }
            }
        }
    }
    out
}

/// `frames.bin` bytes.
pub fn write_frames(frames: &[ColmapFrame]) -> Vec<u8> {
    let mut out = Vec::new();
    out.extend((frames.len() as u64).to_le_bytes());
    for f in frames {
        out.extend(f.id.to_le_bytes());
        out.extend(f.rig_id.to_le_bytes());
        put_pose(&mut out, &f.rig_from_world);
        out.extend((f.data_ids.len() as u32).to_le_bytes());
        for d in &f.data_ids {
            put_sensor(&mut out, &d.sensor);
            out.extend(d.id.to_le_bytes());
        }
    }
    out
}
