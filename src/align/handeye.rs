//! Alignment with poses rather than positions: a known camera–body extrinsic
//! (lever arm), keyframe orientations joined to the positions, and the
//! estimate of the extrinsic itself (hand-eye calibration with scale).
//!
//! Frames: SLAM poses `T_slam_cam` (positions `aᵢ`, SLAM units; rotations
//! `Aᵢ = R_slam_cam`); reference poses `T_world_body` (positions `bᵢ`, metres;
//! rotations `Bᵢ = R_world_body`); the extrinsic `T_body_cam`, whose inverse
//! `T_cam_body = (R_cam_body, c)` puts the body origin at `c` (metres) in the
//! camera frame. The model: `bᵢ = s·R·aᵢ + t + R·Aᵢ·c` and
//! `Bᵢ = R·Aᵢ·R_cam_body`, with `T_world_slam = (R, t, s)`.

use nalgebra::{Matrix3, Matrix4, SMatrix, SVector, UnitQuaternion, Vector3, Vector4};

use super::dof::{tilt_deg, Anchor, Dof, DofDiagnostics, DofOptions};
use super::{align, horn, umeyama, AlignDiagnostics, AlignOptions, Alignment};
use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::trajectory::{matched_pairs, Trajectory};

/// Iterations of the alternating schemes (they stop earlier once converged).
const MAX_ITERATIONS: usize = 50;

fn check(a: &[Vector3<f64>], ra: &[UnitQuaternion<f64>], b: &[Vector3<f64>]) -> Result<()> {
    let n = a.len();
    for (what, len) in [
        ("slam orientations", ra.len()),
        ("reference positions", b.len()),
    ] {
        if len != n {
            return Err(Error::ShapeMismatch {
                what: what.into(),
                expected: format!("{n} rows, one per SLAM position"),
                got: format!("{len} rows"),
            });
        }
    }
    Ok(())
}

fn residual_alignment(
    t: Sim3,
    a: &[Vector3<f64>],
    b: &[Vector3<f64>],
    diagnostics: AlignDiagnostics,
) -> Alignment {
    let residuals: Vec<f64> = a
        .iter()
        .zip(b)
        .map(|(p, q)| (q - t.transform_point(p)).norm())
        .collect();
    let rmse =
        (residuals.iter().map(|e| e * e).sum::<f64>() / residuals.len().max(1) as f64).sqrt();
    Alignment {
        transform: t,
        residuals,
        rmse,
        diagnostics,
    }
}

/// SLAM positions moved from the camera to the body origin, in SLAM units:
/// `aᵢ + Aᵢ·c / s`.
pub fn body_positions(
    a: &[Vector3<f64>],
    ra: &[UnitQuaternion<f64>],
    c: &Vector3<f64>,
    s: f64,
) -> Vec<Vector3<f64>> {
    a.iter().zip(ra).map(|(p, q)| p + q * c / s).collect()
}

/// Fits `T_world_slam` to camera poses and body positions with a KNOWN
/// extrinsic `body_from_cam = T_body_cam` (its scale is ignored; the lever arm
/// is metres). Alternates: move the SLAM positions to the body origin with the
/// current scale, refit. The residuals are between the body positions.
pub fn align_with_extrinsic(
    a: &[Vector3<f64>],
    ra: &[UnitQuaternion<f64>],
    b: &[Vector3<f64>],
    body_from_cam: &Sim3,
    opts: &AlignOptions,
) -> Result<Alignment> {
    align_with_extrinsic_by(a, ra, b, body_from_cam, |p, q| align(p, q, opts))
}

