//! KITTI odometry pose files, as the odometry benchmark, ORB-SLAM2/3, DSO
//! and evo (`evo_ape kitti`, `--save_as_kitti`) write them.
//!
//! - One pose a line: the 12 numbers of the 3×4 matrix `[R | t]`
//!   (camera-to-world, row-major), white-space separated; blank and `#`
//!   lines are skipped. The 3×3 part must be a rotation to within
//!   [`ROTATION_TOLERANCE`] (the benchmark's files carry 6–10 significant
//!   digits); it is read as the nearest unit quaternion.
//! - No stamps in the file: they come from the sequence's `times.txt` (one
//!   number of seconds a line, [`read_times`]), from a frame rate, or are the
//!   pose index (two files without stamps pair by index, as evo pairs them)
//!   — [`KittiStamps`].
//! - Written ([`write_kitti`]) with every number in the shortest form that
//!   reads back exactly (evo writes `%.18e`, which holds the same value).

use std::path::Path;

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};

use crate::error::{num, Error, Result};
use crate::io::lines::{for_each_line, head, parse_fields, pose_text};
use crate::trajectory::Trajectory;

/// Largest entry of `|RᵀR − I|` (and of `|det R − 1|`) a pose's 3×3 part may
/// have: a rotation written with six significant digits is off by ~1e-6; a
/// matrix that is no rotation (a scaled or sheared one, columns swapped) is
/// off by far more.
pub const ROTATION_TOLERANCE: f64 = 1e-3;

/// Camera positions and orientations `R_world_cam`, in file order.
pub type Poses = (Vec<Vector3<f64>>, Vec<UnitQuaternion<f64>>);

/// Where a KITTI file's stamps come from.
#[derive(Clone, Debug, PartialEq)]
pub enum KittiStamps {
    /// Pose `i` at `i` seconds: files without stamps pair by index.
    Index,
    /// Pose `i` at `i / rate` seconds.
    Rate(f64),
    /// One stamp per pose, seconds (a `times.txt`).
    Times(Vec<f64>),
}

/// Reads the poses of a KITTI file: camera positions and orientations
/// (`R_world_cam`), in file order. Errors name the line: a count other than
/// 12, a field that is no finite number, a 3×3 part that is no rotation; a
/// file without poses is an error too.
pub fn read_kitti_poses(path: &Path) -> Result<Poses> {
    let mut positions = Vec::new();
    let mut orientations = Vec::new();
    for_each_line(path, "a KITTI pose file", |k, raw| {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            return Ok(());
        }
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.len() != 12 {
            return Err(Error::parse(
                path,
                k,
                format!(
                    "expected 12 values (the 3×4 matrix [R | t], row by row), got {}",
                    fields.len()
                ),
            ));
        }
        let v = parse_fields(path, k, &fields)?;
        let r = Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
        let q = rotation(&r).map_err(|why| Error::parse(path, k, why))?;
        positions.push(Vector3::new(v[3], v[7], v[11]));
        orientations.push(q);
        Ok(())
    })?;
    if positions.is_empty() {
        return Err(Error::parse(path, 0, "no poses in the file"));
    }
    Ok((positions, orientations))
}

/// The unit quaternion of a 3×3 matrix that is a rotation to within
/// [`ROTATION_TOLERANCE`], or why it is not one.
pub(crate) fn rotation(r: &Matrix3<f64>) -> std::result::Result<UnitQuaternion<f64>, String> {
    let off = (r.transpose() * r - Matrix3::identity()).abs().max();
    let det = r.determinant();
    if off > ROTATION_TOLERANCE || (det - 1.0).abs() > ROTATION_TOLERANCE {
        return Err(format!(
            "the 3×3 part is not a rotation (largest entry of |RᵀR − I| {}, det {})",
            num(off),
            num(det)
        ));
    }
    Ok(UnitQuaternion::from_rotation_matrix(
        &Rotation3::from_matrix_unchecked(*r),
    ))
}

