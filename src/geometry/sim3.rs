//! Similarity transforms of 3-D space, Sim(3).
//!
//! Convention: `T_a_b` maps coordinates in frame `b` into frame `a`:
//! `p_a = s · R · p_b + t`. Composition reads right to left:
//! `(A * B).transform_point(p) == A.transform_point(B.transform_point(p))`.
//! Quaternions at every public boundary are `(x, y, z, w)`.

use crate::simd::Isa;
use std::mem::MaybeUninit;

use nalgebra::{Matrix3, Matrix4, Quaternion, Rotation3, UnitQuaternion, Vector3};
use rayon::prelude::*;

use crate::error::{Error, Result};

/// Tolerance on `RᵀR = I` and `det R = 1` when a rotation matrix is given.
const ORTHONORMAL_TOL: f64 = 1e-6;

/// Points per parallel work item in [`Sim3::transform_points_into`]: large
/// enough to amortise scheduling, small enough to balance two to sixteen cores.
const POINTS_PER_TASK: usize = 1 << 15;

/// A similarity transform `p ↦ s·R·p + t` (scale `s > 0`, rotation `R`, translation `t`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sim3 {
    /// Rotation `R`.
    pub rotation: UnitQuaternion<f64>,
    /// Translation `t`, in the units of the target frame.
    pub translation: Vector3<f64>,
    /// Scale `s` (target units per source unit), finite and `> 0`.
    pub scale: f64,
}

impl Default for Sim3 {
    fn default() -> Self {
        Self::identity()
    }
}

impl Sim3 {
    /// The identity transform.
    pub fn identity() -> Self {
        Sim3 {
            rotation: UnitQuaternion::identity(),
            translation: Vector3::zeros(),
            scale: 1.0,
        }
    }

