//! Keyframe rendering: one ray per pixel through the analytic scene, an
//! intensity image, its gradient, and semi-dense inverse depth with noise.
//!
//! Noise model (stated, LSD-SLAM-like): only pixels whose image gradient is at
//! least `min_gradient` (grey levels per pixel, central differences on the
//! image blurred with a [1 2 1]/4 kernel) get a depth, as in LSD-SLAM's
//! semi-dense maps. Their inverse depth is `ρ = ρ_true · (1 + σ_rel · ε)`,
//! where `ε` is a unit-variance Gaussian field correlated over 5×5 pixels (a
//! box-filtered white field, standing in for LSD-SLAM's spatial
//! regularisation), and the stated variance is `(σ_rel · ρ)²`.

use nalgebra::{UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

use super::scene::{Scene, BACKGROUND_INTENSITY};
use crate::geometry::PinholeCamera;

/// What one camera sees: per-pixel arrays, row-major, index `x + y·width`.
#[derive(Clone, Debug)]
pub struct View {
    /// Depth along the optical axis (camera z), metres; 0 where no surface is hit.
    pub depth: Vec<f32>,
    /// Grey level of the rendered image.
    pub intensity: Vec<u8>,
    /// Image gradient magnitude, grey levels per pixel (0 on the border).
    pub gradient: Vec<f32>,
}

/// Semi-dense inverse depth of a view, in 1/metres.
#[derive(Clone, Debug)]
pub struct DepthMap {
    /// Noisy inverse depth, 1/m; 0 where unknown.
    pub idepth: Vec<f32>,
    /// Stated variance of `idepth`, 1/m²; 0 where unknown.
    pub idepth_var: Vec<f32>,
}

/// Ray casts every pixel of `camera` at pose `R_world_cam`, `p_world_cam`.
pub fn render(
    scene: &Scene,
    camera: &PinholeCamera,
    orientation: &UnitQuaternion<f64>,
    position: &Vector3<f64>,
) -> View {
    let w = camera.width as usize;
    let h = camera.height as usize;
    let r = orientation.to_rotation_matrix();
    let mut depth = vec![0f32; w * h];
    let mut intensity = vec![BACKGROUND_INTENSITY; w * h];
    depth
        .par_chunks_mut(w)
        .zip(intensity.par_chunks_mut(w))
        .enumerate()
        .for_each(|(y, (drow, irow))| {
            let yn = (y as f64 - camera.cy) / camera.fy;
            for x in 0..w {
                let xn = (x as f64 - camera.cx) / camera.fx;
                // Camera-frame direction with z = 1: the ray parameter is the depth.
                let dir = r * Vector3::new(xn, yn, 1.0);
                if let Some(hit) = scene.ray_cast(position, &dir, 1e3) {
                    drow[x] = hit.t as f32;
                    irow[x] = scene.intensity(&hit);
                }
            }
        });
    let gradient = gradient(&intensity, w, h);
    View {
        depth,
        intensity,
        gradient,
    }
}

/// Gradient magnitude of an 8-bit image after a [1 2 1]/4 blur in x and y.
fn gradient(img: &[u8], w: usize, h: usize) -> Vec<f32> {
    let mut tmp = vec![0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let c = img[x + y * w] as f32;
            let l = img[x.saturating_sub(1) + y * w] as f32;
            let r = img[(x + 1).min(w - 1) + y * w] as f32;
            tmp[x + y * w] = 0.25 * l + 0.5 * c + 0.25 * r;
        }
    }
    let mut blur = vec![0f32; w * h];
    for y in 0..h {
        for x in 0..w {
            let c = tmp[x + y * w];
            let u = tmp[x + y.saturating_sub(1) * w];
            let d = tmp[x + (y + 1).min(h - 1) * w];
            blur[x + y * w] = 0.25 * u + 0.5 * c + 0.25 * d;
        }
    }
    let mut g = vec![0f32; w * h];
    for y in 1..h.saturating_sub(1) {
        for x in 1..w - 1 {
            let i = x + y * w;
            let gx = 0.5 * (blur[i + 1] - blur[i - 1]);
            let gy = 0.5 * (blur[i + w] - blur[i - w]);
            g[i] = (gx * gx + gy * gy).sqrt();
        }
    }
    g
}

