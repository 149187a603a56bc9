//! The paper's test scene: a 10×5 m ground plane at `z = 0` with eight 1×1×1 m
//! cubes standing on it, in the world frame (metres, `z` up, gravity along −z).
//!
//! Two views of the same geometry: an analytic ray/box/plane intersector (fast,
//! used to render keyframes) and a parry [`TriMesh`] (ray casting and point
//! projection, used to score point clouds). A test checks that the two agree.

use nalgebra::{Point3, Vector3};
use parry3d::query::{PointQuery, Ray, RayCast};
use parry3d::shape::TriMesh;

use crate::error::{Error, Result};

/// Standard gravity, m/s², acting along −z of the world frame.
pub const GRAVITY: f64 = 9.81;

/// Face id of the ground plane; cube `i`, face `j` (0..6: −x, +x, −y, +y, −z, +z) has `1 + 6i + j`.
pub const PLANE_FACE: u32 = 0;

/// Intensity of pixels that see no surface (the sky).
pub const BACKGROUND_INTENSITY: u8 = 0;

/// A ray hit on the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter: the hit is `origin + t·dir` (metres when `dir` is a unit vector).
    pub t: f64,
    /// World point of the hit, metres.
    pub point: Vector3<f64>,
    /// Outward unit normal of the face that was hit.
    pub normal: Vector3<f64>,
    /// Which face (see [`PLANE_FACE`]).
    pub face: u32,
}

/// The ground plane and the cubes, with a procedural texture and one directional light.
#[derive(Clone)]
pub struct Scene {
    /// Half sizes of the ground plane along x and y, metres (centred on the origin).
    pub plane_half: [f64; 2],
    /// Lower corners of the cubes (`z = 0`: they stand on the plane), metres.
    pub cube_min: Vec<Vector3<f64>>,
    /// Edge length of every cube, metres.
    pub cube_size: f64,
    /// Unit vector towards the light (world frame).
    pub light: Vector3<f64>,
    /// Seed of the texture's grey levels.
    pub texture_seed: u64,
    mesh: TriMesh,
}

impl std::fmt::Debug for Scene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Scene")
            .field("plane_half", &self.plane_half)
            .field("cube_min", &self.cube_min)
            .field("cube_size", &self.cube_size)
            .finish_non_exhaustive()
    }
}

/// Cube centres (x, y) of the paper-like layout, metres.
const CUBE_CENTRES: [[f64; 2]; 8] = [
    [-3.5, -1.5],
    [-3.0, 1.3],
    [-1.2, -0.3],
    [0.0, 1.6],
    [0.6, -1.6],
    [1.8, 0.4],
    [3.2, -1.2],
    [3.6, 1.4],
];

impl Scene {
    /// The paper's scene: a 10×5 m plane and eight 1 m cubes. (A fixed, valid
    /// layout; the `Result` is that of building the parry mesh.)
    pub fn paper() -> Result<Self> {
        let cubes = CUBE_CENTRES
            .iter()
            .map(|c| Vector3::new(c[0] - 0.5, c[1] - 0.5, 0.0))
            .collect();
        Self::try_new([5.0, 2.5], cubes, 1.0)
    }

    /// A plane of half sizes `plane_half` (metres) with cubes of edge `cube_size`
    /// whose lower corners are `cube_min` (z must be 0: standing on the plane).
    pub fn try_new(
        plane_half: [f64; 2],
        cube_min: Vec<Vector3<f64>>,
        cube_size: f64,
    ) -> Result<Self> {
        if !(plane_half[0] > 0.0 && plane_half[1] > 0.0 && plane_half.iter().all(|v| v.is_finite()))
        {
            return Err(Error::invalid(
                "plane size",
                format!("must be finite and > 0, got {plane_half:?}"),
            ));
        }
        if !(cube_size.is_finite() && cube_size > 0.0) {
            return Err(Error::invalid(
                "cube size",
                format!("must be finite and > 0, got {cube_size}"),
            ));
        }
        if let Some(i) = cube_min
            .iter()
            .position(|c| c.iter().any(|v| !v.is_finite()))
        {
            return Err(Error::NonFinite {
                what: "cube corners".into(),
                index: i,
            });
        }
        let mesh = build_mesh(plane_half, &cube_min, cube_size)?;
        Ok(Scene {
            plane_half,
            cube_min,
            cube_size,
            light: Vector3::new(0.45, 0.3, 0.84).normalize(),
            texture_seed: 0x05ee_d0f5_ce9e,
            mesh,
        })
    }

    /// The scene as a parry triangle mesh (f32, world frame, metres): two
    /// triangles for the plane, ten for each cube (the bottom lies on the plane).
    pub fn mesh(&self) -> &TriMesh {
        &self.mesh
    }

    /// Gravity in the world frame, m/s²: `(0, 0, −9.81)`.
    pub fn gravity() -> Vector3<f64> {
        Vector3::new(0.0, 0.0, -GRAVITY)
    }

