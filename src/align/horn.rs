//! Horn's closed-form rotation (J. Opt. Soc. Am. A 4(4), 1987): the unit
//! quaternion maximising `Σ b̂ᵢ·R(âᵢ)` is the eigenvector of the largest
//! eigenvalue of a symmetric 4×4 matrix `N` built from `S = Σ âᵢ b̂ᵢᵀ`.

use nalgebra::{Matrix3, Matrix4, Quaternion, SymmetricEigen, UnitQuaternion};

/// Horn's `N` for `s[(i, j)] = Σ a_i b_j` (source coordinate `i`, target
/// coordinate `j`), quaternion order `(w, x, y, z)`.
pub(crate) fn n_matrix(s: &Matrix3<f64>) -> Matrix4<f64> {
    let (sxx, sxy, sxz) = (s[(0, 0)], s[(0, 1)], s[(0, 2)]);
    let (syx, syy, syz) = (s[(1, 0)], s[(1, 1)], s[(1, 2)]);
    let (szx, szy, szz) = (s[(2, 0)], s[(2, 1)], s[(2, 2)]);
    Matrix4::new(
        sxx + syy + szz,
        syz - szy,
        szx - sxz,
        sxy - syx,
        syz - szy,
        sxx - syy - szz,
        sxy + syx,
        szx + sxz,
        szx - sxz,
        sxy + syx,
        -sxx + syy - szz,
        syz + szy,
        sxy - syx,
        szx + sxz,
        syz + szy,
        -sxx - syy + szz,
    )
}

/// Eigenvalues of `n` (largest first) and the rotation of the eigenvector of
/// the largest one.
pub(crate) fn largest_eigen(n: &Matrix4<f64>) -> ([f64; 4], UnitQuaternion<f64>) {
    let eig = SymmetricEigen::new(*n);
    let mut order = [0usize, 1, 2, 3];
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let values = order.map(|i| eig.eigenvalues[i]);
    let v = eig.eigenvectors.column(order[0]);
    let q = UnitQuaternion::from_quaternion(Quaternion::new(v[0], v[1], v[2], v[3]));
    (values, q)
}
