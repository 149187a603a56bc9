//! Fits with other degrees of freedom and anchored fits (`align::dof`):
//! exact recovery of known transforms, the least-squares optimum against a
//! brute-force search of the same cost, rpg_trajectory_evaluation's `posyaw`
//! alignment on EuRoC V1_02, the gravity check, degenerate input, the robust
//! and windowed variants and the covariance of the dof's own parameters.

use std::f64::consts::PI;

use nalgebra::{DMatrix, DVector, Matrix3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal, UnitSphere};
use slam2world::align::covariance::covariance;
use slam2world::align::dof::{
    align_dof, align_dof_robust, covariance_dof, fit_window, Anchor, Dof, DofOptions,
};
use slam2world::align::robust::{align_robust, RobustOptions};
use slam2world::align::windowed::{windowed_fits, windowed_fits_with};
use slam2world::align::{align, AlignMethod, AlignOptions, Alignment};
use slam2world::trajectory::associate;
use slam2world::{Error, Sim3, Trajectory};

use crate::common;

const ANCHORS: [Anchor; 2] = [Anchor::None, Anchor::First];

fn gauss(rng: &mut ChaCha8Rng) -> Vector3<f64> {
    Vector3::new(
        StandardNormal.sample(rng),
        StandardNormal.sample(rng),
        StandardNormal.sample(rng),
    )
}

/// A flight-like path (horizontal loops, some climb) about `centre`, metres.
fn track(rng: &mut ChaCha8Rng, n: usize, centre: Vector3<f64>) -> Vec<Vector3<f64>> {
    (0..n)
        .map(|i| {
            let f = i as f64;
            let smooth = Vector3::new(
                4.0 * (0.031 * f).cos(),
                2.5 * (0.047 * f).sin(),
                0.8 * (0.013 * f).sin(),
            );
            centre + smooth + gauss(rng) * 0.3
        })
        .collect()
}

fn yaw(psi: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Vector3::z_axis(), psi)
}

fn random_rotation(rng: &mut ChaCha8Rng) -> UnitQuaternion<f64> {
    let axis: [f64; 3] = UnitSphere.sample(rng);
    UnitQuaternion::from_scaled_axis(Vector3::from(axis) * rng.random_range(-3.1..3.1))
}

/// A random transform of the family `dof` allows.
fn truth(rng: &mut ChaCha8Rng, dof: Dof) -> Sim3 {
    let t = Vector3::new(
        rng.random_range(-50.0..50.0),
        rng.random_range(-50.0..50.0),
        rng.random_range(-50.0..50.0),
    );
    let rotation = if dof.yaw_only() {
        yaw(rng.random_range(-PI..PI))
    } else {
        random_rotation(rng)
    };
    let scale = if dof.has_scale() {
        10f64.powf(rng.random_range(-1.0..1.0))
    } else {
        1.0
    };
    Sim3::try_new(rotation, t, scale).unwrap()
}

fn apply(t: &Sim3, a: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    a.iter().map(|p| t.transform_point(p)).collect()
}

fn opts(dof: Dof, anchor: Anchor) -> DofOptions {
    DofOptions {
        dof,
        anchor,
        ..Default::default()
    }
}

/// [`opts`] without the gravity check: the noise of these tests is large
/// against the track's extent, which tilts the Sim(3) by up to a few degrees
/// (the check has its own test).
fn unchecked(dof: Dof, anchor: Anchor) -> DofOptions {
    DofOptions {
        max_tilt_deg: None,
        ..opts(dof, anchor)
    }
}

/// `Σ w ‖b − T(a)‖²`.
fn cost(t: &Sim3, a: &[Vector3<f64>], b: &[Vector3<f64>], w: Option<&[f64]>) -> f64 {
    a.iter()
        .zip(b)
        .enumerate()
        .map(|(i, (p, q))| w.map_or(1.0, |w| w[i]) * (q - t.transform_point(p)).norm_squared())
        .sum()
}

/// Relative scale difference, rotation angle (rad), translation difference over `size`.
fn diff(a: &Sim3, b: &Sim3, size: f64) -> (f64, f64, f64) {
    (
        (a.scale - b.scale).abs() / b.scale,
        a.rotation.angle_to(&b.rotation),
        (a.translation - b.translation).norm() / size,
    )
}

// ------------------------------------------------------------ brute force

/// The transforms of a dof and anchor as a parameter vector: a yaw (rad) or
/// a rotation vector applied before `r0`, the translation unless anchored
/// (then `t = b₀ − s·R·a₀`), `ln s` when scaled.
struct Params {
    dof: Dof,
    anchor: Anchor,
    r0: UnitQuaternion<f64>,
    a0: Vector3<f64>,
    b0: Vector3<f64>,
}

impl Params {
    fn rotation_len(&self) -> usize {
        if self.dof.yaw_only() {
            1
        } else {
            3
        }
    }

    fn transform(&self, p: &[f64]) -> Sim3 {
        let k = self.rotation_len();
        let rotation = if self.dof.yaw_only() {
            yaw(p[0])
        } else {
            UnitQuaternion::from_scaled_axis(Vector3::new(p[0], p[1], p[2])) * self.r0
        };
        let scale = if self.dof.has_scale() {
            p[p.len() - 1].exp()
        } else {
            1.0
        };
        let translation = match self.anchor {
            Anchor::None => Vector3::new(p[k], p[k + 1], p[k + 2]),
            Anchor::First => self.b0 - rotation * self.a0 * scale,
        };
        Sim3 {
            rotation,
            translation,
            scale,
        }
    }
}

