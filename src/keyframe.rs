//! SLAM keyframes: a pose, a camera and a semi-dense inverse-depth image.
//!
//! The data layout follows LSD-SLAM's `keyframeMsg`: per-pixel arrays in row-major
//! order, index `x + y·width` (x = column, y = row).

use crate::error::{Error, Result};
use crate::geometry::{PinholeCamera, Sim3};

/// One keyframe as a SLAM system publishes it.
#[derive(Clone, Debug)]
pub struct Keyframe {
    /// The SLAM system's keyframe id (LSD-SLAM re-publishes an id as it refines it).
    pub id: i32,
    /// Capture time, seconds (the message's own `time`, not the log time).
    pub timestamp: f64,
    /// `T_slam_cam`: maps camera-frame points into the SLAM frame (LSD-SLAM's
    /// `camToWorld`); its scale is the keyframe's depth normalisation.
    pub pose: Sim3,
    /// Intrinsics; `width × height` is the size of every per-pixel array.
    pub camera: PinholeCamera,
    /// Inverse depth along z (1/units of the SLAM frame), `≤ 0` where unknown.
    pub idepth: Vec<f32>,
    /// Variance of `idepth`, when the SLAM system gives it.
    pub idepth_var: Option<Vec<f32>>,
    /// Colour, 3 bytes a pixel in the order of the source message.
    pub color: Option<Vec<u8>>,
}

/// `pixels` inverse depths are `width × height` of `camera`.
fn check_pixels(id: i32, camera: &PinholeCamera, pixels: usize) -> Result<()> {
    if pixels != camera.width as usize * camera.height as usize {
        return Err(Error::ShapeMismatch {
            what: format!("keyframe {id} idepth"),
            expected: format!("({}, {})", camera.height, camera.width),
            got: format!("{pixels} values"),
        });
    }
    Ok(())
}

/// The keyframe's stamp is finite.
fn check_stamp(id: i32, timestamp: f64) -> Result<()> {
    if !timestamp.is_finite() {
        return Err(Error::NonFinite {
            what: format!("keyframe {id} timestamp"),
            index: 0,
        });
    }
    Ok(())
}

impl Keyframe {
    /// Builds a keyframe, checking every per-pixel array against `width × height`.
    pub fn try_new(
        id: i32,
        timestamp: f64,
        pose: Sim3,
        camera: PinholeCamera,
        idepth: Vec<f32>,
        idepth_var: Option<Vec<f32>>,
        color: Option<Vec<u8>>,
    ) -> Result<Self> {
        let n = camera.width as usize * camera.height as usize;
        let size = format!("({}, {})", camera.height, camera.width);
        check_pixels(id, &camera, idepth.len())?;
        if let Some(v) = &idepth_var {
            if v.len() != n {
                return Err(Error::ShapeMismatch {
                    what: format!("keyframe {id} idepth_var"),
                    expected: size,
                    got: format!("{} values", v.len()),
                });
            }
        }
        if let Some(c) = &color {
            if c.len() != 3 * n {
                return Err(Error::ShapeMismatch {
                    what: format!("keyframe {id} color"),
                    expected: format!("({}, {}, 3)", camera.height, camera.width),
                    got: format!("{} bytes", c.len()),
                });
            }
        }
        check_stamp(id, timestamp)?;
        Ok(Keyframe {
            id,
            timestamp,
            pose,
            camera,
            idepth,
            idepth_var,
            color,
        })
    }

    /// A keyframe whose `pixels` per-pixel values are kept elsewhere (a
    /// bounded-memory read leaves them on disk): the checks of
    /// [`Keyframe::try_new`] on the pose, camera, stamp and pixel count, with
    /// empty arrays. Backprojection needs the arrays put back first.
    pub fn without_pixels(
        id: i32,
        timestamp: f64,
        pose: Sim3,
        camera: PinholeCamera,
        pixels: usize,
    ) -> Result<Self> {
        check_pixels(id, &camera, pixels)?;
        check_stamp(id, timestamp)?;
        Ok(Keyframe {
            id,
            timestamp,
            pose,
            camera,
            idepth: Vec::new(),
            idepth_var: None,
            color: None,
        })
    }

    /// Number of pixels, `width × height`.
    pub fn len(&self) -> usize {
        self.idepth.len()
    }

    /// True for an image with no pixels (never for a keyframe built by `try_new`).
    pub fn is_empty(&self) -> bool {
        self.idepth.is_empty()
    }
}
