//! COLMAP `.txt` files (`reconstruction_io_text.cc`): `#` comment lines, one
//! record a line (an image takes two: its pose line and its `POINTS2D` line).
//! Numbers are written in the shortest form that reads back to the same bits.

use std::fmt::Write as _;
use std::path::Path;
use std::str::FromStr;

use super::{
    CameraModel, ColmapCamera, ColmapFrame, ColmapImage, ColmapPoint3D, ColmapRig, DataId, Point2D,
    RigSensor, Rigid3, SensorId, SensorType, TrackElement,
};
use crate::error::{Error, Result};

/// The bytes of a text file as UTF-8 (a leading byte-order mark dropped).
pub fn utf8<'a>(path: &Path, bytes: &'a [u8]) -> Result<&'a str> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    std::str::from_utf8(bytes).map_err(|e| {
        let line = 1 + bytes[..e.valid_up_to()]
            .iter()
            .filter(|&&b| b == b'\n')
            .count();
        Error::parse(path, line, "not UTF-8 text")
    })
}

/// The tokens of one line, with the file and line number for errors.
struct Tokens<'a> {
    path: &'a Path,
    line: usize,
    it: std::str::SplitWhitespace<'a>,
    field: usize,
}

impl<'a> Tokens<'a> {
    fn new(path: &'a Path, line: usize, text: &'a str) -> Self {
        Tokens {
            path,
            line,
            it: text.split_whitespace(),
            field: 0,
        }
    }

    fn err(&self, reason: String) -> Error {
        Error::parse(self.path, self.line, reason)
    }

    fn word(&mut self, what: &str) -> Result<&'a str> {
        self.field += 1;
        self.it
            .next()
            .ok_or_else(|| self.err(format!("field {} ({what}) is missing", self.field)))
    }

    fn num<T: FromStr>(&mut self, what: &str) -> Result<T> {
        let w = self.word(what)?;
        w.parse().map_err(|_| {
            self.err(format!(
                "field {} ({what}) is not a valid number: {w:?}",
                self.field
            ))
        })
    }

    fn pose(&mut self, what: &str) -> Result<Rigid3> {
        let mut v = [0.0; 7];
        for x in &mut v {
            *x = self.num(what)?;
        }
        Ok(Rigid3 {
            qvec: [v[0], v[1], v[2], v[3]],
            tvec: [v[4], v[5], v[6]],
        })
    }

    fn sensor(&mut self, what: &str) -> Result<SensorId> {
        let w = self.word(what)?;
        let kind = SensorType::from_name(w).ok_or_else(|| {
            self.err(format!(
                "field {} ({what}) must be CAMERA, IMU or INVALID, got {w:?}",
                self.field
            ))
        })?;
        Ok(SensorId {
            kind,
            id: self.num(what)?,
        })
    }

    fn rest(&mut self) -> Option<&'a str> {
        self.it.next()
    }

    fn end(&mut self) -> Result<()> {
        match self.it.next() {
            None => Ok(()),
            Some(w) => Err(self.err(format!(
                "unexpected field {} {w:?} after the record",
                self.field + 1
            ))),
        }
    }
}