    /// First hit of the ray `origin + t·dir`, `0 < t ≤ max_t`, computed
    /// analytically (slab test per cube, one plane test).
    pub fn ray_cast(&self, origin: &Vector3<f64>, dir: &Vector3<f64>, max_t: f64) -> Option<Hit> {
        let mut best: Option<(f64, Vector3<f64>, u32)> = None;
        if dir.z != 0.0 {
            let t = -origin.z / dir.z;
            if t > 0.0 && t <= max_t {
                let x = origin.x + t * dir.x;
                let y = origin.y + t * dir.y;
                if x.abs() <= self.plane_half[0] && y.abs() <= self.plane_half[1] {
                    let n = Vector3::new(0.0, 0.0, if dir.z < 0.0 { 1.0 } else { -1.0 });
                    best = Some((t, n, PLANE_FACE));
                }
            }
        }
        for (i, lo) in self.cube_min.iter().enumerate() {
            let limit = best.map_or(max_t, |b| b.0);
            if let Some((t, axis, side)) = slab(origin, dir, lo, self.cube_size, limit) {
                let mut n = Vector3::zeros();
                n[axis] = if side { 1.0 } else { -1.0 };
                let face = 1 + 6 * i as u32 + 2 * axis as u32 + side as u32;
                best = Some((t, n, face));
            }
        }
        best.map(|(t, normal, face)| Hit {
            t,
            point: origin + dir * t,
            normal,
            face,
        })
    }

    /// The same query through parry's ray cast on [`Scene::mesh`] (f32): the ray parameter of the first hit.
    pub fn ray_cast_mesh(
        &self,
        origin: &Vector3<f64>,
        dir: &Vector3<f64>,
        max_t: f64,
    ) -> Option<f64> {
        let ray = Ray::new(
            Point3::new(origin.x as f32, origin.y as f32, origin.z as f32),
            Vector3::new(dir.x as f32, dir.y as f32, dir.z as f32),
        );
        self.mesh
            .cast_local_ray(&ray, max_t as f32, false)
            .map(f64::from)
    }

    /// Distance of a world point (metres) to the nearest surface of the scene,
    /// by parry point projection on the mesh (f32 arithmetic).
    pub fn distance(&self, p: &[f64; 3]) -> f64 {
        let q = Point3::new(p[0] as f32, p[1] as f32, p[2] as f32);
        let proj = self.mesh.project_local_point(&q, false);
        f64::from((proj.point - q).norm())
    }

    /// Grey level (0–255) seen at a hit: a per-face pattern of random patches
    /// (0.25 m cells on the plane, 0.2 m on the cubes) lit by ambient light plus
    /// one directional (Lambertian) light, so that patch borders, face edges
    /// and silhouettes give image gradient.
    pub fn intensity(&self, hit: &Hit) -> u8 {
        let p = hit.point;
        let (u, v, cell) = if hit.face == PLANE_FACE {
            (p.x, p.y, 0.25)
        } else {
            let axis = ((hit.face - 1) % 6 / 2) as usize;
            let (a, b) = match axis {
                0 => (p.y, p.z),
                1 => (p.x, p.z),
                _ => (p.x, p.y),
            };
            (a, b, 0.2 * self.cube_size)
        };
        let iu = (u / cell).floor() as i64;
        let iv = (v / cell).floor() as i64;
        let h = hash3(self.texture_seed, hit.face as u64, iu as u64, iv as u64);
        let albedo = 0.15 + 0.85 * ((h >> 11) as f64 / (1u64 << 53) as f64);
        let shade = 0.35 + 0.65 * hit.normal.dot(&self.light).max(0.0);
        (255.0 * albedo * shade).round().clamp(1.0, 255.0) as u8
    }
}

/// Slab test of a ray against the axis-aligned cube `[lo, lo + size]`: the
/// entry parameter in `(0, limit]`, the axis of the entry face and whether it
/// is the upper (`+`) face. Origins inside the cube give `None`.
fn slab(
    o: &Vector3<f64>,
    d: &Vector3<f64>,
    lo: &Vector3<f64>,
    size: f64,
    limit: f64,
) -> Option<(f64, usize, bool)> {
    let mut t_near = f64::NEG_INFINITY;
    let mut t_far = f64::INFINITY;
    let mut axis = 0;
    let mut side = false;
    for k in 0..3 {
        let a = lo[k];
        let b = lo[k] + size;
        if d[k] == 0.0 {
            if o[k] < a || o[k] > b {
                return None;
            }
            continue;
        }
        let inv = 1.0 / d[k];
        let (t0, t1, upper) = if inv > 0.0 {
            ((a - o[k]) * inv, (b - o[k]) * inv, false)
        } else {
            ((b - o[k]) * inv, (a - o[k]) * inv, true)
        };
        if t0 > t_near {
            t_near = t0;
            axis = k;
            side = upper;
        }
        t_far = t_far.min(t1);
    }
    if t_near <= t_far && t_near > 0.0 && t_near <= limit {
        Some((t_near, axis, side))
    } else {
        None
    }
}

