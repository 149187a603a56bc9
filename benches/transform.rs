//! `Sim3` point transform throughput (points per second), f32 and f64,
//! 1e3 … 1e7 points (1e8 with `S2W_BENCH_1E8=1`: 1.2 GB per f32 buffer):
//! into a caller's buffer, into a new buffer (`Sim3::transform_points`,
//! `PointCloud::transformed`) and in place, beside a plain copy of the same
//! bytes into an existing and into a new buffer (the memory-bandwidth limit).
//! Peers (numpy, Open3D) are measured side by side by `benches/compare.py`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use nalgebra::Vector3;
use slam2world::cloud::PointCloud;
use slam2world::Sim3;

mod common;

fn sizes() -> Vec<usize> {
    let mut s = vec![1_000, 10_000, 100_000, 1_000_000, 10_000_000];
    if std::env::var_os("S2W_BENCH_1E8").is_some() {
        s.push(100_000_000);
    }
    common::sizes(&s)
}

fn bench_transform(c: &mut Criterion) {
    let t = Sim3::from_quaternion_xyzw([0.1, 0.2, 0.3, 0.9], Vector3::new(1.0, 2.0, 3.0), 15.49)
        .expect("a valid transform");
    let mut g = c.benchmark_group("transform");
    g.measurement_time(Duration::from_secs(1))
        .warm_up_time(Duration::from_millis(300))
        .sample_size(10);
    for n in sizes() {
        let p32: Vec<f32> = (0..3 * n).map(|i| (i % 1000) as f32 * 0.01).collect();
        let mut out32 = vec![0f32; 3 * n];
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(BenchmarkId::new("f32_into", n), &n, |b, _| {
            b.iter(|| t.transform_points_into(black_box(&p32), &mut out32))
        });
        g.bench_with_input(BenchmarkId::new("f32_new", n), &n, |b, _| {
            b.iter(|| t.transform_points(black_box(&p32)))
        });
        // The limits: a plain copy of the same bytes, into the existing buffer
        // and into a new one (page faults included, as in `f32_new`).
        g.bench_with_input(BenchmarkId::new("f32_copy_into", n), &n, |b, _| {
            b.iter(|| out32.copy_from_slice(black_box(&p32)))
        });
        g.bench_with_input(BenchmarkId::new("f32_copy_new", n), &n, |b, _| {
            b.iter(|| black_box(&p32).to_vec())
        });
        let mut inplace = p32.clone();
        g.bench_with_input(BenchmarkId::new("f32_in_place", n), &n, |b, _| {
            b.iter(|| t.transform_points_in_place(black_box(&mut inplace)))
        });
        let cloud = PointCloud::try_new(p32, None, None).expect("a valid cloud");
        g.bench_with_input(BenchmarkId::new("pointcloud_transformed", n), &n, |b, _| {
            b.iter(|| black_box(&cloud).transformed(&t))
        });
        drop((cloud, out32, inplace));
        let p64: Vec<f64> = (0..3 * n).map(|i| (i % 1000) as f64 * 0.01).collect();
        g.bench_with_input(BenchmarkId::new("f64_new", n), &n, |b, _| {
            b.iter(|| t.transform_points(black_box(&p64)))
        });
    }
    g.finish();
}

criterion_group!(benches, bench_transform);
criterion_main!(benches);
