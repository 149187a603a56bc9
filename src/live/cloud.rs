//! [`LiveCloud`]: the world cloud of a growing session, bounded for a
//! viewer.

use std::collections::HashMap;

use crate::cloud::{backproject_batch_counted, PointFilter};
use crate::error::Result;
use crate::geometry::Sim3;
use crate::keyframe::Keyframe;

/// One keyframe's points as last backprojected.
struct Entry {
    /// The pose they were backprojected with.
    pose: Sim3,
    /// SLAM-frame coordinates (`n × 3`), every k-th of the keyframe's.
    points: Vec<f32>,
    /// Their colours (`n × 3`), when the keyframe has them.
    colors: Option<Vec<u8>>,
}

/// The world cloud of a session that grows keyframe by keyframe, for a
/// viewer (`follow`'s `world.mcap`, live in Foxglove): each keyframe's
/// points backprojected once, in the SLAM frame, at most `per_keyframe` of
/// them (every k-th), and again only when the graph moves the keyframe; the
/// world cloud is then all of them under `T_world_slam`, at most
/// `max_points` (every k-th beyond). An update costs the new or moved
/// keyframes' backprojection and one transform of at most `max_points`
/// points, not the whole run's pixels again; the world cloud is gathered
/// into the same memory at every update (fresh megabytes would cost a page
/// fault per 4 KiB page each time).
pub struct LiveCloud {
    filter: PointFilter,
    per_keyframe: usize,
    max_points: usize,
    cache: HashMap<i32, Entry>,
    points: Vec<f32>,
    colors: Vec<u8>,
}

impl LiveCloud {
    /// An empty cloud: `filter` as the conversion's, the two bounds.
    pub fn new(filter: PointFilter, per_keyframe: usize, max_points: usize) -> Self {
        LiveCloud {
            filter,
            per_keyframe: per_keyframe.max(1),
            max_points: max_points.max(1),
            cache: HashMap::new(),
            points: Vec::new(),
            colors: Vec::new(),
        }
    }

    /// Keyframes backprojected so far.
    pub fn len(&self) -> usize {
        self.cache.len()
    }

    /// True before the first keyframe.
    pub fn is_empty(&self) -> bool {
        self.cache.is_empty()
    }

    /// Brings the cache up to `keyframes` (in the session's order: the
    /// filter's keyframe index is the position there), then gives the world
    /// cloud under `t_world_slam`: coordinates (`n × 3`) and, when every
    /// keyframe has them, colours. Errors: the backprojection's (a filter
    /// out of range).
    pub fn update<'a>(
        &mut self,
        keyframes: impl Iterator<Item = &'a Keyframe>,
        t_world_slam: &Sim3,
    ) -> Result<(&[f32], Option<&[u8]>)> {
        let mut order = Vec::new();
        for (i, kf) in keyframes.enumerate() {
            order.push(kf.id);
            if self.cache.get(&kf.id).is_some_and(|e| e.pose == kf.pose) {
                continue;
            }
            let (c, _) = backproject_batch_counted(
                std::slice::from_ref(kf),
                i,
                &self.filter,
                |_| Sim3::identity(),
                kf.color.is_some(),
            )?;
            let stride = c.len().div_ceil(self.per_keyframe).max(1);
            let points: Vec<f32> = c
                .points
                .chunks_exact(3)
                .step_by(stride)
                .flatten()
                .copied()
                .collect();
            let colors = c.colors.map(|col| {
                col.chunks_exact(3)
                    .step_by(stride)
                    .flatten()
                    .copied()
                    .collect()
            });
            self.cache.insert(
                kf.id,
                Entry {
                    pose: kf.pose,
                    points,
                    colors,
                },
            );
        }
        let present: std::collections::HashSet<i32> = order.iter().copied().collect();
        self.cache.retain(|id, _| present.contains(id));
        let total: usize = self.cache.values().map(|e| e.points.len() / 3).sum();
        let stride = total.div_ceil(self.max_points).max(1);
        let with_colors = self.cache.values().all(|e| e.colors.is_some());
        // Every stride-th point of the keyframes in order: the points whose
        // index over the whole run is a multiple of the stride, each
        // keyframe's first one found from the points before it.
        let (points, colors) = (&mut self.points, &mut self.colors);
        points.clear();
        colors.clear();
        let mut k = 0usize;
        for id in &order {
            let e = &self.cache[id];
            let n = e.points.len() / 3;
            let first = (stride - k % stride) % stride;
            k += n;
            if first >= n {
                continue;
            }
            let m = (n - first).div_ceil(stride);
            take_every(points, &e.points, first, stride, m);
            if let (true, Some(c)) = (with_colors, &e.colors) {
                take_every(colors, c, first, stride, m);
            }
        }
        t_world_slam.transform_points_in_place(points)?;
        Ok((points, with_colors.then_some(colors.as_slice())))
    }
}