/// Non-empty, non-comment lines with their 1-based numbers.
fn records(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

/// Reads `cameras.txt`: `CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]`.
pub fn read_cameras(path: &Path, text: &str) -> Result<Vec<ColmapCamera>> {
    let mut out = Vec::new();
    for (line, l) in records(text) {
        let mut t = Tokens::new(path, line, l);
        let id = t.num("CAMERA_ID")?;
        let name = t.word("MODEL")?;
        let model = CameraModel::from_name(name)
            .ok_or_else(|| t.err(format!("unknown camera model {name:?}")))?;
        let width = t.num("WIDTH")?;
        let height = t.num("HEIGHT")?;
        let mut params = Vec::with_capacity(model.num_params());
        while let Some(w) = t.rest() {
            params.push(
                w.parse()
                    .map_err(|_| t.err(format!("camera parameter {w:?} is not a number")))?,
            );
        }
        if params.len() != model.num_params() {
            return Err(t.err(format!(
                "camera {id} ({name}) has {} parameters, the model has {}",
                params.len(),
                model.num_params()
            )));
        }
        out.push(ColmapCamera {
            id,
            model,
            width,
            height,
            params,
        });
    }
    Ok(out)
}

/// Reads `images.txt`: `IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME`, then a
/// line of `X Y POINT3D_ID` triples (`-1` for none). The name is one word, as
/// COLMAP writes it; a pose line with more fields (a name with a space, which
/// COLMAP would cut at the space) is refused. A missing last `POINTS2D` line
/// means no points (as `read_write_model.py` reads it).
pub fn read_images(path: &Path, text: &str) -> Result<Vec<ColmapImage>> {
    let mut out = Vec::new();
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim()));
    while let Some((line, l)) = lines.next() {
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let mut t = Tokens::new(path, line, l);
        let id = t.num("IMAGE_ID")?;
        let cam_from_world = t.pose("QW QX QY QZ TX TY TZ")?;
        let camera_id = t.num("CAMERA_ID")?;
        let name = t.word("NAME")?.to_owned();
        t.end()?;
        let mut points2d = Vec::new();
        if let Some((line2, l2)) = lines.next() {
            let fields: Vec<&str> = l2.split_whitespace().collect();
            if fields.len() % 3 != 0 {
                return Err(Error::parse(
                    path,
                    line2,
                    format!(
                        "POINTS2D of image {id}: {} values, not a multiple of 3 (X Y POINT3D_ID)",
                        fields.len()
                    ),
                ));
            }
            points2d.reserve(fields.len() / 3);
            for (k, c) in fields.chunks_exact(3).enumerate() {
                let bad = |what: &str, w: &str| {
                    Error::parse(
                        path,
                        line2,
                        format!("point {k} of image {id}: {what} {w:?} is not valid"),
                    )
                };
                let x: f64 = c[0].parse().map_err(|_| bad("X", c[0]))?;
                let y: f64 = c[1].parse().map_err(|_| bad("Y", c[1]))?;
                let p: i128 = c[2].parse().map_err(|_| bad("POINT3D_ID", c[2]))?;
                let point3d_id = match p {
                    -1 => None,
                    p => Some(u64::try_from(p).map_err(|_| bad("POINT3D_ID", c[2]))?),
                };
                points2d.push(Point2D {
                    xy: [x, y],
                    point3d_id,
                });
            }
        }
        out.push(ColmapImage {
            id,
            cam_from_world,
            camera_id,
            name,
            points2d,
        });
    }
    Ok(out)
}

