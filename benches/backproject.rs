//! Backprojection throughput (pixels per second) into the world frame: 123
//! keyframes of 640×480 with the viewer's default filters (the case),
//! and 1e3 … 1e7 pixels (one keyframe of fewer rows below 640×480, whole
//! keyframes above) with no keyframe cut. The side-by-side numpy comparison is
//! `benches/compare.py --only backproject`; the transform is `benches/transform.rs`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slam2world::cloud::{backproject, PointFilter};
use slam2world::{Keyframe, PinholeCamera, Sim3};

mod common;

const KEYFRAMES: usize = 123;
const W: u32 = 640;
const H: u32 = 480;

/// A semi-dense keyframe: a smooth inverse-depth surface with noise, about half
/// the pixels without depth, variances spread across the thresholds.
fn keyframe(rng: &mut ChaCha8Rng, id: i32, h: u32) -> Keyframe {
    let cam = PinholeCamera::try_new(517.3, 516.5, 318.6, 255.3, W, h).unwrap();
    let n = (W * h) as usize;
    let (mut idepth, mut var) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let phase: f32 = rng.random_range(0.0..6.0);
    for y in 0..h {
        for x in 0..W {
            let (xf, yf) = (x as f32, y as f32);
            let hole = (xf / 9.0 + phase).sin() * (yf / 7.0).sin() > 0.2;
            let d = 1.0 + 0.2 * (xf / 60.0).sin() + 0.1 * (yf / 50.0).cos();
            idepth.push(if hole {
                0.0
            } else {
                d + rng.random_range(-0.01..0.01)
            });
            var.push(10f32.powf(rng.random_range(-6.0..-2.0)));
        }
    }
    let color = (0..3 * n).map(|i| (i % 251) as u8).collect();
    let pose = Sim3::from_quaternion_xyzw(
        [0.1, rng.random_range(-0.5..0.5), 0.05, 1.0],
        Vector3::new(
            rng.random_range(-2.0..2.0),
            0.0,
            rng.random_range(-2.0..2.0),
        ),
        rng.random_range(0.5..2.0),
    )
    .unwrap();
    Keyframe::try_new(
        id,
        id as f64 * 0.1,
        pose,
        cam,
        idepth,
        Some(var),
        Some(color),
    )
    .unwrap()
}

fn bench_backproject(c: &mut Criterion) {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let world_slam =
        Sim3::from_quaternion_xyzw([0.3, 0.1, 0.0, 1.0], Vector3::new(1.0, 2.0, 3.0), 2.5).unwrap();
    let mut g = c.benchmark_group("backproject");
    g.sample_size(10)
        .measurement_time(Duration::from_secs(2))
        .warm_up_time(Duration::from_millis(300));
    let all = PointFilter {
        cut_first_keyframes: None,
        ..PointFilter::default()
    };
    for n in common::sizes(&[1_000, 10_000, 100_000, 1_000_000, 10_000_000]) {
        let per_kf = (W * H) as usize;
        let kfs: Vec<Keyframe> = if n < per_kf {
            vec![keyframe(&mut rng, 0, (n / W as usize).max(3) as u32)]
        } else {
            (0..(n / per_kf) as i32)
                .map(|i| keyframe(&mut rng, i, H))
                .collect()
        };
        let pixels: usize = kfs.iter().map(|k| k.idepth.len()).sum();
        g.throughput(Throughput::Elements(pixels as u64));
        g.bench_with_input(BenchmarkId::new("pixels", n), &n, |b, _| {
            b.iter(|| backproject(black_box(&kfs), &all, Some(&world_slam)).unwrap())
        });
    }
    // Under `cargo test`: seven keyframes, the first past the default cut.
    let n_kf = if common::benchmarking() { KEYFRAMES } else { 7 };
    let kfs: Vec<Keyframe> = (0..n_kf as i32).map(|i| keyframe(&mut rng, i, H)).collect();
    let filter = PointFilter::default();
    g.throughput(Throughput::Elements((n_kf * (W * H) as usize) as u64));
    g.bench_function("default_filter_world_123x640x480", |b| {
        b.iter(|| backproject(black_box(&kfs), &filter, Some(&world_slam)).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench_backproject);
criterion_main!(benches);
