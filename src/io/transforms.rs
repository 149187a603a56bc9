//! nerfstudio / instant-ngp `transforms.json`: the camera poses of a NeRF or
//! Gaussian-splatting scene, read as a trajectory and written back carried
//! by a Sim(3) with every other key kept.
//!
//! - `frames[]`: each with `file_path` and `transform_matrix`, the 4×4
//!   camera-to-world `[R t; 0 1]` in the OpenGL camera convention (x right,
//!   y up, looking along −z). The trajectory holds the project's convention
//!   (x right, y down, looking along +z): `R_world_cam = R_gl · diag(1, −1,
//!   −1)`, the same camera centre.
//! - Stamps: when every frame's file name is a stamp
//!   ([`image_name_time`], as for COLMAP images) the frames are ordered by
//!   it; else the frame order (frame `i` at `i` seconds). Two scenes of the
//!   same images pair by file name ([`Transforms::keys`]).
//! - Written back ([`Transforms::carried_bytes`]): each `transform_matrix`
//!   becomes `[R_t R  s R_t t + t_t; 0 1]` (rotation kept orthonormal,
//!   translation scaled); every other key (intrinsics, `file_path`,
//!   `applied_transform`, masks, …) is written as it was read.
//! - A trained model's `dataparser_transforms.json` ([`Dataparser`]) is
//!   rewritten for the carried scene so that the training frame stays put.

use std::path::Path;

use nalgebra::{Matrix3, Matrix4, UnitQuaternion, Vector3};
use serde_json::Value;

use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::io::colmap::image_name_time;
use crate::io::kitti::rotation as check_rotation;
use crate::io::lines::head;
use crate::trajectory::Trajectory;

/// Largest `transforms.json` read, bytes (a scene of 100 000 frames is ~60 MB).
pub const MAX_BYTES: u64 = 1 << 30;

/// One frame of a scene.
#[derive(Clone, Debug)]
pub struct Frame {
    /// `file_path` as written.
    pub file_path: String,
    /// Its index in `frames`.
    pub index: usize,
    /// The 4×4 `transform_matrix` (OpenGL camera convention).
    pub matrix: Matrix4<f64>,
}

/// A `transforms.json`: the document as read and its frames.
#[derive(Clone, Debug)]
pub struct Transforms {
    /// The whole document (written back with only the matrices changed).
    pub doc: Value,
    /// The frames, in file order.
    pub frames: Vec<Frame>,
}

/// The OpenGL-to-OpenCV camera flip, `diag(1, −1, −1)`.
fn flip() -> Matrix3<f64> {
    Matrix3::from_diagonal(&Vector3::new(1.0, -1.0, -1.0))
}

/// Whether the file looks like JSON (its first character that is no white
/// space is `{`): no trajectory text format starts so.
pub fn looks_like_transforms(path: &Path) -> Result<bool> {
    let head = head(path)?;
    let text = String::from_utf8_lossy(&head);
    let text = text.trim_start_matches('\u{feff}');
    Ok(text.trim_start().starts_with('{'))
}