/// Central-difference Jacobian of `f` at `p`.
fn jacobian(f: &dyn Fn(&[f64]) -> Vec<f64>, p: &[f64], rows: usize) -> DMatrix<f64> {
    let mut j = DMatrix::<f64>::zeros(rows, p.len());
    for q in 0..p.len() {
        let h = 1e-6 * (1.0 + p[q].abs());
        let mut hi = p.to_vec();
        hi[q] += h;
        let mut lo = p.to_vec();
        lo[q] -= h;
        for (row, (x, y)) in f(&hi).iter().zip(&f(&lo)).enumerate() {
            j[(row, q)] = (x - y) / (2.0 * h);
        }
    }
    j
}

/// Levenberg–Marquardt on the stacked residuals `f(p)` with a central-difference
/// Jacobian, then plain Gauss–Newton steps to the stationary point (the cost
/// alone stops changing before the parameters do); returns the parameters and
/// the sum of squares.
fn minimise(f: &dyn Fn(&[f64]) -> Vec<f64>, mut p: Vec<f64>) -> (Vec<f64>, f64) {
    let sq = |r: &[f64]| r.iter().map(|x| x * x).sum::<f64>();
    let mut r = f(&p);
    let mut c = sq(&r);
    let mut lambda = 1e-3;
    let k = p.len();
    for _ in 0..400 {
        let j = jacobian(f, &p, r.len());
        let g = j.transpose() * DVector::from_column_slice(&r);
        let a = j.transpose() * &j;
        let mut stepped = false;
        while lambda < 1e12 {
            let mut damped = a.clone();
            for d in 0..k {
                damped[(d, d)] += lambda * a[(d, d)].max(1e-12);
            }
            let Some(delta) = damped.lu().solve(&(-&g)) else {
                lambda *= 10.0;
                continue;
            };
            let next: Vec<f64> = p.iter().zip(delta.iter()).map(|(x, d)| x + d).collect();
            let rn = f(&next);
            let cn = sq(&rn);
            if cn < c {
                p = next;
                r = rn;
                c = cn;
                lambda = (lambda * 0.3).max(1e-12);
                stepped = true;
                break;
            }
            lambda *= 10.0;
        }
        if !stepped {
            break;
        }
    }
    for _ in 0..5 {
        let j = jacobian(f, &p, r.len());
        let g = j.transpose() * DVector::from_column_slice(&r);
        let Some(delta) = (j.transpose() * &j).lu().solve(&(-g)) else {
            break;
        };
        let next: Vec<f64> = p.iter().zip(delta.iter()).map(|(x, d)| x + d).collect();
        let rn = f(&next);
        let cn = sq(&rn);
        if cn > c * (1.0 + 1e-12) {
            break;
        }
        (p, r, c) = (next, rn, cn);
    }
    (p, c)
}

/// The minimum of `Σ w ‖b − T(a)‖²` over the transforms of `dof` with
/// `anchor`, by multi-start Levenberg–Marquardt on the raw cost (24 yaws on
/// a grid, or 24 random rotations and the identity).
fn brute_force(
    a: &[Vector3<f64>],
    b: &[Vector3<f64>],
    w: Option<&[f64]>,
    dof: Dof,
    anchor: Anchor,
) -> (Sim3, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(99);
    let n = a.len() as f64;
    let mean = |v: &[Vector3<f64>]| v.iter().sum::<Vector3<f64>>() / n;
    let (ma, mb) = (mean(a), mean(b));
    let spread =
        |v: &[Vector3<f64>], m: Vector3<f64>| v.iter().map(|p| (p - m).norm_squared()).sum::<f64>();
    let s0 = if dof.has_scale() {
        (spread(b, mb) / spread(a, ma)).sqrt()
    } else {
        1.0
    };
    let starts: Vec<(f64, UnitQuaternion<f64>)> = if dof.yaw_only() {
        (0..24)
            .map(|k| (-PI + k as f64 * PI / 12.0, UnitQuaternion::identity()))
            .collect()
    } else {
        std::iter::once(UnitQuaternion::identity())
            .chain((0..24).map(|_| random_rotation(&mut rng)))
            .map(|r| (0.0, r))
            .collect()
    };
    let mut best: Option<(Sim3, f64)> = None;
    for (psi, r0) in starts {
        let par = Params {
            dof,
            anchor,
            r0,
            a0: a[0],
            b0: b[0],
        };
        let mut p0 = Vec::new();
        if dof.yaw_only() {
            p0.push(psi);
        } else {
            p0.extend([0.0; 3]);
        }
        if anchor == Anchor::None {
            let r = if dof.yaw_only() { yaw(psi) } else { r0 };
            p0.extend((mb - r * ma * s0).iter());
        }
        if dof.has_scale() {
            p0.push(s0.ln());
        }
        let f = |p: &[f64]| -> Vec<f64> {
            let t = par.transform(p);
            a.iter()
                .zip(b)
                .enumerate()
                .flat_map(|(i, (x, y))| {
                    let e = (y - t.transform_point(x)) * w.map_or(1.0, |w| w[i]).sqrt();
                    [e.x, e.y, e.z]
                })
                .collect()
        };
        let (p, c) = minimise(&f, p0);
        if best.as_ref().is_none_or(|(_, bc)| c < *bc) {
            best = Some((par.transform(&p), c));
        }
    }
    best.unwrap()
}

// ------------------------------------------------------------ rpg reference