/// Reads a KITTI file with its stamps (see [`KittiStamps`]); a `times.txt`
/// with another count than the poses' is an error naming both counts.
pub fn read_kitti(path: &Path, stamps: &KittiStamps) -> Result<Trajectory> {
    let (positions, orientations) = read_kitti_poses(path)?;
    let n = positions.len();
    let timestamps = match stamps {
        KittiStamps::Index => (0..n).map(|i| i as f64).collect(),
        KittiStamps::Rate(rate) => {
            if !(rate.is_finite() && *rate > 0.0) {
                return Err(Error::invalid(
                    "rate",
                    format!(
                        "must be a positive number of poses per second, got {}",
                        num(*rate)
                    ),
                ));
            }
            (0..n).map(|i| i as f64 / rate).collect()
        }
        KittiStamps::Times(t) => {
            if t.len() != n {
                return Err(Error::invalid(
                    "times",
                    format!(
                        "{} stamps for the {n} poses of {}: one stamp a pose",
                        t.len(),
                        path.display()
                    ),
                ));
            }
            t.clone()
        }
    };
    Trajectory::try_new(timestamps, positions, Some(orientations))
}

/// Reads a KITTI `times.txt`: one number of seconds a line (blank and `#`
/// lines skipped), not decreasing.
pub fn read_times(path: &Path) -> Result<Vec<f64>> {
    let mut times: Vec<f64> = Vec::new();
    for_each_line(path, "a times file", |k, raw| {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            return Ok(());
        }
        let fields: Vec<&str> = line.split_whitespace().collect();
        if fields.len() != 1 {
            return Err(Error::parse(
                path,
                k,
                format!("expected one stamp (seconds), got {} values", fields.len()),
            ));
        }
        let t = parse_fields(path, k, &fields)?[0];
        if let Some(&last) = times.last() {
            if t < last {
                return Err(Error::parse(
                    path,
                    k,
                    format!(
                        "stamp {} is earlier than the previous one ({})",
                        num(t),
                        num(last)
                    ),
                ));
            }
        }
        times.push(t);
        Ok(())
    })?;
    if times.is_empty() {
        return Err(Error::parse(path, 0, "no stamps in the file"));
    }
    Ok(times)
}

/// Whether the file's first pose line holds 12 numbers (a KITTI file; a TUM
/// line holds 8, a EuRoC row 8 or more separated by commas).
pub fn looks_like_kitti(path: &Path) -> Result<bool> {
    let head = head(path)?;
    let text = String::from_utf8_lossy(&head);
    let first = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'));
    Ok(first.is_some_and(|l| {
        let fields: Vec<&str> = l.split_whitespace().collect();
        fields.len() == 12 && fields.iter().all(|f| f.parse::<f64>().is_ok())
    }))
}

/// The KITTI text of `traj` ([`write_kitti`]'s content); poses without
/// orientation get the identity rotation. The stamps are not in it
/// ([`times_bytes`]).
pub fn kitti_bytes(traj: &Trajectory) -> Result<Vec<u8>> {
    use std::fmt::Write as _;
    pose_text(traj, "KITTI", "", |s, _, t, q| {
        let r = q.to_rotation_matrix();
        let r = r.matrix();
        for row in 0..3 {
            let sep = if row == 0 { "" } else { " " };
            // Writing into a String cannot fail.
            let _ = write!(
                s,
                "{sep}{} {} {} {}",
                r[(row, 0)],
                r[(row, 1)],
                r[(row, 2)],
                t[row]
            );
        }
        s.push('\n');
    })
}

/// The stamps of `traj` as a KITTI `times.txt` (one number of seconds a
/// line, the shortest form that reads back exactly).
pub fn times_bytes(traj: &Trajectory) -> Vec<u8> {
    let mut s = String::with_capacity(20 * traj.len());
    for t in &traj.timestamps {
        s += &format!("{t}\n");
    }
    s.into_bytes()
}