    /// Builds a transform, checking that every part is finite and the scale positive.
    pub fn try_new(
        rotation: UnitQuaternion<f64>,
        translation: Vector3<f64>,
        scale: f64,
    ) -> Result<Self> {
        if !(scale.is_finite() && scale > 0.0) {
            return Err(Error::invalid(
                "scale",
                format!("must be finite and > 0, got {scale}"),
            ));
        }
        if let Some(i) = translation.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "translation".into(),
                index: i,
            });
        }
        if rotation.coords.iter().any(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "rotation".into(),
                index: 0,
            });
        }
        Ok(Sim3 {
            rotation,
            translation,
            scale,
        })
    }

    /// From a rotation matrix, which must be orthonormal with determinant +1
    /// (to 1e-6); it is re-orthonormalised before use.
    pub fn from_rotation_matrix(
        r: &Matrix3<f64>,
        translation: Vector3<f64>,
        scale: f64,
    ) -> Result<Self> {
        Self::try_new(rotation_from_matrix(r)?, translation, scale)
    }

    /// From a quaternion `(x, y, z, w)`; it is normalised, and must not be zero.
    pub fn from_quaternion_xyzw(
        q: [f64; 4],
        translation: Vector3<f64>,
        scale: f64,
    ) -> Result<Self> {
        Self::try_new(unit_quaternion_xyzw(q)?, translation, scale)
    }

    /// From a 4×4 homogeneous matrix `[[sR, t], [0, 1]]`. The scale is
    /// `det(sR)^(1/3)`; the remaining block must be a rotation.
    pub fn from_matrix(m: &Matrix4<f64>) -> Result<Self> {
        if let Some(i) = m.iter().position(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "matrix".into(),
                index: i,
            });
        }
        let last = m.fixed_view::<1, 4>(3, 0);
        if (last[0].abs() + last[1].abs() + last[2].abs() + (last[3] - 1.0).abs()) > 1e-9 {
            return Err(Error::invalid(
                "matrix",
                format!(
                    "last row must be [0, 0, 0, 1], got [{}, {}, {}, {}]",
                    last[0], last[1], last[2], last[3]
                ),
            ));
        }
        let sr: Matrix3<f64> = m.fixed_view::<3, 3>(0, 0).into_owned();
        let det = sr.determinant();
        if det.is_nan() || det <= 0.0 {
            return Err(Error::invalid(
                "matrix",
                format!("the 3x3 block must have a positive determinant (a scaled rotation), got {det:.6e}"),
            ));
        }
        let scale = det.cbrt();
        let rotation = rotation_from_matrix(&(sr / scale))?;
        Self::try_new(rotation, m.fixed_view::<3, 1>(0, 3).into_owned(), scale)
    }

    /// From LSD-SLAM's `camToWorld` array `[qx, qy, qz, qw, tx, ty, tz]`, whose
    /// quaternion is not unit: its norm is the scale (LSD-SLAM's bundled Sophus
    /// stores `s·q`), its direction the rotation.
    pub fn from_lsd_slam(cam_to_world: &[f64; 7]) -> Result<Self> {
        let q = [
            cam_to_world[0],
            cam_to_world[1],
            cam_to_world[2],
            cam_to_world[3],
        ];
        let norm = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
        let rotation = unit_quaternion_xyzw(q)?;
        Self::try_new(
            rotation,
            Vector3::new(cam_to_world[4], cam_to_world[5], cam_to_world[6]),
            norm,
        )
    }

    /// The inverse of [`Sim3::from_lsd_slam`]: `[s·qx, s·qy, s·qz, s·qw, tx, ty, tz]`.
    pub fn to_lsd_slam(&self) -> [f64; 7] {
        let q = self.quaternion_xyzw();
        let t = self.translation;
        let s = self.scale;
        [s * q[0], s * q[1], s * q[2], s * q[3], t.x, t.y, t.z]
    }

    /// The rotation as a quaternion `(x, y, z, w)` with `w ≥ 0`.
    pub fn quaternion_xyzw(&self) -> [f64; 4] {
        let c = self.rotation.coords; // nalgebra stores (i, j, k, w)
        let sign = if c[3] < 0.0 { -1.0 } else { 1.0 };
        [sign * c[0], sign * c[1], sign * c[2], sign * c[3]]
    }

    /// The rotation matrix `R`.
    pub fn rotation_matrix(&self) -> Matrix3<f64> {
        self.rotation.to_rotation_matrix().into_inner()
    }

    /// The 4×4 homogeneous matrix `[[sR, t], [0, 1]]`.
    pub fn matrix(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(self.rotation_matrix() * self.scale));
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        m
    }

    /// The inverse transform: `T_b_a` from `T_a_b`.
    pub fn inverse(&self) -> Self {
        let rinv = self.rotation.inverse();
        let sinv = 1.0 / self.scale;
        Sim3 {
            rotation: rinv,
            translation: -(rinv * self.translation) * sinv,
            scale: sinv,
        }
    }

    /// Maps one point: `s·R·p + t`.
    pub fn transform_point(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * p * self.scale + self.translation
    }

    /// `s·R` (row-major) and `t` as plain arrays, for point kernels.
    pub fn affine(&self) -> ([[f64; 3]; 3], [f64; 3]) {
        let m = self.rotation_matrix() * self.scale;
        (
            [
                [m[(0, 0)], m[(0, 1)], m[(0, 2)]],
                [m[(1, 0)], m[(1, 1)], m[(1, 2)]],
                [m[(2, 0)], m[(2, 1)], m[(2, 2)]],
            ],
            [self.translation.x, self.translation.y, self.translation.z],
        )
    }

    /// Maps the row-major `(N, 3)` points of `src` into `dst` (same length), in
    /// parallel. The arithmetic is done in `f64` whatever the storage type.
    pub fn transform_points_into<T: PointScalar>(&self, src: &[T], dst: &mut [T]) -> Result<()> {
        if dst.len() != src.len() {
            return Err(Error::ShapeMismatch {
                what: "points".into(),
                expected: "(N, 3) input and an output of the same size".into(),
                got: format!("{} input and {} output values", src.len(), dst.len()),
            });
        }
        check_rows(src.len())?;
        // SAFETY: `MaybeUninit<T>` has the layout of `T`, and the kernel only
        // ever writes initialised values through this view.
        let dst = unsafe {
            std::slice::from_raw_parts_mut(dst.as_mut_ptr().cast::<MaybeUninit<T>>(), dst.len())
        };
        self.transform_uninit(src, dst);
        Ok(())
    }

    /// Maps row-major `(N, 3)` points into a new vector, in parallel: the output
    /// is written once (no zero-fill pass) into a buffer advised to use huge pages
    /// ([`crate::buffer`]). The arithmetic is done in `f64`.
    pub fn transform_points<T: PointScalar>(&self, src: &[T]) -> Result<Vec<T>> {
        check_rows(src.len())?;
        // SAFETY: `transform_uninit` writes one output value per input value,
        // every element of `dst` (`src.len()`, rows checked above).
        unsafe {
            crate::buffer::try_filled_advised("transformed points", src.len(), |dst| {
                self.transform_uninit(src, dst)
            })
        }
    }

    /// Maps row-major `(N, 3)` points in place, in parallel.
    pub fn transform_points_in_place<T: PointScalar>(&self, pts: &mut [T]) -> Result<()> {
        check_rows(pts.len())?;
        let (m, t) = self.affine();
        let kernel = |c: &mut [T]| in_place_block(&m, &t, c);
        let chunk = 3 * POINTS_PER_TASK;
        if pts.len() <= chunk {
            kernel(pts);
        } else {
            pts.par_chunks_mut(chunk).with_max_len(1).for_each(kernel);
        }
        Ok(())
    }

    /// The one point kernel: maps `src` into `dst` (same length, a multiple of 3,
    /// checked by the callers), one rayon task per block of points.
    fn transform_uninit<T: PointScalar>(&self, src: &[T], dst: &mut [MaybeUninit<T>]) {
        let (m, t) = self.affine();
        let kernel = |(s, d): (&[T], &mut [MaybeUninit<T>])| transform_block(&m, &t, s, d);
        let chunk = 3 * POINTS_PER_TASK;
        if src.len() <= chunk {
            kernel((src, dst));
        } else {
            // One task per chunk, so that a descheduled thread holds back at
            // most one chunk on a busy machine.
            src.par_chunks(chunk)
                .zip(dst.par_chunks_mut(chunk))
                .with_max_len(1)
                .for_each(kernel);
        }
    }
}

