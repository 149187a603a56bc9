//! Planner queries: state and occupancy at points, voxel centres, ray casts
//! through the map, and collision of robot shapes with occupied voxels
//! (through parry's shape-versus-cuboid intersection tests).

use parry3d::math::{Isometry, Vector};
use parry3d::query::intersection_test;
use parry3d::shape::{Ball, Capsule, Cuboid, Segment, Shape};

use super::key::{coord_to_key, key_to_coord, Key, TREE_DEPTH, TREE_MAX_VAL};
use super::tree::Node;
use super::{probability, OccupancyMap, OCCUPIED_LOGODDS};
use crate::error::{Error, Result};

/// Occupancy state of a point: unknown (never observed), free or occupied.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(i8)]
pub enum VoxelState {
    /// Outside every observed voxel (or outside the tree).
    Unknown = -1,
    /// Log-odds below the occupancy threshold (probability < 0.5).
    Free = 0,
    /// Log-odds at or above the threshold (probability >= 0.5).
    Occupied = 1,
}

impl VoxelState {
    /// The state of an observed voxel with log-odds `l`.
    fn of_logodds(l: f32) -> Self {
        if l >= OCCUPIED_LOGODDS {
            VoxelState::Occupied
        } else {
            VoxelState::Free
        }
    }
}

fn check_finite(what: &str, v: &[f64]) -> Result<()> {
    match v.iter().position(|x| !x.is_finite()) {
        Some(i) => Err(Error::NonFinite {
            what: what.into(),
            index: i,
        }),
        None => Ok(()),
    }
}

impl OccupancyMap {
    /// Key of a point (metres), `None` outside the tree.
    pub fn key_of(&self, p: [f64; 3]) -> Option<Key> {
        Some([
            coord_to_key(p[0], self.resolution_factor)?,
            coord_to_key(p[1], self.resolution_factor)?,
            coord_to_key(p[2], self.resolution_factor)?,
        ])
    }

    /// Centre (metres) of the finest voxel with key `k`.
    pub fn key_center(&self, k: Key) -> [f64; 3] {
        let r = self.params.resolution;
        [
            key_to_coord(k[0], r),
            key_to_coord(k[1], r),
            key_to_coord(k[2], r),
        ]
    }

    /// Log-odds of the leaf containing `p`, `None` where unknown.
    pub fn logodds_at(&self, p: [f64; 3]) -> Option<f32> {
        self.tree.search(self.key_of(p)?).map(|(n, _)| n.value)
    }

    /// State at a point (metres, map frame).
    pub fn state(&self, p: [f64; 3]) -> VoxelState {
        self.logodds_at(p)
            .map_or(VoxelState::Unknown, VoxelState::of_logodds)
    }

    /// Occupancy probability at a point, `None` where unknown.
    pub fn occupancy(&self, p: [f64; 3]) -> Option<f64> {
        self.logodds_at(p).map(probability)
    }

    /// Leaves of one state as `(centre, edge length)` in metres, depth-first.
    /// Pruned leaves cover `2^k` voxels per axis.
    pub fn leaves(&self, state: VoxelState) -> Vec<([f64; 3], f64)> {
        let mut out = Vec::new();
        let r = self.params.resolution;
        self.tree.for_each_leaf(|base, depth, v| {
            if VoxelState::of_logodds(v) == state {
                let size = r * f64::from(1u32 << (TREE_DEPTH - depth));
                let c = base.map(|k| (k as i32 - TREE_MAX_VAL) as f64 * r + 0.5 * size);
                out.push((c, size));
            }
        });
        out
    }

    /// Number of finest voxels of one state (a pruned leaf at depth `d`
    /// counts `8^(16 − d)`); at most `2^48`, computed from the leaves.
    pub fn count_voxels(&self, state: VoxelState) -> u64 {
        let mut n = 0u64;
        self.tree.for_each_leaf(|_, depth, v| {
            if VoxelState::of_logodds(v) == state {
                n += 1u64 << (3 * (TREE_DEPTH - depth));
            }
        });
        n
    }

    /// Centres (metres) of every finest voxel of one state (pruned leaves
    /// expanded), depth-first per leaf, or [`Error::TooLarge`] when there are
    /// more than `max_voxels` of them (checked with [`Self::count_voxels`]
    /// before anything is allocated: one leaf near the root is `2^45` voxels).
    /// [`Self::leaves`] gives the same space as leaves with their sizes.
    pub fn try_voxel_centers(&self, state: VoxelState, max_voxels: u64) -> Result<Vec<[f64; 3]>> {
        let count = self.count_voxels(state);
        if count > max_voxels {
            return Err(Error::TooLarge {
                what: format!(
                    "{} voxel centres (use the leaves with their sizes instead)",
                    match state {
                        VoxelState::Occupied => "occupied",
                        VoxelState::Free => "free",
                        VoxelState::Unknown => "unknown",
                    }
                ),
                count,
                limit: max_voxels,
            });
        }
        Ok(self.voxel_centers_unbounded(state, count as usize))
    }