/// Reads a `transforms.json`. Errors: not JSON, no `frames` list, a frame
/// without `file_path` or a 4×4 numeric `transform_matrix`, a rotation part
/// that is none (the frame named), no frames.
pub fn read_transforms(path: &Path) -> Result<Transforms> {
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let len = file.metadata().map_err(|e| Error::io(path, e))?.len();
    if len > MAX_BYTES {
        return Err(Error::parse(
            path,
            0,
            format!("{len} bytes: larger than the {MAX_BYTES} a transforms.json is read to"),
        ));
    }
    let doc: Value = serde_json::from_reader(std::io::BufReader::new(file))
        .map_err(|e| Error::parse(path, e.line(), format!("not a transforms.json: {e}")))?;
    let Some(list) = doc.get("frames").and_then(Value::as_array) else {
        return Err(Error::parse(
            path,
            0,
            "no \"frames\" list: not a transforms.json (nerfstudio / instant-ngp)",
        ));
    };
    let mut frames = Vec::with_capacity(list.len());
    for (index, f) in list.iter().enumerate() {
        let bad = |why: &str| Error::parse(path, 0, format!("frames[{index}]: {why}"));
        let file_path = f
            .get("file_path")
            .and_then(Value::as_str)
            .ok_or_else(|| bad("no \"file_path\" string"))?
            .to_owned();
        let rows = f
            .get("transform_matrix")
            .and_then(Value::as_array)
            .filter(|r| r.len() == 4)
            .ok_or_else(|| bad("no 4×4 \"transform_matrix\""))?;
        let mut m = Matrix4::zeros();
        for (r, row) in rows.iter().enumerate() {
            let row = row
                .as_array()
                .filter(|v| v.len() == 4)
                .ok_or_else(|| bad("no 4×4 \"transform_matrix\""))?;
            for (c, v) in row.iter().enumerate() {
                m[(r, c)] = v
                    .as_f64()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| bad("a \"transform_matrix\" entry that is no finite number"))?;
            }
        }
        check_rotation(&m.fixed_view::<3, 3>(0, 0).into_owned())
            .map_err(|why| bad(&format!("\"transform_matrix\" ({file_path}): {why}")))?;
        frames.push(Frame {
            file_path,
            index,
            matrix: m,
        });
    }
    if frames.is_empty() {
        return Err(Error::parse(path, 0, "\"frames\" is empty: no poses"));
    }
    Ok(Transforms { doc, frames })
}

impl Transforms {
    /// The frames' stamps ([`image_name_time`] of every file name, else the
    /// frame order) and the frames in stamp order.
    pub fn stamped(&self) -> (Vec<f64>, Vec<&Frame>) {
        let names: Option<Vec<f64>> = self
            .frames
            .iter()
            .map(|f| image_name_time(&f.file_path))
            .collect();
        let mut order: Vec<(f64, &Frame)> = match names {
            Some(t) => t.into_iter().zip(&self.frames).collect(),
            None => self.frames.iter().map(|f| (f.index as f64, f)).collect(),
        };
        order.sort_by(|a, b| a.0.total_cmp(&b.0));
        order.into_iter().unzip()
    }

    /// The camera poses as a trajectory in the project's camera convention,
    /// stamped as [`Transforms::stamped`] says.
    pub fn trajectory(&self) -> Result<Trajectory> {
        let (stamps, frames) = self.stamped();
        let (positions, orientations) = frames.iter().map(|f| f.pose()).unzip();
        Trajectory::try_new(stamps, positions, Some(orientations))
    }

    /// The key two scenes of the same images pair by: the file name without
    /// folders and extension (`images/frame_00001.png` → `frame_00001`).
    pub fn key(file_path: &str) -> &str {
        let file = file_path.rsplit(['/', '\\']).next().unwrap_or(file_path);
        file.rsplit_once('.').map_or(file, |(stem, _)| stem)
    }

    /// The document with every `transform_matrix` carried by `t` (the pose
    /// `T_world_cam` becomes `t · T_world_cam`), as pretty JSON; nothing
    /// else changed.
    pub fn carried_bytes(&self, t: &Sim3) -> Result<Vec<u8>> {
        let mut doc = self.doc.clone();
        let r_t = *t.rotation.to_rotation_matrix().matrix();
        let list = doc
            .get_mut("frames")
            .and_then(Value::as_array_mut)
            .ok_or_else(|| Error::invalid("transforms", "no \"frames\" list"))?;
        for f in &self.frames {
            let m = &f.matrix;
            let r = r_t * m.fixed_view::<3, 3>(0, 0);
            let p = t.transform_point(&Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]));
            let rows: Vec<Value> = (0..4)
                .map(|i| {
                    let row: [f64; 4] = if i < 3 {
                        [r[(i, 0)], r[(i, 1)], r[(i, 2)], p[i]]
                    } else {
                        [m[(3, 0)], m[(3, 1)], m[(3, 2)], m[(3, 3)]]
                    };
                    Value::from(row.to_vec())
                })
                .collect();
            list[f.index]["transform_matrix"] = Value::from(rows);
        }
        let mut out = serde_json::to_vec_pretty(&doc)
            .map_err(|e| Error::invalid("transforms", e.to_string()))?;
        out.push(b'\n');
        Ok(out)
    }
}

