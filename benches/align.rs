//! Closed-form alignment throughput (pairs per second), 1e3 … 1e7 pairs.
//! Peers (numpy, evo) are measured side by side by `benches/compare.py`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slam2world::align::{align, fit_flat, AlignMethod, AlignOptions};
use slam2world::Sim3;

mod common;

fn pairs(n: usize) -> (Vec<Vector3<f64>>, Vec<Vector3<f64>>) {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let t = Sim3::from_quaternion_xyzw([0.1, 0.2, 0.3, 0.9], Vector3::new(1.0, 2.0, 3.0), 15.49)
        .expect("a valid transform");
    let a: Vec<Vector3<f64>> = (0..n)
        .map(|_| Vector3::new(rng.random(), rng.random(), rng.random()))
        .collect();
    let b = a
        .iter()
        .map(|p| t.transform_point(p) + Vector3::new(rng.random::<f64>() * 1e-3, 0.0, 0.0))
        .collect();
    (a, b)
}

fn bench_align(c: &mut Criterion) {
    let mut g = c.benchmark_group("align");
    g.measurement_time(Duration::from_secs(1))
        .warm_up_time(Duration::from_millis(300))
        .sample_size(10);
    for n in common::sizes(&[1_000, 10_000, 100_000, 1_000_000, 10_000_000]) {
        let (a, b) = pairs(n);
        g.throughput(Throughput::Elements(n as u64));
        for (name, method) in [
            ("horn", AlignMethod::Horn),
            ("umeyama", AlignMethod::Umeyama),
        ] {
            let opts = AlignOptions {
                method,
                ..Default::default()
            };
            g.bench_with_input(BenchmarkId::new(name, n), &n, |bench, _| {
                bench.iter(|| align(black_box(&a), black_box(&b), &opts))
            });
        }
        // The NumPy-layout path of the Python `align`: one vectorised pass,
        // the residuals left for when they are asked for.
        let flat = |v: &[Vector3<f64>]| v.iter().flat_map(|p| [p.x, p.y, p.z]).collect::<Vec<_>>();
        let (fa, fb) = (flat(&a), flat(&b));
        let opts = AlignOptions::default();
        g.bench_with_input(BenchmarkId::new("fit_flat", n), &n, |bench, _| {
            bench.iter(|| fit_flat(black_box(&fa), black_box(&fb), &opts))
        });
    }
    g.finish();
}

criterion_group!(benches, bench_align);
criterion_main!(benches);