    /// Centres (metres) of every finest voxel of one state (pruned leaves
    /// expanded), depth-first per leaf. Unbounded: a pruned leaf near the root
    /// holds up to `2^45` voxels, so maps from untrusted files go through
    /// [`Self::try_voxel_centers`].
    pub fn voxel_centers(&self, state: VoxelState) -> Vec<[f64; 3]> {
        let count = self.count_voxels(state);
        // No reservation beyond 2^24 up front: a huge count then fails as
        // the vector grows, not in one allocation.
        self.voxel_centers_unbounded(state, count.min(1 << 24) as usize)
    }

    fn voxel_centers_unbounded(&self, state: VoxelState, reserve: usize) -> Vec<[f64; 3]> {
        let mut out = Vec::with_capacity(reserve);
        let r = self.params.resolution;
        self.tree.for_each_leaf(|base, depth, v| {
            if VoxelState::of_logodds(v) != state {
                return;
            }
            let n = 1u32 << (TREE_DEPTH - depth);
            for dz in 0..n {
                for dy in 0..n {
                    for dx in 0..n {
                        out.push([
                            key_to_coord(base[0] + dx as u16, r),
                            key_to_coord(base[1] + dy as u16, r),
                            key_to_coord(base[2] + dz as u16, r),
                        ]);
                    }
                }
            }
        });
        out
    }

    /// Casts a ray from `origin` along `direction` (metres, map frame) and
    /// returns the centre of the first occupied voxel (OctoMap's `castRay`).
    /// `None` when the ray leaves `max_range` (`None`: the tree) without a hit,
    /// or meets an unknown voxel first while `ignore_unknown` is false.
    pub fn cast_ray(
        &self,
        origin: [f64; 3],
        direction: [f64; 3],
        max_range: Option<f64>,
        ignore_unknown: bool,
    ) -> Result<Option<[f64; 3]>> {
        check_finite("origin", &origin)?;
        check_finite("direction", &direction)?;
        let norm = (direction[0].powi(2) + direction[1].powi(2) + direction[2].powi(2)).sqrt();
        if norm == 0.0 {
            return Err(Error::invalid("direction", "zero vector"));
        }
        let dir = direction.map(|d| d / norm);
        let mut key = self.key_of(origin).ok_or_else(|| Error::OutOfRange {
            what: "origin".into(),
            reason: "outside the octree".into(),
        })?;
        let r = self.params.resolution;
        let mut step = [0i32; 3];
        let mut t_max = [f64::MAX; 3];
        let mut t_delta = [f64::MAX; 3];
        for i in 0..3 {
            if dir[i] != 0.0 {
                step[i] = if dir[i] > 0.0 { 1 } else { -1 };
                let border = key_to_coord(key[i], r) + step[i] as f64 * 0.5 * r;
                t_max[i] = (border - origin[i]) / dir[i];
                t_delta[i] = r / dir[i].abs();
            }
        }
        loop {
            match self.tree.search(key) {
                Some((n, _)) if n.value >= OCCUPIED_LOGODDS => {
                    return Ok(Some(self.key_center(key)))
                }
                Some(_) => {}
                None if !ignore_unknown => return Ok(None),
                None => {}
            }
            let dim = if t_max[0] < t_max[1] {
                if t_max[0] < t_max[2] {
                    0
                } else {
                    2
                }
            } else if t_max[1] < t_max[2] {
                1
            } else {
                2
            };
            if let Some(m) = max_range {
                if t_max[dim] > m {
                    return Ok(None);
                }
            }
            let next = key[dim] as i32 + step[dim];
            if !(0..65536).contains(&next) {
                return Ok(None);
            }
            key[dim] = next as u16;
            t_max[dim] += t_delta[dim];
        }
    }