/// A 64-bit mix of four words (splitmix64 steps): the texture's random source.
fn hash3(a: u64, b: u64, c: u64, d: u64) -> u64 {
    let mut h = a;
    for w in [b, c, d] {
        h = splitmix(h ^ w.wrapping_mul(0x9e37_79b9_7f4a_7c15));
    }
    h
}

fn splitmix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

fn build_mesh(plane_half: [f64; 2], cubes: &[Vector3<f64>], size: f64) -> Result<TriMesh> {
    let mut v: Vec<Point3<f32>> = Vec::new();
    let mut idx: Vec<[u32; 3]> = Vec::new();
    let (hx, hy) = (plane_half[0] as f32, plane_half[1] as f32);
    v.extend([
        Point3::new(-hx, -hy, 0.0),
        Point3::new(hx, -hy, 0.0),
        Point3::new(hx, hy, 0.0),
        Point3::new(-hx, hy, 0.0),
    ]);
    idx.extend([[0, 1, 2], [0, 2, 3]]);
    for lo in cubes {
        let base = v.len() as u32;
        for k in 0..8u32 {
            let c = |bit: u32, i: usize| (lo[i] + if k & bit != 0 { size } else { 0.0 }) as f32;
            v.push(Point3::new(c(1, 0), c(2, 1), c(4, 2)));
        }
        // Corner k has x = bit 0, y = bit 1, z = bit 2. Ten outward triangles (no bottom).
        let faces: [[u32; 4]; 5] = [
            [0, 4, 6, 2], // −x
            [1, 3, 7, 5], // +x
            [0, 1, 5, 4], // −y
            [2, 6, 7, 3], // +y
            [4, 5, 7, 6], // +z
        ];
        for f in faces {
            idx.push([base + f[0], base + f[1], base + f[2]]);
            idx.push([base + f[0], base + f[2], base + f[3]]);
        }
    }
    TriMesh::new(v, idx).map_err(|e| Error::invalid("scene mesh", e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn analytic_ray_cast_matches_parry() {
        let scene = Scene::paper().unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut hits = 0;
        let mut n = 0;
        while n < 3000 {
            let o = Vector3::new(
                rng.random_range(-6.0..6.0),
                rng.random_range(-3.5..3.5),
                rng.random_range(0.05..3.0),
            );
            let inside = scene.cube_min.iter().any(|lo| {
                (0..3).all(|k| o[k] >= lo[k] - 1e-3 && o[k] <= lo[k] + scene.cube_size + 1e-3)
            });
            if inside {
                continue;
            }
            n += 1;
            let d = Vector3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..0.3),
            )
            .normalize();
            let a = scene.ray_cast(&o, &d, 100.0);
            let b = scene.ray_cast_mesh(&o, &d, 100.0);
            match (a, b) {
                (Some(h), Some(t)) => {
                    hits += 1;
                    assert!(
                        (h.t - t).abs() < 1e-4 * h.t.max(1.0),
                        "ray {n}: {} vs {t}",
                        h.t
                    );
                    assert!(scene.distance(&[h.point.x, h.point.y, h.point.z]) < 1e-5);
                }
                (None, None) => {}
                _ => panic!("ray {n} from {o:?} along {d:?}: analytic {a:?}, parry {b:?}"),
            }
        }
        assert!(hits > 1000, "too few hits to be a test: {hits}");
    }

    #[test]
    fn normals_and_faces() {
        let scene = Scene::paper().unwrap();
        let lo = scene.cube_min[2];
        let o = Vector3::new(lo.x + 0.5, lo.y + 0.5, 3.0);
        let h = scene
            .ray_cast(&o, &Vector3::new(0.0, 0.0, -1.0), 10.0)
            .unwrap();
        assert!((h.t - 2.0).abs() < 1e-12);
        assert_eq!(h.normal, Vector3::new(0.0, 0.0, 1.0));
        assert_eq!(h.face, 1 + 6 * 2 + 5);
        let o = Vector3::new(-4.9, 2.4, 3.0);
        let h = scene
            .ray_cast(&o, &Vector3::new(0.0, 0.0, -1.0), 10.0)
            .unwrap();
        assert_eq!(h.face, PLANE_FACE);
        assert!(scene
            .ray_cast(&o, &Vector3::new(0.0, 0.0, 1.0), 10.0)
            .is_none());
        assert!((scene.distance(&[0.0, 0.0, 0.5]) - 0.5).abs() < 1e-6);
    }

    #[test]
    fn texture_has_contrast() {
        let scene = Scene::paper().unwrap();
        let mut seen = std::collections::BTreeSet::new();
        for i in 0..40 {
            let p = Vector3::new(-4.0 + 0.25 * i as f64 + 0.1, -2.0, 0.0);
            let h = Hit {
                t: 1.0,
                point: p,
                normal: Vector3::z(),
                face: PLANE_FACE,
            };
            seen.insert(scene.intensity(&h) / 16);
        }
        assert!(seen.len() >= 6, "grey levels too uniform: {seen:?}");
    }
}
