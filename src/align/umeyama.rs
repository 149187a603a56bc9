//! Umeyama's SVD rotation (IEEE PAMI 13(4), 1991) with the reflection
//! correction, as evo computes it; the cross-check of Horn's method.

use nalgebra::{Matrix3, Rotation3, UnitQuaternion};

use crate::error::{Error, Result};

/// Singular values of `s`, largest first.
pub(crate) fn singular_values(s: &Matrix3<f64>) -> [f64; 3] {
    let sv = s.singular_values();
    let mut v = [sv[0], sv[1], sv[2]];
    v.sort_by(|a, b| b.total_cmp(a));
    v
}

/// The rotation maximising `tr(R·S)` for `s = Σ âᵢ b̂ᵢᵀ`: with
/// `Sᵀ = U·D·Vᵀ`, `R = U·diag(1, 1, ±1)·Vᵀ` (the sign makes `det R = +1`,
/// flipping the smallest singular direction).
pub(crate) fn rotation(s: &Matrix3<f64>) -> Result<UnitQuaternion<f64>> {
    let svd = s.transpose().svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Err(Error::Degenerate {
            reason: "the SVD of the cross-covariance did not converge".into(),
            value: f64::NAN,
        });
    };
    let mut d = Matrix3::identity();
    if u.determinant() * v_t.determinant() < 0.0 {
        let sv = &svd.singular_values;
        let mut k = 0;
        for i in 1..3 {
            if sv[i] < sv[k] {
                k = i;
            }
        }
        d[(k, k)] = -1.0;
    }
    let r = u * d * v_t;
    Ok(UnitQuaternion::from_rotation_matrix(
        &Rotation3::from_matrix_unchecked(r),
    ))
}