    /// Whether `shape` at `center` (metres, map frame; `rotation` maps the
    /// shape's frame into the map frame) intersects any occupied voxel.
    /// Voxels are visited only where the shape's bounding box overlaps
    /// subtrees whose maximum log-odds is occupied.
    pub fn collides_shape(
        &self,
        shape: &dyn Shape,
        center: [f64; 3],
        rotation: nalgebra::UnitQuaternion<f32>,
    ) -> Result<bool> {
        check_finite("center", &center)?;
        if !self.tree.root.exists() {
            return Ok(false);
        }
        // Work relative to `center` so that f32 keeps voxel precision.
        let pose = Isometry::from_parts(Vector::zeros().into(), rotation);
        let aabb = shape.compute_aabb(&pose);
        let lo = [0, 1, 2].map(|i| center[i] + aabb.mins[i] as f64);
        let hi = [0, 1, 2].map(|i| center[i] + aabb.maxs[i] as f64);
        let mut hit = false;
        self.collide_rec(
            self.tree.root,
            [0; 3],
            0,
            &lo,
            &hi,
            &mut |c, size| {
                let half = (size * 0.5) as f32;
                let cube = Cuboid::new(Vector::new(half, half, half));
                let p = Isometry::translation(
                    (c[0] - center[0]) as f32,
                    (c[1] - center[1]) as f32,
                    (c[2] - center[2]) as f32,
                );
                // Every pair used here (ball, cuboid, capsule, segment) is supported.
                intersection_test(&pose, shape, &p, &cube).unwrap_or(true)
            },
            &mut hit,
        );
        Ok(hit)
    }

    #[allow(clippy::too_many_arguments)]
    fn collide_rec(
        &self,
        node: Node,
        base: Key,
        depth: u32,
        lo: &[f64; 3],
        hi: &[f64; 3],
        test: &mut impl FnMut([f64; 3], f64) -> bool,
        hit: &mut bool,
    ) {
        if *hit || node.value < OCCUPIED_LOGODDS {
            return;
        }
        let r = self.params.resolution;
        let size = r * f64::from(1u32 << (TREE_DEPTH - depth));
        let min = base.map(|k| (k as i32 - TREE_MAX_VAL) as f64 * r);
        for i in 0..3 {
            if min[i] > hi[i] || min[i] + size < lo[i] {
                return;
            }
        }
        if !node.has_children() {
            let c = min.map(|m| m + 0.5 * size);
            if test(c, size) {
                *hit = true;
            }
            return;
        }
        let half = 1u16 << (TREE_DEPTH - 1 - depth);
        for (i, c) in self.tree.children(node).iter().enumerate() {
            if c.exists() {
                let k = [
                    base[0] | if i & 1 != 0 { half } else { 0 },
                    base[1] | if i & 2 != 0 { half } else { 0 },
                    base[2] | if i & 4 != 0 { half } else { 0 },
                ];
                self.collide_rec(*c, k, depth + 1, lo, hi, test, hit);
                if *hit {
                    return;
                }
            }
        }
    }

    /// Whether a sphere robot (centre in metres, radius > 0) touches an
    /// occupied voxel.
    pub fn collides_sphere(&self, center: [f64; 3], radius: f64) -> Result<bool> {
        if !(radius.is_finite() && radius > 0.0) {
            return Err(Error::invalid(
                "radius",
                format!("{radius} is not a positive length"),
            ));
        }
        self.collides_shape(
            &Ball::new(radius as f32),
            center,
            nalgebra::UnitQuaternion::identity(),
        )
    }

    /// Whether an axis-aligned box robot (centre and half extents in metres)
    /// touches an occupied voxel.
    pub fn collides_box(&self, center: [f64; 3], half_extents: [f64; 3]) -> Result<bool> {
        if let Some(h) = half_extents.iter().find(|h| !(h.is_finite() && **h > 0.0)) {
            return Err(Error::invalid(
                "half_extents",
                format!("{h} is not a positive length"),
            ));
        }
        let cube = Cuboid::new(Vector::new(
            half_extents[0] as f32,
            half_extents[1] as f32,
            half_extents[2] as f32,
        ));
        self.collides_shape(&cube, center, nalgebra::UnitQuaternion::identity())
    }

    /// Whether the straight segment `a → b` (metres), swept by a sphere of
    /// `radius` (0: the bare segment), stays clear of occupied voxels.
    /// Unknown space counts as free.
    pub fn segment_is_free(&self, a: [f64; 3], b: [f64; 3], radius: f64) -> Result<bool> {
        check_finite("a", &a)?;
        check_finite("b", &b)?;
        if !(radius.is_finite() && radius >= 0.0) {
            return Err(Error::invalid(
                "radius",
                format!("{radius} is not a length >= 0"),
            ));
        }
        let mid = [0, 1, 2].map(|i| 0.5 * (a[i] + b[i]));
        let pa = nalgebra::Point3::new(
            (a[0] - mid[0]) as f32,
            (a[1] - mid[1]) as f32,
            (a[2] - mid[2]) as f32,
        );
        let pb = nalgebra::Point3::new(-pa.x, -pa.y, -pa.z);
        let id = nalgebra::UnitQuaternion::identity();
        let hit = if radius > 0.0 {
            self.collides_shape(&Capsule::new(pa, pb, radius as f32), mid, id)?
        } else if a == b {
            self.state(a) == VoxelState::Occupied
        } else {
            self.collides_shape(&Segment::new(pa, pb), mid, id)?
        };
        Ok(!hit)
    }
}