/// [`align_with_extrinsic`] with another positions-only fit `fit(source,
/// target)` (e.g. [`super::dof::align_dof`] with other degrees of freedom or
/// an anchor): the same alternation of lever-arm move and refit.
pub fn align_with_extrinsic_by<F>(
    a: &[Vector3<f64>],
    ra: &[UnitQuaternion<f64>],
    b: &[Vector3<f64>],
    body_from_cam: &Sim3,
    fit: F,
) -> Result<Alignment>
where
    F: Fn(&[Vector3<f64>], &[Vector3<f64>]) -> Result<Alignment>,
{
    let refit = fit;
    check(a, ra, b)?;
    let body_unscaled = Sim3::try_new(body_from_cam.rotation, body_from_cam.translation, 1.0)?;
    let c = body_unscaled.inverse().translation;
    let mut fit = refit(a, b)?;
    for _ in 0..MAX_ITERATIONS {
        let s = fit.transform.scale;
        let moved = body_positions(a, ra, &c, s);
        let next = refit(&moved, b)?;
        let change = (next.transform.scale / s - 1.0).abs();
        fit = next;
        if change < 1e-14 {
            break;
        }
    }
    Ok(fit)
}

/// `qᵀ·M·q` maximiser for symmetric `m` (quaternion order `(w, x, y, z)`).
fn largest(m: &Matrix4<f64>) -> ([f64; 4], UnitQuaternion<f64>) {
    horn::largest_eigen(m)
}

/// `qᵀ·M·q` maximiser over the rotations about z, `q = (cos φ, 0, 0, sin φ)`:
/// the top eigenvector of the `(w, z)` block, `φ = ½·atan2(2·M_wz, M_ww − M_zz)`.
fn largest_yaw(m: &Matrix4<f64>) -> UnitQuaternion<f64> {
    let phi = 0.5 * (2.0 * m[(0, 3)]).atan2(m[(0, 0)] - m[(3, 3)]);
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 2.0 * phi)
}

fn outer_wxyz(q: &UnitQuaternion<f64>) -> Matrix4<f64> {
    let v = Vector4::new(q.w, q.i, q.j, q.k);
    v * v.transpose()
}

/// Fits `T_world_slam` to positions AND orientations in one closed form:
/// maximises `qᵀ·((2s/σₚ²)·N + (4/σᵣ²)·Σ qᵢqᵢᵀ)·q` over unit quaternions, where
/// `N` is Horn's matrix of the positions and `qᵢ = Bᵢ·R_body_cam·Aᵢᵀ` the
/// rotation each pose pair asks for (`σₚ`, `σᵣ`: per-axis position and
/// rotation residual sigmas, re-estimated from the fit three times). Near
/// straight paths, where the positions leave the rotation about the line
/// free, still align. `rb` are the reference rotations `R_world_body`;
/// `body_from_cam` (default identity) supplies `R_body_cam` and the lever arm.
pub fn align_with_orientations(
    a: &[Vector3<f64>],
    ra: &[UnitQuaternion<f64>],
    b: &[Vector3<f64>],
    rb: &[UnitQuaternion<f64>],
    body_from_cam: Option<&Sim3>,
    scale: bool,
) -> Result<Alignment> {
    let dof = if scale { Dof::Sim3 } else { Dof::Se3 };
    joint_fit(a, ra, b, rb, body_from_cam, dof, Anchor::None)
}

/// [`align_with_orientations`] with the degrees of freedom and anchor of
/// `opts` (its `weights` must be `None`; `method` is not used: the joint form
/// is Horn's): a yaw-only dof maximises the same form over rotations about z
/// (a 2 × 2 eigenproblem, closed form), the scale is fitted as the dof says,
/// and [`Anchor::First`] centres the positions on the first pair instead of
/// the centroids (`t = b₀ − s·R·a₀`: its body position is met exactly). A
/// yaw-only fit is refused ([`Error::GravityTilted`]) when the full-rotation
/// joint fit of the same poses tilts the estimate's z axis more than
/// `opts.max_tilt_deg`; its diagnostics carry [`DofDiagnostics`] (as do
/// anchored fits).
pub fn align_with_orientations_dof(
    a: &[Vector3<f64>],
    ra: &[UnitQuaternion<f64>],
    b: &[Vector3<f64>],
    rb: &[UnitQuaternion<f64>],
    body_from_cam: Option<&Sim3>,
    opts: &DofOptions,
) -> Result<Alignment> {
    if opts.weights.is_some() {
        return Err(Error::invalid(
            "weights",
            "the joint fit of positions and orientations takes no weights",
        ));
    }
    let dof = opts.dof;
    if !dof.yaw_only() {
        return joint_fit(a, ra, b, rb, body_from_cam, dof, opts.anchor);
    }
    let full = if dof.has_scale() { Dof::Sim3 } else { Dof::Se3 };
    let tilt = joint_fit(a, ra, b, rb, body_from_cam, full, opts.anchor)
        .ok()
        .map(|f| tilt_deg(&f.transform.rotation));
    if let (Some(threshold_deg), Some(angle_deg)) = (opts.max_tilt_deg, tilt) {
        if angle_deg > threshold_deg {
            return Err(Error::GravityTilted {
                dof: dof.as_str().into(),
                angle_deg,
                threshold_deg,
            });
        }
    }
    let mut fit = joint_fit(a, ra, b, rb, body_from_cam, dof, opts.anchor)?;
    if let Some(d) = fit.diagnostics.dof.as_mut() {
        d.gravity_tilt_deg = tilt;
    }
    Ok(fit)
}

