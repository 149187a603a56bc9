//! Metric scale and gravity from what a user knows besides the ground plane
//! (`align::ground`), one prior a function, all ending in the same frame:
//!
//! - [`scale_from_distance`]: two poses a known distance apart (two marks on
//!   the floor, a measured corridor) give the scale; its relative error is
//!   the two positions' error over their distance, so the farther apart the
//!   better.
//! - [`planar_motion`]: a ground robot's cameras ride in one plane; its
//!   normal is "up" (gravity without a cloud), oriented by the cameras'
//!   "image up". The plane is the least-squares one of the camera centres;
//!   how far they leave it, against how far they spread in it, bounds the
//!   tilt an uneven floor or a slope can put into it, and a path too far
//!   from a plane (a line, a hand-held camera, stairs) is refused with that
//!   bound.
//! - [`level_frame`]: `T_world_slam` from an "up", a scale and the first
//!   camera's height: z up, the first camera over the origin at that height,
//!   x along its heading (yaw and the horizontal origin are not observable,
//!   as with `--anchor first`).

use nalgebra::{Matrix3, SymmetricEigen, UnitQuaternion, Vector3};

use crate::error::{Error, Result};
use crate::geometry::Sim3;
use crate::trajectory::Trajectory;

/// `T_world_slam` with z along `up` (SLAM frame, unit), metres = `scale` ×
/// SLAM units, the first camera of `cameras` at `(0, 0, first_height)` and
/// x along its heading (its optical axis on the level; x stays the SLAM
/// frame's tilted one when it looks straight up or down, or without
/// orientations).
pub fn level_frame(up: &Vector3<f64>, cameras: &Trajectory, scale: f64, first_height: f64) -> Sim3 {
    let tilt = UnitQuaternion::rotation_between(up, &Vector3::z()).unwrap_or_else(|| {
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
    });
    let heading = cameras
        .orientations
        .as_ref()
        .and_then(|o| o.first())
        .map(|q| tilt * (q * Vector3::z()))
        .filter(|f| f.x.hypot(f.y) > 1e-6);
    let yaw = heading.map_or(0.0, |f| -f.y.atan2(f.x));
    let rotation = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw) * tilt;
    let first = cameras.positions.first().copied().unwrap_or_default();
    Sim3 {
        rotation,
        translation: Vector3::new(0.0, 0.0, first_height) - scale * (rotation * first),
        scale,
    }
}

/// A scale from a known distance between two poses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KnownDistance {
    /// Metres per SLAM unit.
    pub scale: f64,
    /// The two poses' distance in the SLAM frame, SLAM units.
    pub slam_distance: f64,
    /// The distance given, metres.
    pub metres: f64,
}

/// The scale that makes poses `a` and `b` of `cameras` (indices) `metres`
/// apart. Errors: an index out of range, a distance that is not a positive
/// number, two poses at the same place.
pub fn scale_from_distance(
    cameras: &Trajectory,
    a: usize,
    b: usize,
    metres: f64,
) -> Result<KnownDistance> {
    let n = cameras.len();
    for (what, i) in [("first pose", a), ("second pose", b)] {
        if i >= n {
            return Err(Error::invalid(
                "known_distance",
                format!(
                    "the {what} is {i}, and there are {n} poses (0 .. {})",
                    n.max(1) - 1
                ),
            ));
        }
    }
    scale_between(
        &cameras.positions[a],
        &cameras.positions[b],
        metres,
        cameras,
        &format!("poses {a} and {b}"),
    )
}

/// The scale that makes the SLAM-frame points `a` and `b` (camera centres
/// or map points; `what` names them in an error) `metres` apart; `cameras`
/// give the SLAM frame's size. Errors: a distance that is not a positive
/// number, a point not finite, the two at the same place (less than a
/// millionth of the cameras' extent apart).
pub fn scale_between(
    a: &Vector3<f64>,
    b: &Vector3<f64>,
    metres: f64,
    cameras: &Trajectory,
    what: &str,
) -> Result<KnownDistance> {
    if !(metres.is_finite() && metres > 0.0) {
        return Err(Error::invalid(
            "known_distance",
            format!("the distance must be a positive number of metres, got {metres}"),
        ));
    }
    if !a.iter().chain(b.iter()).all(|v| v.is_finite()) {
        return Err(Error::invalid(
            "known_distance",
            format!("{what}: the points must be finite"),
        ));
    }
    let d = (a - b).norm();
    // The SLAM frame's own size: a distance below a millionth of it is the
    // same place.
    let size = cameras
        .positions
        .iter()
        .map(|p| (p - cameras.positions[0]).norm())
        .fold(0.0, f64::max);
    if d.is_nan() || d <= 1e-6 * size {
        return Err(Error::Degenerate {
            reason: format!("{what} are at the same place: no scale from their distance"),
            value: d,
        });
    }
    Ok(KnownDistance {
        scale: metres / d,
        slam_distance: d,
        metres,
    })
}