/// rpg_trajectory_evaluation's `posyaw` alignment over all frames, as written
/// in uzh-rpg/rpg_trajectory_evaluation@8c8ceec (MIT):
/// `align_utils.alignPositionYaw(p_es, p_gt, …, n_aligned=-1)` calls
/// `align_trajectory.align_umeyama(gt, est, known_scale=True, yaw_only=True)`:
/// unweighted means, `rot_C = data_zc.T @ model_zc` (data = estimate),
/// `get_best_yaw`: `θ = π/2 − atan2(C00 + C11, C01 − C10)`, `R = rot_z(θ)`
/// (`transformations.rotation_matrix(θ, [0, 0, 1])`), `t = μ_gt − R·μ_est`.
fn rpg_posyaw(est: &[Vector3<f64>], gt: &[Vector3<f64>]) -> (Matrix3<f64>, Vector3<f64>) {
    let n = est.len() as f64;
    let mu_m = gt.iter().sum::<Vector3<f64>>() / n;
    let mu_d = est.iter().sum::<Vector3<f64>>() / n;
    let mut c = Matrix3::zeros();
    for (d, m) in est.iter().zip(gt) {
        c += (d - mu_d) * (m - mu_m).transpose();
    }
    let a = c[(0, 1)] - c[(1, 0)];
    let b = c[(0, 0)] + c[(1, 1)];
    let theta = PI / 2.0 - b.atan2(a);
    let (s, co) = theta.sin_cos();
    let r = Matrix3::new(co, -s, 0.0, s, co, 0.0, 0.0, 0.0, 1.0);
    (r, mu_m - r * mu_d)
}

fn assert_equals_rpg(fit: &Alignment, est: &[Vector3<f64>], gt: &[Vector3<f64>], what: &str) {
    let (r, t) = rpg_posyaw(est, gt);
    let dr = (fit.transform.rotation_matrix() - r).amax();
    let dt = (fit.transform.translation - t).amax();
    assert!(dr < 1e-9 && dt < 1e-9, "{what}: |ΔR| {dr:e}, |Δt| {dt:e} m");
    assert_eq!(fit.transform.scale, 1.0);
}

fn euroc_ground_truth() -> Option<Trajectory> {
    let p = common::data("euroc_v102", "V102_groundtruth.csv")?;
    Some(slam2world::io::text::read_euroc(p).unwrap())
}

// ------------------------------------------------------------ tests

#[test]
fn each_dof_recovers_a_known_transform_exactly() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for dof in Dof::ALL {
        for anchor in ANCHORS {
            for trial in 0..5 {
                let n = rng.random_range(2..300).max(dof.min_pairs() + 1);
                let a = track(&mut rng, n, Vector3::new(3.0, -7.0, 1.0));
                let t = truth(&mut rng, dof);
                let b = apply(&t, &a);
                let fit = align_dof(&a, &b, &opts(dof, anchor)).unwrap();
                let size = t.translation.norm() + t.scale * 10.0;
                let (ds, da, dt) = diff(&fit.transform, &t, size);
                assert!(
                    ds < 1e-12 && da < 1e-12 && dt < 1e-12,
                    "{dof} {anchor} #{trial} n={n}: {ds:e} {da:e} {dt:e}"
                );
                assert!(fit.rmse < 1e-12 * size, "{dof} {anchor}: rmse {}", fit.rmse);
                assert_eq!(fit.residuals.len(), n);
                if !dof.has_scale() {
                    assert_eq!(fit.transform.scale, 1.0);
                }
                if dof.yaw_only() {
                    let z = fit.transform.rotation * Vector3::z();
                    assert!(z.xy().norm() < 1e-15, "{dof}: a yaw only, z -> {z:?}");
                }
            }
        }
    }
}

#[test]
fn sim3_and_se3_without_anchor_are_align() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let a = track(&mut rng, 80, Vector3::new(1.0, 2.0, 3.0));
    let t = truth(&mut rng, Dof::Sim3);
    let mut b = apply(&t, &a);
    for p in &mut b {
        *p += gauss(&mut rng) * 0.05;
    }
    let w: Vec<f64> = (0..80).map(|i| 0.5 + (i % 7) as f64).collect();
    for (dof, scale) in [(Dof::Sim3, true), (Dof::Se3, false)] {
        for method in [AlignMethod::Horn, AlignMethod::Umeyama] {
            for weights in [None, Some(w.clone())] {
                let o = DofOptions {
                    dof,
                    method,
                    weights: weights.clone(),
                    ..Default::default()
                };
                let plain = align(
                    &a,
                    &b,
                    &AlignOptions {
                        scale,
                        method,
                        weights,
                    },
                )
                .unwrap();
                assert_eq!(align_dof(&a, &b, &o).unwrap(), plain, "{dof} {method:?}");
            }
        }
        let mut outlying = b.clone();
        outlying[5] += Vector3::new(30.0, 0.0, 0.0);
        let ro = RobustOptions::default();
        let plain = align_robust(
            &a,
            &outlying,
            &AlignOptions {
                scale,
                ..Default::default()
            },
            &ro,
        )
        .unwrap();
        let r = align_dof_robust(&a, &outlying, &opts(dof, Anchor::None), &ro).unwrap();
        assert_eq!(r, plain);
    }
}

