//! COLMAP camera models (`src/colmap/sensor/models.h`): ids, names, number of
//! parameters, and where the pinhole part sits in the parameter list.

use crate::error::{Error, Result};
use crate::geometry::PinholeCamera;

/// Every camera model COLMAP defines, with its numeric id (the `int` in
/// `cameras.bin`) and its name (the word in `cameras.txt`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CameraModel {
    /// 0 `SIMPLE_PINHOLE`: f, cx, cy.
    SimplePinhole,
    /// 1 `PINHOLE`: fx, fy, cx, cy.
    Pinhole,
    /// 2 `SIMPLE_RADIAL`: f, cx, cy, k.
    SimpleRadial,
    /// 3 `RADIAL`: f, cx, cy, k1, k2.
    Radial,
    /// 4 `OPENCV`: fx, fy, cx, cy, k1, k2, p1, p2.
    OpenCv,
    /// 5 `OPENCV_FISHEYE`: fx, fy, cx, cy, k1, k2, k3, k4.
    OpenCvFisheye,
    /// 6 `FULL_OPENCV`: fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6.
    FullOpenCv,
    /// 7 `FOV`: fx, fy, cx, cy, omega.
    Fov,
    /// 8 `SIMPLE_RADIAL_FISHEYE`: f, cx, cy, k.
    SimpleRadialFisheye,
    /// 9 `RADIAL_FISHEYE`: f, cx, cy, k1, k2.
    RadialFisheye,
    /// 10 `THIN_PRISM_FISHEYE`: fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, sx1, sy1.
    ThinPrismFisheye,
    /// 11 `RAD_TAN_THIN_PRISM_FISHEYE`: fx, fy, cx, cy, k0..k5, p0, p1, s0..s3.
    RadTanThinPrismFisheye,
    /// 12 `SIMPLE_DIVISION`: f, cx, cy, k.
    SimpleDivision,
    /// 13 `DIVISION`: fx, fy, cx, cy, k.
    Division,
    /// 14 `SIMPLE_FISHEYE`: f, cx, cy.
    SimpleFisheye,
    /// 15 `FISHEYE`: fx, fy, cx, cy.
    Fisheye,
    /// 16 `EUCM`: fx, fy, cx, cy, alpha, beta.
    Eucm,
    /// 17 `EQUIRECTANGULAR`: w, h (metadata; no focal length).
    Equirectangular,
}

/// `(model, id, name, number of parameters, number of focal lengths)`.
const TABLE: [(CameraModel, i32, &str, usize, usize); 18] = [
    (CameraModel::SimplePinhole, 0, "SIMPLE_PINHOLE", 3, 1),
    (CameraModel::Pinhole, 1, "PINHOLE", 4, 2),
    (CameraModel::SimpleRadial, 2, "SIMPLE_RADIAL", 4, 1),
    (CameraModel::Radial, 3, "RADIAL", 5, 1),
    (CameraModel::OpenCv, 4, "OPENCV", 8, 2),
    (CameraModel::OpenCvFisheye, 5, "OPENCV_FISHEYE", 8, 2),
    (CameraModel::FullOpenCv, 6, "FULL_OPENCV", 12, 2),
    (CameraModel::Fov, 7, "FOV", 5, 2),
    (
        CameraModel::SimpleRadialFisheye,
        8,
        "SIMPLE_RADIAL_FISHEYE",
        4,
        1,
    ),
    (CameraModel::RadialFisheye, 9, "RADIAL_FISHEYE", 5, 1),
    (
        CameraModel::ThinPrismFisheye,
        10,
        "THIN_PRISM_FISHEYE",
        12,
        2,
    ),
    (
        CameraModel::RadTanThinPrismFisheye,
        11,
        "RAD_TAN_THIN_PRISM_FISHEYE",
        16,
        2,
    ),
    (CameraModel::SimpleDivision, 12, "SIMPLE_DIVISION", 4, 1),
    (CameraModel::Division, 13, "DIVISION", 5, 2),
    (CameraModel::SimpleFisheye, 14, "SIMPLE_FISHEYE", 3, 1),
    (CameraModel::Fisheye, 15, "FISHEYE", 4, 2),
    (CameraModel::Eucm, 16, "EUCM", 6, 2),
    (CameraModel::Equirectangular, 17, "EQUIRECTANGULAR", 2, 0),
];

impl CameraModel {
    /// All models, in id order.
    pub const ALL: [CameraModel; 18] = {
        let mut all = [CameraModel::SimplePinhole; 18];
        let mut i = 0;
        while i < 18 {
            all[i] = TABLE[i].0;
            i += 1;
        }
        all
    };