/// nerfstudio's `dataparser_transforms.json` (a trained model's): the
/// training frame is `scale · (transform · x)` of a point `x` of the scene's
/// frame (`transform` 3×4 `[R t]`, the translation scaled after it).
#[derive(Clone, Debug)]
pub struct Dataparser {
    /// The whole document (written back with `transform` and `scale` changed).
    pub doc: Value,
    /// `R`, `t` of `transform`.
    pub rotation: Matrix3<f64>,
    /// `t` of `transform`.
    pub translation: Vector3<f64>,
    /// `scale`.
    pub scale: f64,
}

/// Reads a `dataparser_transforms.json`: a 3×4 `transform` whose 3×3 part is
/// a rotation and a positive `scale`.
pub fn read_dataparser(path: &Path) -> Result<Dataparser> {
    let text = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let doc: Value = serde_json::from_slice(&text).map_err(|e| {
        Error::parse(
            path,
            e.line(),
            format!("not a dataparser_transforms.json: {e}"),
        )
    })?;
    let bad = |why: &str| Error::parse(path, 0, format!("not a dataparser_transforms.json: {why}"));
    let rows = doc
        .get("transform")
        .and_then(Value::as_array)
        .filter(|r| r.len() == 3)
        .ok_or_else(|| bad("no 3×4 \"transform\""))?;
    let mut m = [[0.0; 4]; 3];
    for (r, row) in rows.iter().enumerate() {
        let row = row
            .as_array()
            .filter(|v| v.len() == 4)
            .ok_or_else(|| bad("no 3×4 \"transform\""))?;
        for (c, v) in row.iter().enumerate() {
            m[r][c] = v
                .as_f64()
                .filter(|x| x.is_finite())
                .ok_or_else(|| bad("a \"transform\" entry that is no finite number"))?;
        }
    }
    let scale = doc
        .get("scale")
        .and_then(Value::as_f64)
        .filter(|s| s.is_finite() && *s > 0.0)
        .ok_or_else(|| bad("no positive \"scale\""))?;
    let rotation = Matrix3::from_fn(|r, c| m[r][c]);
    check_rotation(&rotation).map_err(|why| bad(&format!("\"transform\": {why}")))?;
    Ok(Dataparser {
        translation: Vector3::new(m[0][3], m[1][3], m[2][3]),
        rotation,
        scale,
        doc,
    })
}

impl Dataparser {
    /// The document for the scene carried by `t` (its points `x' = t · x`):
    /// the training frame stays the same, `scale · (transform · x')` of the
    /// new scene equals that of the old, so a model trained before still
    /// fits and its exports land in the new (metric) frame.
    pub fn carried_bytes(&self, t: &Sim3) -> Result<Vec<u8>> {
        // x = R_tᵀ (x' − t_t) / s_t, so scale' = s / s_t, R' = R R_tᵀ and
        // t' = s_t t − R R_tᵀ t_t.
        let r_t = *t.rotation.to_rotation_matrix().matrix();
        let r = self.rotation * r_t.transpose();
        let p = t.scale * self.translation - r * t.translation;
        let rows: Vec<Value> = (0..3)
            .map(|i| Value::from(vec![r[(i, 0)], r[(i, 1)], r[(i, 2)], p[i]]))
            .collect();
        let mut doc = self.doc.clone();
        doc["transform"] = Value::from(rows);
        doc["scale"] = Value::from(self.scale / t.scale);
        let mut out = serde_json::to_vec_pretty(&doc)
            .map_err(|e| Error::invalid("dataparser transforms", e.to_string()))?;
        out.push(b'\n');
        Ok(out)
    }
}

impl Frame {
    /// The camera centre and `R_world_cam` in the project's convention.
    pub fn pose(&self) -> (Vector3<f64>, UnitQuaternion<f64>) {
        let m = &self.matrix;
        let r = m.fixed_view::<3, 3>(0, 0) * flip();
        let q =
            UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(r));
        (Vector3::new(m[(0, 3)], m[(1, 3)], m[(2, 3)]), q)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(dir: &tempfile::TempDir, text: &str) -> std::path::PathBuf {
        let p = dir.path().join("transforms.json");
        std::fs::write(&p, text).unwrap();
        p
    }

