//! Property tests of the closed-form alignment and of Sim(3) algebra: random
//! transforms (scales 1e-3 … 1e3, 15.49 among them), noise-free round trips,
//! Horn against Umeyama, degenerate input.

use nalgebra::{Matrix4, UnitQuaternion, Vector3, Vector4};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal, UnitSphere};
use slam2world::align::{align, align_flat, fit_flat, residuals_flat, AlignMethod, AlignOptions};
use slam2world::{Error, Sim3};

fn random_rotation(rng: &mut ChaCha8Rng) -> UnitQuaternion<f64> {
    let axis: [f64; 3] = UnitSphere.sample(rng);
    let angle = rng.random_range(-3.1..3.1);
    UnitQuaternion::from_scaled_axis(Vector3::from(axis) * angle)
}

fn random_sim3(rng: &mut ChaCha8Rng, scale: f64) -> Sim3 {
    let t = Vector3::new(
        rng.random_range(-100.0..100.0),
        rng.random_range(-100.0..100.0),
        rng.random_range(-100.0..100.0),
    );
    Sim3::try_new(random_rotation(rng), t, scale).unwrap()
}

fn random_cloud(rng: &mut ChaCha8Rng, n: usize, spread: f64, centre: f64) -> Vec<Vector3<f64>> {
    let c = Vector3::new(centre, -centre, 0.5 * centre);
    (0..n)
        .map(|_| {
            let g: [f64; 3] = [
                StandardNormal.sample(rng),
                StandardNormal.sample(rng),
                StandardNormal.sample(rng),
            ];
            c + Vector3::from(g) * spread
        })
        .collect()
}

fn scales(rng: &mut ChaCha8Rng) -> Vec<f64> {
    let mut s = vec![1e-3, 0.0646, 1.0, 15.49, 1e3];
    s.extend((0..10).map(|_| 10f64.powf(rng.random_range(-3.0..3.0))));
    s
}

/// Differences between two transforms: relative scale, rotation angle (rad),
/// translation relative to the target's size.
fn diff(a: &Sim3, b: &Sim3, size: f64) -> (f64, f64, f64) {
    (
        (a.scale - b.scale).abs() / b.scale,
        a.rotation.angle_to(&b.rotation),
        (a.translation - b.translation).norm() / size,
    )
}

#[test]
fn noise_free_round_trips_recover_the_transform() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for s in scales(&mut rng) {
        for method in [AlignMethod::Horn, AlignMethod::Umeyama] {
            let n = rng.random_range(3..400);
            let a = random_cloud(&mut rng, n, 2.0, 5.0);
            let t = random_sim3(&mut rng, s);
            let b: Vec<_> = a.iter().map(|p| t.transform_point(p)).collect();
            let opts = AlignOptions {
                method,
                ..Default::default()
            };
            let r = align(&a, &b, &opts).unwrap();
            let size = t.translation.norm() + s * 10.0;
            let (ds, da, dt) = diff(&r.transform, &t, size);
            assert!(
                ds < 1e-9 && da < 1e-9 && dt < 1e-9,
                "s={s} {method:?} n={n}: {ds:e} {da:e} {dt:e}"
            );
            // Guards the paper's inverted formula: it would return 1/s.
            if (s - 1.0).abs() > 1e-3 {
                assert!((r.transform.scale * s - 1.0).abs() > 1e-3);
            }
            assert!(r.rmse <= 1e-9 * s * 10.0);
        }
    }
}

#[test]
fn horn_equals_umeyama_on_noisy_data() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for s in scales(&mut rng) {
        for scale in [true, false] {
            let n = rng.random_range(3..2000);
            let a = random_cloud(&mut rng, n, 1.0, 3.0);
            let t = random_sim3(&mut rng, s);
            let b: Vec<_> = a
                .iter()
                .map(|p| {
                    let e: [f64; 3] = [
                        StandardNormal.sample(&mut rng),
                        StandardNormal.sample(&mut rng),
                        StandardNormal.sample(&mut rng),
                    ];
                    t.transform_point(p) + Vector3::from(e) * 0.05 * s
                })
                .collect();
            let opts = |method| AlignOptions {
                method,
                scale,
                weights: None,
            };
            let h = align(&a, &b, &opts(AlignMethod::Horn)).unwrap();
            let u = align(&a, &b, &opts(AlignMethod::Umeyama)).unwrap();
            let (ds, da, dt) = diff(&h.transform, &u.transform, t.translation.norm() + s * 10.0);
            assert!(
                ds < 1e-9 && da < 1e-9 && dt < 1e-9,
                "s={s}: {ds:e} {da:e} {dt:e}"
            );
            assert!((h.rmse - u.rmse).abs() <= 1e-9 * u.rmse);
        }
    }
}

