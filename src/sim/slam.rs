//! The SLAM-like estimate: what LSD-SLAM would publish for the true path.
//!
//! * The SLAM frame is the first camera frame with an unknown scale:
//!   `T_world_slam = (R_world_cam(0), t, s)`, `s` chosen so that the SLAM path
//!   is `slam_path_length` units long, `t` so that the stable stage maps exactly.
//! * Tracking (all frames): each frame-to-frame step is the true step carried
//!   into the SLAM frame and multiplied by a scale error `λ_k`: during the
//!   start stage `λ` wanders around `init_scale` with occasional jumps; in the
//!   converging stretch it moves smoothly (raised cosine) to 1; after it, `λ =
//!   1 + drift·(t − t_stable)`. Positions are the integral of the steps plus
//!   white noise and rare non-accumulating bursts; rotations carry white noise.
//! * Keyframes (the optimised map, as the final graph message gives it): the
//!   true pose in the SLAM frame (with the drift once stable) plus noise, and
//!   LSD-SLAM's normalisation: stored inverse depth has mean 1 and the factor
//!   is the Sim(3) scale of `T_slam_cam`.

use nalgebra::{UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, StandardNormal};

use crate::error::{Error, Result};
use crate::geometry::Sim3;

/// Seeded random source for one named stream of a run.
pub(crate) fn stream(seed: u64, id: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(mix(seed, id))
}