#[test]
#[ignore = "slow: make test runs it"]
fn noisy_fits_are_the_least_squares_optimum() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for dof in Dof::ALL {
        for anchor in ANCHORS {
            for weighted in [false, true] {
                let n = 40;
                let a = track(&mut rng, n, Vector3::new(-2.0, 5.0, 0.5));
                let t = truth(&mut rng, dof);
                // Noise, and a tilt the yaw-only fits cannot follow (0.8°).
                let tilt = UnitQuaternion::from_euler_angles(0.8f64.to_radians(), 0.0, 0.0);
                let b: Vec<_> = a
                    .iter()
                    .map(|p| t.transform_point(&(tilt * p)) + gauss(&mut rng) * 0.1 * t.scale)
                    .collect();
                let w: Option<Vec<f64>> =
                    weighted.then(|| (0..n).map(|_| rng.random_range(0.2..3.0)).collect());
                let o = DofOptions {
                    weights: w.clone(),
                    ..unchecked(dof, anchor)
                };
                let fit = align_dof(&a, &b, &o).unwrap();
                let (bf, bf_cost) = brute_force(&a, &b, w.as_deref(), dof, anchor);
                let cf_cost = cost(&fit.transform, &a, &b, w.as_deref());
                let size = t.translation.norm() + t.scale * 10.0;
                let (ds, da, dt) = diff(&fit.transform, &bf, size);
                let what = format!("{dof} {anchor} weighted={weighted}");
                assert!(
                    ds < 1e-8 && da < 1e-8 && dt < 1e-8,
                    "{what}: closed form vs brute force {ds:e} {da:e} {dt:e}"
                );
                assert!(
                    cf_cost <= bf_cost * (1.0 + 1e-12),
                    "{what}: cost {cf_cost} above the brute-force {bf_cost}"
                );
                // The fit's rmse is the weighted rms of its residuals.
                let wsum = w.as_ref().map_or(n as f64, |w| w.iter().sum());
                assert!((fit.rmse - (cf_cost / wsum).sqrt()).abs() < 1e-12 * fit.rmse);
            }
        }
    }
}

#[test]
fn anchor_first_pins_the_first_pair() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    for dof in Dof::ALL {
        let a = track(&mut rng, 60, Vector3::new(0.0, 0.0, 0.0));
        let t = truth(&mut rng, dof);
        let b: Vec<_> = a
            .iter()
            .map(|p| t.transform_point(p) + gauss(&mut rng) * 0.2 * t.scale)
            .collect();
        let free = align_dof(&a, &b, &unchecked(dof, Anchor::None)).unwrap();
        let pinned = align_dof(&a, &b, &unchecked(dof, Anchor::First)).unwrap();
        let scale = b[0].norm() + t.scale * a[0].norm() + 1.0;
        assert!(
            pinned.residuals[0] <= 1e-13 * scale,
            "{dof}: first pair off by {}",
            pinned.residuals[0]
        );
        assert!(
            free.residuals[0] > 1e-3,
            "{dof}: the free fit already pins it"
        );
        // A constraint can only raise the cost.
        assert!(pinned.rmse >= free.rmse, "{dof}");
        let d = pinned.diagnostics.dof.as_ref().unwrap();
        assert_eq!((d.dof, d.anchor), (dof, Anchor::First));
    }
    // The anchor is pinned whatever its weight, and counts towards the pairs.
    let a = track(&mut rng, 10, Vector3::zeros());
    let b = apply(&truth(&mut rng, Dof::FourDof), &a);
    let mut w = vec![0.0; 10];
    w[4] = 1.0;
    let o = DofOptions {
        weights: Some(w),
        ..opts(Dof::FourDof, Anchor::First)
    };
    let fit = align_dof(&a, &b, &o).unwrap();
    assert!(
        fit.residuals.iter().all(|&r| r < 1e-12),
        "{:?}",
        fit.residuals
    );
}

#[test]
fn euroc_ground_truth_with_a_secret_yaw_and_translation() {
    let Some(gt) = euroc_ground_truth() else {
        return;
    };
    let world = &gt.positions;
    let secret = Sim3::try_new(yaw(1.234_567), Vector3::new(12.5, -3.25, 0.75), 1.0).unwrap();
    let est = apply(&secret.inverse(), world);
    let fit = align_dof(&est, world, &opts(Dof::FourDof, Anchor::None)).unwrap();
    let (ds, da, dt) = diff(&fit.transform, &secret, 20.0);
    assert!(da < 1e-12 && dt < 1e-12 && ds == 0.0, "{da:e} {dt:e}");
    assert!(fit.rmse < 1e-12);
    assert_equals_rpg(&fit, &est, world, "EuRoC V1_02, secret yaw");

    // Secret scale too: only scale+4dof recovers it.
    let secret5 = Sim3::try_new(yaw(-2.5), Vector3::new(-4.0, 8.0, -1.5), 3.7).unwrap();
    let est5 = apply(&secret5.inverse(), world);
    let fit5 = align_dof(&est5, world, &opts(Dof::ScaleFourDof, Anchor::None)).unwrap();
    let (ds, da, dt) = diff(&fit5.transform, &secret5, 20.0);
    assert!(
        ds < 1e-12 && da < 1e-12 && dt < 1e-12,
        "{ds:e} {da:e} {dt:e}"
    );
    let fit4 = align_dof(&est5, world, &opts(Dof::FourDof, Anchor::None)).unwrap();
    assert!(
        fit4.rmse > 0.1,
        "4dof cannot absorb a scale of 3.7: {}",
        fit4.rmse
    );
}