#[test]
fn least_squares_optimum_and_scale_direction() {
    // Perturbing the optimum in scale, rotation or translation never lowers
    // the sum of squared residuals; s is target units per source unit.
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let a = random_cloud(&mut rng, 300, 1.0, 0.0);
    let t = random_sim3(&mut rng, 15.49);
    let b: Vec<_> = a
        .iter()
        .map(|p| t.transform_point(p) + Vector3::new(rng.random_range(-0.5..0.5), 0.0, 0.0))
        .collect();
    let r = align(&a, &b, &AlignOptions::default()).unwrap();
    let sse = |x: &Sim3| -> f64 {
        a.iter()
            .zip(&b)
            .map(|(p, q)| (q - x.transform_point(p)).norm_squared())
            .sum()
    };
    let best = sse(&r.transform);
    assert!((best / 300.0).sqrt() - r.rmse < 1e-12);
    let o = r.transform;
    for k in [
        Sim3 {
            scale: o.scale * 1.001,
            ..o
        },
        Sim3 {
            scale: o.scale / 1.001,
            ..o
        },
        Sim3 {
            scale: 1.0 / o.scale,
            ..o
        },
        Sim3 {
            rotation: UnitQuaternion::from_euler_angles(1e-3, 0.0, 0.0) * o.rotation,
            ..o
        },
        Sim3 {
            translation: o.translation + Vector3::new(0.0, 0.0, 1e-3),
            ..o
        },
    ] {
        assert!(sse(&k) > best);
    }
}

#[test]
fn large_inputs_parallel_path_and_far_from_origin() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    // 200 000 pairs 1e5 units from the origin with unit spread.
    let a = random_cloud(&mut rng, 200_000, 1.0, 1e5);
    let t = random_sim3(&mut rng, 0.37);
    let b: Vec<_> = a.iter().map(|p| t.transform_point(p)).collect();
    let r = align(&a, &b, &AlignOptions::default()).unwrap();
    assert!((r.transform.scale / 0.37 - 1.0).abs() < 1e-9);
    assert!(r.transform.rotation.angle_to(&t.rotation) < 1e-9);
    assert!(r.rmse < 1e-9 * 1e5);
    // The flat (NumPy layout) entry point, whose sums take the vectorised
    // path, gives the same answer to rounding.
    let flat = |v: &[Vector3<f64>]| v.iter().flat_map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>();
    let f = align_flat(&flat(&a), &flat(&b), &AlignOptions::default()).unwrap();
    let (ds, dr, dt) = diff(&f.transform, &r.transform, 1e5);
    assert!(ds < 1e-12 && dr < 1e-12 && dt < 1e-12, "{ds} {dr} {dt}");
    assert!(matches!(
        align_flat(&[0.0; 10], &[0.0; 10], &AlignOptions::default()),
        Err(Error::ShapeMismatch { .. })
    ));
    // Residuals into a caller's buffer: the same numbers as the eager fit.
    let mut out = vec![f64::NAN; a.len()];
    let rms = residuals_flat(&f.transform, &flat(&a), &flat(&b), &mut out).unwrap();
    assert_eq!(out, f.residuals);
    assert_eq!(rms, f.rmse);
    assert!(matches!(
        residuals_flat(&f.transform, &flat(&a), &flat(&b), &mut out[1..]),
        Err(Error::ShapeMismatch { .. })
    ));
    assert!(matches!(
        residuals_flat(&f.transform, &flat(&a), &flat(&b)[3..], &mut out),
        Err(Error::ShapeMismatch { .. })
    ));
}

/// Noisy pairs: `b = T(a) + σ·n` around a far-away centre.
fn noisy(
    rng: &mut ChaCha8Rng,
    n: usize,
    sigma: f64,
    centre: f64,
) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>, Sim3) {
    let a = random_cloud(rng, n, 3.0, centre);
    let t = random_sim3(rng, 15.49);
    let b = a
        .iter()
        .map(|p| {
            let e: [f64; 3] = [
                StandardNormal.sample(rng),
                StandardNormal.sample(rng),
                StandardNormal.sample(rng),
            ];
            t.transform_point(p) + Vector3::from(e) * sigma
        })
        .collect();
    (a, b, t)
}

fn max_abs(v: &[Vector3<f64>]) -> f64 {
    v.iter().map(|p| p.amax()).fold(0.0, f64::max)
}