    const TWO: &str = r#"{
  "fl_x": 500.5, "w": 640, "camera_model": "OPENCV",
  "frames": [
    {"file_path": "images/frame_00002.png", "transform_matrix": [[1,0,0,1],[0,1,0,2],[0,0,1,3],[0,0,0,1]], "mask_path": "m.png"},
    {"file_path": "images/frame_00001.png", "transform_matrix": [[0,-1,0,0],[1,0,0,0],[0,0,1,-1],[0,0,0,1]]}
  ],
  "applied_transform": [[0,1,0,0],[1,0,0,0],[0,0,-1,0]]
}"#;

    #[test]
    fn poses_turn_to_the_opencv_camera_and_back() {
        let dir = tempfile::tempdir().unwrap();
        let t = read_transforms(&scene(&dir, TWO)).unwrap();
        let traj = t.trajectory().unwrap();
        // File names without stamps: the frame order.
        assert_eq!(traj.timestamps, vec![0.0, 1.0]);
        assert_eq!(traj.positions[0], Vector3::new(1.0, 2.0, 3.0));
        // The first camera looks along −z of the world in OpenGL: +z of its own frame is −z.
        let forward = traj.orientations.as_ref().unwrap()[0] * Vector3::z();
        assert!((forward - Vector3::new(0.0, 0.0, -1.0)).norm() < 1e-15);
        assert_eq!(Transforms::key(&t.frames[0].file_path), "frame_00002");
        let s = Sim3 {
            rotation: UnitQuaternion::from_euler_angles(0.3, -0.2, 1.0),
            translation: Vector3::new(5.0, -1.0, 2.0),
            scale: 2.5,
        };
        let out = dir.path().join("out.json");
        std::fs::write(&out, t.carried_bytes(&s).unwrap()).unwrap();
        let back = read_transforms(&out).unwrap();
        let moved = back.trajectory().unwrap();
        for i in 0..2 {
            let want = s.transform_point(&traj.positions[i]);
            assert!((moved.positions[i] - want).norm() < 1e-12);
            let q = s.rotation * traj.orientations.as_ref().unwrap()[i];
            assert!(moved.orientations.as_ref().unwrap()[i].angle_to(&q) < 1e-12);
        }
        // Every other key as it was.
        let mut a = back.doc.clone();
        let mut b = t.doc.clone();
        for d in [&mut a, &mut b] {
            for f in d["frames"].as_array_mut().unwrap() {
                f.as_object_mut().unwrap().remove("transform_matrix");
            }
        }
        assert_eq!(a, b);
    }

    #[test]
    fn bad_scenes_say_what_is_wrong() {
        let dir = tempfile::tempdir().unwrap();
        let e = read_transforms(&scene(&dir, r#"{"fl_x": 1}"#))
            .unwrap_err()
            .to_string();
        assert!(e.contains("no \"frames\" list"), "{e}");
        let e = read_transforms(&scene(&dir, "{\"frames\": [}"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a transforms.json"), "{e}");
        let e = read_transforms(&scene(&dir, r#"{"frames": []}"#))
            .unwrap_err()
            .to_string();
        assert!(e.contains("empty"), "{e}");
        let scaled = r#"{"frames": [{"file_path": "a.png", "transform_matrix": [[2,0,0,0],[0,2,0,0],[0,0,2,0],[0,0,0,1]]}]}"#;
        let e = read_transforms(&scene(&dir, scaled))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("frames[0]") && e.contains("not a rotation"),
            "{e}"
        );
        let short = r#"{"frames": [{"file_path": "a.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0]]}]}"#;
        let e = read_transforms(&scene(&dir, short))
            .unwrap_err()
            .to_string();
        assert!(e.contains("4×4"), "{e}");
        assert!(looks_like_transforms(&scene(&dir, "\n  {\"frames\": []}")).unwrap());
    }
}
