//! Trajectory text files.
//!
//! - TUM: one pose per line, `timestamp tx ty tz qx qy qz qw` (seconds,
//!   metres, quaternion `(x, y, z, w)`), `#` comment lines.
//! - EuRoC ground truth CSV (`state_groundtruth_estimate0/data.csv`):
//!   `timestamp [ns], p_x, p_y, p_z, q_w, q_x, q_y, q_z, …` (w first; further
//!   columns ignored), `#` header. Times become seconds (`ns / 1e9`, as evo does).
//! - KITTI odometry poses: [`crate::io::kitti`].
//! - EuRoC IMU CSV (`imu0/data.csv`): `timestamp [ns], w_x, w_y, w_z [rad/s],
//!   a_x, a_y, a_z [m/s²]`.

use std::path::Path;

use nalgebra::{UnitQuaternion, Vector3};

use crate::error::{Error, Result};
use crate::geometry::unit_quaternion_xyzw;
use crate::imu::ImuSamples;
pub use crate::io::lines::MAX_LINE_BYTES;
use crate::io::lines::{bounded_lines, for_each_line, parse_fields, pose_text};
use crate::trajectory::Trajectory;

/// Trajectory file formats.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum TrajectoryFormat {
    /// `timestamp tx ty tz qx qy qz qw` (seconds).
    #[default]
    Tum,
    /// EuRoC ground truth CSV: `ns, x, y, z, qw, qx, qy, qz, …`.
    Euroc,
    /// KITTI odometry poses: the 12 numbers of `[R | t]` a line, no stamps
    /// ([`crate::io::kitti`]).
    Kitti,
    /// nerfstudio / instant-ngp `transforms.json` ([`crate::io::transforms`]).
    Transforms,
}

impl std::str::FromStr for TrajectoryFormat {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s.to_ascii_lowercase().as_str() {
            "tum" => Ok(TrajectoryFormat::Tum),
            "euroc" => Ok(TrajectoryFormat::Euroc),
            "kitti" => Ok(TrajectoryFormat::Kitti),
            "transforms" => Ok(TrajectoryFormat::Transforms),
            _ => Err(Error::invalid(
                "format",
                format!(
                    "expected \"tum\", \"euroc\", \"kitti\" or \"transforms\", got {}",
                    crate::error::cut(s)
                ),
            )),
        }
    }
}

impl TrajectoryFormat {
    /// Reads a trajectory file in this format ([`read_tum`], [`read_euroc`],
    /// [`crate::io::kitti::read_kitti`] with the pose index for stamps).
    pub fn read(self, path: impl AsRef<Path>) -> Result<Trajectory> {
        match self {
            TrajectoryFormat::Tum => read_tum(path),
            TrajectoryFormat::Euroc => read_euroc(path),
            TrajectoryFormat::Kitti => {
                crate::io::kitti::read_kitti(path.as_ref(), &crate::io::kitti::KittiStamps::Index)
            }
            TrajectoryFormat::Transforms => {
                crate::io::transforms::read_transforms(path.as_ref())?.trajectory()
            }
        }
    }

    /// The format of a reference file: `given`, else what
    /// [`TrajectoryFormat::of_file`] finds, where a TUM-looking file takes
    /// the format given for the estimate (`--format`), if any.
    pub fn of_reference(
        given: Option<TrajectoryFormat>,
        est_given: Option<TrajectoryFormat>,
        path: &Path,
    ) -> Result<TrajectoryFormat> {
        if let Some(f) = given {
            return Ok(f);
        }
        Ok(match Self::of_file(None, path)? {
            TrajectoryFormat::Tum => est_given.unwrap_or(TrajectoryFormat::Tum),
            found => found,
        })
    }