/// Writes a KITTI file, atomically (temporary file in the same folder, renamed).
pub fn write_kitti(traj: &Trajectory, path: &Path) -> Result<()> {
    let bytes = kitti_bytes(traj)?;
    crate::io::atomic::write_bytes_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file(dir: &tempfile::TempDir, name: &str, text: &str) -> std::path::PathBuf {
        let p = dir.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    fn sample() -> Trajectory {
        let q = UnitQuaternion::from_euler_angles(0.1, -0.4, 2.9);
        Trajectory::try_new(
            vec![0.5, 0.6, 0.75],
            vec![
                Vector3::new(1.0, 2.0, 3.0),
                Vector3::new(-0.1, 1e-12, 7.25),
                Vector3::new(1.0 / 3.0, 0.0, -2.0),
            ],
            Some(vec![UnitQuaternion::identity(), q, q.inverse()]),
        )
        .unwrap()
    }

    #[test]
    fn written_poses_read_back_exactly_with_their_stamps() {
        let dir = tempfile::tempdir().unwrap();
        let t = sample();
        let p = dir.path().join("poses.txt");
        write_kitti(&t, &p).unwrap();
        let times = file(
            &dir,
            "times.txt",
            &String::from_utf8(times_bytes(&t)).unwrap(),
        );
        assert!(looks_like_kitti(&p).unwrap());
        let back = read_kitti(&p, &KittiStamps::Times(read_times(&times).unwrap())).unwrap();
        assert_eq!(back.timestamps, t.timestamps);
        assert_eq!(back.positions, t.positions);
        let (a, b) = (back.orientations.unwrap(), t.orientations.unwrap());
        for (x, y) in a.iter().zip(&b) {
            assert!(x.angle_to(y) < 1e-15, "{x:?} {y:?}");
        }
        let by_index = read_kitti(&p, &KittiStamps::Index).unwrap();
        assert_eq!(by_index.timestamps, vec![0.0, 1.0, 2.0]);
        let by_rate = read_kitti(&p, &KittiStamps::Rate(10.0)).unwrap();
        assert_eq!(by_rate.timestamps, vec![0.0, 0.1, 0.2]);
    }

    #[test]
    fn bad_files_name_the_line() {
        let dir = tempfile::tempdir().unwrap();
        let id = "1 0 0 0 0 1 0 0 0 0 1 0";
        let short = file(&dir, "short.txt", &format!("{id}\n1 0 0 0 0 1 0 0 0 0 1\n"));
        let e = read_kitti_poses(&short).unwrap_err().to_string();
        assert!(e.contains(":2:") && e.contains("got 11"), "{e}");
        let scaled = file(&dir, "scaled.txt", "2 0 0 0 0 2 0 0 0 0 2 0\n");
        let e = read_kitti_poses(&scaled).unwrap_err().to_string();
        assert!(e.contains(":1:") && e.contains("not a rotation"), "{e}");
        let mirrored = file(&dir, "mirrored.txt", "-1 0 0 0 0 1 0 0 0 0 1 0\n");
        let e = read_kitti_poses(&mirrored).unwrap_err().to_string();
        assert!(e.contains("not a rotation"), "{e}");
        let word = file(
            &dir,
            "word.txt",
            &format!("{id}\n1 0 0 x 0 1 0 0 0 0 1 0\n"),
        );
        let e = read_kitti_poses(&word).unwrap_err().to_string();
        assert!(e.contains(":2:") && e.contains("field 4"), "{e}");
        let empty = file(&dir, "empty.txt", "\n# nothing\n");
        assert!(read_kitti_poses(&empty).is_err());
        let ok = file(&dir, "ok.txt", &format!("{id}\n{id}\n"));
        let e = read_kitti(&ok, &KittiStamps::Times(vec![0.0]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("1 stamps for the 2 poses"), "{e}");
        let e = read_kitti(&ok, &KittiStamps::Rate(0.0))
            .unwrap_err()
            .to_string();
        assert!(e.contains("positive"), "{e}");
        let back = file(&dir, "times.txt", "0.1\n0.05\n");
        let e = read_times(&back).unwrap_err().to_string();
        assert!(e.contains(":2:") && e.contains("earlier"), "{e}");
        assert!(!looks_like_kitti(&file(&dir, "tum.txt", "0 1 2 3 0 0 0 1\n")).unwrap());
    }

    #[test]
    fn a_rotation_written_with_six_digits_is_read() {
        let dir = tempfile::tempdir().unwrap();
        // KITTI ground truth, sequence 00, a line as the benchmark writes it.
        let p = file(
            &dir,
            "00.txt",
            "9.999978e-01 5.272628e-04 -2.066935e-03 -4.690294e-02 -5.296506e-04 9.999992e-01 \
             -1.154865e-03 -2.839928e-02 2.066324e-03 1.155958e-03 9.999971e-01 8.586941e-01\n",
        );
        let (pos, q) = read_kitti_poses(&p).unwrap();
        assert_eq!(
            pos[0],
            Vector3::new(-4.690294e-02, -2.839928e-02, 8.586941e-01)
        );
        assert!(q[0].angle() < 3e-3);
    }
}
