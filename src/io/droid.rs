//! DROID-SLAM reconstruction folders: the arrays `demo.py --reconstruction_path`
//! saves (`save_reconstruction`, princeton-vl/DROID-SLAM 8016d2b), one `.npy`
//! file each:
//!
//! | file | shape, dtype | what |
//! |---|---|---|
//! | `tstamps.npy` | (N,) float | the frame index DROID-SLAM was given for each keyframe |
//! | `images.npy` | (N, 3, H, W) uint8 | the keyframe images, **BGR** (OpenCV), channel first |
//! | `poses.npy` | (N, 7) float | **world-to-camera** `[tx, ty, tz, qx, qy, qz, qw]` (lietorch SE3) |
//! | `disps.npy` | (N, h, w) float | disparity = inverse depth along z, 1/model units |
//! | `intrinsics.npy` | (N, 4) float | `fx, fy, cx, cy` at 1/8 of the image resolution |
//!
//! `disps.npy` is `video.disps_up` (full resolution, `h = H`) in the upstream
//! demo and `video.disps` (`h = H/8`) in forks and older scripts: the grid is
//! worked out from the shapes (`H = r·h`, `W = r·w` for an integer `r`) and the
//! intrinsics scaled by `8/r` to it, as DROID-SLAM's own `view_reconstruction.py`
//! does (`4 * intrinsics` for its half-resolution grid). Pixel coordinates are
//! DROID-SLAM's: the integer index, no half-pixel shift.

use std::path::Path;

use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::geometry::{PinholeCamera, Sim3};
use crate::io::npy::{read_npy, NpyArray, NpyData, NpyDtype};
use crate::keyframe::Keyframe;

/// What [`read_droid`] found.
#[derive(Clone, Debug)]
pub struct DroidReconstruction {
    /// One keyframe per saved frame: `id` = index in the arrays, `timestamp` =
    /// `tstamps[i]`, `pose` = `T_slam_cam` (the inverse of the stored pose),
    /// `idepth` = disparity on the disparity grid, `color` = RGB from the image
    /// sampled on that grid, no variance.
    pub keyframes: Vec<Keyframe>,
    /// Image size `(height, width)`, pixels.
    pub image_size: (u32, u32),
    /// Image pixels per disparity pixel, `r` (8 for `disps`, 1 for `disps_up`).
    pub downsample: u32,
}

/// The five files, in the order they are checked.
const FILES: [&str; 5] = [
    "tstamps.npy",
    "images.npy",
    "poses.npy",
    "disps.npy",
    "intrinsics.npy",
];

fn shape_err(dir: &Path, file: &str, expected: String, a: &NpyArray) -> Error {
    Error::Reconstruction {
        path: dir.join(file),
        reason: format!(
            "expected shape {expected}, found {:?} ({:?})",
            a.shape,
            a.dtype()
        ),
    }
}

fn is_float(a: &NpyArray) -> bool {
    matches!(a.dtype(), NpyDtype::F32 | NpyDtype::F64)
}