    /// The format of a file: `given`, else a `transforms.json` when it is
    /// JSON, KITTI when its first pose line holds 12 numbers, else TUM.
    pub fn of_file(given: Option<TrajectoryFormat>, path: &Path) -> Result<TrajectoryFormat> {
        if let Some(f) = given {
            return Ok(f);
        }
        Ok(if crate::io::transforms::looks_like_transforms(path)? {
            TrajectoryFormat::Transforms
        } else if crate::io::kitti::looks_like_kitti(path)? {
            TrajectoryFormat::Kitti
        } else {
            TrajectoryFormat::Tum
        })
    }
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
                    format!(
                        "timestamp {} is earlier than the previous one ({})",
                        crate::error::num(t),
                        crate::error::num(last)
                    ),
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

/// Reads a TUM trajectory file (`timestamp tx ty tz qx qy qz qw` per line),
/// as a stream of lines of at most [`MAX_LINE_BYTES`].
pub fn read_tum(path: impl AsRef<Path>) -> Result<Trajectory> {
    let path = path.as_ref();
    let mut b = Builder::new(path);
    for_each_line(path, "a TUM trajectory", |k, raw| {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            return Ok(());
        }
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.len() != 8 {
            return Err(Error::parse(
                path,
                k,
                format!(
                    "expected 8 values (timestamp tx ty tz qx qy qz qw), got {}",
                    fields.len()
                ),
            ));
        }
        let v = parse_fields(path, k, &fields)?;
        b.push(k, v[0], [v[1], v[2], v[3]], [v[4], v[5], v[6], v[7]])
    })?;
    b.finish()
}

/// Reads EuRoC ground truth CSV (`ns, x, y, z, qw, qx, qy, qz[, …]`).
pub fn read_euroc(path: impl AsRef<Path>) -> Result<Trajectory> {
    let path = path.as_ref();
    let mut b = Builder::new(path);
    for_each_line(path, "a EuRoC ground-truth CSV", |k, raw| {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            return Ok(());
        }
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() < 8 {
            return Err(Error::parse(
                path,
                k,
                format!(
                    "expected at least 8 comma-separated values (ns, x, y, z, qw, qx, qy, qz), got {}",
                    fields.len()
                ),
            ));
        }
        let v = parse_fields(path, k, &fields[..8])?;
        b.push(k, v[0] / 1e9, [v[1], v[2], v[3]], [v[5], v[6], v[7], v[4]])
    })?;
    b.finish()
}

/// Writes a TUM file, atomically (temporary file in the same folder, renamed).
/// Numbers are written in the shortest form that reads back exactly; poses
/// without orientation get the identity quaternion.
pub fn write_tum(traj: &Trajectory, path: impl AsRef<Path>) -> Result<()> {
    let path = path.as_ref();
    let bytes = tum_bytes(traj)?;
    crate::io::atomic::write_bytes_atomic(path, &bytes)
}

/// The TUM text of `traj` ([`write_tum`]'s content).
pub fn tum_bytes(traj: &Trajectory) -> Result<Vec<u8>> {
    use std::fmt::Write as _;
    pose_text(
        traj,
        "TUM",
        "# timestamp tx ty tz qx qy qz qw\n",
        |s, t, p, q| {
            let q = q.coords; // (x, y, z, w)
                              // Writing into a String cannot fail.
            let _ = writeln!(
                s,
                "{t} {} {} {} {} {} {} {}",
                p.x, p.y, p.z, q[0], q[1], q[2], q[3]
            );
        },
    )
}