/// Appends to `out` the `m` triples of `src` at `first`, `first + stride`, …
fn take_every<T: Copy>(out: &mut Vec<T>, src: &[T], first: usize, stride: usize, m: usize) {
    if stride == 1 {
        // Under the budget: the keyframe's points whole, one copy.
        out.extend_from_slice(&src[3 * first..3 * (first + m)]);
        return;
    }
    out.reserve(3 * m);
    for s in src[3 * first..].chunks(3 * stride).take(m) {
        out.extend_from_slice(&s[..3]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::backproject;
    use crate::sim::{simulate, SimConfig};

    #[test]
    fn unbounded_it_is_the_batch_cloud_and_bounded_every_kth_of_it() {
        let sim = simulate(&SimConfig {
            width: 64,
            height: 48,
            ..SimConfig::default().reduced(8)
        })
        .unwrap();
        let kfs = &sim.keyframes;
        let t = sim.truth.t_world_slam;
        let filter = PointFilter::default();
        let batch = backproject(kfs, &filter, Some(&t)).unwrap();
        let mut all = LiveCloud::new(filter, usize::MAX, usize::MAX);
        // Half the keyframes, then all: the first half is not backprojected again.
        all.update(kfs[..kfs.len() / 2].iter(), &t).unwrap();
        let (p, c) = all.update(kfs.iter(), &t).unwrap();
        assert_eq!(p.len(), batch.points.len());
        for (a, b) in p.iter().zip(&batch.points) {
            assert!((a - b).abs() < 1e-4, "{a} {b}");
        }
        assert_eq!(c, batch.colors.as_deref());
        assert_eq!(all.len(), kfs.len());
        // A keyframe moved by the graph is backprojected again.
        let mut moved = kfs.clone();
        moved[3].pose.translation.x += 0.5;
        let (q, _) = all.update(moved.iter(), &t).unwrap();
        let again = backproject(&moved, &filter, Some(&t)).unwrap();
        assert_eq!(q.len(), again.points.len());
        assert!(q
            .iter()
            .zip(&again.points)
            .all(|(a, b)| (a - b).abs() < 1e-4));
        // Bounded over the run: every k-th point of the whole cloud.
        let n = batch.points.len() / 3;
        let mut run = LiveCloud::new(filter, usize::MAX, n / 3);
        let (r, rc) = run.update(kfs.iter(), &t).unwrap();
        let stride = n.div_ceil(n / 3);
        let every: Vec<f32> = batch
            .points
            .chunks_exact(3)
            .step_by(stride)
            .flatten()
            .copied()
            .collect();
        assert!(stride > 1 && r.len() == every.len());
        assert!(r.iter().zip(&every).all(|(a, b)| (a - b).abs() < 1e-4));
        let colors = batch.colors.as_deref().unwrap();
        let every_color: Vec<u8> = colors
            .chunks_exact(3)
            .step_by(stride)
            .flatten()
            .copied()
            .collect();
        assert_eq!(rc, Some(every_color.as_slice()));
        // Bounded: at most the budget, each point one of the batch's.
        let mut small = LiveCloud::new(filter, 50, 400);
        let (s, _) = small.update(kfs.iter(), &t).unwrap();
        assert!(!s.is_empty() && s.len() / 3 <= 400);
        let first = &s[..3];
        assert!(batch
            .points
            .chunks_exact(3)
            .any(|b| b.iter().zip(first).all(|(x, y)| (x - y).abs() < 1e-4)));
    }
}