#[test]
fn gravity_aligned_vio_like_estimates_match_rpg_posyaw() {
    let Some(gt) = euroc_ground_truth() else {
        return;
    };
    // Every 20th pose (10 Hz), with the yaw drifting by 1.5° over the run,
    // a random-walk position drift and white noise; gravity stays along z.
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let world: Vec<Vector3<f64>> = gt.positions.iter().step_by(20).copied().collect();
    let n = world.len();
    let secret = Sim3::try_new(yaw(-0.7), Vector3::new(2.0, 1.0, -0.3), 1.0).unwrap();
    let mut drift = Vector3::zeros();
    let est: Vec<Vector3<f64>> = world
        .iter()
        .enumerate()
        .map(|(i, p)| {
            drift += gauss(&mut rng) * 0.002;
            let psi = 1.5f64.to_radians() * i as f64 / n as f64;
            let vio = yaw(psi) * p + drift + gauss(&mut rng) * 0.01;
            secret.inverse().transform_point(&vio)
        })
        .collect();
    let fit = align_dof(&est, &world, &opts(Dof::FourDof, Anchor::None)).unwrap();
    assert!(fit.rmse > 0.005 && fit.rmse < 0.2, "rmse {}", fit.rmse);
    assert_equals_rpg(&fit, &est, &world, "EuRoC V1_02, VIO-like");
    let tilt = fit
        .diagnostics
        .dof
        .as_ref()
        .unwrap()
        .gravity_tilt_deg
        .unwrap();
    assert!(tilt < 0.5, "gravity-aligned, tilt {tilt}°");

    // The estimate shipped with the data (10 Hz, roughly metric, gravity
    // aligned), matched by time as evo does.
    let Some(p) = common::data("euroc_v102", "V102.txt") else {
        return;
    };
    let vio = slam2world::io::text::read_tum(p).unwrap();
    let pairs = associate(&vio, &gt, 0.01, 0.0);
    assert!(pairs.len() > 790, "{} pairs", pairs.len());
    let est: Vec<_> = pairs.iter().map(|&(i, _)| vio.positions[i]).collect();
    let world: Vec<_> = pairs.iter().map(|&(_, j)| gt.positions[j]).collect();
    let fit = align_dof(&est, &world, &opts(Dof::FourDof, Anchor::None)).unwrap();
    assert_equals_rpg(&fit, &est, &world, "EuRoC V1_02, V102.txt");
    let se3 = align_dof(&est, &world, &opts(Dof::Se3, Anchor::None)).unwrap();
    // evo's SE(3) figure (PROVENANCE.md); the 4-DoF fit can only be worse.
    assert!((se3.rmse - 0.091727).abs() < 5e-6, "se3 rmse {}", se3.rmse);
    assert!(
        fit.rmse >= se3.rmse && fit.rmse < 1.1 * se3.rmse,
        "4dof rmse {}",
        fit.rmse
    );
    eprintln!(
        "V102.txt: 4dof rmse {:.6} m (se3 {:.6} m), Sim(3) tilt {:.3} deg, yaw determinacy {:.6}",
        fit.rmse,
        se3.rmse,
        fit.diagnostics
            .dof
            .as_ref()
            .unwrap()
            .gravity_tilt_deg
            .unwrap(),
        fit.diagnostics.dof.as_ref().unwrap().yaw_determinacy,
    );
}

#[test]
fn tilted_gravity_is_refused() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let world = track(&mut rng, 200, Vector3::new(5.0, 5.0, 1.0));
    for (deg, refused) in [(3.0, true), (0.5, false)] {
        let axis = Vector3::new(0.6, -0.8, 0.0);
        let tilt = UnitQuaternion::from_scaled_axis(axis * f64::to_radians(deg));
        let t = Sim3::try_new(yaw(0.4) * tilt, Vector3::new(1.0, -2.0, 0.5), 2.0).unwrap();
        let est = apply(&t.inverse(), &world);
        for dof in [Dof::FourDof, Dof::ScaleFourDof] {
            for anchor in ANCHORS {
                let r = align_dof(&est, &world, &opts(dof, anchor));
                if refused {
                    match r {
                        Err(
                            ref e @ Error::GravityTilted {
                                dof: ref named,
                                angle_deg,
                                threshold_deg,
                            },
                        ) => {
                            assert!((angle_deg - deg).abs() < 1e-9, "{angle_deg}");
                            assert_eq!(threshold_deg, 2.0);
                            assert_eq!(named, dof.as_str());
                            assert!(e.to_string().contains("dof=\"sim3\""), "{e}");
                        }
                        other => panic!("{dof} {anchor}: {other:?}"),
                    }
                } else {
                    let fit = r.unwrap();
                    let d = fit.diagnostics.dof.as_ref().unwrap();
                    assert!((d.gravity_tilt_deg.unwrap() - deg).abs() < 1e-9);
                }
            }
        }
        // The threshold is an option; None turns the check off.
        let o = DofOptions {
            max_tilt_deg: Some(5.0),
            ..opts(Dof::ScaleFourDof, Anchor::None)
        };
        assert!(align_dof(&est, &world, &o).is_ok());
        let o = DofOptions {
            max_tilt_deg: None,
            ..opts(Dof::FourDof, Anchor::None)
        };
        assert!(align_dof(&est, &world, &o).is_ok());
        // Sim(3) does not assume gravity.
        assert!(align_dof(&est, &world, &opts(Dof::Sim3, Anchor::First)).is_ok());
    }
    let o = DofOptions {
        max_tilt_deg: Some(-1.0),
        ..opts(Dof::FourDof, Anchor::None)
    };
    assert!(matches!(
        align_dof(&world, &world, &o),
        Err(Error::InvalidArgument { .. })
    ));
}