/// Reads a DROID-SLAM reconstruction folder (see the module documentation).
pub fn read_droid(dir: &Path) -> Result<DroidReconstruction> {
    let missing: Vec<&str> = FILES
        .iter()
        .copied()
        .filter(|f| !dir.join(f).is_file())
        .collect();
    if !missing.is_empty() {
        return Err(Error::Reconstruction {
            path: dir.into(),
            reason: format!(
                "not a DROID-SLAM reconstruction folder: missing {}",
                missing.join(", ")
            ),
        });
    }
    let [tstamps, images, poses, disps, intrinsics] = FILES.map(|f| read_npy(&dir.join(f)));
    let (tstamps, images, poses, disps, intrinsics) =
        (tstamps?, images?, poses?, disps?, intrinsics?);
    let n = match (tstamps.shape.as_slice(), is_float(&tstamps)) {
        ([n], true) => *n,
        _ => return Err(shape_err(dir, "tstamps.npy", "(N,) float".into(), &tstamps)),
    };
    let (big_h, big_w) = match images.shape.as_slice() {
        [m, 3, h, w] if *m == n && images.dtype() == NpyDtype::U8 => (*h, *w),
        _ => {
            return Err(shape_err(
                dir,
                "images.npy",
                format!("({n}, 3, H, W) uint8"),
                &images,
            ))
        }
    };
    if poses.shape != [n, 7] || !is_float(&poses) {
        return Err(shape_err(
            dir,
            "poses.npy",
            format!("({n}, 7) float"),
            &poses,
        ));
    }
    if intrinsics.shape != [n, 4] || !is_float(&intrinsics) {
        return Err(shape_err(
            dir,
            "intrinsics.npy",
            format!("({n}, 4) float"),
            &intrinsics,
        ));
    }
    let (h, w) = match disps.shape.as_slice() {
        [m, h, w] if *m == n && is_float(&disps) && *h > 0 && *w > 0 => (*h, *w),
        _ => {
            return Err(shape_err(
                dir,
                "disps.npy",
                format!("({n}, h, w) float"),
                &disps,
            ))
        }
    };
    let r = big_h / h;
    if r == 0 || big_h != r * h || big_w != r * w {
        return Err(Error::Reconstruction {
            path: dir.join("disps.npy"),
            reason: format!(
                "disparity grid {h}x{w} is not the image grid {big_h}x{big_w} divided by a whole number \
                 (expected {}x{} for disps or {big_h}x{big_w} for disps_up)",
                big_h / 8,
                big_w / 8
            ),
        });
    }
    let size = |v: usize| {
        u32::try_from(v)
            .map_err(|_| Error::invalid("DROID-SLAM image size", format!("{v} exceeds u32")))
    };
    let (h32, w32, r32) = (size(h)?, size(w)?, size(r)?);
    let k = 8.0 / r as f64;
    let t = tstamps.to_f64();
    let p = poses.to_f64();
    let kin = intrinsics.to_f64();
    let d = disps.to_f32();
    let NpyData::U8(img) = &images.data else {
        return Err(shape_err(
            dir,
            "images.npy",
            format!("({n}, 3, H, W) uint8"),
            &images,
        ));
    };
    let plane = big_h * big_w;
    let off = (r - 1) / 2;
    let mut keyframes = Vec::with_capacity(n);
    for i in 0..n {
        let g = &p[7 * i..7 * i + 7];
        let q = Quaternion::new(g[6], g[3], g[4], g[5]);
        if g.iter().any(|v| !v.is_finite()) || q.norm() < 1e-12 {
            return Err(Error::Reconstruction {
                path: dir.join("poses.npy"),
                reason: format!("pose {i} is not a valid [tx ty tz qx qy qz qw]: {g:?}"),
            });
        }
        let cam_from_world = Sim3 {
            rotation: UnitQuaternion::from_quaternion(q),
            translation: Vector3::new(g[0], g[1], g[2]),
            scale: 1.0,
        };
        let c = &kin[4 * i..4 * i + 4];
        let camera = PinholeCamera::try_new(c[0] * k, c[1] * k, c[2] * k, c[3] * k, w32, h32)
            .map_err(|e| Error::Reconstruction {
                path: dir.join("intrinsics.npy"),
                reason: format!("frame {i}: {e}"),
            })?;
        let idepth = d[i * h * w..(i + 1) * h * w].to_vec();
        let base = i * 3 * plane;
        let mut color = Vec::with_capacity(3 * h * w);
        for y in 0..h {
            for x in 0..w {
                let at = (r * y + off) * big_w + r * x + off;
                // BGR planes → RGB bytes.
                color.extend([
                    img[base + 2 * plane + at],
                    img[base + plane + at],
                    img[base + at],
                ]);
            }
        }
        let id =
            i32::try_from(i).map_err(|_| Error::invalid("DROID-SLAM frames", "more than 2^31"))?;
        keyframes.push(Keyframe::try_new(
            id,
            t[i],
            cam_from_world.inverse(),
            camera,
            idepth,
            None,
            Some(color),
        )?);
    }
    Ok(DroidReconstruction {
        keyframes,
        image_size: (size(big_h)?, size(big_w)?),
        downsample: r32,
    })
}

/// The multi-view depth consistency check of DROID-SLAM's viewer
/// (`droid_backends.depth_filter`, `src/droid_kernels.cu`).
#[derive(Clone, Debug, PartialEq)]
pub struct DepthFilter {
    /// A neighbour agrees when the depth of the reprojected point differs by
    /// less than this from the neighbour's depth at one of the four pixels
    /// around the projection (model units of depth). DROID-SLAM's viewers use
    /// 0.005 (`view_reconstruction.py`, `visualization.py`).
    pub threshold: f64,
    /// Keep a pixel seen consistently by at least this many neighbours (the
    /// viewers: 2).
    pub min_count: u32,
    /// Keep a pixel whose disparity exceeds this fraction of its keyframe's
    /// mean disparity (drops far, unreliable points; `visualization.py`: 0.5,
    /// `view_reconstruction.py`: 0.25); 0 disables it.
    pub min_disparity_ratio: f64,
    /// The neighbours checked, as offsets in the keyframe list. The kernel
    /// checks `i−1, i−2, i−3, i+3, i+4, i+5` (its `ix + neigh_id` for the upper
    /// three skips `i+1, i+2`); that set is the default, to match its output.
    pub neighbours: Vec<isize>,
}

impl Default for DepthFilter {
    fn default() -> Self {
        DepthFilter {
            threshold: crate::defaults::DEPTH_THRESHOLD,
            min_count: crate::defaults::DEPTH_MIN_COUNT,
            min_disparity_ratio: crate::defaults::MIN_DISPARITY_RATIO,
            neighbours: vec![-1, -2, -3, 3, 4, 5],
        }
    }
}

