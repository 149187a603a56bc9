//! `Sim3` point transform throughput (points per second), f32 and f64,
//! 1e3 … 1e7 points, into a new buffer and in place.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use nalgebra::Vector3;
use slam2world::Sim3;

fn bench_transform(c: &mut Criterion) {
    let t = Sim3::from_quaternion_xyzw([0.1, 0.2, 0.3, 0.9], Vector3::new(1.0, 2.0, 3.0), 15.49)
        .expect("a valid transform");
    let mut g = c.benchmark_group("transform");
    g.measurement_time(Duration::from_secs(3))
        .warm_up_time(Duration::from_millis(500))
        .sample_size(10);
    for n in [1_000usize, 100_000, 1_000_000, 10_000_000] {
        let p64: Vec<f64> = (0..3 * n).map(|i| (i % 1000) as f64 * 0.01).collect();
        let p32: Vec<f32> = p64.iter().map(|&v| v as f32).collect();
        let mut out32 = vec![0f32; 3 * n];
        let mut out64 = vec![0f64; 3 * n];
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(BenchmarkId::new("f32_into", n), &n, |b, _| {
            b.iter(|| t.transform_points_into(black_box(&p32), &mut out32))
        });
        g.bench_with_input(BenchmarkId::new("f32_new", n), &n, |b, _| {
            b.iter(|| t.transform_points(black_box(&p32)))
        });
        g.bench_with_input(BenchmarkId::new("f64_into", n), &n, |b, _| {
            b.iter(|| t.transform_points_into(black_box(&p64), &mut out64))
        });
        let mut inplace = p32.clone();
        g.bench_with_input(BenchmarkId::new("f32_in_place", n), &n, |b, _| {
            b.iter(|| t.transform_points_in_place(black_box(&mut inplace)))
        });
        // The limit: a plain copy of the same bytes.
        g.bench_with_input(BenchmarkId::new("f32_memcpy", n), &n, |b, _| {
            b.iter(|| out32.copy_from_slice(black_box(&p32)))
        });
    }
    g.finish();
}

criterion_group!(benches, bench_transform);
criterion_main!(benches);