#[test]
fn degenerate_inputs_are_refused_with_the_figure() {
    // Vertical motion only: no yaw, whatever the anchor.
    let column: Vec<_> = (0..20)
        .map(|i| Vector3::new(1.5, -2.0, 0.1 * i as f64))
        .collect();
    let mut moved = column.clone();
    for p in &mut moved {
        p.z += 3.0;
    }
    for dof in [Dof::FourDof, Dof::ScaleFourDof] {
        for anchor in ANCHORS {
            match align_dof(&column, &moved, &opts(dof, anchor)) {
                Err(Error::Degenerate { reason, value }) => {
                    assert!(
                        reason.contains("horizontally") && reason.contains("yaw"),
                        "{reason}"
                    );
                    assert_eq!(value, 0.0);
                }
                other => panic!("{dof} {anchor}: {other:?}"),
            }
        }
    }
    // A mirror image: horizontal motion on both sides, but no yaw relates them.
    let a = [
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(-1.0, 0.0, 0.0),
        Vector3::new(0.0, 1.0, 0.0),
        Vector3::new(0.0, -1.0, 0.0),
    ];
    let b: Vec<_> = a.iter().map(|p| Vector3::new(p.x, -p.y, p.z)).collect();
    match align_dof(&a, &b, &opts(Dof::FourDof, Anchor::None)) {
        Err(Error::Degenerate { reason, value }) => {
            assert!(reason.contains("yaw determinacy"), "{reason}");
            assert!(value.abs() <= 1e-10, "{value}");
        }
        other => panic!("{other:?}"),
    }
    // Coincident points, and points all on the anchor.
    let same = vec![Vector3::new(4.0, 5.0, 6.0); 8];
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let some = track(&mut rng, 8, Vector3::zeros());
    for dof in Dof::ALL {
        for anchor in ANCHORS {
            match align_dof(&same, &some, &opts(dof, anchor)) {
                Err(Error::Degenerate { reason, value }) => {
                    assert!(reason.contains("source points coincide"), "{reason}");
                    assert_eq!(value, 0.0);
                }
                other => panic!("{dof} {anchor}: {other:?}"),
            }
        }
    }
    // Collinear points: a full rotation is undefined, a yaw is not.
    let line: Vec<_> = (0..10)
        .map(|i| Vector3::new(1.0, 0.5, 0.0) * i as f64)
        .collect();
    let e = align_dof(&line, &line, &opts(Dof::Sim3, Anchor::First)).unwrap_err();
    assert!(e.to_string().contains("collinear"), "{e}");
    let fit = align_dof(&line, &line, &opts(Dof::FourDof, Anchor::None)).unwrap();
    assert!(fit.rmse < 1e-12);
    assert_eq!(
        fit.diagnostics.dof.as_ref().unwrap().gravity_tilt_deg,
        None,
        "the Sim(3) of a line cannot see gravity"
    );
    // Too few pairs, bad shapes and values.
    assert!(matches!(
        align_dof(&line[..1], &line[..1], &opts(Dof::FourDof, Anchor::First)),
        Err(Error::TooFew {
            need: 2,
            got: 1,
            ..
        })
    ));
    assert!(matches!(
        align_dof(&line[..2], &line[..2], &opts(Dof::Sim3, Anchor::First)),
        Err(Error::TooFew {
            need: 3,
            got: 2,
            ..
        })
    ));
    assert!(matches!(
        align_dof(&line, &line[..9], &opts(Dof::FourDof, Anchor::None)),
        Err(Error::ShapeMismatch { .. })
    ));
    let mut bad = some.clone();
    bad[3].y = f64::NAN;
    match align_dof(&some, &bad, &opts(Dof::ScaleFourDof, Anchor::First)) {
        Err(Error::NonFinite { what, index }) => assert_eq!((what.as_str(), index), ("target", 3)),
        other => panic!("{other:?}"),
    }
    for (w, expect) in [
        (vec![1.0; 7], "ShapeMismatch"),
        (vec![-1.0; 8], "InvalidArgument"),
        (vec![f64::INFINITY; 8], "NonFinite"),
        ([vec![1.0], vec![0.0; 7]].concat(), "TooFew"),
    ] {
        let o = DofOptions {
            weights: Some(w),
            ..opts(Dof::FourDof, Anchor::None)
        };
        let e = align_dof(&some, &some, &o).unwrap_err();
        assert!(format!("{e:?}").starts_with(expect), "{expect}: {e:?}");
    }
    let e = "yaw".parse::<Dof>().unwrap_err();
    assert!(matches!(e, Error::InvalidArgument { .. }));
    for choice in ["\"sim3\"", "\"se3\"", "\"4dof\"", "\"scale+4dof\""] {
        assert!(e.to_string().contains(choice), "{e}");
    }
    assert_eq!("Scale+4DoF".parse::<Dof>().unwrap(), Dof::ScaleFourDof);
}

#[test]
#[ignore = "slow: make test runs it"]
fn robust_fits_ignore_outliers_with_every_dof() {
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    for dof in Dof::ALL {
        for anchor in ANCHORS {
            let n = 80;
            let a = track(&mut rng, n, Vector3::new(2.0, 2.0, 2.0));
            let t = truth(&mut rng, dof);
            let clean = apply(&t, &a);
            let mut b = clean.clone();
            for i in (3..n).step_by(5) {
                b[i] += Vector3::new(8.0, -5.0, 3.0 + i as f64 * 0.1) * t.scale;
            }
            let o = opts(dof, anchor);
            let r = align_dof_robust(&a, &b, &o, &RobustOptions::default()).unwrap();
            let size = t.translation.norm() + t.scale * 10.0;
            let (ds, da, dt) = diff(&r.alignment.transform, &t, size);
            assert!(
                ds < 1e-9 && da < 1e-9 && dt < 1e-9,
                "{dof} {anchor}: {ds:e} {da:e} {dt:e}"
            );
            for (i, &inlier) in r.inliers.iter().enumerate() {
                assert_eq!(
                    inlier,
                    i < 3 || (i - 3) % 5 != 0,
                    "{dof} {anchor}: pair {i}"
                );
            }
            // Without outliers: the plain fit.
            let plain = align_dof(&a, &clean, &o).unwrap();
            let r = align_dof_robust(&a, &clean, &o, &RobustOptions::default()).unwrap();
            assert_eq!(r.alignment, plain, "{dof} {anchor}");
        }
    }
    // The gravity check holds for the robust fit too.
    let world = track(&mut rng, 60, Vector3::zeros());
    let tilt = UnitQuaternion::from_euler_angles(0.0, 4f64.to_radians(), 0.0);
    let est = apply(&Sim3::try_new(tilt, Vector3::zeros(), 1.0).unwrap(), &world);
    assert!(matches!(
        align_dof_robust(
            &est,
            &world,
            &opts(Dof::FourDof, Anchor::None),
            &RobustOptions::default()
        ),
        Err(Error::GravityTilted { .. })
    ));
}