/// For every pixel of every keyframe, the number of neighbouring keyframes
/// ([`DepthFilter::neighbours`]) that see it at a consistent depth: the pixel
/// `(x, y)` with disparity `d > 0` is backprojected at depth `1/d`, carried
/// into the neighbour's camera (`T_cam_j_slam · T_slam_cam_i`), projected to
/// `(u, v)` at depth `z > 0`; with `u0 = ⌊u⌋`, `v0 = ⌊v⌋` and
/// `0 ≤ u0 < w−1`, `0 ≤ v0 < h−1`, the neighbour counts when
/// `|z − 1/d_j| < threshold` at any of the four pixels `(u0 + {0,1}, v0 + {0,1})`
/// with `d_j > 0`. Keyframes must share one image size.
pub fn depth_consistency_counts(
    keyframes: &[Keyframe],
    filter: &DepthFilter,
) -> Result<Vec<Vec<u32>>> {
    if !(filter.threshold.is_finite() && filter.threshold > 0.0) {
        return Err(Error::invalid(
            "threshold",
            format!("must be finite and > 0, got {}", filter.threshold),
        ));
    }
    let Some(first) = keyframes.first() else {
        return Ok(Vec::new());
    };
    let (w, h) = (first.camera.width as usize, first.camera.height as usize);
    if let Some(k) = keyframes.iter().find(|k| {
        (k.camera.width as usize, k.camera.height as usize) != (w, h) || k.idepth.len() != w * h
    }) {
        return Err(Error::ShapeMismatch {
            what: format!("keyframe {} image", k.id),
            expected: format!("({h}, {w}) like the first keyframe"),
            got: format!("({}, {})", k.camera.height, k.camera.width),
        });
    }
    let n = keyframes.len();
    let counts = keyframes
        .par_iter()
        .enumerate()
        .map(|(i, ki)| {
            let mut count = vec![0u32; w * h];
            for &off in &filter.neighbours {
                let Some(j) = i.checked_add_signed(off).filter(|&j| j < n && j != i) else {
                    continue;
                };
                let kj = &keyframes[j];
                let rel = kj.pose.inverse() * ki.pose;
                let (m, t) = rel.affine();
                let cj = &kj.camera;
                for y in 0..h {
                    for x in 0..w {
                        let d = ki.idepth[y * w + x] as f64;
                        if d.is_nan() || d <= 0.0 {
                            continue;
                        }
                        let p = ki.camera.backproject(x as f64, y as f64, 1.0 / d);
                        let q = [
                            m[0][0] * p[0] + m[0][1] * p[1] + m[0][2] * p[2] + t[0],
                            m[1][0] * p[0] + m[1][1] * p[1] + m[1][2] * p[2] + t[1],
                            m[2][0] * p[0] + m[2][1] * p[1] + m[2][2] * p[2] + t[2],
                        ];
                        if q[2].is_nan() || q[2] <= 0.0 {
                            continue;
                        }
                        let [u, v] = cj.project(&q);
                        let (u0, v0) = (u.floor(), v.floor());
                        if !(u0 >= 0.0 && v0 >= 0.0 && u0 < (w - 1) as f64 && v0 < (h - 1) as f64) {
                            continue;
                        }
                        let (u0, v0) = (u0 as usize, v0 as usize);
                        let agrees = [(0, 0), (1, 0), (0, 1), (1, 1)].iter().any(|&(dx, dy)| {
                            let dj = kj.idepth[(v0 + dy) * w + u0 + dx] as f64;
                            dj > 0.0 && (q[2] - 1.0 / dj).abs() < filter.threshold
                        });
                        if agrees {
                            count[y * w + x] += 1;
                        }
                    }
                }
            }
            count
        })
        .collect();
    Ok(counts)
}

/// The keyframes with every pixel that fails the filter set to `idepth = 0`
/// (so that backprojection with `PointFilter::none()` keeps exactly the
/// consistent points): fewer than `min_count` consistent neighbours, or a
/// disparity at most `min_disparity_ratio` times the keyframe's mean.
pub fn filter_consistent(keyframes: &[Keyframe], filter: &DepthFilter) -> Result<Vec<Keyframe>> {
    let counts = depth_consistency_counts(keyframes, filter)?;
    Ok(keyframes
        .iter()
        .zip(counts)
        .map(|(k, c)| {
            let mean =
                k.idepth.iter().map(|&v| v as f64).sum::<f64>() / k.idepth.len().max(1) as f64;
            let floor = filter.min_disparity_ratio * mean;
            let mut out = k.clone();
            for (d, &n) in out.idepth.iter_mut().zip(&c) {
                if n < filter.min_count || (*d as f64) <= floor {
                    *d = 0.0;
                }
            }
            out
        })
        .collect())
}