/// The joint closed form of [`align_with_orientations`] for `dof` and
/// `anchor`; the plain Sim(3) / SE(3) without anchor is exactly that
/// function's, the others fill [`AlignDiagnostics::dof`] (the tilt of a
/// full rotation is that of the fit itself; the yaw-only caller fills its own).
fn joint_fit(
    a: &[Vector3<f64>],
    ra: &[UnitQuaternion<f64>],
    b: &[Vector3<f64>],
    rb: &[UnitQuaternion<f64>],
    body_from_cam: Option<&Sim3>,
    dof: Dof,
    anchor: Anchor,
) -> Result<Alignment> {
    let scale = dof.has_scale();
    let yaw_only = dof.yaw_only();
    let pick = |m: &Matrix4<f64>| -> ([f64; 4], UnitQuaternion<f64>) {
        let (eigenvalues, q) = largest(m);
        if yaw_only {
            (eigenvalues, largest_yaw(m))
        } else {
            (eigenvalues, q)
        }
    };
    check(a, ra, b)?;
    if rb.len() != a.len() {
        return Err(Error::ShapeMismatch {
            what: "reference orientations".into(),
            expected: format!("{} rows, one per SLAM position", a.len()),
            got: format!("{} rows", rb.len()),
        });
    }
    let n = a.len();
    if n < 3 {
        return Err(Error::TooFew {
            what: "pose pairs".into(),
            need: 3,
            got: n,
        });
    }
    if a.iter().chain(b).any(|p| p.iter().any(|v| !v.is_finite())) {
        return Err(Error::NonFinite {
            what: "positions".into(),
            index: a
                .iter()
                .chain(b)
                .position(|p| p.iter().any(|v| !v.is_finite()))
                .unwrap_or(0)
                % n,
        });
    }
    let (r_body_cam, c) = match body_from_cam {
        Some(t) => {
            let unscaled = Sim3::try_new(t.rotation, t.translation, 1.0)?;
            (t.rotation, unscaled.inverse().translation)
        }
        None => (UnitQuaternion::identity(), Vector3::zeros()),
    };
    let wanted: Vec<UnitQuaternion<f64>> = ra
        .iter()
        .zip(rb)
        .map(|(qa, qb)| qb * r_body_cam * qa.inverse())
        .collect();
    let mut q_rot = Matrix4::zeros();
    for q in &wanted {
        q_rot += outer_wxyz(q);
    }
    let (_, mut rot) = pick(&q_rot);
    let nf = n as f64;
    let mean_b = match anchor {
        Anchor::None => b.iter().sum::<Vector3<f64>>() / nf,
        Anchor::First => b[0],
    };
    let mut s = 1.0;
    let mut t = Sim3::identity();
    let mut diag = None;
    // The scale first from the spreads (rotation-free), then from the joint fit.
    for round in 0..4 {
        let moved = if c.norm() > 0.0 && round > 0 {
            body_positions(a, ra, &c, s)
        } else {
            a.to_vec()
        };
        let mean_a = match anchor {
            Anchor::None => moved.iter().sum::<Vector3<f64>>() / nf,
            Anchor::First => moved[0],
        };
        let mut cov = Matrix3::zeros();
        let (mut var_a, mut var_b) = (0.0, 0.0);
        for (p, q) in moved.iter().zip(b) {
            let (pa, qb) = (p - mean_a, q - mean_b);
            cov += pa * qb.transpose();
            var_a += pa.norm_squared();
            var_b += qb.norm_squared();
        }
        if var_a <= 0.0 || var_b <= 0.0 {
            return Err(Error::Degenerate {
                reason: "all positions coincide: the scale is undefined (diagnostic: spread)"
                    .into(),
                value: var_a.min(var_b),
            });
        }
        let n_pos = horn::n_matrix(&cov);
        if round == 0 {
            s = if scale { (var_b / var_a).sqrt() } else { 1.0 };
        }
        // Residual sigmas of the current estimate.
        let r = rot.to_rotation_matrix().into_inner();
        let tr = mean_b - r * mean_a * s;
        let sp2 = (moved
            .iter()
            .zip(b)
            .map(|(p, q)| (q - (r * p * s + tr)).norm_squared())
            .sum::<f64>()
            / (3.0 * nf))
            .max(1e-12 * var_b / nf);
        let sr2 =
            (wanted.iter().map(|q| rot.angle_to(q).powi(2)).sum::<f64>() / (3.0 * nf)).max(1e-12);
        let m = n_pos * (2.0 * s / sp2) + q_rot * (4.0 / sr2);
        let (eigenvalues, q) = pick(&m);
        rot = q;
        let r = rot.to_rotation_matrix().into_inner();
        if scale {
            s = (r * cov).trace() / var_a;
        }
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::Degenerate {
                reason: "the best scale is not positive (diagnostic: the scale)".into(),
                value: s,
            });
        }
        t = Sim3::try_new(rot, mean_b - r * mean_a * s, s)?;
        let lmax = eigenvalues[0].abs().max(eigenvalues[3].abs());
        diag = Some(AlignDiagnostics {
            n,
            weight_sum: nf,
            eigenvalues,
            relative_eigen_gap: if lmax > 0.0 {
                (eigenvalues[0] - eigenvalues[1]) / lmax
            } else {
                0.0
            },
            singular_values: umeyama::singular_values(&(cov / nf)),
            source_spread: (var_a / nf).sqrt(),
            target_spread: (var_b / nf).sqrt(),
            dof: (yaw_only || anchor != Anchor::None).then(|| {
                let h = |v: &Vector3<f64>| v.x * v.x + v.y * v.y;
                let aa_h: f64 = moved.iter().map(|p| h(&(p - mean_a))).sum();
                let bb_h: f64 = b.iter().map(|q| h(&(q - mean_b))).sum();
                let peak = (cov[(0, 1)] - cov[(1, 0)]).hypot(cov[(0, 0)] + cov[(1, 1)]);
                let norm = (aa_h * bb_h).sqrt();
                DofDiagnostics {
                    dof,
                    anchor,
                    source_horizontal_spread: (aa_h / nf).sqrt(),
                    target_horizontal_spread: (bb_h / nf).sqrt(),
                    yaw_determinacy: if norm > 0.0 { peak / norm } else { 0.0 },
                    gravity_tilt_deg: (!yaw_only).then(|| tilt_deg(&rot)),
                }
            }),
        });
    }
    let Some(diagnostics) = diag else {
        return Err(Error::Degenerate {
            reason: "no fit".into(),
            value: 0.0,
        });
    };
    let moved = body_positions(a, ra, &c, s);
    Ok(residual_alignment(t, &moved, b, diagnostics))
}