#[test]
fn covariance_of_the_dof_parameters() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let n = 50;
    let a = track(&mut rng, n, Vector3::new(10.0, -4.0, 2.0));
    let w: Vec<f64> = (0..n).map(|_| rng.random_range(0.5..2.0)).collect();

    // Sim(3) and SE(3) without anchor: the covariance of crate::align::covariance.
    for (dof, scale) in [(Dof::Sim3, true), (Dof::Se3, false)] {
        let t = truth(&mut rng, dof);
        let b: Vec<_> = apply(&t, &a)
            .iter()
            .map(|p| p + gauss(&mut rng) * 0.05)
            .collect();
        let o = DofOptions {
            weights: Some(w.clone()),
            ..unchecked(dof, Anchor::None)
        };
        let fit = align_dof(&a, &b, &o).unwrap();
        let ours = covariance_dof(&fit.transform, &a, &b, Some(&w), dof, Anchor::None).unwrap();
        let theirs = covariance(&fit.transform, &a, &b, Some(&w), scale).unwrap();
        let err = (ours.to_sim3().matrix - theirs.matrix).amax() / theirs.matrix.amax();
        assert!(err < 1e-10, "{dof}: {err:e}");
        assert_eq!(ours.redundancy, theirs.dof as f64);
        assert!((ours.sigma2 / theirs.sigma2 - 1.0).abs() < 1e-12);
    }

    // Every dof and anchor against dense first-order propagation through a
    // numerical Jacobian of the residuals in the dof's own parameters (and of
    // the transform, for the Sim(3) mapping), with the anchor's noise.
    for dof in Dof::ALL {
        for anchor in ANCHORS {
            let t = truth(&mut rng, dof);
            let b: Vec<_> = apply(&t, &a)
                .iter()
                .map(|p| p + gauss(&mut rng) * 0.05)
                .collect();
            let o = DofOptions {
                weights: Some(w.clone()),
                ..unchecked(dof, anchor)
            };
            let fit = align_dof(&a, &b, &o).unwrap();
            let c = covariance_dof(&fit.transform, &a, &b, Some(&w), dof, anchor).unwrap();
            let k = c.parameters.len();
            let anchored = anchor == Anchor::First;
            assert_eq!(k, dof.n_params() - if anchored { 3 } else { 0 });
            let f = fit.transform;
            // p = (rotation: yaw or rotation vector, t unless anchored, ln s).
            let perturbed = |p: &[f64]| -> Sim3 {
                let (rot, i) = if dof.yaw_only() {
                    (yaw(p[0]), 1)
                } else {
                    (
                        UnitQuaternion::from_scaled_axis(Vector3::new(p[0], p[1], p[2])),
                        3,
                    )
                };
                let rotation = rot * f.rotation;
                let scale = if dof.has_scale() {
                    f.scale * p[k - 1].exp()
                } else {
                    f.scale
                };
                let translation = if anchored {
                    b[0] - rotation * a[0] * scale
                } else {
                    f.translation + Vector3::new(p[i], p[i + 1], p[i + 2])
                };
                Sim3 {
                    rotation,
                    translation,
                    scale,
                }
            };
            let first = usize::from(anchored);
            let m = 3 * (n - first);
            let h = 1e-6;
            let mut jac = DMatrix::<f64>::zeros(m, k);
            let mut emb = DMatrix::<f64>::zeros(7, k);
            for q in 0..k {
                let mut hi = vec![0.0; k];
                hi[q] = h;
                let mut lo = vec![0.0; k];
                lo[q] = -h;
                let (th, tl) = (perturbed(&hi), perturbed(&lo));
                for i in first..n {
                    let d = (th.transform_point(&a[i]) - tl.transform_point(&a[i])) / (2.0 * h);
                    for ax in 0..3 {
                        jac[(3 * (i - first) + ax, q)] = d[ax] * w[i].sqrt();
                    }
                }
                let dr = (th.rotation * tl.rotation.inverse()).scaled_axis() / (2.0 * h);
                let dt = (th.translation - tl.translation) / (2.0 * h);
                for ax in 0..3 {
                    emb[(ax, q)] = dr[ax];
                    emb[(3 + ax, q)] = dt[ax];
                }
                emb[(6, q)] = (th.scale / tl.scale).ln() / (2.0 * h);
            }
            let err = (&c.embedding - &emb).amax() / emb.amax();
            assert!(err < 1e-6, "{dof} {anchor}: embedding off by {err:e}");
            // δp = A·(whitened noise − D·e₀); noise covariance σ²·(I + D·Dᵀ/w₀).
            let gain = (jac.transpose() * &jac).try_inverse().unwrap() * jac.transpose();
            let mut d = DMatrix::<f64>::zeros(m, 3);
            for i in first..n {
                for ax in 0..3 {
                    d[(3 * (i - first) + ax, ax)] = w[i].sqrt();
                }
            }
            let inv_w0 = if anchored { 1.0 / w[0] } else { 0.0 };
            let noise = DMatrix::<f64>::identity(m, m) + &d * d.transpose() * inv_w0;
            let residual_maker = DMatrix::<f64>::identity(m, m) - &jac * &gain;
            let sse = cost(&f, &a, &b, Some(&w));
            let sigma2 = sse / (&residual_maker * &noise).trace();
            let expected = &gain * &noise * gain.transpose() * sigma2;
            let err = (&c.matrix - &expected).amax() / expected.amax();
            assert!(err < 1e-6, "{dof} {anchor}: covariance off by {err:e}");
            assert!(
                (c.sigma2 / sigma2 - 1.0).abs() < 1e-6,
                "{dof} {anchor}: sigma2"
            );
            let mut e0 = DMatrix::<f64>::zeros(7, 3);
            for ax in 0..3 {
                e0[(3 + ax, ax)] = inv_w0.sqrt();
            }
            let via_p = &emb * &gain;
            let via_anchor = &e0 - &via_p * &d * inv_w0.sqrt();
            let full = (&via_p * via_p.transpose() + &via_anchor * via_anchor.transpose()) * sigma2;
            let mapped = c.to_sim3();
            let err = (0..7)
                .flat_map(|i| (0..7).map(move |j| (i, j)))
                .map(|(i, j)| (mapped.matrix[(i, j)] - full[(i, j)]).abs())
                .fold(0.0, f64::max)
                / full.amax();
            assert!(err < 1e-6, "{dof} {anchor}: Sim(3) mapping off by {err:e}");
            if !dof.has_scale() {
                let (lo, hi) = mapped.scale_interval(0.95).unwrap();
                assert_eq!((lo, hi), (f.scale, f.scale), "the scale is fixed");
            }
            if dof.yaw_only() {
                let half = mapped.rotation_half_widths(0.95).unwrap();
                assert_eq!((half[0], half[1]), (0.0, 0.0), "no roll or pitch");
                assert!(half[2] > 0.0);
            }
        }
    }

    // Monte Carlo (noise on every target point, the anchor's included): the
    // predicted sigmas of the yaw, ln s and tx match their spread over draws.
    let t = Sim3::try_new(yaw(0.3), Vector3::new(1.0, 2.0, 3.0), 2.0).unwrap();
    let clean = apply(&t, &a);
    for anchor in ANCHORS {
        let trials = 400;
        let mut draws: [Vec<f64>; 3] = Default::default();
        let mut predicted = [0.0; 3];
        for _ in 0..trials {
            let b: Vec<_> = clean.iter().map(|p| p + gauss(&mut rng) * 0.2).collect();
            let fit = align_dof(&a, &b, &unchecked(Dof::ScaleFourDof, anchor)).unwrap();
            let c =
                covariance_dof(&fit.transform, &a, &b, None, Dof::ScaleFourDof, anchor).unwrap();
            assert_eq!(c.sigma("rx"), None);
            draws[0].push(fit.transform.rotation.scaled_axis().z);
            draws[1].push(fit.transform.scale.ln());
            draws[2].push(fit.transform.translation.x);
            let full = c.to_sim3();
            for (p, s) in predicted.iter_mut().zip([
                c.sigma("yaw").unwrap(),
                c.sigma("log_scale").unwrap(),
                full.matrix[(3, 3)].sqrt(),
            ]) {
                *p += s / trials as f64;
            }
        }
        let sd = |v: &[f64]| {
            let m = v.iter().sum::<f64>() / v.len() as f64;
            (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
        };
        for (name, (v, p)) in ["yaw", "ln s", "tx"]
            .iter()
            .zip(draws.iter().zip(predicted))
        {
            let s = sd(v);
            assert!(
                (s / p - 1.0).abs() < 0.15,
                "{anchor}: {name} sd {s:e}, predicted {p:e}"
            );
        }
    }
    // An anchor of weight 0 has no bounded noise.
    let b = apply(&t, &a);
    let mut w0 = w.clone();
    w0[0] = 0.0;
    assert!(matches!(
        covariance_dof(&t, &a, &b, Some(&w0), Dof::FourDof, Anchor::First),
        Err(Error::Degenerate { .. })
    ));
}