/// The EuRoC ground-truth CSV text of `traj`: a `#timestamp [ns],p_x [m],…`
/// header, then `ns,x,y,z,qw,qx,qy,qz` rows (the stamps as whole
/// nanoseconds, the rest in the shortest form that reads back exactly);
/// poses without orientation get the identity quaternion.
pub fn euroc_bytes(traj: &Trajectory) -> Result<Vec<u8>> {
    use std::fmt::Write as _;
    let header = "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],\
                  q_RS_y [],q_RS_z []\n";
    pose_text(traj, "EuRoC", header, |s, t, p, q| {
        let q = q.coords; // (x, y, z, w)
                          // Writing into a String cannot fail.
        let _ = writeln!(
            s,
            "{:.0},{},{},{},{},{},{},{}",
            t * 1e9,
            p.x,
            p.y,
            p.z,
            q[3],
            q[0],
            q[1],
            q[2]
        );
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
    let (mut timestamps, mut gyro, mut accel) = (Vec::new(), Vec::new(), Vec::new());
    for_each_line(path, "a EuRoC IMU CSV", |k, raw| {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            return Ok(());
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != 7 {
            return Err(Error::parse(
                path,
                k,
                format!(
                    "expected 7 comma-separated values (ns, gyro x y z, accel x y z), got {}",
                    fields.len()
                ),
            ));
        }
        // Integer nanoseconds where they are written so (EuRoC); a float otherwise.
        let t = match fields[0].parse::<i64>() {
            Ok(ns) => ns as f64 * 1e-9,
            Err(_) => parse_fields(path, k, &fields[..1])?[0] * 1e-9,
        };
        let v = parse_fields(path, k, &fields[1..])?;
        timestamps.push(t);
        gyro.push(Vector3::new(v[0], v[1], v[2]));
        accel.push(Vector3::new(v[3], v[4], v[5]));
        Ok(())
    })?;
    ImuSamples::try_new(timestamps, gyro, accel)
}

/// The unit of the time stamps of a trajectory file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimeUnit {
    /// Seconds.
    Seconds,
    /// Milliseconds.
    Milliseconds,
    /// Microseconds.
    Microseconds,
    /// Nanoseconds (ORB-SLAM3's EuRoC runs write them as floats).
    Nanoseconds,
}

impl TimeUnit {
    /// Seconds per unit.
    pub fn seconds(self) -> f64 {
        match self {
            TimeUnit::Seconds => 1.0,
            TimeUnit::Milliseconds => 1e-3,
            TimeUnit::Microseconds => 1e-6,
            TimeUnit::Nanoseconds => 1e-9,
        }
    }

    /// Units per second (1, 1e3, 1e6, 1e9).
    pub fn per_second(self) -> f64 {
        match self {
            TimeUnit::Seconds => 1.0,
            TimeUnit::Milliseconds => 1e3,
            TimeUnit::Microseconds => 1e6,
            TimeUnit::Nanoseconds => 1e9,
        }
    }

    /// Stamps read in this unit (now seconds), as the file wrote them.
    pub fn written(self, seconds: &[f64]) -> Vec<f64> {
        seconds.iter().map(|s| s * self.per_second()).collect()
    }

    /// Stamps read in this unit (now seconds) read again in `unit`.
    pub fn reread(self, seconds: &mut [f64], unit: TimeUnit) {
        if unit != self {
            // Back to the written value first: ns stamps of 1.7e18 keep their
            // last digits (a factor 1e-9 taken first would cost them).
            let (from, to) = (self.per_second(), unit.per_second());
            seconds.iter_mut().for_each(|s| *s = *s * from / to);
        }
    }

    /// `"s"`, `"ms"`, `"us"`, `"ns"`.
    pub fn symbol(self) -> &'static str {
        match self {
            TimeUnit::Seconds => "s",
            TimeUnit::Milliseconds => "ms",
            TimeUnit::Microseconds => "us",
            TimeUnit::Nanoseconds => "ns",
        }
    }

    /// From `"s"`, `"ms"`, `"us"` (or `"µs"`), `"ns"`.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "s" => Ok(TimeUnit::Seconds),
            "ms" => Ok(TimeUnit::Milliseconds),
            "us" | "µs" => Ok(TimeUnit::Microseconds),
            "ns" => Ok(TimeUnit::Nanoseconds),
            _ => Err(Error::invalid(
                "time_unit",
                format!("expected \"s\", \"ms\", \"us\" or \"ns\", got {s:?}"),
            )),
        }
    }

    const ALL: [TimeUnit; 4] = [
        TimeUnit::Seconds,
        TimeUnit::Milliseconds,
        TimeUnit::Microseconds,
        TimeUnit::Nanoseconds,
    ];
}

/// How the fields of a trajectory file are separated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Delimiter {
    /// Spaces or tabs (TUM).
    Whitespace,
    /// Commas (CSV), spaces around them allowed.
    Comma,
}

/// What [`read_trajectory`] found out about a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TextInfo {
    /// The unit the stamps were read in (converted to seconds).
    pub unit: TimeUnit,
    /// True when the unit was detected ([`detect_time_unit`]), false when the
    /// caller gave it.
    pub unit_detected: bool,
    /// The field separator, decided by the first record.
    pub delimiter: Delimiter,
    /// True when a header line (a first record that is not numbers) was skipped.
    pub header: bool,
    /// Rows whose stamp equals the previous row's: dropped, the first row of
    /// each stamp is kept.
    pub repeated_stamps: usize,
}