/// The result of [`estimate_body_from_cam`].
#[derive(Clone, Debug)]
pub struct HandEye {
    /// The estimated `T_body_cam` (metres, scale 1).
    pub body_from_cam: Sim3,
    /// The fit of `T_world_slam` with it (residuals between body positions).
    pub alignment: Alignment,
    /// rms angle between `Bᵢ` and `R·Aᵢ·R_cam_body`, rad.
    pub rotation_rmse: f64,
}

/// Estimates the camera–body extrinsic together with `T_world_slam` (hand-eye
/// calibration with scale): alternates a linear least-squares solve for
/// `(s, t, c)` at fixed `R` with a Horn fit of the lever-arm-corrected
/// positions; `R_cam_body` is the chordal mean of `(R·Aᵢ)ᵀ·Bᵢ`. Needs rotation
/// about at least two axes for the lever arm to be observable
/// ([`Error::Degenerate`] otherwise).
pub fn estimate_body_from_cam(
    a: &[Vector3<f64>],
    ra: &[UnitQuaternion<f64>],
    b: &[Vector3<f64>],
    rb: &[UnitQuaternion<f64>],
) -> Result<HandEye> {
    check(a, ra, b)?;
    if rb.len() != a.len() {
        return Err(Error::ShapeMismatch {
            what: "reference orientations".into(),
            expected: format!("{} rows", a.len()),
            got: format!("{} rows", rb.len()),
        });
    }
    let opts = AlignOptions::default();
    let mut fit = align(a, b, &opts)?;
    let mut c = Vector3::zeros();
    for _ in 0..MAX_ITERATIONS {
        let r = fit.transform.rotation_matrix();
        // Linear least squares in x = (s, t, c): bᵢ = s·R·aᵢ + t + R·Aᵢ·c.
        let mut h = SMatrix::<f64, 7, 7>::zeros();
        let mut g = SVector::<f64, 7>::zeros();
        for ((p, q), qa) in a.iter().zip(b).zip(ra) {
            let mut j = SMatrix::<f64, 3, 7>::zeros();
            j.fixed_view_mut::<3, 1>(0, 0).copy_from(&(r * p));
            j.fixed_view_mut::<3, 3>(0, 1)
                .copy_from(&Matrix3::identity());
            j.fixed_view_mut::<3, 3>(0, 4)
                .copy_from(&(r * qa.to_rotation_matrix().into_inner()));
            h += j.transpose() * j;
            g += j.transpose() * q;
        }
        let Some(x) = h.cholesky().map(|ch| ch.solve(&g)) else {
            return Err(Error::Degenerate {
                reason: "the lever arm is not observable (the camera hardly rotates) \
                         (diagnostic: smallest eigenvalue of the normal matrix)"
                    .into(),
                value: h.symmetric_eigenvalues().min(),
            });
        };
        let s = x[0];
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::Degenerate {
                reason: "the best scale is not positive (diagnostic: the scale)".into(),
                value: s,
            });
        }
        let c_new = Vector3::new(x[4], x[5], x[6]);
        let moved = body_positions(a, ra, &c_new, s);
        let next = align(&moved, b, &opts)?;
        let change = (c_new - c).norm() + (next.transform.scale / fit.transform.scale - 1.0).abs();
        c = c_new;
        fit = next;
        if change < 1e-12 {
            break;
        }
    }
    let r = fit.transform.rotation;
    let mut m = Matrix4::zeros();
    for (qa, qb) in ra.iter().zip(rb) {
        m += outer_wxyz(&((r * qa).inverse() * qb));
    }
    let (_, r_cam_body) = largest(&m);
    let rotation_rmse = (ra
        .iter()
        .zip(rb)
        .map(|(qa, qb)| (r * qa * r_cam_body).angle_to(qb).powi(2))
        .sum::<f64>()
        / a.len() as f64)
        .sqrt();
    let cam_from_body = Sim3::try_new(r_cam_body, c, 1.0)?;
    Ok(HandEye {
        body_from_cam: cam_from_body.inverse(),
        alignment: fit,
        rotation_rmse,
    })
}

