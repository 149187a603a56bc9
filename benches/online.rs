//! Latency of the online session per keyframe (issue 18): the simulated paper
//! run at 640×480, the viewer's default filter, a 0.1 m octree with 10 m
//! rays, fed message by message; per keyframe pushed once the map exists,
//! push-to-map-updated (decode + fit + backproject + insert) and the 2-D grid
//! projected after it, p50 / p99 and the breakdown; and every tracked-frame
//! push (one keyframe inserted per frame while a map is built in steps). Run it on one core
//! (`RAYON_NUM_THREADS=1 taskset -c 0 cargo bench --bench online`), and again
//! with another process keeping the other core busy.
//!
//! Under `cargo test` (no `--bench` argument) it runs as a smoke test: the
//! same path on 160×120 images, stopped after a few keyframes of the map
//! (simulating and pushing the whole log takes minutes unoptimised).

use std::time::Instant;

use slam2world::io::mcap::McapFile;
use slam2world::io::messages::decode::MessageKind;
use slam2world::pipeline::session::{LogFeed, Pushed, SessionOptions};

fn pct(v: &mut [f64], p: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * p).round() as usize]
}

/// Keyframes of the map a smoke run (`cargo test`) measures before it stops.
const SMOKE_KEYFRAMES: usize = 3;

fn main() {
    let smoke = !std::env::args().any(|a| a == "--bench");
    let dir = tempfile::tempdir().expect("tempdir");
    let log = dir.path().join("paper.mcap");
    let mut args = vec![
        "slam2world".to_string(),
        "simulate".into(),
        "-o".into(),
        log.display().to_string(),
    ];
    if smoke {
        for set in ["width=160", "height=120"] {
            args.extend(["--set".into(), set.into()]);
        }
    }
    let code = slam2world::cli::main_with_args(args);
    assert_eq!(code, 0);
    let file = McapFile::open(&log).expect("log");
    let channels = file.channels().expect("channels");
    let scan = file.scan(|_| true).expect("scan");
    let mut feed = LogFeed::new(SessionOptions::default()).expect("session");
    let (mut total, mut decode, mut fit, mut bp, mut ins, mut grid) =
        (vec![], vec![], vec![], vec![], vec![], vec![]);
    let mut rebuilds = 0;
    let mut frames = vec![];
    for m in scan.iter() {
        let c = &channels[&m.channel_id];
        let kind = MessageKind::from_schema(&c.schema_name);
        let t0 = Instant::now();
        let pushed = feed
            .push(&c.topic, kind, &c.message_encoding, m.data)
            .expect("push");
        let dt = t0.elapsed().as_secs_f64();
        if kind == Some(MessageKind::Keyframe) && matches!(pushed, Pushed::Other) {
            // A tracked frame: while a map is built in steps, it inserts one keyframe.
            frames.push(dt);
        }
        if let Pushed::Keyframe {
            decode_s, timing, ..
        } = pushed
        {
            if feed.session.map().is_none() {
                continue;
            }
            // A rebuild (inserted keyframes moved) is part of the latency.
            rebuilds += usize::from(timing.rebuilt);
            let tg = Instant::now();
            let g = feed.session.grid(0.2, 1.8, None).expect("grid");
            std::hint::black_box(&g);
            grid.push(tg.elapsed().as_secs_f64());
            total.push(dt);
            decode.push(decode_s);
            fit.push(timing.fit_s);
            bp.push(timing.backproject_s);
            ins.push(timing.insert_s);
            if smoke && total.len() == SMOKE_KEYFRAMES {
                break;
            }
        }
    }
    assert!(
        !total.is_empty(),
        "no keyframe was pushed after the map existed"
    );
    let ms = |v: &mut Vec<f64>| (1e3 * pct(v, 0.5), 1e3 * pct(v, 0.99));
    println!(
        "online: {} keyframes after the map exists ({} of them rebuilt it), threads {}",
        total.len(),
        rebuilds,
        rayon::current_num_threads()
    );
    for (name, v) in [
        ("push-to-map-updated", &mut total),
        ("  decode", &mut decode),
        ("  fit", &mut fit),
        ("  backproject", &mut bp),
        ("  insert", &mut ins),
        ("grid (after)", &mut grid),
        ("tracked-frame push", &mut frames),
    ] {
        if v.is_empty() {
            println!("{name:22} none");
            continue;
        }
        let (p50, p99) = ms(v);
        println!("{name:22} p50 {p50:8.2} ms  p99 {p99:8.2} ms");
    }
}
