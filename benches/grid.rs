//! 2-D grid projection (`OccupancyMap::grid`): a 20 × 20 × 4 m room mapped at
//! 0.1 m from four scans of 1e4 … 1e6 points (max range 10 m), projected over
//! the band 0.15 … 1.95 m at 0.1 m cells and at 0.4 m cells; on the rayon pool
//! and on one thread. Throughput in tree nodes per second.

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

fn room_map(n: usize) -> OccupancyMap {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut m = OccupancyMap::try_new(MapParams {
        max_range: Some(10.0),
        ..MapParams::new(0.1)
    })
    .unwrap();
    for k in 0..4 {
        let o = [-6.0 + 4.0 * k as f32, 1.0, 1.5];
        m.insert_scan(&room_scan(&mut rng, o, n / 4), o).unwrap();
    }
    m
}

fn bench_grid(c: &mut Criterion) {
    let mut g = c.benchmark_group("grid");
    g.sample_size(20)
        .measurement_time(Duration::from_secs(2))
        .warm_up_time(Duration::from_millis(300));
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    for n in common::sizes(&[10_000, 100_000, 1_000_000]) {
        let m = room_map(n);
        g.throughput(Throughput::Elements(m.num_nodes() as u64));
        for (name, res) in [("0.1m", None), ("0.4m", Some(0.4))] {
            g.bench_with_input(BenchmarkId::new(format!("pool/{name}"), n), &n, |b, _| {
                b.iter(|| m.grid(black_box(0.15), 1.95, res).unwrap())
            });
            g.bench_with_input(
                BenchmarkId::new(format!("one_thread/{name}"), n),
                &n,
                |b, _| b.iter(|| one.install(|| m.grid(black_box(0.15), 1.95, res).unwrap())),
            );
        }
    }
    g.finish();
}

criterion_group!(benches, bench_grid);
criterion_main!(benches);
