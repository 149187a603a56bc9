//! The simulation's hot paths: rendering a 640×480 keyframe (one ray per
//! pixel) and scoring points against the scene (parry point projection).

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use slam2world::sim::evaluate::point_distances;
use slam2world::sim::path::CameraPath;
use slam2world::sim::render::render;
use slam2world::sim::Scene;
use slam2world::PinholeCamera;

fn bench(c: &mut Criterion) {
    let scene = Scene::paper().unwrap();
    let cam = PinholeCamera::from_hfov(640, 480, 75.0).unwrap();
    let path = CameraPath::paper(7000.0 / 60.0, 195.12).unwrap();
    let s = path.state(30.0);
    let mut g = c.benchmark_group("sim");
    g.measurement_time(Duration::from_secs(3)).sample_size(10);
    g.throughput(Throughput::Elements(640 * 480));
    g.bench_function("render_640x480", |b| {
        b.iter(|| render(black_box(&scene), &cam, &s.orientation, &s.position))
    });
    let n = 100_000usize;
    let pts: Vec<f32> = (0..n)
        .flat_map(|i| {
            let t = i as f32 * 0.618_034;
            [
                4.5 * (t.fract() * 2.0 - 1.0),
                2.3 * ((t * 1.7).fract() * 2.0 - 1.0),
                (t * 3.1).fract() * 1.2,
            ]
        })
        .collect();
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("point_distances_100k", |b| {
        b.iter(|| point_distances(black_box(&scene), &pts).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
