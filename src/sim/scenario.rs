//! A family of simulated runs beyond the paper's one (`simulate --scenario
//! SEED`): each seed draws the stage lengths, the frame, keyframe and
//! reference rates, the run's length and speed, the SLAM scale, the tracking,
//! keyframe and reference noise, and the start-up's scale wander, jumps and
//! drift from ranges that cover real systems, so that every automatic
//! decision (the start-up stages above all) is tested on runs it was not
//! tuned on. The drawn values are the [`SimConfig`] (the truth sidecar holds
//! it whole).
//!
//! | knob | range |
//! |---|---|
//! | frame rate | 20, 25, 30, 40, 50, 60 Hz (LSD-SLAM, ORB-SLAM, DSO) |
//! | start-up (start + converging) | 2–60 s, log-uniform; the start stage 15–70 % of it |
//! | stable stage | 3–150 s, log-uniform |
//! | keyframes | 0.5–4 per second (five at least in the stable stage) |
//! | speed | 0.3–3 m/s; the SLAM scale 0.05–20 m per SLAM unit, log-uniform |
//! | tracking noise | 0.5–10 % of a frame's step; bursts 0–0.3 % of the stable frames |
//! | start-stage scale | ×1.3–3 or ÷1.3–3 off the final scale; wander σ 0.02–0.3 in ln; 0–3 jumps/s |
//! | scale drift once stable | none (half the runs) or ±5·10⁻⁴ per second |
//! | reference | 10, 20, 50, 100, 120, 200 Hz; noise 1–15 % of its step between matched frames |
//!
//! Images are 32×24 (the stages live in the tracking; the depth maps are
//! only what a keyframe needs to exist).

use rand::Rng;

use super::slam::stream;
use super::SimConfig;

const FRAME_RATES: [f64; 6] = [20.0, 25.0, 30.0, 40.0, 50.0, 60.0];
const REFERENCE_RATES: [f64; 6] = [10.0, 20.0, 50.0, 100.0, 120.0, 200.0];

/// Stream id of the scenario draw (apart from the run's own streams).
const SCENARIO_STREAM: u64 = 0x5ce0;

/// A value log-uniform in `[lo, hi]`.
fn log_uniform(rng: &mut impl Rng, lo: f64, hi: f64) -> f64 {
    (lo.ln() + rng.random::<f64>() * (hi.ln() - lo.ln())).exp()
}

/// A value uniform in `[lo, hi]`.
fn uniform(rng: &mut impl Rng, lo: f64, hi: f64) -> f64 {
    lo + rng.random::<f64>() * (hi - lo)
}

impl SimConfig {
    /// Run `seed` of the scenario family (see the module doc); the run's own
    /// random streams are seeded with `seed` too.
    pub fn scenario(seed: u64) -> SimConfig {
        let mut rng = stream(seed, SCENARIO_STREAM);
        let r = &mut rng;
        let fps = FRAME_RATES[r.random_range(0..FRAME_RATES.len())];
        let startup = log_uniform(r, 2.0, 60.0);
        let start_share = uniform(r, 0.15, 0.7);
        let stable = log_uniform(r, 3.0, 150.0);
        let converge_start = (startup * start_share * fps).round() as usize;
        let stable_start = ((startup * fps).round() as usize).max(converge_start + 1);
        let n_frames = stable_start + (stable * fps).round().max(2.0) as usize;
        let duration = n_frames as f64 / fps;
        // At least five keyframes in the stable stage: a fit needs three.
        let kf_rate = uniform(r, 0.5, 4.0).max(5.0 / (duration - stable_start as f64 / fps));
        let n_keyframes = ((kf_rate * duration).round() as usize).clamp(3, n_frames);
        let speed = uniform(r, 0.3, 3.0);
        let path_length = speed * duration;
        let scale = log_uniform(r, 0.05, 20.0);
        let slam_path_length = path_length / scale;
        // A frame's step, SLAM units; the reference's step between matched frames, metres.
        let step = slam_path_length / n_frames as f64;
        let imu_rate = REFERENCE_RATES[r.random_range(0..REFERENCE_RATES.len())];
        let ref_step = speed / imu_rate.min(fps);
        let off = log_uniform(r, 1.3, 3.0);
        let init_scale = if r.random::<bool>() { off } else { 1.0 / off };
        let drift = if r.random::<bool>() {
            uniform(r, -5e-4, 5e-4)
        } else {
            0.0
        };
        SimConfig {
            seed,
            n_frames,
            fps,
            n_keyframes,
            width: 32,
            height: 24,
            path_length,
            slam_path_length,
            converge_start,
            stable_start,
            init_scale,
            init_wander: uniform(r, 0.02, 0.3),
            jump_prob: uniform(r, 0.0, 3.0) / fps,
            jump_sigma: uniform(r, 0.2, 0.8),
            scale_drift: drift,
            frame_pos_sigma: step * uniform(r, 0.005, 0.1),
            burst_prob: uniform(r, 0.0, 3e-3),
            burst_sigma: step * uniform(r, 0.5, 2.0),
            keyframe_pos_sigma: step * uniform(r, 0.05, 0.2),
            imu_rate,
            reference_pos_sigma: ref_step * uniform(r, 0.01, 0.15),
            ..SimConfig::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scenarios_are_valid_and_differ() {
        let runs: Vec<SimConfig> = (0..200).map(SimConfig::scenario).collect();
        for c in &runs {
            c.validate().unwrap();
            let startup = c.stable_start as f64 / c.fps;
            assert!((1.9..=60.1).contains(&startup), "{startup}");
        }
        assert_eq!(SimConfig::scenario(7), SimConfig::scenario(7));
        let rates: std::collections::BTreeSet<u64> =
            runs.iter().map(|c| c.imu_rate as u64).collect();
        assert_eq!(rates.len(), REFERENCE_RATES.len());
    }
}