/// The unit of a file's stamps, from their magnitude and spacing.
///
/// Read in a unit, the stamps have *camera-like spacing* when their median
/// positive step is between 10 µs and 10 s (100 kHz to 0.1 Hz) and the
/// largest is at most 4.2e9 s; they *look like Unix time* when the largest is
/// between 1e8 and 4.2e9 s (1973 to 2103; at most one unit can). The first
/// rule that picks a unit decides: (1) camera-like spacing and Unix time;
/// (2) camera-like spacing, the coarsest such unit (seconds first); (3) Unix
/// time; (4) seconds. With one stamp there is no spacing and (1) is Unix time
/// alone. Examples: EuRoC ORB-SLAM3 `1.4036e18` → ns; TUM `1.3e9` → s; frame
/// indices `0, 1, 2, …` → s; `0, 33, 66, …` → ms; stamps since boot
/// `3e11, 3e11 + 3.3e7, …` → ns. Relative stamps more than 10 s apart read
/// as a finer unit: give the unit for those.
pub fn detect_time_unit(stamps: &[f64]) -> TimeUnit {
    Stamps::of(stamps).own_unit()
}

/// Seconds that are Unix time: 1973 to 2103.
const UNIX_SECONDS: std::ops::RangeInclusive<f64> = 1e8..=4.2e9;

/// What the unit rules look at in a file's stamps: the largest magnitude and
/// the median positive step (none with fewer than two distinct stamps).
#[derive(Clone, Copy, Debug)]
struct Stamps {
    max: f64,
    step: Option<f64>,
}

impl Stamps {
    fn of(stamps: &[f64]) -> Stamps {
        let mut dt: Vec<f64> = stamps
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|d| *d > 0.0)
            .collect();
        let step = if dt.is_empty() {
            None
        } else {
            let mid = dt.len() / 2;
            dt.select_nth_unstable_by(mid, f64::total_cmp);
            Some(dt[mid])
        };
        Stamps {
            max: stamps.iter().fold(0.0f64, |m, t| m.max(t.abs())),
            step,
        }
    }

    /// Whether the stamps read in `u` are Unix time.
    fn unix(self, u: TimeUnit) -> bool {
        UNIX_SECONDS.contains(&(self.max * u.seconds()))
    }

    /// The unit of [`detect_time_unit`] (see there).
    fn own_unit(self) -> TimeUnit {
        let spacing = |u: TimeUnit| {
            self.max * u.seconds() <= *UNIX_SECONDS.end() && camera_like(self.step, u)
        };
        let pick = |rule: &dyn Fn(TimeUnit) -> bool| TimeUnit::ALL.into_iter().find(|&u| rule(u));
        pick(&|u| spacing(u) && self.unix(u))
            .or_else(|| pick(&spacing))
            .or_else(|| pick(&|u| self.unix(u)))
            .unwrap_or(TimeUnit::Seconds)
    }
}

/// Whether a median step read in `unit` is one of a camera, an IMU or a
/// ground truth: 10 µs to 10 s (100 kHz to 0.1 Hz); no step passes.
fn camera_like(median: Option<f64>, unit: TimeUnit) -> bool {
    median.is_none_or(|d| (1e-5..=10.0).contains(&(d * unit.seconds())))
}

/// The factor between neighbouring units (s, ms, µs, ns).
const UNIT_STEP: f64 = 1e3;

/// The median steps, seconds, of the streams an estimate and a reference
/// come in: 0.2 ms (a 5 kHz IMU or motion capture) to 60 s (keyframes a
/// minute apart).
const PAIR_STEP: std::ops::RangeInclusive<f64> = 2e-4..=60.0;

/// A 30 Hz camera's step, seconds: the middle of the steps on a log scale.
const TYPICAL_STEP: f64 = 1.0 / 30.0;