#[test]
fn windowed_fits_with_a_dof_per_window() {
    let mut rng = ChaCha8Rng::seed_from_u64(10);
    let n = 300;
    let world = track(&mut rng, n, Vector3::new(0.0, 0.0, 1.0));
    // A VIO whose yaw drifts by 20° over the run.
    let est: Vec<_> = world
        .iter()
        .enumerate()
        .map(|(i, p)| yaw(-f64::to_radians(20.0) * i as f64 / n as f64) * p)
        .collect();
    let coord: Vec<f64> = (0..n).map(|i| i as f64).collect();
    let global = align_dof(&est, &world, &opts(Dof::FourDof, Anchor::None)).unwrap();

    // Sim(3) through the hook is the windowed fitter's own fit.
    let own = windowed_fits(
        &est,
        &world,
        &coord,
        8.0,
        &AlignOptions::default(),
        &global.transform,
    );
    let hooked = windowed_fits_with(&est, &world, &coord, 8.0, &global.transform, |a, b, w| {
        fit_window(a, b, w, Dof::Sim3, AlignMethod::Horn)
    });
    assert_eq!(own, hooked);

    let local = windowed_fits_with(&est, &world, &coord, 8.0, &global.transform, |a, b, w| {
        fit_window(a, b, w, Dof::FourDof, AlignMethod::Horn)
    });
    let rms = |e: &[f64]| (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt();
    let windowed: Vec<f64> = local
        .iter()
        .zip(est.iter().zip(&world))
        .map(|(t, (p, q))| (q - t.transform_point(p)).norm())
        .collect();
    assert!(
        rms(&windowed) < 0.05 * global.rmse,
        "windowed {} vs single {}",
        rms(&windowed),
        global.rmse
    );
    for (i, t) in local.iter().enumerate() {
        let z = t.rotation * Vector3::z();
        assert!(
            z.xy().norm() < 1e-15 && t.scale == 1.0,
            "window {i}: not a 4-DoF transform"
        );
    }
    // The local yaw follows the drift: +20° at the end.
    let end = local[n - 1].rotation.scaled_axis().z.to_degrees();
    assert!((end - 20.0).abs() < 0.5, "end yaw {end}");
}