#[test]
fn one_pass_rmse_equals_the_rms_of_the_residuals() {
    // The one-pass fit takes the rms residual from moments relative to a
    // sampled prior; it must equal the rms of the explicit residuals to
    // rounding, for tiny and large noise, with and without weights, on the
    // sequential (small) and parallel (large) paths, near and far from the
    // origin.
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let flat = |v: &[Vector3<f64>]| v.iter().flat_map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>();
    for &(n, sigma, centre) in &[
        (10, 1e-2, 0.0),
        (3_000, 1e-9, 1e3),
        (100_003, 1e-4, 0.0),
        (100_003, 1e-6, 1e4),
        (100_003, 5.0, 10.0),
    ] {
        let (a, b, _) = noisy(&mut rng, n, sigma, centre);
        let (fa, fb) = (flat(&a), flat(&b));
        for weights in [None, Some((0..n).map(|i| 0.5 + (i % 7) as f64).collect())] {
            let opts = AlignOptions {
                weights,
                ..Default::default()
            };
            let eager = align_flat(&fa, &fb, &opts).unwrap();
            let fit = fit_flat(&fa, &fb, &opts).unwrap();
            assert_eq!(fit.transform, eager.transform);
            // Both are exact to the rounding of the residuals themselves,
            // ε·|b| per coordinate.
            let tol = 1e-10 + f64::EPSILON * max_abs(&b) / eager.rmse;
            let rel = (fit.rmse / eager.rmse - 1.0).abs();
            assert!(rel < tol, "n={n} σ={sigma}: {} vs {}", fit.rmse, eager.rmse);
            assert!(
                eager.rmse > 0.5 * sigma && eager.rmse < 40.0 * sigma,
                "{}",
                eager.rmse
            );
        }
    }
}

#[test]
fn one_pass_rmse_without_a_usable_prior() {
    // Only rows that the prior's sample skips carry weight: the sample fit is
    // refused, and the rms residual must still be exact.
    let mut rng = ChaCha8Rng::seed_from_u64(22);
    let n = 10_000;
    let (a, b, t) = noisy(&mut rng, n, 1e-5, 100.0);
    let w: Vec<f64> = (0..n)
        .map(|i| if (200..300).contains(&i) { 1.0 } else { 0.0 })
        .collect();
    let flat = |v: &[Vector3<f64>]| v.iter().flat_map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>();
    let opts = AlignOptions {
        weights: Some(w.clone()),
        ..Default::default()
    };
    let fit = fit_flat(&flat(&a), &flat(&b), &opts).unwrap();
    let (ds, dr, dt) = diff(&fit.transform, &t, 100.0);
    assert!(ds < 1e-5 && dr < 1e-5 && dt < 1e-5, "{ds} {dr} {dt}");
    let expect = (200..300)
        .map(|i| (b[i] - fit.transform.transform_point(&a[i])).norm_squared())
        .sum::<f64>()
        / 100.0;
    let tol = 1e-10 + f64::EPSILON * max_abs(&b) / fit.rmse;
    assert!(
        (fit.rmse / expect.sqrt() - 1.0).abs() < tol,
        "{} {}",
        fit.rmse,
        expect.sqrt()
    );
}

#[test]
fn degenerate_input_is_refused_with_its_diagnostic() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let a = random_cloud(&mut rng, 20, 1.0, 0.0);
    let d = AlignOptions::default();
    for method in [AlignMethod::Horn, AlignMethod::Umeyama] {
        let o = AlignOptions {
            method,
            ..d.clone()
        };
        let p = vec![Vector3::new(0.5, 0.5, 0.5); 20];
        match align(&p, &a, &o) {
            Err(Error::Degenerate { reason, value }) => {
                assert!(reason.contains("source points coincide"), "{reason}");
                assert!(value < 1e-12);
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(align(&a, &p, &o), Err(Error::Degenerate { .. })));
        let dir = Vector3::new(0.3, -1.0, 2.0);
        let line: Vec<_> = (0..20).map(|i| dir * (i as f64 * 0.1 - 1.0)).collect();
        let t = random_sim3(&mut rng, 2.0);
        let mapped: Vec<_> = line.iter().map(|p| t.transform_point(p)).collect();
        match align(&line, &mapped, &o) {
            Err(Error::Degenerate { reason, value }) => {
                assert!(reason.contains("collinear"), "{reason}");
                assert!(value < 1e-9);
            }
            other => panic!("{other:?}"),
        }
        assert!(matches!(
            align(&a[..2], &a[..2], &o),
            Err(Error::TooFew {
                need: 3,
                got: 2,
                ..
            })
        ));
        let mut inf = a.clone();
        inf[4].x = f64::INFINITY;
        assert!(matches!(
            align(&inf, &a, &o),
            Err(Error::NonFinite { index: 4, .. })
        ));
    }
    // Planar points determine the rotation.
    let plane: Vec<_> = a.iter().map(|p| Vector3::new(p.x, p.y, 0.0)).collect();
    let t = random_sim3(&mut rng, 3.0);
    let mapped: Vec<_> = plane.iter().map(|p| t.transform_point(p)).collect();
    let r = align(&plane, &mapped, &d).unwrap();
    assert!(r.transform.rotation.angle_to(&t.rotation) < 1e-9);
    assert!(r.diagnostics.singular_values[2] < 1e-9 * r.diagnostics.singular_values[0]);
}