/// Refuses a flat coordinate count that is not `3·N`.
fn check_rows(len: usize) -> Result<()> {
    if len % 3 != 0 {
        return Err(Error::ShapeMismatch {
            what: "points".into(),
            expected: "(N, 3)".into(),
            got: format!("{len} values"),
        });
    }
    Ok(())
}

/// Points per group in the kernels: the group is split into x, y, z lanes so
/// that the compiler maps them with packed SIMD arithmetic.
const LANES: usize = 8;

#[inline(always)]
fn map(m: &[[f64; 3]; 3], t: &[f64; 3], p: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * p[0] + m[0][1] * p[1] + m[0][2] * p[2] + t[0],
        m[1][0] * p[0] + m[1][1] * p[1] + m[1][2] * p[2] + t[1],
        m[2][0] * p[0] + m[2][1] * p[1] + m[2][2] * p[2] + t[2],
    ]
}

/// Maps the `LANES` points of `g` (`3·LANES` values), returned as x, y, z lanes.
#[inline(always)]
fn map_lanes<T: PointScalar>(m: &[[f64; 3]; 3], t: &[f64; 3], g: &[T]) -> [[f64; LANES]; 3] {
    let mut p = [[0f64; LANES]; 3];
    for i in 0..LANES {
        for k in 0..3 {
            p[k][i] = g[3 * i + k].to_f64();
        }
    }
    let mut q = [[0f64; LANES]; 3];
    for k in 0..3 {
        for i in 0..LANES {
            q[k][i] = m[k][0] * p[0][i] + m[k][1] * p[1][i] + m[k][2] * p[2][i] + t[k];
        }
    }
    q
}