/// [`estimate_body_from_cam`] on two trajectories with orientations: SLAM
/// keyframes `T_slam_cam` and reference body poses `T_world_body`, paired as
/// [`matched_pairs`] does (`offset` seconds added to the SLAM stamps). Also
/// returns the number of pairs.
pub fn estimate_body_from_cam_trajectories(
    slam: &Trajectory,
    reference: &Trajectory,
    max_diff: f64,
    offset: f64,
) -> Result<(HandEye, usize)> {
    slam.check_lengths()?;
    reference.check_lengths()?;
    let (Some(qs), Some(qr)) = (&slam.orientations, &reference.orientations) else {
        return Err(Error::invalid(
            "orientations",
            "the extrinsic needs the orientations of both trajectories",
        ));
    };
    let pairs = matched_pairs(slam, reference, max_diff, offset, 3)?;
    let a: Vec<Vector3<f64>> = pairs.iter().map(|&(i, _)| slam.positions[i]).collect();
    let ra: Vec<_> = pairs.iter().map(|&(i, _)| qs[i]).collect();
    let b: Vec<Vector3<f64>> = pairs.iter().map(|&(_, j)| reference.positions[j]).collect();
    let rb: Vec<_> = pairs.iter().map(|&(_, j)| qr[j]).collect();
    Ok((estimate_body_from_cam(&a, &ra, &b, &rb)?, pairs.len()))
}