/// A 64-bit seed for stream `id` of a run (a splitmix64 step).
pub(crate) fn mix(seed: u64, id: u64) -> u64 {
    let mut z = seed ^ id.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A standard normal 3-vector times `sigma`.
pub(crate) fn gauss3(rng: &mut ChaCha8Rng, sigma: f64) -> Vector3<f64> {
    if sigma == 0.0 {
        return Vector3::zeros();
    }
    let mut g = || -> f64 { StandardNormal.sample(rng) };
    Vector3::new(g(), g(), g()) * sigma
}

/// Parameters of the scale error `λ_k` of the tracking.
#[derive(Clone, Copy, Debug)]
pub struct ScaleModel {
    /// First frame of the converging stretch.
    pub converge_start: usize,
    /// First frame of the stable stage.
    pub stable_start: usize,
    /// Level around which `λ` wanders in the start stage.
    pub init_scale: f64,
    /// Standard deviation of the slow wander of `ln λ` in the start stage.
    pub init_wander: f64,
    /// Probability per frame of a jump in the start stage (a fifth of it while converging).
    pub jump_prob: f64,
    /// Standard deviation of `ln` of a jump.
    pub jump_sigma: f64,
    /// Relative scale drift per second once stable.
    pub drift: f64,
}

/// The scale error `λ_k` of every frame-to-frame step `k → k+1` (`n − 1` values).
pub fn scale_errors(m: &ScaleModel, n: usize, fps: f64, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let steps = n.saturating_sub(1);
    let mut out = Vec::with_capacity(steps);
    let mut wander = 0.0f64;
    let ou_keep = 0.995f64;
    let ou_sigma = m.init_wander * (1.0 - ou_keep * ou_keep).sqrt();
    let mut level_at_converge = m.init_scale;
    for k in 0..steps {
        let jump = |rng: &mut ChaCha8Rng, p: f64, s: f64| -> f64 {
            if p > 0.0 && rng.random::<f64>() < p {
                let z: f64 = StandardNormal.sample(rng);
                (s * z).exp()
            } else {
                1.0
            }
        };
        let lam = if k < m.converge_start {
            let z: f64 = StandardNormal.sample(rng);
            wander = ou_keep * wander + ou_sigma * z;
            let level = m.init_scale * wander.exp();
            level_at_converge = level;
            level * jump(rng, m.jump_prob, m.jump_sigma)
        } else if k < m.stable_start {
            let u = (k - m.converge_start) as f64 / (m.stable_start - m.converge_start) as f64;
            let w = 0.5 * (1.0 + (std::f64::consts::PI * u).cos());
            (1.0 + (level_at_converge - 1.0) * w) * jump(rng, 0.2 * m.jump_prob, 0.3 * m.jump_sigma)
        } else {
            1.0 + m.drift * (k - m.stable_start) as f64 / fps
        };
        out.push(lam);
    }
    out
}

/// Noise of the tracking poses.
#[derive(Clone, Copy, Debug)]
pub struct TrackingNoise {
    /// White position noise, SLAM units.
    pub pos_sigma: f64,
    /// White rotation noise (rotation-vector components), rad.
    pub rot_sigma: f64,
    /// Probability per frame of a burst (a non-accumulating position error) once stable.
    pub burst_prob: f64,
    /// Standard deviation of a burst, SLAM units.
    pub burst_sigma: f64,
}

/// The tracked SLAM poses `T_slam_cam` of every frame, with the true
/// `T_world_slam`. `world_pos`, `world_rot` are the true `T_world_cam`.
pub struct Tracking {
    /// SLAM positions of every frame, SLAM units.
    pub positions: Vec<Vector3<f64>>,
    /// SLAM orientations `R_slam_cam`.
    pub orientations: Vec<UnitQuaternion<f64>>,
    /// Noise-free SLAM positions (the integral of the scaled steps).
    pub clean_positions: Vec<Vector3<f64>>,
    /// The true `T_world_slam`.
    pub t_world_slam: Sim3,
}

/// Integrates the scaled steps into the SLAM frame (see the module doc).
pub fn track(
    world_pos: &[Vector3<f64>],
    world_rot: &[UnitQuaternion<f64>],
    lambda: &[f64],
    stable_start: usize,
    slam_path_length: f64,
    noise: &TrackingNoise,
    rng: &mut ChaCha8Rng,
) -> Result<Tracking> {
    let n = world_pos.len();
    if n < 2 || world_rot.len() != n || lambda.len() + 1 != n {
        return Err(Error::TooFew {
            what: "frames (positions, rotations, n-1 scale errors)".into(),
            need: 2,
            got: n,
        });
    }
    if !(slam_path_length.is_finite() && slam_path_length > 0.0) {
        return Err(Error::invalid(
            "slam_path_length",
            format!("must be > 0, got {slam_path_length}"),
        ));
    }
    let scaled: f64 = (0..n - 1)
        .map(|k| lambda[k] * (world_pos[k + 1] - world_pos[k]).norm())
        .sum();
    if scaled <= 0.0 {
        return Err(Error::Degenerate {
            reason: "the camera does not move".into(),
            value: scaled,
        });
    }
    let s = scaled / slam_path_length;
    let r_ws = world_rot[0];
    let r_sw = r_ws.inverse();
    let mut clean = Vec::with_capacity(n);
    clean.push(Vector3::zeros());
    for k in 0..n - 1 {
        let step = r_sw * (world_pos[k + 1] - world_pos[k]) * (lambda[k] / s);
        clean.push(clean[k] + step);
    }
    let kk = stable_start.min(n - 1);
    let t = world_pos[kk] - r_ws * clean[kk] * s;
    let t_world_slam = Sim3::try_new(r_ws, t, s)?;
    let burst = Normal::new(0.0, noise.burst_sigma.max(0.0))
        .map_err(|e| Error::invalid("burst_sigma", e.to_string()))?;
    let mut positions = Vec::with_capacity(n);
    let mut orientations = Vec::with_capacity(n);
    for k in 0..n {
        let mut p = clean[k] + gauss3(rng, noise.pos_sigma);
        if k >= kk && noise.burst_prob > 0.0 && rng.random::<f64>() < noise.burst_prob {
            p += Vector3::new(burst.sample(rng), burst.sample(rng), burst.sample(rng));
        }
        positions.push(p);
        let dq = UnitQuaternion::from_scaled_axis(gauss3(rng, noise.rot_sigma));
        orientations.push(r_sw * world_rot[k] * dq);
    }
    Ok(Tracking {
        positions,
        orientations,
        clean_positions: clean,
        t_world_slam,
    })
}

/// LSD-SLAM's keyframe normalisation: divides the inverse depth (SLAM units)
/// by its mean over the valid pixels, scales the variance accordingly, and
/// returns the factor `σ = 1 / mean` that becomes the keyframe's Sim(3) scale.
/// Errors when no pixel has depth.
pub fn normalise(idepth: &mut [f32], idepth_var: &mut [f32]) -> Result<f64> {
    let (sum, count) = idepth
        .iter()
        .filter(|&&v| v > 0.0)
        .fold((0.0f64, 0usize), |(s, c), &v| (s + v as f64, c + 1));
    if count == 0 {
        return Err(Error::TooFew {
            what: "keyframe pixels with depth".into(),
            need: 1,
            got: 0,
        });
    }
    let mean = sum / count as f64;
    let k = 1.0 / mean;
    for (d, v) in idepth.iter_mut().zip(idepth_var.iter_mut()) {
        if *d > 0.0 {
            *d = (*d as f64 * k) as f32;
            *v = (*v as f64 * k * k) as f32;
        }
    }
    Ok(k)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> ScaleModel {
        ScaleModel {
            converge_start: 100,
            stable_start: 400,
            init_scale: 2.0,
            init_wander: 0.2,
            jump_prob: 0.05,
            jump_sigma: 0.5,
            drift: 0.0,
        }
    }

    #[test]
    fn scale_error_has_three_stages() {
        let mut rng = stream(1, 1);
        let l = scale_errors(&model(), 600, 60.0, &mut rng);
        assert_eq!(l.len(), 599);
        assert!(l[400..].iter().all(|&v| v == 1.0));
        let early = l[..100].iter().filter(|&&v| (v - 1.0).abs() > 0.2).count();
        assert!(early > 50, "start stage should be off the stable level");
        assert!((l[399] - 1.0).abs() < 0.05 * (l[100] - 1.0).abs().max(0.1) + 0.05);
    }

    #[test]
    fn tracking_maps_the_stable_stage_exactly() {
        let n = 500;
        let pos: Vec<Vector3<f64>> = (0..n)
            .map(|k| {
                let t = k as f64 * 0.05;
                Vector3::new(t.cos() * 3.0, t.sin() * 2.0, 1.0 + 0.1 * t)
            })
            .collect();
        let rot: Vec<UnitQuaternion<f64>> = (0..n)
            .map(|k| UnitQuaternion::from_euler_angles(0.1, -0.2, 0.01 * k as f64))
            .collect();
        let mut rng = stream(2, 1);
        let lam = scale_errors(&model(), n, 60.0, &mut rng);
        let noise = TrackingNoise {
            pos_sigma: 0.0,
            rot_sigma: 0.0,
            burst_prob: 0.0,
            burst_sigma: 0.0,
        };
        let tr = track(&pos, &rot, &lam, 400, 2.0, &noise, &mut rng).unwrap();
        let len: f64 = tr.positions.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
        assert!((len - 2.0).abs() < 1e-9);
        assert!(tr.positions[0].norm() == 0.0);
        for k in 400..n {
            let back = tr.t_world_slam.transform_point(&tr.positions[k]);
            assert!((back - pos[k]).norm() < 1e-9);
            let r = tr.t_world_slam.rotation * tr.orientations[k];
            assert!(r.angle_to(&rot[k]) < 1e-12);
        }
        assert!((tr.t_world_slam.transform_point(&tr.positions[50]) - pos[50]).norm() > 1e-3);
    }

    #[test]
    fn normalisation_gives_mean_one() {
        let mut d = vec![0.0f32, 2.0, 4.0, -1.0, 6.0];
        let mut v = vec![0.0f32, 0.04, 0.16, 0.0, 0.36];
        let k = normalise(&mut d, &mut v).unwrap();
        assert!((k - 0.25).abs() < 1e-12);
        assert_eq!(d, vec![0.0, 0.5, 1.0, -1.0, 1.5]);
        assert!((v[2] - 0.01).abs() < 1e-9);
        assert!(normalise(&mut [0.0f32], &mut [0.0f32]).is_err());
    }
}
