//! Trajectory text files.
//!
//! - TUM: one pose per line, `timestamp tx ty tz qx qy qz qw` (seconds,
//!   metres, quaternion `(x, y, z, w)`), `#` comment lines.
//! - EuRoC ground truth CSV (`state_groundtruth_estimate0/data.csv`):
//!   `timestamp [ns], p_x, p_y, p_z, q_w, q_x, q_y, q_z, …` (w first; further
//!   columns ignored), `#` header. Times become seconds (`ns / 1e9`, as evo does).
//! - EuRoC IMU CSV (`imu0/data.csv`): `timestamp [ns], w_x, w_y, w_z [rad/s],
//!   a_x, a_y, a_z [m/s²]`.

use std::io::Write;
use std::path::Path;

use nalgebra::{UnitQuaternion, Vector3};

use crate::error::{Error, Result};
use crate::geometry::unit_quaternion_xyzw;
use crate::imu::ImuSamples;
use crate::trajectory::Trajectory;

/// Trajectory file formats.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TrajectoryFormat {
    /// `timestamp tx ty tz qx qy qz qw` (seconds).
    #[default]
    Tum,
    /// EuRoC ground truth CSV: `ns, x, y, z, qw, qx, qy, qz, …`.
    Euroc,
}

impl std::str::FromStr for TrajectoryFormat {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "tum" => Ok(TrajectoryFormat::Tum),
            "euroc" => Ok(TrajectoryFormat::Euroc),
            _ => Err(Error::invalid(
                "format",
                format!(
                    "expected \"tum\" or \"euroc\", got {}",
                    crate::error::cut(s)
                ),
            )),
        }
    }
}

/// Reads a trajectory file in `format`.
pub fn read_trajectory(path: impl AsRef<Path>, format: TrajectoryFormat) -> Result<Trajectory> {
    let path = path.as_ref();
    match format {
        TrajectoryFormat::Tum => read_tum(path),
        TrajectoryFormat::Euroc => read_euroc(path),
    }
}

/// Reads a file as UTF-8 text, dropping a leading byte-order mark.
fn read_text(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(&bytes);
    String::from_utf8(bytes.to_vec()).map_err(|e| {
        Error::parse(
            path,
            0,
            format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
        )
    })
}

fn parse_fields(path: &Path, line: usize, fields: &[&str]) -> Result<Vec<f64>> {
    fields
        .iter()
        .enumerate()
        .map(|(k, f)| {
            let v: f64 = f.trim().parse().map_err(|_| {
                Error::parse(
                    path,
                    line,
                    format!("field {} is not a number: {f:?}", k + 1),
                )
            })?;
            if !v.is_finite() {
                return Err(Error::parse(
                    path,
                    line,
                    format!("field {} is not finite: {f:?}", k + 1),
                ));
            }
            Ok(v)
        })
        .collect()
}

/// Collects parsed rows into a trajectory, checking time order with the line
/// numbers of the file.
struct Builder<'a> {
    path: &'a Path,
    stamps: Vec<f64>,
    positions: Vec<Vector3<f64>>,
    orientations: Vec<UnitQuaternion<f64>>,
}

impl<'a> Builder<'a> {
    fn new(path: &'a Path) -> Self {
        Builder {
            path,
            stamps: Vec::new(),
            positions: Vec::new(),
            orientations: Vec::new(),
        }
    }

    fn push(&mut self, line: usize, t: f64, p: [f64; 3], q_xyzw: [f64; 4]) -> Result<()> {
        if let Some(&last) = self.stamps.last() {
            if t < last {
                return Err(Error::parse(
                    self.path,
                    line,
                    format!("timestamp {t} is earlier than the previous one ({last})"),
                ));
            }
        }
        let q = unit_quaternion_xyzw(q_xyzw)
            .map_err(|e| Error::parse(self.path, line, format!("quaternion: {e}")))?;
        self.stamps.push(t);
        self.positions.push(Vector3::from(p));
        self.orientations.push(q);
        Ok(())
    }

    fn finish(self) -> Result<Trajectory> {
        if self.stamps.is_empty() {
            return Err(Error::parse(self.path, 0, "no poses in the file"));
        }
        Trajectory::try_new(self.stamps, self.positions, Some(self.orientations))
    }
}