#[cfg(test)]
mod tests {
    use super::*;

    type Poses = (
        Vec<Vector3<f64>>,
        Vec<UnitQuaternion<f64>>,
        Vec<Vector3<f64>>,
        Vec<UnitQuaternion<f64>>,
        Sim3,
        Sim3,
    );

    /// A wiggly path with rotations about all axes, camera poses in a SLAM frame.
    fn poses(n: usize, straight: bool) -> Poses {
        let t_ws =
            Sim3::from_quaternion_xyzw([0.2, -0.4, 0.1, 0.8], Vector3::new(3.0, 1.0, -2.0), 5.0)
                .unwrap();
        let body_from_cam = Sim3::from_quaternion_xyzw(
            [0.5, -0.5, 0.5, 0.5],
            Vector3::new(-0.02, -0.06, 0.01),
            1.0,
        )
        .unwrap();
        let cam_from_body = body_from_cam.inverse();
        let (mut a, mut ra, mut b, mut rb) = (vec![], vec![], vec![], vec![]);
        for i in 0..n {
            let f = i as f64 * 0.1;
            let p = if straight {
                Vector3::new(f, 0.0, 0.0)
            } else {
                Vector3::new(f.sin(), (0.7 * f).cos(), 0.3 * f)
            };
            let q = UnitQuaternion::from_euler_angles(0.5 * f.sin(), 0.4 * (1.3 * f).cos(), f);
            // Camera pose in the world, then the body pose.
            let cam_w = t_ws.rotation * q;
            let pos_w = t_ws.transform_point(&p);
            rb.push(cam_w * cam_from_body.rotation);
            b.push(pos_w + cam_w * cam_from_body.translation);
            a.push(p);
            ra.push(q);
        }
        (a, ra, b, rb, t_ws, body_from_cam)
    }

    #[test]
    fn known_extrinsic_removes_the_lever_arm() {
        let (a, ra, b, _, t, x) = poses(80, false);
        let plain = align(&a, &b, &AlignOptions::default()).unwrap();
        assert!(plain.rmse > 1e-3);
        let fit = align_with_extrinsic(&a, &ra, &b, &x, &AlignOptions::default()).unwrap();
        assert!(fit.rmse < 1e-10, "{}", fit.rmse);
        assert!((fit.transform.scale - t.scale).abs() < 1e-9);
    }

    #[test]
    fn extrinsic_is_estimated() {
        let (a, ra, b, rb, t, x) = poses(80, false);
        let he = estimate_body_from_cam(&a, &ra, &b, &rb).unwrap();
        assert!((he.body_from_cam.translation - x.translation).norm() < 1e-8);
        assert!(he.body_from_cam.rotation.angle_to(&x.rotation) < 1e-8);
        assert!((he.alignment.transform.scale - t.scale).abs() < 1e-8);
    }

    #[test]
    fn orientations_fix_a_straight_path() {
        let (a, ra, b, rb, t, x) = poses(30, true);
        assert!(align(&a, &b, &AlignOptions::default()).is_err());
        let fit = align_with_orientations(&a, &ra, &b, &rb, Some(&x), true).unwrap();
        assert!(fit.transform.rotation.angle_to(&t.rotation) < 1e-6);
        assert!((fit.transform.scale / t.scale - 1.0).abs() < 1e-6);
        assert!(fit.rmse < 1e-6);
    }
}
