//! Pinhole camera (LSD-SLAM convention: x right, y down, z forward; pixel
//! `(x, y)` = (column, row), integer indices at pixel centres).

use crate::error::{Error, Result};

/// A distortion-free pinhole camera: focal lengths and principal point in pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PinholeCamera {
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x (column), pixels.
    pub cx: f64,
    /// Principal point y (row), pixels.
    pub cy: f64,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}

impl PinholeCamera {
    /// Checks that the focal lengths are finite and positive, the principal
    /// point finite, and the image non-empty.
    pub fn try_new(fx: f64, fy: f64, cx: f64, cy: f64, width: u32, height: u32) -> Result<Self> {
        for (name, v) in [("fx", fx), ("fy", fy)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::invalid(
                    name,
                    format!("must be finite and > 0, got {v}"),
                ));
            }
        }
        for (name, v) in [("cx", cx), ("cy", cy)] {
            if !v.is_finite() {
                return Err(Error::invalid(name, format!("must be finite, got {v}")));
            }
        }
        if width == 0 || height == 0 {
            return Err(Error::invalid(
                "image size",
                format!("must be non-empty, got {width}x{height}"),
            ));
        }
        Ok(PinholeCamera {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
        })
    }

    /// A camera with the principal point at the image centre and the given
    /// horizontal field of view (degrees); square pixels.
    pub fn from_hfov(width: u32, height: u32, hfov_deg: f64) -> Result<Self> {
        if !(hfov_deg > 0.0 && hfov_deg < 180.0) {
            return Err(Error::invalid(
                "hfov",
                format!("must be in (0, 180) degrees, got {hfov_deg}"),
            ));
        }
        let f = 0.5 * width as f64 / (0.5 * hfov_deg.to_radians()).tan();
        Self::try_new(
            f,
            f,
            0.5 * (width as f64 - 1.0),
            0.5 * (height as f64 - 1.0),
            width,
            height,
        )
    }

    /// The point at `depth` along z that projects to pixel `(x, y)`:
    /// `((x − cx)/fx · d, (y − cy)/fy · d, d)`.
    #[inline]
    pub fn backproject(&self, x: f64, y: f64, depth: f64) -> [f64; 3] {
        [
            (x - self.cx) / self.fx * depth,
            (y - self.cy) / self.fy * depth,
            depth,
        ]
    }

    /// Pixel coordinates of a camera-frame point (z must be > 0 to be in front).
    #[inline]
    pub fn project(&self, p: &[f64; 3]) -> [f64; 2] {
        [
            self.fx * p[0] / p[2] + self.cx,
            self.fy * p[1] / p[2] + self.cy,
        ]
    }
}