/// Reads a TUM trajectory file (`timestamp tx ty tz qx qy qz qw` per line).
pub fn read_tum(path: impl AsRef<Path>) -> Result<Trajectory> {
    let path = path.as_ref();
    let text = read_text(path)?;
    let mut b = Builder::new(path);
    for (k, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.len() != 8 {
            return Err(Error::parse(
                path,
                k + 1,
                format!(
                    "expected 8 values (timestamp tx ty tz qx qy qz qw), got {}",
                    fields.len()
                ),
            ));
        }
        let v = parse_fields(path, k + 1, &fields)?;
        b.push(k + 1, v[0], [v[1], v[2], v[3]], [v[4], v[5], v[6], v[7]])?;
    }
    b.finish()
}

/// Reads EuRoC ground truth CSV (`ns, x, y, z, qw, qx, qy, qz[, …]`).
pub fn read_euroc(path: impl AsRef<Path>) -> Result<Trajectory> {
    let path = path.as_ref();
    let text = read_text(path)?;
    let mut b = Builder::new(path);
    for (k, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() < 8 {
            return Err(Error::parse(
                path,
                k + 1,
                format!(
                    "expected at least 8 comma-separated values (ns, x, y, z, qw, qx, qy, qz), got {}",
                    fields.len()
                ),
            ));
        }
        let v = parse_fields(path, k + 1, &fields[..8])?;
        b.push(
            k + 1,
            v[0] / 1e9,
            [v[1], v[2], v[3]],
            [v[5], v[6], v[7], v[4]],
        )?;
    }
    b.finish()
}

/// Writes a TUM file, atomically (temporary file in the same folder, renamed).
/// Numbers are written in the shortest form that reads back exactly; poses
/// without orientation get the identity quaternion.
pub fn write_tum(traj: &Trajectory, path: impl AsRef<Path>) -> Result<()> {
    let path = path.as_ref();
    traj.check_lengths()?;
    crate::io::atomic::write_atomic(path, |file| {
        let mut w = std::io::BufWriter::new(file);
        let io = |e| Error::io(path, e);
        writeln!(w, "# timestamp tx ty tz qx qy qz qw").map_err(io)?;
        for i in 0..traj.len() {
            let p = traj.positions[i];
            let q = match &traj.orientations {
                Some(o) => o[i].coords, // (x, y, z, w)
                None => UnitQuaternion::<f64>::identity().coords,
            };
            writeln!(
                w,
                "{} {} {} {} {} {} {} {}",
                traj.timestamps[i], p.x, p.y, p.z, q[0], q[1], q[2], q[3]
            )
            .map_err(io)?;
        }
        w.flush().map_err(io)
    })
}

/// Reads EuRoC `imu0/data.csv` content: `timestamp [ns], w_x, w_y, w_z
/// [rad/s], a_x, a_y, a_z [m/s²]` per line, `#` comment lines and blank
/// lines skipped. Times become seconds (integer nanoseconds read exactly).
///
/// Errors: [`Error::Io`], [`Error::Parse`] (with the line number) for a
/// malformed line, and the checks of [`ImuSamples::try_new`].
pub fn read_euroc_imu(path: impl AsRef<Path>) -> Result<ImuSamples> {
    let path = path.as_ref();
    let text = read_text(path)?;
    let (mut timestamps, mut gyro, mut accel) = (Vec::new(), Vec::new(), Vec::new());
    for (k, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != 7 {
            return Err(Error::parse(
                path,
                k + 1,
                format!(
                    "expected 7 comma-separated values (ns, gyro x y z, accel x y z), got {}",
                    fields.len()
                ),
            ));
        }
        // Integer nanoseconds where they are written so (EuRoC); a float otherwise.
        let t = match fields[0].parse::<i64>() {
            Ok(ns) => ns as f64 * 1e-9,
            Err(_) => parse_fields(path, k + 1, &fields[..1])?[0] * 1e-9,
        };
        let v = parse_fields(path, k + 1, &fields[1..])?;
        timestamps.push(t);
        gyro.push(Vector3::new(v[0], v[1], v[2]));
        accel.push(Vector3::new(v[3], v[4], v[5]));
    }
    ImuSamples::try_new(timestamps, gyro, accel)
}