/// Semi-dense noisy inverse depth (see the module's noise model). `seed`
/// fixes the noise field; `rel_sigma = 0` gives the exact inverse depth.
pub fn depth_map(
    view: &View,
    w: usize,
    h: usize,
    min_gradient: f32,
    rel_sigma: f64,
    seed: u64,
) -> DepthMap {
    let n = w * h;
    let eps = if rel_sigma > 0.0 {
        correlated_noise(w, h, seed)
    } else {
        vec![0f32; n]
    };
    let mut idepth = vec![0f32; n];
    let mut var = vec![0f32; n];
    for i in 0..n {
        let d = view.depth[i];
        if d > 0.0 && view.gradient[i] >= min_gradient {
            let rho = 1.0 / d as f64;
            let noisy = rho * (1.0 + rel_sigma * eps[i] as f64);
            if noisy > 0.0 {
                idepth[i] = noisy as f32;
                let s = rel_sigma * noisy;
                var[i] = (s * s) as f32;
            }
        }
    }
    DepthMap {
        idepth,
        idepth_var: var,
    }
}

/// A unit-variance Gaussian field, white noise averaged over 5×5 pixels.
fn correlated_noise(w: usize, h: usize, seed: u64) -> Vec<f32> {
    const R: usize = 2;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (pw, ph) = (w + 2 * R, h + 2 * R);
    let white: Vec<f32> = (0..pw * ph)
        .map(|_| {
            let v: f64 = StandardNormal.sample(&mut rng);
            v as f32
        })
        .collect();
    let k = (2 * R + 1) as f32;
    let mut rows = vec![0f32; w * ph];
    for y in 0..ph {
        let line = &white[y * pw..(y + 1) * pw];
        let mut acc: f32 = line[..2 * R + 1].iter().sum();
        for x in 0..w {
            if x > 0 {
                acc += line[x + 2 * R] - line[x - 1];
            }
            rows[x + y * w] = acc;
        }
    }
    let mut out = vec![0f32; w * h];
    for x in 0..w {
        let mut acc: f32 = (0..2 * R + 1).map(|y| rows[x + y * w]).sum();
        for y in 0..h {
            if y > 0 {
                acc += rows[x + (y + 2 * R) * w] - rows[x + (y - 1) * w];
            }
            // Sum of 25 unit normals has variance 25: divide by 5.
            out[x + y * w] = acc / k;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn depth_is_consistent_with_the_scene() {
        let scene = Scene::paper().unwrap();
        let (w, h) = (640usize, 480usize);
        let cam = PinholeCamera::from_hfov(w as u32, h as u32, 75.0).unwrap();
        // Camera at 3 m looking straight down: x right = +x, y down = −y.
        let rot = nalgebra::Rotation3::from_matrix_unchecked(nalgebra::Matrix3::new(
            1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0,
        ));
        let q = UnitQuaternion::from_rotation_matrix(&rot);
        let p = Vector3::new(0.3, 0.2, 3.0);
        let v = render(&scene, &cam, &q, &p);
        let mut checked = 0;
        for y in (0..h).step_by(23) {
            for x in (0..w).step_by(19) {
                let d = v.depth[x + y * w] as f64;
                if d > 0.0 {
                    let pc = cam.backproject(x as f64, y as f64, d);
                    let pw = q * Vector3::new(pc[0], pc[1], pc[2]) + p;
                    assert!(scene.distance(&[pw.x, pw.y, pw.z]) < 1e-5);
                    checked += 1;
                }
            }
        }
        assert!(checked > 300);
        let g = v.gradient.iter().filter(|&&g| g >= 5.0).count();
        assert!(g > w * h / 20 && g < w * h / 2, "semi-dense share off: {g}");
        let exact = depth_map(&v, w, h, 5.0, 0.0, 1);
        let noisy = depth_map(&v, w, h, 5.0, 0.02, 1);
        let mut rel = Vec::new();
        for i in 0..w * h {
            if exact.idepth[i] > 0.0 {
                assert!((exact.idepth[i] * v.depth[i] - 1.0).abs() < 1e-6);
                rel.push((noisy.idepth[i] / exact.idepth[i] - 1.0) as f64);
            }
        }
        let sd = (rel.iter().map(|r| r * r).sum::<f64>() / rel.len() as f64).sqrt();
        assert!((sd / 0.02 - 1.0).abs() < 0.3, "noise std {sd}");
    }

    #[test]
    fn noise_field_has_unit_variance() {
        let e = correlated_noise(200, 150, 3);
        let m = e.iter().map(|&v| v as f64).sum::<f64>() / e.len() as f64;
        let v = e.iter().map(|&v| (v as f64 - m).powi(2)).sum::<f64>() / e.len() as f64;
        assert!(m.abs() < 0.1 && (v - 1.0).abs() < 0.15, "mean {m}, var {v}");
        // Neighbours are correlated (4/5 of the box overlaps).
        let c = (0..149 * 200)
            .filter(|i| i % 200 != 199)
            .map(|i| e[i] as f64 * e[i + 1] as f64)
            .sum::<f64>()
            / (149.0 * 199.0);
        assert!((c - 0.8).abs() < 0.15, "correlation {c}");
    }
}