/// How much the time spans `a` and `b` (first, last) share: the length of
/// their intersection over that of their union, 1 for the same span, 0 for
/// spans apart; two single stamps at the same time count as 1.
fn span_overlap(a: (f64, f64), b: (f64, f64)) -> f64 {
    let inter = a.1.min(b.1) - a.0.max(b.0);
    let union = a.1.max(b.1) - a.0.min(b.0);
    if union > 0.0 {
        inter.max(0.0) / union
    } else if inter == 0.0 {
        1.0
    } else {
        0.0
    }
}

/// The units of two trajectories' stamps that record the same motion (an
/// estimate and its reference), each judged against the other.
///
/// `est` and `reference` are the stamps as written; `est_given` and
/// `ref_given` are units the caller knows (they stay as given). Read in the
/// right units, the two time spans (the estimate's shifted by `offset`
/// seconds) lie over each other: their intersection is at least `1000^-1/2`
/// (3 %) of their union. That bound is the geometric middle between one span
/// read twice (1) and a span read in a neighbouring unit against its true one
/// (1/1000 at most), so it holds for any run length, rate or clock base.
/// Every combination of units (given ones fixed) that passes is a candidate;
/// the one giving more sides a sensor's median step wins (0.2 ms to 60 s),
/// then the one reading more sides as Unix time (1973 to 2103), then the one
/// that keeps more sides at their own unit (the given one, or [`detect_time_unit`] of its
/// stamps), then the larger overlap, then the one whose steps lie nearer a
/// 30 Hz camera's on a log scale (both sides read a unit off alike overlap as
/// much). Two files on one clock from 0, both read a
/// unit off alike, overlap as well as read right: only their steps tell them
/// apart, and a file too sparse for a camera-like step (keyframes over 10 s
/// apart) beside a partner whose step misleads cannot be told. When no
/// combination passes (clocks apart by more than the run, which an offset
/// estimate is for) or a side is empty, the own units stand and the
/// association says what it sees.
pub fn match_time_units(
    est: &[f64],
    reference: &[f64],
    est_given: Option<TimeUnit>,
    ref_given: Option<TimeUnit>,
    offset: f64,
) -> (TimeUnit, TimeUnit) {
    let (est_stamps, ref_stamps) = (Stamps::of(est), Stamps::of(reference));
    let own_est = est_given.unwrap_or_else(|| est_stamps.own_unit());
    let own_ref = ref_given.unwrap_or_else(|| ref_stamps.own_unit());
    let (Some(&e0), Some(&e1), Some(&r0), Some(&r1)) =
        (est.first(), est.last(), reference.first(), reference.last())
    else {
        return (own_est, own_ref);
    };
    let overlap = |ue: TimeUnit, ur: TimeUnit| {
        let (se, sr) = (ue.per_second(), ur.per_second());
        span_overlap((e0 / se + offset, e1 / se + offset), (r0 / sr, r1 / sr))
    };
    let enough = UNIT_STEP.sqrt().recip();
    let choices = |given: Option<TimeUnit>| match given {
        Some(u) => vec![u],
        None => TimeUnit::ALL.to_vec(),
    };
    // A side read in a unit: whether its median step is one of a sensor's
    // (PAIR_STEP) and whether it is Unix time.
    let reading = |side: Stamps, u: TimeUnit| {
        let sensor = side
            .step
            .is_none_or(|d| PAIR_STEP.contains(&(d * u.seconds())));
        (usize::from(sensor), usize::from(side.unix(u)))
    };
    // ((sensor steps, Unix clocks, sides at their own unit), overlap, units)
    let mut passing = Vec::new();
    for ue in choices(est_given) {
        for ur in choices(ref_given) {
            let o = overlap(ue, ur);
            if o >= enough {
                let (se, ee) = reading(est_stamps, ue);
                let (sr, er) = reading(ref_stamps, ur);
                let own = usize::from(ue == own_est) + usize::from(ur == own_ref);
                passing.push(((se + sr, ee + er, own), o, ue, ur));
            }
        }
    }
    let Some(top) = passing.iter().map(|c| c.0).max() else {
        return (own_est, own_ref);
    };
    passing.retain(|c| c.0 == top);
    let most = passing.iter().fold(0.0f64, |m, c| m.max(c.1));
    // Read a unit off alike, both steps move 1000-fold: the tie goes to the
    // steps nearer a 30 Hz camera's, on a log scale.
    let off_typical = |step: Option<f64>, u: TimeUnit| {
        step.map_or(0.0, |d| (d * u.seconds() / TYPICAL_STEP).log10().abs())
    };
    let off = |c: &(_, f64, TimeUnit, TimeUnit)| {
        off_typical(est_stamps.step, c.2) + off_typical(ref_stamps.step, c.3)
    };
    passing
        .into_iter()
        .filter(|c| c.1 >= most * (1.0 - 1e-9))
        .min_by(|a, b| off(a).total_cmp(&off(b)))
        .map_or((own_est, own_ref), |c| (c.2, c.3))
}