    fn row(self) -> &'static (CameraModel, i32, &'static str, usize, usize) {
        &TABLE[self as usize]
    }

    /// The model with COLMAP's numeric id.
    pub fn from_id(id: i32) -> Option<Self> {
        usize::try_from(id)
            .ok()
            .and_then(|i| TABLE.get(i))
            .map(|r| r.0)
    }

    /// The model with COLMAP's name (`"OPENCV"`, …).
    pub fn from_name(name: &str) -> Option<Self> {
        TABLE.iter().find(|r| r.2 == name).map(|r| r.0)
    }

    /// COLMAP's numeric id.
    pub fn id(self) -> i32 {
        self.row().1
    }

    /// COLMAP's name.
    pub fn name(self) -> &'static str {
        self.row().2
    }

    /// Number of parameters the model stores.
    pub fn num_params(self) -> usize {
        self.row().3
    }

    /// Indices of `(fx, fy, cx, cy)` in the parameter list (`fx == fy` for
    /// the models with one focal length); `None` for a model without a focal
    /// length (`EQUIRECTANGULAR`).
    pub fn pinhole_indices(self) -> Option<[usize; 4]> {
        match self.row().4 {
            1 => Some([0, 0, 1, 2]),
            2 => Some([0, 1, 2, 3]),
            _ => None,
        }
    }
}

/// One camera of a model.
#[derive(Clone, Debug, PartialEq)]
pub struct ColmapCamera {
    /// COLMAP's `camera_id`.
    pub id: u32,
    /// The camera model.
    pub model: CameraModel,
    /// Image width, pixels.
    pub width: u64,
    /// Image height, pixels.
    pub height: u64,
    /// The model's parameters in COLMAP's order (`model.num_params()` values),
    /// pixels where they are lengths; kept as read, distortion included.
    pub params: Vec<f64>,
}

impl ColmapCamera {
    /// The pinhole part of the camera (focal lengths and principal point; the
    /// distortion is dropped) in this project's pixel convention.
    ///
    /// COLMAP puts the centre of the upper-left pixel at `(0.5, 0.5)`; here
    /// pixel centres are the integer indices, so `cx = cx_colmap − 0.5` and
    /// `cy = cy_colmap − 0.5`. Errors for a model without a focal length and
    /// for image sizes above `u32::MAX`.
    pub fn pinhole(&self) -> Result<PinholeCamera> {
        let what = || format!("camera {} ({})", self.id, self.model.name());
        let [ifx, ify, icx, icy] = self.model.pinhole_indices().ok_or_else(|| {
            Error::invalid(what(), "the model has no focal length, so no pinhole part")
        })?;
        let p = |i: usize| {
            self.params.get(i).copied().ok_or_else(|| {
                Error::invalid(
                    what(),
                    format!(
                        "{} parameters, the model needs {}",
                        self.params.len(),
                        self.model.num_params()
                    ),
                )
            })
        };
        let size = |v: u64| {
            u32::try_from(v)
                .map_err(|_| Error::invalid(what(), format!("image size {v} exceeds u32")))
        };
        PinholeCamera::try_new(
            p(ifx)?,
            p(ify)?,
            p(icx)? - 0.5,
            p(icy)? - 0.5,
            size(self.width)?,
            size(self.height)?,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_names_and_counts_agree_with_the_table() {
        for (i, m) in CameraModel::ALL.iter().enumerate() {
            assert_eq!(m.id(), i as i32);
            assert_eq!(CameraModel::from_id(m.id()), Some(*m));
            assert_eq!(CameraModel::from_name(m.name()), Some(*m));
        }
        assert_eq!(CameraModel::from_id(18), None);
        assert_eq!(CameraModel::from_id(-1), None);
        assert_eq!(CameraModel::OpenCv.num_params(), 8);
        assert_eq!(CameraModel::RadTanThinPrismFisheye.num_params(), 16);
    }

    #[test]
    fn pinhole_part_moves_the_principal_point_to_pixel_centres() {
        let c = ColmapCamera {
            id: 1,
            model: CameraModel::SimpleRadial,
            width: 640,
            height: 480,
            params: vec![500.0, 320.0, 240.0, 0.01],
        };
        let p = c.pinhole().unwrap();
        assert_eq!((p.fx, p.fy, p.cx, p.cy), (500.0, 500.0, 319.5, 239.5));
        let e = ColmapCamera {
            model: CameraModel::Equirectangular,
            params: vec![640.0, 480.0],
            ..c
        };
        assert!(e.pinhole().is_err());
    }
}