/// Maps `src` into `dst` with the widest SIMD the processor has: the same
/// arithmetic, compiled once for the baseline and once for AVX2 + FMA
/// (chosen at run time), since the f32 → f64 → f32 kernel is compute bound
/// with baseline SSE2 on a loaded core.
#[inline]
fn transform_block<T: PointScalar>(
    m: &[[f64; 3]; 3],
    t: &[f64; 3],
    src: &[T],
    dst: &mut [MaybeUninit<T>],
) {
    match Isa::detect() {
        // SAFETY: `Isa::Avx2Fma` is only detected on a CPU with AVX2 and FMA.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2Fma => unsafe { transform_block_avx2(m, t, src, dst) },
        _ => transform_block_generic(m, t, src, dst),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn transform_block_avx2<T: PointScalar>(
    m: &[[f64; 3]; 3],
    t: &[f64; 3],
    src: &[T],
    dst: &mut [MaybeUninit<T>],
) {
    transform_block_generic(m, t, src, dst);
}

#[inline(always)]
fn transform_block_generic<T: PointScalar>(
    m: &[[f64; 3]; 3],
    t: &[f64; 3],
    src: &[T],
    dst: &mut [MaybeUninit<T>],
) {
    let mut s_groups = src.chunks_exact(3 * LANES);
    let mut d_groups = dst.chunks_exact_mut(3 * LANES);
    for (s, d) in (&mut s_groups).zip(&mut d_groups) {
        let q = map_lanes(m, t, s);
        for i in 0..LANES {
            for k in 0..3 {
                d[3 * i + k].write(T::from_f64(q[k][i]));
            }
        }
    }
    let rest = s_groups.remainder().chunks_exact(3);
    for (s, d) in rest.zip(d_groups.into_remainder().chunks_exact_mut(3)) {
        let q = map(m, t, [s[0].to_f64(), s[1].to_f64(), s[2].to_f64()]);
        d[0].write(T::from_f64(q[0]));
        d[1].write(T::from_f64(q[1]));
        d[2].write(T::from_f64(q[2]));
    }
}

/// [`transform_block`] in place: each group is read whole before it is written.
#[inline]
fn in_place_block<T: PointScalar>(m: &[[f64; 3]; 3], t: &[f64; 3], pts: &mut [T]) {
    match Isa::detect() {
        // SAFETY: `Isa::Avx2Fma` is only detected on a CPU with AVX2 and FMA.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2Fma => unsafe { in_place_block_avx2(m, t, pts) },
        _ => in_place_block_generic(m, t, pts),
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn in_place_block_avx2<T: PointScalar>(m: &[[f64; 3]; 3], t: &[f64; 3], pts: &mut [T]) {
    in_place_block_generic(m, t, pts);
}

#[inline(always)]
fn in_place_block_generic<T: PointScalar>(m: &[[f64; 3]; 3], t: &[f64; 3], pts: &mut [T]) {
    let mut groups = pts.chunks_exact_mut(3 * LANES);
    for g in &mut groups {
        let q = map_lanes(m, t, g);
        for i in 0..LANES {
            for k in 0..3 {
                g[3 * i + k] = T::from_f64(q[k][i]);
            }
        }
    }
    for p in groups.into_remainder().chunks_exact_mut(3) {
        let q = map(m, t, [p[0].to_f64(), p[1].to_f64(), p[2].to_f64()]);
        p[0] = T::from_f64(q[0]);
        p[1] = T::from_f64(q[1]);
        p[2] = T::from_f64(q[2]);
    }
}

/// Storage types of point coordinates (`f32`, `f64`).
pub trait PointScalar: Copy + Default + Send + Sync + 'static {
    /// Widens to `f64`.
    fn to_f64(self) -> f64;
    /// Narrows from `f64` (round to nearest).
    fn from_f64(v: f64) -> Self;
}

impl PointScalar for f32 {
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self as f64
    }
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v as f32
    }
}

impl PointScalar for f64 {
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v
    }
}

impl std::ops::Mul for Sim3 {
    type Output = Sim3;
    /// `A * B` maps with `B` first, then `A`.
    fn mul(self, b: Sim3) -> Sim3 {
        Sim3 {
            rotation: self.rotation * b.rotation,
            translation: self.rotation * b.translation * self.scale + self.translation,
            scale: self.scale * b.scale,
        }
    }
}

/// A unit quaternion from `(x, y, z, w)`, normalised; errors on zero or non-finite input.
pub fn unit_quaternion_xyzw(q: [f64; 4]) -> Result<UnitQuaternion<f64>> {
    if let Some(i) = q.iter().position(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "quaternion".into(),
            index: i,
        });
    }
    let norm = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    if norm < 1e-12 {
        return Err(Error::invalid("quaternion", "has zero norm"));
    }
    Ok(UnitQuaternion::from_quaternion(Quaternion::new(
        q[3], q[0], q[1], q[2],
    )))
}