/// Reads `points3D.txt`: `POINT3D_ID X Y Z R G B ERROR TRACK[]`.
pub fn read_points3d(path: &Path, text: &str) -> Result<Vec<ColmapPoint3D>> {
    let mut out = Vec::new();
    for (line, l) in records(text) {
        let mut t = Tokens::new(path, line, l);
        let id = t.num("POINT3D_ID")?;
        let xyz = [t.num("X")?, t.num("Y")?, t.num("Z")?];
        let rgb = [t.num("R")?, t.num("G")?, t.num("B")?];
        let error = t.num("ERROR")?;
        let mut track = Vec::new();
        while let Some(w) = t.rest() {
            let image_id = w
                .parse()
                .map_err(|_| t.err(format!("track IMAGE_ID {w:?} is not valid")))?;
            let point2d_idx = t.num("track POINT2D_IDX")?;
            track.push(TrackElement {
                image_id,
                point2d_idx,
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
    Ok(out)
}

/// Reads `rigs.txt`: `RIG_ID NUM_SENSORS REF_TYPE REF_ID (TYPE ID HAS_POSE [QW QX QY QZ TX TY TZ])*`.
pub fn read_rigs(path: &Path, text: &str) -> Result<Vec<ColmapRig>> {
    let mut out = Vec::new();
    for (line, l) in records(text) {
        let mut t = Tokens::new(path, line, l);
        let id = t.num("RIG_ID")?;
        let n: u64 = t.num("NUM_SENSORS")?;
        let mut ref_sensor = None;
        let mut sensors = Vec::new();
        if n > 0 {
            ref_sensor = Some(t.sensor("REF_SENSOR")?);
            for _ in 1..n {
                let sensor = t.sensor("SENSOR")?;
                let sensor_from_rig = match t.num::<i64>("HAS_POSE")? {
                    0 => None,
                    1 => Some(t.pose("SENSOR_FROM_RIG")?),
                    v => return Err(t.err(format!("HAS_POSE must be 0 or 1, got {v}"))),
                };
                sensors.push(RigSensor {
                    sensor,
                    sensor_from_rig,
                });
            }
        }
        t.end()?;
        out.push(ColmapRig {
            id,
            ref_sensor,
            sensors,
        });
    }
    Ok(out)
}

/// Reads `frames.txt`: `FRAME_ID RIG_ID QW QX QY QZ TX TY TZ NUM_DATA_IDS (TYPE SENSOR_ID DATA_ID)*`.
pub fn read_frames(path: &Path, text: &str) -> Result<Vec<ColmapFrame>> {
    let mut out = Vec::new();
    for (line, l) in records(text) {
        let mut t = Tokens::new(path, line, l);
        let id = t.num("FRAME_ID")?;
        let rig_id = t.num("RIG_ID")?;
        let rig_from_world = t.pose("RIG_FROM_WORLD")?;
        let n: u64 = t.num("NUM_DATA_IDS")?;
        let mut data_ids = Vec::new();
        for _ in 0..n {
            let sensor = t.sensor("DATA_ID")?;
            data_ids.push(DataId {
                sensor,
                id: t.num("DATA_ID")?,
            });
        }
        t.end()?;
        out.push(ColmapFrame {
            id,
            rig_id,
            rig_from_world,
            data_ids,
        });
    }
    Ok(out)
}

/// A number in the shortest form that parses back to the same `f64`, with an
/// exponent for very large or small magnitudes (C++ streams read both).
fn num(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 || (1e-5..1e16).contains(&a) || !v.is_finite() {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

fn put_pose(s: &mut String, p: &Rigid3) {
    for v in p.qvec.iter().chain(&p.tvec) {
        let _ = write!(s, " {}", num(*v));
    }
}

/// `cameras.txt` text.
pub fn write_cameras(cameras: &[ColmapCamera]) -> String {
    let mut s = String::from(
        "# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n",
    );
    let _ = writeln!(s, "# Number of cameras: {}", cameras.len());
    for c in cameras {
        let _ = write!(s, "{} {} {} {}", c.id, c.model.name(), c.width, c.height);
        for p in &c.params {
            let _ = write!(s, " {}", num(*p));
        }
        s.push('\n');
    }
    s
}

/// `images.txt` text; errors for a name that is empty or holds white space
/// (the text format cannot carry it; `.bin` can).
pub fn write_images(path: &Path, images: &[ColmapImage]) -> Result<String> {
    let mut s = String::from(
        "# Image list with two lines of data per image:\n#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n#   POINTS2D[] as (X, Y, POINT3D_ID)\n",
    );
    let obs: usize = images
        .iter()
        .map(|im| {
            im.points2d
                .iter()
                .filter(|p| p.point3d_id.is_some())
                .count()
        })
        .sum();
    let mean = if images.is_empty() {
        0.0
    } else {
        obs as f64 / images.len() as f64
    };
    let _ = writeln!(
        s,
        "# Number of images: {}, mean observations per image: {}",
        images.len(),
        mean
    );
    for im in images {
        if im.name.is_empty() || im.name.chars().any(char::is_whitespace) {
            return Err(Error::Reconstruction {
                path: path.into(),
                reason: format!(
                    "image {} is named {:?}: a text model cannot hold an empty name or one with white space (write .bin)",
                    im.id, im.name
                ),
            });
        }
        let _ = write!(s, "{}", im.id);
        put_pose(&mut s, &im.cam_from_world);
        let _ = writeln!(s, " {} {}", im.camera_id, im.name);
        let mut first = true;
        for p in &im.points2d {
            if !first {
                s.push(' ');
            }
            first = false;
            let _ = write!(s, "{} {} ", num(p.xy[0]), num(p.xy[1]));
            match p.point3d_id {
                Some(id) => {
                    let _ = write!(s, "{id}");
                }
                None => s.push_str("-1"),
            }
        }
        s.push('\n');
    }
    Ok(s)
}

/// `points3D.txt` text.
pub fn write_points3d(points: &[ColmapPoint3D]) -> String {
    let mut s = String::from(
        "# 3D point list with one line of data per point:\n#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)\n",
    );
    let obs: usize = points.iter().map(|p| p.track.len()).sum();
    let mean = if points.is_empty() {
        0.0
    } else {
        obs as f64 / points.len() as f64
    };
    let _ = writeln!(
        s,
        "# Number of points: {}, mean track length: {}",
        points.len(),
        mean
    );
    for p in points {
        let _ = write!(
            s,
            "{} {} {} {} {} {} {} {}",
            p.id,
            num(p.xyz[0]),
            num(p.xyz[1]),
            num(p.xyz[2]),
            p.rgb[0],
            p.rgb[1],
            p.rgb[2],
            num(p.error)
        );
        for t in &p.track {
            let _ = write!(s, " {} {}", t.image_id, t.point2d_idx);
        }
        s.push('\n');
    }
    s
}

/// `rigs.txt` text.
pub fn write_rigs(rigs: &[ColmapRig]) -> String {
    let mut s = String::from(
        "# Rig calib list with one line of data per calib:\n#   RIG_ID, NUM_SENSORS, REF_SENSOR_TYPE, REF_SENSOR_ID, SENSORS[] as (SENSOR_TYPE, SENSOR_ID, HAS_POSE, [QW, QX, QY, QZ, TX, TY, TZ])\n",
    );
    let _ = writeln!(s, "# Number of rigs: {}", rigs.len());
    for r in rigs {
        match &r.ref_sensor {
            None => {
                let _ = write!(s, "{} 0", r.id);
            }
            Some(refs) => {
                let _ = write!(
                    s,
                    "{} {} {} {}",
                    r.id,
                    r.sensors.len() + 1,
                    refs.kind.name(),
                    refs.id
                );
                for x in &r.sensors {
                    let _ = write!(s, " {} {}", x.sensor.kind.name(), x.sensor.id);
                    match &x.sensor_from_rig {
                        None => s.push_str(" 0"),
                        Some(p) => {
                            s.push_str(" 1");
                            put_pose(&mut s, p);
                        }
                    }
                }
            }
        }
        s.push('\n');
    }
    s
}

/// `frames.txt` text.
pub fn write_frames(frames: &[ColmapFrame]) -> String {
    let mut s = String::from(
        "# Frame list with one line of data per frame:\n#   FRAME_ID, RIG_ID, RIG_FROM_WORLD[QW, QX, QY, QZ, TX, TY, TZ], NUM_DATA_IDS, DATA_IDS[] as (SENSOR_TYPE, SENSOR_ID, DATA_ID)\n",
    );
    let _ = writeln!(s, "# Number of frames: {}", frames.len());
    for f in frames {
        let _ = write!(s, "{} {}", f.id, f.rig_id);
        put_pose(&mut s, &f.rig_from_world);
        let _ = write!(s, " {}", f.data_ids.len());
        for d in &f.data_ids {
            let _ = write!(s, " {} {} {}", d.sensor.kind.name(), d.sensor.id, d.id);
        }
        s.push('\n');
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_round_trip_exactly() {
        for v in [
            0.0,
            -0.0,
            1.0,
            0.1,
            1e-7,
            -3.5e-12,
            1.0e20,
            123456.789,
            f64::MIN_POSITIVE,
        ] {
            assert_eq!(num(v).parse::<f64>().unwrap().to_bits(), v.to_bits(), "{v}");
        }
        assert_eq!(num(1e-7), "1e-7");
    }
}