#[test]
fn sim3_algebra_agrees_with_4x4_matrices() {
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let h = |p: &Vector3<f64>| Vector4::new(p.x, p.y, p.z, 1.0);
    for s in scales(&mut rng) {
        let a = random_sim3(&mut rng, s);
        let b = random_sim3(&mut rng, 1.0 / s.sqrt());
        let (ma, mb) = (a.matrix(), b.matrix());
        let tol = |m: &Matrix4<f64>| 1e-12 * m.amax().max(1.0);
        let ab = (a * b).matrix();
        assert!((ab - ma * mb).amax() < tol(&ab));
        let inv = a.inverse().matrix();
        let m_inv = ma.try_inverse().unwrap();
        assert!((inv - m_inv).amax() < 1e-9 * m_inv.amax());
        assert!((a * a.inverse())
            .matrix()
            .relative_eq(&Matrix4::identity(), 1e-9, 1e-9));
        let p = random_cloud(&mut rng, 100, 3.0, 1.0);
        let flat: Vec<f64> = p.iter().flat_map(|v| [v.x, v.y, v.z]).collect();
        let out = a.transform_points(&flat).unwrap();
        for (i, v) in p.iter().enumerate() {
            let q = ma * h(v);
            for k in 0..3 {
                assert!((out[3 * i + k] - q[k]).abs() < 1e-12 * q.amax().max(1.0));
            }
        }
        let back = Sim3::from_matrix(&ma).unwrap();
        assert!((back.scale / s - 1.0).abs() < 1e-12);
    }
}

#[test]
fn one_pass_rmse_property_over_random_problems() {
    // Random sizes (3 … 5000: the prior's sample is all of the pairs or a
    // part), scales 1e-3 … 1e3, noise from none to larger than the spread,
    // centres far from the origin, weights with zeros: the rms residual of the
    // one-pass fit equals that of the explicit residuals, to the rounding of
    // the residuals themselves.
    let mut rng = ChaCha8Rng::seed_from_u64(23);
    let flat = |v: &[Vector3<f64>]| v.iter().flat_map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>();
    for case in 0..200 {
        let n = if case % 4 == 0 {
            rng.random_range(3..40)
        } else {
            rng.random_range(40..5000)
        };
        let scale = 10f64.powf(rng.random_range(-3.0..3.0));
        let t = random_sim3(&mut rng, scale);
        let centre = [0.0, 1.0, 1e3][case % 3];
        let a = random_cloud(&mut rng, n, 1.0, centre);
        let sigma = [0.0, 1e-9, 1e-4, 1e-1, 3.0][case % 5] * scale;
        let b: Vec<Vector3<f64>> = a
            .iter()
            .map(|p| {
                let e: [f64; 3] = [
                    StandardNormal.sample(&mut rng),
                    StandardNormal.sample(&mut rng),
                    StandardNormal.sample(&mut rng),
                ];
                t.transform_point(p) + Vector3::from(e) * sigma
            })
            .collect();
        let weights = (case % 2 == 1).then(|| {
            (0..n)
                .map(|i| {
                    if i % 5 == 0 {
                        0.0
                    } else {
                        rng.random_range(0.1..2.0)
                    }
                })
                .collect::<Vec<f64>>()
        });
        let opts = AlignOptions {
            weights,
            ..Default::default()
        };
        let (fa, fb) = (flat(&a), flat(&b));
        let eager = match align_flat(&fa, &fb, &opts) {
            Ok(r) => r,
            // Tiny weighted problems may leave fewer than three pairs.
            Err(Error::TooFew { .. }) => continue,
            Err(e) => panic!("case {case}: {e}"),
        };
        let fit = fit_flat(&fa, &fb, &opts).unwrap();
        assert_eq!(fit.transform, eager.transform, "case {case}");
        let tol = 1e-9 * eager.rmse + 16.0 * f64::EPSILON * max_abs(&b);
        assert!(
            (fit.rmse - eager.rmse).abs() <= tol,
            "case {case} (n {n}, σ {sigma:e}): {} vs {}",
            fit.rmse,
            eager.rmse
        );
    }
}