/// The plane a ground robot's cameras ride in ([`planar_motion`]).
#[derive(Clone, Debug, PartialEq)]
pub struct PlanarMotion {
    /// Unit normal, towards the cameras' "image up".
    pub normal: Vector3<f64>,
    /// `normal · x + offset` is the height of `x` over the cameras' plane.
    pub offset: f64,
    /// Rms distance of the camera centres from the plane, SLAM units.
    pub rms: f64,
    /// Rms spread of the centres along the plane's narrower axis, SLAM units.
    pub extent: f64,
    /// Degrees a tilt can hide in the fit: `atan(rms / extent)`, the tilt
    /// of a plane through the centres that a slope as large as their
    /// out-of-plane spread would give.
    pub tilt_bound_deg: f64,
    /// Standard error of the normal, degrees, for out-of-plane errors that
    /// are independent from pose to pose (a lower bound on a real run).
    pub sigma_deg: f64,
    /// Camera centres fitted.
    pub n: usize,
}

/// The plane of `cameras`' centres, "up" from their orientations. Errors:
/// fewer than 3 poses or no orientations (up and down cannot be told), a
/// path whose [`PlanarMotion::tilt_bound_deg`] exceeds `max_tilt_bound_deg`
/// (a line, a hand-held camera, stairs; the default is
/// [`crate::defaults::PLANAR_MAX_TILT_BOUND_DEG`]), cameras whose "image up" does not
/// agree on a side of the plane.
pub fn planar_motion(cameras: &Trajectory, max_tilt_bound_deg: f64) -> Result<PlanarMotion> {
    if max_tilt_bound_deg.is_nan() || max_tilt_bound_deg <= 0.0 {
        return Err(Error::invalid(
            "max_tilt_bound_deg",
            format!("must be a positive number of degrees, got {max_tilt_bound_deg}"),
        ));
    }
    let n = cameras.len();
    if n < 3 {
        return Err(Error::TooFew {
            what: "camera poses for planar motion".into(),
            need: 3,
            got: n,
        });
    }
    let Some(orientations) = cameras.orientations.as_ref() else {
        return Err(Error::invalid(
            "planar_motion",
            "the poses have no orientations: up and down along the plane's normal cannot be told",
        ));
    };
    let c = cameras.positions.iter().sum::<Vector3<f64>>() / n as f64;
    let cov = cameras.positions.iter().fold(Matrix3::zeros(), |m, p| {
        let d = p - c;
        m + d * d.transpose()
    }) / n as f64;
    let e = SymmetricEigen::new(cov);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| e.eigenvalues[i].total_cmp(&e.eigenvalues[j]));
    let (l3, l2) = (
        e.eigenvalues[order[0]].max(0.0),
        e.eigenvalues[order[1]].max(0.0),
    );
    let (rms, extent) = (l3.sqrt(), l2.sqrt());
    let tilt_bound_deg = rms.atan2(extent).to_degrees();
    if tilt_bound_deg.is_nan() || tilt_bound_deg > max_tilt_bound_deg {
        return Err(Error::Degenerate {
            reason: format!(
                "the cameras do not ride in one plane: they leave their best plane by {rms:.3e} \
                 units rms against an in-plane spread of {extent:.3e}, so up is uncertain by up \
                 to {tilt_bound_deg:.1} deg (at most {max_tilt_bound_deg} deg; a line, a \
                 hand-held camera or stairs)"
            ),
            value: tilt_bound_deg,
        });
    }
    let mut normal = e.eigenvectors.column(order[0]).into_owned().normalize();
    let up: Vector3<f64> = orientations.iter().map(|q| -(q * Vector3::y())).sum();
    let agree = up.dot(&normal) / up.norm().max(f64::MIN_POSITIVE);
    if agree.is_nan() || agree.abs() < 0.5 {
        return Err(Error::Degenerate {
            reason: format!(
                "the cameras' image up lies along their plane ({:.0} deg from its normal): up \
                 and down cannot be told",
                agree.clamp(-1.0, 1.0).acos().to_degrees()
            ),
            value: agree,
        });
    }
    if agree < 0.0 {
        normal = -normal;
    }
    Ok(PlanarMotion {
        normal,
        offset: -normal.dot(&c),
        rms,
        extent,
        tilt_bound_deg,
        sigma_deg: (l3 / (n as f64 * l2.max(f64::MIN_POSITIVE)))
            .sqrt()
            .atan()
            .to_degrees(),
        n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::defaults::PLANAR_MAX_TILT_BOUND_DEG;

    fn planar_motion_default(c: &Trajectory) -> Result<PlanarMotion> {
        planar_motion(c, PLANAR_MAX_TILT_BOUND_DEG)
    }

    /// Cameras on a circle of radius 2 in the plane z = 1 of a turned frame,
    /// looking ahead with image y down; `bob` adds a vertical wiggle.
    fn circle(bob: f64) -> (Trajectory, UnitQuaternion<f64>) {
        let turn = UnitQuaternion::from_euler_angles(0.3, -0.7, 1.1);
        let mut pos = Vec::new();
        let mut rot = Vec::new();
        for k in 0..60 {
            let a = k as f64 * 0.1;
            pos.push(
                turn * Vector3::new(2.0 * a.cos(), 2.0 * a.sin(), 1.0 + bob * (7.0 * a).sin()),
            );
            let ahead = Vector3::new(-a.sin(), a.cos(), 0.0);
            let down = -Vector3::z();
            let r = Matrix3::from_columns(&[down.cross(&ahead), down, ahead]);
            rot.push(turn * UnitQuaternion::from_matrix(&r));
        }
        let stamps = (0..60).map(f64::from).collect();
        (Trajectory::try_new(stamps, pos, Some(rot)).unwrap(), turn)
    }

    #[test]
    fn a_flat_path_gives_up_and_the_level_frame_puts_the_first_camera_over_the_origin() {
        let (cams, turn) = circle(0.0);
        let p = planar_motion_default(&cams).unwrap();
        assert!(p.normal.angle(&(turn * Vector3::z())) < 1e-7, "{p:?}");
        assert!(p.rms < 1e-6 && p.tilt_bound_deg < 1e-4, "{p:?}");
        let t = level_frame(&p.normal, &cams, 2.5, 1.2);
        let c0 = t.transform_point(&cams.positions[0]);
        assert!((c0 - Vector3::new(0.0, 0.0, 1.2)).norm() < 1e-9, "{c0:?}");
        // Every camera at 1.2 m, heading along +x at the first.
        for c in &cams.positions {
            assert!((t.transform_point(c).z - 1.2).abs() < 1e-9);
        }
        let ahead = t.rotation * (cams.orientations.as_ref().unwrap()[0] * Vector3::z());
        assert!((ahead - Vector3::x()).norm() < 1e-9, "{ahead:?}");
    }

    #[test]
    fn a_path_off_its_plane_and_a_line_are_refused() {
        let (cams, _) = circle(0.6);
        let e = planar_motion_default(&cams).unwrap_err().to_string();
        assert!(e.contains("do not ride in one plane"), "{e}");
        let (mut cams, _) = circle(0.0);
        for (k, p) in cams.positions.iter_mut().enumerate() {
            let k = k as f64;
            *p = Vector3::new(k, 1e-3 * k.sin(), 1e-3 * (1.7 * k).cos());
        }
        assert!(planar_motion_default(&cams).is_err());
        cams.orientations = None;
        let e = planar_motion_default(&cams).unwrap_err().to_string();
        assert!(e.contains("no orientations"), "{e}");
    }

    #[test]
    fn a_known_distance_gives_the_scale() {
        let (cams, _) = circle(0.0);
        let k = scale_from_distance(&cams, 0, 31, 8.0).unwrap();
        let d = (cams.positions[0] - cams.positions[31]).norm();
        assert!((k.scale - 8.0 / d).abs() < 1e-12 && k.slam_distance == d);
        assert!(scale_from_distance(&cams, 0, 60, 1.0).is_err());
        assert!(scale_from_distance(&cams, 0, 5, -1.0).is_err());
        let e = scale_from_distance(&cams, 3, 3, 1.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("same place"), "{e}");
    }
}