/// A rotation from a 3×3 matrix that must be orthonormal with determinant +1 to 1e-6.
pub fn rotation_from_matrix(r: &Matrix3<f64>) -> Result<UnitQuaternion<f64>> {
    if let Some(i) = r.iter().position(|v| !v.is_finite()) {
        return Err(Error::NonFinite {
            what: "rotation".into(),
            index: i,
        });
    }
    let ortho = (r.transpose() * r - Matrix3::identity()).amax();
    let det = r.determinant();
    if ortho > ORTHONORMAL_TOL || (det - 1.0).abs() > ORTHONORMAL_TOL {
        return Err(Error::invalid(
            "rotation",
            format!("not a rotation matrix (|RᵀR − I|max = {ortho:.3e}, det = {det:.6})"),
        ));
    }
    // Orthonormal to 1e-6: the quaternion of the matrix (Shepperd's method),
    // normalised, is the nearest rotation to first order.
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(*r));
    Ok(UnitQuaternion::new_normalize(q.into_inner()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Sim3 {
        Sim3::from_quaternion_xyzw([0.1, -0.3, 0.2, 0.9], Vector3::new(1.0, -2.0, 3.0), 15.49)
            .unwrap()
    }

    #[test]
    fn point_kernels_match_the_f64_map_on_every_point() {
        let t = sample();
        // Not a multiple of the group size, more than one parallel block.
        let n = 2 * POINTS_PER_TASK + 7;
        let pts: Vec<f32> = (0..3 * n)
            .map(|i| ((i * 7919) % 2003) as f32 * 0.01 - 10.0)
            .collect();
        let new = t.transform_points(&pts).unwrap();
        let mut into = vec![0f32; pts.len()];
        t.transform_points_into(&pts, &mut into).unwrap();
        let mut in_place = pts.clone();
        t.transform_points_in_place(&mut in_place).unwrap();
        assert_eq!(new, into);
        assert_eq!(new, in_place);
        for (p, q) in pts.chunks_exact(3).zip(new.chunks_exact(3)) {
            let want = t.transform_point(&Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64));
            for k in 0..3 {
                // One rounding to f32 of the f64 result.
                let tol = f32::EPSILON as f64 * want[k].abs();
                assert!(
                    (q[k] as f64 - want[k]).abs() <= tol,
                    "{} vs {}",
                    q[k],
                    want[k]
                );
            }
        }
        assert!(t.transform_points(&pts[..4]).is_err());
        assert!(t.transform_points_into(&pts[..6], &mut into[..3]).is_err());
    }

    #[test]
    fn matrix_round_trip_and_inverse() {
        let t = sample();
        let back = Sim3::from_matrix(&t.matrix()).unwrap();
        assert!((back.matrix() - t.matrix()).amax() < 1e-12);
        let id = t * t.inverse();
        assert!((id.matrix() - Matrix4::identity()).amax() < 1e-12);
        assert!((t.inverse().matrix() - t.matrix().try_inverse().unwrap()).amax() < 1e-12);
    }

    #[test]
    fn composition_matches_matrices() {
        let a = sample();
        let b = Sim3::from_quaternion_xyzw([0.0, 0.0, 1.0, 1.0], Vector3::new(0.5, 0.0, 0.0), 0.25)
            .unwrap();
        assert!(((a * b).matrix() - a.matrix() * b.matrix()).amax() < 1e-12);
        let p = Vector3::new(0.3, -0.7, 2.0);
        let lhs = (a * b).transform_point(&p);
        let rhs = a.transform_point(&b.transform_point(&p));
        assert!((lhs - rhs).amax() < 1e-12);
    }

    #[test]
    fn lsd_slam_scale_is_quaternion_norm() {
        let t = Sim3::from_lsd_slam(&[0.0, 0.0, 0.0, 2.0, 1.0, 2.0, 3.0]).unwrap();
        assert_eq!(t.scale, 2.0);
        let back = t.to_lsd_slam();
        assert!((back[3] - 2.0).abs() < 1e-15);
        assert!(Sim3::from_lsd_slam(&[0.0; 7]).is_err());
    }

    #[test]
    fn points_f32_and_f64_agree_with_point_map() {
        let t = sample();
        let n = 3 * POINTS_PER_TASK + 17;
        let pts: Vec<f64> = (0..3 * n)
            .map(|i| ((i * 7919) % 1000) as f64 * 0.01 - 5.0)
            .collect();
        let out = t.transform_points(&pts).unwrap();
        let pts32: Vec<f32> = pts.iter().map(|&v| v as f32).collect();
        let out32 = t.transform_points(&pts32).unwrap();
        let mut inplace = pts.clone();
        t.transform_points_in_place(&mut inplace).unwrap();
        for i in (0..n).step_by(997) {
            let p = Vector3::new(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
            let q = t.transform_point(&p);
            for k in 0..3 {
                assert!((out[3 * i + k] - q[k]).abs() < 1e-9);
                assert!((inplace[3 * i + k] - q[k]).abs() < 1e-9);
                assert!((out32[3 * i + k] as f64 - q[k]).abs() < 1e-3 * q[k].abs().max(1.0));
            }
        }
        assert!(t.transform_points(&pts[..4]).is_err());
    }

    #[test]
    fn rejects_bad_input() {
        assert!(Sim3::from_quaternion_xyzw([0.0; 4], Vector3::zeros(), 1.0).is_err());
        assert!(Sim3::from_quaternion_xyzw([0.0, 0.0, 0.0, 1.0], Vector3::zeros(), -1.0).is_err());
        assert!(
            Sim3::from_quaternion_xyzw([f64::NAN, 0.0, 0.0, 1.0], Vector3::zeros(), 1.0).is_err()
        );
        let mut m = Matrix4::identity();
        m[(0, 1)] = 0.5;
        assert!(Sim3::from_matrix(&m).is_err());
        m = Matrix4::identity();
        m[(3, 0)] = 1.0;
        assert!(Sim3::from_matrix(&m).is_err());
    }
}
