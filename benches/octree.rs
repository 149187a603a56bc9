//! Occupancy insertion throughput (points/s): four scans of a 20 × 20 × 4 m room
//! seen from inside, 1e3 … 1e6 points (1e7 with `S2W_BENCH_1E7=1`), resolution
//! 0.1 m, max range 10 m; parallel (rayon) and sequential. OctoMap's figure on
//! the same points: `benches/compare.py --only octree`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use slam2world::map::{MapParams, OccupancyMap};

mod common;

/// Points where rays from `origin` in random directions meet the room's walls.
fn room_scan(rng: &mut ChaCha8Rng, origin: [f32; 3], n: usize) -> Vec<f32> {
    let lo = [-10.0f32, -10.0, 0.0];
    let hi = [10.0f32, 10.0, 4.0];
    let mut pts = Vec::with_capacity(3 * n);
    for _ in 0..n {
        let d: [f32; 3] = [0, 1, 2].map(|_| rng.random_range(-1.0f32..1.0));
        let norm = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-6);
        let d = d.map(|v| v / norm);
        let mut t = f32::INFINITY;
        for i in 0..3 {
            if d[i] > 0.0 {
                t = t.min((hi[i] - origin[i]) / d[i]);
            } else if d[i] < 0.0 {
                t = t.min((lo[i] - origin[i]) / d[i]);
            }
        }
        pts.extend((0..3).map(|i| origin[i] + t * d[i]));
    }
    pts
}

fn bench_insert(c: &mut Criterion) {
    let params = MapParams {
        max_range: Some(10.0),
        ..MapParams::new(0.1)
    };
    let mut g = c.benchmark_group("octree_insert");
    g.sample_size(10)
        .measurement_time(Duration::from_secs(2))
        .warm_up_time(Duration::from_millis(300));
    let mut sizes = vec![1_000usize, 10_000, 100_000, 1_000_000];
    if std::env::var_os("S2W_BENCH_1E7").is_some() {
        sizes.push(10_000_000);
    }
    for n in common::sizes(&sizes) {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let scans: Vec<([f32; 3], Vec<f32>)> = (0..4)
            .map(|k| {
                let o = [-6.0 + 4.0 * k as f32, 1.0, 1.5];
                let pts = room_scan(&mut rng, o, n / 4);
                (o, pts)
            })
            .collect();
        g.throughput(Throughput::Elements(n as u64));
        g.bench_with_input(BenchmarkId::new("parallel", n), &n, |b, _| {
            b.iter(|| {
                let mut m = OccupancyMap::try_new(params).unwrap();
                for (o, pts) in &scans {
                    m.insert_scan(black_box(pts), *o).unwrap();
                }
                m
            })
        });
        g.bench_with_input(BenchmarkId::new("sequential", n), &n, |b, _| {
            b.iter(|| {
                let mut m = OccupancyMap::try_new(params).unwrap();
                for (o, pts) in &scans {
                    m.insert_scan_sequential(black_box(pts), *o).unwrap();
                }
                m
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench_insert);
criterion_main!(benches);