/// Reads a trajectory in TUM column order (`timestamp tx ty tz qx qy qz qw`)
/// as the SLAM systems write it — DPVO `--save_trajectory`, MASt3R-SLAM
/// `logs/*.txt`, DSO `result.txt`, ORB-SLAM3 `f_*.txt` / `kf_*.txt` — with
/// what those files vary in found out and reported in [`TextInfo`]:
/// - the time unit ([`detect_time_unit`], or `time_unit` when given); stamps
///   are converted to seconds;
/// - commas instead of white space (decided by the first record);
/// - one header line (a first record whose fields are not numbers);
/// - repeated stamps: the first row of each stamp is kept, the rest dropped
///   and counted. Stamps that go back in time are an error naming the line.
///
/// Lines longer than [`MAX_LINE_BYTES`] are a format error. `#` lines and
/// blank lines are skipped. For files [`read_tum`] reads, the poses are the
/// same (the unit then detected as seconds).
pub fn read_trajectory(path: &Path, time_unit: Option<TimeUnit>) -> Result<(Trajectory, TextInfo)> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(Error::parse(path, 0, "not a regular file"));
    }
    let reader = std::io::BufReader::new(file);
    let mut delimiter = None;
    let mut header = false;
    let mut first = true;
    let mut rows: Vec<(usize, [f64; 8])> = Vec::new();
    bounded_lines(path, "a trajectory file", reader, |k, raw| {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            return Ok(());
        }
        let delim = *delimiter.get_or_insert(if line.contains(',') {
            Delimiter::Comma
        } else {
            Delimiter::Whitespace
        });
        let fields: Vec<&str> = match delim {
            Delimiter::Comma => line.split(',').map(str::trim).collect(),
            Delimiter::Whitespace => line.split_whitespace().collect(),
        };
        if std::mem::replace(&mut first, false) && fields[0].parse::<f64>().is_err() {
            header = true;
            return Ok(());
        }
        if fields.len() != 8 {
            return Err(Error::parse(
                path,
                k,
                format!(
                    "expected 8 values (timestamp tx ty tz qx qy qz qw), got {}",
                    fields.len()
                ),
            ));
        }
        let v = parse_fields(path, k, &fields)?;
        rows.push((k, [v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7]]));
        Ok(())
    })?;
    let stamps: Vec<f64> = rows.iter().map(|r| r.1[0]).collect();
    let (unit, unit_detected) = match time_unit {
        Some(u) => (u, false),
        None => (detect_time_unit(&stamps), true),
    };
    let mut b = Builder::new(path);
    let mut repeated = 0;
    let mut last = None;
    for (k, v) in &rows {
        if last == Some(v[0]) {
            repeated += 1;
            continue;
        }
        if let Some(prev) = last {
            if v[0] < prev {
                return Err(Error::parse(
                    path,
                    *k,
                    format!(
                        "timestamp {} is earlier than the previous one ({prev})",
                        v[0]
                    ),
                ));
            }
        }
        last = Some(v[0]);
        // Divided by units per second (exact for 1e3, 1e6, 1e9), as evo does for ns.
        let t = v[0] / unit.per_second();
        b.push(*k, t, [v[1], v[2], v[3]], [v[4], v[5], v[6], v[7]])?;
    }
    let info = TextInfo {
        unit,
        unit_detected,
        delimiter: delimiter.unwrap_or(Delimiter::Whitespace),
        header,
        repeated_stamps: repeated,
    };
    Ok((b.finish()?, info))
}
